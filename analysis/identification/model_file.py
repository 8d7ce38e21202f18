"""The model file `maskless identify` writes, and its loader for design and simulation.

YAML with the discrete innovations form (A, B, C, D, K), Ts, the offsets removed before fitting
and their units, the one-step innovations variance (what a Kalman design needs), the stability and
the verdict. The loader returns the ``LinearModel`` in SI that the designs and plants use.
"""

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import yaml

from maskless.errors import MissingFileError, ModelError
from maskless.systems.linear_model import LinearModel

if TYPE_CHECKING:
    # For annotations only: identification imports scipy.signal (~0.6 s), which `maskless
    # simulate` loads this module for but never uses.
    from maskless.analysis.identification.report import FittedModel

# Each unit the files may carry: its SI unit and the SI value of one of it.
_SI_UNITS = {"m": ("m", 1.0), "mm": ("m", 1e-3), "A": ("A", 1.0), "mA": ("A", 1e-3)}
# The units a model file may carry.
MODEL_FILE_UNITS = tuple(_SI_UNITS)


def model_file_contents(
    fitted: "FittedModel",
    *,
    input_unit: str,
    output_unit: str,
    input_offset: float,
    output_offset: float,
    detrend: str,
    trend_slopes_per_sample: tuple[float, float] | None,
    verdict: str,
) -> dict:
    """The YAML mapping of one fitted model, with the record's offsets and units.

    The model is of the detrended record's deviations, in the record's units; the variance is in
    output_unit².
    """
    model = fitted.model
    contents = {
        "method": fitted.method,
        "order": model.order,
        "sample_period_s": model.sample_period_s,
        **{name: getattr(model, name).tolist() for name in ("A", "B", "C", "D", "K")},
        "input": {"unit": input_unit, "offset": input_offset},
        "output": {"unit": output_unit, "offset": output_offset},
        "detrend": detrend,
        "innovations_variance": model.innovations_variance,
        "stable": model.is_stable(),
        "verdict": verdict,
    }
    if trend_slopes_per_sample is not None:
        contents["input"]["trend_slope_per_sample"] = trend_slopes_per_sample[0]
        contents["output"]["trend_slope_per_sample"] = trend_slopes_per_sample[1]
    return contents


def load_identified_model(path: str | Path) -> LinearModel:
    """Reads a model file into SI, as the ``LinearModel`` the designs and plants use.

    The state keeps the output's scale, so B and D scale by (output unit in SI) / (input unit in
    SI), K stays, the innovations variance scales by the output's square and the offsets become
    the operating point.

    Raises:
        ModelError: a missing field, a unit other than m, mm, A or mA, or matrices of the wrong
            shape, naming the file.
    """
    path = Path(path)
    contents = _model_file_contents(path)
    try:
        output_unit, output_scale = _si_unit(path, contents, "output")
        input_unit, input_scale = _si_unit(path, contents, "input")
        matrices = {name: np.array(contents[name], float) for name in ("A", "B", "C", "D", "K")}
        variance = contents.get("innovations_variance")
        return LinearModel(
            A=matrices["A"],
            B=matrices["B"] * output_scale / input_scale,
            C=matrices["C"],
            D=matrices["D"] * output_scale / input_scale,
            K=matrices["K"],
            sample_period_s=float(contents["sample_period_s"]),
            operating_output=float(contents["output"]["offset"]) * output_scale,
            operating_input=float(contents["input"]["offset"]) * input_scale,
            input_unit=input_unit,
            output_unit=output_unit,
            innovations_variance=None if variance is None else variance * output_scale**2,
        )
    except KeyError as missing:
        raise ModelError(f"{path}: missing field {missing}") from None
    except (TypeError, ValueError) as error:  # ModelError is a ValueError: it names the matrix
        raise ModelError(f"{path}: {error}") from None


def _model_file_contents(path: Path) -> dict:
    """The mapping a model file holds, refused with the file named when it is none."""
    try:
        contents = yaml.safe_load(path.read_text())
    except FileNotFoundError:
        raise MissingFileError(f"model file not found: {path}") from None
    except (OSError, UnicodeDecodeError, yaml.YAMLError) as error:
        raise ModelError(
            f"{path}: not a readable YAML model file ({type(error).__name__})"
        ) from None
    if not isinstance(contents, dict):
        raise ModelError(
            f"{path}: expected a mapping of A, B, C, D, K, sample_period_s, input, output"
        )
    return contents


def _si_unit(path: Path, contents: dict, signal: str) -> tuple[str, float]:
    """(SI unit, scale to it) of the file's ``signal`` ("input" or "output")."""
    unit = contents[signal]["unit"]
    if unit not in _SI_UNITS:
        raise ModelError(f"{path}: {signal}.unit = {unit!r}: expected one of {sorted(_SI_UNITS)}")
    return _SI_UNITS[unit]
