"""The physics of the bladder positioner, as pure functions of one scalar type.

Every function here runs unchanged on floats, on ``AutoDiffXd`` and on ``pydrake.symbolic``
expressions (only ``pydrake.math`` min, max and sqrt, no branches), so one set of equations serves
the scalar-templated plant (``pneumatic_plant.PneumaticPlant_``), its compiled symbolic form, the
steady-state solver and the analysis.

The model, in SI (p gauge pressure in the bladder, z the head's lift, v its rate, s the two valves'
spool positions expressed as currents):

- valve spool: a first-order lag behind the coil current through a play (backlash) band, which is
  the hysteresis a proportional solenoid valve shows; ds/dt = dead_zone(i - s, h) / tau.
- valve opening: 0 below the starting current, linear to 1 at the saturation current.
- mass flow through a valve or leak (ISO 6358-1): q = C rho_0 p_up phi(p_down / p_up), choked
  (phi = 1) at pressure ratios below the critical ratio b, subsonic above it, with the standard's
  linear (laminar) segment near ratio 1 so the flow is smooth through zero.
- bladder air: a polytropic mass balance dp/dt = n / V (R T q_net - p_abs dV/dt) with a volume
  V = V_0 + A_v z that grows with the lift.
- head: m dz/dt^2 = p A + k (z_0 - z) - m g - c v + limit forces, where the bladder carries the
  head as gauge pressure times effective contact area on top of its own fabric stiffness, and stiff
  one-sided springs stand for the physical lift limits.
"""

from dataclasses import dataclass, field

import pydrake.math as dm

from maskless.systems.config_loading import UNSET

STATE_NAMES = (
    "gauge_pressure_pa",
    "lift_m",
    "lift_rate_m_s",
    "inlet_spool_current_a",
    "outlet_spool_current_a",
)
GAUGE_PRESSURE, LIFT, LIFT_RATE, INLET_SPOOL, OUTLET_SPOOL = range(len(STATE_NAMES))


@dataclass
class ValveParameters:
    """A current-controlled proportional valve (SMC PVQ); assets/pneumatic.yaml gives sources.

    Attributes:
        sonic_conductance_m3_s_pa: ISO 6358 sonic conductance C at full opening.
        critical_pressure_ratio: ISO 6358 b.
        starting_current_a: no flow below this coil current (normally closed valve).
        saturation_current_a: fully open at and above this coil current.
        hysteresis_fraction: width of the play band as a fraction of the current span.
        time_constant_s: spool response lag.
    """

    sonic_conductance_m3_s_pa: float = UNSET
    critical_pressure_ratio: float = UNSET
    starting_current_a: float = UNSET
    saturation_current_a: float = UNSET
    hysteresis_fraction: float = UNSET
    time_constant_s: float = UNSET

    @property
    def current_span_a(self) -> float:
        """The coil currents over which the valve opens: saturation minus starting current (A)."""
        return self.saturation_current_a - self.starting_current_a

    @property
    def play_half_width_a(self) -> float:
        """Half the width of the spool's play band (A): half the hysteresis fraction of the span."""
        return 0.5 * self.hysteresis_fraction * self.current_span_a


