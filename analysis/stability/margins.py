"""Gain, phase and delay margins of a discrete-time SISO loop closed by a dynamic controller.

Both the plant and the controller are ``LinearModel``s (``maskless.systems.linear_model``),
single-input, single-output discrete state spaces

    x(k+1) = A x(k) + B v(k),   w(k) = C x(k) + D v(k),   z = exp(j ω Ts),

of which only the deterministic part (A, B, C, D) enters a loop. The models built here (cascades,
loop transfers, delayed models) are of deviations: they carry no operating point, units or
innovations description.

Sign convention: the controller computes the plant input from the plant output *with its own
sign*, u = K(z) y (an LQG controller's u = -K x̂ already carries the minus sign), and the loop is
closed exactly as written. The loop transfer is therefore L(z) = -K(z) G(z), chosen so that the
closed loop is the textbook negative-feedback loop: its poles are the zeros of 1 + L(z), the
Nyquist critical point is -1, and the margins below read as usual. Functions that close or open
the loop take ``sign`` (±1) for a controller written without its sign: u = sign · K(z) y.

Everything here is pure numpy/scipy on the models' arrays, so a margin check can run on an
identified model without building a Drake diagram.
"""

import math
import operator
from dataclasses import dataclass

import numpy as np
import scipy.optimize

from maskless.systems.linear_model import LinearModel

# The margin search grid starts this fraction of the Nyquist frequency above zero: crossings below
# it (six decades under Nyquist) are outside any loop this toolkit closes.
LOWEST_FREQUENCY_FRACTION = 1e-6
# An open-loop pole this close to z = ±1 makes L infinite there, so that band edge is not
# evaluated (a numerical integrator at 1 + 1e-16 would otherwise give a meaningless margin).
_EDGE_POLE_TOLERANCE = 1e-6
# A refined phase crossing must land this close (rad) to -180°; otherwise brentq found the ±180°
# branch cut of the angle, not a crossing.
_PHASE_ROOT_TOLERANCE_RAD = 1e-6


def _same_period(first: LinearModel, second: LinearModel, names: str) -> None:
    if not math.isclose(first.sample_period_s, second.sample_period_s, rel_tol=1e-9):
        raise ValueError(
            f"{names} must share one sample period, got {first.sample_period_s} s and "
            f"{second.sample_period_s} s"
        )


def _check_sign(sign) -> float:
    if sign not in (1, -1):
        raise ValueError(f"sign must be +1 or -1, got {sign!r}")
    return float(sign)


def _scaled(model: LinearModel, factor: float) -> LinearModel:
    """Factor · model (output scaled)."""
    return LinearModel(model.A, model.B, factor * model.C, factor * model.D, model.sample_period_s)


def series(first: LinearModel, second: LinearModel) -> LinearModel:
    """The cascade whose input drives ``first`` and whose output is ``second``'s.

    The transfer function is second(z) · first(z); the states are [x_first, x_second].

    Args:
        first: Model fed by the cascade input.
        second: Model fed by ``first``'s output.

    Raises:
        ValueError: if the sample periods differ.
    """
    _same_period(first, second, "first and second")
    n1, n2 = first.order, second.order
    A = np.block([[first.A, np.zeros((n1, n2))], [second.B @ first.C, second.A]])
    B = np.vstack([first.B, second.B @ first.D])
    C = np.hstack([second.D @ first.C, second.C])
    return LinearModel(A, B, C, second.D @ first.D, first.sample_period_s)


def loop_transfer(plant: LinearModel, controller: LinearModel, sign: int = 1) -> LinearModel:
    """The loop transfer L(z) = -sign · K(z) G(z), broken at the plant input.

    With u = sign · K(z) y, the closed loop's poles are the zeros of 1 + L(z) (negative
    feedback around L), so ``discrete_margins(loop_transfer(plant, controller))`` gives the
    textbook margins.

    Args:
        plant: G, from u to y.
        controller: K, from y to the controller output.
        sign: +1 when the controller output is applied as u (it carries its own minus sign, as
            an LQG controller u = -K x̂ does); -1 when u = -K(z) y.

    Raises:
        ValueError: if the sample periods differ or ``sign`` is not ±1.
    """
    _same_period(plant, controller, "plant and controller")
    return series(plant, _scaled(controller, -_check_sign(sign)))


