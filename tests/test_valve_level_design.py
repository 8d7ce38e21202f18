"""The two-valve level designs: ranges, split, seed, the targeted levels; no plant truth read.

One test reads the pneumatic plant's steady lift: why the design spreads a valve's levels over
its whole interval, checked on the plant the benchmark measures it on.
"""

import numpy as np
import pytest
import scipy.optimize

from maskless.analysis.identification.settled_curve import basis_grid
from maskless.systems.control.excitation import random_holds
from maskless.systems.control.valve_level_design import (
    MIN_TURN_SHARE,
    _gap_filling,
    _interleaved,
    _least_respected,
    _width_share,
    random_level_currents,
    targeted_level_currents,
)
from maskless.systems.plant.pneumatic_physics import LIFT
from maskless.systems.plant.pneumatic_plant import equilibrium_state, load_pneumatic_parameters

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


INTERVALS = ((0.055, 0.075), (0.030, 0.110))


def _targeted(seed=0, samples=8000, hold_s=6.0):
    return targeted_level_currents(samples, TS, TOPS, INTERVALS, hold_s, seed)


def _holds(currents, valve):
    """(first sample, level) of each hold of ``valve`` in a targeted stretch of 60-sample holds.

    A hold's first sample is its approach: the top current (from above), shut or the level
    itself (from below); its level is its last sample.
    """
    firsts = np.arange(0, currents.shape[1] - 59, 60)
    mine = firsts[currents[valve, firsts + 59] > 0.0]
    return mine, currents[valve, mine + 59]


def test_the_start_placed_worse_gets_more_of_the_holds_inside_the_intervals():
    assert _width_share(np.array(INTERVALS), np.array(TOPS)) == MIN_TURN_SHARE
    equal = np.array([[0.05, 0.07], [0.04, 0.06]])
    assert _width_share(equal, np.array([0.2, 0.2])) == pytest.approx(0.5)
    wide = np.array([[0.05, 0.08], [0.04, 0.05]])
    assert _width_share(wide, np.array([0.2, 0.2])) == pytest.approx(0.75)
    assert _width_share(np.array([[0.05, 0.05], [0.04, 0.04]]), np.array(TOPS)) == 0.5
    for share in (0.5, 0.25, 0.8):
        turns = _interleaved(40, share)
        # Every prefix stays within one hold of its share.
        behind = np.cumsum(turns == 0) - share * np.arange(1, 41)
        assert np.all(np.abs(behind) <= 1.0)


def test_targeted_levels_spread_each_valve_over_its_interval_approached_from_both_sides():
    currents = _targeted(samples=120 * 60)  # whole holds only
    assert not np.any((currents[0] > 0.0) & (currents[1] > 0.0))
    counts = []
    for valve, ((low, high), top) in enumerate(zip(INTERVALS, TOPS, strict=True)):
        firsts, levels = _holds(currents, valve)
        counts.append(levels.size)
        assert np.all((levels >= low) & (levels <= high))
        # As many equal parts of the interval as levels, one level in each.
        parts = np.floor((levels - low) / (high - low) * levels.size).astype(int)
        np.testing.assert_array_equal(np.sort(parts), np.arange(levels.size))
        from_above = currents[valve, firsts] == top
        assert np.all(from_above[1:] != from_above[:-1])
        # From below, the valve was shut before the level: at the hold's first sample or before.
        below = firsts[~from_above]
        shut_first = currents[valve, below] == 0.0
        assert np.all(shut_first | (currents[valve, np.maximum(below - 1, 0)] == 0.0))
    # The outlet's interval is wider: it gets four holds to the inlet's one.
    assert counts[0] == pytest.approx(MIN_TURN_SHARE * sum(counts), abs=1)


def _best_curve_with_start(currents_ma, lifts_mm, start_ma):
    """The settled curves' family fitted with its start fixed: a function of the current (mA).

    The family is rest plus monotone Bernstein steps (``settled_curve``); the saturation is
    searched over a 0.5 mA grid.
    """
    best = None
    for saturation in np.arange(150.0, 200.0, 0.5):
        steps = basis_grid(currents_ma, np.array([start_ma]), np.array([saturation]))[0]
        columns = np.column_stack([np.ones_like(currents_ma), steps])
        coefficients, norm = scipy.optimize.nnls(columns, lifts_mm)
        if best is None or norm < best[0]:
            best = norm, saturation, coefficients
    _, saturation, coefficients = best

    def curve(currents):
        steps = basis_grid(currents, np.array([start_ma]), np.array([saturation]))[0]
        return coefficients[0] + steps @ coefficients[1:]

    return curve


