"""A valve's starting current from a section: its settled levels with the other valve held open.

Why a section: a bladder at rest vents so little air through an outlet just past its start that
the outlet's settled levels alone place that start no closer than 10-25 mA (the plant's outlet
lifts the head 0.008 mm per mA there, against some 0.05 mm of scatter between settled levels).
With the inlet held open the same opening passes far more air, and its first milliamperes move
the head ten times as far. A sum of per-valve curves does not describe those levels (the flows
then balance at another pressure), so ``settled_curve`` keeps them out of the curves' fit and
reads each valve's start from its section alone, here:

- a section is the settled levels at which the other valves hold one and the same current, not
  all of them shut, with at least ``MIN_SECTION_LEVELS`` distinct currents of this valve: only a
  designed record has one (``valve_level_design.targeted_level_currents`` with
  ``other_valve_currents_a``), continuous random levels never repeat a current;
- near its start the output is a hinge, flat below it and straight above it:
  y = a + b max(0, p - s), a and b (either sign) by least squares at each start s of a grid;
- p is where the valve's spool rests, not its coil current: a proportional valve has play (its
  datasheet allows hysteresis of up to 10 % of the range, a half-width up to 5 %), so after a
  rise the spool rests at the lower edge of the band round the coil current, after a fall at its
  upper edge. The play operator p_k = min(max(p_(k-1), u_k - w), u_k + w), run over every hold of
  the record in turn, gives it; the half-width w is profiled over a grid with s. Unmodelled, the
  play scatters a section's levels by 2 w times its slope, more than the noise on the outlet;
- what the section cannot tell apart is reported as in ``settled_curve``: the starts whose
  profile (the lowest over w) is within chi2(1, 0.95) = 3.84 residual variances of the best
  (``profile_interval``), open-ended where the section's levels never reach past the start, and
  never narrower than the gaps between its levels about the starts it holds
  (``covering_levels_gap``): a section's output bends above the start, and a straight hinge
  through levels far above it reads the start where their line meets the flat. On patient 28
  of the standard population, still (stop 44 of issue 14), the outlet's section had no level
  between 54.8 and 81.3 mA, and its hinge put the start at 55.1 mA with an interval of
  53.3-58.3 mA (the plant's: 60 mA). A section approached from one side only cannot tell a
  start from a play band's shift of it, and its interval is then as wide as the widest play:
  levels approached alternately from shut and from the top (``targeted_level_currents``) see
  both edges and separate the two;
- above its start a section's slope can change once more, where the head leaves a travel stop:
  with the inlet at 190 mA, still patient 34 of the standard population rests on its upper stop
  (a stiff spring) until the outlet passes 81.5 mA, and its lift falls 0.035 mm per mA there,
  0.19 past it. The one hinge then meets the flat at that knee: with its advised holds (stop 46
  of issue 14) the outlet's start read 76.5 mA with an interval of 72.5-80.2 mA, and 76.5 mA
  (67.1-81.1) on the plant's noise-free lift at its spools, the plant's 60 mA, unwarned. So a
  second knot k above s is fitted too, y = a + b max(0, p - s) + c max(0, p - k), b and b + c of
  one sign (an opening valve only adds flow: a stop changes the lift's slope, never its
  direction). The start is read from it where three tests pass, at 95 % and with n >=
  ``MIN_BENT_SECTION_LEVELS`` levels; elsewhere the one hinge stands, bit for bit:
  1. the one hinge leaves more scatter than the record's noise: its residual variance over the
     level noise the curves' fit leaves on the other levels passes F(n - 4, their degrees of
     freedom), a lack-of-fit test (``settled_curve`` reads the sections again with that noise);
  2. the second knot lowers the sum of squares by more than F(2, n - 6) residual variances per
     added parameter (c and k: nested least squares);
  3. the bent hinge's first slope, its knots held, shows on the levels approached from within
     the section alone (``approached_within``): its t statistic past t(0.975), the variance
     the larger of theirs and the record's noise.
  Levels refilled from outside the section that had not settled (below) read low where the
  design puts them, just under the start, and bend a hinge as a knee does. On the 60 mA plant
  (seed 22 of ``benchmarks/hammerstein.py``, stop 47 of issue 14) three such levels read
  0.09-0.20 mm low: tests 1 and 2 alone passed (0.105 mm of scatter against the curves' 0.061
  mm; p = 0.012) and read the outlet's start 39 mA low, with an interval of 0-36.5 mA,
  unwarned. So in tests 1 and 2 the refilled levels have a level of their own (one parameter
  more): seed 22's scatter is then 0.081 mm, no lack of fit. Where the refilled levels are not
  all short, that offset does not absorb them (a planted section, ``tests/test_section_start``)
  and test 3 stops some. Still, the three cannot always tell a knee from such levels, so a
  bent reading's intervals cover the straight one's too (``SectionStart``), and a fit whose
  two readings' profile intervals do not meet warns. Patient 34's outlet reads 60.4 mA, its
  interval 47.1-80.2 mA, warned;
- a level whose hold followed one with the other valves elsewhere (shut, or at another current)
  began far from the section and may not have settled: the pneumatic plant's head, filled from
  207.6 to 225.7 mm with the inlet open, was still 0.02 mm short of its level a minute later (a
  time constant of about 9 s there; seed 46 of ``benchmarks/hammerstein.py``, true height), and
  such levels read about 0.13 mm low, about as far as the outlet's first milliampere moves the
  head there. On the true height that put the outlet's start 8.5-17.2 mA low (seeds 34, 46 and
  53). ``approached_within`` keeps the levels whose hold the section's own preceded
  (``targeted_level_currents`` with ``section_block`` holds them in one run).
"""