def _closed_loop_matrix(plant: LinearModel, controller: LinearModel, sign: float) -> np.ndarray:
    """The state matrix of [x_plant; x_controller] with u = sign · (Cc xc + Dc y), y = C x + D u."""
    G, K = plant, controller
    # The feedthroughs form an algebraic loop u = sign Dc (C x + D u) + ...; it is well posed only
    # when 1 - sign Dc D is invertible.
    well_posed = 1.0 - sign * K.D[0, 0] * G.D[0, 0]
    if abs(well_posed) < 1e-12:
        raise ValueError(
            "plant and controller form an ill-posed algebraic loop: 1 - sign * D_controller * "
            f"D_plant = {well_posed:g}"
        )
    # u = u_x x + u_c xc after solving the algebraic loop.
    u_x = sign * K.D @ G.C / well_posed
    u_c = sign * K.C / well_posed
    y_x = G.C + G.D @ u_x
    y_c = G.D @ u_c
    return np.block([[G.A + G.B @ u_x, G.B @ u_c], [K.B @ y_x, K.A + K.B @ y_c]])


def feedback_loop_poles(plant: LinearModel, controller: LinearModel, sign: int = 1) -> np.ndarray:
    """Closed-loop poles of the plant with u = sign · K(z) y.

    The default ``sign=+1`` closes the loop exactly as the controller is written (the controller
    carries its own minus sign); these are the zeros of 1 + ``loop_transfer(plant, controller,
    sign)``, including any modes hidden from the loop transfer.

    Args:
        plant: G, from u to y.
        controller: K, from y to the controller output.
        sign: ±1, see ``loop_transfer``.

    Returns:
        The n_plant + n_controller eigenvalues of the closed-loop state matrix (complex).

    Raises:
        ValueError: if the sample periods differ, ``sign`` is not ±1, or the feedthroughs make
            the loop ill-posed (1 - sign · D_controller · D_plant = 0).
    """
    _same_period(plant, controller, "plant and controller")
    matrix = _closed_loop_matrix(plant, controller, _check_sign(sign))
    return np.linalg.eigvals(matrix).astype(complex)


def added_delay_samples_loop(loop: LinearModel, delay_samples: int) -> LinearModel:
    """``loop`` followed by a pure delay z^-d, for latency robustness checks.

    The delay is a shift register of d states after the output, so the result has n + d states
    and transfer function z^-d · loop(z). It applies equally to a plant (to model actuation or
    sensing latency before closing the loop) or to a loop transfer.

    Args:
        loop: The model to delay.
        delay_samples: d >= 0, whole samples.

    Raises:
        ValueError: if ``delay_samples`` is not a non-negative integer.
    """
    try:
        d = operator.index(delay_samples)
    except TypeError:
        raise ValueError(
            f"delay_samples must be a non-negative integer, got {delay_samples!r}"
        ) from None
    if isinstance(delay_samples, bool) or d < 0:
        raise ValueError(f"delay_samples must be a non-negative integer, got {delay_samples!r}")
    if d == 0:
        return loop
    n = loop.order
    first = np.zeros((d, 1))
    first[0, 0] = 1.0
    shift = np.eye(d, k=-1)
    A = np.block([[loop.A, np.zeros((n, d))], [first @ loop.C, shift]])
    B = np.vstack([loop.B, first @ loop.D])
    C = np.zeros((1, n + d))
    C[0, -1] = 1.0
    return LinearModel(A, B, C, np.zeros((1, 1)), loop.sample_period_s)


