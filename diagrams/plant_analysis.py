"""Analyses of the pneumatic plant and the controllers, as `maskless analyze` reports them.

They are the operating range (steady lift, pressure, gain and time constants per valve current)
and loop stability (poles and margins of both controllers, against lift, head mass and latency).

The computations are in ``analysis.operating_range`` and ``analysis.stability``; this module
builds their inputs from a scenario, turns the results into JSON-ready reports and text, and
writes the files.
"""

import dataclasses
import json
import math
from dataclasses import dataclass
from pathlib import Path

from maskless.diagrams.output_folder import output_folder
from maskless.diagrams.request_labels import LabelledRequest
from maskless.diagrams.scenario import Scenario
from maskless.errors import ConfigError
from maskless.systems.limits import HEAD_MASS_KG, LATENCY_S, OPERATING_RANGE_POINTS

# The sensor latency the controller must tolerate (issue 5: "up to 100 ms").
LATENCY_REQUIREMENT_S = 0.1
# Rows of a sweep the text summary shows (the JSON has them all).
_SUMMARY_ROWS = 8


@dataclass(frozen=True)
class StabilityRequest(LabelledRequest):
    """Where the offset-free LQG's loop is judged; checked when made.

    Attributes:
        lifts_m: lifts the head rests at (m).
        mass_factors: head masses as factors on the scenario's head; 1 is always included.
        extra_latency_ticks: sensor latency beyond the designed-for delay (controller ticks); 0 is
            always included.
        labels: see ``LabelledRequest``.
    """

    lifts_m: tuple[float, ...] = (0.002, 0.005, 0.009, 0.013)
    mass_factors: tuple[float, ...] = (0.8, 1.2)
    extra_latency_ticks: tuple[int, ...] = (1, 2)

    def __post_init__(self):
        """Raises ConfigError for the first field out of range, named as the user named it."""
        label = self.label
        if not self.lifts_m or not all(math.isfinite(lift) for lift in self.lifts_m):
            raise ConfigError(f"{label('lifts_m')} {self.lifts_m}: expected finite lifts")
        if not all(math.isfinite(f) and f > 0 for f in self.mass_factors):
            raise ConfigError(
                f"{label('mass_factors')} {self.mass_factors}: expected positive factors"
            )
        if not all(isinstance(t, int) and t >= 0 for t in self.extra_latency_ticks):
            raise ConfigError(
                f"{label('extra_latency_ticks')} {self.extra_latency_ticks}: expected whole "
                "ticks >= 0"
            )


# --- operating-range ------------------------------------------------------------------------------


def analyze_operating_range(
    scenario: Scenario,
    points: int = 22,
    out: str | Path | None = None,
    points_label: str = "points",
):
    """Sweeps each valve's current: steady lift, pressure, and Drake's linearisation there.

    Each valve takes ``points`` currents from starting to saturation (the inlet with the outlet
    shut; the outlet with the inlet fully open). Returns the JSON-ready report; with ``out``, also
    writes OUT/operating_range.json and OUT/operating_range.png, named under ``files``.
    ``points_label`` is what the user called ``points`` (a flag), for the message.
    """
    from maskless.analysis.operating_range import default_operating_ranges

    OPERATING_RANGE_POINTS.check(points, points_label)
    ranges = default_operating_ranges(scenario.pneumatic, points)
    report = operating_range_report(ranges)
    if out is not None:
        from maskless.analysis.operating_range_plots import plot_operating_range

        out = output_folder(out)
        plot = plot_operating_range(out / "operating_range.png", ranges)
        report["files"] = {"report": str(out / "operating_range.json"), "plot": str(plot)}
        (out / "operating_range.json").write_text(json.dumps(report, indent=1))
    return report