from dataclasses import dataclass

import numpy as np
import scipy.optimize
import scipy.stats

from maskless.analysis.identification.profile_interval import (
    CHI2_95,
    covering_levels_gap,
    profile_interval,
)

# Distinct currents of a valve that make a section: a hinge and a play width (4 parameters) with
# as many residual degrees of freedom left (convention).
MIN_SECTION_LEVELS = 6
# The play's half-width grid, as fractions of the valve's range: up to the datasheet's 10 %
# hysteresis (a half-width of 5 %), in steps of a quarter of a percent.
PLAY_HALF_WIDTHS = np.arange(0.0, 0.05 + 1e-12, 0.0025)
# The starts' grid step, as a fraction of the range (``settled_curve``'s refined step).
_START_STEP = 1.0 / 400.0
# Levels a section needs before a second knot is tried: its 6 parameters (two hinges, a level,
# a play width) and 2 residual degrees of freedom for the F test (module docstring).
MIN_BENT_SECTION_LEVELS = 8


@dataclass(frozen=True)
class SectionStart:
    """One valve's start from its section, in the fractions of its range the fit works in.

    Attributes:
        start: the best starting current.
        interval: (lowest, highest) start the section cannot tell apart: within the profile's
            95 % rise, or in the gap between its levels about the start.
        play_half_width: the play band's half-width at the best fit.
        profile_interval: (lowest, highest) start within the profile's 95 % rise alone.
        straight_start: where the start was read from the hinge bent once above it (module
            docstring), the plain hinge's start; else None. Both intervals then cover what
            either reading's does.
        readings_apart: where bent, whether the two readings' profile intervals do not meet.
    """

    start: float
    interval: tuple[float, float]
    play_half_width: float
    profile_interval: tuple[float, float]
    straight_start: float | None = None
    readings_apart: bool = False

    @property
    def bent(self) -> bool:
        """Whether the start was read from the bent hinge, not the plain one."""
        return self.straight_start is not None


def play_operator(currents: np.ndarray, half_width: float) -> np.ndarray:
    """Where a spool with play of ``half_width`` rests after each of ``currents`` in turn.

    It starts at the first current (the centre of its band) and moves only as far as the coil
    current leaving the band pushes it.
    """
    spool = np.empty(currents.size)
    position = currents[0] if currents.size else 0.0
    for k, current in enumerate(currents):
        position = min(max(position, current - half_width), current + half_width)
        spool[k] = position
    return spool


def find_sections(currents: np.ndarray) -> dict[int, np.ndarray]:
    """Per valve with a section (see the module docstring), the mask of its levels.

    Args:
        currents: (M, inputs) each settled level's currents.
    """
    found = {}
    for valve in range(currents.shape[1]):
        others = np.delete(currents, valve, axis=1)
        open_rows = np.any(others != 0.0, axis=1)
        keys, group = np.unique(others[open_rows], axis=0, return_inverse=True)
        best = None
        for index in range(keys.shape[0]):
            mask = np.zeros(currents.shape[0], dtype=bool)
            mask[np.flatnonzero(open_rows)[group.ravel() == index]] = True
            distinct = np.unique(currents[mask, valve]).size
            if distinct >= MIN_SECTION_LEVELS and (best is None or distinct > best[0]):
                best = (distinct, mask)
        if best is not None:
            found[valve] = best[1]
    return found


