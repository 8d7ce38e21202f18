"""Split-range allocation: one lift command to the inlet and outlet valve currents.

The controller commands a *lift* w (m): the lift the plant would settle at if the command were
held. ``SplitRangeAllocation`` turns it into two coil currents through the inverse of the plant's
static map (the Hammerstein inverse the paper proposes in Sec. VI): above the lift the bladder holds
with both valves closed, the inlet opens along the inverted steady-lift curve, skipping the valve's
dead band below its starting current; below it, the inlet shuts and the outlet opens to the vacuum
pump. Because the inverse cancels the static nonlinearity, the controller sees a plant whose steady
gain from w to lift is one at every operating point.

The map is piecewise linear in w with knots from a design function, written with min and max only,
so it runs on floats and inside a SymbolicVectorSystem.
"""

from dataclasses import dataclass

import numpy as np
import pydrake.math as dm

from maskless.errors import ModelError


@dataclass(frozen=True)
class SplitRangeAllocation:
    """A monotone piecewise-linear map from a command to (inlet, outlet) currents (A).

    The command is in the units of the controller's design model input: a lift (m) for the
    pneumatic plant's Hammerstein inverse, an inlet-equivalent current (A) for identified models.

    Attributes:
        command_knots: increasing commands; commands outside are clipped to the end knots.
        inlet_currents_a: the inlet current at each knot.
        outlet_currents_a: the outlet current at each knot.
    """

    command_knots: np.ndarray
    inlet_currents_a: np.ndarray
    outlet_currents_a: np.ndarray

    def __post_init__(self):
        """Raises ValueError unless the knots increase, with a finite current per valve at each."""
        knots = np.asarray(self.command_knots, dtype=float)
        if knots.ndim != 1 or knots.size < 2 or not np.all(np.diff(knots) > 0):
            raise ValueError(f"command_knots = {knots}: expected >= 2 increasing lifts")
        for name in ("inlet_currents_a", "outlet_currents_a"):
            values = np.asarray(getattr(self, name), dtype=float)
            if values.shape != knots.shape or not np.all(np.isfinite(values)):
                raise ValueError(f"{name}: expected {knots.size} finite currents, got {values}")

    @property
    def command_range(self) -> tuple[float, float]:
        """The commands the valves can realise; the controller saturates its command here."""
        return float(self.command_knots[0]), float(self.command_knots[-1])

    def currents(self, command):
        """(inlet, outlet) currents (A) for a command (float or symbolic)."""
        return (
            _piecewise_linear(command, self.command_knots, self.inlet_currents_a),
            _piecewise_linear(command, self.command_knots, self.outlet_currents_a),
        )


def _piecewise_linear(x, knots, values):
    """Linear interpolation through (knots, values), constant beyond the ends.

    Written as a sum of clamped ramps: min and max only, so it also builds a symbolic expression.
    """
    result = float(values[0])
    for k in range(len(knots) - 1):
        slope = (values[k + 1] - values[k]) / (knots[k + 1] - knots[k])
        if slope != 0.0:
            segment = dm.min(dm.max(x, float(knots[k])), float(knots[k + 1])) - float(knots[k])
            result = result + float(slope) * segment
    return result


def allocation_from_steady_lift(
    inlet_currents_a,
    steady_lifts_m,
    outlet_starting_current_a: float,
    outlet_saturation_current_a: float,
    outlet_full_open_below_m: float,
    num_knots: int = 12,
) -> SplitRangeAllocation:
    """An allocation from a sampled steady-lift curve of the inlet (outlet closed).

    Args:
        inlet_currents_a: increasing inlet currents, from the valve's starting current up.
        steady_lifts_m: the lift the plant settles at for each (increasing with current).
        outlet_starting_current_a: the outlet valve's starting current, where its span begins (A).
        outlet_saturation_current_a: the outlet valve's saturation current, where its span
            ends (A).
        outlet_full_open_below_m: how far below the lowest steady lift the command must go for
            the outlet to open fully; transients only, since nothing holds a lift there.
        num_knots: knots spread evenly in lift over the inlet's curve.
    """
    currents = np.asarray(inlet_currents_a, dtype=float)
    lifts = np.asarray(steady_lifts_m, dtype=float)
    if currents.shape != lifts.shape or not np.all(np.diff(lifts) > 0):
        raise ValueError("steady_lifts_m: expected one lift per current, increasing with current")
    if not outlet_full_open_below_m > 0:
        raise ValueError(f"outlet_full_open_below_m = {outlet_full_open_below_m}: expected > 0")
    inlet_lifts = np.linspace(lifts[0], lifts[-1], num_knots)
    return _split_range(
        inlet_lifts,
        np.interp(inlet_lifts, lifts, currents),
        lifts[0] - outlet_full_open_below_m,
        outlet_starting_current_a,
        outlet_saturation_current_a,
    )


