"""LinearModel: DC gain, poles, steady targets and frequency response against scipy.signal."""

import math

import numpy as np
import pytest
import scipy.signal

from maskless.errors import ModelError
from maskless.systems.linear_model import LinearModel, stable

TS = 0.048


def random_model(seed, n, feedthrough=0.0):
    """A stable SISO model with n states and well-spread poles."""
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(n, n))
    A *= 0.9 / np.max(np.abs(np.linalg.eigvals(A)))
    return LinearModel(A, rng.normal(size=(n, 1)), rng.normal(size=(1, n)), [[feedthrough]], TS)


def first_order(a, b, c=1.0, d=0.0):
    """x+ = a x + b u, y = c x + d u."""
    return LinearModel([[a]], [[b]], [[c]], [[d]], TS)


def scipy_dc_gain(model):
    """G(1) from scipy's transfer function of the model's matrices."""
    num, den = scipy.signal.ss2tf(model.A, model.B, model.C, model.D)
    return np.polyval(num[0], 1.0) / np.polyval(den, 1.0)


@pytest.mark.parametrize(
    "seed, n, feedthrough", [(1, 1, 0.0), (2, 2, 0.0), (3, 4, 0.3), (4, 6, -1.2)]
)
def test_dc_gain_is_scipys_transfer_function_at_z_equal_one(seed, n, feedthrough):
    model = random_model(seed, n, feedthrough)
    assert model.dc_gain() == pytest.approx(scipy_dc_gain(model), rel=1e-9)
    assert model.dc_gain() == pytest.approx(model.transfer_function(1.0).real, rel=1e-12)


@pytest.mark.parametrize(
    "a, b, c, d", [(0.9, 0.5, 1.0, 0.0), (-0.3, 2.0, -0.5, 0.1), (0.0, 1.0, 1.0, 0.0)]
)
def test_dc_gain_of_a_first_order_model_is_c_b_over_one_minus_a_plus_d(a, b, c, d):
    assert first_order(a, b, c, d).dc_gain() == pytest.approx(c * b / (1 - a) + d, rel=1e-12)


def test_dc_gain_of_a_static_gain_is_the_gain():
    gain = LinearModel.static_gain(-2.5, TS)
    assert gain.order == 0 and gain.poles().size == 0
    assert gain.dc_gain() == -2.5
    assert gain.steady_target() == (pytest.approx(np.zeros(0)), pytest.approx(-0.4))


@pytest.mark.parametrize("seed, n", [(5, 1), (6, 3), (7, 5)])
def test_poles_are_the_eigenvalues_of_a(seed, n):
    model = random_model(seed, n)
    np.testing.assert_allclose(
        np.sort_complex(model.poles()), np.sort_complex(np.linalg.eigvals(model.A)), atol=1e-12
    )
    assert model.poles().dtype == complex
    assert model.is_stable()
    # random_model puts the largest pole at 0.9: scaled up, it leaves the unit circle.
    assert not LinearModel(1.2 * model.A, model.B, model.C, model.D, TS).is_stable()


@pytest.mark.parametrize("a, b, c, d", [(0.9, 0.5, 1.0, 0.0), (0.2, -2.0, 3.0, 0.4)])
def test_steady_target_of_a_first_order_model(a, b, c, d):
    # (1 - a) x = b u and c x + d u = 1: u = 1 / g, x = b u / (1 - a), g = c b / (1 - a) + d.
    x_ss, u_ss = first_order(a, b, c, d).steady_target()
    gain = c * b / (1 - a) + d
    assert u_ss == pytest.approx(1 / gain, rel=1e-12)
    assert x_ss[0] == pytest.approx(b / ((1 - a) * gain), rel=1e-12)


@pytest.mark.parametrize("seed, n, feedthrough", [(8, 3, 0.0), (9, 5, 0.7)])
def test_steady_target_is_an_equilibrium_at_unit_output(seed, n, feedthrough):
    model = random_model(seed, n, feedthrough)
    x_ss, u_ss = model.steady_target()
    np.testing.assert_allclose(model.A @ x_ss + model.B[:, 0] * u_ss, x_ss, atol=1e-12)
    assert (model.C @ x_ss)[0] + model.D[0, 0] * u_ss == pytest.approx(1.0, rel=1e-12)
    assert u_ss == pytest.approx(1.0 / model.dc_gain(), rel=1e-9)


def test_steady_target_with_the_input_held():
    # The states are the output at consecutive samples and A has an eigenvalue at 1: with the
    # input held the equilibrium at unit output is [1, 1] exactly.
    model = LinearModel([[0.0, 1.0], [-0.5, 1.5]], [[0.0], [1.0]], [[1.0, 0.0]], [[0.0]], TS)
    x_ss, u_ss = model.steady_target(hold_input=True)
    np.testing.assert_allclose(x_ss, [1.0, 1.0], atol=1e-12)
    assert u_ss == 0.0
    # Without an eigenvalue at 1 no such equilibrium exists: the least-squares state.
    lagging = first_order(0.5, 1.0)
    x_ss, _ = lagging.steady_target(hold_input=True)
    assert x_ss[0] == pytest.approx(1.0 / 1.25)  # min (0.5 x)² + (x - 1)²


