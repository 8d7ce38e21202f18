"""Each valve's static curve from the settled ends of held levels: stage one of a Hammerstein fit.

A level held past the plant's settling time shows one point of the static curves directly: the
mean output over the rest of the hold is the rest output plus each valve's steady effect at its
current, with no dynamics to model. ``analysis.identification.hammerstein`` fits the curves from
those points first and the dynamics after, with the curves fixed: a joint prediction-error search
lets the maps absorb what a linear model of a plant whose time constants change with its level
gets wrong in the transients, and its starting current trades off against the map's first pieces.

Choices, and why:

- **The curve above the starting current s is a monotone quadratic in t = (u - s) / (c - s)**
  (the degree-2 Bernstein polynomial with non-decreasing coefficients), flat at 0 below s and at
  its full value from the saturation current c on. Two shape parameters: a hold a valve is driven
  at gives one point, an hour's record some dozen settled ones per valve, so a flexible shape
  would follow the noise. It leaves s with any slope from 0 (a quadratic start) up, and covers
  a valve whose effect grows gently and then fast (a bladder's lift: choked flow in against a
  leak out) or linearly. A cubic, and a third step hinged at the span's middle, were tried
  and lost over the benchmark's population (README, "Tried and not kept").
- **s and c are profiled over a grid**, the shape's coefficients fitted by non-negative least
  squares at each grid point, so no local search can wander along the trade-off between s and
  the curve's first slope; the grid is refined around its best point. Each valve's sign (does
  opening it raise or lower the output) is chosen by the same least squares, and the valves are
  fitted in turn, each with the others' curves held, for a few sweeps.
- **Each level is placed where its valve's spool rests**, not at its coil current: a proportional
  valve has play (the datasheet allows hysteresis of 10 % of the range), so after a rise the spool
  rests at the lower edge of its band, after a fall at the upper (``section_start.play_operator``
  run over every hold of the record). After the sweeps without it, two more search each free
  valve's half-width over 0-5 % of its range together with its ends (every play at every point
  of the coarse grid, ``grid_least_squares`` solving them all at once), every step kept only
  where the sum of squares drops. Searched in turn instead (the play at the ends found, then the
  ends at that play), the fit stopped in a valley: on seed 18 of the benchmark's designed record
  the inlet's start read 85.5 mA with 0.95 mA of play, where 60 mA with 2.6 mA fits the same
  levels with a third of the sum of squares; searched together it reads 65.1 mA (60.3 mA with
  the weights below). Profiled from the first sweep, before the curves had settled, the fit
  found 4.6 mA of play on a planted record without any and put the inlet's start 3.9 mA low.
  With noisy levels some play always
  fits a hair better, so the played fit is kept only where its sum of squares is below that of
  the same sweeps with the play held at zero by more than chi2(0.95) residual variances (one
  degree per play: a likelihood-ratio test); on a planted record without play the search found
  3.3 mA that fitted as well to rounding, and the test refused it. A fit that finds no play is
  the fit with the play held at zero, bit for bit, except that a valve whose start a section
  found has its levels placed with that section's play from the first sweep. Unmodelled, the
  pneumatic plant's 2.6 mA of play scatters the inlet's steep middle (about 0.3 mm per mA) by
  some 0.8 mm, and the quadratic bends to it: on a record with few levels near the start (seed 1
  of the benchmark's sequential design) the inlet's start read 83.6 mA without the play and
  58.4 mA with it, the plant's being 60.
- **Each level weighs the samples it averages** (weighted least squares): a level is the mean
  of the output over the settled rest of its hold, and the holds of a designed record run from
  5 s to a minute, so a short one's mean scatters several times as far. Refitting the 32
  records the benchmark's designed loop made before these changes (issue 14), the inlet's start
  was within 5 mA on 26 unweighted and 29 weighted, its mean error 2.47 and 1.74 mA.
- **What the levels cannot tell apart is reported**: each starting current's 95 % profile
  interval, the starts whose best fit (saturation, sign and play at their best) raises the sum
  of squares by at most chi2(1, 0.95) = 3.84 residual variances over the best (a
  likelihood-ratio interval for Gaussian errors), widened to the gaps between the settled
  levels about the starts it holds, from the nearest level at or below its lowest to the
  nearest above its highest (``profile_interval.covering_levels_gap``): inside a gap only the
  quadratic's shape places a start, and the plant's lift (gentle for 15 mA, then steep) is not a
  quadratic. Each saturation current likewise: inside a gap of levels only the quadratic places
  the curve's top. On seed 13 of the 60 mA plant's benchmark record the outlet's levels skip
  153.7-175.9 mA; its saturation read 173.8 mA, the plant's 165, and its curve missed the
  plant's by 13.8 % of its full scale with nothing to say so; its interval reads 153.7-187.7 mA.
"""