def approached_within(
    hold_currents: np.ndarray,
    hold_first_samples: np.ndarray,
    level_holds: np.ndarray,
    mask: np.ndarray,
    valve: int,
) -> np.ndarray:
    """(M,) ``mask`` less the levels whose hold was approached from outside their section.

    A level counts where the hold before its own held the other valves at its currents. Holds
    of one sample are passed over: they are a design's approaches (``targeted_level_currents``
    pushes the valve to shut or to its top for a sample to choose the edge of its play band).
    The record's first hold has nothing before it and does not count.

    Args:
        hold_currents: (H, inputs) every hold's currents, in order.
        hold_first_samples: (H,) the sample each hold begins at.
        level_holds: (M,) the hold each settled level ends.
        mask: (M,) the section's levels.
        valve: the valve the section is of.
    """
    lengths = np.diff(hold_first_samples)
    others = np.delete(hold_currents, valve, axis=1)
    kept = np.array(mask, dtype=bool)
    for level in np.flatnonzero(kept):
        before = level_holds[level] - 1
        while before >= 0 and lengths[before] < 2:
            before -= 1
        kept[level] = before >= 0 and np.array_equal(others[before], others[level_holds[level]])
    return kept


def section_start(
    hold_currents: np.ndarray,
    level_holds: np.ndarray,
    outputs: np.ndarray,
    mask: np.ndarray,
    max_start: float,
    level_noise: tuple[float, int] | None = None,
    refilled: np.ndarray | None = None,
) -> SectionStart:
    """The valve's start from the levels in ``mask`` (see the module docstring).

    Starts are searched from a play band's width below the section's lowest level to its highest
    (clipped to 0 and ``max_start``). Where the profile is still within the interval's rise at
    an end of that search, the data cannot bound the start there: the interval reaches 0 or
    ``max_start``.

    Args:
        hold_currents: (H,) the valve's current over every hold of the record, in order, as
            fractions of its range.
        level_holds: (M,) the hold each settled level is the end of.
        outputs: (M,) the settled levels' outputs.
        mask: (M,) the section's levels.
        max_start: the highest start allowed, as a fraction of the range.
        level_noise: (variance, degrees of freedom) of a settled level's noise, from levels
            outside the section; without it the hinge is never bent (no lack of fit to test).
        refilled: (M,) the levels whose hold was approached from outside the section (not
            ``approached_within``): a bent hinge's first slope must show without them.
    """
    y = outputs[mask] - outputs[mask].mean()
    levels = hold_currents[level_holds[mask]]
    lowest = max(levels.min() - PLAY_HALF_WIDTHS[-1], 0.0)
    starts = np.arange(lowest, min(levels.max(), max_start) + 1e-12, _START_STEP)
    # Where the spool rests at each level, per half-width: the best one's also bounds the gap.
    spools = [play_operator(hold_currents, w)[level_holds[mask]] for w in PLAY_HALF_WIDTHS]
    # (half-widths, starts) residual sum of squares of the best hinge.
    hinged = np.array([_hinge_sums(spool, y, starts) for spool in spools])
    straight = _reading(hinged, 4, starts, spools, max_start)
    bent = None
    if level_noise is not None and y.size >= MIN_BENT_SECTION_LEVELS:
        within = None if refilled is None else ~refilled[mask]
        bent = _bent_if_tests_pass(spools, y, starts, level_noise, within)
    if bent is None:
        return straight
    read = _reading(bent, 6, starts, spools, max_start)
    # Both readings stand in the intervals: the tests can be passed by levels that had not
    # settled as well as by a knee (module docstring).
    return SectionStart(
        start=read.start,
        interval=_spanning(read.interval, straight.interval),
        play_half_width=read.play_half_width,
        profile_interval=_spanning(read.profile_interval, straight.profile_interval),
        straight_start=straight.start,
        readings_apart=(
            read.profile_interval[1] < straight.profile_interval[0]
            or straight.profile_interval[1] < read.profile_interval[0]
        ),
    )


def _spanning(first: tuple[float, float], second: tuple[float, float]) -> tuple[float, float]:
    """The interval from the lower of two intervals' lows to the higher of their highs."""
    return min(first[0], second[0]), max(first[1], second[1])