def operating_range_report(ranges: dict) -> dict:
    """The sweeps as a JSON-ready dict in mA, mm, kPa, mm/mA and s.

    Args:
        ranges: valve -> ``operating_range.OperatingRange``, with "inlet" swept with the outlet
            shut (its lifts are the working range).
    """
    from maskless.analysis.stability.margins import json_safe
    from maskless.systems.units import a_to_ma, m_to_mm

    valves = {}
    for valve, sweep in ranges.items():
        rows = [
            {
                "current_ma": a_to_ma(float(current)),
                "lift_mm": m_to_mm(float(lift)),
                "gauge_pressure_kpa": float(pressure) / 1000.0,
                # None where the head is at or past a travel limit (nothing to linearise).
                "dc_gain_mm_per_ma": json_safe(gain),
                "slow_time_constant_s": json_safe(taus[0]),
                # The NaN that pads a row with a complex pair is no mode: dropped.
                "time_constants_s": [json_safe(t) for t in taus if not math.isnan(t)],
            }
            for current, lift, pressure, gain, taus in zip(
                sweep.currents_a,
                sweep.lift_m,
                sweep.gauge_pressure_pa,
                sweep.dc_gain_m_per_a,
                sweep.time_constants_s,
                strict=True,
            )
        ]
        valves[valve] = {
            "held_valve": "outlet" if valve == "inlet" else "inlet",
            "held_current_ma": a_to_ma(sweep.held_current_a),
            "lift_span_mm": m_to_mm(sweep.lift_span_m),
            "rows": rows,
        }
    lifts = ranges["inlet"].lift_range_m
    return {
        "valves": valves,
        # None when the inlet holds the head nowhere inside its travel.
        "working_range_mm": [m_to_mm(lift) for lift in lifts] if lifts else None,
        "working_range_note": "steady lifts the inlet holds with the outlet shut, inside the "
        "travel",
    }


def _tidy(value: float, digits: int) -> float:
    """``value`` rounded to ``digits``, with -0 shown as 0 (a pressure of -1e-11 kPa is zero)."""
    return round(value, digits) + 0.0


def _shown_rows(rows: list) -> list:
    """At most ``_SUMMARY_ROWS`` rows, evenly spread, first and last included."""
    if len(rows) <= _SUMMARY_ROWS:
        return rows
    picks = sorted({round(i * (len(rows) - 1) / (_SUMMARY_ROWS - 1)) for i in range(_SUMMARY_ROWS)})
    return [rows[i] for i in picks]


def format_operating_range(report: dict, head_mass_kg: float) -> str:
    """The operating-range report as lines a person reads."""
    lines = [f"maskless analyze operating-range: pneumatic plant, {head_mass_kg:g} kg head", ""]
    for valve, entry in report["valves"].items():
        rows = entry["rows"]
        lines.append(
            f"{valve.capitalize()} swept {rows[0]['current_ma']:.0f}-{rows[-1]['current_ma']:.0f} "
            f"mA, {entry['held_valve']} held at {entry['held_current_ma']:.0f} mA: lift "
            f"{rows[0]['lift_mm']:.2f} to {rows[-1]['lift_mm']:.2f} mm "
            f"(span {entry['lift_span_mm']:.2f} mm inside the travel)"
        )
        lines.append("   current    lift   gauge    DC gain   slow tau")
        lines.append("      (mA)    (mm)   (kPa)    (mm/mA)        (s)")
        for row in _shown_rows(rows):
            steady = f"    {row['current_ma']:6.1f}  {_tidy(row['lift_mm'], 2):6.2f}"
            steady += f"  {_tidy(row['gauge_pressure_kpa'], 3):6.3f}"
            if row["dc_gain_mm_per_ma"] is None:
                lines.append(f"{steady}  past the travel: held by the stop")
                continue
            lines.append(
                f"{steady}  {row['dc_gain_mm_per_ma']:+9.4f}  {row['slow_time_constant_s']:9.2f}"
            )
        lines.append("")
    if report["working_range_mm"] is None:
        lines.append("Working range (inlet, outlet shut): none inside the travel")
    else:
        low, high = report["working_range_mm"]
        lines.append(f"Working range (inlet, outlet shut): {low:.2f} to {high:.2f} mm of lift")
    lines += _files_lines(report)
    return "\n".join(lines)


# --- stability ------------------------------------------------------------------------------------


def offset_free_setup(config):
    """(nominal parameters, allocation, design) of the offset-free LQG for the pneumatic plant.

    As ``closed_loop.build_closed_loop`` designs it: the nominal head's parameters and their
    Hammerstein inverse (``NominalPneumatic``), the plant linearised at the configured operating
    lift, and the measurement delay of the configured cameras.
    """
    from maskless.diagrams.controller_design import (
        NominalPneumatic,
        pneumatic_offset_free_design,
    )

    nominal = NominalPneumatic.of(config)
    return nominal.parameters, nominal.allocation, pneumatic_offset_free_design(config, nominal)


