"""Offset-free LQG: the controller that holds the head within the clinical 1 mm.

Design is pure (``design_offset_free_lqg``): the plant's discrete linear model (from Drake's
``Linearize`` of the pneumatic plant, or an identified model) is augmented with a constant input
disturbance d, x+ = A x + B (u + d), and, for the estimator, with the measurement's delay: the
fused height the controller reads at a tick is the head's height some ticks ago (the camera's
latency, and one tick because the controller reads the filters' state before its own tick), so the
estimator carries a chain of past heights and reads the oldest, y = C x(k - delay). Modelling the
2-tick delay lowered the worst overshoot in benchmarks/accuracy.py from 0.61 to 0.57 mm with the
shipped weights (from 1.46 to 1.31 mm with a ten times lighter command weight).

Drake's DiscreteTimeLinearQuadraticRegulator gives the state feedback K on (A, B); Drake's
DiscreteAlgebraicRiccatiEquation gives the steady Kalman covariance of the augmented model, from
which the filter gain M = P Cᵀ (C P Cᵀ + V)⁻¹ corrects the estimate with the measurement of the
same tick (the predictor gain A P Cᵀ (...)⁻¹ that ``DiscreteTimeSteadyStateKalmanFilter`` returns
would add a sample of delay).

Running is one discrete system (``add_offset_free_lqg``), which reads its command from a stateless
one (``{name}.command``) so that the command is computed once per tick. Every period it

1. corrects its prediction with the fused height: x̂ = x̂⁻ + M (y - C x̂⁻);
2. commands u = N_u Δr - d̂ - K (x̂ - N_x Δr), where (N_x, N_u) is the steady state and input that
   hold the reference deviation Δr (the target calculation) and d̂ the disturbance estimate, which
   removes any steady offset: a model error, a heavier head, valve hysteresis;
3. saturates the command to what the valves can do and stores it; the estimator predicts with the
   saturated command, so neither it nor the disturbance estimate winds up (anti-windup);
4. passes the command through the split-range allocation (the Hammerstein inverse) to the two
   valve currents.
"""

from dataclasses import dataclass

import numpy as np
import pydrake.math as dm
from pydrake.math import DiscreteAlgebraicRiccatiEquation
from pydrake.symbolic import MakeVectorVariable, Variable
from pydrake.systems.controllers import DiscreteTimeLinearQuadraticRegulator
from pydrake.systems.framework import DiagramBuilder

from maskless.errors import ModelError
from maskless.systems.config_loading import UNSET
from maskless.systems.control.valve_allocation import SplitRangeAllocation
from maskless.systems.linear_model import LinearModel
from maskless.systems.named_symbolic_system import (
    PortMap,
    add_named_symbolic_system,
    building_expressions,
    diagram_form,
)


@dataclass
class OffsetFreeLqgWeights:
    """Design weights, in SI; assets/simulation.yaml gives the reasons for the shipped values.

    The command and its disturbance are weighed by the height they would hold in steady state
    (the model's DC gain times the command), so the same weights serve a model driven by a lift
    command (the pneumatic design, DC gain about 1) and one driven by a current in amperes (an
    identified model, DC gain ~0.2 m/A).

    Attributes:
        output_error_weight_per_m2: LQR weight on the height error, y² (1/m²).
        command_weight_per_m2: LQR weight on the command's height equivalent (1/m²).
        state_weight_fraction: LQR weight on each model state, as a fraction of the output's
            (keeps the Riccati equation well posed for states the output does not see).
        process_noise_m2: Kalman process noise on each model state per period (model error).
        disturbance_noise_m2: Kalman random-walk variance of the input disturbance's height
            equivalent per period: how fast the offset estimate follows a change.
        measurement_noise_m2: variance of the fused height the controller reads.
    """

    output_error_weight_per_m2: float = UNSET
    command_weight_per_m2: float = UNSET
    state_weight_fraction: float = UNSET
    process_noise_m2: float = UNSET
    disturbance_noise_m2: float = UNSET
    measurement_noise_m2: float = UNSET