def _reading(sse, parameters: int, starts, spools, max_start: float) -> SectionStart:
    """The start and intervals of a hinge's (half-widths, starts) sums, ``parameters`` fitted.

    The profile interval reaches 0 or ``max_start`` where it is still within its rise at that
    end of the search (``section_start``).
    """
    levels = spools[0].size
    # The lowest sum of squares (on exact ties the first: the narrowest play, the lowest start).
    row, column = np.unravel_index(np.argmin(sse), sse.shape)
    profile = sse.min(axis=0)
    threshold = sse[row, column] * (1.0 + CHI2_95 / max(1, levels - parameters))
    low, high = profile_interval(starts, profile, threshold, starts[column], _START_STEP)
    # The profile crosses its threshold somewhere between grid points: a step past each end.
    low, high = max(low - _START_STEP, 0.0), high + _START_STEP
    if profile[0] <= threshold:  # no worse at the search's bottom: unbounded below
        low = 0.0
    if profile[-1] <= threshold:  # nor at its top: the hinge may lie above every level
        high = max_start
    profiled = (low, min(high, max_start))
    return SectionStart(
        start=float(starts[column]),
        interval=covering_levels_gap(profiled, spools[row], starts[column], 0.0, max_start),
        play_half_width=float(PLAY_HALF_WIDTHS[row]),
        profile_interval=profiled,
    )


def _bent_if_tests_pass(spools, y, starts, level_noise, within):
    """(half-widths, starts) the bent hinge's sums where it is to be read; else None.

    Three tests (module docstring): the plain hinge lacks fit and a second knot fits past
    chance, both with the levels refilled from outside the section (not ``within`` (n,))
    given an offset of their own where some are; and the bent hinge's first slope shows on the
    levels approached from within (not tested where ``within`` is None: holds not known).
    """
    refilled = None if within is None or within.all() or not within.any() else ~within
    offsets = 0 if refilled is None else 1
    centred = _centred(y, refilled)
    plains = np.array([_hinge_sums(spool, centred, starts, refilled) for spool in spools])
    # The plain hinge's start off the grid: two knots a step apart bracket a start between
    # grid points and would pass the test on the grid's error alone.
    row, column = np.unravel_index(np.argmin(plains), plains.shape)
    plain = _off_grid_hinge_sum(spools[row], centred, starts[column], refilled)
    if not _lacks_fit(plain, y.size - 4 - offsets, level_noise):
        return None
    bent = min(_bent_hinge_sums(spool, centred, starts, refilled).min() for spool in spools)
    if not _second_knot_significant(plain, bent, centred, y.size - 6 - offsets):
        return None
    sums = np.array([_bent_hinge_sums(spool, y, starts) for spool in spools])
    if within is not None:
        row = np.unravel_index(np.argmin(sums), sums.shape)[0]
        start, knot, slope = _best_pair(spools[row], y, starts)
        if not _first_slope_shows(
            spools[row][within], y[within], (start, knot, slope), level_noise
        ):
            return None
    return sums


def _centred(values: np.ndarray, refilled: np.ndarray | None) -> np.ndarray:
    """``values`` less their mean down axis 0, or less the mean of each of two groups.

    ``refilled`` (n,) splits the rows in two: the levels refilled from outside the section get
    a level of their own, for the shortfall of their unsettled approach.
    """
    if refilled is None:
        return values - values.mean(axis=0)
    centred = np.array(values, dtype=float)
    for group in (refilled, ~refilled):
        centred[group] -= centred[group].mean(axis=0)
    return centred


def _first_slope_shows(spool, y, bent_hinge, level_noise) -> bool:
    """Whether these levels show ``bent_hinge``'s first slope, of its sign.

    ``bent_hinge`` (start, knot, first slope). y on 1, max(0, p - start) and max(0, p - knot)
    by least squares: the first slope's t statistic past t(0.975), its variance the larger of
    these levels' residual one and ``level_noise``'s (a few levels can fit three parameters by
    chance: on the 60 mA plant's seed 22, six fitted to 0.02 mm, the record's noise 0.06 mm).
    Levels refilled from outside a section that had not settled read low just below its start
    and bend a hinge there (module docstring); the levels approached from within it are not
    touched.
    """
    start, knot, slope = bent_hinge
    columns = np.column_stack(
        [np.ones(y.size), np.maximum(spool - start, 0.0), np.maximum(spool - knot, 0.0)]
    )
    dof = y.size - 3
    if dof < 1 or np.linalg.matrix_rank(columns) < 3:
        return False
    fitted, residual, _, _ = np.linalg.lstsq(columns, y, rcond=None)
    if fitted[1] * slope <= 0.0:
        return False
    variance, dof = max((float(residual[0]) / dof if residual.size else 0.0, dof), level_noise)
    if variance == 0.0:
        return True
    spread = np.linalg.inv(columns.T @ columns)[1, 1]
    return bool(abs(fitted[1]) / np.sqrt(variance * spread) > scipy.stats.t.ppf(0.975, dof))


