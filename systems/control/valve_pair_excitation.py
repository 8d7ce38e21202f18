"""Excitation of both valves: a signal per valve, or one signal split between them.

The plant has an inlet valve (supply into the bladder) and an outlet valve (bladder to the vacuum
pump). An identification from both needs both to move, in one of two ways (``VALVE_DRIVES``):

- ``independent``: each valve follows its own signal, clipped to its own [0, saturation] range.
  A multi-input fit tells the valves' effects apart only if the two signals are uncorrelated at
  the lags the model spans: random designs take the outlet's draws from a seed of their own
  (:func:`outlet_seed`), and a PRBS is the inlet's sequence started half its period later
  (``excitation.prbs(half_period_shift=True)``), since a seed would only shift it by a random lag.
- ``split-range``: one command, in inlet-equivalent amperes, drives the valve pair as the
  controller does on an identified model (``valve_allocation.current_split_allocation``): above
  the inlet's starting current the inlet gets the command; below it the outlet opens, from its
  starting current to saturation over one inlet span lower. So the command's part above the split
  opens the inlet and its part below opens the outlet, never both at once, and commands beyond
  either end are clipped to that valve's saturation.

``inlet`` (the outlet shut) is the single-input drive of the paper.

Pure numpy on :class:`excitation.ExcitationSignal`; the run lives in ``diagrams.excitation_run``.
"""

from dataclasses import replace

import numpy as np

from maskless.systems.control.excitation import ExcitationSignal
from maskless.systems.control.valve_allocation import SplitRangeAllocation

VALVE_DRIVES = ("inlet", "independent", "split-range")

# The spawn key of the outlet's child seed: any fixed key gives a stream independent of the run
# seed's own (numpy's SeedSequence hashes both).
_OUTLET_SPAWN_KEY = (1,)


def outlet_seed(seed: int) -> int:
    """The outlet's seed in an ``independent`` drive of run seed ``seed``.

    A ``SeedSequence`` child of the run's seed: its draws are independent of the inlet's (which
    uses ``seed`` itself), and it is not another run's seed plus one.

    Args:
        seed: The run's non-negative integer seed.
    """
    child = np.random.SeedSequence(seed, spawn_key=_OUTLET_SPAWN_KEY)
    return int(child.generate_state(1, dtype=np.uint32)[0])


def split_range_currents(
    command: ExcitationSignal, allocation: SplitRangeAllocation
) -> tuple[ExcitationSignal, ExcitationSignal]:
    """(inlet, outlet) currents (A) a split-range ``command`` asks of the valve pair.

    The allocation is piecewise linear and constant beyond its end knots, which is
    ``np.interp``; beyond the ends each valve stays at its saturation current (clipped).

    Args:
        command: The designed command (A, inlet-equivalent current).
        allocation: The split range, e.g. ``current_split_allocation(inlet, outlet)``.
    """
    knots = allocation.command_knots
    inlet = np.interp(command.values, knots, allocation.inlet_currents_a)
    outlet = np.interp(command.values, knots, allocation.outlet_currents_a)
    return replace(command, values=inlet), replace(command, values=outlet)


def split_range_clipped_fractions(
    command: ExcitationSignal, allocation: SplitRangeAllocation
) -> tuple[float, float]:
    """(inlet, outlet) fractions of the samples of ``command`` clipped at that valve's end.

    The inlet clips above the allocation's last knot, the outlet below its first.

    Args:
        command: The designed command (A, inlet-equivalent current).
        allocation: The split range the command drives.
    """
    low, high = allocation.command_range
    return float(np.mean(command.values > high)), float(np.mean(command.values < low))
