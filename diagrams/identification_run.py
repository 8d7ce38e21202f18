"""Identifying models from a recorded experiment, as `maskless identify` does.

Holds the request, the record read from CSV or a maskless MCAP recording, the fits and their
report, and the files.

The figures and the verdict come from ``analysis.identification.report``; this module reads the
record, chooses its parts and writes the results.
"""

import dataclasses
import json
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from maskless.analysis.identification import report as identification_report
from maskless.analysis.identification.data_diagnostics import (
    diagnose_record,
    refuse_constant,
    refuse_unfit_part,
    widest_spread,
)
from maskless.analysis.identification.diagnostics_text import (
    format_diagnostics,
    format_input_diagnostics,
)
from maskless.analysis.identification.fit_plots import plot_compare, plot_record, plot_residuals
from maskless.analysis.identification.model_file import (
    MODEL_FILE_UNITS,
    input_models_from_contents,
    model_file_contents,
    model_from_contents,
)
from maskless.analysis.identification.records import (
    Detrended,
    detrend,
    identified_before_the_cut,
    named_fields,
    noting_cuts,
    parse_range,
    parts_overlap,
    read_aligned_mcap,
    read_csv_signal,
    refuse_other_period,
)
from maskless.analysis.identification.report import FittedModel, Part
from maskless.analysis.identification.subspace import minimum_samples as subspace_minimum
from maskless.diagrams.background import Worker
from maskless.diagrams.identification_request import (
    DEFAULT_MCAP_INPUT,
    DEFAULT_MCAP_OUTPUT,
    IdentificationRequest,
)
from maskless.diagrams.output_folder import output_folder
from maskless.diagrams.plot_worker import start_plot_worker
from maskless.errors import ConfigError, ModelError, RecordError
from maskless.systems.linear_model import LinearModel

# Records at least this long report the optimiser's progress on stderr.
_PROGRESS_MIN_SAMPLES = 50_000
# A maskless recording's field names end in their SI unit (longest suffix first: "_m_s" is m/s).
_FIELD_UNITS = {"_m_s": "m/s", "_pa": "Pa", "_a": "A", "_m": "m"}
# A CSV carries no units: the robot's CSV convention (valve current in mA, head distance in mm,
# as the authors' record) is assumed unless --input-unit/--output-unit say otherwise.
CSV_UNITS = ("mA", "mm")
# Where each unit came from, as the report says it.
UNIT_GIVEN, UNIT_FROM_FIELD, UNIT_CSV_DEFAULT, UNIT_NOT_GIVEN = (
    "given",
    "from the recording's field name",
    "assumed: a CSV carries no units; the robot's CSV convention",
    "not given",
)


@dataclass
class IdentificationRun:
    """The outcome of ``identify_record``.

    Attributes:
        request: what was asked.
        report: the figures, baselines and verdict (the JSON `maskless identify` writes).
        fitted_models: one per order, in the request's order.
        parts: the detrended estimation and validation parts.
        offsets: what detrending removed (and the detrended record).
        units: (input unit, output unit), as given or read; with m inputs the first is a tuple,
            one unit per input.
        signals: (input, output) of the whole record as read, before detrending.
        input_names: the inputs' names (one per column of an m-input record; one for one input).
    """

    request: IdentificationRequest
    report: dict
    fitted_models: list[FittedModel]
    parts: list[Part]
    offsets: Detrended
    units: tuple[str, str]
    signals: tuple[np.ndarray, np.ndarray] | None = None
    input_names: tuple[str, ...] = ("input",)

    @property
    def model(self) -> LinearModel:
        """The fitted model of the first (or only) order asked for, about the record's offsets.

        Its operating point is what detrending removed, in the record's units, as a model file
        written by `maskless identify` loads.

        Raises:
            ModelError: an m-input model, which the single-input ``LinearModel`` (and so every
                design and plant) cannot hold; its per-input models are in
                ``fitted_models[0].input_models``.
        """
        if self.fitted_models[0].model is None:
            raise ModelError(
                f"a model of {len(self.input_names)} inputs ({', '.join(self.input_names)}): "
                "the designs and plants drive one input; see fitted_models[0].input_models"
            )
        return dataclasses.replace(
            self.fitted_models[0].model,
            operating_input=self.offsets.input_offset,
            operating_output=self.offsets.output_offset,
            input_unit=self.units[0],
            output_unit=self.units[1],
        )