import functools
from dataclasses import dataclass

import numpy as np
import scipy.optimize
import scipy.stats

from maskless.analysis.identification.grid_least_squares import lowest_sums_of_squares
from maskless.analysis.identification.profile_interval import (
    CHI2_95,
    covering_levels_gap,
    profile_interval,
)
from maskless.analysis.identification.section_start import (
    MIN_SECTION_LEVELS,
    PLAY_HALF_WIDTHS,
    approached_within,
    find_sections,
    play_operator,
    section_start,
)

# The grid's step for the starting and saturation currents, as a fraction of each input's range,
# and the step of the refinement around the coarse grid's best point.
_GRID_STEP = 1.0 / 80.0
_REFINED_STEP = _GRID_STEP / 5.0
# How near its best a saturation's profile searches the start (a fraction of the range). The
# start's profile searches the saturation to 1e-7; the same here took the curves' fit of the 60
# mA plant's seeds 13 and 22 from 1.95 and 1.80 s to 2.41 and 2.28 s, and 1e-4 to 2.20 and 2.00 s
# (a sum of squares is flat at its best: ``test_each_ends_profile_is_...`` holds either way).
_SATURATION_PROFILE_TOLERANCE = 1e-4
# Passes over the valves, each fitted with the others' curves held; then those with the play.
_SWEEPS = 3
_PLAY_SWEEPS = 2
# Knots of the piecewise-linear map a curve is stored as (``ValveMap``): a quadratic sampled at
# 16 pieces is within 1/1024 of its full value of the quadratic.
MAP_PIECES = 16
# A valve's sign: opening it raises the output, or lowers it.
_SIGNS = (1.0, -1.0)


def parameter_count(inputs: int) -> int:
    """The curves' parameters: the rest output, and per input two ends and two shape steps."""
    return 1 + 4 * inputs


def enough_levels(currents: np.ndarray, fixed_starts: int = 0) -> bool:
    """Whether levels at ``currents`` (M, inputs) can fit the curves.

    Twice the curves' parameters, less the ``fixed_starts`` starting currents found elsewhere
    (a section's), and each input at two distinct currents at least.
    """
    count = parameter_count(currents.shape[1]) - fixed_starts
    return currents.shape[0] >= 2 * count and all(
        np.unique(currents[:, i]).size >= 2 for i in range(currents.shape[1])
    )


@dataclass(frozen=True)
class SettledLevels:
    """The holds that settled: (M, inputs) currents, (M,) mean outputs, (M,) samples averaged.

    ``hold_currents`` (H, inputs) are the currents of every hold of the record in turn, settled
    or not, ``hold_first_samples`` (H,) where each begins, and ``level_holds`` (M,) the hold each
    level ends: a valve's play makes where its spool rests depend on the currents before
    (``section_start``). Left out, the levels are taken as the record's only holds, in order.
    """

    currents: np.ndarray
    outputs: np.ndarray
    samples: np.ndarray
    hold_currents: np.ndarray | None = None
    level_holds: np.ndarray | None = None
    hold_first_samples: np.ndarray | None = None

    def holds_in_order(self) -> tuple[np.ndarray, np.ndarray]:
        """(every hold's currents (H, inputs), the hold each level ends (M,)), as above."""
        if self.hold_currents is None:
            return self.currents, np.arange(self.outputs.size)
        return self.hold_currents, self.level_holds


