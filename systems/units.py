"""Unit conversions: the paper's printed units (mm, mm², mA) to SI (m, m², A), durations to ticks.

Every number that enters the toolkit in a printed unit passes through one of these functions, so
the conversions are written (and tested) once.
"""

import math

MM_PER_M = 1000.0
MA_PER_A = 1000.0


def mm_to_m(value_mm):
    """Millimetres to metres (works on floats and numpy arrays)."""
    return value_mm / MM_PER_M


def m_to_mm(value_m):
    """Metres to millimetres, for reports and plots (clinicians read mm)."""
    return value_m * MM_PER_M


def mm2_to_m2(value_mm2):
    """Square millimetres (a variance in mm²) to square metres."""
    return value_mm2 / MM_PER_M**2


def ma_to_a(value_ma):
    """Milliamperes to amperes."""
    return value_ma / MA_PER_A


def a_to_ma(value_a):
    """Amperes to milliamperes, for reports and plots."""
    return value_a * MA_PER_A


def whole_ticks(duration_s: float, period_s: float) -> int:
    """A duration as whole ticks of ``period_s``, rounded up.

    A limit between two ticks is reached at the later one (0.5 s at 15 Hz: 8 ticks); the 1e-9
    keeps a duration of a whole number of ticks from rounding past it on float error.
    """
    return math.ceil(duration_s / period_s - 1e-9)
