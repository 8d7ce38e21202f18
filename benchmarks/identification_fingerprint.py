"""A fingerprint of single-input identification results, one JSON line, to compare two trees.

Fits order 2 by PEM, ARMAX, ARX and N4SID to a simulated record (tests/identification_records.py,
order 2, coloured noise, 3,000 samples, seed 3) and, when ../shared/paper-data is present, to the
first 6,000 samples of the authors' record (their mean removed), estimating on the first 60 %.
The SHA-256 of every coefficient, x(0), fit, MSE and FPE, as raw float64 bytes, is printed per
record. Run it with another tree's package to compare that tree's results with this one's, e.g.
``cd OTHER_TREE && .venv/bin/python THIS_TREE/benchmarks/identification_fingerprint.py``.
"""

import argparse
import hashlib
import json
import sys
from pathlib import Path

import numpy as np

import maskless
from maskless.analysis.identification.report import Part, identify

sys.path.insert(0, str(Path(__file__).parents[1] / "tests"))
from identification_records import load_paper_record, simulate_record  # noqa: E402


def fingerprint(u: np.ndarray, y: np.ndarray) -> str:
    """SHA-256 of the four methods' single-input results on (u, y)."""
    digest = hashlib.sha256()
    split = y.size * 6 // 10
    for method in ("pem", "armax", "arx", "n4sid"):
        report, fitted = identify(
            method,
            Part("estimation", u[:split], y[:split]),
            Part("validation", u[split:], y[split:]),
            [2],
            1.0,
        )
        for name in ("a", "b", "k", "initial_state"):
            digest.update(np.ascontiguousarray(getattr(fitted[0].polynomials, name)).tobytes())
        for part in ("estimation", "validation"):
            for key in ("fit_percent_1step", "fit_percent_sim", "mse", "fpe"):
                digest.update(np.float64(report["models"][0][part][key]).tobytes())
    return digest.hexdigest()


def main():
    argparse.ArgumentParser(description=__doc__).parse_args()
    u, y, _, _ = simulate_record(2, "coloured", 3000, seed=3)
    figures = {"benchmark": "identification_fingerprint", "package": maskless.__file__}
    figures["simulated"] = fingerprint(u, y)
    paper = load_paper_record()
    figures["paper_record"] = "absent" if paper is None else fingerprint(*(s[:6000] for s in paper))
    print(json.dumps(figures))


if __name__ == "__main__":
    main()
