"""Unit conversions (mm and m, mA and A, mm² and m²) and their inverses."""

import numpy as np
import pytest

from maskless.systems.units import a_to_ma, m_to_mm, ma_to_a, mm2_to_m2, mm_to_m, whole_ticks


def test_mm_to_m():
    assert mm_to_m(692.357479) == pytest.approx(0.692357479, rel=1e-15)
    np.testing.assert_allclose(mm_to_m(np.array([1.0, -5.0])), [0.001, -0.005])


def test_m_to_mm_inverts_mm_to_m():
    assert m_to_mm(mm_to_m(12.5)) == pytest.approx(12.5, rel=1e-15)
    assert m_to_mm(0.00075) == pytest.approx(0.75)  # the paper's fused std bound


def test_mm2_to_m2_is_a_variance_conversion():
    # sigma_r1^2 = 70 mm^2 is (8.3666 mm)^2 = (0.0083666 m)^2
    assert mm2_to_m2(70.0) == pytest.approx(mm_to_m(np.sqrt(70.0)) ** 2, rel=1e-14)
    assert mm2_to_m2(2000.0) == pytest.approx(2.0e-3)


def test_ma_to_a():
    assert ma_to_a(165.0) == pytest.approx(0.165)
    assert ma_to_a(81.32508) == pytest.approx(0.08132508)


def test_a_to_ma_inverts_ma_to_a():
    assert a_to_ma(ma_to_a(60.0)) == pytest.approx(60.0, rel=1e-15)


@pytest.mark.parametrize(
    "duration_s, period_s, ticks",
    # A whole number of ticks stays whole despite float error (1.0 / (1 / 15) is not exactly 15);
    # anything past it is the next tick.
    [(0.5, 1 / 15, 8), (1.0, 1 / 15, 15), (0.3, 0.1, 3), (0.3000001, 0.1, 4), (0.0, 0.1, 0)],
)
def test_whole_ticks_rounds_a_duration_up_to_whole_ticks(duration_s, period_s, ticks):
    assert whole_ticks(duration_s, period_s) == ticks