@dataclass(frozen=True)
class Margins:
    """Classic stability margins of a loop transfer L (negative feedback around L).

    Attributes:
        gain_margin: Smallest 1/|L| over the -180° phase crossings (ratio); inf when the phase
            never reaches -180°. A value below 1 means a gain *reduction* reaches -1 (a
            conditionally stable loop).
        gain_margin_db: 20 log10(gain_margin) (dB); inf when gain_margin is.
        phase_crossover_rad_s: Frequency of that crossing (rad/s); nan when none.
        phase_margin_deg: Smallest 180° + ∠L over the |L| = 1 crossings, wrapped to (-180, 180]
            (deg); inf when |L| never crosses 1.
        gain_crossover_rad_s: Frequency of that crossing (rad/s); nan when none.
        delay_margin_s: Smallest extra pure delay that brings a gain crossing onto -1 (s): the
            phase margin over the crossover frequency when there is one crossing with positive
            phase margin; otherwise the smallest (margin mod 360°) / frequency over all crossings.
            inf when none. Meaningful, like the others, when the nominal closed loop is stable.
    """

    gain_margin: float
    gain_margin_db: float
    phase_crossover_rad_s: float
    phase_margin_deg: float
    gain_crossover_rad_s: float
    delay_margin_s: float

    def as_dict(self) -> dict[str, float | str | None]:
        """The margins as JSON-safe values.

        Finite floats stay as they are, ±inf become the strings "inf" / "-inf" (meaning "no
        crossing, unbounded"), and nan becomes None (no such frequency).
        """
        return {name: json_safe(value) for name, value in vars(self).items()}


def json_safe(value: float) -> float | str | None:
    """A float as JSON allows it: ±inf as "inf" / "-inf", nan as None."""
    value = float(value)
    if math.isnan(value):
        return None
    if math.isinf(value):
        return "inf" if value > 0 else "-inf"
    return float(value)


def _band_edge_response(loop: LinearModel, z: float) -> float | None:
    """L at z = ±1 (real there), or None when an open-loop pole sits on that edge."""
    if loop.order and np.min(np.abs(loop.poles() - z)) < _EDGE_POLE_TOLERANCE:
        return None
    return float(loop.transfer_function(np.array([z + 0j]))[0].real)


def _refined_roots(function, omega: np.ndarray, values: np.ndarray, ok: np.ndarray) -> list:
    """Roots of ``function`` on the grid: its exact zeros, and those brentq finds between points.

    brentq runs in each interval whose ends change sign and where ``ok`` (per interval) allows it.
    """
    roots = list(omega[values == 0.0])
    changes = np.flatnonzero((values[:-1] * values[1:] < 0.0) & ok)
    for i in changes:
        roots.append(
            scipy.optimize.brentq(function, omega[i], omega[i + 1], xtol=1e-12 * omega[-1])
        )
    return roots


def _phase_crossings(
    loop: LinearModel, omega: np.ndarray, phase_values: np.ndarray
) -> list[tuple[float, float]]:
    """(frequency (rad/s), |L|) at each -180° phase crossing of L, the z = 1 band edge included.

    ``phase_values`` is angle(-L) on the grid ``omega``. L is real at z = 1, so a negative L there
    is a crossing at ω = 0; that edge is skipped when L has a pole there.
    """

    def distance_to_minus_180(w):  # angle(-L) is 0 exactly where ∠L = -180° (mod 360°)
        return np.angle(-loop.frequency_response(w))

    # angle(-L) also changes sign where it jumps across ±180° (∠L passes 0°); those intervals jump
    # by about 2π and are excluded.
    not_a_wrap = np.abs(np.diff(phase_values)) < math.pi
    phase_crossings = []
    for w in _refined_roots(distance_to_minus_180, omega, phase_values, not_a_wrap):
        value = complex(loop.frequency_response(w))
        # L = 0 (a zero on the unit circle) has no phase; it is no crossing.
        if abs(value) > 0.0 and abs(np.angle(-value)) < _PHASE_ROOT_TOLERANCE_RAD:
            phase_crossings.append((float(w), abs(value)))
    dc = _band_edge_response(loop, 1.0)
    if dc is not None and dc < 0.0:
        phase_crossings.append((0.0, -dc))
    return phase_crossings


def _gain_margin(phase_crossings: list[tuple[float, float]]) -> tuple[float, float, float]:
    """(phase crossover (rad/s), gain margin, gain margin (dB)) from the phase crossings.

    The crossing with the largest |L| sets them; with none, the phase crossover is nan and the
    gain margin inf.
    """
    if not phase_crossings:
        return math.nan, math.inf, math.inf
    phase_crossover, crossing_magnitude = max(phase_crossings, key=lambda c: c[1])
    gain_margin = 1.0 / crossing_magnitude
    return phase_crossover, gain_margin, 20.0 * math.log10(gain_margin)