def _field_unit(topic_and_field: str) -> str:
    """The unit a maskless field's name ends in; "" (not given) for a name without one."""
    for suffix, unit in _FIELD_UNITS.items():
        if topic_and_field.endswith(suffix):
            return unit
    return ""


def read_record(
    request: IdentificationRequest, cut_notes: list[str] | None = None
) -> tuple[np.ndarray, np.ndarray, tuple[str | None, str | None]]:
    """The input and output records and their units (None: a CSV, which carries none).

    Records that cannot be used are refused with the file named. ``cut_notes``: as
    ``records.read_mcap_signals`` takes it.
    """
    label = request.label
    output_path = request.output or request.input
    if request.input.suffix == ".mcap" or output_path.suffix == ".mcap":
        input_field = request.input_column or DEFAULT_MCAP_INPUT
        output_field = request.output_column or DEFAULT_MCAP_OUTPUT
        u, y, period_s = read_aligned_mcap(
            request.input, input_field, output_path, output_field, cut_notes
        )
        refuse_other_period(label("ts"), request.ts, period_s)
        topic, fields = named_fields(input_field)
        input_units = tuple(_field_unit(f"{topic}:{field}") for field in fields)
        units = (input_units[0] if u.ndim == 1 else input_units, _field_unit(output_field))
        return u, y, units
    if request.output is None:
        raise RecordError(f"{label('output')} is required when {label('input')} is a CSV file")
    columns = _input_columns(request)
    u = (
        read_csv_signal(request.input, request.input_column)
        if len(columns) == 1
        else _stack_columns(request.input, columns)
    )
    y = read_csv_signal(request.output, request.output_column)
    if u.shape[0] != y.size:
        raise RecordError(
            f"{request.input} has {u.shape[0]} values but {request.output} has {y.size}; expected "
            "one output per input"
        )
    return u, y, (None, None)


def _input_columns(request: IdentificationRequest) -> list[str | None]:
    """The input's columns (CSV) or fields (MCAP): "A,B" names several inputs."""
    column = request.input_column
    if column is None:
        return [None]
    names = named_fields(column)[1]
    return names if len(names) > 1 else [column]


def _stack_columns(path: Path, columns: list[str]) -> np.ndarray:
    """Several CSV columns of one file as an (N, m) input, each as ``read_csv_signal`` reads it."""
    signals = [read_csv_signal(path, column) for column in columns]
    if len({signal.size for signal in signals}) != 1:
        raise RecordError(
            f"{path}: columns {columns} have {[s.size for s in signals]} values: expected one "
            "length"
        )
    return np.column_stack(signals)


def input_names(request: IdentificationRequest, inputs: int) -> tuple[str, ...]:
    """The inputs' names: their CSV columns or MCAP fields, or "input i" (arrays, indices)."""
    if inputs == 1:
        return ("input",)
    columns = _input_columns(request)
    if len(columns) != inputs:
        return tuple(f"input {i + 1}" for i in range(inputs))
    return tuple(f"column {column}" if column.isdigit() else column.strip() for column in columns)


def _sources(request: IdentificationRequest) -> tuple[str, str]:
    """Where the input and output came from, as messages name them."""
    if request.input is None:
        return "u", "y"
    output = request.output or request.input
    if request.input.suffix == ".mcap" or output.suffix == ".mcap":
        fields = (
            request.input_column or DEFAULT_MCAP_INPUT,
            request.output_column or DEFAULT_MCAP_OUTPUT,
        )
        return f"{request.input}:{fields[0]}", f"{output}:{fields[1]}"
    columns = (request.input_column, request.output_column)
    return tuple(
        f"{path} column {column}" if column is not None else str(path)
        for path, column in zip((request.input, output), columns, strict=True)
    )


def _units(
    request: IdentificationRequest, read: tuple[str | None, str | None]
) -> tuple[tuple[str, str], tuple[str, str]]:
    """(units, where each came from): the request's, else the record's, else the CSV's."""
    chosen = []
    for given, from_record, csv_default in zip(
        (request.input_unit, request.output_unit), read, CSV_UNITS, strict=True
    ):
        if given is not None:
            chosen.append((given, UNIT_GIVEN))
        elif from_record is None:
            chosen.append((csv_default, UNIT_CSV_DEFAULT))
        else:
            chosen.append((from_record, UNIT_FROM_FIELD if from_record else UNIT_NOT_GIVEN))
    (input_unit, input_origin), (output_unit, output_origin) = chosen
    return (input_unit, output_unit), (input_origin, output_origin)


