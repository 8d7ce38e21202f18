"""The model file `maskless identify` writes, and its loader for design and simulation.

YAML with the discrete innovations form (A, B, C, D, K), Ts, the offsets removed before fitting
and their units, the one-step innovations variance (what a Kalman design needs), the stability and
the verdict. The loader returns the ``LinearModel`` in SI that the designs and plants use.

A Hammerstein model (``method: hammerstein``) is held as its linear part's polynomials (a, and b
per valve), its input delay, each valve's static map (``valves``: knot currents and openings, in
the input's unit) and the output with every valve shut (``output.offset``); it loads as one
``HammersteinModel`` in SI.

A model of m inputs (the inlet and the outlet valve) holds B (n x m), D (1 x m) and, instead of
``input``, ``inputs``: one mapping per column of B with the input's name, unit and offset. The
designs and plants drive one input, so ``load_identified_model`` refuses such a file in one line
naming it; ``load_input_models`` reads it as one single-input ``LinearModel`` per input (the others
held at their operating points), each checked as a single-input file is.
"""

import math
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from maskless.errors import MissingFileError, ModelError
from maskless.systems.config_loading import read_yaml
from maskless.systems.hammerstein_model import HammersteinModel
from maskless.systems.limits import SAMPLE_PERIOD_S
from maskless.systems.linear_model import LinearModel
from maskless.systems.plant.valve_map import ValveMap

if TYPE_CHECKING:
    # For annotations only: identification imports scipy.optimize (~0.35 s), which `maskless
    # simulate` loads this module for but never uses.
    from maskless.analysis.identification.report import FittedModel

# Each unit the files may carry: its SI unit and the SI value of one of it.
_SI_UNITS = {"m": ("m", 1.0), "mm": ("m", 1e-3), "A": ("A", 1.0), "mA": ("A", 1e-3)}
# The units a model file may carry.
MODEL_FILE_UNITS = tuple(_SI_UNITS)
# What a Hammerstein file's method field says, and the valves its maps belong to, in input order.
HAMMERSTEIN_METHOD = "hammerstein"
VALVE_NAMES = ("inlet", "outlet")


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
    if fitted.model is None:
        return _multi_input_contents(
            fitted,
            input_units=input_unit,
            output_unit=output_unit,
            input_offsets=input_offset,
            output_offset=output_offset,
            detrend=detrend,
            trend_slopes_per_sample=trend_slopes_per_sample,
            verdict=verdict,
        )
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


def hammerstein_file_contents(model: HammersteinModel, *, verdict: str) -> dict:
    """The YAML mapping of a Hammerstein model, in its own units (``model.input_unit``, ...)."""
    if model.inputs > len(VALVE_NAMES):
        raise ModelError(
            f"a model file holds at most {len(VALVE_NAMES)} valves, got {model.inputs}"
        )
    return {
        "method": HAMMERSTEIN_METHOD,
        "order": model.order,
        "input_delay_samples": model.input_delay_samples,
        "sample_period_s": model.sample_period_s,
        "a": model.a.tolist(),
        "b": model.b.tolist(),
        "valves": {
            name: {"currents": valve.currents.tolist(), "openings": valve.openings.tolist()}
            for name, valve in zip(VALVE_NAMES, model.maps, strict=False)
        },
        "input": {"unit": model.input_unit},
        "output": {"unit": model.output_unit, "offset": model.operating_output},
        "stable": model.is_stable(),
        "verdict": verdict,
    }


def load_identified_model(path: str | Path) -> LinearModel | HammersteinModel:
    """Reads a model file into SI: the ``LinearModel`` or ``HammersteinModel`` it holds.

    The state keeps the output's scale, so B and D scale by (output unit in SI) / (input unit in
    SI), K stays, the innovations variance scales by the output's square and the offsets become
    the operating point.

    Raises:
        MissingFileError: there is no such file.
        ModelError: naming the file and the field: a file that is not UTF-8 YAML (or holds an
            alias, a repeated key, deep nesting), not a mapping, a missing field, a unit other
            than m, mm, A or mA, a matrix of the wrong shape or not finite, a sample period out
            of ``SAMPLE_PERIOD_S``, or ``stable: true`` on a model whose poles say otherwise.
    """
    path = Path(path)
    try:
        contents = read_yaml(path, ModelError)
    except MissingFileError:
        raise MissingFileError(f"model file not found: {path}") from None
    return model_from_contents(contents, str(path))


