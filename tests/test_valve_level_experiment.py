"""The two-valve random-level design: its ranges, its split, its seed."""

import numpy as np
import pytest

from maskless.diagrams.valve_level_experiment import random_level_currents

TS = 0.1
TOPS, STARTS = (0.19, 0.18), (0.06, 0.05)


def _levels(arrangement="split_range", seed=0, samples=20000):
    return random_level_currents(samples, TS, TOPS, STARTS, (1.0, 10.0), seed, arrangement)


def test_levels_span_each_valve_and_are_held_within_the_hold_range():
    currents = _levels()
    for row, top in zip(currents, TOPS, strict=True):
        assert 0.0 <= row.min() < 0.01 and top - 0.01 < row.max() <= top
    changes = np.flatnonzero(np.any(np.diff(currents, axis=1) != 0, axis=0)) + 1
    holds = np.diff(changes) * TS
    assert holds.min() >= 1.0 - TS / 2 and holds.max() <= 10.0 + TS / 2


def test_split_range_never_opens_both_valves_and_sometimes_neither():
    currents = _levels()
    inlet_open, outlet_open = (row >= start for row, start in zip(currents, STARTS, strict=True))
    assert not np.any(inlet_open & outlet_open)
    assert np.mean(~inlet_open & ~outlet_open) > 0.3  # neither driven, and the rest below start
    independent = _levels("independent")
    opened = (independent[0] >= STARTS[0]) & (independent[1] >= STARTS[1])
    assert np.mean(opened) > 0.3


def test_the_same_seed_gives_the_same_levels_and_another_seed_others():
    np.testing.assert_array_equal(_levels(seed=3), _levels(seed=3))
    assert not np.array_equal(_levels(seed=3), _levels(seed=4))


@pytest.mark.parametrize(
    "arguments, message",
    [
        ({"arrangement": "both"}, "arrangement = 'both'"),
        ({"samples": 1}, "samples = 1"),
        ({"hold_range_s": (2.0, 1.0)}, "hold_range_s"),
        ({"starting_currents_a": (0.2, 0.05)}, "starting_currents_a"),
    ],
)
def test_bad_arguments_are_one_line_naming_the_argument(arguments, message):
    fields = {
        "samples": 100,
        "sample_period_s": TS,
        "top_currents_a": TOPS,
        "starting_currents_a": STARTS,
        "hold_range_s": (1.0, 10.0),
        "seed": 0,
        **arguments,
    }
    with pytest.raises(ValueError, match=message):
        random_level_currents(**fields)
