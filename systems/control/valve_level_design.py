"""Amplitude-rich currents for both valves, for identifying their static maps (Hammerstein).

A binary or small-amplitude signal sees one slope of a valve's curve; a Hammerstein fit needs the
whole curve, from below the starting current to past saturation. So each valve is driven through
random levels spread uniformly over ``[0, top]``, each held for a random time comparable to the
plant's time constants (so the head settles often enough to show the steady curve, and moves
often enough to show the dynamics). The hold lengths are drawn as ``excitation.multilevel_prbs``
draws its own (``excitation.random_holds``). ``maskless excite --signal valve-levels`` runs it.

The design knows only what a valve's datasheet states, its whole current range (0 to ``top``,
past the largest rated current to show the flat top): never the starting current the fit is to
find. Uniform levels are the design that favours no guess of it. They are stratified: each
valve's levels come in blocks of eight, one from each eighth of its range in random order, so
an hour (some 37 levels per valve in a split range, about half of them held long enough to
settle) leaves no stretch of the curve unvisited, as independent draws often do.

Two arrangements:

- ``split_range``: at each level one valve (inlet or outlet), or neither, is driven over its whole
  range while the other is shut (0 A, below any starting current). That is how the controller's
  split-range allocation uses the valves (never both open), where the plant is a sum of one
  valve's effect at a time and each valve's curve is its curve with the other shut. The levels
  where neither is driven, and the driven valve's levels below its start, show the rest output
  the maps' flat parts must explain.
- ``independent``: both valves draw their levels independently, so both are often open together;
  the bladder's pressure then balances both flows at once, which no sum of per-valve maps
  describes exactly.

``excitation.multilevel_prbs`` draws levels from a grid for one valve at a time; its split range
(``valve_pair_excitation``) never applies a current between 0 and a valve's starting current,
where the map's flat part is, so this design draws its own: continuous levels.

**Targeted levels** (``targeted_level_currents``): the valves held inside intervals of starting
currents (the one placed worse more often), approached alternately from below and from above, so
the hysteresis averages out, and over the stretches of the curves no settled level has shown;
``diagrams.valve_level_experiment.run_sequential_experiment`` designs part of a record with them
from the record before it (why, there).
"""

import numpy as np

from maskless.systems.control.excitation import hold_samples, random_holds

ARRANGEMENTS = ("split_range", "independent")
# The highest level of either valve (A): past the proportional valves' rated 165 mA, so the levels
# show the curve's flat top (the datasheet range the design knows; assets/pneumatic.yaml).
TOP_CURRENT_A = 0.190
# Equal parts of a valve's range that each block of its levels visits once (``_stratified``).
_STRATA = 8
# The least share of the holds inside the intervals each valve gets (``_width_share``).
MIN_TURN_SHARE = 0.2