def model_from_contents(contents, source: str) -> LinearModel | HammersteinModel:
    """The model (in SI) of a model file's mapping, checked field by field.

    ``source`` names the file in every message. ``maskless identify`` checks what it is about to
    write with this too, so it never writes a file this loader would refuse.
    """
    if isinstance(contents, dict) and "inputs" in contents:
        models = input_models_from_contents(contents, source)
        raise ModelError(
            f"{source}: a model of {len(models)} inputs ({', '.join(_input_names(contents))}): "
            "the designs and plants drive one input, so they cannot use it yet; identify with one "
            "--input-column for a design model"
        )
    if not isinstance(contents, dict):
        raise ModelError(
            f"{source}: expected a mapping of A, B, C, D, K, sample_period_s, input, output; "
            f"got {type(contents).__name__}"
        )
    if contents.get("method") == HAMMERSTEIN_METHOD:
        return _hammerstein_from_contents(contents, source)
    output_unit, output_scale = _si_unit(source, contents, "output")
    input_unit, input_scale = _si_unit(source, contents, "input")
    matrices = {name: _matrix(source, contents, name) for name in ("A", "B", "C", "D", "K")}
    period = _field(source, contents, "sample_period_s")
    SAMPLE_PERIOD_S.check(period, f"{source}: sample_period_s", ModelError)
    variance = contents.get("innovations_variance")
    if variance is not None:
        variance = _number(source, contents, "innovations_variance") * output_scale**2
    offsets = {
        signal: _number(source, _field(source, contents, signal), "offset", signal)
        for signal in ("input", "output")
    }
    try:
        model = LinearModel(
            A=matrices["A"],
            B=matrices["B"] * output_scale / input_scale,
            C=matrices["C"],
            D=matrices["D"] * output_scale / input_scale,
            K=matrices["K"],
            sample_period_s=period,
            operating_output=offsets["output"] * output_scale,
            operating_input=offsets["input"] * input_scale,
            input_unit=input_unit,
            output_unit=output_unit,
            innovations_variance=variance,
        )
    except ModelError as error:  # it names the matrix or the field
        raise ModelError(f"{source}: {error}") from None
    _check_claimed_stability(source, contents, model)
    return model


def _hammerstein_from_contents(contents: dict, source: str) -> HammersteinModel:
    """A ``method: hammerstein`` file's model in SI, checked field by field."""
    output_unit, output_scale = _si_unit(source, contents, "output")
    input_unit, input_scale = _si_unit(source, contents, "input")
    if input_unit != "A" or output_unit != "m":
        raise ModelError(
            f"{source}: fields 'input.unit', 'output.unit': expected a current (A or mA) in and "
            "a height (m or mm) out"
        )
    a = _matrix(source, contents, "a")
    b = _matrix(source, contents, "b")
    valves = _field(source, contents, "valves")
    if not isinstance(valves, dict) or list(valves) != list(VALVE_NAMES[: len(valves)]):
        raise ModelError(
            f"{source}: field 'valves': expected a mapping of {' and '.join(VALVE_NAMES)} (in "
            "that order) to their maps"
        )
    maps = []
    for name, valve in valves.items():
        where = f"valves.{name}"
        if not isinstance(valve, dict):
            raise ModelError(f"{source}: field '{where}' = {valve!r}: expected a mapping")
        currents = _vector(source, valve, "currents", f"{where}.")
        openings = _vector(source, valve, "openings", f"{where}.")
        try:
            maps.append(ValveMap(currents * input_scale, openings))
        except ModelError as error:
            raise ModelError(f"{source}: field '{where}': {error}") from None
    period = _field(source, contents, "sample_period_s")
    SAMPLE_PERIOD_S.check(period, f"{source}: sample_period_s", ModelError)
    delay = _field(source, contents, "input_delay_samples")
    offset = _number(source, _field(source, contents, "output"), "offset", "output")
    try:
        model = HammersteinModel(
            maps=tuple(maps),
            a=a,
            b=b * output_scale,
            input_delay_samples=delay,
            operating_output=offset * output_scale,
            sample_period_s=period,
            input_unit=input_unit,
            output_unit=output_unit,
        )
    except ModelError as error:  # it names the field
        raise ModelError(f"{source}: {error}") from None
    _check_claimed_stability(source, contents, model)
    return model