def _split_range(
    inlet_commands,
    inlet_currents,
    outlet_fully_open_command: float,
    outlet_starting_current_a: float,
    outlet_saturation_current_a: float,
) -> SplitRangeAllocation:
    """The allocation both designs share: the inlet above its first command, the outlet below.

    The inlet serves ``inlet_commands`` (from its starting current up); below the first of them
    the outlet ramps from its starting current to fully open at ``outlet_fully_open_command``. At
    the first inlet command the currents jump both valves' dead bands (a knot a hair above keeps
    the map a function).
    """
    epsilon = 1e-6 * (inlet_commands[-1] - inlet_commands[0])
    tail = len(inlet_commands) - 1
    return SplitRangeAllocation(
        command_knots=np.concatenate(
            [
                [outlet_fully_open_command, inlet_commands[0], inlet_commands[0] + epsilon],
                inlet_commands[1:],
            ]
        ),
        inlet_currents_a=np.concatenate([[0.0, 0.0, inlet_currents[0]], inlet_currents[1:]]),
        outlet_currents_a=np.concatenate(
            [[outlet_saturation_current_a, outlet_starting_current_a, 0.0], np.zeros(tail)]
        ),
    )


def current_split_allocation(inlet, outlet) -> SplitRangeAllocation:
    """The split range for a model whose input is the inlet current (an identified model).

    Commands from the inlet's starting to its saturation current go to the inlet unchanged;
    commands below its starting current, down to one current span lower, open the outlet from
    its starting to its saturation current instead. Both valves' dead bands are skipped, which
    is the inverse of their static map.

    Args:
        inlet: the inlet valve (``pneumatic_physics.ValveParameters``).
        outlet: the outlet valve (``pneumatic_physics.ValveParameters``).
    """
    inlet_range = np.array([inlet.starting_current_a, inlet.saturation_current_a])
    return _split_range(
        inlet_range,
        inlet_range,
        inlet.starting_current_a - inlet.current_span_a,
        outlet.starting_current_a,
        outlet.saturation_current_a,
    )


def static_curve_inverse(model) -> SplitRangeAllocation:
    """The split range for a Hammerstein model: the inverse of its valves' static curves.

    The command is the steady output change from every valve shut (the model's output unit): a
    positive one opens the inlet to the current whose static curve (map times DC gain) gives it,
    a negative one the outlet; both valves' dead bands are skipped. The controller then sees the
    linear part with a unit DC gain (``HammersteinModel.valve_linear_model(0)``). The maps are
    piecewise linear, so the inverse is exact: the curves' knots with the axes swapped.

    Args:
        model: a ``hammerstein_model.HammersteinModel`` with an inlet map, and an outlet map
            when it has two inputs.

    Raises:
        ModelError: the inlet does not raise the output, or the outlet does not lower it.
    """
    gains = model.dc_gains()
    if not gains[0] > 0 or (model.inputs > 1 and not gains[1] < 0):
        raise ModelError(
            f"static gains {gains.tolist()}: expected the inlet to raise the output (> 0) and the "
            "outlet to lower it (< 0), as a split range needs"
        )
    epsilon = 1e-6 * float(np.sum(np.abs(gains)))
    inlet_commands, inlet_currents = _strictly_increasing(
        gains[0] * model.maps[0].openings, model.maps[0].currents, epsilon
    )
    knots, inlet, outlet = [inlet_commands], [inlet_currents], [np.zeros(inlet_commands.size)]
    if model.inputs > 1:
        outlet_commands, outlet_currents = _strictly_increasing(
            -gains[1] * model.maps[1].openings, model.maps[1].currents, epsilon
        )
        # The outlet's commands are negative, largest current first.
        outlet_commands, outlet_currents = -outlet_commands[::-1], outlet_currents[::-1]
        # At command 0 the outlet sits at its starting current; a hair above, the inlet at its own.
        inlet_commands = inlet_commands.copy()
        inlet_commands[0] += epsilon
        knots = [outlet_commands, inlet_commands]
        inlet = [np.zeros(outlet_commands.size), inlet_currents]
        outlet = [outlet_currents, np.zeros(inlet_commands.size)]
    return SplitRangeAllocation(
        np.concatenate(knots), np.concatenate(inlet), np.concatenate(outlet)
    )


def _strictly_increasing(commands, currents, epsilon):
    """(commands, currents) sorted, a run of equal commands kept as its first and last knot.

    A run of equal commands is a flat stretch of the map: the command gets the run's smallest
    current, and ``epsilon`` above it the run's largest, where the map rises again (a knot a hair
    above keeps the allocation a function).
    """
    order = np.lexsort((currents, commands))
    commands, currents = commands[order], currents[order].copy()
    new_run = np.concatenate([[True], np.diff(commands) > 0])
    run_end = np.concatenate([new_run[1:], [True]])
    kept = new_run | run_end
    commands = np.where(run_end & ~new_run, commands + epsilon, commands)
    return commands[kept], currents[kept]