@dataclass(frozen=True)
class OffsetFreeLqgDesign:
    """The gains of an offset-free LQG design.

    Attributes:
        model: the model designed on.
        measurement_delay_samples: ticks between the head's height and its fused estimate
            reaching the controller.
        K: LQR gain on the model state, u = -K x (1 x n).
        M: Kalman filter (update) gain of the augmented state [x, d, delayed heights]
            ((n + 1 + delay) x 1).
        augmented_A, augmented_B, augmented_C: the disturbance- and delay-augmented model.
        state_per_reference: N_x, steady state per unit reference deviation.
        command_per_reference: N_u, steady command per unit reference deviation.
    """

    model: LinearModel
    measurement_delay_samples: int
    K: np.ndarray
    M: np.ndarray
    augmented_A: np.ndarray
    augmented_B: np.ndarray
    augmented_C: np.ndarray
    state_per_reference: np.ndarray
    command_per_reference: float

    def estimator_state_at(self, output_deviation_m: float) -> np.ndarray:
        """The augmented state [x, d, delayed heights] at rest at ``output_deviation_m``.

        The disturbance estimate d is zero.
        """
        return np.concatenate(
            [
                self.state_per_reference * output_deviation_m,
                [0.0],
                np.full(self.measurement_delay_samples, output_deviation_m),
            ]
        )


def augment_for_estimation(model: LinearModel, measurement_delay_samples: int = 0):
    """(A_a, B_a, C_a) of the model augmented with an input disturbance and the measurement delay.

    The augmented model is x+ = A x + B (u + d), d+ = d, z1+ = C x, z(i+1)+ = z(i), and the
    measurement y = z(delay) (y = C x with no delay).
    """
    if measurement_delay_samples < 0:
        raise ValueError(f"measurement_delay_samples must be >= 0, got {measurement_delay_samples}")
    n, delay = model.A.shape[0], measurement_delay_samples
    size = n + 1 + delay
    A_a = np.zeros((size, size))
    A_a[:n, :n], A_a[:n, n : n + 1], A_a[n, n] = model.A, model.B, 1.0
    B_a = np.zeros((size, 1))
    B_a[:n] = model.B
    C_a = np.zeros((1, size))
    if delay == 0:
        C_a[:, :n] = model.C
    else:
        A_a[n + 1, :n] = model.C[0]
        for i in range(1, delay):
            A_a[n + 1 + i, n + i] = 1.0
        C_a[0, size - 1] = 1.0
    return A_a, B_a, C_a


def design_offset_free_lqg(
    model: LinearModel, weights: OffsetFreeLqgWeights, measurement_delay_samples: int = 0
) -> OffsetFreeLqgDesign:
    """LQR and steady Kalman gains for ``model`` with an input-disturbance estimate.

    The measurement is ``measurement_delay_samples`` ticks old.

    Args:
        model: the plant's model, its output the head height (m); D = 0.
        weights: the design weights.
        measurement_delay_samples: ticks between the head's height and the measurement.

    Raises:
        ModelError: a model with feedthrough, an integrating model (a pole at z = 1, which it
            names) or one whose input holds no output in steady state: the weights are given per
            metre of steady height, so the design needs a bounded, nonzero DC gain.
    """
    if model.D[0, 0] != 0.0:
        raise ModelError(
            f"D = {model.D[0, 0]}: the offset-free design needs a model without feedthrough (the "
            "command acts after the tick that measured)"
        )
    n = model.A.shape[0]
    try:
        N_x, N_u = model.steady_target()
    except ModelError as error:
        raise ModelError(
            f"{error}; the offset-free design weighs the command and the disturbance per metre "
            "of the height they hold in steady state, so it needs a bounded, nonzero DC gain: "
            "identify a model whose slowest pole is stable and whose input moves the output"
        ) from None
    state_scale = _output_scaled_identity(N_x)
    Q = weights.output_error_weight_per_m2 * (
        model.C.T @ model.C + weights.state_weight_fraction * state_scale
    )
    # Weights on the command's height equivalent g u, with g the DC gain (m per command unit),
    # here from the steady target already solved (C N_x = 1 with N_u holding it): g = 1 / N_u.
    height_per_command = 1.0 / N_u
    R = np.array([[weights.command_weight_per_m2 * height_per_command**2]])
    K, _ = DiscreteTimeLinearQuadraticRegulator(model.A, model.B, Q, R)
    A_a, B_a, C_a = augment_for_estimation(model, measurement_delay_samples)
    # The delayed heights are exact copies: no process noise of their own.
    W = np.zeros_like(A_a)
    W[:n, :n] = weights.process_noise_m2 * state_scale
    W[n, n] = weights.disturbance_noise_m2 / height_per_command**2
    V = np.array([[weights.measurement_noise_m2]])
    # The filter's prior covariance solves the dual (estimation) Riccati equation.
    P = DiscreteAlgebraicRiccatiEquation(A_a.T, C_a.T, W, V)
    M = P @ C_a.T / (C_a @ P @ C_a.T + V)[0, 0]
    return OffsetFreeLqgDesign(
        model=model,
        measurement_delay_samples=measurement_delay_samples,
        K=K,
        M=M,
        augmented_A=A_a,
        augmented_B=B_a,
        augmented_C=C_a,
        state_per_reference=N_x,
        command_per_reference=N_u,
    )


