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
  direction), and the start and its interval are read from it where it lowers the sum of
  squares by more than F(2, n - 6, 0.95) residual variances per added parameter (c and k: an F
  test of nested least squares; with n >= ``MIN_BENT_SECTION_LEVELS`` levels); elsewhere the one
  hinge stands, bit for bit. Patient 34's outlet then reads 60.4 mA (47.1-65.0);
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
        bent: whether the start was read from the hinge bent once above it (a second knot
            passed the F test), not from the plain hinge.
    """

    start: float
    interval: tuple[float, float]
    play_half_width: float
    profile_interval: tuple[float, float]
    bent: bool = False


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
    """
    y = outputs[mask] - outputs[mask].mean()
    levels = hold_currents[level_holds[mask]]
    lowest = max(levels.min() - PLAY_HALF_WIDTHS[-1], 0.0)
    starts = np.arange(lowest, min(levels.max(), max_start) + 1e-12, _START_STEP)
    # Where the spool rests at each level, per half-width: the best one's also bounds the gap.
    spools = [play_operator(hold_currents, w)[level_holds[mask]] for w in PLAY_HALF_WIDTHS]
    # (half-widths, starts) residual sum of squares of the best hinge, and of the best bent one.
    hinged = np.array([_hinge_sums(spool, y, starts) for spool in spools])
    sse, parameters, bent_read = hinged, 4, False
    if y.size >= MIN_BENT_SECTION_LEVELS:
        bent = np.array([_bent_hinge_sums(spool, y, starts) for spool in spools])
        # The plain hinge's start off the grid: two knots a step apart bracket a start between
        # grid points and would pass the test on the grid's error alone.
        row, column = np.unravel_index(np.argmin(hinged), hinged.shape)
        plain = _off_grid_hinge_sum(spools[row], y, starts[column])
        if _second_knot_significant(plain, bent.min(), y):
            sse, parameters, bent_read = bent, 6, True
    # The lowest sum of squares (on exact ties the first: the narrowest play, the lowest start).
    row, column = np.unravel_index(np.argmin(sse), sse.shape)
    profile = sse.min(axis=0)
    threshold = sse[row, column] * (1.0 + CHI2_95 / max(1, y.size - parameters))
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
        bent=bent_read,
    )


def _hinge_sums(spool: np.ndarray, y: np.ndarray, starts: np.ndarray) -> np.ndarray:
    """(G,) the residual sum of squares of ``y`` (centred) on a + b max(0, spool - s), per s."""
    hinge = np.maximum(spool[:, None] - starts[None, :], 0.0)
    hinge -= hinge.mean(axis=0)
    spread = np.sum(hinge**2, axis=0)
    along = y @ hinge
    explained = np.divide(along**2, spread, out=np.zeros_like(spread), where=spread > 0)
    # Rounding can leave an exact fit a hair below zero.
    return np.maximum(y @ y - explained, 0.0)


def _off_grid_hinge_sum(spool: np.ndarray, y: np.ndarray, start: float) -> float:
    """The plain hinge's lowest residual sum of squares within a grid step of ``start``."""
    found = scipy.optimize.minimize_scalar(
        lambda s: _hinge_sums(spool, y, np.array([s]))[0],
        bounds=(start - _START_STEP, start + _START_STEP),
        method="bounded",
        options={"xatol": 1e-9},
    )
    return min(float(found.fun), float(_hinge_sums(spool, y, np.array([start]))[0]))


def _bent_hinge_sums(spool: np.ndarray, y: np.ndarray, starts: np.ndarray) -> np.ndarray:
    """(G,) per start s, the lowest residual sum of squares of a hinge at s bent once above it.

    y (centred) on a + b max(0, spool - s) + c max(0, spool - k) over every knot k > s of
    ``starts``, with b and b + c of one sign (module docstring); no lower than the plain hinge
    at s (c = 0). All pairs at once, by the 2x2 normal equations of the centred hinges.
    """
    hinge = np.maximum(spool[:, None] - starts[None, :], 0.0)
    hinge -= hinge.mean(axis=0)
    gram, along = hinge.T @ hinge, y @ hinge
    first, knot = np.triu_indices(starts.size, 1)
    s11, s12, s22 = gram[first, first], gram[first, knot], gram[knot, knot]
    determinant = s11 * s22 - s12**2
    # Two hinges that coincide at every level (no level between s and k) add nothing.
    solvable = determinant > 1e-12 * s11 * s22
    safe = np.where(solvable, determinant, 1.0)
    slope = (s22 * along[first] - s12 * along[knot]) / safe
    bend = (s11 * along[knot] - s12 * along[first]) / safe
    explained = slope * along[first] + bend * along[knot]
    allowed = solvable & (slope * (slope + bend) >= 0.0)
    sums = np.full(starts.size, np.inf)
    np.minimum.at(sums, first[allowed], np.maximum(y @ y - explained[allowed], 0.0))
    return np.minimum(sums, _hinge_sums(spool, y, starts))


def _second_knot_significant(hinge_sse: float, bent_sse: float, y: np.ndarray) -> bool:
    """Whether a second knot (2 more parameters) fits ``y`` past chance: the F test at 95 %."""
    gain = hinge_sse - bent_sse
    # An exact hinge leaves both sums at rounding's size: nothing for a second knot to explain.
    if gain <= 1e-9 * float(y @ y):
        return False
    critical = scipy.stats.f.ppf(0.95, 2, y.size - 6)
    return bool(gain / 2.0 > critical * bent_sse / (y.size - 6))
