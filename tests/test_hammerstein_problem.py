"""The Hammerstein search's stable denominator: reflection coefficients and back.

The rest of the problem (its criterion, its start) is tested through ``estimate_hammerstein`` in
test_hammerstein.py, against a planted system.
"""

import numpy as np
import pytest

from maskless.analysis.identification.hammerstein_problem import (
    HammersteinProblem,
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


def test_samples_left_uncounted_do_not_move_the_arx_start():
    # A first-order linear record (pole 0.9) whose middle stretch a plant no model here describes
    # replaced by an unrelated swing: counted, it pulls the ARX pole; uncounted, the pole is 0.9.
    rng = np.random.default_rng(0)
    u = rng.uniform(0.0, 1.0, (3000, 1))
    y = np.zeros(3000)
    for k in range(1, 3000):
        y[k] = 0.9 * y[k - 1] + 0.5 * u[k - 1, 0]
    y += 1e-3 * rng.standard_normal(3000)
    y[1000:1600] += 3.0 * np.sin(np.arange(600) / 40.0)
    counted = np.ones(3000, dtype=bool)
    counted[1000:1600] = False
    kept = HammersteinProblem(u, y, 1, 1, 1, linear=True, counted=counted)
    assert kept.arx_poles()[0] == pytest.approx(0.9, abs=2e-3)
    assert abs(HammersteinProblem(u, y, 1, 1, 1, linear=True).arx_poles()[0] - 0.9) > 0.02
    # The criterion counts only those samples.
    assert kept.residuals(kept.initial_guesses()[0]).size == counted.sum()