@dataclass(frozen=True)
class StaticCurves:
    """Per input its starting and saturation current and shape; the rest output.

    Currents in the units of the levels they were fitted to; ``increments`` (inputs, 2) are the
    Bernstein coefficients' non-negative steps times the input's sign, so each curve's full value
    (its DC gain) is their sum; ``start_intervals`` (inputs, 2) the starting currents the levels
    cannot tell apart (the 95 % profile interval, widened to the gaps of levels about its starts),
    ``profile_intervals`` (inputs, 2) the profile intervals alone; ``saturation_intervals``
    (inputs, 2) the saturation currents the levels cannot tell apart, found so too (a start's
    profile turned round); ``play_half_widths``
    (inputs,) the half-width of each valve's play band (its section's, where one found its
    start); ``from_sections`` (inputs,) whether a section found it (``section_start``),
    ``straight_section_starts`` (inputs,) where that section's hinge was bent once above the
    start, the plain hinge's start (else None; ``bent_sections`` says which) and
    ``sections_read_apart`` (inputs,) whether the two readings' profile intervals do not meet;
    ``section_levels`` (M,) which of the settled levels were sections, left out of the curves'
    fit; ``settled_currents`` per input, the currents of the
    levels that showed its curve alone (it open, the others shut); ``residual_rms`` the root of
    the levels' weighted mean squared residual (each weighs the samples it averages);
    ``unread_section_levels`` the levels of sections found but left in the curves' fit (too few
    levels outside them), which no sum of curves describes.
    """

    starts: np.ndarray
    saturations: np.ndarray
    increments: np.ndarray
    rest_output: float
    residual_rms: float
    start_intervals: np.ndarray
    play_half_widths: tuple[float, ...]
    from_sections: tuple[bool, ...]
    section_levels: np.ndarray
    settled_currents: tuple[np.ndarray, ...]
    profile_intervals: np.ndarray
    saturation_intervals: np.ndarray
    unread_section_levels: int = 0
    straight_section_starts: tuple[float | None, ...] = ()
    sections_read_apart: tuple[bool, ...] = ()

    @property
    def bent_sections(self) -> tuple[bool, ...]:
        """(inputs,) whether each valve's start came from a section's bent hinge."""
        return tuple(start is not None for start in self.straight_section_starts)

    def curve(self, index: int, currents) -> np.ndarray:
        """The steady output change of input ``index`` from shut, at ``currents``."""
        basis = _basis(np.asarray(currents, float), self.starts[index], self.saturations[index])
        return basis @ self.increments[index]

    def gains(self) -> np.ndarray:
        """Per input, the steady output change from shut to saturation."""
        return self.increments.sum(axis=1)

    def map_knots(self, index: int) -> tuple[np.ndarray, np.ndarray]:
        """(currents, openings): the curve over its gain at ``MAP_PIECES`` + 1 knots, 0 to 1."""
        currents = np.linspace(self.starts[index], self.saturations[index], MAP_PIECES + 1)
        openings = self.curve(index, currents) / self.gains()[index]
        openings[0], openings[-1] = 0.0, 1.0
        return currents, np.maximum.accumulate(np.clip(openings, 0.0, 1.0))


@dataclass(frozen=True)
class _Target:
    """The levels' outputs (M,) and their weights (M,) in the least squares.

    A level is the mean output over its hold's settled samples, so its noise variance falls as
    one over their number: it weighs the samples it averages, over their mean (all 1 when the
    holds are alike), and a sum of squares reads in units of a level of average length.
    """

    outputs: np.ndarray
    weights: np.ndarray


def others_shut(u, index: int) -> np.ndarray:
    """(N,) True where every input of ``u`` (N, inputs) but ``index`` is shut (zero)."""
    return np.all(np.delete(u, index, axis=1) == 0.0, axis=1)


def hold_runs(u) -> tuple[np.ndarray, np.ndarray]:
    """(first sample, end) of each hold of ``u`` (N, inputs): a run of unchanged currents."""
    change = np.flatnonzero(np.any(np.diff(u, axis=0) != 0.0, axis=1)) + 1
    return np.concatenate([[0], change]), np.concatenate([change, [u.shape[0]]])


def settled_levels(u, y, settle_samples: int, min_tail_samples: int) -> SettledLevels:
    """Each hold (a run of unchanged currents) longer than ``settle_samples + min_tail_samples``.

    Its mean output from ``settle_samples`` after it began to its end.
    """
    starts, ends = hold_runs(u)
    tail = max(1, min_tail_samples)
    kept = np.flatnonzero(ends - starts - settle_samples >= tail)
    return levels_from(u, y, (starts, ends), kept, starts[kept] + settle_samples)


def levels_from(u, y, runs, kept, settled_samples) -> SettledLevels:
    """The ``SettledLevels`` of the holds ``kept`` (M,), each from its settled sample on.

    ``runs`` are ``hold_runs(u)`` and ``kept`` indices into them; each level is its hold's mean
    output from its sample in ``settled_samples`` (M,) to the hold's end.
    """
    starts, ends = runs
    kept = np.asarray(kept, dtype=int)
    settled_samples = np.asarray(settled_samples, dtype=int)
    return SettledLevels(
        currents=u[starts[kept]].reshape(kept.size, u.shape[1]),
        outputs=np.array(
            [y[f : ends[k]].mean() for k, f in zip(kept, settled_samples, strict=True)]
        ),
        samples=ends[kept] - settled_samples,
        hold_currents=u[starts],
        level_holds=kept,
        hold_first_samples=starts,
    )


def samples_outside(levels: SettledLevels, chosen: np.ndarray, settle: int, samples: int):
    """(samples,) True outside the holds of the ``chosen`` levels (M,).

    Each hold is taken from the sample before it (a one-sample approach) to ``settle`` samples
    after it ends (the plant's return).
    """
    outside = np.ones(samples, dtype=bool)
    bounds = np.append(levels.hold_first_samples, samples)
    for hold in levels.level_holds[chosen]:
        outside[max(bounds[hold] - 1, 0) : bounds[hold + 1] + settle] = False
    return outside