def test_on_the_pneumatic_plant_rival_starts_curves_part_most_at_the_higher_start():
    # The plant's noise-free steady lift with the outlet shut, at a random part's inlet levels.
    parameters = load_pneumatic_parameters()
    rest = equilibrium_state(parameters, 0.0, 0.0)[LIFT]
    levels = np.array([0, 0, 0, 0, 0, 7, 20, 33, 45, 53, 80, 101, 110, 128, 146, 163, 178.0])
    lifts = np.array([equilibrium_state(parameters, c / 1e3, 0.0)[LIFT] - rest for c in levels])
    plant = _best_curve_with_start(levels, 1e3 * lifts, 60.0)  # the plant's start
    grid = np.arange(50.0, 100.5, 0.5)
    for rival in (70.0, 80.0):
        difference = np.abs(_best_curve_with_start(levels, 1e3 * lifts, rival)(grid) - plant(grid))
        # Largest within 5 mA of the rival's start; at the plant's start a third of that at most.
        # So each start an interval holds is told from those below it by a level at itself: the
        # design spreads its levels over the whole interval (held about the interval's top
        # instead, the design missed more starts on a plant starting at 80 mA: README).
        assert abs(grid[np.argmax(difference)] - rival) <= 5.0
        assert difference[grid == 60.0][0] < difference.max() / 3


def test_holds_over_the_rest_of_the_curve_fill_its_widest_gaps():
    lows, tops = np.array([INTERVALS[0][1], INTERVALS[1][1]]), np.array(TOPS)
    # Seen: the inlet at 0.09 and 0.18 A, the outlet at 0.13 and 0.175 A (both tops' eighths
    # seen). The inlet's 0.09-0.18 A gap is 47 % of its range, the outlet's 0.13-0.175 A 25 %:
    # the inlet's is split first, then the outlet's (25 % against the inlet's halves, 24 %).
    settled = ((0.09, 0.18), (0.13, 0.175))
    valves, currents = _gap_filling(settled, lows, tops, 2)
    np.testing.assert_array_equal(valves, [0, 1])
    np.testing.assert_allclose(currents, [0.135, 0.1525])
    # Each hold splits a gap at least as wide as any left after it.
    valves, currents = _gap_filling(settled, lows, tops, 12)
    points = [
        np.sort(np.r_[low, top, seen, currents[valves == v]])
        for v, (low, top, seen) in enumerate(zip(lows, tops, settled, strict=True))
    ]
    widest_left = max(np.diff(p).max() / top for p, top in zip(points, tops, strict=True))
    last = valves[-1]
    neighbours = np.sort(points[last])
    at = np.searchsorted(neighbours, currents[-1])
    assert widest_left <= (neighbours[at + 1] - neighbours[at - 1]) / tops[last] + 1e-12
    # Through the design: the holds above the intervals are those, the other valve shut.
    stretch = targeted_level_currents(1800, TS, TOPS, INTERVALS, 6.0, 0, 0.5, (0.0, 0.15), settled)
    covering = []
    for valve in (0, 1):
        firsts, levels = _holds(stretch, valve)
        # The inlet held at 0.15 A is the outlet's hold inside its interval, not the inlet's.
        above = (levels > lows[valve]) & (levels != (0.15, 0.0)[valve])
        covering += levels[above].tolist()
        for first in firsts[above]:
            np.testing.assert_array_equal(stretch[1 - valve, first + 1 : first + 60], 0.0)
    expected = _gap_filling(settled, lows, tops, len(covering))[1]
    np.testing.assert_allclose(np.sort(covering), np.sort(expected))