def random_level_currents(
    samples: int,
    sample_period_s: float,
    top_currents_a: tuple[float, float],
    hold_range_s: tuple[float, float],
    seed: int,
    arrangement: str = "split_range",
    stratified: bool = True,
) -> np.ndarray:
    """(2, samples) inlet and outlet currents (A): random levels held for random times.

    Args:
        samples: the record's length.
        sample_period_s: the period of a sample (s).
        top_currents_a: each valve's highest level (A): past its rated range to show the flat top.
        hold_range_s: (shortest, longest) time a level is held (s), drawn uniformly in whole
            samples (``excitation.hold_samples``).
        seed: the random generator's seed (same seed, same signal).
        arrangement: one of ``ARRANGEMENTS`` (see the module docstring).
        stratified: levels in blocks that visit every eighth of a valve's range (``_stratified``);
            False: each level drawn independently (the earlier design, bit for bit).

    Raises:
        ValueError: naming the argument out of range.
    """
    if arrangement not in ARRANGEMENTS:
        raise ValueError(f"arrangement = {arrangement!r}: expected one of {ARRANGEMENTS}")
    if isinstance(samples, bool) or not (isinstance(samples, int) and samples >= 2):
        raise ValueError(f"samples = {samples!r}: expected an integer >= 2")
    if not all(np.isfinite(top) and top > 0 for top in top_currents_a):
        raise ValueError(f"top_currents_a = {top_currents_a}: expected a positive current each")
    rng = np.random.default_rng(seed)
    holds = random_holds(rng, samples, hold_range_s, sample_period_s)
    # Independent levels are drawn before the split, as the earlier design drew them.
    levels = np.zeros((holds.size, 2))
    if not stratified:
        levels = rng.uniform(0.0, 1.0, size=(holds.size, 2)) * np.asarray(top_currents_a)
    driven = np.ones((holds.size, 2), dtype=bool)
    if arrangement == "split_range":
        active = rng.integers(3, size=holds.size)  # the inlet, the outlet, or neither
        driven = np.column_stack([active == 0, active == 1])
    for valve, top in enumerate(top_currents_a):
        if stratified:
            levels[driven[:, valve], valve] = top * _stratified(rng, int(driven[:, valve].sum()))
        levels[~driven[:, valve], valve] = 0.0
    return np.repeat(levels, holds, axis=0)[:samples].T