def fit_static_curves(
    levels: SettledLevels,
    max_start: float,
    max_saturation: float,
    read_sections: bool = False,
    sections_from_within: bool = False,
):
    """The ``StaticCurves`` that fit the settled levels best (see the module docstring).

    Currents are searched as fractions of each input's range over the levels: starting currents
    from its lowest level up to ``max_start`` of the range, saturation currents up to
    ``max_saturation`` (past 1: beyond the highest level). With ``read_sections`` (a record
    designed with sections: ``valve_level_design.targeted_level_currents`` with
    ``other_valve_currents_a``), a valve with a section takes its start from it
    (``section_start``) and those levels stay out of the curves' fit; otherwise a record whose
    levels repeat on a grid would be read as sections it was never designed to have. With
    ``sections_from_within`` too, a section's start is read from its levels approached from
    within it (``section_start.approached_within``), all of them where fewer than a section's
    ``MIN_SECTION_LEVELS`` currents were; the others stay out of the curves' fit all the same.
    Returns None when some input was held at fewer than two distinct levels.
    """
    u, y = levels.currents, levels.outputs
    inputs = u.shape[1]
    if any(np.unique(u[:, i]).size < 2 for i in range(inputs)):
        return None
    low, span = u.min(axis=0), np.ptp(u, axis=0)
    # Every hold's currents as fractions of each input's range: the play runs over them all.
    holds, level_holds = levels.holds_in_order()
    fractions = (holds - low) / span
    read = _SectionsRead({}, np.zeros(y.size, dtype=bool), 0)
    if read_sections:
        read = _section_starts(levels, fractions, level_holds, max_start, sections_from_within)
    curves = _curves_beside(levels, fractions, (low, span), (max_start, max_saturation), read)
    noise = _level_noise(curves) if read.starts else None
    if noise is not None:
        # Read again with the noise the curves left: a section that one hinge does not fit
        # within it may be bent (``section_start``); the curves then fitted beside it.
        bent = _section_starts(
            levels, fractions, level_holds, max_start, sections_from_within, noise
        )
        if any(found.bent for found in bent.starts.values()):
            curves = _curves_beside(
                levels, fractions, (low, span), (max_start, max_saturation), bent
            )
    return curves


@dataclass(frozen=True)
class _SectionsRead:
    """``_section_starts``'s reading of a record's sections.

    ``starts`` {valve: its ``SectionStart``}, ``in_sections`` (M,) the levels in any section,
    ``unread`` the sections' levels left in the curves' fit (too few others).
    """

    starts: dict
    in_sections: np.ndarray
    unread: int


def _level_noise(curves: StaticCurves) -> tuple[float, int] | None:
    """(variance, degrees of freedom) of a level's noise about the curves; None without any.

    Weighted by the samples each level averages, as the curves' fit is: the variance of a level
    of the mean length.
    """
    fitted = int(np.sum(~curves.section_levels))
    dof = fitted - parameter_count(curves.starts.size)
    if dof < 1:
        return None
    return curves.residual_rms**2 * fitted / dof, dof


