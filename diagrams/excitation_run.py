"""Exciting the plant open loop for identification: the run and its summary.

The inlet valve (outlet shut) follows the paper's uniform white noise (Eq. 22-23), a PRBS, a
Schroeder multisine or a multilevel PRBS about an offset current, clipped to the valve's
[0, saturation] range as the authors clipped theirs, while the cameras, their local Kalman filters
and the fusion watch the head. Or both valves move (``valve_drive``): each with its own signal, or
one signal split between them (``systems.control.valve_pair_excitation``). The recording has the
topics of a closed-loop run (the command topic carries both valve currents as applied), so
`maskless identify` reads it as it is. ``diagrams.excitation_design`` holds the request and
designs the currents.
"""

import dataclasses
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource

from maskless.analysis.metrics import estimate_error_std_m
from maskless.diagrams.closed_loop import ClosedLoop, LoopDrive, add_plant, assemble_loop
from maskless.diagrams.controller_design import NominalPneumatic

# SIGNALS is imported "as" itself, re-exported: `maskless workflow` takes it from here.
from maskless.diagrams.excitation_design import SIGNALS as SIGNALS
from maskless.diagrams.excitation_design import (
    ExcitationPlan,
    ExcitationRequest,
    plan_excitation,
)
from maskless.diagrams.fit_split import parts_of_share
from maskless.diagrams.output_folder import RunFolder
from maskless.diagrams.run_summary import estimation_start_s
from maskless.diagrams.scenario import PneumaticPlant, Scenario, kind_name
from maskless.diagrams.simulation import RUN_FILES, SimulationRun, simulate_loop
from maskless.errors import ConfigError
from maskless.recording import FIT_SPLIT_METADATA
from maskless.systems.control.excitation import (
    ExcitationSignal,
    add_excitation_source,
    clip_to_valve_range,
    clipped_fraction,
    sampled_signal,
    theoretical_uniform_std,
)
from maskless.systems.units import a_to_ma, m_to_mm


@dataclass
class ExcitationRun:
    """The outcome of ``excite``.

    Attributes:
        run: the simulated experiment: its signals, recording and plot (``write_mcap``,
            ``plot(path, show_tolerance=False)``).
        designed: the excitation as designed (A): the inlet's, or the split-range command.
        applied: the inlet's current, clipped to its range, as applied (A).
        summary: the signal's statistics (mA), each valve's currents (mA) and what the head and
            fused estimate did (mm).
        applied_outlet: the outlet's current as applied (A); None when it stayed shut.
        designed_outlet: the outlet's own signal as designed (A), in an independent drive; else
            None.
    """

    run: SimulationRun
    designed: ExcitationSignal
    applied: ExcitationSignal
    summary: dict
    applied_outlet: ExcitationSignal | None = None
    designed_outlet: ExcitationSignal | None = None


def excite(scenario: Scenario, request: ExcitationRequest) -> ExcitationRun:
    """Designs the excitation ``request`` asks for, checks it, and runs it on the plant open loop.

    The plant is ``scenario``'s; the run lasts ``request.duration_s`` (the scenario's own duration
    is not used).

    Raises:
        ConfigError: fewer than two samples, a PRBS with fewer than two bits, a multisine band
            with no line of the frequency grid, a multilevel hold shorter than a sample, or an
            excitation that clipping to a driven valve's range leaves constant.
    """
    return _run_plan(plan_excitation(scenario, request))


def _run_plan(plan: ExcitationPlan) -> ExcitationRun:
    """Simulates the planned experiment and summarises it."""
    if plan.request.signal == "designed-levels":
        return _run_designed_levels(plan)
    loop = build_excitation_loop(plan.scenario, plan.inlet, outlet=plan.outlet)
    run = simulate_loop(loop, plan.scenario)
    summary = excitation_summary(plan, run)
    return ExcitationRun(run, plan.designed, plan.inlet, summary, plan.outlet, plan.designed_outlet)


def sequential_design(request: ExcitationRequest):
    """The sequential design (``valve_level_experiment.SequentialDesign``) ``request`` asks for.

    Its targeted holds last the request's shortest hold, or the design's own if longer: a fit
    whose holds were too short for the plant advises holds of at least so long
    (``hammerstein._joint_search_warnings``), and a user who asks for them gets them everywhere.
    """
    from maskless.diagrams.valve_level_experiment import SequentialDesign

    return SequentialDesign(hold_s=max(SequentialDesign.hold_s, request.hold_s[0]))