def _poles(poles) -> list[list[float]]:
    return [[float(z.real), float(z.imag)] for z in poles]


def _paper_report(paper) -> dict:
    margins = paper.loop.margins
    # |S - 1| = |L / (1 + L)| <= max|L| / (1 - max|L|): how much feedback changes the response.
    change = paper.peak_loop_gain / (1.0 - paper.peak_loop_gain)
    return {
        "model": "the paper's identified model (Eq. 26) and LQG gains (Eq. 29-34)",
        "sample_period_s": paper.loop.plant.sample_period_s,
        "open_loop_poles": _poles(paper.open_loop_poles),
        "regulator_poles": _poles(paper.regulator_poles),
        "estimator_poles": _poles(paper.estimator_poles),
        "closed_loop_poles": _poles(paper.loop.poles),
        "regulator_pole_shift": paper.regulator_pole_shift,
        "max_pole_magnitude": paper.loop.max_pole_magnitude,
        "stable": paper.loop.stable,
        "peak_loop_gain": paper.peak_loop_gain,
        "peak_loop_gain_frequency_rad_s": paper.peak_loop_gain_frequency_rad_s,
        "max_response_change_percent": 100.0 * change,
        "margins": margins.as_dict(),
        "verdict": (
            f"max |L| = {paper.peak_loop_gain:.2e}: feedback changes the head's response by at "
            f"most {100.0 * change:.1e} % and moves the plant's poles by "
            f"{paper.regulator_pole_shift:.1e}; the loop is nearly open"
        ),
    }


def _case_report(case, latency_requirement_s: float) -> dict:
    from maskless.systems.units import a_to_ma, m_to_mm

    valves = case.operating_point.valves
    margins = case.analysis.margins
    return {
        "lift_mm": m_to_mm(case.lift_m),
        "mass_factor": case.mass_factor,
        "head_mass_kg": case.head_mass_kg,
        "extra_latency_ticks": case.extra_delay_samples,
        "extra_latency_s": case.extra_delay_s,
        "command_mm": m_to_mm(case.operating_point.command_m),
        "valve": valves.valve,
        "inlet_current_ma": a_to_ma(valves.inlet_current_a),
        "outlet_current_ma": a_to_ma(valves.outlet_current_a),
        "stable": case.analysis.stable,
        "max_pole_magnitude": case.analysis.max_pole_magnitude,
        "poles": _poles(case.analysis.poles),
        "margins": margins.as_dict(),
        "delay_margin_exceeds_requirement": bool(margins.delay_margin_s > latency_requirement_s),
    }


def stability_report(paper, cases, design, plant_head_mass_kg: float) -> dict:
    """The stability analysis as a JSON-ready dict.

    Values are SI, with mm, mA, dB and degrees where the field name says so.

    Args:
        paper: ``loop_robustness.analyze_paper_loop``.
        cases: ``loop_robustness.robustness_cases``.
        design: the offset-free LQG design the cases close the loop with.
        plant_head_mass_kg: the configured plant's head mass, which the mass factors scale (kg).
    """
    from maskless.analysis.stability.margins import json_safe
    from maskless.systems.units import m_to_mm

    model = design.model
    period = model.sample_period_s
    delay = design.measurement_delay_samples
    entries = [_case_report(case, LATENCY_REQUIREMENT_S) for case in cases]
    margins = [case.analysis.margins for case in cases]
    return {
        "paper_lqg": _paper_report(paper),
        "offset_free_lqg": {
            "design": {
                "operating_lift_mm": m_to_mm(model.operating_input),
                "sample_period_s": period,
                "measurement_delay_ticks": delay,
                "measurement_delay_s": delay * period,
            },
            "plant_head_mass_kg": plant_head_mass_kg,
            "latency_requirement_s": LATENCY_REQUIREMENT_S,
            "all_stable": all(entry["stable"] for entry in entries),
            "min_gain_margin_db": json_safe(min(m.gain_margin_db for m in margins)),
            "min_phase_margin_deg": json_safe(min(m.phase_margin_deg for m in margins)),
            "min_delay_margin_s": json_safe(min(m.delay_margin_s for m in margins)),
            "max_pole_magnitude": max(case.analysis.max_pole_magnitude for case in cases),
            "cases": entries,
        },
    }