def _curves_beside(levels: SettledLevels, fractions, scale, limits, read: _SectionsRead):
    """The ``StaticCurves`` of the levels outside ``read``'s sections, its starts fixed.

    ``scale`` (low, span) maps fractions of each input's range back to its currents, ``limits``
    are (max_start, max_saturation).
    """
    (low, span), (max_start, max_saturation) = scale, limits
    sections, outside = read.starts, ~read.in_sections
    inputs = levels.currents.shape[1]
    u, y = levels.currents[outside], levels.outputs[outside]
    level_holds = levels.holds_in_order()[1][outside]
    samples = levels.samples[outside]
    target = _Target(y, samples / samples.mean())

    @functools.cache
    def spool(i, half_width):
        """Where input i's spool rests at each level (fractions of the range).

        Cached: the searches ask for every play of the grid at each sweep and again for the
        intervals, and the play operator runs over every hold of the record.
        """
        return play_operator(fractions[:, i], half_width)[level_holds]

    fixed = [sections[i].start if i in sections else None for i in range(inputs)]
    plays = [sections[i].play_half_width if i in sections else 0.0 for i in range(inputs)]
    # Start each valve linear over its whole range; the sweeps move its ends.
    plays, ends, signs, x = _sweeps(
        spool, target, fixed, limits, plays, [(0.0, 1.0)] * inputs, [1.0] * inputs
    )
    if None in fixed:
        # Then each valve's play too, searched with its ends from there; kept where it lowers
        # the sum of squares significantly against the same sweeps with the play held at zero.
        played = _sweeps(spool, target, fixed, limits, plays, ends, signs, PLAY_HALF_WIDTHS)
        plain = _sweeps(spool, target, fixed, limits, plays, ends, signs, np.zeros(1))
        plays, ends, signs, x = played if _significant_play(target, plain, played) else plain
    columns = _columns(x, ends, signs)
    sse, coefficients = _nonnegative_fit(columns, target)
    variance = sse / max(1, y.size - parameter_count(inputs))
    threshold = sse + CHI2_95 * variance
    profiled, intervals, saturation_intervals = [], [], []
    for i in range(inputs):
        start_profile, saturation_profile = _end_profiles(
            lambda w, i=i: spool(i, w),
            [plays[i]] if i in sections else PLAY_HALF_WIDTHS,
            target,
            columns[:i] + columns[i + 1 :],
            max_start,
            max_saturation,
            sections[i].start if i in sections else None,
        )
        positions = spool(i, plays[i])
        if i in sections:
            profiled.append(sections[i].profile_interval)
            intervals.append(sections[i].interval)
        else:
            profiled.append(_within(start_profile, threshold, ends[i][0]))
            intervals.append(
                covering_levels_gap(profiled[i], positions, ends[i][0], 0.0, max_start)
            )
        saturation_intervals.append(
            covering_levels_gap(
                _within(saturation_profile, threshold, ends[i][1]),
                positions,
                ends[i][1],
                ends[i][0],
                max_saturation,
            )
        )
    increments = np.array(
        [signs[i] * coefficients[1 + 2 * i : 3 + 2 * i] for i in range(inputs)], dtype=float
    )
    starts = np.array([low[i] + span[i] * ends[i][0] for i in range(inputs)])
    saturations = np.array([low[i] + span[i] * ends[i][1] for i in range(inputs)])
    return StaticCurves(
        starts=starts,
        saturations=saturations,
        increments=increments,
        rest_output=float(coefficients[0] - coefficients[-1]),
        residual_rms=float(np.sqrt(sse / y.size)),
        start_intervals=np.array(
            [low[i] + span[i] * np.asarray(intervals[i]) for i in range(inputs)]
        ),
        profile_intervals=np.array(
            [low[i] + span[i] * np.asarray(profiled[i]) for i in range(inputs)]
        ),
        saturation_intervals=np.array(
            [low[i] + span[i] * np.asarray(saturation_intervals[i]) for i in range(inputs)]
        ),
        play_half_widths=tuple(float(span[i] * plays[i]) for i in range(inputs)),
        from_sections=tuple(i in sections for i in range(inputs)),
        straight_section_starts=tuple(
            low[i] + span[i] * sections[i].straight_start
            if i in sections and sections[i].bent
            else None
            for i in range(inputs)
        ),
        sections_read_apart=tuple(
            i in sections and sections[i].readings_apart for i in range(inputs)
        ),
        section_levels=read.in_sections,
        unread_section_levels=read.unread,
        settled_currents=tuple(u[(u[:, i] > 0.0) & others_shut(u, i), i] for i in range(inputs)),
    )


def _section_starts(
    levels: SettledLevels, fractions, level_holds, max_start, from_within, level_noise=None
):
    """The sections' ``_SectionsRead``: their starts, their levels, and those left unread.

    ``fractions`` (H, inputs) are every hold's currents as fractions of each input's range and
    ``level_holds`` (M,) the hold each level ends. None found where the levels outside the
    sections would leave some valve fewer than two distinct currents or the curves fewer than
    twice their parameters (each section's valve's start counted as found): they then stay in
    the fit. Counted as free, a record of 29 levels, 12 of them a section, was left 17 for the
    curves, one short of 18: the section stayed in the fit, which no sum of curves describes,
    and the outlet's curve came out 225 % of full scale off (the benchmark's plant with the inlet
    starting at 80 mA, seed 7 of a design since reverted); read, its starts were 2.2 and 0.3 mA
    off. ``level_noise`` goes to ``section_start``: with it, a section may be read bent.
    """
    masks = find_sections(levels.currents)
    in_sections = np.zeros(levels.outputs.size, dtype=bool)
    for mask in masks.values():
        in_sections |= mask
    if not masks or not enough_levels(levels.currents[~in_sections], fixed_starts=len(masks)):
        return _SectionsRead({}, np.zeros(levels.outputs.size, dtype=bool), int(in_sections.sum()))
    if from_within and levels.hold_first_samples is not None:
        masks = {valve: _within_or_all(levels, mask, valve) for valve, mask in masks.items()}
    found = {
        valve: section_start(
            fractions[:, valve],
            level_holds,
            levels.outputs,
            mask,
            max_start,
            level_noise,
            # Only a reading with the levels' noise can bend a hinge and ask which were refilled.
            None if level_noise is None else _refilled(levels, mask, valve),
        )
        for valve, mask in masks.items()
    }
    return _SectionsRead(found, in_sections, 0)