def _stratified(rng, count: int, strata: int = _STRATA) -> np.ndarray:
    """``count`` fractions of the range, uniform, in blocks that each visit every stratum once.

    Each block of ``strata`` levels is one uniform draw from each of ``strata`` equal parts of
    the range, in random order: i.i.d. levels leave gaps (a dozen settled levels of a valve can
    miss a fifth of its range), and a gap is where the static curve is only guessed.
    """
    if count == 0:
        return np.zeros(0)
    blocks = -(-count // strata)
    order = np.concatenate([rng.permutation(strata) for _ in range(blocks)])[:count]
    return (order + rng.uniform(0.0, 1.0, size=count)) / strata


def targeted_level_currents(
    samples: int,
    sample_period_s: float,
    top_currents_a: tuple[float, float],
    start_intervals_a,
    hold_s: float,
    seed: int,
    coverage_share: float = 0.0,
    other_valve_currents_a: tuple[float, float] = (0.0, 0.0),
    settled_currents_a: tuple = ((), ()),
    least_inside: tuple[int, int] = (0, 0),
    cover_under_sections: bool = False,
    section_block: bool = False,
) -> np.ndarray:
    """(2, samples) currents (A): the valves' holds inside their starting currents' intervals.

    Each hold is ``hold_s`` long and drives one valve, the other shut (as in ``split_range``) or
    held at ``other_valve_currents_a``. Of the holds inside the intervals, each valve gets a
    share as wide as its interval (``_width_share``: the start the record so far places worse
    gets more), and its levels one in each of as many equal parts of its interval (a round's few
    levels still span it). With ``coverage_share``, that share of the holds (spread evenly
    among the others) goes over the rest of the curves instead, from an interval's top to its
    valve's top current, with the other valve shut: first the top eighth of a range no settled
    level has reached, then each in the middle of the widest stretch no settled level has shown
    yet, of either valve (``_gap_filling``), so a record whose random part is cut short still
    shows its curves whole; never the stretch's last hold, cut short where the stretch is not
    a whole number of holds. Within each of those two kinds, a valve's holds alternate between
    approached from below (shut before the level: its hold's first sample shuts it if it was
    open, and at the stretch's start, where the design does not see what came before) and from
    above (the hold's first sample at the valve's top current, which pushes the spool past any
    play band the datasheet allows, then the level), so half its levels rest at each edge of
    the band.

    Args:
        samples: the stretch's length.
        sample_period_s: the period of a sample (s).
        top_currents_a: each valve's highest current (A), the datasheet range's top.
        start_intervals_a: (2, 2) each valve's (lowest, highest) starting current the record so
            far cannot tell apart (A), within [0, top].
        hold_s: how long each level is held (s): long enough to settle.
        seed: the random generator's seed (same seed, same signal).
        coverage_share: the share of holds above the interval, 0 to 1 (0: none, bit for bit
            the design without it).
        other_valve_currents_a: per valve, the current (A) the other valve holds during its
            holds inside the interval (0: shut, the split range). A valve whose own effect is
            small near its start (the outlet, venting a bladder at low pressure) shows that
            start several times more sharply on top of the other valve held open: the same
            opening then passes more air. Those levels form a section of the plant's steady
            output at one current of the other valve (``settled_curve``).
        settled_currents_a: per valve, the currents (A) at which the record so far settled
            with it alone open (``HammersteinFit.settled_currents``): the holds over the rest
            of the curves go between them.
        least_inside: per valve, the fewest holds inside its interval, whatever the widths
            say (as many as there are, shared in proportion, when the two ask for more): a
            section needs its levels (``section_start.MIN_SECTION_LEVELS``) even when the
            other valve's interval is the wider.
        cover_under_sections: a valve held with the other open gets its holds over the curve
            from its interval's lowest start up, not from its highest: those holds inside the
            interval are a section's and show no level of its curve alone, so an interval
            reaching the curve's top (a start the record so far places anywhere) would leave
            the whole curve unshown. False: from the highest, bit for bit the design without it.
        section_block: a valve held with the other open gets its holds inside the interval in
            one run at the stretch's start, so that each after the first begins where the
            section's last left the plant (``section_start.approached_within``): refilled
            from a bladder the other holds left low, the pneumatic plant's head came within
            0.02 mm of a section's level only a minute later. The stretch's last hold stays
            one inside an interval. False: interleaved, bit for bit the design without it.

    Raises:
        ValueError: naming the argument out of range.
    """
    if isinstance(samples, bool) or not (isinstance(samples, int) and samples >= 2):
        raise ValueError(f"samples = {samples!r}: expected an integer >= 2")
    if not 0.0 <= coverage_share <= 1.0:
        raise ValueError(f"coverage_share = {coverage_share!r}: expected 0 to 1")
    tops, intervals = _checked_ranges(top_currents_a, start_intervals_a)
    if len(settled_currents_a) != 2 or any(np.ndim(seen) != 1 for seen in settled_currents_a):
        raise ValueError(
            f"settled_currents_a = {settled_currents_a}: expected a sequence of currents (A) "
            "per valve"
        )
    least = np.asarray(least_inside)
    if least.shape != (2,) or not (np.issubdtype(least.dtype, np.integer) and np.all(least >= 0)):
        raise ValueError(f"least_inside = {least_inside}: expected a count >= 0 per valve")
    others = np.asarray(other_valve_currents_a, dtype=float)
    if others.shape != (2,) or not np.all((others >= 0.0) & (others <= tops[::-1])):
        raise ValueError(
            f"other_valve_currents_a = {other_valve_currents_a}: expected per valve a current "
            "from 0 to the other valve's top current"
        )
    # At least two samples: the approach from above and the level.
    hold = max(hold_samples((hold_s, hold_s), sample_period_s)[0], 2)
    rng = np.random.default_rng(seed)
    count = -(-samples // hold)
    # Counted from the stretch's end, so that its last hold, cut short where the stretch is not
    # a whole number of holds (and then never settled), is never one over the curves' rest.
    order = np.arange(count)[::-1]
    covering = np.floor((order + 1) * coverage_share) - np.floor(order * coverage_share) == 1
    turns = np.empty(count, dtype=int)
    levels = np.zeros(count)
    # A valve whose holds inside its interval keep the other open: a section's.
    held_open = others > 0.0
    sectioned = cover_under_sections & held_open
    turns[covering], levels[covering] = _gap_filling(
        settled_currents_a,
        np.where(sectioned, intervals[:, 0], intervals[:, 1]),
        tops,
        int(covering.sum()),
    )
    # The start the record so far places worse gets more of the holds inside the intervals.
    inside_count = int((~covering).sum())
    inlet_share = _least_respected(_width_share(intervals, tops), least, inside_count)
    turns[~covering] = _interleaved(inside_count, inlet_share)
    rank = np.zeros(count, dtype=int)
    for valve, (low, high) in enumerate(intervals):
        inside = np.flatnonzero((turns == valve) & ~covering)
        # As many strata as levels: a round's few levels spread over the whole interval.
        levels[inside] = low + (high - low) * _stratified(rng, inside.size, inside.size)
        above = np.flatnonzero((turns == valve) & covering)
        # Each kind of hold alternates its approach on its own, so both kinds see both edges.
        rank[inside], rank[above] = np.arange(inside.size), np.arange(above.size)
    from_above = (rank + rng.integers(2)) % 2 == 1
    if section_block and held_open.any():
        order = _section_first(~covering & held_open[turns], covering)
        turns, levels, covering, from_above = (
            a[order] for a in (turns, levels, covering, from_above)
        )
    return _turns(turns, levels, covering, from_above, tops, others, hold)[:, :samples]


def _section_first(in_block: np.ndarray, covering: np.ndarray) -> np.ndarray:
    """The holds' order with those ``in_block`` first, the rest after, each in its own order.

    Where that leaves a hold over the curves' rest (``covering``) last, the last hold of the
    others moves to the end: the stretch's last hold may be cut short, and is never one of those.
    """
    order = np.concatenate([np.flatnonzero(in_block), np.flatnonzero(~in_block)])
    if covering[order[-1]] and not covering.all():
        last = np.flatnonzero(~covering[order])[-1]
        order = np.append(np.delete(order, last), order[last])
    return order


def top_eighth_floor(top_current_a):
    """The lowest current (A) of a valve's top eighth, which the design holds first.

    Past its highest settled level a curve is only extrapolated (``_gap_filling``).
    """
    return top_current_a * (1.0 - 1.0 / _STRATA)


def _width_share(intervals: np.ndarray, tops: np.ndarray) -> float:
    """The inlet's share of the holds inside the intervals: its interval's width over both.

    Widths as fractions of each valve's range, the share within ``MIN_TURN_SHARE`` and one minus
    it (a half when neither interval has a width).
    """
    widths = (intervals[:, 1] - intervals[:, 0]) / tops
    share = 0.5 if widths.sum() <= 0.0 else widths[0] / widths.sum()
    return float(np.clip(share, MIN_TURN_SHARE, 1.0 - MIN_TURN_SHARE))


def _least_respected(inlet_share: float, least: np.ndarray, count: int) -> float:
    """``inlet_share`` moved as little as gives each valve ``least`` of ``count`` holds.

    ``_interleaved`` gives a share s of ``count`` turns within one turn of s ``count``, exactly
    where that is whole, so these bounds give at least ``least``. When the two ask for more
    than ``count``, in proportion to what they ask.
    """
    if count == 0 or not least.any():
        return inlet_share
    if least.sum() >= count:
        return float(least[0] / least.sum())
    return float(np.clip(inlet_share, least[0] / count, 1.0 - least[1] / count))


def _interleaved(count: int, inlet_share: float) -> np.ndarray:
    """(count,) 0 (inlet) or 1 (outlet) per turn, each to the valve furthest behind its share."""
    shares = np.array([inlet_share, 1.0 - inlet_share])
    turns = np.empty(count, dtype=int)
    given = np.zeros(2)
    for k in range(count):
        # Ties go to the inlet: the same turns on every run.
        turns[k] = int(np.argmax(shares * (k + 1) - given))
        given[turns[k]] += 1
    return turns


def _gap_filling(settled, floors, tops, count: int) -> tuple[np.ndarray, np.ndarray]:
    """(valves, currents) of ``count`` holds: unseen tops first, then the widest gaps' middles.

    A valve none of whose settled levels (nor its floor) reaches the top eighth of its range
    gets the first hold there, in its middle, the inlet before the outlet. Then a valve's gaps
    are those between its ``floors`` (below which its curve needs no hold here: its interval's
    top, whose holds show it, or its lowest start where those holds are a section's), its
    ``tops`` and the currents ``settled`` so far between them (its curve's stretches no settled
    level has shown); the widest of both valves, as fractions of each one's top current, gets
    the next hold, in its middle. A valve whose floor is its top current has no gap; when
    neither has one, the hold is at the top current (the curve's flat end).
    """
    points = [
        sorted({low, top, *(c for c in np.asarray(seen, float) if low < c < top)})
        for seen, low, top in zip(settled, floors, tops, strict=True)
    ]
    valves, currents = np.zeros(count, dtype=int), np.zeros(count)
    # Past a curve's highest settled level a fit only extrapolates (a saturation it never saw),
    # and the widest gap may lie lower: so a top eighth no level has reached is held first. In
    # its middle, not at the top current itself, where a section may hold this valve open for
    # the other's levels (``other_valve_currents_a``): a level there with the other valve shut
    # would be read as one of that section's, and left out of this valve's curve.
    unseen_tops = [
        valve
        for valve, (near, top) in enumerate(zip(points, tops, strict=True))
        if near[0] < top and near[-2] < top_eighth_floor(top)
    ][:count]
    for k, valve in enumerate(unseen_tops):
        valves[k], currents[k] = valve, tops[valve] * (1.0 - 0.5 / _STRATA)
        points[valve].insert(-1, currents[k])
    for k in range(len(unseen_tops), count):
        gaps = [np.diff(p) / top for p, top in zip(points, tops, strict=True)]
        # Ties go to the inlet: the same holds on every run.
        valves[k] = int(np.argmax([g.max() if g.size else 0.0 for g in gaps]))
        near = points[valves[k]]
        if not gaps[valves[k]].size:
            currents[k] = near[-1]
            continue
        widest = int(np.argmax(gaps[valves[k]]))
        currents[k] = 0.5 * (near[widest] + near[widest + 1])
        near.insert(widest + 1, currents[k])
    return valves, currents


def _turns(turns, levels, covering, from_above, tops, others, hold) -> np.ndarray:
    """(2, holds * hold) each hold's valve at its level, approached as ``from_above`` says.

    From below, a valve left open before (its own hold, or held open during the other's), or at
    the stretch's first hold, is shut for the hold's first sample.
    """
    currents = np.zeros((2, turns.size * hold))
    for k, valve in enumerate(turns):
        begin = k * hold
        currents[valve, begin : begin + hold] = levels[k]
        if not covering[k]:
            currents[1 - valve, begin : begin + hold] = others[valve]
        if from_above[k]:
            currents[valve, begin] = tops[valve]
        elif begin == 0 or currents[valve, begin - 1] > 0.0:
            currents[valve, begin] = 0.0
    return currents


def _checked_ranges(top_currents_a, start_intervals_a) -> tuple[np.ndarray, np.ndarray]:
    """(tops (2,), intervals (2, 2)) as arrays, each interval ordered and within [0, top]."""
    tops = np.asarray(top_currents_a, dtype=float)
    if tops.shape != (2,) or not np.all(np.isfinite(tops) & (tops > 0)):
        raise ValueError(f"top_currents_a = {top_currents_a}: expected a positive current each")
    intervals = np.asarray(start_intervals_a, dtype=float)
    if intervals.shape != (2, 2) or not (
        np.all(np.isfinite(intervals))
        and np.all(intervals[:, 0] >= 0.0)
        and np.all(intervals[:, 0] <= intervals[:, 1])
        and np.all(intervals[:, 1] <= tops)
    ):
        raise ValueError(
            f"start_intervals_a = {start_intervals_a}: expected (2, 2) (lowest, highest) per "
            "valve with 0 <= lowest <= highest <= its top current"
        )
    return tops, intervals
