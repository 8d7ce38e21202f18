"""The figures of a closed-loop run, as a JSON-ready dict and as text a person reads.

Reports are in mm, mA and s, the units clinicians and valve datasheets use.
"""

from typing import TYPE_CHECKING

import numpy as np

from maskless.analysis.detection_figures import detection_latency_s, flag_figures, rises
from maskless.analysis.metrics import estimate_error_std_m, tracking_metrics
from maskless.analysis.safety_figures import SafetyLog, safety_figures, time_to_safe_state_s
from maskless.systems.control.offset_free_lqg import closed_loop_poles as offset_free_poles
from maskless.systems.control.paper_lqg import closed_loop_poles
from maskless.systems.control.safety_supervisor import REASONS
from maskless.systems.sensing.fault_detection import FUSION_HEALTH, TRACK_FLAGS
from maskless.systems.units import a_to_ma, m_to_mm

if TYPE_CHECKING:
    from maskless.diagrams.simulation import SimulationRun


def estimation_start_s(config, times_s) -> float:
    """When estimates start to be judged (s).

    That is once the filters have forgotten their initial guess (``metrics.estimation_start_s``),
    or half-way through a shorter run.
    """
    return min(config.metrics.estimation_start_s, float(times_s[-1]) / 2)


def summarize(run: "SimulationRun") -> dict:
    """The run's figures as a JSON-ready dict (mm, mA and s, what people read)."""
    config, loop, s = run.scenario, run.closed_loop, run.signals
    times = s["head_height_m"].times_s
    head, reference = s["head_height_m"].values[0], s["reference_head_height_m"].values[0]
    steps = [t for t in config.reference.step_times_s if t <= times[-1]]
    metrics = tracking_metrics(
        times,
        head,
        reference,
        last_step_time_s=steps[-1] if steps else 0.0,
        tolerance_m=config.metrics.tolerance_m,
        evaluation_delay_s=config.metrics.evaluation_delay_s,
    )
    start = estimation_start_s(config, times)
    estimation = {"evaluation_start_s": start}
    for name in loop.sensor_names:
        track = s[f"{name}_filter.estimated_state"].values[0]
        valid_fraction = float(np.mean(s[f"{name}.valid"].values[0] > 0.5))
        # A track that never saw a frame only replays its initial guess: no error to report.
        estimation[f"{name}_error_std_mm"] = (
            m_to_mm(estimate_error_std_m(times, track, head, start)) if valid_fraction > 0 else None
        )
        estimation[f"{name}_valid_fraction"] = valid_fraction
    fused = s["fusion.estimated_state"].values[0]
    estimation["fused_error_std_mm"] = m_to_mm(estimate_error_std_m(times, fused, head, start))
    estimation["fused_error_mean_mm"] = m_to_mm(
        float(np.mean(fused[times >= start] - head[times >= start]))
    )

    detection = _detection(config, loop, s)
    safety = None
    if "safety.beam_hold" in s:
        log = safety_log(s)
        safety = _safety(config, log)
        for name, fault in detection["faults"].items():
            reason, latency = time_to_safe_state_s(log, config.faults[name].start_s)
            fault["safe_state_reason"], fault["safe_state_latency_s"] = reason, latency
    paper = config.paper
    inlet = s["inlet_valve_current_a"].values[0]
    outlet = s["outlet_valve_current_a"].values[0]
    commands = {
        "inlet_range_ma": [a_to_ma(float(inlet.min())), a_to_ma(float(inlet.max()))],
        "outlet_range_ma": [a_to_ma(float(outlet.min())), a_to_ma(float(outlet.max()))],
    }
    controller = (
        _paper_model_figures(loop, paper, inlet)
        if loop.controller == "paper-lqg"
        else _offset_free_figures(loop)
    )

    def tracking_mm(value):
        # A figure that is no number (a head that went NaN) is reported as none: JSON has no NaN.
        return None if value is None or not np.isfinite(value) else m_to_mm(value)

    return {
        "plant": loop.plant,
        "controller": loop.controller,
        "duration_s": config.duration_s,
        "random_seed": config.random_seed,
        "tracking": {
            "tolerance_mm": m_to_mm(config.metrics.tolerance_m),
            "settled": metrics.settled,
            "settle_time_s": metrics.settle_time_s,
            "window_s": [metrics.window_start_s, metrics.window_end_s],
            "rms_error_mm": tracking_mm(metrics.rms_error_m),
            "p95_abs_error_mm": tracking_mm(metrics.p95_abs_error_m),
            "max_abs_error_mm": tracking_mm(metrics.max_abs_error_m),
            "time_within_tolerance_fraction": metrics.time_within_tolerance_fraction,
            "overshoot_mm": tracking_mm(metrics.overshoot_m),
            "final_error_mm": tracking_mm(metrics.final_error_m),
            "head_travel_mm": m_to_mm(float(head.max() - head.min())),
            "reference_travel_mm": m_to_mm(float(reference.max() - reference.min())),
        },
        "estimation": estimation,
        "fault_detection": detection,
        **({"safety": safety} if safety is not None else {}),
        "valve_commands": commands,
        "paper_model" if loop.controller == "paper-lqg" else "offset_free_lqg": controller,
        "paper_reported": {
            "fused_std_mm": paper.reported_fused_std_mm,
            "tracking_band_mm": paper.reported_tracking_band_mm,
            "overshoot_mm": paper.reported_overshoot_mm,
            "settle_time_s": paper.reported_settle_time_s,
        },
    }


