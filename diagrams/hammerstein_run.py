"""`maskless identify --method hammerstein`: both valves' maps and the dynamics from a recording.

Reads the inlet's and the outlet's currents and the fused head height from a maskless MCAP recording
(``maskless excite`` driving both valves), fits a Hammerstein model per order on the estimation part
(``analysis.identification.hammerstein``, read as ``DESIGNED_RECORD_READING`` says, as the
sequential design's rounds read it) and judges it on the validation part (each, unless given, as a
designed recording says: ``fit_split``) by simulation fit against the linear model of the same
order, fitted by the same output-error code. Each model is simulated over the whole record from rest
at its first currents and judged on the validation part (``hammerstein.held_out_simulation``: not
from rest at the part's first currents, which judges where the split fell). Writes OUT/report.json,
one model file per order (``model_file.hammerstein_file_contents``, in A and m) and a plot of each
valve's static curve and the validation simulation.
"""

import json
from pathlib import Path

import numpy as np
import yaml

from maskless.analysis.identification.data_diagnostics import (
    refuse_constant,
    refuse_unfit_part,
    widest_spread,
)
from maskless.analysis.identification.fit_metrics import fit_percent
from maskless.analysis.identification.hammerstein import (
    DESIGNED_RECORD_READING,
    estimate_hammerstein,
    held_out_simulation,
    minimum_samples,
)
from maskless.analysis.identification.model_file import (
    VALVE_NAMES,
    hammerstein_file_contents,
    model_from_contents,
)
from maskless.analysis.identification.records import (
    VALVE_CURRENTS_FIELDS,
    identified_before_the_cut,
    named_fields,
    noting_cuts,
    read_aligned_mcap,
    refuse_other_period,
)
from maskless.analysis.identification.report import EXPLAINS_SIM
from maskless.diagrams.fit_split import fit_split
from maskless.diagrams.identification_request import DEFAULT_MCAP_OUTPUT
from maskless.diagrams.output_folder import output_folder
from maskless.errors import RecordError
from maskless.recording import FIT_SPLIT_METADATA, read_leading_metadata

# The Hammerstein model must beat the linear one by this many points of validation fit for the
# verdict to call the valve maps worth their parameters.
_MARGIN_POINTS = 5.0
# How the verdict of maps worth their parameters (and a converged fit) begins.
MAPS_EXPLAIN_VERDICT = "the valve maps explain"


def read_two_valve_record(
    recording: Path,
    input_field: str = VALVE_CURRENTS_FIELDS,
    output_recording: Path | None = None,
    output_field: str = DEFAULT_MCAP_OUTPUT,
    cut_notes: list[str] | None = None,
):
    """(currents (N, 2) in A, output (N,), its period in s) from maskless recordings.

    Args:
        recording: the MCAP recording of the valves' currents (A).
        input_field: "TOPIC:FIELD,FIELD", the inlet's and the outlet's current in that order.
        output_recording: the MCAP recording of the output (default: ``recording``).
        output_field: "TOPIC:FIELD" of the output (m).
        cut_notes: as ``records.read_mcap_signals`` takes it.

    Raises:
        RecordError: not an MCAP recording, an input that is not two fields, or currents and
            output that share fewer than 2 samples or have a gap (``records.read_aligned_mcap``).
    """
    output_recording = output_recording or recording
    for flag, path in (("--input", recording), ("--output", output_recording)):
        if Path(path).suffix != ".mcap":
            raise RecordError(
                f"{flag} {path}: --method hammerstein reads a maskless MCAP recording (both "
                "valves' currents and the head height)"
            )
    u, y, period_s = read_aligned_mcap(
        recording, input_field, output_recording, output_field, cut_notes
    )
    if u.ndim != 2 or u.shape[1] != len(VALVE_NAMES):
        raise RecordError(
            f"--input-column {input_field!r}: expected TOPIC:FIELD,FIELD, the inlet's and the "
            f"outlet's current (default {VALVE_CURRENTS_FIELDS})"
        )
    return u, y, period_s