def test_a_top_eighth_no_settled_level_reached_is_held_first_in_its_middle():
    lows, tops = np.array([INTERVALS[0][1], INTERVALS[1][1]]), np.array(TOPS)
    # Neither valve's settled levels reach its top eighth (from 0.16625 and 0.1575 A): the
    # first holds go to their middles, the inlet's first, then the gaps below them.
    settled = ((0.09,), (0.13,))
    valves, currents = _gap_filling(settled, lows, tops, 3)
    np.testing.assert_array_equal(valves, [0, 1, 0])
    # The gap left is the inlet's 0.09-0.178 A, 46 % of its range (the outlet's 0.13-0.169 A
    # is 21 %), not 0.09-0.19 A: the hold at the top eighth shows that stretch.
    np.testing.assert_allclose(currents, [0.19 * 15 / 16, 0.18 * 15 / 16, (0.09 + 0.178125) / 2])
    # One hold: the inlet's top only.
    valves, currents = _gap_filling(settled, lows, tops, 1)
    np.testing.assert_array_equal(valves, [0])
    # A settled level in the inlet's top eighth (0.17 A): only the outlet's top is held first.
    valves, currents = _gap_filling(((0.09, 0.17), (0.13,)), lows, tops, 1)
    np.testing.assert_array_equal(valves, [1])
    np.testing.assert_allclose(currents, [0.18 * 15 / 16])
    # Intervals reaching into the top eighths show them too: no top holds, the gaps' middles
    # (the outlet's 0.16-0.18 A is 11 % of its range, the inlet's 0.17-0.19 A 10.5 %).
    valves, currents = _gap_filling(settled, np.array([0.17, 0.16]), tops, 2)
    np.testing.assert_array_equal(valves, [1, 0])
    np.testing.assert_allclose(currents, [0.17, 0.18])
    # Never at the top current itself: a section holding that valve open sits there.
    stretch = targeted_level_currents(1800, TS, TOPS, INTERVALS, 6.0, 0, 0.5, (0.0, 0.19), settled)
    _, inlet_levels = _holds(stretch, 0)
    alone = inlet_levels[inlet_levels != 0.19]
    assert np.any(np.isclose(alone, 0.19 * 15 / 16))


def test_an_interval_reaching_the_top_current_leaves_that_valve_no_gap():
    tops = np.array(TOPS)
    # The inlet's interval reaches its top: the holds go to the outlet's top eighth, then its
    # gaps (0.10 to the top eighth's middle, 0.16875 A).
    valves, currents = _gap_filling(((), ()), np.array([TOPS[0], 0.10]), tops, 2)
    np.testing.assert_array_equal(valves, 1)
    np.testing.assert_allclose(currents, [0.16875, (0.10 + 0.16875) / 2])
    # Neither has a gap: the holds sit at the inlet's top current, the curve's flat end.
    valves, currents = _gap_filling(((), ()), tops, tops, 2)
    np.testing.assert_array_equal(valves, 0)
    np.testing.assert_array_equal(currents, TOPS[0])
    stretch = targeted_level_currents(600, TS, TOPS, ((0.05, TOPS[0]), (0.03, 0.1)), 6.0, 0, 0.5)
    assert stretch.shape == (2, 600)


def test_a_valve_held_with_the_other_open_is_covered_from_its_intervals_lowest_start():
    # The outlet's interval spans 0.05-0.17 A, and its holds inside keep the inlet open at
    # 0.19 A: sections, none a level of its curve alone.
    intervals, others = ((0.06, 0.10), (0.05, 0.17)), (0.0, 0.19)
    settled = ((0.12, 0.15, 0.175), ())
    tops = np.array(TOPS)

    def alone_outlet_levels(cover_under_sections):
        stretch = targeted_level_currents(
            3000, TS, TOPS, intervals, 6.0, 0, 0.4, others, settled, (0, 0), cover_under_sections
        )
        firsts, levels = _holds(stretch, 1)
        alone = [np.all(stretch[0, first + 1 : first + 60] == 0.0) for first in firsts]
        return np.sort(levels[alone])

    # 50 holds, 20 over the curves. Counted from the interval's top, the outlet's curve has no
    # gap but 0.17-0.18 A, and it gets one hold there; the other 19 go to the inlet.
    valves, currents = _gap_filling(settled, np.array([0.10, 0.17]), tops, 20)
    np.testing.assert_allclose(alone_outlet_levels(False), currents[valves == 1])
    assert np.sum(valves == 1) == 1 and currents[valves == 1][0] > 0.17
    # From the interval's lowest start its 0.05-0.18 A is the widest gap (72 % of its range):
    # 16 of the 20 go to the outlet, all below the interval's top, with the inlet shut.
    valves, currents = _gap_filling(settled, np.array([0.10, 0.05]), tops, 20)
    np.testing.assert_allclose(alone_outlet_levels(True), np.sort(currents[valves == 1]))
    assert np.sum(valves == 1) == 16 and np.all(currents[valves == 1] < 0.17)
    # A valve probed with the other shut is covered from its interval's top as before.
    shut = targeted_level_currents(
        3000, TS, TOPS, intervals, 6.0, 0, 0.4, (0.0, 0.0), settled, (0, 0), True
    )
    np.testing.assert_array_equal(
        shut,
        targeted_level_currents(3000, TS, TOPS, intervals, 6.0, 0, 0.4, (0.0, 0.0), settled),
    )


