"""What the controller needs to know of the pneumatic plant: its static map and linearisation.

- ``steady_lift_curve`` samples the lift the head settles at for each inlet current (outlet
  shut); ``pneumatic_allocation`` inverts it into the split-range allocation.
- ``linearize_pneumatic_plant`` is Drake's ``Linearize`` of the templated plant at that
  equilibrium, about either valve's current; ``pneumatic_design_model`` discretises it
  (zero-order hold) at the controller period, with the lift command as input: the input the
  allocation gives the controller.

The valve is linearised with its spool moving: inside the play band a valve passes no small change
at all (the hysteresis), which the offset-free controller rejects as a disturbance instead.
"""

from dataclasses import dataclass

import numpy as np
from pydrake.systems.primitives import Linearize
from scipy.linalg import expm

from maskless.systems.control.valve_allocation import (
    SplitRangeAllocation,
    allocation_from_steady_lift,
)
from maskless.systems.linear_model import LinearModel
from maskless.systems.plant.pneumatic_physics import (
    GAUGE_PRESSURE,
    INLET_SPOOL,
    LIFT,
    LIFT_RATE,
    OUTLET_SPOOL,
    PneumaticParameters,
)
from maskless.systems.plant.pneumatic_plant import (
    PneumaticPlant,
    equilibrium_state,
)

# The states each valve's current reaches: the other valve's spool rests inside its play band, so
# it is neither driven nor moving (a mode at zero that no input reaches).
VALVE_STATES = {
    "inlet": (GAUGE_PRESSURE, LIFT, LIFT_RATE, INLET_SPOOL),
    "outlet": (GAUGE_PRESSURE, LIFT, LIFT_RATE, OUTLET_SPOOL),
}
# How far past the edge of the play band the spool sits when linearised: small enough to leave the
# equilibrium (Drake's Linearize checks it), large enough to pick the moving branch of the band.
_SPOOL_MOVING_OFFSET_A = 1e-9


def steady_lift_curve(p: PneumaticParameters, num_points: int = 400):
    """(inlet currents, steady lifts) from the valve's starting to its saturation current."""
    # Lift grows about quadratically with opening: sample densely near the start.
    fractions = np.linspace(0.0, 1.0, num_points) ** 2
    currents = p.inlet.starting_current_a + fractions * p.inlet.current_span_a
    lifts = np.array([equilibrium_state(p, i, 0.0)[LIFT] for i in currents])
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


def linearize_pneumatic_plant(
    p: PneumaticParameters,
    inlet_current_a: float,
    outlet_current_a: float = 0.0,
    valve: str = "inlet",
):
    """Continuous (A, B, C) of the plant at rest with the spools at the given coil currents.

    The input is the coil current of ``valve`` and the output the head height, on the states
    ``VALVE_STATES[valve]``.

    The driven valve's spool is linearised about to open further (its coil a play band's half
    width ahead of it); the other valve's spool rests at the centre of its band.

    Args:
        p: the plant's parameters.
        inlet_current_a: the inlet coil current at rest (A).
        outlet_current_a: the outlet coil current at rest (A); 0 shuts the outlet.
        valve: "inlet" or "outlet", whose coil current is the input.

    Raises:
        ValueError: ``valve`` is neither "inlet" nor "outlet".
    """
    if valve not in VALVE_STATES:
        raise ValueError(f"valve = {valve!r}: expected 'inlet' or 'outlet'")
    state = equilibrium_state(p, inlet_current_a, outlet_current_a)
    coil_currents_a = {"inlet": inlet_current_a, "outlet": outlet_current_a}
    # The coil leads the spool by the play band's half width: the spool is about to move.
    driven = p.inlet if valve == "inlet" else p.outlet
    coil_currents_a[valve] += driven.play_half_width_a + _SPOOL_MOVING_OFFSET_A
    plant = PneumaticPlant(p, state)
    context = plant.CreateDefaultContext()
    for name, current_a in coil_currents_a.items():
        plant.GetInputPort(f"{name}_valve_current_a").FixValue(context, [current_a])
    linear = Linearize(
        plant,
        context,
        input_port_index=plant.GetInputPort(f"{valve}_valve_current_a").get_index(),
        output_port_index=plant.GetOutputPort("head_height_m").get_index(),
    )
    keep = list(VALVE_STATES[valve])
    return linear.A()[np.ix_(keep, keep)], linear.B()[keep, :], linear.C()[:, keep]


def zero_order_hold(A, B, sample_period_s: float):
    """Exact discretisation of x' = A x + B u with u held over each period."""
    n, m = B.shape
    block = np.zeros((n + m, n + m))
    block[:n, :n], block[:n, n:] = A, B
    discrete = expm(block * sample_period_s)
    return discrete[:n, :n], discrete[:n, n:]


@dataclass(frozen=True)
class AllocationPoint:
    """Where a split-range allocation puts the valves for one command.

    Attributes:
        valve: "inlet" or "outlet", the valve the command moves there (one at a time).
        inlet_current_a, outlet_current_a: the two coil currents (A).
        amps_per_command: the moving valve's current per unit command there (A/m for a lift
            command), negative for the outlet (a higher command shuts it).
    """

    valve: str
    inlet_current_a: float
    outlet_current_a: float
    amps_per_command: float


def allocation_point(allocation: SplitRangeAllocation, command: float) -> AllocationPoint:
    """The currents at ``command`` and the slope of the segment it lies on.

    At a knot, the segment is the one below.
    """
    knots = allocation.command_knots
    segment = int(np.clip(np.searchsorted(knots, command) - 1, 0, len(knots) - 2))
    inlet, outlet = allocation.inlet_currents_a, allocation.outlet_currents_a
    # Split range: the inlet moves on its segments; where it does not, the outlet does.
    valve = "inlet" if inlet[segment + 1] != inlet[segment] else "outlet"
    moving = inlet if valve == "inlet" else outlet
    slope = (moving[segment + 1] - moving[segment]) / (knots[segment + 1] - knots[segment])
    inlet_a, outlet_a = allocation.currents(command)
    return AllocationPoint(
        valve=valve,
        inlet_current_a=float(inlet_a),
        outlet_current_a=float(outlet_a),
        amps_per_command=float(slope),
    )


def pneumatic_design_model(
    p: PneumaticParameters,
    allocation: SplitRangeAllocation,
    operating_lift_m: float,
    sample_period_s: float,
) -> LinearModel:
    """The plant linearised at ``operating_lift_m`` and discretised, with the lift command as input.

    The input column is the moving valve's current column (the inlet's over its range, the
    outlet's below it) scaled by the allocation's current per metre there.

    Args:
        p: the plant's parameters (the nominal head, whose steady lift the allocation inverts).
        allocation: the split-range allocation from the lift command to the valve currents.
        operating_lift_m: the lift command the model is linearised at (m); the nominal head rests
            at this lift.
        sample_period_s: the controller's period (s).

    Returns:
        The model from the lift command (m) to the head height (m), operating at that command
        and the height the head rests at there.
    """
    point = allocation_point(allocation, operating_lift_m)
    A, B, C = linearize_pneumatic_plant(
        p, point.inlet_current_a, point.outlet_current_a, point.valve
    )
    Ad, Bd = zero_order_hold(A, B * point.amps_per_command, sample_period_s)
    return LinearModel(
        A=Ad,
        B=Bd,
        C=C,
        D=np.zeros((1, 1)),
        sample_period_s=sample_period_s,
        operating_input=operating_lift_m,
        operating_output=p.rest_head_height_m + operating_lift_m,
        input_unit="m",
        output_unit="m",
    )
