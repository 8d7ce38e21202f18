"""What the controller needs to know of the pneumatic plant: its static map and linearisation.

- ``steady_lift_curve`` samples the lift the head settles at for each inlet current (outlet
  shut); ``pneumatic_allocation`` inverts it into the split-range allocation.
- ``linearize_pneumatic_plant`` is Drake's ``Linearize`` of the templated plant at that
  equilibrium; ``pneumatic_design_model`` discretises it (zero-order hold) at the controller
  period, with the lift command as input: the input the allocation gives the controller.

The valve is linearised with its spool moving: inside the play band a valve passes no small change
at all (the hysteresis), which the offset-free controller rejects as a disturbance instead.
"""

import numpy as np
from pydrake.systems.primitives import Linearize
from scipy.linalg import expm

from maskless.systems.offset_free_lqg import LinearDesignModel
from maskless.systems.pneumatic_physics import (
    GAUGE_PRESSURE,
    INLET_SPOOL,
    LIFT,
    LIFT_RATE,
    PneumaticParameters,
    valve_opening,
)
from maskless.systems.pneumatic_plant import (
    PneumaticPlant,
    equilibrium_state,
    steady_gauge_pressure_pa,
    steady_lift_m,
)
from maskless.systems.valve_allocation import SplitRangeAllocation, allocation_from_steady_lift

# States the inlet current reaches; the outlet spool, shut at rest, is neither driven nor seen.
DESIGN_STATES = (GAUGE_PRESSURE, LIFT, LIFT_RATE, INLET_SPOOL)
# How far past the edge of the play band the spool sits when linearised: small enough to leave the
# equilibrium (Drake's Linearize checks it), large enough to pick the moving branch of the band.
_SPOOL_MOVING_OFFSET_A = 1e-9


def steady_lift_curve(p: PneumaticParameters, num_points: int = 400):
    """(inlet currents, steady lifts) from the valve's starting to its saturation current."""
    # Lift grows about quadratically with opening: sample densely near the start.
    fractions = np.linspace(0.0, 1.0, num_points) ** 2
    currents = p.inlet.starting_current_a + fractions * p.inlet.current_span_a
    lifts = np.array(
        [
            steady_lift_m(p, steady_gauge_pressure_pa(p, valve_opening(i, p.inlet), 0.0))
            for i in currents
        ]
    )
    return currents, lifts


def pneumatic_allocation(
    p: PneumaticParameters, outlet_full_open_below_m: float
) -> SplitRangeAllocation:
    """The Hammerstein inverse of the plant's static map, with the outlet below it."""
    currents, lifts = steady_lift_curve(p)
    keep = np.concatenate([[True], np.diff(lifts) > 0])
    return allocation_from_steady_lift(
        currents[keep],
        lifts[keep],
        p.outlet.starting_current_a,
        p.outlet.saturation_current_a,
        outlet_full_open_below_m,
    )


def linearize_pneumatic_plant(p: PneumaticParameters, inlet_current_a: float):
    """Continuous (A, B, C) of the plant at rest with the inlet spool at ``inlet_current_a``
    (outlet shut), with input the inlet coil current and output the head height, on the states
    ``DESIGN_STATES``."""
    state = equilibrium_state(p, inlet_current_a, 0.0)
    # The coil leads the spool by the play band's half width: the spool is about to move.
    coil_current_a = inlet_current_a + p.inlet.play_half_width_a + _SPOOL_MOVING_OFFSET_A
    plant = PneumaticPlant(p, state)
    context = plant.CreateDefaultContext()
    plant.GetInputPort("inlet_valve_current_a").FixValue(context, [coil_current_a])
    plant.GetInputPort("outlet_valve_current_a").FixValue(context, [0.0])
    linear = Linearize(
        plant,
        context,
        input_port_index=plant.GetInputPort("inlet_valve_current_a").get_index(),
        output_port_index=plant.GetOutputPort("head_height_m").get_index(),
    )
    keep = list(DESIGN_STATES)
    return linear.A()[np.ix_(keep, keep)], linear.B()[keep, :], linear.C()[:, keep]


def zero_order_hold(A, B, sample_period_s: float):
    """Exact discretisation of x' = A x + B u with u held over each period."""
    n, m = B.shape
    block = np.zeros((n + m, n + m))
    block[:n, :n], block[:n, n:] = A, B
    discrete = expm(block * sample_period_s)
    return discrete[:n, :n], discrete[:n, n:]


def pneumatic_design_model(
    p: PneumaticParameters,
    allocation: SplitRangeAllocation,
    operating_lift_m: float,
    sample_period_s: float,
) -> LinearDesignModel:
    """The plant linearised at ``operating_lift_m`` and discretised, with the lift command as
    input: the inlet current's column scaled by the allocation's current per metre there."""
    knots, inlet = allocation.command_knots, allocation.inlet_currents_a
    current = float(np.interp(operating_lift_m, knots, inlet))
    segment = int(np.clip(np.searchsorted(knots, operating_lift_m) - 1, 0, len(knots) - 2))
    amps_per_m = (inlet[segment + 1] - inlet[segment]) / (knots[segment + 1] - knots[segment])
    A, B, C = linearize_pneumatic_plant(p, current)
    Ad, Bd = zero_order_hold(A, B * amps_per_m, sample_period_s)
    return LinearDesignModel(
        A=Ad,
        B=Bd,
        C=C,
        sample_period_s=sample_period_s,
        input_operating_point=operating_lift_m,
        output_operating_point_m=p.rest_head_height_m + operating_lift_m,
    )