def _detection(config, loop, s) -> dict:
    """When each check fired, and how soon after each injected fault one fired."""
    camera_flags = {
        name: dict(zip(TRACK_FLAGS, s[f"{name}_filter.health"].values, strict=True))
        for name in loop.sensor_names
    }
    fusion = s["fusion.health"]
    tracks_used, *fusion_flags = fusion.values
    fused = dict(zip(FUSION_HEALTH[1:], fusion_flags, strict=True))
    fused["fewer_tracks"] = (tracks_used < len(loop.sensor_names) - 0.5).astype(float)
    faults = {}
    for fault_name, fault in config.faults.items():
        if fault.start_s > fusion.times_s[-1]:
            continue
        # A camera fault may be caught at its camera or at the fusion; a valve fault only there.
        watched = {f"{fault.target}.{k}": v for k, v in camera_flags.get(fault.target, {}).items()}
        watched.update({f"fusion.{k}": v for k, v in fused.items()})
        # The supervisor's own checks (the bladder's pressure) detect what the cameras cannot;
        # its reasons are latched, so each detects when it rises.
        if "safety.reasons" in s:
            watched.update(
                {
                    f"safety.{r}": rises(row)
                    for r, row in zip(REASONS, s["safety.reasons"].values, strict=True)
                }
            )
        flag, latency = detection_latency_s(fusion.times_s, watched, fault.start_s)
        faults[fault_name] = {
            "kind": fault.kind,
            "start_s": fault.start_s,
            "detected_by": flag,
            "latency_s": latency,
        }
    return {
        "cameras": {
            name: flag_figures(s[f"{name}_filter.health"].times_s, flags)
            for name, flags in camera_flags.items()
        },
        "fusion": {
            **flag_figures(fusion.times_s, fused),
            "fewest_tracks_used": int(round(float(tracks_used.min()))),
        },
        "faults": faults,
    }


def safety_log(s: dict) -> SafetyLog:
    """The supervisor's logged signals with the truth it is judged against."""
    pressure = s.get("plant.bladder_gauge_pressure_pa")
    return SafetyLog(
        times_s=s["safety.beam_hold"].times_s,
        head_height_m=s["head_height_m"].values[0],
        reference_m=s["reference_head_height_m"].values[0],
        beam_hold=s["safety.beam_hold"].values[0],
        reasons=s["safety.reasons"].values,
        mode=s["safety.mode"].values[0],
        inlet_a=s["safety.inlet_valve_current_a"].values[0],
        outlet_a=s["safety.outlet_valve_current_a"].values[0],
        gauge_pressure_pa=None if pressure is None else pressure.values[0],
    )


def _safety(config, log: SafetyLog) -> dict:
    """The supervisor's figures."""
    return {
        "tolerance_mm": m_to_mm(config.metrics.tolerance_m),
        "max_gauge_pressure_limit_kpa": config.safety.max_gauge_pressure_pa / 1e3,
        **safety_figures(log, config.metrics.tolerance_m),
    }


def summary_with_timing(run: "SimulationRun") -> dict:
    """``run.metrics`` and how long the run took (which depends on the machine, not the run)."""
    timing = {"wall_time_s": run.wall_time_s, "real_time_factor": run.real_time_factor}
    return {**run.metrics, "timing": timing}


