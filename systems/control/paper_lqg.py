"""LQG control of the head height (Sec. V, Eq. 27-34).

Design is pure: ``design_lqg`` returns the LQR gain from Drake's
DiscreteTimeLinearQuadraticRegulator (Eq. 29, 31 with N = 0) and the estimator gain from Drake's
DiscreteTimeSteadyStateKalmanFilter, which is the one-step predictor gain A P Cᵀ (C P Cᵀ + V)⁻¹ of
Eq. 34. Running is a system: ``make_paper_lqg`` runs the estimator (Eq. 34) and the feedback
law u = u_op - K (x̂ - N_x r) as one discrete system whose only Python is in its construction.

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
from pydrake.systems.framework import DiagramBuilder

from maskless.errors import ModelError
from maskless.systems.linear_model import LinearModel
from maskless.systems.named_symbolic_system import (
    PortMap,
    add_named_symbolic_system,
    building_expressions,
    diagram_form,
)
from maskless.systems.paper_parameters import (
    LqgWeights,
    PaperParameters,
    paper_identified_model,
    paper_lqg_weights,
)
from maskless.systems.plant.valve_map import effective_valve_current


@dataclass(frozen=True)
class LqgDesign:
    """Gains of an LQG design on a discrete model.

    Attributes:
        K: LQR gain, u = -K x (A/m in SI).
        S: the LQR Riccati solution P of Eq. 29.
        L: the estimator's predictor gain (dimensionless for a distance model).
        state_for_output: N_x, the state that sets the regulator's target for a reference r: the
            controller regulates x̂ towards N_x r. The paper's regulator has no feedforward path
            (N_u = 0), so N_x is the model's steady target with the input held
            (``LinearModel.steady_target(hold_input=True)``): the least-squares solution of
            (I - A) N_x = 0, C N_x = 1, which for Eq. 26 is about [1, 1] (both states are the
            output at consecutive samples).
    """

    K: np.ndarray
    S: np.ndarray
    L: np.ndarray
    state_for_output: np.ndarray


def design_lqg(model: LinearModel, weights: LqgWeights) -> LqgDesign:
    """The paper's LQG gains for ``model`` with ``weights`` (Eq. 29-34).

    Raises:
        ModelError: ``model`` has a feedthrough D (the controller's command depends on its
            estimate only, so the paper's loop has none).
    """
    if model.D[0, 0] != 0.0:
        raise ModelError(f"D = {model.D[0, 0]}: the paper's LQG needs a model without feedthrough")
    K, S = DiscreteTimeLinearQuadraticRegulator(model.A, model.B, weights.Q, weights.R)
    L = DiscreteTimeSteadyStateKalmanFilter(model.A, model.C, weights.W, weights.V)
    state_for_output, _ = model.steady_target(hold_input=True)
    return LqgDesign(K=K, S=S, L=L, state_for_output=state_for_output)


def paper_lqg(paper: PaperParameters) -> tuple[LinearModel, LqgDesign]:
    """The paper's model (Eq. 26) and its LQG gains from the paper's weights."""
    model = paper_identified_model(paper)
    return model, design_lqg(model, paper_lqg_weights(paper))


def closed_loop_poles(model: LinearModel, design: LqgDesign) -> dict[str, np.ndarray]:
    """Eigenvalues of the open loop A, the regulator A - B K and the estimator A - L C."""
    return {
        "open_loop": model.poles(),
        "regulator": np.linalg.eigvals(model.A - model.B @ design.K),
        "estimator": np.linalg.eigvals(model.A - design.L @ model.C),
    }


def controller_state_space(model: LinearModel, design: LqgDesign) -> LinearModel:
    """The paper's LQG controller at a constant reference, from output to current deviation.

    From the output deviation y to the current deviation u: the predictor
    x̂+ = A x̂ + B u + L (y - C x̂) (Eq. 34) with u = -K x̂, that is
    x̂+ = (A - B K - L C) x̂ + L y, u = -K x̂ (no feedthrough: the command depends on the
    estimate only, as in ``add_paper_lqg``). The sign is the controller's own, as
    ``analysis.stability.margins`` expects.

    Args:
        model: the model the gains were designed on.
        design: the gains (``design_lqg``).
    """
    A, B, C = model.A, model.B, model.C
    return model.controller(
        A - B @ design.K - design.L @ C,
        design.L,
        -design.K,
        np.zeros((1, 1)),
    )


@building_expressions
def add_paper_lqg(
    builder: DiagramBuilder,
    model: LinearModel,
    design: LqgDesign,
    camera_height_m: float,
    valve_currents_a: tuple[float, float],
    name: str = "paper_lqg",
) -> PortMap:
    """Adds the LQG controller to ``builder``.

    .. pydrake_system::

        name: paper_lqg
        input_ports:
        - fused_estimated_state
        - reference_head_height_m
        - applied_current_a
        output_ports:
        - valve_current_a
        - estimated_head_height_m

    Args:
        builder: where the controller's systems go.
        model: the model the gains were designed on (SI).
        design: the gains.
        camera_height_m: height of the camera whose distance the model outputs (m).
        valve_currents_a: the valve's (starting, saturation) currents (A), the static input map
            the model's input passes through.
        name: the controller's name.

    Every sample period the controller reads the fused estimate's height (the measurement y of
    Eq. 34), the reference and the current actually applied, updates its estimate x̂ (Eq. 34) and
    holds the reference it read; its command u = u_op - K (x̂ - N_x r) depends on that state only,
    so a new reference acts at the next tick (a sampled-data controller) and the command changes
    only at ticks (the one-sample computation delay of the predictor form). The state is
    [x̂, held reference offset]; it starts at zero: the model's operating point.
    """
    n = model.A.shape[0]
    A, B, C, K, L = model.A, model.B, model.C, design.K, design.L
    x_hat = MakeVectorVariable(n, "x_hat")
    held_reference = Variable("held_reference_output_m")  # r in the model's output coordinates
    fused = MakeVectorVariable(2, "fused_estimated_state")
    reference_height = Variable("reference_head_height_m")
    applied = Variable("applied_current_a")

    def model_output(height):
        """A head height as the model's output: distance below the camera, minus d_op."""
        return camera_height_m - height - model.operating_output

    innovation = model_output(fused[0]) - (C @ x_hat)[0]
    # The model's input is the current after the valve's static map (the Hammerstein structure it
    # was identified with), so the estimator sees what the valve passes, not what was asked.
    passed = effective_valve_current(applied, *valve_currents_a)
    next_x_hat = A @ x_hat + B[:, 0] * (passed - model.operating_input) + L[:, 0] * innovation
    command = model.operating_input - (K @ (x_hat - design.state_for_output * held_reference))[0]
    return add_named_symbolic_system(
        builder,
        name,
        inputs=[
            ("fused_estimated_state", list(fused)),
            ("reference_head_height_m", [reference_height]),
            ("applied_current_a", [applied]),
        ],
        outputs=[
            ("valve_current_a", [command]),
            # The head height the estimate x̂ stands for (the safety supervisor's beam hold).
            (
                "estimated_head_height_m",
                [camera_height_m - model.operating_output - (C @ x_hat)[0]],
            ),
        ],
        state=[*x_hat, held_reference],
        dynamics=[*next_x_hat, model_output(reference_height)],
        time_period=model.sample_period_s,
    )


make_paper_lqg = diagram_form(add_paper_lqg)
