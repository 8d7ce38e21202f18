"""The pneumatic plant's operating range, and how the plant behaves there.

The operating range is where each valve current holds the head.

For each coil current of one valve (the other held), ``operating_range`` gives the steady state
(``pneumatic_plant.equilibrium_state``: lift and bladder gauge pressure) and Drake's ``Linearize``
of the plant there (``pneumatic_design.linearize_pneumatic_plant``): its DC gain from the coil
current to the lift and the time constants of its modes. Pure functions on the plant's parameters;
``operating_range_plots.plot_operating_range`` draws the result.
"""

from dataclasses import dataclass

import numpy as np

from maskless.systems.plant.pneumatic_design import VALVE_STATES, linearize_pneumatic_plant
from maskless.systems.plant.pneumatic_physics import GAUGE_PRESSURE, LIFT, PneumaticParameters
from maskless.systems.plant.pneumatic_plant import beyond_travel, equilibrium_state

VALVES = ("inlet", "outlet")


@dataclass(frozen=True)
class OperatingRange:
    """Steady state and linearisation of the plant along one valve's current range.

    Attributes:
        valve: "inlet" or "outlet", the valve whose current is swept.
        held_current_a: the other valve's coil current, held constant (A).
        currents_a: the swept coil currents (A), increasing (N,).
        lift_m: steady lift of the head at each current (m) (N,).
        gauge_pressure_pa: steady bladder gauge pressure (Pa) (N,).
        dc_gain_m_per_a: steady lift per unit coil current of the linearised plant, -C A⁻¹ B
            (m/A, the same number in mm/mA) (N,); NaN where the head is at or past a travel limit.
        time_constants_s: time constants -1/Re(λ) of the linearised plant's modes (a complex
            pair counted once, the row padded with NaN), slowest first, one row per current
            (N, states); NaN where the head is at or past a travel limit.
        beyond_travel: where the head rests at or past a travel limit (N,), held by the model's
            stop rather than the bladder: no lift a patient's head reaches.
    """

    valve: str
    held_current_a: float
    currents_a: np.ndarray
    lift_m: np.ndarray
    gauge_pressure_pa: np.ndarray
    dc_gain_m_per_a: np.ndarray
    time_constants_s: np.ndarray
    beyond_travel: np.ndarray

    @property
    def slow_time_constant_s(self) -> np.ndarray:
        """The slowest mode's time constant at each current (s): the bladder's fill and leak."""
        return self.time_constants_s[:, 0]

    @property
    def lift_range_m(self) -> tuple[float, float] | None:
        """(lowest, highest) steady lift inside the travel (m); None if there is none."""
        within = self.lift_m[~self.beyond_travel]
        return (float(within.min()), float(within.max())) if within.size else None

    @property
    def lift_span_m(self) -> float:
        """How far the swept current moves the steady lift within the travel (m); 0 if nowhere."""
        lifts = self.lift_range_m
        return lifts[1] - lifts[0] if lifts else 0.0


def valve_currents_a(p: PneumaticParameters, valve: str, num_points: int) -> np.ndarray:
    """``num_points`` coil currents (A), evenly spaced over the valve's range.

    They run from the valve's starting to its saturation current.

    Args:
        p: the plant's parameters.
        valve: "inlet" or "outlet".
        num_points: how many currents, at least 2.

    Raises:
        ValueError: ``valve`` is unknown or ``num_points`` < 2.
    """
    parameters = _valve_parameters(p, valve)
    if isinstance(num_points, bool) or not isinstance(num_points, int | np.integer):
        raise ValueError(f"num_points = {num_points!r}: expected an integer >= 2")
    if num_points < 2:
        raise ValueError(f"num_points = {num_points}: expected an integer >= 2")
    return np.linspace(parameters.starting_current_a, parameters.saturation_current_a, num_points)