def _input_units(
    request: IdentificationRequest, read: tuple[str, ...] | None, inputs: int
) -> tuple[tuple[str, ...], str]:
    """With m inputs, (their units, where they came from).

    --input-unit gives "UNIT" for all or "UNIT,UNIT" one each; else the recording's fields' units,
    else (a CSV) the robot's CSV convention.
    """
    given, label = request.input_unit, request.label("input_unit")
    if given is None and read is None:
        return (CSV_UNITS[0],) * inputs, UNIT_CSV_DEFAULT
    if given is None:
        read = (read,) * inputs if isinstance(read, str) else read  # "" from arrays: not given
        return read, UNIT_FROM_FIELD if all(read) else UNIT_NOT_GIVEN
    units = tuple(unit.strip() for unit in given.split(","))
    if len(units) == 1:
        return units * inputs, UNIT_GIVEN
    if len(units) != inputs or not all(units):
        raise ConfigError(
            f"{label} {given!r}: expected one unit for all {inputs} inputs or {inputs} "
            "comma-separated units"
        )
    return units, UNIT_GIVEN


def minimum_samples(orders: list[int], method: str, inputs: int = 1) -> int:
    """The fewest samples a part needs for the largest order (N4SID's Hankel matrices need more)."""
    largest = max(orders)
    return subspace_minimum(largest, inputs) if method == "n4sid" else 10 * largest


def identify_record(request: IdentificationRequest) -> "IdentificationRun":
    """Reads the record ``request`` names, fits each order and judges it.

    Each order is fitted on the estimation part and judged on both parts (see
    ``analysis.identification.report.identify``).

    Raises:
        RecordError: a record that cannot be read or used as asked, naming the file and field.
    """
    if request.input is None:
        raise RecordError(f"{request.label('input')}: expected the record to read")
    with noting_cuts() as cut:
        u, y, units = read_record(request, cut)
        return identify_signals(u, y, request, units, identified_before_the_cut(cut))


def identify(
    u, y, sample_period_s: float, order: int = 2, method: str = "pem", **options
) -> "IdentificationRun":
    """Identifies a model of ``y`` from ``u``, judged as `maskless identify` judges it.

    Args:
        u: the input samples (say a valve current, A): (N,), or (N, m) for m inputs (say the
            inlet and the outlet valve currents, A).
        y: the output samples (say the head height, m), one per input sample.
        sample_period_s: the samples' period (s).
        order: the model order.
        method: "pem", "armax", "arx" or "n4sid".
        **options: any other ``IdentificationRequest`` field (``estimation="0:0.6"``,
            ``detrend="mean"``, ``input_unit="A"``, ...).

    Returns:
        The run: ``.model`` the fitted model, ``.report`` its figures, baselines and verdict.
    """
    request = IdentificationRequest(
        input=None, ts=sample_period_s, orders=(order,), method=method, **options
    )
    u, y = np.asarray(u, dtype=float), np.asarray(y, dtype=float)
    if y.ndim != 1 or u.ndim not in (1, 2) or u.shape[0] != y.size or 0 in u.shape[1:]:
        raise RecordError(
            f"u and y: expected y 1-D and u 1-D (one input) or (N, m) (m inputs) of one length, "
            f"got shapes {u.shape} and {y.shape}"
        )
    if u.ndim == 2 and u.shape[1] == 1:
        u = u[:, 0]
    if not (np.all(np.isfinite(u)) and np.all(np.isfinite(y))):
        raise RecordError("u and y: expected finite numbers only")
    return identify_signals(u, y, request, ("", ""))


