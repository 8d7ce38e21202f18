"""Records for identification tests (simulated from known systems, the authors' own) and checks."""

from pathlib import Path

import numpy as np
import pytest
import scipy.signal

PAPER_DATA = Path(__file__).resolve().parents[2] / "shared" / "paper-data"

TRUE_SYSTEMS = {
    2: {"poles": [0.9, 0.7], "b": [0.5, 0.3], "noise_zeros": [0.6, -0.4]},
    4: {
        "poles": [0.95, 0.8, 0.5 + 0.3j, 0.5 - 0.3j],
        "b": [1.0, -0.6, 0.3, 0.1],
        "noise_zeros": [0.6, -0.4, 0.3, 0.2],
    },
}


def simulate_record(order: int, noise: str, samples: int, seed: int = 0):
    """A(q) y = B(q) u + C(q) e with white u; returns u, y, the true A coefficients and b.

    C = 1 for "white" noise (equation error), C with the listed zeros for "coloured". The A
    coefficients are [1, a1..an].
    """
    system = TRUE_SYSTEMS[order]
    rng = np.random.default_rng(seed)
    a = np.real(np.poly(system["poles"]))
    c = np.real(np.poly(system["noise_zeros"])) if noise == "coloured" else np.array([1.0])
    u = rng.standard_normal(samples)
    e = 0.1 * rng.standard_normal(samples)
    y = scipy.signal.lfilter([0.0, *system["b"]], a, u) + scipy.signal.lfilter(c, a, e)
    return u, y, a, np.array(system["b"])


def load_paper_record():
    """The authors' identification record with their preprocessing (whole-record mean removed).

    None when ../shared/paper-data is absent.
    """
    if not (PAPER_DATA / "inputUGWN3.csv").is_file():
        return None
    u = np.loadtxt(PAPER_DATA / "inputUGWN3.csv")
    y = np.loadtxt(PAPER_DATA / "outputUGWN3.csv")
    return u - u.mean(), y - y.mean()


def paper_record():
    """``load_paper_record`` for a test, which skips saying why when the record is absent."""
    record = load_paper_record()
    if record is None:
        pytest.skip(f"the authors' record is not at {PAPER_DATA} (shared/ is absent)")
    return record


def largest_pole_error(estimated, true_poles) -> float:
    """The largest distance from a true pole to the nearest estimated one."""
    return max(min(abs(p - q) for q in estimated) for p in true_poles)


def scipy_dc_gain(model) -> float:
    """The static gain by scipy's transfer function of the model's matrices, at z = 1."""
    num, den = scipy.signal.ss2tf(model.A, model.B, model.C, model.D)
    return np.polyval(num[0], 1.0) / np.polyval(den, 1.0)