def _paper_model_figures(loop, paper, command) -> dict:
    """Why the paper's LQG cannot move the head: its model's gain and its poles."""
    model, design = loop.model, loop.design
    # The model's output is a distance below the camera; the head rises as it shrinks.
    lift_gain_mm_per_ma = -m_to_mm(model.dc_gain()) / a_to_ma(1.0)
    lift_limits = [
        lift_gain_mm_per_ma * (current - paper.operating_current_ma)
        for current in (0.0, paper.valve_saturation_current_ma)
    ]
    poles = closed_loop_poles(model, design)
    return {
        "lift_gain_mm_per_ma": lift_gain_mm_per_ma,
        "steady_lift_range_mm": sorted(lift_limits),
        "lqr_gain_ma_per_mm": (design.K[0] * a_to_ma(1.0) / m_to_mm(1.0)).tolist(),
        "open_loop_pole_magnitudes": np.abs(poles["open_loop"]).tolist(),
        "regulator_pole_magnitudes": np.abs(poles["regulator"]).tolist(),
        "estimator_pole_magnitudes": np.abs(poles["estimator"]).tolist(),
        "command_range_ma": [a_to_ma(float(command.min())), a_to_ma(float(command.max()))],
        "operating_current_ma": paper.operating_current_ma,
        "valve_range_ma": [0.0, paper.valve_saturation_current_ma],
    }


def _offset_free_figures(loop) -> dict:
    """The offset-free design's model and poles."""
    poles = offset_free_poles(loop.design)
    return {
        "model_order": int(loop.model.A.shape[0]),
        "sample_period_s": loop.model.sample_period_s,
        "model_dc_gain": loop.model.dc_gain(),
        "regulator_pole_magnitudes": np.abs(poles["regulator"]).tolist(),
        "estimator_pole_magnitudes": np.abs(poles["estimator"]).tolist(),
    }


def tracking_lines(t: dict) -> list[str]:
    """The tracking figures of a summary (its "tracking" section) as lines a person reads."""
    band = t["tolerance_mm"]
    start_s, end_s = t["window_s"]
    settle = (
        f"settled within ±{band:g} mm after {t['settle_time_s']:.2f} s"
        if t["settled"]
        else f"NOT within ±{band:g} mm at the end"
    )
    if t["p95_abs_error_mm"] is None:
        window = [
            f"no tracking window: it starts at t = {start_s:g} s, after the run ends at {end_s:g} s"
        ]
    else:
        window = [
            f"from t = {start_s:g} to {end_s:g} s: within ±{band:g} mm "
            f"{100 * t['time_within_tolerance_fraction']:.1f} % of the time; "
            f"RMS {t['rms_error_mm']:.3f} mm, p95 {t['p95_abs_error_mm']:.3f} mm, "
            f"max {t['max_abs_error_mm']:.3f} mm"
        ]
    overshoot = (
        "n/a (no reference step)" if t["overshoot_mm"] is None else f"{t['overshoot_mm']:.3f} mm"
    )
    return [
        f"{settle}; final error {t['final_error_mm']:+.3f} mm",
        *window,
        f"overshoot {overshoot}; the reference moved "
        f"{t['reference_travel_mm']:.2f} mm, the head {t['head_travel_mm']:.4f} mm",
    ]


def format_summary(summary: dict) -> str:
    """The summary as lines a person reads."""
    t, e = summary["tracking"], summary["estimation"]
    reported = summary["paper_reported"]
    lines = [
        f"maskless simulate: plant '{summary['plant']}', controller '{summary['controller']}', "
        f"{summary['duration_s']:g} s simulated, seed {summary['random_seed']}",
        "",
        "Tracking (true head height vs reference)",
        *(f"  {line}" for line in tracking_lines(t)),
        f"  the paper reports ±{reported['tracking_band_mm']:g} mm tracking, "
        f"{reported['overshoot_mm']:g} mm overshoot and ~{reported['settle_time_s']:g} s settling "
        "on its bench",
        "",
        f"Estimation (estimate - true head height, std, from t = {e['evaluation_start_s']:.0f} s)",
    ]
    for key, value in e.items():
        if key.endswith("_error_std_mm"):
            name = key.removesuffix("_error_std_mm")
            valid = e.get(f"{name}_valid_fraction")
            extra = f" ({100 * valid:.2f} % valid frames)" if valid is not None else ""
            shown = "no valid frames" if value is None else f"{value:.3f} mm"
            lines.append(f"  {name:<10} {shown}{extra}")
    lines.append(
        f"  fused mean error {e['fused_error_mean_mm']:+.3f} mm; the paper reports a fused std "
        f"of at most {reported['fused_std_mm']:g} mm"
    )
    lines += _format_detection(summary["fault_detection"])
    if "safety" in summary:
        lines += _format_safety(summary["safety"])
    c = summary["valve_commands"]
    lines += [
        "",
        f"Valve commands: inlet {c['inlet_range_ma'][0]:.1f}-{c['inlet_range_ma'][1]:.1f} mA, "
        f"outlet {c['outlet_range_ma'][0]:.1f}-{c['outlet_range_ma'][1]:.1f} mA",
    ]
    if "paper_model" in summary:
        lines += _format_paper_model(summary["paper_model"])
    else:
        o = summary["offset_free_lqg"]
        lines += [
            f"Offset-free LQG on an order-{o['model_order']} model at "
            f"{o['sample_period_s']:.4f} s: pole magnitudes regulator "
            f"{_poles(o['regulator_pole_magnitudes'])}, estimator "
            f"{_poles(o['estimator_pole_magnitudes'])}",
        ]
    if "timing" in summary:
        timing = summary["timing"]
        lines += [
            "",
            f"Wall time {timing['wall_time_s']:.3f} s "
            f"({timing['real_time_factor']:.0f}x real time)",
        ]
    if "files" in summary:
        lines += ["Files:"] + [f"  {kind}: {path}" for kind, path in summary["files"].items()]
    return "\n".join(lines)