def identify_signals(
    u: np.ndarray,
    y: np.ndarray,
    request: IdentificationRequest,
    units: tuple[str | None, str | None],
    record_warnings: tuple[str, ...] = (),
) -> "IdentificationRun":
    """``identify_record`` on signals already read.

    ``units``: as read, before the request's ("" not given; None: a CSV's, which carries none).
    ``record_warnings``: what reading them warned (a cut-off recording), the report's first.
    """
    label = request.label
    orders = list(request.orders)
    inputs = 1 if u.ndim == 1 else u.shape[1]
    names = input_names(request, inputs)
    sources = _sources(request)
    if inputs == 1:
        units, unit_origins = _units(request, units)
        for signal, name, source, unit in zip(
            (u, y), ("input", "output"), sources, units, strict=True
        ):
            refuse_constant(signal, name, source, unit)
    else:
        input_units, input_origin = _input_units(request, units[0], inputs)
        # The output's unit as for one input (the input's part of _units is not used).
        (_, output_unit), (_, output_origin) = _units(request, ("", units[1]))
        units, unit_origins = (input_units, output_unit), (input_origin, output_origin)
        # Inputs of one unit (both valves' currents) are judged each against the widest: one
        # that varies by rounding of it is constant. Inputs of units not given may differ.
        same_unit = all(input_units) and len(set(input_units)) == 1
        scale = widest_spread(u) if same_unit else 0.0
        for column, name, unit in zip(u.T, names, input_units, strict=True):
            refuse_constant(column, f"input {name}", sources[0], unit, scale)
        refuse_constant(y, "output", sources[1], output_unit)
    estimation_slice = parse_range(request.estimation, y.size, label("estimation"))
    validation_slice = parse_range(request.validation, y.size, label("validation"))
    needed = minimum_samples(orders, request.method, inputs)
    needing = f"order {max(orders)} with {request.method}"
    for name, part in (("estimation", estimation_slice), ("validation", validation_slice)):
        flag = label(name)
        refuse_unfit_part(flag, part, y, sources[1], needed, needing)
        if request.k_step is not None and request.k_step >= part.stop - part.start:
            raise RecordError(f"{label('k_step')} {request.k_step}: longer than the {flag} part")
    offsets = _detrend(u, y, request.detrend)
    parts = [
        Part("estimation", offsets.u[estimation_slice], offsets.y[estimation_slice]),
        Part("validation", offsets.u[validation_slice], offsets.y[validation_slice]),
    ]
    overlap = parts_overlap(estimation_slice, validation_slice)

    def report_progress(evaluations, cost):
        print(f"fitting: {evaluations} evaluations, cost {cost:.6g}", file=sys.stderr, flush=True)

    long_record = parts[0].y.size >= _PROGRESS_MIN_SAMPLES
    report, fitted_models = identification_report.identify(
        request.method,
        parts[0],
        parts[1],
        orders,
        request.ts,
        estimate_initial_state=request.estimate_initial_state,
        progress=report_progress if long_record else None,
        k_step=request.k_step,
        overlap=overlap,
        record_diagnostics=diagnose_record(u, y, request.detrend, units)
        if inputs == 1
        else tuple(
            diagnose_record(column, y, request.detrend, (unit, units[1]))
            for column, unit in zip(u.T, units[0], strict=True)
        ),
        input_names=names if inputs > 1 else None,
        record_warnings=record_warnings,
    )
    report["record"] = {
        "samples": int(y.size),
        "estimation": [estimation_slice.start, estimation_slice.stop],
        "validation": [validation_slice.start, validation_slice.stop],
        "detrend": request.detrend,
        "input_offset": offsets.input_offset,
        "output_offset": offsets.output_offset,
        "units": {"input": units[0], "output": units[1]},
        "units_from": {"input": unit_origins[0], "output": unit_origins[1]},
        **({"inputs": list(names)} if inputs > 1 else {}),
    }
    return IdentificationRun(request, report, fitted_models, parts, offsets, units, (u, y), names)


def _detrend(u: np.ndarray, y: np.ndarray, mode: str) -> Detrended:
    """``records.detrend``, with m inputs column by column (offsets and slopes one per input)."""
    if u.ndim == 1:
        return detrend(u, y, mode)
    columns = [detrend(column, y, mode) for column in u.T]
    return Detrended(
        u=np.column_stack([column.u for column in columns]),
        y=columns[0].y,
        input_offset=tuple(column.input_offset for column in columns),
        output_offset=columns[0].output_offset,
        input_slope=tuple(column.input_slope for column in columns),
        output_slope=columns[0].output_slope,
    )


def identify_to_files(
    request: IdentificationRequest,
    out: str | Path,
    plotter: Worker | None = None,
    plots: bool = True,
) -> dict:
    """``identify_record`` then ``write_identification`` (``maskless identify``)."""
    return write_identification(identify_record(request), out, plotter, plots)