@pytest.mark.parametrize(
    "A, pole",
    [
        ([[1.0]], "1"),
        ([[1.0 - 1e-9]], "0.999999999"),
        ([[0.0, 1.0], [-1.0, 2.0]], "1"),  # a double pole at 1
        ([[0.5, 0.0], [0.0, 1.0 + 1e-8]], "1.00000001"),
    ],
)
def test_an_integrating_model_has_no_dc_gain_or_steady_target_and_its_pole_is_named(A, pole):
    n = len(A)
    model = LinearModel(A, np.ones((n, 1)), np.ones((1, n)), [[0.0]], TS)
    message = rf"pole at z = {pole}\b.*\(an integrator"
    with pytest.raises(ModelError, match=message):
        model.dc_gain()
    with pytest.raises(ModelError, match=message):
        model.steady_target()


def test_an_input_that_holds_no_output_has_no_steady_target():
    model = first_order(0.9, 0.0)
    assert model.dc_gain() == 0.0
    with pytest.raises(ModelError, match="no steady state"):
        model.steady_target()


@pytest.mark.parametrize(
    "fields, match",
    [
        (dict(A=np.eye(2)[0]), r"A must be a square 2-D array"),
        (dict(A=np.zeros((2, 3))), r"A must be a square 2-D array"),
        (dict(B=np.zeros((2, 2))), r"B must have shape \(2, 1\)"),
        (dict(C=np.zeros((2, 2))), r"C must have shape \(1, 2\)"),
        (dict(D=np.zeros(1)), r"D must have shape \(1, 1\)"),
        (dict(K=np.zeros((1, 2))), r"K must have shape \(2, 1\)"),
        (dict(B=[[np.nan], [0.0]]), r"B must be finite"),
        (dict(sample_period_s=0.0), r"sample_period_s must be positive"),
        (dict(sample_period_s=math.inf), r"sample_period_s must be positive"),
        (dict(sample_period_s="0.048"), r"sample_period_s must be a number"),
        (dict(operating_input=math.nan), r"operating_input must be finite"),
        (dict(operating_output="0.7"), r"operating_output must be a number"),
        (dict(innovations_variance=-1e-6), r"innovations_variance must be >= 0"),
        (dict(output_unit=None), r"output_unit must be a string"),
    ],
)
def test_bad_models_are_refused_naming_the_field(fields, match):
    arguments = dict(
        A=np.eye(2), B=np.ones((2, 1)), C=np.ones((1, 2)), D=[[0.0]], sample_period_s=TS
    )
    arguments.update(fields)
    with pytest.raises(ModelError, match=match):
        LinearModel(**arguments)


def test_the_arrays_are_read_only_copies():
    A = np.array([[0.5]])
    model = LinearModel(A, [[1.0]], [[1.0]], [[0.0]], TS, K=[[0.2]])
    A[0, 0] = 0.9
    assert model.A[0, 0] == 0.5
    for matrix in (model.A, model.B, model.C, model.D, model.K):
        with pytest.raises(ValueError, match="read-only"):
            matrix[0, 0] = 1.0


@pytest.mark.parametrize("n, feedthrough", [(1, 0.0), (4, 0.0), (6, 0.7)])
def test_frequency_response_matches_scipy_freqz(n, feedthrough):
    model = random_model(n, n, feedthrough)
    omega = np.geomspace(1e-3, math.pi / TS, 50)
    num, den = scipy.signal.ss2tf(model.A, model.B, model.C, model.D)
    _, reference = scipy.signal.freqz(num[0], den, worN=omega * TS)
    np.testing.assert_allclose(model.frequency_response(omega), reference, rtol=1e-9)
    assert model.frequency_response(omega.reshape(5, 10)).shape == (5, 10)
    assert model.frequency_response(2.0).shape == ()


def test_frequency_response_matches_scipy_dfreqresp():
    model = random_model(3, 3, feedthrough=0.4)  # D != 0, so scipy's numerator is well formed
    omega = np.linspace(0.5, 60.0, 40)
    _, reference = scipy.signal.dfreqresp(
        scipy.signal.dlti(model.A, model.B, model.C, model.D, dt=TS), w=omega * TS
    )
    np.testing.assert_allclose(model.frequency_response(omega), reference, rtol=1e-9)
    with pytest.raises(ModelError, match="omega_rad_s must be finite"):
        model.frequency_response([1.0, math.nan])


def test_output_subtracted_from_turns_a_distance_into_a_height():
    distance = LinearModel(
        [[0.5, 0.1], [0.0, 0.8]],
        [[1.0], [0.5]],
        [[1.0, 0.0]],
        [[0.0]],
        TS,
        operating_input=0.08,
        operating_output=0.69,
        input_unit="A",
        output_unit="m",
        K=[[0.3], [0.2]],
        innovations_variance=4e-8,
    )
    height = distance.output_subtracted_from(0.9)
    assert height.operating_output == pytest.approx(0.9 - 0.69)
    assert height.dc_gain() == pytest.approx(-distance.dc_gain())
    np.testing.assert_array_equal(height.C, -distance.C)
    np.testing.assert_array_equal(height.K, -distance.K)
    np.testing.assert_array_equal(height.A, distance.A)
    np.testing.assert_array_equal(height.B, distance.B)
    assert (height.operating_input, height.input_unit, height.output_unit) == (0.08, "A", "m")
    assert height.innovations_variance == distance.innovations_variance


def test_stable_uses_the_strict_radius():
    assert stable([0.5, -0.9j])
    assert not stable([0.5, 1.0])
    assert not stable([0.95], tol=0.1)
    assert stable(np.array([], dtype=complex))
    with pytest.raises(ModelError, match=r"poles must be a 1-D array \(n,\)"):
        stable(np.zeros((2, 2)))
    with pytest.raises(ModelError, match=r"tol must lie in \[0, 1\)"):
        stable([0.5], tol=1.0)