def _output_scaled_identity(N_x: np.ndarray) -> np.ndarray:
    """A diagonal that weighs each state as much as the output it would produce in steady state.

    In steady state the states are N_x per unit output, so one number weighs states of any units
    (Pa, m, A) evenly.
    """
    scale = np.where(np.abs(N_x) > 1e-12, 1.0 / np.maximum(np.abs(N_x), 1e-12), 1.0)
    return np.diag(scale**2)


def closed_loop_poles(design: OffsetFreeLqgDesign) -> dict[str, np.ndarray]:
    """Regulator poles eig(A - B K) and estimator poles eig(A_a - A_a M C_a) (separation)."""
    model = design.model
    A_a, C_a = design.augmented_A, design.augmented_C
    return {
        "regulator": np.linalg.eigvals(model.A - model.B @ design.K),
        "estimator": np.linalg.eigvals(A_a - A_a @ design.M @ C_a),
    }


def controller_state_space(design: OffsetFreeLqgDesign) -> LinearModel:
    """The unsaturated controller from the measured height deviation y to the command deviation u.

    At a constant reference (Δr = 0), with the predicted estimate as state: z̄ = z + M (y - C_a z),
    u = -F z̄, z+ = A_a z̄ + B_a u, where F = [K, 1, 0...] (the disturbance estimate is subtracted
    from the command). The sign is the controller's own (u = C_c z + D_c y), as
    ``analysis.stability.margins`` expects.
    """
    model = design.model
    size = design.augmented_A.shape[0]
    n = model.A.shape[0]
    F = np.zeros((1, size))
    F[0, :n], F[0, n] = design.K[0], 1.0
    correct = np.eye(size) - design.M @ design.augmented_C
    closed = design.augmented_A - design.augmented_B @ F
    return model.controller(
        closed @ correct,
        closed @ design.M,
        -F @ correct,
        -F @ design.M,
    )