def plot_calls(identified: "IdentificationRun", out: Path) -> list[tuple]:
    """The record, compare and residual plots of ``identified`` as ``serve_calls`` calls."""
    fitted_models, report, units = identified.fitted_models, identified.report, identified.units
    ts = identified.request.ts
    calls = []
    if identified.signals is not None and isinstance(units[0], str):
        u, y = identified.signals
        record = report["diagnostics"]["record"]
        calls.append((plot_record, (out / "record.png", u, y, ts, units, record), {}))
    elif identified.signals is not None:  # a record plot per input
        u, y = identified.signals
        for index, name in enumerate(identified.input_names):
            record = report["diagnostics"]["inputs"][name]["record"]
            path = out / f"record_input{index + 1}.png"
            calls.append(
                (plot_record, (path, u[:, index], y, ts, (units[0][index], units[1]), record), {})
            )
    for fitted in fitted_models:
        stem = f"{fitted.method}_order{fitted.order}"
        curves = list(fitted.curves)
        stability = "" if fitted.linear_models[0].is_stable() else ", UNSTABLE"
        name = f"{fitted.method} order {fitted.order}{stability}"
        compare = out / f"compare_{stem}.png"
        calls.append((plot_compare, (compare, curves, name, ts, units[1]), {}))
        calls.append((plot_residuals, (out / f"residuals_{stem}.png", curves, name), {}))
    return calls


def write_identification(
    identified: "IdentificationRun",
    out: str | Path,
    plotter: Worker | None = None,
    plots: bool = True,
) -> dict:
    """Writes OUT/report.json, one model file per order, and the record, compare, residual plots.

    The record plot is record.png; the others are one per model. ``plotter`` draws them on the
    second core meanwhile (``start_plot_worker``: the command starts it before it imports the
    estimators; one is started here if None); this waits for it, or stops it if writing fails.
    With ``plots`` False no plot is drawn, and an earlier run's plots in OUT are removed (they
    would read as this run's). Returns the report with each model's file and plot named.
    """
    fitted_models, report, units = identified.fitted_models, identified.report, identified.units
    out = output_folder(out)
    several = not isinstance(units[0], str)
    named_units = (
        list(zip(identified.input_names, units[0], strict=True))
        if several
        else [("input", units[0])]
    ) + [("output", units[1])]
    convertible = all(unit in MODEL_FILE_UNITS for _, unit in named_units)
    if not convertible:
        report["warnings"].append(
            "the units ("
            + ", ".join(
                f"{name} {unit!r}" if unit else f"{name} not given" for name, unit in named_units
            )
            + ") are not all among "
            f"{', '.join(MODEL_FILE_UNITS)}: the model files hold them as given, and the designs "
            "and plants, which work in SI, refuse them"
        )

    report["removed_stale_files"] = remove_stale_outputs(
        out, [f"{fitted.method}_order{fitted.order}" for fitted in fitted_models], plots
    )
    calls = plot_calls(identified, out) if plots else []
    report["plots"] = [Path(args[0]).name for _, args, _ in calls]
    plotter = plotter or (start_plot_worker(out) if plots else None)
    try:
        for call in calls:
            plotter.send(call)
        _write_model_files(identified, out, convertible)
        (out / "report.json").write_text(json.dumps(report, indent=1))
        if plotter is not None:
            plotter.wait()
    except BaseException:
        if plotter is not None:
            plotter.stop()
        raise
    return report


def _write_model_files(identified: "IdentificationRun", out: Path, convertible: bool) -> None:
    """One model file per order, each read back before it is written; named in the report.

    ``convertible``: whether the units convert to SI, so a design could load the file.
    """
    request, units, offsets = identified.request, identified.units, identified.offsets
    several = not isinstance(units[0], str)
    linear = request.detrend == "linear"
    for fitted, entry in zip(identified.fitted_models, identified.report["models"], strict=True):
        contents = model_file_contents(
            fitted,
            input_unit=units[0],
            output_unit=units[1],
            input_offset=offsets.input_offset,
            output_offset=offsets.output_offset,
            detrend=request.detrend,
            trend_slopes_per_sample=(offsets.input_slope, offsets.output_slope) if linear else None,
            verdict=entry["verdict"],
        )
        path = out / f"model_{fitted.method}_order{fitted.order}.yaml"
        # Read back as `--plant identified:` would, so no run writes a file the loader refuses
        # (units it cannot convert to SI are named in the warnings above instead); an m-input
        # file, which the designs refuse, is checked input by input.
        if convertible:
            (input_models_from_contents if several else model_from_contents)(contents, str(path))
        path.write_text(yaml.safe_dump(contents, sort_keys=False))
        entry["model_file"] = str(path)


