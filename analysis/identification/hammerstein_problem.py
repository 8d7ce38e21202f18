"""The Hammerstein fit's search problem: the parameter vector, the criterion and the start.

``analysis.identification.hammerstein`` runs the search; this module says what it searches over.

Choices, and why:

- **The map is piecewise linear on knots**, spread evenly between an explicit starting current
  s_i (flat at 0 below) and saturation current c_i (flat at 1 above). A valve's physics has exactly
  those two kinks (its opening is clamped there), which a smooth basis would round off and a
  polynomial could not place; between them a few linear pieces follow the flow law's curvature.
  It is monotone by construction: the openings at the knots are the cumulative sums of a softmax,
  positive increments that sum to 1. A segment the search makes flat at either end moves the
  reported starting (saturation) current to where the map really leaves 0 (reaches 1).
- **The scale ambiguity** (a map times g with B_i / g gives the same output) **is fixed by
  f_i(c_i) = 1**: the map is the fraction open, and B_i(1)/A(1) carries the valve's whole steady
  effect. The static curve reported is that DC gain times the map.
- **A(q) is stable by construction**: it is built from reflection coefficients tanh(rho_j), each
  in (-1, 1) (the Schur-Cohn step-up recursion), so the simulation never explodes mid-search.
- **The joint search's start**: for each pair of starting currents on a grid, the
  overparameterised ARX (each lagged input expanded in the map's hat basis, linear least squares)
  split into B_i and f_i by a rank-one SVD (Bai 1998); the few grid points whose models simulate
  best each start the search. s_i is a logistic function of its parameter and c_i one between s_i
  and past the data, so both stay in range with no bounds.
"""

import itertools

import numpy as np
import scipy.signal

from maskless.analysis.identification.prediction_error import roots_mirrored_inside
from maskless.errors import ModelError
from maskless.systems.hammerstein_model import HammersteinModel
from maskless.systems.plant.valve_map import ValveMap

# Starting currents tried for the initial guess, as fractions of each input's range in the data.
_START_GRID = np.linspace(0.0, 0.6, 13)
# The best starting guesses the search is run from (the best final cost is kept).
_SEARCH_STARTS = 4
# The narrowest map allowed, as a fraction of the input's range: knots closer than this would make
# the map a step, which no valve is and no finite difference can differentiate.
_MIN_SPAN_FRACTION = 0.05
# The highest starting current allowed, as a fraction of the input's range: above it too little of
# the data would show the map's slope.
MAX_START = 1.0 - _MIN_SPAN_FRACTION
# The highest saturation current allowed, as a fraction of the input's range above its lowest
# value: a saturation past the data (above 1) says the record never reached it.
MAX_SATURATION = 1.5
# A linear model's map is affine over this many input ranges around the data, so it stays linear
# wherever a validation record is likely to go.
_LINEAR_MAP_WIDTH = 21.0
# An opening within this of 0 (of 1) is taken as shut (as fully open) when the map's ends are
# reported: a thousandth of the valve's effect, below what a record resolves. (A floor on each
# segment's rise would keep segments from going flat, but it also forbids a flat top that the
# search needs to place saturation where a valve's map really is flat.)
_FLAT = 1e-3
# Reflection coefficients are kept within this of +-1, so tanh's inverse stays finite.
_REFLECTION_LIMIT = 1.0 - 1e-9


def reflection_polynomial(reflections) -> np.ndarray:
    """a1..an of A(q) = 1 + a1 q^-1 + ... from reflection coefficients (the step-up recursion).

    Every |k_j| < 1 gives a polynomial with every root strictly inside the unit circle.
    """
    polynomial = np.array([1.0])
    for k in reflections:
        extended = np.concatenate([polynomial, [0.0]])
        polynomial = extended + k * extended[::-1]
    return polynomial[1:]


def polynomial_reflections(a) -> np.ndarray:
    """The reflection coefficients of 1 + a1 q^-1 + ..., after mirroring any root outside into it.

    The inverse of ``reflection_polynomial`` (the step-down recursion) for a stable polynomial; an
    unstable one is first made stable with the same magnitude response shape.
    """
    roots, outside = roots_mirrored_inside(a)
    roots[outside] *= _REFLECTION_LIMIT
    polynomial = np.real(np.poly(roots))
    reflections = []
    while polynomial.size > 1:
        k = float(np.clip(polynomial[-1], -_REFLECTION_LIMIT, _REFLECTION_LIMIT))
        reflections.append(k)
        polynomial = (polynomial - k * polynomial[::-1])[:-1] / (1.0 - k * k)
    return np.array(reflections[::-1])