def test_other_valve_currents_hold_the_other_valve_open_and_keep_both_approaches():
    other = 0.15
    currents = targeted_level_currents(8000, TS, TOPS, INTERVALS, 6.0, 0, 0.0, (0.0, other))
    split = _targeted()
    # The inlet is probed as in the split range, the outlet with the inlet held at 0.15 A.
    np.testing.assert_array_equal(currents[1], split[1])
    outlet_holds = split[1] > 0.0
    np.testing.assert_array_equal(currents[0, outlet_holds], other)
    inlet_firsts, inlet_levels = _holds(split, 0)
    inlet_holds = split[0] > 0.0
    inlet_holds[inlet_firsts] = False
    np.testing.assert_array_equal(currents[0, inlet_holds], split[0, inlet_holds])
    # A hold approached from below now starts shut, since the inlet was open before it.
    from_below = split[0, inlet_firsts] == inlet_levels
    assert np.all(currents[0, inlet_firsts[from_below]] == 0.0)
    assert np.all(currents[0, inlet_firsts[~from_below]] == TOPS[0])


def test_holds_over_the_rest_of_the_curve_keep_the_other_valve_shut():
    currents = targeted_level_currents(8000, TS, TOPS, INTERVALS, 6.0, 0, 0.5, (0.0, 0.15))
    firsts, levels = _holds(currents, 1)
    high = INTERVALS[1][1]
    for first, level in zip(firsts, levels, strict=True):
        inlet = currents[0, first + 1 : first + 60]
        # Inside the interval the inlet is held open; over the rest of the curve it is shut.
        np.testing.assert_array_equal(inlet, 0.15 if level <= high else 0.0)


def test_a_valve_keeps_the_least_holds_asked_for_though_the_other_interval_is_wider():
    # INTERVALS: the outlet's is four times the inlet's (as fractions), so the inlet would get
    # MIN_TURN_SHARE of 133 holds inside; asked for 60, it gets them, and 5 levels (a round's
    # share of a section) of a 9-hold stretch when the outlet's interval is far the wider.
    assert _width_share(np.array(INTERVALS), np.array(TOPS)) == MIN_TURN_SHARE
    plain = _targeted()
    asked = targeted_level_currents(8000, TS, TOPS, INTERVALS, 6.0, 0, least_inside=(60, 0))
    assert len(_holds(plain, 0)[0]) == round(MIN_TURN_SHARE * 8000 / 60)
    assert len(_holds(asked, 0)[0]) == 60
    short = targeted_level_currents(540, TS, TOPS, INTERVALS, 6.0, 0, least_inside=(5, 0))
    assert len(_holds(short, 0)[0]) == 5
    # Already given more than asked: the design is the one without the ask, bit for bit.
    np.testing.assert_array_equal(
        targeted_level_currents(8000, TS, TOPS, INTERVALS, 6.0, 0, least_inside=(0, 20)), plain
    )


@pytest.mark.parametrize(("share", "least", "count"), [(0.8, (0, 3), 7), (0.2, (4, 0), 7)])
def test_least_holds_move_the_share_just_enough(share, least, count):
    moved = _least_respected(share, np.array(least), count)
    turns = _interleaved(count, moved)
    assert np.sum(turns == 0) >= least[0] and np.sum(turns == 1) >= least[1]
    # Asked for more holds than there are: shared in proportion to the asks.
    assert _least_respected(share, np.array([6, 3]), 6) == pytest.approx(6 / 9)


def test_targeted_levels_are_seeded():
    np.testing.assert_array_equal(_targeted(seed=3), _targeted(seed=3))
    assert not np.array_equal(_targeted(seed=3), _targeted(seed=4))


