"""The paper's LQG: its gains against scipy's Riccati solutions in the paper's units, its ports."""

import dataclasses

import numpy as np
import pytest
import scipy.linalg
from system_harness import port_layout

from maskless.errors import ModelError
from maskless.systems.control.paper_lqg import (
    closed_loop_poles,
    design_lqg,
    make_paper_lqg,
)
from maskless.systems.paper_parameters import (
    load_paper_parameters,
    paper_identified_model,
    paper_lqg_weights,
)

CAMERA_M = 0.9


@pytest.fixture(scope="module")
def paper():
    return load_paper_parameters()


@pytest.fixture(scope="module")
def model(paper):
    return paper_identified_model(paper)


@pytest.fixture(scope="module")
def design(paper, model):
    return design_lqg(model, paper_lqg_weights(paper))


def test_lqr_gain_matches_scipy_in_the_papers_units(paper, model, design):
    # Eq. 29 and 31 (N = 0) solved by scipy in mm and mA; K in mA/mm equals K in A/m.
    A, B = model.A, np.array(paper.B_mm_per_ma).reshape(2, 1)
    Q, R = np.eye(2) * 1.0566, np.array([[0.058006]])
    P = scipy.linalg.solve_discrete_are(A, B, Q, R)
    K = np.linalg.solve(R + B.T @ P @ B, B.T @ P @ A)
    np.testing.assert_allclose(design.K, K, rtol=1e-6)


def test_estimator_gain_is_scipys_one_step_predictor_gain(model, design):
    # Eq. 34: L = A P C' (C P C' + Re)^-1, P from the dual DARE, Qe = 0.4511 I, Re = 0.01 (mm^2).
    A, C = model.A, model.C
    P = scipy.linalg.solve_discrete_are(A.T, C.T, np.eye(2) * 0.4511, np.array([[0.01]]))
    L = A @ P @ C.T @ np.linalg.inv(C @ P @ C.T + 0.01)
    np.testing.assert_allclose(design.L, L, rtol=1e-6)


def test_a_model_with_feedthrough_is_refused(paper, model):
    with pytest.raises(ModelError, match="D = 0.001: .* without feedthrough"):
        design_lqg(dataclasses.replace(model, D=[[1e-3]]), paper_lqg_weights(paper))


def test_the_papers_lqr_leaves_the_poles_where_they_were(model, design):
    poles = closed_loop_poles(model, design)
    open_loop = np.sort_complex(poles["open_loop"])
    np.testing.assert_allclose(np.sort_complex(poles["regulator"]), open_loop, atol=1e-6)
    # The closed form of Eq. 26's poles: z^2 - 1.988 z + 0.9883 = 0.
    np.testing.assert_allclose(np.sort_complex(np.roots([1, -1.988, 0.9883])), open_loop)
    assert np.all(np.abs(poles["estimator"]) < 1)


def test_state_for_output_is_the_steady_target_with_the_input_held(model, design):
    # The paper's regulator has no feedforward: its target holds the input at the operating point.
    N_x = design.state_for_output
    np.testing.assert_array_equal(N_x, model.steady_target(hold_input=True)[0])
    assert (model.C @ N_x)[0] == pytest.approx(1.0, abs=1e-3)
    np.testing.assert_allclose(N_x, [1.0, 1.0], atol=2e-3)  # both states are the output


@pytest.mark.parametrize(
    "applied, passed",
    [(0.09, 0.09), (0.03, 0.0), (0.2, 0.165)],
    ids=["linear_range", "below_starting_current", "above_saturation"],
)
def test_controller_ports_and_equations(model, design, applied, passed):
    controller = make_paper_lqg(model, design, CAMERA_M, (0.060, 0.165), name="paper_lqg")
    assert controller.get_name() == "paper_lqg"
    assert port_layout(controller) == (
        {"fused_estimated_state": 2, "reference_head_height_m": 1, "applied_current_a": 1},
        {"valve_current_a": 1, "estimated_head_height_m": 1},
    )
    context = controller.CreateDefaultContext()
    x_hat = np.array([0.001, 0.0015])
    held_reference = -0.004  # the model's output coordinate of the reference read last tick
    context.SetDiscreteState(np.append(x_hat, held_reference))
    height, reference = 0.205, 0.212
    controller.GetInputPort("fused_estimated_state").FixValue(context, [height, 0.01])
    controller.GetInputPort("reference_head_height_m").FixValue(context, [reference])
    controller.GetInputPort("applied_current_a").FixValue(context, [applied])
    # u = u_op - K (x_hat - N_x r) with the reference held from the last tick.
    u_expected = model.operating_input - design.K @ (
        x_hat - design.state_for_output * held_reference
    )
    assert controller.GetOutputPort("valve_current_a").Eval(context)[0] == pytest.approx(
        u_expected[0], rel=1e-12
    )
    # The height x_hat stands for: its output is the distance below the camera, less d_op.
    assert controller.GetOutputPort("estimated_head_height_m").Eval(context)[0] == pytest.approx(
        CAMERA_M - model.operating_output - (model.C @ x_hat)[0], rel=1e-12
    )
    # Eq. 34: x(k+1) = A x - L (C x - y) + B u, y and u as deviations in the model's coordinates
    # (distance below the camera), u the current the valve passes (no flow below 60 mA, clipped at
    # 165 mA), and the new reference is held.
    y = CAMERA_M - height - model.operating_output
    expected_next = (
        model.A @ x_hat
        - design.L[:, 0] * ((model.C @ x_hat)[0] - y)
        + model.B[:, 0] * (passed - model.operating_input)
    )
    updated = controller.EvalUniquePeriodicDiscreteUpdate(context).get_vector().CopyToVector()
    np.testing.assert_allclose(updated[:2], expected_next, rtol=1e-12)
    assert updated[2] == pytest.approx(CAMERA_M - reference - model.operating_output)