def _shown(value, fmt: str) -> str:
    """A JSON number as text: "inf" (no crossing) as "none"."""
    return "none" if value in ("inf", None) else format(value, fmt)


def _paper_lines(paper: dict) -> list[str]:
    ol = paper["open_loop_poles"][0]
    estimator = ", ".join(f"{re:.3f}" for re, _ in paper["estimator_poles"])
    margins = paper["margins"]
    gain_margin = _shown(margins["gain_margin_db"], ".1f")
    if margins["phase_margin_deg"] == "inf":
        phase_margin = "none (|L| never reaches 1)"
    else:
        phase_margin = f"{margins['phase_margin_deg']:.1f} deg"
    return [
        f"Paper LQG on the paper's model (Eq. 26, Ts {paper['sample_period_s']:g} s)",
        f"  open-loop poles {ol[0]:.5f} ± {abs(ol[1]):.5f}j; the regulator moves them by "
        f"{paper['regulator_pole_shift']:.1e}; estimator poles {estimator}",
        f"  max |L| {paper['peak_loop_gain']:.2e} at {paper['peak_loop_gain_frequency_rad_s']:.3f} "
        f"rad/s; gain margin {gain_margin} dB; phase margin {phase_margin}",
        f"  {paper['verdict']}",
    ]


def format_stability(report: dict) -> str:
    """The stability report as lines a person reads.

    One row per lift and head mass, the margins at each extra latency side by side.
    """
    o = report["offset_free_lqg"]
    d = o["design"]
    groups: dict[tuple, list] = {}
    for case in o["cases"]:
        groups.setdefault((case["lift_mm"], case["mass_factor"]), []).append(case)
    latencies = " / ".join(
        f"+{1000 * c['extra_latency_s']:.0f}" for c in next(iter(groups.values()))
    )
    lines = [
        "maskless analyze stability",
        "",
        *_paper_lines(report["paper_lqg"]),
        "",
        f"Offset-free LQG (designed at {d['operating_lift_mm']:g} mm lift for the nominal head, "
        f"{d['measurement_delay_ticks']}-tick ({1000 * d['measurement_delay_s']:.0f} ms) "
        f"measurement delay, Ts {d['sample_period_s']:.4f} s) on the linearised pneumatic plant;",
        f"margins at {latencies} ms of extra sensor latency",
        f"  {'lift mm':>7}  {'head (kg)':<10} {'valve':<6}  {'max|pole|':<9}  {'GM (dB)':<18}  "
        f"{'PM (deg)':<21}  delay margin (s)",
    ]
    for (lift_mm, factor), cases in groups.items():
        unstable = [f"+{1000 * c['extra_latency_s']:.0f} ms" for c in cases if not c["stable"]]
        flag = f"  UNSTABLE at {', '.join(unstable)}" if unstable else ""

        def column(name, fmt, cases=cases):
            return " / ".join(_shown(c["margins"][name], fmt) for c in cases)

        lines.append(
            f"  {lift_mm:7.1f}  {cases[0]['head_mass_kg']:.2f} x{factor:<4g} "
            f"{cases[0]['valve']:<6}  {max(c['max_pole_magnitude'] for c in cases):<9.5f}  "
            f"{column('gain_margin_db', '.1f'):<18}  {column('phase_margin_deg', '.1f'):<21}  "
            f"{column('delay_margin_s', '.2f')}{flag}"
        )
    unstable = sum(not case["stable"] for case in o["cases"])
    verdict = "all stable" if unstable == 0 else f"{unstable} UNSTABLE"
    lines += [
        f"  {len(o['cases'])} cases, {verdict}; worst: GM {_shown(o['min_gain_margin_db'], '.1f')}"
        f" dB, PM {_shown(o['min_phase_margin_deg'], '.1f')} deg, delay margin "
        f"{_shown(o['min_delay_margin_s'], '.2f')} s (requirement: "
        f"{1000 * o['latency_requirement_s']:.0f} ms of latency), max |pole| "
        f"{o['max_pole_magnitude']:.5f}",
    ]
    lines += _files_lines(report)
    return "\n".join(lines)


