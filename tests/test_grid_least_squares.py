"""The batched non-negative fit against scipy.optimize.nnls, one problem at a time."""

import numpy as np
import pytest
import scipy.optimize

from maskless.analysis.identification.grid_least_squares import lowest_sums_of_squares


def _scipy_sse(y, held, own, weights):
    """The sum of squares scipy.optimize.nnls leaves, with a free offset (two opposed columns).

    Weighted by scaling each row, the offset's too, by the root of its weight.
    """
    ones = np.ones((y.size, 1))
    root = np.sqrt(weights)[:, None]
    _, norm = scipy.optimize.nnls(root * np.hstack([ones, held, own, -ones]), root[:, 0] * y)
    return norm**2


def _check_against_scipy(y, held, candidates, weights=None):
    found = lowest_sums_of_squares(y, held, candidates, weights)
    plain = np.ones(y.size) if weights is None else weights
    expected = np.array(
        [[_scipy_sse(y, held, sign * own, plain) for sign in (1.0, -1.0)] for own in candidates]
    )
    np.testing.assert_allclose(found, expected, rtol=1e-9, atol=1e-12 * (y @ y))


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("held_count, own_count", [(0, 1), (0, 2), (2, 2), (3, 2), (4, 1)])
def test_random_problems_match_nnls(seed, held_count, own_count):
    rng = np.random.default_rng(seed)
    levels = 12
    held = rng.standard_normal((levels, held_count))
    candidates = rng.standard_normal((40, levels, own_count))
    # Outputs that some weights of mixed signs explain, so many constraints bind.
    y = held @ rng.standard_normal(held_count) + candidates[0] @ rng.standard_normal(own_count)
    y += 0.3 * rng.standard_normal(levels)
    _check_against_scipy(y, held, candidates)
    # Levels averaged over holds of different lengths weigh as many samples as they average.
    _check_against_scipy(y, held, candidates, rng.uniform(0.05, 20.0, levels))


def test_flat_constant_and_dependent_columns_match_nnls():
    # The curves' own degenerate cases: a candidate flat at zero over every level (its start above
    # them all), one flat at its full value (its saturation below them all), one whose columns
    # repeat each other, one a held column spans, and held columns that repeat each other.
    rng = np.random.default_rng(4)
    x = np.sort(rng.uniform(0.0, 1.0, 15))
    held = np.column_stack([x, x**2])
    y = 0.5 * x + 2.0 * x**2 + 0.05 * rng.standard_normal(15)
    candidates = np.stack(
        [
            np.zeros((15, 2)),
            np.ones((15, 2)),
            np.column_stack([x**3, x**3]),
            np.column_stack([x, np.sqrt(x)]),
            np.column_stack([np.sqrt(x), x**3]),
        ]
    )
    _check_against_scipy(y, held, candidates)
    _check_against_scipy(y, np.column_stack([x, x]), candidates)


def test_an_exact_fit_has_no_residual():
    x = np.linspace(0.0, 1.0, 10)
    candidates = np.column_stack([x, x**2])[None]
    y = 3.0 - x - 2.0 * x**2
    sse = lowest_sums_of_squares(y, np.zeros((10, 0)), candidates)
    # Lowering the output: the negated columns fit it exactly (to rounding), the columns as given
    # cannot.
    assert sse[0, 1] == pytest.approx(0.0, abs=1e-14 * (y @ y))
    assert sse[0, 0] > 1.0


def test_shapes_and_weights_are_named():
    with pytest.raises(ValueError, match="held: expected shape"):
        lowest_sums_of_squares(np.zeros(5), np.zeros((4, 1)), np.zeros((3, 5, 2)))
    with pytest.raises(ValueError, match="candidates: expected shape"):
        lowest_sums_of_squares(np.zeros(5), np.zeros((5, 1)), np.zeros((3, 4, 2)))
    for weights in (np.ones(4), np.array([1.0, 2.0, 0.0, 1.0, 1.0])):
        with pytest.raises(ValueError, match="weights: expected 5 positive values"):
            lowest_sums_of_squares(np.zeros(5), np.zeros((5, 1)), np.zeros((3, 5, 2)), weights)
