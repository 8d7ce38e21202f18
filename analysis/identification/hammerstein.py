"""Hammerstein identification: a monotone static map per valve and MISO linear dynamics.

The model is ``systems.hammerstein_model.HammersteinModel``: y = y_op + sum_i q^-d B_i/A_i f_i(u_i).
Here every A_i is one A(q): one bladder moves one head, and a shared denominator halves the
dynamics' parameters the valve maps trade off against.

Choices, and why:

- **Two stages where the record allows**: when enough holds (runs of unchanged currents) last
  past the settling time (``_SETTLE_TIME_CONSTANTS`` time constants of the slowest pole of the
  record's ARX model), each valve's static curve comes from their settled ends first
  (``settled_curve``: the map and its DC gain, the starting current profiled over a grid), and
  the search fits only the dynamics, with B_i(1) / A(1) held at the curve's gain. In one joint
  search the maps absorb what a linear model of a plant whose time constants change with its
  level gets wrong in the transients, and the starting current trades off against the map's
  first pieces; on the pneumatic plant that put starting currents 0-60 mA off. A record without
  settled holds (levels shorter than the plant settles) gets the joint search below.
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
- **Output error (simulation focus)**: the parameters minimise the simulated output's error,
  the criterion the model is judged by, and the error the controller's own model error is. It is
  consistent for any output noise that does not depend on the input (an open-loop experiment),
  with no noise model to fit; a one-step criterion would weight the high frequencies where the
  cameras' noise is and the static curve is not.
- **A(q) is stable by construction**: it is built from reflection coefficients tanh(rho_j), each
  in (-1, 1) (the Schur-Cohn step-up recursion), so the simulation never explodes mid-search.
- **The joint search's start**: for each pair of starting currents on a grid, the
  overparameterised ARX (each lagged input expanded in the map's hat basis, linear least squares)
  split into B_i and f_i by a rank-one SVD (Bai 1998); the few grid points whose models simulate
  best each start
  ``scipy.optimize.least_squares`` (Levenberg-Marquardt), and the lowest cost found is kept.
  s_i is a logistic function of its parameter and c_i one between s_i and past the data, so both
  stay in range with no bounds.

A linear model is the same structure with each map affine over the data (``linear=True``), so the
baselines a Hammerstein fit must beat are fitted by the same code and criterion.
"""

import dataclasses
import itertools
from dataclasses import dataclass

import numpy as np
import scipy.optimize
import scipy.signal

from maskless.analysis.identification.fit_metrics import fit_percent
from maskless.analysis.identification.settled_curve import (
    fit_static_curves,
    parameter_count,
    settled_levels,
)
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
_MAX_START = 1.0 - _MIN_SPAN_FRACTION
# The highest saturation current allowed, as a fraction of the input's range above its lowest
# value: a saturation past the data (above 1) says the record never reached it.
_MAX_SATURATION = 1.5
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
# A hold has settled this many time constants of the slowest pole after it began: e^-4, 2 % of
# its step, left (the tail's mean then carries less than 1 %).
_SETTLE_TIME_CONSTANTS = 4.0