def _vector(source: str, contents: dict, name: str, within: str = "") -> np.ndarray:
    """A field holding a non-empty list of finite numbers."""
    value = _field(source, contents, name, within)
    numbers = isinstance(value, list) and all(
        isinstance(x, int | float) and not isinstance(x, bool) for x in value
    )
    if not numbers or not value or not np.all(np.isfinite(np.array(value, float))):
        raise ModelError(f"{source}: field '{within}{name}': expected a list of finite numbers")
    return np.array(value, float)


def _field(source: str, contents: dict, name: str, within: str = ""):
    """``contents[name]``, or a ModelError naming the missing field."""
    if name not in contents:
        raise ModelError(f"{source}: missing field '{within}{name}'")
    return contents[name]


def _number(source: str, contents, name: str, within: str = "") -> float:
    """A finite number field of ``contents`` (the mapping ``within``, when nested)."""
    dotted = f"{within}.{name}" if within else name
    if not isinstance(contents, dict):
        raise ModelError(f"{source}: field '{within}' = {contents!r}: expected a mapping")
    value = _field(source, contents, name, f"{within}." if within else "")
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise ModelError(f"{source}: field '{dotted}' = {value!r}: expected a finite number")
    return float(value)


def _matrix(source: str, contents: dict, name: str) -> np.ndarray:
    """A field holding a rectangular matrix of finite numbers (its shape is checked later)."""
    value = _field(source, contents, name)
    rows = value if isinstance(value, list) else None
    if not rows or not all(isinstance(row, list) for row in rows):
        raise ModelError(f"{source}: field '{name}': expected a matrix, a list of rows")
    if len({len(row) for row in rows}) != 1:
        raise ModelError(f"{source}: field '{name}': rows of different lengths")
    numbers = all(
        isinstance(x, int | float) and not isinstance(x, bool) for row in rows for x in row
    )
    matrix = np.array(rows, float) if numbers else None
    if matrix is None or not np.all(np.isfinite(matrix)):
        raise ModelError(f"{source}: field '{name}': expected finite numbers only")
    return matrix


def _si_unit(source: str, contents: dict, signal: str) -> tuple[str, float]:
    """(SI unit, scale to it) of the file's ``signal`` ("input" or "output")."""
    section = _field(source, contents, signal)
    if not isinstance(section, dict):
        raise ModelError(f"{source}: field '{signal}' = {section!r}: expected a mapping")
    unit = _field(source, section, "unit", f"{signal}.")
    if unit not in _SI_UNITS:
        raise ModelError(
            f"{source}: field '{signal}.unit' = {unit!r}: expected one of {sorted(_SI_UNITS)}"
        )
    return _SI_UNITS[unit]


def _check_claimed_stability(
    source: str, contents: dict, model: LinearModel | HammersteinModel
) -> None:
    """Refuses a ``stable`` field that is no boolean, or that the poles contradict."""
    claimed = contents.get("stable")
    if claimed is None:
        return
    if not isinstance(claimed, bool):
        raise ModelError(f"{source}: field 'stable' = {claimed!r}: expected true or false")
    if claimed != model.is_stable():
        poles = model.poles()
        largest = float(np.abs(poles).max()) if poles.size else 0.0
        raise ModelError(
            f"{source}: field 'stable' = {str(claimed).lower()}, but A's largest pole magnitude "
            f"is {largest:.6g}"
        )