@pytest.mark.parametrize(
    "arguments, message",
    [
        ({"samples": 1}, "samples = 1"),
        ({"start_intervals_a": ((0.07, 0.06), (0.0, 0.1))}, "start_intervals_a"),
        ({"start_intervals_a": ((0.0, 0.2), (0.0, 0.1))}, "start_intervals_a"),
        ({"top_currents_a": (0.19, 0.0)}, "top_currents_a"),
        ({"hold_s": 0.0}, "hold_s must satisfy"),
        ({"coverage_share": 1.5}, "coverage_share = 1.5"),
        ({"other_valve_currents_a": (0.185, 0.0)}, "other_valve_currents_a"),
        ({"other_valve_currents_a": (-0.01, 0.0)}, "other_valve_currents_a"),
        ({"settled_currents_a": ((0.1,),)}, "settled_currents_a"),
        ({"settled_currents_a": (0.1, 0.12)}, "settled_currents_a"),
        ({"least_inside": (1, -1)}, "least_inside"),
        ({"least_inside": (1.5, 0)}, "least_inside"),
        ({"least_inside": (1,)}, "least_inside"),
    ],
)
def test_bad_targeted_arguments_name_the_argument(arguments, message):
    fields = {
        "samples": 100,
        "sample_period_s": TS,
        "top_currents_a": TOPS,
        "start_intervals_a": INTERVALS,
        "hold_s": 2.0,
        "seed": 0,
        **arguments,
    }
    with pytest.raises(ValueError, match=message):
        targeted_level_currents(**fields)


def test_a_stretch_cut_short_ends_inside_an_interval_never_over_the_curves():
    # 11 whole 60-sample holds and a last one of 24 samples, which never settles: a quarter of
    # the 12 holds (3) go over the curves, all among the whole ones.
    samples = 11 * 60 + 24
    settled = ((0.09,), (0.13,))
    stretch = targeted_level_currents(samples, TS, TOPS, INTERVALS, 6.0, 0, 0.25, (0, 0), settled)
    ends = np.minimum(np.arange(60, samples + 60, 60), samples) - 1
    valves = np.argmax(stretch[:, ends] > 0.0, axis=0)
    levels = stretch[valves, ends]
    over = levels > np.array(INTERVALS)[valves, 1]
    assert over.sum() == 3 and not over[-1]
    assert levels[-1] >= np.array(INTERVALS)[valves[-1], 0]


def _hold_table(stretch):
    """(valve, level, from above, the other valve's current) per 60-sample hold of ``stretch``."""
    firsts = np.arange(0, stretch.shape[1], 60)
    last = np.minimum(firsts + 59, stretch.shape[1] - 1)
    # Here only the outlet's holds keep the other valve open: an open outlet is its hold.
    valves = (stretch[1, last] > 0.0).astype(int)
    return np.column_stack(
        [
            valves,
            stretch[valves, last],
            # From above (the hold's first sample at the top current), else from below.
            stretch[valves, firsts] == np.asarray(TOPS)[valves],
            stretch[1 - valves, last],
        ]
    )


# 34 and 33.4 holds leave a hold over the curves last once the section's move to the front.
@pytest.mark.parametrize("samples", [50 * 60, 34 * 60, 33 * 60 + 24])
def test_a_section_block_holds_the_sections_levels_in_one_run_at_the_stretchs_start(samples):
    # The outlet's holds inside its interval keep the inlet open at 0.19 A (a section).
    intervals, others, settled = ((0.06, 0.10), (0.05, 0.17)), (0.0, 0.19), ((0.12,), (0.15,))
    arguments = (samples, TS, TOPS, intervals, 6.0, 0, 0.25, others, settled, (0, 6), True)
    interleaved = _hold_table(targeted_level_currents(*arguments))
    block = _hold_table(targeted_level_currents(*arguments, section_block=True))
    in_section = interleaved[:, 3] == others[1]
    count = int(in_section.sum())
    assert count >= 6 and not np.all(in_section[:count])
    # The same holds, each approached as before; the section's first, in their own order.
    np.testing.assert_array_equal(block[:count], interleaved[in_section])
    assert np.all(block[count:, 3] != others[1])
    np.testing.assert_array_equal(
        np.sort(block[count:], axis=0), np.sort(interleaved[~in_section], axis=0)
    )
    # The stretch's last hold, cut short where the stretch is not whole holds, is inside an
    # interval, never over the curves' rest: the inlet's inside holds are those within its
    # interval, the outlet's those with the inlet open.
    valve, level, _, other = block[-1]
    assert (valve == 0 and level <= intervals[0][1]) or (valve == 1 and other == others[1])


def test_without_a_section_a_section_block_changes_nothing():
    arguments = (8000, TS, TOPS, INTERVALS, 6.0, 0, 0.25, (0.0, 0.0), ((0.09,), (0.13,)))
    np.testing.assert_array_equal(
        targeted_level_currents(*arguments, section_block=True),
        targeted_level_currents(*arguments),
    )
