"""The local Kalman filter at each camera (Sec. III-B, Eq. 3-9).

State x = [d, ḋ] with d the head height above the table (the paper's common frame is the v2
camera's; we use the table, which both cameras reach through their mount heights), constant-velocity
model F = [[1, ΔT], [0, 1]] (Eq. 4), process noise Q = W Wᵀ σ_a² with W = [ΔT²/2, ΔT]ᵀ (Eq. 6),
measurement z = H x + v with H = [1 0] and variance σ_r² (Eq. 7).

How we read "σ_a = 2000 mm²": the unit is a variance's, so σ_a² = 2000 (mm/s²)². With that reading
and the paper's 15 Hz frames, the steady-state filter passes 15.2 % of white measurement noise
variance to its estimate, close to the 80.81 % reduction the paper reports for the Xbox; reading it
as σ_a = 2000 mm/s² passes 68 % (a 32 % reduction), far from it.

The filter runs at its camera's frame rate: each tick predicts over one frame period (Eq. 8) and,
when the frame is usable, updates (Eq. 9). A frame is usable when ``valid`` is set, its distance
lies inside the camera's working range and its innovation inside the gate (``fault_detection``):
zeros, NaNs, infinities and implausible jumps never reach the estimate, the filter just predicts.
The filter also reports whether its camera went stale, keeps being rejected, or is stuck. The
first tick, at t = 0, also predicts over a whole frame: the configured initial estimate is taken
to hold one frame before the start. Its outputs are the
estimate and covariance predicted to the current time, so the fusion site can combine tracks from
cameras that tick at different instants.
"""

from dataclasses import dataclass

import numpy as np
from pydrake.math import DiscreteAlgebraicRiccatiEquation
from pydrake.symbolic import (
    Expression,
    MakeVectorVariable,
    Variable,
    if_then_else,
    logical_and,
    logical_not,
)
from pydrake.systems.framework import DiagramBuilder

from maskless.errors import ConfigError
from maskless.systems.config_loading import UNSET
from maskless.systems.named_symbolic_system import (
    PortMap,
    SymbolicSystem,
    add_symbolic_system,
    building_expressions,
    diagram_form,
)
from maskless.systems.ordered_conditions import if_all
from maskless.systems.sensing.fault_detection import (
    FaultDetectionConfig,
    frames_in,
    nis_bound,
)

MEASUREMENT_MATRIX = np.array([[1.0, 0.0]])  # H in Eq. 7


@dataclass
class LocalFilterConfig:
    """Start of every local filter (the paper gives none).

    Attributes:
        initial_position_std_m: std of the initial height estimate (m).
        initial_velocity_std_m_s: std of the initial velocity estimate (m/s).
    """

    initial_position_std_m: float = UNSET
    initial_velocity_std_m_s: float = UNSET


def transition_matrix(dt):
    """F of Eq. 4 for a step of ``dt`` s (float or symbolic)."""
    return np.array([[1.0, dt], [0.0, 1.0]], dtype=object if _is_symbolic(dt) else float)


def process_noise_covariance(dt, acceleration_variance):
    """Q of Eq. 6: W Wᵀ σ_a², W = [ΔT²/2, ΔT]ᵀ (m², m²/s, m²/s²)."""
    return acceleration_variance * np.array(
        [[dt**4 / 4, dt**3 / 2], [dt**3 / 2, dt**2]], dtype=object if _is_symbolic(dt) else float
    )


def predict(x, P, dt, acceleration_variance):
    """The prediction phase, Eq. 8, without input (Eq. 5): returns x(k|k-1), P(k|k-1)."""
    F = transition_matrix(dt)
    return F @ x, F @ P @ F.T + process_noise_covariance(dt, acceleration_variance)


def update(x, P, z, measurement_variance):
    """The update phase, Eq. 9 with H = [1 0]: returns x(k|k), P(k|k)."""
    innovation_variance = P[0, 0] + measurement_variance
    gain = P[:, 0] / innovation_variance
    x_new = x + gain * (z - x[0])
    P_new = P - np.outer(gain, P[0, :])
    return x_new, P_new


def steady_state_covariances(dt, acceleration_variance, measurement_variance):
    """The filter's steady-state prior and posterior covariances, from Drake's DARE.

    Drake's discrete algebraic Riccati equation is solved as the dual of the LQR equation:
    A -> Fᵀ, B -> Hᵀ.

    Returns:
        (P(k|k-1), P(k|k)) as 2x2 arrays.
    """
    F = transition_matrix(dt)
    Q = process_noise_covariance(dt, acceleration_variance)
    R = np.array([[measurement_variance]])
    prior = DiscreteAlgebraicRiccatiEquation(F.T, MEASUREMENT_MATRIX.T, Q, R)
    _, posterior = update(np.zeros(2), prior, 0.0, measurement_variance)
    return prior, posterior


def add_local_kalman_filter(builder: DiagramBuilder, name: str, **filter_arguments) -> PortMap:
    """Adds one local filter to ``builder`` (``local_kalman_filter_system`` says what it is).

    .. pydrake_system::

        name: kinect_v1_filter
        input_ports:
        - distance_m
        - valid
        output_ports:
        - estimated_state
        - covariance
        - health

    Args:
        builder: where the filter's systems go.
        name: the filter's name.
        **filter_arguments: the keyword arguments of ``local_kalman_filter_system`` (the
            camera's height and frame period, the variances, the start, the range, ``config``
            and ``detection``).
    """
    return add_symbolic_system(builder, name, local_kalman_filter_system(name, **filter_arguments))


