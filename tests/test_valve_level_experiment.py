"""The sequential valve-level experiment: each round designed from the record before it only."""

import numpy as np
import pytest

from maskless.analysis.identification.section_start import MIN_SECTION_LEVELS
from maskless.diagrams.scenario import load_scenario
from maskless.diagrams.valve_level_experiment import (
    designable_intervals,
    run_sequential_experiment,
    tops_seen_by_long_holds,
)
from maskless.systems.control.valve_level_design import (
    _gap_filling,
    random_level_currents,
    targeted_level_currents,
)
from tests.test_valve_level_design import INTERVALS, TOPS, TS


def test_a_sequential_design_reads_only_the_record_before_each_round():
    config = load_scenario()
    period_s = config.offset_free_lqg.sample_period_s
    planned = random_level_currents(900, period_s, TOPS, (2.0, 6.0), 1)
    seen = []

    def reading_of(u, y):
        seen.append((u.copy(), y.copy()))
        # The currents each valve's settled holds showed its curve at: here, one made up.
        return INTERVALS, ((0.1 + 0.01 * len(seen),), ())

    applied, fused, _, intervals = run_sequential_experiment(
        config,
        planned,
        period_s,
        TOPS,
        (300, 700),
        reading_of,
        4.0,
        0,
        rounds=2,
        coverage_share=0.5,
    )
    # Each round saw the final record up to its part, and nothing after.
    assert [u.shape[0] for u, _ in seen] == [300, 500]
    for u, y in seen:
        np.testing.assert_array_equal(u, applied[:, : u.shape[0]].T)
        np.testing.assert_array_equal(y, fused[: y.size])
    # Outside the stretch the planned currents run; inside, targeted levels from each round.
    np.testing.assert_array_equal(applied[:, :300], planned[:, :300])
    np.testing.assert_array_equal(applied[:, 700:], planned[:, 700:])
    for begin, stop, seed in ((300, 500, 0), (500, 700, 1)):
        settled = ((0.1 + 0.01 * (seed + 1),), ())
        expected = targeted_level_currents(
            stop - begin, period_s, TOPS, INTERVALS, 4.0, seed, 0.5, (0.0, 0.0), settled
        )
        np.testing.assert_array_equal(applied[:, begin:stop], expected)
    np.testing.assert_array_equal(intervals, [INTERVALS] * 2)


@pytest.mark.parametrize("section_block", [False, True])
def test_a_valve_held_with_the_other_open_gets_a_sections_levels_over_the_rounds(section_block):
    # Section levels need MIN_SECTION_LEVELS distinct currents; with the inlet's interval the
    # wider, the widths alone would give the outlet MIN_TURN_SHARE of each round's holds (2 of
    # 10 here, 4 over two rounds), too few for a section.
    config = load_scenario()
    period_s = config.offset_free_lqg.sample_period_s
    planned = random_level_currents(1400, period_s, TOPS, (2.0, 6.0), 1)
    wide_inlet = ((0.02, 0.12), (0.05, 0.06))

    def reading_of(u, y):
        return wide_inlet, ((), ())

    applied, *_ = run_sequential_experiment(
        config,
        planned,
        period_s,
        TOPS,
        (200, 1400),
        reading_of,
        4.0,
        0,
        rounds=2,
        other_valve_currents_a=(0.0, 0.15),
        section_block=section_block,
    )
    # The outlet's holds are those with the inlet held at 0.15 A; each hold is 60 samples.
    firsts = np.arange(200, 1400, 60)
    outlet_levels = applied[1, firsts + 59][applied[0, firsts + 59] == 0.15]
    assert np.unique(outlet_levels).size >= MIN_SECTION_LEVELS
    low, high = wide_inlet[1]
    assert np.all((outlet_levels >= low) & (outlet_levels <= high))
    if not section_block:
        return
    # Each round's (10 holds each) section holds come first, in one run.
    for round_firsts in (firsts[:10], firsts[10:]):
        in_section = applied[0, round_firsts + 59] == 0.15
        count = int(in_section.sum())
        assert count >= 1 and np.all(in_section[:count]) and not in_section[count:].any()