def _refilled(levels: SettledLevels, mask, valve) -> np.ndarray | None:
    """(M,) ``mask``'s levels approached from outside it; None where the holds are not known."""
    if levels.hold_first_samples is None:
        return None
    return mask & ~approached_within(
        levels.hold_currents, levels.hold_first_samples, levels.level_holds, mask, valve
    )


def _within_or_all(levels: SettledLevels, mask, valve) -> np.ndarray:
    """``mask``'s levels approached from within (``approached_within``), or all where too few."""
    within = approached_within(
        levels.hold_currents, levels.hold_first_samples, levels.level_holds, mask, valve
    )
    enough = np.unique(levels.currents[within, valve]).size >= MIN_SECTION_LEVELS
    return within if enough else mask


def _sweeps(spool, target, fixed, limits, plays, ends, signs, play_grid=None):
    """(plays, ends, signs, x) after fitting each valve in turn, the others' curves held.

    ``spool(i, half_width)`` gives valve i's spool positions at the levels, ``fixed`` each
    valve's start from its section (or None), ``limits`` (max_start, max_saturation). With a
    ``play_grid`` (half-widths) each free valve's play is searched over it together with its
    ends, and a valve's ends and play move only where the sum of squares drops: those sweeps
    never end worse than they began.
    """
    plays, ends, signs = list(plays), list(ends), list(signs)
    x = np.column_stack([spool(i, plays[i]) for i in range(len(plays))])
    for _ in range(_SWEEPS if play_grid is None else _PLAY_SWEEPS):
        for i in range(len(plays)):
            columns = _columns(x, ends, signs)
            held = columns[:i] + columns[i + 1 :]
            searched, incumbent = [plays[i]], None
            if play_grid is not None:
                incumbent = (ends[i], signs[i], plays[i])
                if fixed[i] is None:
                    searched = play_grid
            ends[i], signs[i], plays[i] = _profile(
                lambda w, i=i: spool(i, w), searched, target, held, *limits, fixed[i], incumbent
            )
            x[:, i] = spool(i, plays[i])
    return plays, ends, signs, x


def _significant_play(target, plain, played) -> bool:
    """Whether the ``played`` sweeps' fit beats the ``plain`` one by a likelihood-ratio test.

    Each is (plays, ends, signs, x) from ``_sweeps``. A play is one more parameter per valve, and
    with noisy levels some play always lowers the sum of squares a little; it is kept where the
    drop exceeds the 95 % point of chi-squared (one degree per play the sweeps changed) times
    the played fit's residual variance.
    """
    added = sum(a != b for a, b in zip(played[0], plain[0], strict=True))
    if added == 0:
        return False
    plain_sse = _nonnegative_fit(_columns(plain[3], *plain[1:3]), target)[0]
    played_sse = _nonnegative_fit(_columns(played[3], *played[1:3]), target)[0]
    inputs = len(played[0])
    variance = played_sse / max(1, target.outputs.size - parameter_count(inputs) - added)
    return plain_sse - played_sse > scipy.stats.chi2.ppf(0.95, added) * variance


def _columns(x, ends, signs):
    """Each valve's curve basis at its levels, times its sign."""
    return [_basis(x[:, i], *ends[i]) * signs[i] for i in range(x.shape[1])]


def _end_profiles(spool_of, plays, target, held, max_start, max_saturation, fixed_start=None):
    """The start's and the saturation's profiles on the coarse grid, the others' curves held.

    Each is (grid, the lowest sum of squares at each of its points), the sign and the play (over
    ``plays``) at their best, and the other end: the coarse grid's best, then searched within a
    grid step of it (golden section). One coarse pass serves both. Taken from the coarse grid
    alone, the start's profile rose faster than the fit's refined best: the interval shrank to a
    grid step either side of the best start and held the plant's start on 29 of 35 still
    patients (stop 42 of issue 14; README). With ``fixed_start`` (its section's) the start's
    profile is None and the saturation's is not refined.
    """
    starts = grid_starts(max_start) if fixed_start is None else np.array([fixed_start])
    pairs = np.asarray(coarse_pairs(starts, max_saturation))
    # Saturations repeat across starts; rounded, so that one value is one point of its profile.
    saturations, of_saturation = np.unique(np.round(pairs[:, 1], 9), return_inverse=True)
    by_start = _CoarseProfile(starts, np.searchsorted(starts, pairs[:, 0]), pairs[:, 1])
    by_saturation = _CoarseProfile(saturations, of_saturation, pairs[:, 0])
    for play in plays:
        sse = _lowest_sums(spool_of(play), target, held, pairs).min(axis=1)
        by_start.take(sse, play)
        by_saturation.take(sse, play)
    if fixed_start is not None:
        return None, (saturations, by_saturation.lowest)

    def start_ends(rows, chosen):
        return np.column_stack([starts[rows], chosen])

    def saturation_ends(rows, chosen):
        return np.column_stack([chosen, saturations[rows]])

    def saturation_bounds(rows):
        best = by_start.best_other[rows]
        low = np.maximum(best - _GRID_STEP, starts[rows] + _GRID_STEP)
        return low, np.minimum(best + _GRID_STEP, max_saturation)

    def start_bounds(rows):
        best = by_saturation.best_other[rows]
        low = np.maximum(best - _GRID_STEP, 0.0)
        high = np.minimum(best + _GRID_STEP, saturations[rows] - _GRID_STEP)
        return low, np.maximum(np.minimum(high, max_start), low)

    refined = []
    for profile, ends_of, bounds, tolerance in (
        (by_start, start_ends, saturation_bounds, 1e-7),
        (by_saturation, saturation_ends, start_bounds, _SATURATION_PROFILE_TOLERANCE),
    ):
        profile.refine(spool_of, target, held, ends_of, bounds, tolerance)
        refined.append((profile.grid, profile.lowest))
    return tuple(refined)