@dataclass
class PneumaticParameters:
    """Every number of the pneumatic plant, in SI; assets/pneumatic.yaml gives each one's source.

    Attributes:
        supply_gauge_pressure_pa: regulated compressor supply to the inlet valve.
        atmospheric_pressure_pa: ambient pressure; gauge pressures are relative to it.
        vacuum_absolute_pressure_pa: the diaphragm pump's suction behind the outlet valve.
        air_temperature_k: air temperature (isothermal supply and bladder walls).
        gas_constant_j_kg_k: specific gas constant of air.
        polytropic_exponent: n in p V^n = const for the bladder air (1 isothermal, 1.4 adiabatic).
        reference_density_kg_m3: ISO 8778 reference air density rho_0 in the ISO 6358 flow law.
        reference_temperature_k: ISO 8778 reference temperature T_0.
        laminar_pressure_ratio: ISO 6358 ratio above which flow is taken as laminar (linear).
        inlet: the valve from the supply into the bladder.
        outlet: the valve from the bladder to the vacuum pump.
        leak_sonic_conductance_m3_s_pa: the bladder's standing leak to atmosphere.
        leak_critical_pressure_ratio: ISO 6358 b of the leak path.
        rest_volume_m3: bladder air volume at zero lift.
        volume_per_lift_m2: bladder volume gained per metre of lift.
        contact_area_m2: effective area over which gauge pressure pushes on the head.
        stiffness_n_m: bladder fabric and cushion stiffness under the head.
        damping_n_s_m: viscous damping of the head on the bladder.
        nominal_head_mass_kg: the head whose weight the unpressurised bladder carries at zero lift.
        head_mass_kg: the head being positioned.
        gravity_m_s2: standard gravity.
        min_lift_m, max_lift_m: the bladder's physical travel (fully down, fully inflated).
        limit_stiffness_n_m: stiffness of the travel limits.
        rest_head_height_m: head height above the table at zero lift.
        simulation_step_s: the fixed step of the compiled plant in the closed loop.
    """

    supply_gauge_pressure_pa: float = UNSET
    atmospheric_pressure_pa: float = UNSET
    vacuum_absolute_pressure_pa: float = UNSET
    air_temperature_k: float = UNSET
    gas_constant_j_kg_k: float = UNSET
    polytropic_exponent: float = UNSET
    reference_density_kg_m3: float = UNSET
    reference_temperature_k: float = UNSET
    laminar_pressure_ratio: float = UNSET
    inlet: ValveParameters = field(default_factory=ValveParameters)
    outlet: ValveParameters = field(default_factory=ValveParameters)
    leak_sonic_conductance_m3_s_pa: float = UNSET
    leak_critical_pressure_ratio: float = UNSET
    rest_volume_m3: float = UNSET
    volume_per_lift_m2: float = UNSET
    contact_area_m2: float = UNSET
    stiffness_n_m: float = UNSET
    damping_n_s_m: float = UNSET
    nominal_head_mass_kg: float = UNSET
    head_mass_kg: float = UNSET
    gravity_m_s2: float = UNSET
    min_lift_m: float = UNSET
    max_lift_m: float = UNSET
    limit_stiffness_n_m: float = UNSET
    rest_head_height_m: float = UNSET
    simulation_step_s: float = UNSET

    @property
    def unloaded_lift_m(self) -> float:
        """Where the bladder fabric carries no load.

        There the nominal head rests at zero lift with the bladder at zero gauge.
        """
        return self.nominal_head_mass_kg * self.gravity_m_s2 / self.stiffness_n_m


def subsonic_flow_factor(pressure_ratio, critical_ratio, laminar_ratio):
    """ISO 6358 flow factor phi(r) for r = p_down / p_up in [0, 1].

    It is 1 when choked (r <= b), the elliptic law above b, and the standard's linear segment from
    ``laminar_ratio`` to zero at r = 1 (which keeps the derivative finite at zero flow).

    The elliptic law is concave, so below ``laminar_ratio`` it lies under the extension of the
    linear segment and above it lies over the segment: the minimum of the two is the piecewise law,
    with no branch.
    """
    below_laminar = dm.min(pressure_ratio, laminar_ratio)
    excess = (dm.max(below_laminar, critical_ratio) - critical_ratio) / (1.0 - critical_ratio)
    elliptic = dm.sqrt(1.0 - excess * excess)
    laminar_excess = (laminar_ratio - critical_ratio) / (1.0 - critical_ratio)
    at_laminar = (1.0 - laminar_excess * laminar_excess) ** 0.5
    linear = at_laminar * (1.0 - pressure_ratio) / (1.0 - laminar_ratio)
    return dm.min(elliptic, linear)


def mass_flow_kg_s(conductance, critical_ratio, p_up, p_down, parameters: PneumaticParameters):
    """ISO 6358 mass flow from absolute pressure ``p_up`` to ``p_down`` (zero if p_down is higher).

    For a valve, whose upstream side is fixed by the circuit (the supply always exceeds the
    bladder, the vacuum is always below it).
    """
    scale = (
        conductance
        * parameters.reference_density_kg_m3
        * (parameters.reference_temperature_k / parameters.air_temperature_k) ** 0.5
    )
    ratio = dm.min(p_down / p_up, 1.0)
    return (
        scale
        * p_up
        * subsonic_flow_factor(ratio, critical_ratio, parameters.laminar_pressure_ratio)
    )


def two_way_mass_flow_kg_s(conductance, critical_ratio, p_1, p_2, parameters: PneumaticParameters):
    """ISO 6358 mass flow from ``p_1`` to ``p_2``, negative when p_2 > p_1.

    For the leak, which breathes in when the outlet pulls the bladder below atmosphere.

    Written as the difference of the two directions, each of which is zero when its own upstream
    side is the lower pressure, so no sign function is needed.
    """
    return mass_flow_kg_s(conductance, critical_ratio, p_1, p_2, parameters) - mass_flow_kg_s(
        conductance, critical_ratio, p_2, p_1, parameters
    )