def _run_designed_levels(plan: ExcitationPlan) -> ExcitationRun:
    """The plan's levels with a stretch designed as the run goes; summarised as applied.

    The summary adds ``design``: the stretch (s), its rounds' starting-current intervals (mA)
    and the share of the record to fit (``valve_level_experiment.SequentialDesign``).
    """
    # Imported here: the designed experiment runs this module's loop.
    from maskless.diagrams.valve_level_experiment import run_designed_experiment

    design = sequential_design(plan.request)
    started = time.perf_counter()
    period_s = plan.inlet.sample_period_s
    currents = np.vstack([plan.inlet.values, plan.outlet.values])
    applied, _, run, intervals = run_designed_experiment(plan.scenario, currents, period_s, design)
    inlet, outlet = (sampled_signal(row, period_s, plan.request.signal) for row in applied)
    plan = dataclasses.replace(
        plan, designed=inlet, inlet=inlet, outlet=outlet, designed_outlet=outlet
    )
    summary = excitation_summary(plan, run)
    # The whole experiment's, its rounds' runs and fits included, not the final run's alone.
    summary["wall_time_s"] = time.perf_counter() - started
    first, end = design.stretch(currents.shape[1])
    summary["design"] = {
        "stretch_s": [first * period_s, end * period_s],
        "round_start_intervals_ma": [a_to_ma(found).tolist() for found in intervals],
        "fit_share": design.fitted_share,
    }
    return ExcitationRun(run, inlet, inlet, summary, outlet, outlet)


def excite_to_files(
    scenario: Scenario, request: ExcitationRequest, out: str | Path, *, overwrite: bool = False
) -> dict:
    """``excite``, writing OUT/run.mcap and OUT/run.png (``maskless excite``).

    With rendered cameras, the recording holds their images and OUT/frames.png shows each
    camera's first and last one. Returns the summary with the files written (``files``).

    A designed experiment's recording says the part of it to fit (``recording.FIT_SPLIT_METADATA``,
    read by `maskless identify --method hammerstein`).

    The request is checked, then OUT claimed as ``simulate_to_files`` claims it (refused when in
    use or, unless ``overwrite``, holding a run), both before anything is simulated; the files
    are written under temporary names and renamed when all are written.

    Raises:
        ConfigError: as ``excite``, or OUT refused.
    """
    plan = plan_excitation(scenario, request)
    with RunFolder(out, RUN_FILES, overwrite=overwrite) as folder:
        excited = _run_plan(plan)
        design = excited.summary.get("design")
        metadata = {FIT_SPLIT_METADATA: parts_of_share(design["fit_share"])} if design else None
        excited.run.write_mcap(folder.temporary("run.mcap"), metadata)
        excited.run.plot(folder.temporary("run.png"), show_tolerance=False)
        files = {"recording": "run.mcap", "plot": "run.png"}
        if excited.run.frames:
            excited.run.plot_frames(folder.temporary("frames.png"))
            files["frames"] = "frames.png"
    return {**excited.summary, "files": folder.final_paths(files)}


def build_excitation_loop(
    config: Scenario,
    signal: ExcitationSignal,
    record: bool = True,
    outlet: ExcitationSignal | None = None,
) -> ClosedLoop:
    """The plant driven open loop by ``signal`` on its inlet, the head watched.

    The outlet follows ``outlet`` (sampled as ``signal``), or stays shut when it is None. The
    cameras, local filters and fusion watch the head; outputs and logs are as
    ``build_closed_loop``'s, logged at the signal's sample period. ``controller`` is
    "excitation", and model and design are None.
    """
    builder = DiagramBuilder()
    nominal = NominalPneumatic.of(config) if isinstance(config.plant, PneumaticPlant) else None
    plant = add_plant(builder, config, nominal)
    if outlet is None:
        inlet_port = add_excitation_source(builder, signal, name="excitation")
        shut = builder.AddNamedSystem("outlet_valve_shut", ConstantVectorSource([0.0]))
        outlet_port = shut.get_output_port()
    else:
        if outlet.sample_period_s != signal.sample_period_s:
            raise ConfigError(
                f"outlet sampled every {outlet.sample_period_s} s: expected the inlet's "
                f"{signal.sample_period_s} s"
            )
        inlet_port = add_excitation_source(builder, signal, name="inlet_excitation")
        outlet_port = add_excitation_source(builder, outlet, name="outlet_excitation")
    resting = builder.AddNamedSystem("reference", ConstantVectorSource([plant.start_height_m]))
    drive = LoopDrive(
        inlet_port,
        outlet_port,
        resting.get_output_port(),
        signal.sample_period_s,
        "excitation",
    )
    return assemble_loop(
        builder, config, plant, drive, record, f"{kind_name(config.plant)}_excitation"
    )


def _valve_summary(applied: ExcitationSignal | None, clipped: float) -> dict:
    """One valve's currents as applied (mA): range, mean, std, and the fraction clipped."""
    values = np.zeros(1) if applied is None else applied.values
    return {
        "driven": applied is not None,
        "range_ma": [a_to_ma(float(values.min())), a_to_ma(float(values.max()))],
        "mean_ma": a_to_ma(float(np.mean(values))),
        "std_ma": a_to_ma(float(np.std(values))),
        "clipped_fraction": clipped,
    }