def _hinge_sums(spool, y, starts, refilled=None) -> np.ndarray:
    """(G,) the residual sum of squares of ``y`` (centred) on a + b max(0, spool - s), per s.

    With ``refilled``, ``y`` centred as ``_centred`` does, and a level of their own for them.
    """
    hinge = _centred(np.maximum(spool[:, None] - starts[None, :], 0.0), refilled)
    spread = np.sum(hinge**2, axis=0)
    along = y @ hinge
    explained = np.divide(along**2, spread, out=np.zeros_like(spread), where=spread > 0)
    # Rounding can leave an exact fit a hair below zero.
    return np.maximum(y @ y - explained, 0.0)


def _off_grid_hinge_sum(spool, y, start, refilled=None) -> float:
    """The plain hinge's lowest residual sum of squares within a grid step of ``start``."""
    found = scipy.optimize.minimize_scalar(
        lambda s: _hinge_sums(spool, y, np.array([s]), refilled)[0],
        bounds=(start - _START_STEP, start + _START_STEP),
        method="bounded",
        options={"xatol": 1e-9},
    )
    return min(float(found.fun), float(_hinge_sums(spool, y, np.array([start]), refilled)[0]))


def _bent_pairs(spool, y, starts, refilled=None):
    """(first, knot, sums, slopes): every pair of grid indices s < k, with its sum of squares.

    y (centred) on a + b max(0, spool - s) + c max(0, spool - k), b and b + c of one sign
    (module docstring), by the 2x2 normal equations of the centred hinges, all pairs at once;
    ``sums`` inf where the signs differ or the two hinges coincide at every level (no level
    between s and k); ``slopes`` (b) the first slope. ``refilled`` as in ``_hinge_sums``.
    """
    hinge = _centred(np.maximum(spool[:, None] - starts[None, :], 0.0), refilled)
    gram, along = hinge.T @ hinge, y @ hinge
    first, knot = np.triu_indices(starts.size, 1)
    s11, s12, s22 = gram[first, first], gram[first, knot], gram[knot, knot]
    determinant = s11 * s22 - s12**2
    solvable = determinant > 1e-12 * s11 * s22
    safe = np.where(solvable, determinant, 1.0)
    slope = (s22 * along[first] - s12 * along[knot]) / safe
    bend = (s11 * along[knot] - s12 * along[first]) / safe
    explained = slope * along[first] + bend * along[knot]
    allowed = solvable & (slope * (slope + bend) >= 0.0)
    sums = np.where(allowed, np.maximum(y @ y - explained, 0.0), np.inf)
    return first, knot, sums, slope


def _bent_hinge_sums(spool, y, starts, refilled=None) -> np.ndarray:
    """(G,) per start s, the lowest residual sum of squares of a hinge at s bent once above it.

    Over every knot k > s of ``starts`` (``_bent_pairs``), and no lower than the plain hinge at
    s (c = 0).
    """
    first, _, sums, _ = _bent_pairs(spool, y, starts, refilled)
    lowest = np.full(starts.size, np.inf)
    np.minimum.at(lowest, first, sums)
    return np.minimum(lowest, _hinge_sums(spool, y, starts, refilled))


def _best_pair(spool: np.ndarray, y: np.ndarray, starts: np.ndarray):
    """(start, knot, first slope) of the bent hinge with the lowest sum of squares."""
    first, knot, sums, slopes = _bent_pairs(spool, y, starts)
    best = int(np.argmin(sums))
    return float(starts[first[best]]), float(starts[knot[best]]), float(slopes[best])


def _lacks_fit(sse: float, residual_dof: int, level_noise: tuple[float, int]) -> bool:
    """Whether ``sse`` over ``residual_dof`` exceeds the levels' noise past chance (F, 95 %)."""
    variance, noise_dof = level_noise
    if not variance > 0.0:
        return sse > 0.0
    return bool(sse / residual_dof / variance > scipy.stats.f.ppf(0.95, residual_dof, noise_dof))


def _second_knot_significant(hinge_sse: float, bent_sse: float, y, residual_dof: int) -> bool:
    """Whether a second knot (2 more parameters) fits ``y`` past chance: the F test at 95 %."""
    gain = hinge_sse - bent_sse
    # An exact hinge leaves both sums at rounding's size: nothing for a second knot to explain.
    if gain <= 1e-9 * float(y @ y):
        return False
    return bool(gain / 2.0 > scipy.stats.f.ppf(0.95, 2, residual_dof) * bent_sse / residual_dof)
