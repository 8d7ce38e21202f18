"""The two-valve random-level design: its ranges, its split, its seed; no plant truth read."""

import numpy as np
import pytest

from maskless.diagrams.valve_level_experiment import random_level_currents
from maskless.systems.control.excitation import random_holds

TS = 0.1
TOPS = (0.19, 0.18)


def _levels(arrangement="split_range", seed=0, samples=20000):
    return random_level_currents(samples, TS, TOPS, (1.0, 10.0), seed, arrangement)


def test_levels_span_each_valve_and_are_held_within_the_hold_range():
    currents = _levels()
    for row, top in zip(currents, TOPS, strict=True):
        assert 0.0 <= row.min() < 0.01 and top - 0.01 < row.max() <= top
    # Split-range holds that drive neither valve join up; independent levels always change.
    independent = _levels("independent")
    changes = np.flatnonzero(np.any(np.diff(independent, axis=1) != 0, axis=0)) + 1
    holds = np.diff(changes) * TS
    assert holds.min() >= 1.0 - TS / 2 and holds.max() <= 10.0 + TS / 2


def test_split_range_drives_one_valve_at_a_time_and_shuts_the_other():
    currents = _levels()
    # The design knows no starting current: the idle valve is shut (0 A), below any.
    assert not np.any((currents[0] > 0.0) & (currents[1] > 0.0))
    neither = np.mean((currents[0] == 0.0) & (currents[1] == 0.0))
    assert 0.25 < neither < 0.42  # a third of the holds drive neither
    # The driven valve's levels are uniform over its whole range, onset region included.
    for row, top in zip(currents, TOPS, strict=True):
        driven = row[row > 0.0]
        assert np.mean(driven < top / 2) == pytest.approx(0.5, abs=0.08)
    independent = _levels("independent")
    assert np.mean((independent[0] > 0.06) & (independent[1] > 0.06)) > 0.3


@pytest.mark.parametrize("arrangement", ["split_range", "independent"])
def test_each_block_of_eight_levels_visits_every_eighth_of_the_range(arrangement):
    currents = _levels(arrangement)
    for row, top in zip(currents, TOPS, strict=True):
        starts = np.flatnonzero(np.diff(np.r_[-1.0, row]) != 0.0)
        driven = row[starts][row[starts] > 0.0]
        eighths = np.floor(driven / top * 8).astype(int)
        blocks = eighths[: eighths.size // 8 * 8].reshape(-1, 8)
        assert blocks.shape[0] >= 10
        for block in blocks:
            np.testing.assert_array_equal(np.sort(block), np.arange(8))


def test_holds_are_drawn_as_the_multilevel_design_draws_them():
    # One generator: the holds first (excitation.random_holds), then the levels.
    # Independent levels are continuous, so every hold ends in a change of both currents.
    holds = random_holds(np.random.default_rng(7), 20000, (1.0, 10.0), TS)
    currents = _levels("independent", seed=7)
    changes = np.flatnonzero(np.any(np.diff(currents, axis=1) != 0, axis=0)) + 1
    np.testing.assert_array_equal(np.diff(np.r_[0, changes]), holds[: changes.size])


def test_the_same_seed_gives_the_same_levels_and_another_seed_others():
    np.testing.assert_array_equal(_levels(seed=3), _levels(seed=3))
    assert not np.array_equal(_levels(seed=3), _levels(seed=4))


@pytest.mark.parametrize(
    "arguments, message",
    [
        ({"arrangement": "both"}, "arrangement = 'both'"),
        ({"samples": 1}, "samples = 1"),
        ({"hold_range_s": (2.0, 1.0)}, "hold_s must satisfy"),
        ({"top_currents_a": (0.19, -0.1)}, "top_currents_a"),
    ],
)
def test_bad_arguments_are_one_line_naming_the_argument(arguments, message):
    fields = {
        "samples": 100,
        "sample_period_s": TS,
        "top_currents_a": TOPS,
        "hold_range_s": (1.0, 10.0),
        "seed": 0,
        **arguments,
    }
    with pytest.raises(ValueError, match=message):
        random_level_currents(**fields)