def excitation_summary(plan: ExcitationPlan, run: SimulationRun) -> dict:
    """The signal's statistics (mA), each valve's (mA) and what the head and estimate did (mm).

    The top-level statistics are the designed signal's (independent: the inlet's; split-range:
    the command's, clipped to its range for ``applied_*``); ``valves`` holds what each valve got.
    """
    designed = plan.designed
    applied = clip_to_valve_range(designed, *plan.designed_range_a)
    times_s, head = run.signals["head_height_m"].times_s, run.signals["head_height_m"].values[0]
    fused = run.signals["fusion.estimated_state"].values[0]
    start_s = estimation_start_s(run.scenario, times_s)
    summary = {
        "plant": run.closed_loop.plant,
        "signal": designed.kind,
        "valve_drive": plan.request.valve_drive,
        "samples": applied.num_samples,
        "sample_period_s": applied.sample_period_s,
        "amplitude_ma": a_to_ma(plan.amplitude_a),
        "offset_ma": a_to_ma(plan.offset_a),
        "mean_ma": a_to_ma(float(np.mean(designed.values))),
        "std_ma": a_to_ma(designed.std()),
        "crest_factor": designed.crest_factor(),
        "clipped_fraction": clipped_fraction(designed, *plan.designed_range_a),
        "applied_std_ma": a_to_ma(applied.std()),
        "applied_crest_factor": applied.crest_factor(),
        "valves": {
            "inlet": _valve_summary(plan.inlet, plan.clipped["inlet"]),
            "outlet": _valve_summary(plan.outlet, plan.clipped["outlet"]),
        },
        "head_height_mm": {"min": m_to_mm(float(head.min())), "max": m_to_mm(float(head.max()))},
        "fused_error_std_mm": m_to_mm(estimate_error_std_m(times_s, fused, head, start_s)),
        "estimation_start_s": start_s,
        "wall_time_s": run.wall_time_s,
    }
    if designed.kind == "uniform":
        summary["uniform_theoretical_std_ma"] = a_to_ma(theoretical_uniform_std(plan.amplitude_a))
    return summary


_DRIVE_WORDS = {
    "inlet": "inlet",
    "independent": "inlet and outlet (a signal each)",
    "split-range": "inlet and outlet (one split-range command)",
}


def _valve_line(valve: str, valve_summary: dict) -> str:
    if not valve_summary["driven"]:
        return f"  {valve}: shut"
    low_ma, high_ma = valve_summary["range_ma"]
    return (
        f"  {valve}: {low_ma:.1f}-{high_ma:.1f} mA, std {valve_summary['std_ma']:.2f} mA, "
        f"{100 * valve_summary['clipped_fraction']:.1f} % of samples clipped"
    )


def format_excitation_summary(summary: dict) -> str:
    """The summary as text a person reads."""
    lines = [
        f"maskless excite: {summary['signal']} on the {summary['plant']} plant's "
        f"{_DRIVE_WORDS[summary['valve_drive']]}, {summary['samples']} samples at "
        f"{summary['sample_period_s']:.4g} s",
        f"  offset {summary['offset_ma']:.1f} mA, amplitude {summary['amplitude_ma']:.1f} mA, "
        f"mean {summary['mean_ma']:.1f} mA",
        f"  std {summary['std_ma']:.2f} mA"
        + (
            f" (A/sqrt(3) = {summary['uniform_theoretical_std_ma']:.2f} mA, Eq. 23)"
            if "uniform_theoretical_std_ma" in summary
            else ""
        ),
        f"  crest factor {summary['crest_factor']:.3f} designed, "
        f"{summary['applied_crest_factor']:.3f} after clipping "
        f"({100 * summary['clipped_fraction']:.1f} % of samples clipped)",
        *(_valve_line(valve, s) for valve, s in summary["valves"].items()),
        f"  head height {summary['head_height_mm']['min']:.2f}-"
        f"{summary['head_height_mm']['max']:.2f} mm; fused estimate error std (from "
        f"t = {summary['estimation_start_s']:g} s) "
        f"{summary['fused_error_std_mm']:.3f} mm",
        f"  wall time {summary['wall_time_s']:.2f} s",
    ]
    if "design" in summary:
        first_s, end_s = summary["design"]["stretch_s"]
        share = summary["design"]["fit_share"]
        rounds = len(summary["design"]["round_start_intervals_ma"])
        lines.append(
            f"  designed {first_s:g}-{end_s:g} s in {rounds} "
            f"rounds from the record before; fit the first {100 * share:g} %, as the recording "
            f"says (maskless identify --method hammerstein fits "
            f"{parts_of_share(share)['estimation']} unless told otherwise)"
        )
    lines.append("Files:")
    lines += [f"  {name}: {path}" for name, path in summary["files"].items()]
    return "\n".join(lines)