def test_a_valve_with_no_interval_gets_its_whole_range_and_an_interval_is_clipped_to_it():
    np.testing.assert_array_equal(
        designable_intervals(None, TOPS), [[0.0, TOPS[0]], [0.0, TOPS[1]]]
    )
    # An interval across a range's end is clipped to it; one above the top (the joint search's
    # ends on 80/45 mA seed 11, 226.5-230.8 mA) to the top, as every round did before.
    found = designable_intervals(((-0.01, 0.05), (0.2265, 0.2308)), TOPS)
    np.testing.assert_array_equal(found, [[0.0, 0.05], [TOPS[1], TOPS[1]]])


def test_a_round_whose_fit_has_no_interval_targets_each_valves_whole_range():
    config = load_scenario()
    period_s = config.offset_free_lqg.sample_period_s
    planned = random_level_currents(900, period_s, TOPS, (2.0, 6.0), 1)
    answers = iter([(None, ((), ())), (INTERVALS, ((), ()))])

    applied, _, _, intervals = run_sequential_experiment(
        config, planned, period_s, TOPS, (300, 700), lambda u, y: next(answers), 4.0, 0, rounds=2
    )
    whole = ((0.0, TOPS[0]), (0.0, TOPS[1]))
    np.testing.assert_array_equal(intervals, [whole, INTERVALS])
    expected = targeted_level_currents(200, period_s, TOPS, whole, 4.0, 0, 0.0, (0.0, 0.0))
    np.testing.assert_array_equal(applied[:, 300:500], expected)
    # The whole range reaches levels the found intervals exclude.
    inlet_low, inlet_high = INTERVALS[0]
    assert np.any((applied[0, 300:500] > inlet_high) | (applied[0, 300:500] < inlet_low))


@pytest.mark.parametrize(
    "arguments, message",
    [({"targeted": (300, 901)}, "targeted = "), ({"rounds": 0}, "rounds = 0")],
)
def test_bad_sequential_arguments_name_the_argument(arguments, message):
    fields = {
        "config": None,
        "currents_a": np.zeros((2, 900)),
        "sample_period_s": TS,
        "top_currents_a": TOPS,
        "targeted": (300, 700),
        "reading_of": None,
        "hold_s": 4.0,
        "seed": 0,
        **arguments,
    }
    with pytest.raises(ValueError, match=message):
        run_sequential_experiment(**fields)


def test_a_top_only_a_hold_shorter_than_the_designs_showed_is_not_taken_as_seen():
    # Holds of 6 s (60 samples) at TS: the inlet alone at 0.175 A for 4 s (a random hold a
    # partial record's fit may call settled), at 0.186 A for 6 s approached from above (a
    # sample at the top current first), the outlet alone at 0.17 A for 4 s, both open for 8 s.
    applied = np.repeat(
        [[0.0, 0.0], [0.175, 0.0], [0.19, 0.0], [0.186, 0.0], [0.0, 0.17], [0.186, 0.17]],
        [30, 40, 1, 59, 40, 80],
        axis=0,
    )
    settled = ((0.05, 0.12, 0.175, 0.186), (0.10, 0.17))
    inlet, outlet = tops_seen_by_long_holds(settled, applied, TOPS, 6.0, TS)
    # Below the top eighth (0.16625 A for the inlet, 0.1575 A for the outlet) all are kept.
    np.testing.assert_array_equal(inlet, [0.05, 0.12, 0.186])
    np.testing.assert_array_equal(outlet, [0.10])
    # The design then holds the outlet's top eighth first, the inlet's not.
    lows = np.array([INTERVALS[0][1], INTERVALS[1][1]])
    valves, currents = _gap_filling((inlet, outlet), lows, np.array(TOPS), 1)
    np.testing.assert_array_equal(valves, [1])
    np.testing.assert_allclose(currents, [0.18 * 15 / 16])