@building_expressions
def add_offset_free_lqg(
    builder: DiagramBuilder,
    design: OffsetFreeLqgDesign,
    allocation: SplitRangeAllocation,
    initial_height_m: float,
    name: str = "offset_free_lqg",
) -> PortMap:
    """Adds the offset-free LQG controller to ``builder``.

    .. pydrake_system::

        name: offset_free_lqg
        input_ports:
        - fused_estimated_state
        - reference_head_height_m
        output_ports:
        - inlet_valve_current_a
        - outlet_valve_current_a
        - command
        - estimated_head_height_m

    Args:
        builder: where the controller goes.
        design: the gains (``design_offset_free_lqg``).
        allocation: maps the command (the model's input units) to the two valve currents.
        initial_height_m: the controller starts believing the head rests here (m): its state
            estimate and held command are the model's equilibrium at this height.
        name: the controller's name.

    The state is [x̂⁻ (n), d̂, delayed heights, held command deviation, inlet and outlet
    currents], stored as offsets from that start (a SymbolicVectorSystem's default state is zero).
    The command changes only at ticks and takes effect right after the tick that read the
    measurement. ``estimated_head_height_m`` is the model's height now, predicted from the last
    tick's corrected estimate and command (the measurement it corrects with is ticks old): the
    safety supervisor gates the beam on it.
    """
    model = design.model
    n = model.A.shape[0]
    low, high = (c - model.operating_input for c in allocation.command_range)
    start_deviation = initial_height_m - model.operating_output
    start_state = design.estimator_state_at(start_deviation)
    size = start_state.size
    start_command = float(np.clip(design.command_per_reference * start_deviation, low, high))
    predicted_offset = MakeVectorVariable(size, "x_hat_offset")
    held_command_offset = Variable("held_command_offset")
    # [x̂⁻, d̂, delayed heights] before this tick's correction
    predicted = np.array([start_state[k] + predicted_offset[k] for k in range(size)])
    held_command = start_command + held_command_offset
    start_currents = [float(c) for c in allocation.currents(model.operating_input + start_command)]
    current_offsets = MakeVectorVariable(2, "current_offset")
    fused = MakeVectorVariable(2, "fused_estimated_state")
    reference = Variable("reference_head_height_m")

    measured = fused[0] - model.operating_output
    innovation = measured - (design.augmented_C @ predicted)[0]
    corrected = predicted + design.M[:, 0] * innovation
    x_hat, d_hat = corrected[:n], corrected[n]
    reference_deviation = reference - model.operating_output
    command = (
        design.command_per_reference * reference_deviation
        - d_hat
        - (design.K @ (x_hat - design.state_per_reference * reference_deviation))[0]
    )
    # A symbolic system evaluates every copy of a sub-expression, and the command (with the
    # innovation in it) appears in every next estimate and in each of the allocation's segments,
    # 17 copies in all (about three quarters of the update's nodes). So a first system,
    # ``{name}.command``, computes the command once, up to its lower limit, and the controller
    # reads it as a variable: min(bounded_below, high) is the same node over the same value, and
    # a min sorts after the sums beside it as before, so every sum adds its terms in the same
    # order and no bit changes (tests/test_offset_free_lqg.py checks).
    bounded_below = Variable("command_bounded_below")
    applied = dm.min(bounded_below, high)
    next_predicted = design.augmented_A @ corrected + design.augmented_B[:, 0] * applied

    # The currents are computed at the tick and held as state: the plant reads them every step,
    # and a state output costs nothing to evaluate.
    next_currents = allocation.currents(model.operating_input + applied)
    command_ports = add_named_symbolic_system(
        builder,
        f"{name}.command",
        inputs=[
            ("fused_estimated_state", list(fused)),
            ("reference_head_height_m", [reference]),
            ("predicted_estimate_offset", list(predicted_offset)),
        ],
        # The fused height passes through, so the controller needs no Multiplexer of its own.
        outputs=[("command_input", [fused[0], dm.max(command, low)])],
    )
    ports = add_named_symbolic_system(
        builder,
        name,
        inputs=[("command_input", [fused[0], bounded_below])],
        outputs=[
            ("inlet_valve_current_a", [start_currents[0] + current_offsets[0]]),
            ("outlet_valve_current_a", [start_currents[1] + current_offsets[1]]),
            ("command", [model.operating_input + held_command]),
            ("estimated_head_height_m", [model.operating_output + (model.C @ predicted[:n])[0]]),
            ("predicted_estimate_offset", list(predicted_offset)),
        ],
        state=[*predicted_offset, held_command_offset, *current_offsets],
        dynamics=[
            *(next_predicted - start_state),
            applied - start_command,
            next_currents[0] - start_currents[0],
            next_currents[1] - start_currents[1],
        ],
        time_period=model.sample_period_s,
    )
    builder.Connect(command_ports.outputs["command_input"], ports.inputs.pop("command_input"))
    builder.Connect(
        ports.outputs.pop("predicted_estimate_offset"),
        command_ports.inputs.pop("predicted_estimate_offset"),
    )
    ports.inputs = command_ports.inputs
    return ports


make_offset_free_lqg = diagram_form(add_offset_free_lqg)