def valve_opening(spool_current, valve: ValveParameters):
    """Fraction open, 0..1: zero below the starting current, linear to the saturation current."""
    fraction = (spool_current - valve.starting_current_a) / valve.current_span_a
    return dm.min(dm.max(fraction, 0.0), 1.0)


def spool_rate(coil_current, spool_current, valve: ValveParameters):
    """ds/dt: the spool follows the coil current only once it leaves the play band (hysteresis)."""
    error = coil_current - spool_current
    half_width = valve.play_half_width_a
    outside_band = error - dm.min(dm.max(error, -half_width), half_width)
    return outside_band / valve.time_constant_s


def bladder_flows_kg_s(gauge_pressure, inlet_opening, outlet_opening, p: PneumaticParameters):
    """(inlet, outlet, leak) mass flows, each positive in its normal direction."""
    bladder = p.atmospheric_pressure_pa + gauge_pressure
    supply = p.atmospheric_pressure_pa + p.supply_gauge_pressure_pa
    inlet = mass_flow_kg_s(
        inlet_opening * p.inlet.sonic_conductance_m3_s_pa,
        p.inlet.critical_pressure_ratio,
        supply,
        bladder,
        p,
    )
    outlet = mass_flow_kg_s(
        outlet_opening * p.outlet.sonic_conductance_m3_s_pa,
        p.outlet.critical_pressure_ratio,
        bladder,
        p.vacuum_absolute_pressure_pa,
        p,
    )
    leak = two_way_mass_flow_kg_s(
        p.leak_sonic_conductance_m3_s_pa,
        p.leak_critical_pressure_ratio,
        bladder,
        p.atmospheric_pressure_pa,
        p,
    )
    return inlet, outlet, leak


def net_mass_flow_kg_s(gauge_pressure, inlet_opening, outlet_opening, p: PneumaticParameters):
    """Air mass flow into the bladder."""
    inlet, outlet, leak = bladder_flows_kg_s(gauge_pressure, inlet_opening, outlet_opening, p)
    return inlet - outlet - leak


def head_force_n(gauge_pressure, lift, lift_rate, p: PneumaticParameters):
    """Net upward force on the head: pressure, fabric spring, weight, damping, travel limits."""
    below = dm.max(p.min_lift_m - lift, 0.0)
    above = dm.max(lift - p.max_lift_m, 0.0)
    return (
        gauge_pressure * p.contact_area_m2
        + p.stiffness_n_m * (p.unloaded_lift_m - lift)
        - p.head_mass_kg * p.gravity_m_s2
        - p.damping_n_s_m * lift_rate
        + p.limit_stiffness_n_m * (below - above)
    )


def gauge_pressure_rate(gauge_pressure, lift, lift_rate, net_flow, p: PneumaticParameters):
    """dp/dt of the polytropic bladder: inflow compresses, growing volume expands."""
    volume = p.rest_volume_m3 + p.volume_per_lift_m2 * lift
    bladder = p.atmospheric_pressure_pa + gauge_pressure
    return (p.polytropic_exponent / volume) * (
        p.gas_constant_j_kg_k * p.air_temperature_k * net_flow
        - bladder * p.volume_per_lift_m2 * lift_rate
    )


def net_flow_of_state(state, p: PneumaticParameters):
    """Air mass flow into the bladder for the state's pressure and spool positions."""
    return net_mass_flow_kg_s(
        state[GAUGE_PRESSURE],
        valve_opening(state[INLET_SPOOL], p.inlet),
        valve_opening(state[OUTLET_SPOOL], p.outlet),
        p,
    )


def state_derivatives(state, inlet_current, outlet_current, p: PneumaticParameters) -> list:
    """d/dt of the state (ordered as ``STATE_NAMES``) for the two coil currents (A)."""
    gauge_pressure, lift, lift_rate = state[GAUGE_PRESSURE], state[LIFT], state[LIFT_RATE]
    net_flow = net_flow_of_state(state, p)
    return [
        gauge_pressure_rate(gauge_pressure, lift, lift_rate, net_flow, p),
        lift_rate,
        head_force_n(gauge_pressure, lift, lift_rate, p) / p.head_mass_kg,
        spool_rate(inlet_current, state[INLET_SPOOL], p.inlet),
        spool_rate(outlet_current, state[OUTLET_SPOOL], p.outlet),
    ]


def head_height_m(state, p: PneumaticParameters):
    """Head height above the table (the plant's output)."""
    return p.rest_head_height_m + state[LIFT]