def identify_hammerstein_to_files(
    recording: Path,
    ts: float,
    orders: list[int],
    out: str | Path,
    estimation: str | None = None,
    validation: str | None = None,
    input_field: str = VALVE_CURRENTS_FIELDS,
    output_recording: Path | None = None,
    output_field: str = DEFAULT_MCAP_OUTPUT,
    plots: bool = True,
) -> dict:
    """Fits, judges and writes (see the module docstring); returns the report.

    The record is read as ``read_two_valve_record`` reads it. A part not given (None) is the
    recording's design's, else the default (``fit_split``); the report holds both parts and where
    each came from, and each model's warnings begin with a cut-off recording's, then the
    split's. With ``plots`` False no plot is drawn, and an earlier run's in ``out`` is removed (it
    would read as this run's).

    Raises:
        RecordError: a recording that cannot be read as two valves and an output, a --ts more
            than 1 % off its sample period, parts out of range or parts the fit cannot use
            (``_refuse_unusable_parts``); it says a cut-off recording too.
    """
    with noting_cuts() as cut:
        u, y, split = _usable_record(
            (recording, input_field, output_recording, output_field),
            ts,
            max(orders),
            (estimation, validation),
            cut,
        )
    record_warnings = identified_before_the_cut(cut)
    estimation_part, validation_part = split.estimation_part, split.validation_part
    u_est, y_est = u[estimation_part], y[estimation_part]
    u_val, y_val = u[validation_part], y[validation_part]
    out = output_folder(out)
    report = {"method": "hammerstein", "recording": str(recording), **split.summary()}
    report["models"] = []
    figures = []
    for order in orders:
        fit = estimate_hammerstein(
            u_est,
            y_est,
            order,
            ts,
            input_unit="A",
            output_unit="m",
            **DESIGNED_RECORD_READING,
        )
        linear = estimate_hammerstein(u_est, y_est, order, ts, linear=True).model
        simulated, linear_simulated = (
            held_out_simulation(model, u, validation_part) for model in (fit.model, linear)
        )
        validation_fit = fit_percent(y_val, simulated)
        linear_fit = fit_percent(y_val, linear_simulated)
        verdict = hammerstein_verdict(validation_fit, linear_fit)
        if not fit.converged:
            verdict = f"the fit failed ({fit.message}); " + verdict
        contents = hammerstein_file_contents(fit.model, verdict=verdict)
        path = out / f"model_hammerstein_order{order}.yaml"
        model_from_contents(contents, str(path))  # never write a file the loader refuses
        path.write_text(yaml.safe_dump(contents, sort_keys=False))
        summary = fit.summary(VALVE_NAMES)
        summary["warnings"] = [*record_warnings, *split.warnings, *summary["warnings"]]
        entry = {
            **summary,
            "order": order,
            "validation_simulation_fit_percent": validation_fit,
            "linear_validation_simulation_fit_percent": linear_fit,
            "verdict": verdict,
            "model_file": str(path),
        }
        report["models"].append(entry)
        figures.append((order, fit.model, simulated, linear_simulated))
    plot_path = out / "hammerstein.png"
    if plots:
        _plot(plot_path, figures, u_val, y_val, ts)
        report["plot"] = str(plot_path)
    else:
        plot_path.unlink(missing_ok=True)
        report["plot"] = None
    (out / "report.json").write_text(json.dumps(report, indent=1))
    return report


def _usable_record(fields, ts: float, order: int, parts, cut_notes: list[str]):
    """(currents (N, 2), output (N,), ``FitSplit``) of the record, or a one-line refusal.

    Args:
        fields: the recording, its currents' "TOPIC:INLET,OUTLET", the output's recording (None:
            the same) and "TOPIC:FIELD", as ``read_two_valve_record`` takes them.
        ts: the sample period asked for (s): refused more than 1 % off the recording's.
        order: the highest order asked for.
        parts: the estimation and validation parts given (None: not given; see ``fit_split``).
        cut_notes: as ``records.read_mcap_signals`` takes it.
    """
    recording, input_field, output_recording, output_field = fields
    u, y, period_s = read_two_valve_record(*fields, cut_notes=cut_notes)
    refuse_other_period("--ts", ts, period_s)
    designed = read_leading_metadata(recording).get(FIT_SPLIT_METADATA)
    split = fit_split(designed, *parts, y.size)
    topic, currents = named_fields(input_field)
    _refuse_unusable_parts(
        u[split.estimation_part],
        y,
        split,
        order,
        [f"{recording} {topic}:{current}" for current in currents],
        f"{output_recording or recording} {output_field}",
    )
    return u, y, split


def _refuse_unusable_parts(
    u_est, y, split, order: int, valve_sources: list[str], output_source: str
) -> None:
    """A one-line RecordError for parts the fit cannot use, before anything is fitted or written.

    An estimation part too short for the model's parameters, a valve whose current it holds
    constant (a recording of `maskless excite` on the inlet alone; a closed loop's, where the
    outlet never opened), or an output constant over either part, where no fit is defined.

    Args:
        u_est: the estimation part's currents (N, 2).
        y: the whole record's output.
        split: the record's ``FitSplit``.
        order: the highest order asked for.
        valve_sources: where each valve's current was read (recording, topic and field).
        output_source: where the output was read.
    """
    estimation = f"the estimation part {split.estimation} ({split.estimation_from})"
    validation = f"the validation part {split.validation} ({split.validation_from})"
    needed = minimum_samples(order, len(VALVE_NAMES))
    needing = f"order {order} with two valves"
    refuse_unfit_part(estimation, split.estimation_part, y, output_source, needed, needing)
    # Judged by simulation, a validation part needs only a spread to divide by.
    refuse_unfit_part(validation, split.validation_part, y, output_source, 2, "a fit")
    scale = widest_spread(u_est)
    for valve, currents, source in zip(VALVE_NAMES, u_est.T, valve_sources, strict=True):
        name = f"{valve} valve's current over the estimation part {split.estimation}"
        try:
            refuse_constant(currents, name, source, "A", scale)
        except RecordError as error:
            error.add_note(
                "--method hammerstein needs both valves driven: record them with maskless excite "
                "--valve-drive split-range (or independent)"
            )
            raise