def _phase_and_delay_margins(loop: LinearModel, gain_roots: list) -> tuple[float, float, float]:
    """(phase margin (deg), gain crossover (rad/s), delay margin (s)) from the |L| = 1 crossings.

    The crossing with the smallest phase margin sets the first two; with none, the margins are
    inf and the gain crossover nan.
    """
    if not gain_roots:
        return math.inf, math.nan, math.inf
    gain_crossings = np.array(gain_roots)
    # angle(-L) is 180° + ∠L already wrapped to (-180°, 180°].
    margins_deg = np.degrees(np.angle(-loop.frequency_response(gain_crossings)))
    best = int(np.argmin(margins_deg))
    phase_margin_deg = float(margins_deg[best])
    gain_crossover = float(gain_crossings[best])
    # A delay τ adds lag ωτ at every crossing; the first crossing it rotates onto -1 sets τ.
    delays = np.radians(np.mod(margins_deg, 360.0)) / gain_crossings
    delay_margin_s = float(np.min(delays))
    return phase_margin_deg, gain_crossover, delay_margin_s


def discrete_margins(loop: LinearModel, n_frequencies: int = 4000) -> Margins:
    """Gain, phase and delay margins of L(exp(j ω Ts)) for 0 <= ω <= π/Ts.

    Crossings are bracketed on a log grid of ``n_frequencies`` points from 1e-6 · π/Ts up to and
    including π/Ts, then refined with brentq. L is real at the band edges z = 1 and z = -1, so a
    negative real value there is a phase crossing too (at ω = 0 or π/Ts); the z = 1 edge is
    skipped when L has a pole there (an integrator).

    Args:
        loop: The loop transfer L, closed with negative feedback (see ``loop_transfer``).
        n_frequencies: Grid points, at least 16; the grid must resolve the phase, so raise it for
            lightly damped resonances.

    Returns:
        The margins; see ``Margins`` for the no-crossing values.

    Raises:
        ValueError: if ``n_frequencies`` is not an integer >= 16.
    """
    if isinstance(n_frequencies, bool) or not isinstance(n_frequencies, int | np.integer):
        raise ValueError(f"n_frequencies must be an integer >= 16, got {n_frequencies!r}")
    if n_frequencies < 16:
        raise ValueError(f"n_frequencies must be an integer >= 16, got {n_frequencies}")
    nyquist = loop.nyquist_rad_s
    at_nyquist = _band_edge_response(loop, -1.0)
    top = nyquist if at_nyquist is not None else nyquist * (1.0 - _EDGE_POLE_TOLERANCE)
    omega = np.geomspace(LOWEST_FREQUENCY_FRACTION * nyquist, top, int(n_frequencies))
    response = loop.frequency_response(omega)
    phase_values = np.angle(-response)
    if at_nyquist is not None:
        # exp(jπ) is -1 + 1.2e-16j; L(-1) is real in truth, so its phase is 0° or 180° exactly.
        response[-1] = at_nyquist
        phase_values[-1] = 0.0 if at_nyquist < 0.0 else math.pi

    def magnitude_minus_one(w):
        return np.abs(loop.frequency_response(w)) - 1.0

    phase_crossings = _phase_crossings(loop, omega, phase_values)
    gain_roots = _refined_roots(
        magnitude_minus_one, omega, np.abs(response) - 1.0, np.ones(omega.size - 1, dtype=bool)
    )
    phase_crossover, gain_margin, gain_margin_db = _gain_margin(phase_crossings)
    phase_margin_deg, gain_crossover, delay_margin_s = _phase_and_delay_margins(loop, gain_roots)

    return Margins(
        gain_margin=float(gain_margin),
        gain_margin_db=float(gain_margin_db),
        phase_crossover_rad_s=float(phase_crossover),
        phase_margin_deg=phase_margin_deg,
        gain_crossover_rad_s=gain_crossover,
        delay_margin_s=delay_margin_s,
    )