class HammersteinProblem:
    """The record in normalised units and the parameter vector's layout.

    Currents are scaled to [0, 1] over each input's range in the data and the output to zero mean
    and unit spread, so one finite-difference step and one trust region suit every parameter. The
    vector is [rho (n); per input b_i (n), s_i, span_i, softmax logits (segments - 1); y_op]; a
    linear model has no s, span or logits. With ``curves`` (``settled_curve.StaticCurves``) each
    map and DC gain is theirs, fixed: per input only b_i2..b_in, b_i1 making B_i(1) / A(1) the
    curve's gain. ``pole_radius`` bounds A(q)'s poles: with the curves fixed, the search otherwise
    puts a pole within 1e-5 of 1 with a zero all but cancelling it, a slow drift no design can
    use; the curves assume the plant settles as the record's ARX model's slowest pole does, so
    the dynamics get no slower pole. ``counted`` (N,) leaves samples out of the criterion and the
    ARX start (the simulation still runs through them): stretches no sum of the maps describes.
    """

    def __init__(
        self, u, y, order, segments, delay, linear, curves=None, pole_radius=None, counted=None
    ):
        """Normalises the record (a checked one: ``hammerstein._checked_record``)."""
        self.order, self.segments, self.delay, self.linear = order, segments, delay, linear
        # The samples the criterion and the ARX start count; None: all, with no indexing added to
        # each of the search's thousands of evaluations.
        self.counted = counted
        self.inputs = u.shape[1]
        self.u_low, self.u_range = u.min(axis=0), np.ptp(u, axis=0)
        self.y_mean, self.y_scale = float(y.mean()), float(np.std(y))
        self.u = (u - self.u_low) / self.u_range
        self.y = (y - self.y_mean) / self.y_scale
        self.fixed_maps, self.fixed_gains = None, None
        # A(q)'s coefficients scale by radius^k: every pole within the radius.
        self.pole_scales = (pole_radius or 1.0) ** np.arange(1, order + 1)
        if curves is not None:
            knots = [curves.map_knots(i) for i in range(self.inputs)]
            self.fixed_maps = [
                ((currents - self.u_low[i]) / self.u_range[i], openings)
                for i, (currents, openings) in enumerate(knots)
            ]
            self.fixed_gains = curves.gains() / self.y_scale
        # Per input: b_i, then the map's start, span and logits. With curves only b_i2..b_in:
        # b_i1 follows from the curve's gain.
        self.input_size = order + (0 if linear else 2 + (segments - 1))
        if curves is not None:
            self.input_size = order - 1
        self.size = order + self.inputs * self.input_size + 1

    # --- the parameter vector -------------------------------------------------------------------

    def unpack(self, theta):
        """(a (inputs, n), b (inputs, n), [(knots, openings) per input], y_op), normalised."""
        n = self.order
        a = reflection_polynomial(np.tanh(theta[:n])) * self.pole_scales
        b, maps = [], []
        for i in range(self.inputs):
            block = theta[n + i * self.input_size : n + (i + 1) * self.input_size]
            if self.fixed_maps is not None:
                tail = block[: n - 1]
                b.append(
                    np.concatenate([[self.fixed_gains[i] * (1.0 + a.sum()) - tail.sum()], tail])
                )
                maps.append(self.fixed_maps[i])
                continue
            b.append(block[:n])
            maps.append(self._map(block[n:]))
        return np.tile(a, (self.inputs, 1)), np.array(b), maps, theta[-1]

    def _map(self, parameters):
        if self.linear:
            middle = 0.5
            half = 0.5 * _LINEAR_MAP_WIDTH
            return np.array([middle - half, middle + half]), np.array([0.0, 1.0])
        start = MAX_START * _logistic(parameters[0])
        room = MAX_SATURATION - start - _MIN_SPAN_FRACTION
        span = _MIN_SPAN_FRACTION + room * _logistic(parameters[1])
        logits = parameters[2:]
        weights = np.exp(np.concatenate([[0.0], logits]) - max(0.0, logits.max(initial=0.0)))
        openings = np.concatenate([[0.0], np.cumsum(weights) / weights.sum()])
        openings[-1] = 1.0
        return start + span * np.linspace(0.0, 1.0, self.segments + 1), openings

    # --- the criterion --------------------------------------------------------------------------

    def simulate(self, theta):
        """The normalised output simulated at ``theta``, from rest at the first currents."""
        a, b, maps, y_op = self.unpack(theta)
        y = np.full(self.y.size, y_op)
        for i, (knots, openings) in enumerate(maps):
            denominator = np.concatenate([[1.0], a[i]])
            f = np.interp(self.u[:, i], knots, openings)
            numerator = np.concatenate([np.zeros(self.delay), b[i]])
            start = scipy.signal.lfilter_zi(numerator, denominator) * f[0]
            y += scipy.signal.lfilter(numerator, denominator, f, zi=start)[0]
        return y

    def residuals(self, theta):
        """The simulation's errors (normalised)."""
        error = self._counted(self.y - self.simulate(theta))
        if not np.all(np.isfinite(error)):
            # Finite and large: the search turns back instead of stopping on a NaN.
            return np.full(error.size, 1e3)
        return error

    def _counted(self, samples):
        """``samples`` (N, ...) at the counted samples only."""
        return samples if self.counted is None else samples[self.counted]

    def cost(self, theta) -> float:
        """The sum of the squared residuals."""
        residuals = self.residuals(theta)
        return float(residuals @ residuals)

    # --- the start ------------------------------------------------------------------------------

    def initial_guesses(self) -> list:
        """The best-simulating rank-one splits of the basis-expanded ARX over the start grid.

        ``_SEARCH_STARTS`` of them, best first: the output-error cost of a mis-specified structure
        (a plant whose time constants change with its level) has local minima, and the search
        from each ends in its own.
        """
        grid = [_START_GRID] * self.inputs
        if self.linear or self.fixed_maps is not None:
            grid = [(None,)] * self.inputs
        scored = []
        for starts in itertools.product(*grid):
            theta = self._arx_start(starts)
            cost = self.cost(theta)
            if np.isfinite(cost):
                scored.append((cost, len(scored), theta))
        if not scored:  # no ARX fit was usable: slow stable poles, no gain, maps at mid range
            return [self._arx_start((0.25,) * self.inputs, fallback=True)]
        scored.sort(key=lambda entry: entry[:2])
        return [theta for *_, theta in scored[:_SEARCH_STARTS]]

    def _basis(self, starts):
        """Per input, the (N, segments) hat-basis values of its map, and the map's knot layout."""
        columns, layouts = [], []
        for i, start in enumerate(starts):
            if self.linear or self.fixed_maps is not None:
                column = self.u[:, [i]]
                if self.fixed_maps is not None:
                    column = np.interp(column, *self.fixed_maps[i])
                columns.append(column)
                layouts.append(None)
                continue
            knots = start + (1.0 - start) * np.linspace(0.0, 1.0, self.segments + 1)
            unit = np.eye(self.segments + 1)
            # Past the last knot np.interp holds every hat at its end value: 0 but the last, 1,
            # as the map is held at 1 past saturation.
            hats = [np.interp(self.u[:, i], knots, unit[j]) for j in range(1, self.segments + 1)]
            columns.append(np.column_stack(hats))
            layouts.append((start, 1.0 - start))
        return columns, layouts

    def _arx_start(self, starts, fallback=False):
        n, d = self.order, self.delay
        columns, layouts = self._basis(starts)
        width = 1 if self.linear or self.fixed_maps is not None else self.segments
        if fallback:
            reflections = np.clip(polynomial_reflections(np.poly([0.9] * n)[1:]), -0.99, 0.99)
        else:
            lag = n + d - 1
            rows = self.y.size - lag
            regressors = [-self.y[lag - j : lag - j + rows] for j in range(1, n + 1)]
            for basis in columns:
                for j in range(n):
                    shift = d + j
                    regressors.append(basis[lag - shift : lag - shift + rows])
            regressors.append(np.ones((rows, 1)))
            matrix = np.column_stack(regressors)
            target = self.y[lag:]
            if self.counted is not None:
                # A row counts when its output and every lagged sample it reads are counted.
                window = np.lib.stride_tricks.sliding_window_view(self.counted, lag + 1)
                rows_counted = window.all(axis=1)
                matrix, target = matrix[rows_counted], target[rows_counted]
            # The normal equations: a few dozen columns, and a Gram matrix is one product where a
            # tall QR or SVD is many (and slow when BLAS threads compete for cores).
            solution, *_ = np.linalg.lstsq(matrix.T @ matrix, matrix.T @ target, rcond=None)
            reflections = polynomial_reflections(solution[:n] / self.pole_scales)
        theta = np.zeros(self.size)
        theta[:n] = np.arctanh(reflections)
        for i in range(self.inputs):
            block = np.zeros(self.input_size)
            if self.fixed_maps is not None:
                # b_i1 follows from the fixed gain: only the rest of the ARX's b_i is kept.
                block[:] = 0.0 if fallback else solution[n + i * n + 1 : n + (i + 1) * n]
                theta[n + i * self.input_size : n + (i + 1) * self.input_size] = block
                continue
            if fallback:
                gains, openings = np.zeros(n), np.linspace(0.0, 1.0, width + 1)
            else:
                stacked = solution[n + i * n * width : n + (i + 1) * n * width].reshape(n, width)
                gains, openings = self._rank_one(stacked)
            if self.linear:
                # The map is affine over _LINEAR_MAP_WIDTH ranges: B per unit of it.
                block[:n] = gains * _LINEAR_MAP_WIDTH
            else:
                block[:n] = gains
                start, span = layouts[i]
                room = MAX_SATURATION - start - _MIN_SPAN_FRACTION
                block[n] = _logit(start / MAX_START)
                block[n + 1] = _logit((span - _MIN_SPAN_FRACTION) / room)
                increments = np.maximum(np.diff(openings), 1e-3)
                block[n + 2 :] = np.log(increments[1:] / increments[0])
            theta[n + i * self.input_size : n + (i + 1) * self.input_size] = block
        if not fallback:
            # y_op: the output the model leaves with no input at all, fitted afresh for the
            # simulated (not one-step) criterion.
            theta[-1] = float(np.mean(self._counted(self.y - self.simulate(theta))))
        return theta

    @staticmethod
    def _rank_one(stacked):
        """(b, openings at the knots): the best rank-one b vᵀ of the lag-by-knot coefficients.

        Normalised so the opening at the last knot is 1 and made monotone by its running maximum.
        """
        left, singular, right = np.linalg.svd(stacked, full_matrices=False)
        b, v = left[:, 0] * singular[0], right[0]
        if v[-1] == 0.0:
            return np.zeros_like(b), np.linspace(0.0, 1.0, v.size + 1)
        b, v = b * v[-1], v / v[-1]
        openings = np.concatenate([[0.0], np.maximum.accumulate(np.clip(v, 0.0, None))])
        openings = openings / openings[-1] if openings[-1] > 0 else np.linspace(0, 1, v.size + 1)
        return b, openings

    def arx_poles(self, map_starts=None) -> np.ndarray:
        """The poles of the record's ARX model (the start of a linear fit).

        With ``map_starts`` (per input, where its map starts as a fraction of its range), of the
        ARX model through each input's hat basis from there instead: one least squares, not the
        best-simulating split over the start grid (``initial_guesses``).
        """
        theta = self.initial_guesses()[0] if map_starts is None else self._arx_start(map_starts)
        return np.roots(np.concatenate([[1.0], self.unpack(theta)[0][0]]))

    # --- the result -----------------------------------------------------------------------------

    def model(self, theta, sample_period_s, units) -> HammersteinModel:
        """The model in the record's units."""
        a, b, maps, y_op = self.unpack(theta)
        valve_maps = []
        for i, (knots, openings) in enumerate(maps):
            currents = self.u_low[i] + self.u_range[i] * knots
            valve_maps.append(ValveMap(*_without_flat_ends(currents, openings)))
        try:
            return HammersteinModel(
                maps=tuple(valve_maps),
                a=a,
                b=b * self.y_scale,
                input_delay_samples=self.delay,
                operating_output=self.y_mean + self.y_scale * y_op,
                sample_period_s=sample_period_s,
                **units,
            )
        except ModelError as error:
            raise ModelError(f"the Hammerstein estimate went bad: {error}") from None


def _logistic(x):
    return 0.5 * (1.0 + np.tanh(0.5 * x))


def _logit(p):
    p = np.clip(p, 1e-6, 1.0 - 1e-6)
    return float(np.log(p / (1.0 - p)))


def _without_flat_ends(currents, openings):
    """The knots from the last that opens at most ``_FLAT`` to the first within it of full.

    A segment whose weight the search drove to nothing leaves a knot on a flat end; the valve
    starts (saturates) where the map really leaves 0 (reaches 1), so that is the knot kept.
    """
    first = int(np.flatnonzero(openings <= _FLAT)[-1])
    last = int(np.flatnonzero(openings >= 1.0 - _FLAT)[0])
    kept = np.clip(openings[first : last + 1], 0.0, 1.0)
    kept[0], kept[-1] = 0.0, 1.0
    return currents[first : last + 1], kept