# The files `maskless identify` writes per model, as globs and with the model's stem filled in.
_MODEL_FILE, _MODEL_PLOTS = "model_{}.yaml", ("compare_{}.png", "residuals_{}.png")
_PER_MODEL_FILES = (_MODEL_FILE, *_MODEL_PLOTS)
# The record's plots: one for a single input, one per input for several.
_RECORD_PLOTS = ("record.png", "record_input*.png")


def remove_stale_outputs(out: Path, stems: list[str], plots: bool = True) -> list[str]:
    """Removes the per-model files of an earlier run in ``out`` that this run does not write.

    Removed rather than named: a model file left beside a new report reads as part of it (a
    user designs on model_pem_order4.yaml believing it judged by this report.json). Only files
    of identify's own naming (``_PER_MODEL_FILES`` with a stem METHOD_orderN) are touched; when
    this run draws no ``plots``, every plot of that naming goes, the record's too. Returns the
    names removed, for the report.
    """
    written = _PER_MODEL_FILES if plots else (_MODEL_FILE,)
    keep = {pattern.format(stem) for pattern in written for stem in stems}
    removed = []
    globs = [pattern.format("*_order*") for pattern in _PER_MODEL_FILES]
    for glob in globs + ([] if plots else list(_RECORD_PLOTS)):
        for path in sorted(out.glob(glob)):
            if path.name not in keep and path.is_file():
                path.unlink()
                removed.append(path.name)
    return removed


def format_identification_report(report: dict, out: str | Path) -> str:
    """The report as lines a person reads."""
    several = "inputs" in report["diagnostics"]
    lines = format_input_diagnostics(report) if several else format_diagnostics(report)
    for model in report["models"]:
        stability = "stable" if model["stable"] else "UNSTABLE"
        lines.append(
            f"{model['method']} order {model['order']} ({model['parameters']} parameters, "
            f"initial state {model['initial_state']}, {stability})"
        )
        for name in ("estimation", "validation"):
            part = model[name]
            k_steps = [key for key in part if key.endswith("step") and key != "fit_percent_1step"]
            extra = "".join(
                f", {key.removeprefix('fit_percent_')} {part[key]:.3f} %" for key in k_steps
            )
            lines.append(
                f"  {name:<10} fit 1-step {part['fit_percent_1step']:.6f} %{extra}, "
                f"sim {part['fit_percent_sim']:.2f} %, MSE {part['mse']:.6g}, "
                f"FPE {part['fpe']:.6g}, n {part['n']}"
            )
        margins = model["margins_on_validation"]
        lines.append(
            "  margins on validation (fit points): "
            + ", ".join(f"{name} {value:+.3f}" for name, value in margins.items())
        )
        for name, part in model.get("input_contributions", {}).get("validation", {}).items():
            gain = "none (integrating)" if part["dc_gain"] is None else f"{part['dc_gain']:.6g}"
            lines.append(
                f"  input {name}: DC gain {gain}; on validation sim fit "
                f"{part['fit_percent_sim_alone']:.1f} % with it alone, "
                f"{part['fit_percent_sim_without']:.1f} % without it "
                f"({part['fit_points_lost_without']:+.1f} points lost), its own part carries "
                f"{part['output_variance_share']:.0%} of the output's variance"
            )
        if "warning" in model:
            lines.append(f"  WARNING: {model['warning']}")
    naive = report["baselines"]["naive_last_value"]
    lines.append(
        "baseline 'next value = last value': fit 1-step "
        + ", ".join(f"{name} {part['fit_percent_1step']:.3f} %" for name, part in naive.items())
    )
    lines += [f"WARNING: {warning}" for warning in report["warnings"]]
    if report.get("removed_stale_files"):
        lines.append(
            "removed an earlier run's files this run did not write: "
            + ", ".join(report["removed_stale_files"])
        )
    drew_none = report.get("plots") == []  # None: not written yet
    written = "report and models (no plots)" if drew_none else "report, models and plots"
    lines += ["", report["verdict"], "", f"{written} in {out}"]
    return "\n".join(lines)
