"""LQG control of the head height (Sec. V, Eq. 27-34).

Design is pure: ``design_lqg`` returns the LQR gain from Drake's
DiscreteTimeLinearQuadraticRegulator (Eq. 29, 31 with N = 0) and the estimator gain from Drake's
DiscreteTimeSteadyStateKalmanFilter, which is the one-step predictor gain A P Cᵀ (C P Cᵀ + V)⁻¹ of
Eq. 34. Running is a system: ``make_lqg_controller`` wires an estimator (Eq. 34) and the feedback
law u = u_op - K (x̂ - N_x r) into a Diagram whose only Python is in its construction.

The measurement is the fused head height; the model's output is a camera distance, so the
controller converts with the camera height the model was identified in. The reference enters as the
steady state N_x r the model would hold at that output (the paper's regulator has no other path
for it), and the estimator is driven by the current actually applied after saturation, so it stays
consistent when the valve limits bite.
"""

from dataclasses import dataclass

import numpy as np
from pydrake.symbolic import MakeVectorVariable, Variable
from pydrake.systems.controllers import DiscreteTimeLinearQuadraticRegulator
from pydrake.systems.estimators import DiscreteTimeSteadyStateKalmanFilter
from pydrake.systems.framework import Diagram, DiagramBuilder

from maskless.systems.named_symbolic_system import (
    building_expressions,
    make_named_symbolic_system,
)
from maskless.systems.paper_parameters import IdentifiedModel, LqgWeights


@dataclass(frozen=True)
class LqgDesign:
    """Gains of an LQG design on a discrete model.

    Attributes:
        K: LQR gain, u = -K x (A/m in SI).
        S: the LQR Riccati solution P of Eq. 29.
        L: the estimator's predictor gain (dimensionless for a distance model).
        state_for_output: N_x, the steady state per unit output, (I - A) N_x = B N_u, C N_x = 1,
            with N_u = 0 when the model cannot hold an output without input.
    """

    K: np.ndarray
    S: np.ndarray
    L: np.ndarray
    state_for_output: np.ndarray


def design_lqg(model: IdentifiedModel, weights: LqgWeights) -> LqgDesign:
    """The paper's LQG gains for ``model`` with ``weights`` (Eq. 29-34)."""
    K, S = DiscreteTimeLinearQuadraticRegulator(model.A, model.B, weights.Q, weights.R)
    L = DiscreteTimeSteadyStateKalmanFilter(model.A, model.C, weights.W, weights.V)
    return LqgDesign(K=K, S=S, L=L, state_for_output=steady_state_per_output(model))


def steady_state_per_output(model: IdentifiedModel) -> np.ndarray:
    """N_x: a state that is an equilibrium with zero input deviation at unit output.

    For the paper's model the equilibria of x(k+1) = A x are the multiples of [1, 1] only if A has
    an eigenvalue at 1; it does not, so in general we take the state on the output direction that
    best satisfies x = A x (least squares), which for Eq. 26 is [1, 1] (both states are the output
    at consecutive samples).
    """
    n = model.A.shape[0]
    lhs = np.vstack([np.eye(n) - model.A, model.C])
    rhs = np.concatenate([np.zeros(n), [1.0]])
    solution, *_ = np.linalg.lstsq(lhs, rhs, rcond=None)
    return solution


def closed_loop_poles(model: IdentifiedModel, design: LqgDesign) -> dict[str, np.ndarray]:
    """Eigenvalues of the open loop A, the regulator A - B K and the estimator A - L C."""
    return {
        "open_loop": np.linalg.eigvals(model.A),
        "regulator": np.linalg.eigvals(model.A - model.B @ design.K),
        "estimator": np.linalg.eigvals(model.A - design.L @ model.C),
    }


@building_expressions
def make_lqg_controller(
    model: IdentifiedModel,
    design: LqgDesign,
    camera_height_m: float,
    name: str = "lqg_controller",
) -> Diagram:
    """Builds the LQG controller.

    .. pydrake_system::

        name: lqg_controller
        input_ports:
        - measured_head_height_m
        - reference_head_height_m
        - applied_current_a
        output_ports:
        - valve_current_a
        - estimated_model_state

    Args:
        model: the model the gains were designed on (SI).
        design: the gains.
        camera_height_m: height of the camera whose distance the model outputs (m).
        name: the Diagram's name.

    The estimator ticks at the model's sample period; the command is x̂'s feedback, so it changes
    only at ticks (the one-sample computation delay of the predictor form, Eq. 34). The estimator
    state starts at zero: the model's operating point.
    """
    n = model.A.shape[0]
    A, B, C, K, L = model.A, model.B, model.C, design.K, design.L
    x_hat = MakeVectorVariable(n, "x_hat")
    measured_height = Variable("measured_head_height_m")
    applied = Variable("applied_current_a")
    measured_output = camera_height_m - measured_height - model.operating_output_m
    innovation = measured_output - (C @ x_hat)[0]
    next_x_hat = A @ x_hat + B[:, 0] * (applied - model.operating_input_a) + L[:, 0] * innovation
    estimator = make_named_symbolic_system(
        "estimator",
        inputs=[("measured_head_height_m", [measured_height]), ("applied_current_a", [applied])],
        outputs=[("estimated_model_state", list(x_hat))],
        state=list(x_hat),
        dynamics=list(next_x_hat),
        time_period=model.sample_period_s,
    )

    state_in = MakeVectorVariable(n, "x_hat")
    reference_height = Variable("reference_head_height_m")
    reference_output = camera_height_m - reference_height - model.operating_output_m
    state_error = np.array(list(state_in)) - design.state_for_output * reference_output
    command = model.operating_input_a - (K @ state_error)[0]
    law = make_named_symbolic_system(
        "feedback_law",
        inputs=[
            ("estimated_model_state", list(state_in)),
            ("reference_head_height_m", [reference_height]),
        ],
        outputs=[("valve_current_a", [command])],
    )

    builder = DiagramBuilder()
    builder.AddSystem(estimator)
    builder.AddSystem(law)
    builder.Connect(
        estimator.GetOutputPort("estimated_model_state"), law.GetInputPort("estimated_model_state")
    )
    builder.ExportInput(estimator.GetInputPort("measured_head_height_m"), "measured_head_height_m")
    builder.ExportInput(law.GetInputPort("reference_head_height_m"), "reference_head_height_m")
    builder.ExportInput(estimator.GetInputPort("applied_current_a"), "applied_current_a")
    builder.ExportOutput(law.GetOutputPort("valve_current_a"), "valve_current_a")
    builder.ExportOutput(estimator.GetOutputPort("estimated_model_state"), "estimated_model_state")
    diagram = builder.Build()
    diagram.set_name(name)
    return diagram
