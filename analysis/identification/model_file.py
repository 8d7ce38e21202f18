"""The model file `maskless identify` writes, and its loader for design and simulation.

YAML with the discrete innovations form (A, B, C, D, K), Ts, the offsets removed before fitting
and their units, the one-step innovations variance (what a Kalman design needs), the stability and
the verdict. The loader returns the SI ``IdentifiedModel`` the LQG design and plants use.
"""

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import yaml

from maskless.systems.paper_parameters import IdentifiedModel

if TYPE_CHECKING:
    # For annotations only: identification imports scipy.signal (~0.6 s), which `maskless
    # simulate` loads this module for but never uses.
    from maskless.analysis.identification.report import FittedModel

# SI value of one unit of each unit the files may carry.
_SI_PER_UNIT = {"m": 1.0, "mm": 1e-3, "A": 1.0, "mA": 1e-3}


def model_file_contents(
    fitted: "FittedModel",
    *,
    sample_period_s: float,
    input_unit: str,
    output_unit: str,
    input_offset: float,
    output_offset: float,
    detrend: str,
    trend_slopes_per_sample: tuple[float, float] | None,
    innovations_variance: float,
    verdict: str,
) -> dict:
    """The YAML mapping of one fitted model (offsets and variance in the record's units)."""
    contents = {
        "method": fitted.method,
        "order": fitted.model.order,
        "sample_period_s": sample_period_s,
        **{name: matrix.tolist() for name, matrix in fitted.model.state_space().items()},
        "input": {"unit": input_unit, "offset": input_offset},
        "output": {"unit": output_unit, "offset": output_offset},
        "detrend": detrend,
        "innovations_variance": innovations_variance,
        "stable": fitted.model.is_stable(),
        "verdict": verdict,
    }
    if trend_slopes_per_sample is not None:
        contents["input"]["trend_slope_per_sample"] = trend_slopes_per_sample[0]
        contents["output"]["trend_slope_per_sample"] = trend_slopes_per_sample[1]
    return contents


def load_identified_model(path: str | Path) -> IdentifiedModel:
    """Reads a model file into SI: B scales by (output unit in SI) / (input unit in SI), the
    offsets become the operating point.

    Raises:
        ValueError: a missing field or a unit other than m, mm, A or mA, naming the file.
    """
    path = Path(path)
    contents = yaml.safe_load(path.read_text())
    try:
        output_scale = _SI_PER_UNIT[contents["output"]["unit"]]
        input_scale = _SI_PER_UNIT[contents["input"]["unit"]]
        matrices = {name: np.array(contents[name], float) for name in ("A", "B", "C", "D", "K")}
        return IdentifiedModel(
            A=matrices["A"],
            B=matrices["B"] * output_scale / input_scale,
            C=matrices["C"],
            D=matrices["D"] * output_scale / input_scale,
            K=matrices["K"],
            sample_period_s=float(contents["sample_period_s"]),
            operating_output_m=float(contents["output"]["offset"]) * output_scale,
            operating_input_a=float(contents["input"]["offset"]) * input_scale,
        )
    except KeyError as missing:
        raise ValueError(
            f"{path}: missing field {missing} or a unit not in {sorted(_SI_PER_UNIT)}"
        ) from None