def _multi_input_contents(
    fitted: "FittedModel",
    *,
    input_units: tuple[str, ...],
    output_unit: str,
    input_offsets: tuple[float, ...],
    output_offset: float,
    detrend: str,
    trend_slopes_per_sample: tuple[tuple[float, ...], float] | None,
    verdict: str,
) -> dict:
    """``model_file_contents`` of an m-input model: B and D of m columns, ``inputs`` per column.

    ``fitted.details["input_names"]`` names the inputs (default "input 1", ...).
    """
    singles = fitted.input_models
    names = fitted.details.get("input_names") or [f"input {i + 1}" for i in range(len(singles))]
    inputs = [
        {"name": name, "unit": unit, "offset": offset}
        for name, unit, offset in zip(names, input_units, input_offsets, strict=True)
    ]
    contents = {
        "method": fitted.method,
        "order": singles[0].order,
        "sample_period_s": singles[0].sample_period_s,
        "A": singles[0].A.tolist(),
        "B": np.column_stack([single.B for single in singles]).tolist(),
        "C": singles[0].C.tolist(),
        "D": np.zeros((1, len(singles))).tolist(),
        "K": singles[0].K.tolist(),
        "inputs": inputs,
        "output": {"unit": output_unit, "offset": output_offset},
        "detrend": detrend,
        "innovations_variance": singles[0].innovations_variance,
        "stable": singles[0].is_stable(),
        "verdict": verdict,
    }
    if trend_slopes_per_sample is not None:
        for entry, slope in zip(inputs, trend_slopes_per_sample[0], strict=True):
            entry["trend_slope_per_sample"] = slope
        contents["output"]["trend_slope_per_sample"] = trend_slopes_per_sample[1]
    return contents


def load_input_models(path: str | Path) -> tuple[LinearModel, ...]:
    """Reads a model file as one single-input ``LinearModel`` (SI) per input.

    A single-input file gives one; an m-input file (``inputs``) gives m, input i's from B's
    column i with that input's unit and offset, the others held at their operating points.

    Raises:
        MissingFileError: there is no such file.
        ModelError: as ``load_identified_model``, and for an ``inputs`` list that does not match
            B's columns.
    """
    path = Path(path)
    try:
        contents = read_yaml(path, ModelError)
    except MissingFileError:
        raise MissingFileError(f"model file not found: {path}") from None
    if isinstance(contents, dict) and "inputs" in contents:
        return input_models_from_contents(contents, str(path))
    return (model_from_contents(contents, str(path)),)


def input_models_from_contents(contents: dict, source: str) -> tuple[LinearModel, ...]:
    """An m-input model file's mapping as one checked single-input ``LinearModel`` per input.

    Each is checked as a single-input file (units, shapes, numbers, sample period, stability),
    after B (n x m) and D (1 x m) are checked to have one column per entry of ``inputs``.
    """
    inputs = contents["inputs"]
    if (
        not isinstance(inputs, list)
        or len(inputs) < 2
        or not all(isinstance(entry, dict) for entry in inputs)
    ):
        raise ModelError(
            f"{source}: field 'inputs' = {inputs!r}: expected a list of two or more mappings "
            "(name, unit, offset), one per column of B"
        )
    if "input" in contents:
        raise ModelError(f"{source}: fields 'input' and 'inputs' both given: expected one")
    columns = {name: _matrix(source, contents, name) for name in ("B", "D")}
    for name, rows in (("B", None), ("D", 1)):
        shape = columns[name].shape
        if shape[1] != len(inputs) or (rows is not None and shape[0] != rows):
            raise ModelError(
                f"{source}: field '{name}' has shape {shape}: expected one column per entry of "
                f"'inputs' ({len(inputs)})" + (", one row" if rows else "")
            )
    models = []
    for index, entry in enumerate(inputs):
        single = {key: value for key, value in contents.items() if key != "inputs"}
        single["input"] = entry
        single["B"] = columns["B"][:, [index]].tolist()
        single["D"] = columns["D"][:, [index]].tolist()
        models.append(model_from_contents(single, f"{source} (inputs[{index}])"))
    return tuple(models)


def _input_names(contents: dict) -> list[str]:
    """The names in a checked ``inputs`` list ("input i" where one has none)."""
    return [
        str(entry.get("name", f"input {index + 1}"))
        for index, entry in enumerate(contents["inputs"])
    ]