def _format_detection(d: dict) -> list[str]:
    """The checks that fired (none: one line), and each fault's detection."""
    fired = [
        f"  {where} {flag}: first at {f['first_set_s']:.2f} s, "
        f"{100 * f['set_fraction']:.1f} % of the run"
        for where, flags in [*d["cameras"].items(), ("fusion", d["fusion"])]
        for flag, f in flags.items()
        if isinstance(f, dict) and f["first_set_s"] is not None
    ]
    lines = ["", "Fault detection" + ("" if fired else ": no check fired")]
    lines += fired
    for name, fault in d["faults"].items():
        found = (
            f"detected by {fault['detected_by']} after {fault['latency_s']:.2f} s"
            if fault["detected_by"]
            else "NOT detected"
        )
        safe = ""
        if fault.get("safe_state_reason"):
            safe = (
                f"; safe state ({fault['safe_state_reason']}) after "
                f"{fault['safe_state_latency_s']:.2f} s"
            )
        elif "safe_state_reason" in fault:
            safe = "; no safe state"
        lines.append(
            f"  fault {name!r} ({fault['kind']} from {fault['start_s']:g} s): {found}{safe}"
        )
    return lines


def _format_safety(f: dict) -> list[str]:
    """The supervisor's state at the end, what it latched and did, and the beam's times."""
    latched = ", ".join(f["latched_at_end"]) or "nothing latched"
    lines = ["", f"Safety: {f['state_at_end']} at the end ({latched})"]
    lines += [
        f"  {e['reason']} at {e['first_s']:.2f} s: {_ACTION_WORDS[e['action']]}"
        for e in f["events"]
    ]
    band = f["tolerance_mm"]
    lines.append(
        f"  beam held {100 * f['beam_hold_fraction']:.1f} % of the run ({f['beam_hold_s']:.1f} s), "
        f"on {f['beam_on_s']:.1f} s; on while the head was beyond ±{band:g} mm: "
        f"{f['beam_on_while_off_target_s']:.3f} s; held while it was within: "
        f"{f['beam_held_while_on_target_s']:.1f} s"
    )
    if "max_gauge_pressure_kpa" in f:
        lines.append(
            f"  bladder pressure at most {f['max_gauge_pressure_kpa']:.2f} kPa "
            f"(limit {f['max_gauge_pressure_limit_kpa']:g} kPa)"
        )
    return lines


# What each safe action does, as the summary says it.
_ACTION_WORDS = {
    "continue": "the loop goes on, the beam held",
    "hold": "the valves hold their currents, the beam held",
    "vent": "the bladder vents to its resting height, the beam held",
}


def _format_paper_model(p: dict) -> list[str]:
    lo, hi = p["steady_lift_range_mm"]
    valve_lo, valve_hi = p["valve_range_ma"]
    return [
        "",
        "Why the paper's loop cannot track (its own model, Eq. 26)",
        f"  steady-state lift {p['lift_gain_mm_per_ma']:.3e} mm/mA: the whole valve range "
        f"({valve_lo:g}-{valve_hi:g} mA) holds the head between {lo:+.4f} and {hi:+.4f} mm of "
        "its start",
        f"  LQR gain K = [{p['lqr_gain_ma_per_mm'][0]:.4f}, "
        f"{p['lqr_gain_ma_per_mm'][1]:.4f}] mA/mm; "
        f"pole magnitudes open loop {_poles(p['open_loop_pole_magnitudes'])}, "
        f"with LQR {_poles(p['regulator_pole_magnitudes'])}",
        f"  command stayed in [{p['command_range_ma'][0]:.3f}, {p['command_range_ma'][1]:.3f}] mA "
        f"around the operating point {p['operating_current_ma']:.2f} mA",
    ]


def _poles(magnitudes) -> str:
    return "[" + ", ".join(f"{m:.6f}" for m in magnitudes) + "]"