class _CoarseProfile:
    """One end's profile over the coarse grid, built play by play.

    Per point of ``grid``: its lowest sum of squares so far, and the other end and the play it
    was found at.
    """

    def __init__(self, grid, point_of_pair, other_of_pair):
        self.grid, self._point, self._other = grid, point_of_pair, other_of_pair
        self.lowest = np.full(grid.size, np.inf)
        self.best_other = np.zeros(grid.size)
        self.best_play = np.zeros(grid.size)

    def take(self, sse, play) -> None:
        """Each point's lowest pair at ``play``, kept where it beats the plays before.

        On equal sums the first pair counts.
        """
        order = np.lexsort((sse, self._point))
        first = order[np.r_[True, np.diff(self._point[order]) != 0]]
        better = sse[first] < self.lowest[self._point[first]]
        kept, rows = self._point[first][better], first[better]
        self.lowest[kept], self.best_other[kept], self.best_play[kept] = (
            sse[rows],
            self._other[rows],
            play,
        )

    def refine(self, spool_of, target, held, ends_of, bounds, tolerance) -> None:
        """Each point's other end searched within ``bounds(rows)`` at its play (golden section).

        ``ends_of(rows, other)`` gives the (start, saturation) pairs of those points; the search
        ends ``tolerance`` (a fraction of the range) from its best. Every point is searched in
        one batch, each at its own play's spool positions: searched play by play, the many small
        least-squares calls cost more in numpy's per-call overhead than in arithmetic.
        """
        rows = np.flatnonzero(np.isfinite(self.lowest))
        if rows.size == 0:
            return
        positions = np.stack([spool_of(play) for play in self.best_play[rows]])

        def sums(chosen):
            return _lowest_sums(positions, target, held, ends_of(rows, chosen)).min(axis=1)

        low, high = bounds(rows)
        refined = _golden_section(sums, low, high, tolerance)
        self.lowest[rows] = np.minimum(self.lowest[rows], refined)


def _golden_section(cost, low, high, tolerance=1e-7):
    """Per row, the lowest value of ``cost`` found in [low, high] by golden-section search.

    ``cost`` maps (R,) points to (R,) values, one per row; each row's bracket shrinks by 0.618 a
    step until the widest is ``tolerance`` (a fraction of the range). Vectorised over the rows,
    so each step is one grid least squares for every start, where scipy's scalar search would
    make one per start.
    """
    ratio = (np.sqrt(5.0) - 1.0) / 2.0
    a, b = np.array(low, float), np.array(high, float)
    c, d = b - ratio * (b - a), a + ratio * (b - a)
    fc, fd = cost(c), cost(d)
    best = np.minimum(fc, fd)
    for _ in range(
        int(np.ceil(np.log(max(np.max(b - a), tolerance) / tolerance) / -np.log(ratio)))
    ):
        left = fc < fd
        a, b = np.where(left, a, c), np.where(left, d, b)
        c_new, d_new = b - ratio * (b - a), a + ratio * (b - a)
        probe = np.where(left, c_new, d_new)
        f_probe = cost(probe)
        fc, fd = np.where(left, f_probe, fd), np.where(left, fc, f_probe)
        c, d = np.where(left, c_new, d), np.where(left, c, d_new)
        best = np.minimum(best, f_probe)
    return best


def _within(profile, threshold, best):
    """(lowest, highest) start (or saturation) with its coarse profile within ``threshold``."""
    grid, lowest = profile
    return profile_interval(grid, lowest, threshold, best, _GRID_STEP)