@building_expressions
def local_kalman_filter_system(
    name: str,
    *,
    camera_height_m: float,
    frame_period_s: float,
    acceleration_variance_m2_s4: float,
    measurement_variance_m2: float,
    initial_height_m: float,
    valid_range_m: tuple[float, float],
    config: LocalFilterConfig,
    detection: FaultDetectionConfig,
) -> SymbolicSystem:
    """One local filter's expressions, to add alone or in a bank (``add_symbolic_banks``).

    Its ports are those of ``add_local_kalman_filter``.

    Args:
        name: the filter's name (in errors).
        camera_height_m: the camera's height above the table; height = camera_height_m - distance.
        frame_period_s: the camera's frame period, the filter's tick (s).
        acceleration_variance_m2_s4: σ_a² (m²/s⁴).
        measurement_variance_m2: σ_r² (m²).
        initial_height_m: the estimate's start (m); velocity starts at 0.
        valid_range_m: (nearest, farthest) distance the camera can report (m); frames outside it
            are not used.
        config: the initial uncertainty.
        detection: the innovation gate and the camera's checks (``fault_detection``).

    ``estimated_state`` is [height (m), velocity (m/s)] and ``covariance`` the 2x2 P row-major, both
    predicted to the current time from the last tick. ``health`` is ``TRACK_FLAGS``, each 1 when
    set: a frame outside the innovation gate is not used, like one outside the range.
    """
    for field_name, value in [
        ("frame_period_s", frame_period_s),
        ("acceleration_variance_m2_s4", acceleration_variance_m2_s4),
        ("measurement_variance_m2", measurement_variance_m2),
        ("initial_position_std_m", config.initial_position_std_m),
        ("initial_velocity_std_m_s", config.initial_velocity_std_m_s),
    ]:
        if not value > 0:
            raise ConfigError(f"{name}: {field_name} = {value}: expected a positive value")
    t = Variable("t")
    distance = Variable("distance_m")
    valid = Variable("valid")
    # The state is stored relative to its start, so Drake's zero default state is the configured
    # initial estimate: [height, velocity, P00, P01, P11] offsets, then the last tick's time.
    s = MakeVectorVariable(5, "offset")
    last_tick = Variable("last_tick_s")
    # The checks' memory (zero at the start): the last usable frame's time, rejected frames and
    # identical readings in a row, and the last reading.
    last_usable, rejected, repeated, last_distance = (
        Variable(n) for n in ("last_usable_s", "rejected_frames", "repeated_frames", "last_m")
    )
    x0 = np.array([initial_height_m, 0.0])
    P0 = np.diag([config.initial_position_std_m**2, config.initial_velocity_std_m_s**2])
    x = x0 + np.array([s[0], s[1]])
    P = P0 + np.array([[s[2], s[3]], [s[3], s[4]]])

    # Ticks are periodic, so the update predicts over one frame period with numeric F and Q: the
    # expressions stay small (they are re-evaluated node by node every tick). Only the output,
    # predicted to the current time, needs the symbolic interval.
    x_prior, P_prior = predict(x, P, frame_period_s, acceleration_variance_m2_s4)
    measured = camera_height_m - distance
    x_post, P_post = update(x_prior, P_prior, measured, measurement_variance_m2)
    # Comparisons with NaN are false, so a NaN distance is never usable.
    in_range = logical_and(
        valid > 0.5, logical_and(distance >= valid_range_m[0], distance <= valid_range_m[1])
    )
    innovation = measured - x_prior[0]
    innovation_variance = P_prior[0, 0] + measurement_variance_m2
    in_gate = (
        innovation * innovation
        <= nis_bound(detection.innovation_gate_probability) * innovation_variance
    )
    usable = logical_and(in_range, in_gate)
    chosen_x = [if_then_else(usable, x_post[i], x_prior[i]) for i in range(2)]
    chosen_P = [if_then_else(usable, P_post[i, j], P_prior[i, j]) for i, j in _UPPER]
    next_state = [chosen_x[i] - x0[i] for i in range(2)]
    next_state += [chosen_P[k] - P0[i, j] for k, (i, j) in enumerate(_UPPER)]
    next_state.append(Expression(t))
    next_state += [
        if_then_else(usable, Expression(t), Expression(last_usable)),
        # Out of the gate first: on most frames it is false and the range is never tested.
        if_all([logical_not(in_gate), in_range], rejected + 1, 0.0),
        if_then_else(logical_and(valid > 0.5, distance == last_distance), repeated + 1, 0.0),
        if_then_else(valid > 0.5, Expression(distance), Expression(last_distance)),
    ]

    frame_rate_hz = 1.0 / frame_period_s
    health = [
        if_then_else(t - last_usable > detection.stale_after_s, 1.0, 0.0),
        if_then_else(rejected >= frames_in(detection.rejecting_after_s, frame_rate_hz), 1.0, 0.0),
        if_then_else(repeated >= frames_in(detection.stuck_after_s, frame_rate_hz), 1.0, 0.0),
    ]
    x_now, P_now = predict(x, P, t - last_tick, acceleration_variance_m2_s4)
    return SymbolicSystem(
        inputs=[("distance_m", [distance]), ("valid", [valid])],
        outputs=[
            ("estimated_state", list(x_now)),
            ("covariance", list(P_now.flatten())),
            ("health", health),
        ],
        state=[*s, last_tick, last_usable, rejected, repeated, last_distance],
        dynamics=next_state,
        time=t,
        time_period=frame_period_s,
    )


_UPPER = [(0, 0), (0, 1), (1, 1)]


def _is_symbolic(value) -> bool:
    return isinstance(value, Expression | Variable)


make_local_kalman_filter = diagram_form(add_local_kalman_filter)