def _checked_cases(scenario: Scenario, request: StabilityRequest, allocation):
    """(lifts (m), mass factors, extra latencies (ticks)) of ``request``, with 1 and 0 added.

    Refused where a head cannot rest at a lift.
    """
    from maskless.analysis.stability.loop_robustness import holdable_lift_range_m
    from maskless.systems.units import m_to_mm

    factors = sorted({1.0, *request.mass_factors})
    ticks = sorted({0, *request.extra_latency_ticks})
    p = scenario.pneumatic
    tick_s = scenario.offset_free_lqg.sample_period_s
    for tick in ticks:
        LATENCY_S.check(
            tick * tick_s, f"{request.label('extra_latency_ticks')} {tick} x {tick_s:.4g} s"
        )
    for factor in factors:
        head = dataclasses.replace(p, head_mass_kg=factor * p.head_mass_kg)
        HEAD_MASS_KG.check(
            head.head_mass_kg, f"{request.label('mass_factors')} {factor:g}: head_mass_kg"
        )
        low, high = holdable_lift_range_m(head, allocation)
        # Resting past a travel limit at every command: the bladder cannot carry this head.
        if high <= p.min_lift_m or low >= p.max_lift_m:
            raise ConfigError(
                f"{request.label('mass_factors')} {request.mass_factors}: a "
                f"{head.head_mass_kg:.2f} kg head (x{factor:g}) cannot be held anywhere in the "
                "bladder's travel"
            )
        for lift in request.lifts_m:
            if not low <= lift <= high:
                raise ConfigError(
                    f"{request.label('lifts_m')}: {m_to_mm(lift):g} mm is out of reach of the "
                    f"{head.head_mass_kg:.2f} kg head (x{factor:g}), which rests between "
                    f"{m_to_mm(low):.2f} and {m_to_mm(high):.2f} mm"
                )
    return list(request.lifts_m), factors, ticks


def analyze_stability(
    scenario: Scenario, request: StabilityRequest | None = None, out: str | Path | None = None
) -> dict:
    """Closed-loop poles and gain, phase and delay margins of both controllers.

    The paper's LQG on the paper's model, and the offset-free LQG (designed as the closed loop
    designs it) on the pneumatic plant linearised at each lift, head mass and extra latency of
    ``request``. Returns the JSON-ready report; with ``out``, also writes OUT/stability.json and
    three plots, named under ``files``.
    """
    from maskless.analysis.stability.loop_robustness import analyze_paper_loop, robustness_cases
    from maskless.systems.control.paper_lqg import paper_lqg

    request = StabilityRequest() if request is None else request
    _, allocation, design = offset_free_setup(scenario)
    lifts, factors, ticks = _checked_cases(scenario, request, allocation)
    paper = analyze_paper_loop(*paper_lqg(scenario.paper))
    cases = robustness_cases(scenario.pneumatic, allocation, design, lifts, factors, ticks)
    report = stability_report(paper, cases, design, scenario.pneumatic.head_mass_kg)
    if out is not None:
        from maskless.analysis.stability.stability_plots import (
            plot_offset_free_loops,
            plot_paper_loop,
            plot_robustness,
        )

        out = output_folder(out)
        report["files"] = {
            "report": str(out / "stability.json"),
            "paper_loop_plot": str(plot_paper_loop(out / "stability_paper_lqg.png", paper)),
            "offset_free_plot": str(
                plot_offset_free_loops(out / "stability_offset_free_lqg.png", cases)
            ),
            "margins_plot": str(
                plot_robustness(out / "stability_margins.png", cases, LATENCY_REQUIREMENT_S)
            ),
        }
        (out / "stability.json").write_text(json.dumps(report, indent=1))
    return report


def _files_lines(report: dict) -> list[str]:
    """The files a report was written to, when it was written (``out`` given)."""
    files = report.get("files", {})
    return ["Files:", *(f"  {kind}: {path}" for kind, path in files.items())] if files else []