@dataclass(frozen=True)
class HammersteinFit:
    """What ``estimate_hammerstein`` returns.

    Attributes:
        model: the estimated model; the starting guess when the search failed.
        converged: whether the search ended on one of scipy's convergence tests.
        message: scipy's reason for stopping, or why the fit failed.
        simulation_fit_percent: the model's simulation fit on the estimation record (MATLAB's
            fit %, initial state at rest at u(0)).
        start_fit_percent: the same figure for the starting guess.
        evaluations: cost evaluations the search made.
        searches: per search run (one per starting guess), its final cost over the best one's
            and the starting current of each valve it ended at; empty when none finished.
        highest_currents: per valve, the highest current of the estimation record: a saturation
            past it was never seen, only allowed.
        start_intervals: per valve, the starting current's 95 % profile interval from the
            settled holds (``settled_curve``), when the maps came from them; else empty.
    """

    model: HammersteinModel
    converged: bool
    message: str
    simulation_fit_percent: float
    start_fit_percent: float
    evaluations: int
    searches: tuple[tuple[float, tuple[float, ...]], ...] = ()
    highest_currents: tuple[float, ...] = ()
    start_intervals: tuple[tuple[float, float], ...] = ()

    def starting_current_spread(self, tolerance: float = 0.01) -> list[tuple[float, float]]:
        """Per valve, (lowest, highest) starting current the record cannot tell apart.

        For maps from settled holds, ``start_intervals``. Otherwise the searches' ends whose
        final cost is within ``tolerance`` (a fraction) of the best: a valve whose curve leaves
        zero gently (the pneumatic plant's lift grows with the square of the opening) is where
        they differ.
        """
        if self.start_intervals:
            return list(self.start_intervals)
        close = [starts for ratio, starts in self.searches if ratio <= 1.0 + tolerance]
        if not close:
            close = [tuple(m.starting_current for m in self.model.maps)]
        return [(min(values), max(values)) for values in zip(*close, strict=True)]

    def summary(self, input_names=("inlet", "outlet")) -> dict:
        """Per valve: its map's ends, spread and static curve; and the poles.

        Each valve's starting current and ``starting_current_spread``, saturation current and
        the record's highest current, DC gain and the static curve at the map's knots.
        """
        model = self.model
        gains = model.dc_gains()
        spread = self.starting_current_spread()
        valves = {}
        for i, valve_map in enumerate(model.maps):
            name = input_names[i] if i < len(input_names) else f"input_{i}"
            valves[name] = {
                "starting_current": valve_map.starting_current,
                "starting_current_spread": list(spread[i]),
                "highest_current_in_record": self.highest_currents[i],
                "saturation_current": valve_map.saturation_current,
                "dc_gain": float(gains[i]),
                "curve_currents": valve_map.currents.tolist(),
                "curve_outputs": (gains[i] * valve_map.openings).tolist(),
            }
        return {
            "converged": self.converged,
            "message": self.message,
            "simulation_fit_percent": self.simulation_fit_percent,
            "start_fit_percent": self.start_fit_percent,
            "input_unit": model.input_unit,
            "output_unit": model.output_unit,
            "valves": valves,
            "poles": [[float(p.real), float(p.imag)] for p in model.poles()],
        }


def estimate_hammerstein(
    u,
    y,
    order: int,
    sample_period_s: float,
    *,
    map_segments: int = 6,
    input_delay_samples: int = 1,
    linear: bool = False,
    input_unit: str = "",
    output_unit: str = "",
    max_evaluations: int = 3000,
) -> HammersteinFit:
    """A Hammerstein model (or, with ``linear``, a linear one) by output-error prediction error.

    Args:
        u: the currents (N, inputs) or (N,) for one input, in ``input_unit``.
        y: the output (N,), in ``output_unit``; not detrended (y_op is estimated).
        order: n, the order of A(q) and of each B_i(q).
        sample_period_s: Ts (s).
        map_segments: linear pieces of each map between its starting and saturation current.
        input_delay_samples: d >= 1, samples from a current to its first effect.
        linear: fit a linear model instead: each map affine over (far beyond) the data's range.
        input_unit: the currents' unit, carried into the model.
        output_unit: the output's unit, carried into the model.
        max_evaluations: the search's budget of cost evaluations.

    Returns:
        The fit: the lowest cost of the searches from the best few starting guesses, with each
        search's end in ``searches``. A fit whose searches all fail (a non-finite cost, scipy
        raising) returns its starting guess with ``converged`` False and the reason in
        ``message``; it never raises for that.

    Raises:
        ValueError: naming the argument, for shapes, non-finite samples, a constant output or
            input, or an order, delay or segment count out of range.
    """
    u, y = _checked_record(u, y, order, map_segments, input_delay_samples, sample_period_s)
    curves, slowest = (None, None) if linear else _settled_curves(u, y, order, input_delay_samples)
    problem = _Problem(u, y, order, map_segments, input_delay_samples, linear, curves, slowest)
    units = {"input_unit": input_unit, "output_unit": output_unit}
    solution, start, failures, ends = None, None, [], []
    for guess in problem.initial_guesses():
        try:
            with np.errstate(all="ignore"):
                found = scipy.optimize.least_squares(
                    problem.residuals, guess, method="lm", x_scale="jac", max_nfev=max_evaluations
                )
        except (ValueError, np.linalg.LinAlgError, FloatingPointError) as error:
            failures.append(f"search failed: {error}")
            start = guess if start is None else start
            continue
        if not np.isfinite(found.cost):
            continue
        ends.append(found)
        if solution is None or found.cost < solution.cost:
            solution, start = found, guess
    if solution is None:
        reason = failures[0] if failures else "search failed: no finite cost anywhere"
        return problem.fit(start, start, False, reason, 0, sample_period_s, units)
    start_cost = problem.cost(start)
    if 2.0 * solution.cost > start_cost:
        return problem.fit(
            start,
            start,
            False,
            f"search failed: it ended at a cost ({2 * solution.cost:.6g}) no better than its "
            f"start ({start_cost:.6g})",
            solution.nfev,
            sample_period_s,
            units,
        )
    converged = solution.status > 0
    message = solution.message if converged else f"not converged: {solution.message}"
    fit = problem.fit(solution.x, start, converged, message, solution.nfev, sample_period_s, units)
    searches = tuple(
        (
            float(end.cost / solution.cost) if solution.cost > 0 else 1.0,
            tuple(m.starting_current for m in problem.model(end.x, sample_period_s, units).maps),
        )
        for end in ends
    )
    intervals = () if curves is None else tuple(map(tuple, curves.start_intervals.tolist()))
    return dataclasses.replace(fit, searches=searches, start_intervals=intervals)


