"""A planted two-input system for multi-input identification tests (the inlet and the outlet).

A(q) y = B1(q) u1 + B2(q) u2 + C(q) e with known poles, a numerator per input (DC gains of
opposite sign, as an inlet fills and an outlet empties the bladder) and coloured noise.
"""

import numpy as np
import scipy.signal

POLES = [0.9, 0.7]
# The inlet raises the output, the outlet lowers it, with different dynamics (B1 has a zero).
NUMERATORS = ([0.5, 0.3], [-0.2, -0.1])
NOISE_ZEROS = [0.6, -0.4]
NOISE_STD = 0.1


def true_dc_gains() -> np.ndarray:
    """B_i(1) / A(1) for each input, from the planted polynomials."""
    a = np.real(np.poly(POLES))
    return np.array([np.sum(b) / np.sum(a) for b in NUMERATORS])


def simulate_two_inputs(samples: int, seed: int = 0, inputs: np.ndarray | None = None):
    """(u of shape (N, 2), y): the planted system driven by two independent white inputs.

    Args:
        samples: N.
        seed: the noise's (and the inputs') seed.
        inputs: (N, 2) inputs to drive it with instead of white noise.
    """
    rng = np.random.default_rng(seed)
    u = rng.standard_normal((samples, 2)) if inputs is None else inputs
    a = np.real(np.poly(POLES))
    c = np.real(np.poly(NOISE_ZEROS))
    y = scipy.signal.lfilter(c, a, NOISE_STD * rng.standard_normal(samples))
    for column, numerator in zip(u.T, NUMERATORS, strict=True):
        y += scipy.signal.lfilter([0.0, *numerator], a, column)
    return u, y