def mode_time_constants_s(A: np.ndarray) -> np.ndarray:
    """Time constants -1/Re(λ) of the modes of x' = A x (s), slowest first.

    A complex pair is one mode (its envelope's time constant); a mode on the imaginary axis has
    an infinite time constant, an unstable one a negative time constant.

    Args:
        A: a real square state matrix (1/s).
    """
    eigenvalues = np.linalg.eigvals(np.asarray(A, dtype=float))
    decay = -eigenvalues[eigenvalues.imag >= 0.0].real
    # A mode on the imaginary axis never decays (of either sign of zero).
    tau = np.full(decay.shape, np.inf)
    np.divide(1.0, decay, out=tau, where=decay != 0.0)
    # Slowest first: infinite, then the largest positive; unstable (negative) modes last.
    return np.array(sorted(tau, key=lambda t: (t < 0, -t)))


def operating_range(
    p: PneumaticParameters,
    valve: str,
    currents_a,
    held_current_a: float,
) -> OperatingRange:
    """The steady state and linearisation at each coil current of ``valve``.

    Args:
        p: the plant's parameters.
        valve: "inlet" or "outlet", the valve whose current is swept.
        currents_a: its coil currents (A), increasing.
        held_current_a: the other valve's coil current (A), held throughout.

    Raises:
        ValueError: ``valve`` is unknown, or ``currents_a`` is empty or not increasing.
    """
    _valve_parameters(p, valve)
    currents = np.asarray(currents_a, dtype=float)
    if currents.ndim != 1 or currents.size == 0 or not np.all(np.diff(currents) > 0):
        raise ValueError(f"currents_a = {currents}: expected increasing coil currents (A)")
    lifts, pressures, gains, time_constants, beyond = [], [], [], [], []
    modes = len(VALVE_STATES[valve])
    for current in currents:
        inlet, outlet = (current, held_current_a) if valve == "inlet" else (held_current_a, current)
        state = equilibrium_state(p, inlet, outlet)
        lifts.append(state[LIFT])
        pressures.append(state[GAUGE_PRESSURE])
        beyond.append(beyond_travel(p, state))
        if beyond[-1]:
            # Held by a travel limit (a well-sealed bladder filling towards the supply): no gain.
            gains.append(np.nan)
            time_constants.append(np.full(modes, np.nan))
            continue
        A, B, C = linearize_pneumatic_plant(p, inlet, outlet, valve)
        gains.append(float((-C @ np.linalg.solve(A, B))[0, 0]))
        tau = mode_time_constants_s(A)
        # A complex pair is one mode: rows are padded to one entry per state with NaN.
        time_constants.append(np.concatenate([tau, np.full(modes - tau.size, np.nan)]))
    return OperatingRange(
        valve=valve,
        held_current_a=float(held_current_a),
        currents_a=currents,
        lift_m=np.array(lifts),
        gauge_pressure_pa=np.array(pressures),
        dc_gain_m_per_a=np.array(gains),
        time_constants_s=np.array(time_constants),
        beyond_travel=np.array(beyond, dtype=bool),
    )


def default_operating_ranges(p: PneumaticParameters, num_points: int) -> dict[str, OperatingRange]:
    """Both valves over their current ranges, each with the other valve at one end of its range.

    The inlet is swept with the outlet shut; the outlet with the inlet fully open.

    The outlet is swept against the full inlet because that is where it holds the widest range
    of lifts: with the inlet shut (as the split-range allocation drives it) the bladder's leak
    breathes in from the room as fast as the outlet draws air out below atmosphere, so the outlet
    then holds the head at most about 2 mm below zero lift (1.9 mm fully open, with the shipped
    parameters); there it acts in transients.

    Args:
        p: the plant's parameters.
        num_points: currents per valve, at least 2.
    """
    return {
        "inlet": operating_range(p, "inlet", valve_currents_a(p, "inlet", num_points), 0.0),
        "outlet": operating_range(
            p,
            "outlet",
            valve_currents_a(p, "outlet", num_points),
            p.inlet.saturation_current_a,
        ),
    }


def _valve_parameters(p: PneumaticParameters, valve: str):
    if valve not in VALVES:
        raise ValueError(f"valve = {valve!r}: expected 'inlet' or 'outlet'")
    return p.inlet if valve == "inlet" else p.outlet
