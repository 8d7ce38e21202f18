"""The Hammerstein search's stable denominator: reflection coefficients and back.

The rest of the problem (its criterion, its start) is tested through ``estimate_hammerstein`` in
test_hammerstein.py, against a planted system.
"""

import numpy as np
import pytest

from maskless.analysis.identification.hammerstein_problem import (
    polynomial_reflections,
    reflection_polynomial,
)


def test_reflection_coefficients_inside_one_give_a_stable_polynomial_and_back():
    rng = np.random.default_rng(0)
    for _ in range(20):
        reflections = rng.uniform(-0.999, 0.999, size=4)
        a = reflection_polynomial(reflections)
        assert np.all(np.abs(np.roots(np.concatenate([[1.0], a]))) < 1.0)
        np.testing.assert_allclose(polynomial_reflections(a), reflections, atol=1e-8)
    # A second-order polynomial's last reflection coefficient is its last coefficient.
    assert reflection_polynomial([0.3, 0.5])[-1] == pytest.approx(0.5)


def test_an_unstable_polynomial_is_mirrored_inside_before_its_reflections():
    # Roots 1.25 and 0.5: 1.25 mirrors to 0.8, so the reflections give (1 - 0.8 q^-1)(1 - 0.5 q^-1).
    a = np.poly([1.25, 0.5])[1:]
    stable = reflection_polynomial(polynomial_reflections(a))
    np.testing.assert_allclose(np.sort(np.roots(np.concatenate([[1.0], stable]))), [0.5, 0.8])
