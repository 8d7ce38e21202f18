"""Track-to-track fusion against Eq. 10 written with explicit inverses."""

import numpy as np
import pytest
from pydrake.symbolic import Expression, ExpressionKind, MakeVectorVariable, Variable
from system_harness import port_layout

from maskless.diagrams.scenario import load_scenario
from maskless.systems.sensing.track_fusion import (
    fuse_tracks,
    fusion_expressions,
    make_track_fusion,
)

DETECTION = load_scenario().fault_detection  # the shipped checks


def random_tracks(count, seed):
    rng = np.random.default_rng(seed)
    states, covariances = [], []
    for _ in range(count):
        M = rng.normal(size=(2, 2)) * 1e-3
        covariances.append(M @ M.T + np.eye(2) * 1e-7)
        states.append(np.array([0.2, 0.0]) + rng.normal(size=2) * 1e-3)
    return states, covariances


def eq_10(states, covariances):
    """Eq. 10 with explicit inverses."""
    informations = [np.linalg.inv(P) for P in covariances]
    P_F = np.linalg.inv(sum(informations))
    x_F = P_F @ sum(Y @ x for Y, x in zip(informations, states, strict=True))
    return x_F, P_F


@pytest.mark.parametrize("count, seed", [(2, 0), (2, 1), (3, 2), (1, 3)])
def test_fuse_tracks_matches_eq_10(count, seed):
    states, covariances = random_tracks(count, seed)
    x_F, P_F = fuse_tracks(states, covariances)
    x_ref, P_ref = eq_10(states, covariances)
    np.testing.assert_allclose(x_F, x_ref, rtol=1e-9)
    np.testing.assert_allclose(P_F, P_ref, rtol=1e-8)


def test_fusion_weights_the_less_noisy_track_more():
    x_F, P_F = fuse_tracks(
        [np.array([1.0, 0.0]), np.array([2.0, 0.0])], [np.eye(2) * 4.0, np.eye(2) * 1.0]
    )
    # Scalar closed form: (x1/s1 + x2/s2) / (1/s1 + 1/s2) = (0.25 + 2) / 1.25
    assert x_F[0] == pytest.approx(1.8)
    assert P_F[0, 0] == pytest.approx(0.8)


def test_system_ports_and_output_match_eq_10():
    fusion = make_track_fusion(["kinect_v1", "kinect_v2"], DETECTION)
    assert fusion.get_name() == "fusion"
    assert port_layout(fusion) == (
        {
            "kinect_v1_estimated_state": 2,
            "kinect_v1_covariance": 4,
            "kinect_v1_health": 3,
            "kinect_v2_estimated_state": 2,
            "kinect_v2_covariance": 4,
            "kinect_v2_health": 3,
        },
        {"estimated_state": 2, "covariance": 4, "health": 3},
    )
    states, covariances = random_tracks(2, 7)
    context = fusion.CreateDefaultContext()
    for name, x, P in zip(["kinect_v1", "kinect_v2"], states, covariances, strict=True):
        fusion.GetInputPort(f"{name}_estimated_state").FixValue(context, x)
        fusion.GetInputPort(f"{name}_covariance").FixValue(context, P.ravel())
        fusion.GetInputPort(f"{name}_health").FixValue(context, np.zeros(3))
    x_ref, P_ref = eq_10(states, covariances)
    np.testing.assert_allclose(
        fusion.GetOutputPort("estimated_state").Eval(context), x_ref, rtol=1e-9
    )
    np.testing.assert_allclose(
        fusion.GetOutputPort("covariance").Eval(context), P_ref.ravel(), rtol=1e-8
    )


def test_no_tracks_is_an_error():
    with pytest.raises(ValueError, match="at least one track"):
        make_track_fusion([], DETECTION)
    with pytest.raises(ValueError, match="one covariance per state"):
        fuse_tracks([np.zeros(2)], [])


def assert_same_arithmetic(original, hoisted, stands_for):
    """Walks two expressions in step: same nodes, same numbers, same order of operations.

    A variable of ``stands_for`` in ``hoisted`` matches the sub-expression it stands for, so a
    system that reads it from a system computing that sub-expression computes the same bits.
    """
    if hoisted.get_kind() == ExpressionKind.Var:
        (variable,) = list(hoisted.GetVariables())
        if variable.get_id() in stands_for:
            assert original.EqualTo(stands_for[variable.get_id()]), (original, hoisted)
            return
    assert original.get_kind() == hoisted.get_kind(), (original, hoisted)
    if original.get_kind() in (ExpressionKind.Constant, ExpressionKind.Var):
        assert original.EqualTo(hoisted), (original, hoisted)
        return
    (function, arguments), (hoisted_function, hoisted_arguments) = (
        original.Unapply(),
        hoisted.Unapply(),
    )
    assert function is hoisted_function and len(arguments) == len(hoisted_arguments)
    if _two_operands_exact_either_way(original, arguments) and _two_operands_exact_either_way(
        hoisted, hoisted_arguments
    ):
        # 0 + a + b and 1 * a * b give the same bits in either order.
        try:
            _same_operands(arguments[1:], hoisted_arguments[1:], stands_for)
        except AssertionError:
            _same_operands(arguments[1:], hoisted_arguments[:0:-1], stands_for)
    else:
        _same_operands(arguments, hoisted_arguments, stands_for)


def _same_operands(arguments, hoisted_arguments, stands_for):
    for a, b in zip(arguments, hoisted_arguments, strict=True):
        if isinstance(a, Expression):
            assert_same_arithmetic(a, b, stands_for)
        else:
            assert a == b, (arguments, hoisted_arguments)


def _two_operands_exact_either_way(expression, arguments) -> bool:
    """A sum of two terms starting from 0, or a product of two factors starting from 1."""
    kind = expression.get_kind()
    return len(arguments) == 3 and (
        (kind == ExpressionKind.Add and arguments[0] == 0.0)
        or (kind == ExpressionKind.Mul and arguments[0] == 1.0)
    )


@pytest.mark.parametrize("count", [1, 2, 3])
@pytest.mark.parametrize("inflated", [False, True])
def test_fusion_with_its_inverses_as_variables_computes_the_same_bits(count, inflated):
    """The fusion system reads each inverse from ``fusion.inverses``: no bit may change."""
    # numpy's floating-point flags mean nothing on expressions.
    with np.errstate(invalid="ignore"):
        states = [np.array(list(MakeVectorVariable(2, f"x{k}"))) for k in range(count)]
        covariances = [
            np.array(list(MakeVectorVariable(4, f"P{k}"))).reshape(2, 2) for k in range(count)
        ]
        if inflated:  # the fusion's flagged branch
            covariances = [
                P + Variable(f"flags{k}") * 1e6 * np.eye(2) for k, P in enumerate(covariances)
            ]
        variables = list(MakeVectorVariable(4 * (count - 1), "inverse")) if count > 1 else []
        hoisted = fusion_expressions(states, covariances, variables)
        state, covariance = fuse_tracks(states, covariances)
    stands_for = {v.get_id(): e for v, e in zip(variables, hoisted.inverses, strict=True)}
    for original, with_variables in [(state, hoisted.state), (covariance, hoisted.covariance)]:
        for a, b in zip(np.ravel(original), np.ravel(with_variables), strict=True):
            assert_same_arithmetic(_expression(a), _expression(b), stands_for)


def _expression(value) -> Expression:
    return value if isinstance(value, Expression) else Expression(value)