def estimate_linear_arx(
    u, y, order: int, sample_period_s: float, *, input_delay_samples: int = 1
) -> HammersteinModel:
    """The MISO ARX model by linear least squares, as a model with affine maps.

    A(q) y = sum_i q^-d B_i(q) u_i + e, with A(q) stable (an unstable root mirrored inside), the
    baseline that ``estimate_hammerstein``'s start improves on. Arguments as there.
    """
    u, y = _checked_record(u, y, order, 1, input_delay_samples, sample_period_s)
    problem = _Problem(u, y, order, 1, input_delay_samples, linear=True)
    return problem.model(problem.initial_guesses()[0], sample_period_s, {})


def _settled_curves(u, y, order, delay):
    """(the static curves of the settled holds (``settled_curve``), the slowest pole's radius).

    A hold has settled ``_SETTLE_TIME_CONSTANTS`` time constants of the slowest pole of the
    record's ARX model after it began. (None, None) if too few holds settled.
    """
    slowest = float(np.max(np.abs(_Problem(u, y, order, 1, delay, linear=True).arx_poles())))
    if not slowest < 1.0:
        return None, None
    settle = int(np.ceil(_SETTLE_TIME_CONSTANTS / -np.log(slowest)))
    levels = settled_levels(u, y, settle, max(1, settle // 8))
    if levels.outputs.size < 2 * parameter_count(u.shape[1]):
        return None, None
    curves = fit_static_curves(levels, _MAX_START, _MAX_SATURATION)
    if curves is None or np.any(curves.gains() == 0.0):
        return None, None
    return curves, slowest


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
    roots = np.roots(np.concatenate([[1.0], a]))
    outside = np.abs(roots) >= 1.0
    roots[outside] = 1.0 / np.conj(roots[outside]) * _REFLECTION_LIMIT
    polynomial = np.real(np.poly(roots))
    reflections = []
    while polynomial.size > 1:
        k = float(np.clip(polynomial[-1], -_REFLECTION_LIMIT, _REFLECTION_LIMIT))
        reflections.append(k)
        polynomial = (polynomial - k * polynomial[::-1])[:-1] / (1.0 - k * k)
    return np.array(reflections[::-1])


class _Problem:
    """The record in normalised units and the parameter vector's layout.

    Currents are scaled to [0, 1] over each input's range in the data and the output to zero mean
    and unit spread, so one finite-difference step and one trust region suit every parameter. The
    vector is [rho (n); per input b_i (n), s_i, span_i, softmax logits (segments - 1); y_op]; a
    linear model has no s, span or logits. With ``curves`` (``settled_curve.StaticCurves``) each
    map and DC gain is theirs, fixed: per input only b_i2..b_in, b_i1 making B_i(1) / A(1) the
    curve's gain. ``pole_radius`` bounds A(q)'s poles: with the curves fixed, the search otherwise
    puts a pole within 1e-5 of 1 with a zero all but cancelling it, a slow drift no design can
    use; the curves assume the plant settles as the record's ARX model's slowest pole does, so
    the dynamics get no slower pole.
    """

    def __init__(self, u, y, order, segments, delay, linear, curves=None, pole_radius=None):
        self.order, self.segments, self.delay, self.linear = order, segments, delay, linear
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
        start = _MAX_START * _logistic(parameters[0])
        room = _MAX_SATURATION - start - _MIN_SPAN_FRACTION
        span = _MIN_SPAN_FRACTION + room * _logistic(parameters[1])
        logits = parameters[2:]
        weights = np.exp(np.concatenate([[0.0], logits]) - max(0.0, logits.max(initial=0.0)))
        openings = np.concatenate([[0.0], np.cumsum(weights) / weights.sum()])
        openings[-1] = 1.0
        return start + span * np.linspace(0.0, 1.0, self.segments + 1), openings

    # --- the criterion --------------------------------------------------------------------------

    def simulate(self, theta):
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
        error = self.y - self.simulate(theta)
        if not np.all(np.isfinite(error)):
            # Finite and large: the search turns back instead of stopping on a NaN.
            return np.full(self.y.size, 1e3)
        return error

    def cost(self, theta) -> float:
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
            # The normal equations: a few dozen columns, and a Gram matrix is one product where a
            # tall QR or SVD is many (and slow when BLAS threads compete for cores).
            solution, *_ = np.linalg.lstsq(matrix.T @ matrix, matrix.T @ self.y[lag:], rcond=None)
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
                room = _MAX_SATURATION - start - _MIN_SPAN_FRACTION
                block[n] = _logit(start / _MAX_START)
                block[n + 1] = _logit((span - _MIN_SPAN_FRACTION) / room)
                increments = np.maximum(np.diff(openings), 1e-3)
                block[n + 2 :] = np.log(increments[1:] / increments[0])
            theta[n + i * self.input_size : n + (i + 1) * self.input_size] = block
        if not fallback:
            # y_op: the output the model leaves with no input at all, fitted afresh for the
            # simulated (not one-step) criterion.
            theta[-1] = float(np.mean(self.y - self.simulate(theta)))
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

    def arx_poles(self) -> np.ndarray:
        """The poles of the record's ARX model (the start of a linear fit)."""
        theta = self.initial_guesses()[0]
        return np.roots(np.concatenate([[1.0], self.unpack(theta)[0][0]]))

    # --- the result -----------------------------------------------------------------------------

    def fit(self, theta, start, converged, message, evaluations, sample_period_s, units):
        model = self.model(theta, sample_period_s, units)
        y = self.y * self.y_scale + self.y_mean
        start_model = self.model(start, sample_period_s, units)
        u = self.u * self.u_range + self.u_low
        return HammersteinFit(
            model=model,
            converged=converged,
            message=message,
            simulation_fit_percent=fit_percent(y, model.simulate(u)),
            start_fit_percent=fit_percent(y, start_model.simulate(u)),
            evaluations=int(evaluations),
            highest_currents=tuple(float(h) for h in self.u_low + self.u_range),
        )

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


def _checked_record(u, y, order, segments, delay, sample_period_s):
    """(u (N, inputs), y (N,)) as floats, or a ValueError naming what is wrong."""
    u, y = np.asarray(u, dtype=float), np.asarray(y, dtype=float)
    if u.ndim == 1:
        u = u[:, None]
    if u.ndim != 2 or y.ndim != 1 or u.shape[0] != y.size:
        raise ValueError(
            f"u must be (N, inputs) and y (N,) of one length N, got {u.shape} and {y.shape}"
        )
    if not (np.all(np.isfinite(u)) and np.all(np.isfinite(y))):
        raise ValueError("u and y must be finite")
    for name, value in (
        ("order", order),
        ("map_segments", segments),
        ("input_delay_samples", delay),
    ):
        if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 1:
            raise ValueError(f"{name} = {value!r}: expected an integer >= 1")
    if not (isinstance(sample_period_s, int | float) and sample_period_s > 0):
        raise ValueError(f"sample_period_s = {sample_period_s!r}: expected a positive number")
    parameters = order + u.shape[1] * (order + segments + 1) + 1
    if y.size < 10 * parameters:
        raise ValueError(f"{y.size} samples are too few for {parameters} parameters (10 each)")
    if np.ptp(y) == 0.0:
        raise ValueError("y is constant: there is nothing to identify")
    constant = [i for i in range(u.shape[1]) if np.ptp(u[:, i]) == 0.0]
    if constant:
        raise ValueError(f"u column {constant[0]} is constant: its map cannot be identified")
    return u, y