def hammerstein_verdict(validation_fit: float, linear_fit: float) -> str:
    """Whether the valve maps earn their parameters, from the validation simulation fits (%).

    The maps explain the output when the model's fit reaches ``report.EXPLAINS_SIM`` (where the
    input carries most of the output, the linear report's bar) and beats the linear model's by
    ``_MARGIN_POINTS``. Below the bar the model explains nothing held out, however far it beats
    a linear model: -80 % against -136 % is two failures, not a win.
    """
    margin = validation_fit - linear_fit
    if not validation_fit >= EXPLAINS_SIM:
        return (
            f"the model does not explain the validation part: its simulation fits "
            f"{validation_fit:.1f} % (a linear model of the same order {linear_fit:.1f} %), "
            f"under the {EXPLAINS_SIM:.0f} % where the input carries most of the output"
        )
    if margin >= _MARGIN_POINTS:
        return (
            f"{MAPS_EXPLAIN_VERDICT} {margin:.1f} points of validation simulation fit more than "
            "a linear model of the same order"
        )
    return (
        f"the valve maps add {margin:.1f} points of validation simulation fit over a linear "
        "model of the same order: not worth their parameters here"
    )


def _plot(path: Path, figures, u_val, y_val, ts: float) -> None:
    """Each valve's static curve (mm per mA) and the validation part, measured and simulated."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figure, (curves, compare) = plt.subplots(2, 1, figsize=(8, 7))
    currents = np.linspace(0.0, float(np.max(u_val)) * 1.05, 300)
    times = np.arange(y_val.size) * ts
    compare.plot(times, 1e3 * y_val, color="black", linewidth=0.8, label="measured")
    for order, model, simulated, linear_simulated in figures:
        for index, name in enumerate(VALVE_NAMES[: model.inputs]):
            curves.plot(
                1e3 * currents,
                1e3 * model.static_curve(index, currents),
                label=f"{name}, order {order}",
            )
        compare.plot(times, 1e3 * simulated, label=f"Hammerstein, order {order}")
        compare.plot(times, 1e3 * linear_simulated, label=f"linear, order {order}")
    curves.set_xlabel("valve current (mA)")
    curves.set_ylabel("steady height change (mm)")
    curves.set_title("static curves (map x DC gain)")
    curves.legend()
    compare.set_xlabel("validation time (s)")
    compare.set_ylabel("head height (mm)")
    compare.set_title("validation: simulated from the record's start")
    compare.legend()
    figure.tight_layout()
    figure.savefig(path)
    plt.close(figure)


def format_hammerstein_report(report: dict) -> str:
    """The report as lines a person reads."""
    lines = [
        f"maskless identify --method hammerstein: {report['recording']}",
        f"  fitted on {report['estimation']} ({report['estimation_from']}), judged on "
        f"{report['validation']} ({report['validation_from']})",
    ]
    for model in report["models"]:
        lines.append(
            f"  order {model['order']}: validation simulation fit "
            f"{model['validation_simulation_fit_percent']:.1f} % (linear "
            f"{model['linear_validation_simulation_fit_percent']:.1f} %): {model['verdict']}"
        )
        for name, valve in model["valves"].items():
            low, high = valve["starting_current_spread"]
            highest = valve["highest_current_in_record"]
            saturation = (
                f"saturates at {1e3 * valve['saturation_current']:.1f} mA"
                if valve["saturation_current"] <= highest
                else f"does not saturate up to the record's highest {1e3 * highest:.1f} mA"
            )
            saturation_spread = valve.get("saturation_current_spread")
            if saturation_spread is not None:
                low_c, high_c = saturation_spread
                saturation += (
                    f" (the record cannot tell apart {1e3 * low_c:.1f}-{1e3 * high_c:.1f} mA)"
                )
            play = valve.get("play_half_width")
            tolerance = valve.get("spread_cost_tolerance")
            spread = f"{1e3 * low:.1f}-{1e3 * high:.1f} mA"
            # A joint search's spread is where its searches ended, not what the record rules out.
            source = (
                f"from {valve['starting_current_from']}, play ±{1e3 * play:.1f} mA; the record "
                f"cannot tell apart {spread}"
                if play is not None
                else f"searches ending within {100 * tolerance:.2g} % of the best cost ended "
                f"at {spread}"
                if tolerance is not None
                else f"the record cannot tell apart {spread}"
            )
            lines.append(
                f"    {name}: starts at {1e3 * valve['starting_current']:.1f} mA ({source}), "
                f"{saturation}, full opening moves the head {1e3 * valve['dc_gain']:.2f} mm"
            )
        lines += [f"    WARNING: {warning}" for warning in model.get("warnings", [])]
        lines.append(f"    model file: {model['model_file']}")
    lines.append(f"  plot: {report['plot'] or 'none (--no-plots)'}")
    return "\n".join(lines)