def _profile(
    spool_of, plays, target, held, max_start, max_saturation, fixed_start=None, incumbent=None
):
    """((start, saturation), sign, play) of one input's curve, by the grid and its refinement.

    The coarse grid is searched at every play of ``plays`` (half-widths; ``spool_of(play)`` the
    spool positions there), the refinement at the best one. With ``fixed_start`` (its section's,
    ``section_start``) only the saturation is searched; with ``incumbent`` (((start,
    saturation), sign, play)) that stays unless the grid beats it.
    """
    starts = grid_starts(max_start) if fixed_start is None else [fixed_start]
    coarse = coarse_pairs(starts, max_saturation)
    best = _best_of(spool_of, plays, target, held, coarse, incumbent)
    offsets = np.arange(-_GRID_STEP, _GRID_STEP + 1e-12, _REFINED_STEP)
    (start, saturation), _, play = best
    fine_starts = np.clip(start + offsets, 0.0, max_start) if fixed_start is None else [start]
    fine = [
        (s, c)
        for s in fine_starts
        for c in np.clip(saturation + offsets, 0.0, max_saturation)
        if c >= s + _GRID_STEP
    ]
    return _best_of(spool_of, [play], target, held, fine, best)


def grid_starts(max_start):
    """The coarse grid's starting currents, 0 to ``max_start`` (fractions of the range)."""
    return np.arange(0.0, max_start + 1e-12, _GRID_STEP)


def coarse_pairs(starts, max_saturation) -> list[tuple[float, float]]:
    """The coarse grid's (start, saturation) points: each start with each saturation past it."""
    return [(start, c) for start in starts for c in _grid_saturations(start, max_saturation)]


def _grid_saturations(start, max_saturation):
    """The coarse grid's saturation currents past ``start``, up to ``max_saturation``."""
    return np.arange(start + _GRID_STEP, max_saturation + 1e-12, _GRID_STEP)


def _best_of(spool_of, plays, target, held, ends, best=None):
    """((start, saturation), sign, play) of the lowest sum of squares over ``ends`` and ``plays``.

    ``best`` stays unless some point is strictly lower: ties go to the earlier (lower) play and
    point, the same on every run.
    """
    lowest = np.inf
    if best is not None:
        (incumbent_ends, sign, play) = best
        lowest = _lowest_sums(spool_of(play), target, held, [incumbent_ends])
        lowest = lowest[0, _SIGNS.index(sign)]
    for play in plays:
        sse = _lowest_sums(spool_of(play), target, held, ends).ravel()  # each point's signs in turn
        k = int(np.argmin(sse))
        if sse[k] < lowest:
            point = ends[k // len(_SIGNS)]
            lowest = sse[k]
            best = ((float(point[0]), float(point[1])), _SIGNS[k % len(_SIGNS)], float(play))
    return best


def _lowest_sums(x, target, held, ends) -> np.ndarray:
    """(len(ends), 2) the lowest sum of squares per (start, saturation) and sign (``_SIGNS``).

    ``x`` is (N,) spool positions at the levels, or (len(ends), N), each pair's own.
    """
    ends = np.asarray(ends, float)
    held = np.column_stack(held) if held else np.zeros((target.outputs.size, 0))
    candidates = basis_grid(x, ends[:, 0], ends[:, 1])
    return lowest_sums_of_squares(target.outputs, held, candidates, target.weights)


def _nonnegative_fit(columns, target):
    """(weighted sum of squares, [offset+, coefficients..., offset-]) of the outputs by columns.

    Every coefficient is at least zero; the offset, free, is the difference of two. Each row is
    scaled by the root of its weight.
    """
    ones = np.ones(target.outputs.size)
    root = np.sqrt(target.weights)
    matrix = np.column_stack([ones, *columns, -ones]) * root[:, None]
    coefficients, norm = scipy.optimize.nnls(matrix, target.outputs * root)
    return norm**2, coefficients


def _basis(x, start, saturation) -> np.ndarray:
    """(N, 2) monotone degree-2 Bernstein steps of t = (x - start) / (saturation - start)."""
    return basis_grid(x, np.array([start]), np.array([saturation]))[0]


def basis_grid(x, starts, saturations) -> np.ndarray:
    """(K, N, 2) ``_basis`` at each (start, saturation) of (K,) ``starts`` and ``saturations``.

    ``x`` is (N,) currents shared by every pair, or (K, N), each pair's own.
    """
    x = x if x.ndim == 2 else x[None, :]
    t = np.clip((x - starts[:, None]) / (saturations - starts)[:, None], 0.0, 1.0)
    return np.stack([1.0 - (1.0 - t) ** 2, t * t], axis=-1)
