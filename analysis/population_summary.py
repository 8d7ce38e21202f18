"""A population Monte Carlo's figures per controller, from its rows (``analysis/trial_table.py``).

Every figure is over all trials of a controller, settled or not; a trial whose run failed counts
as the worst a trial can be (an infinite error, never within the band, never settled), and is
counted on its own; None in a figure is infinity ("never", "failed").
The median is numpy's; a tail quantile (p90 or p10) is one trial's own value (numpy's
inverted CDF), so a tail of trials that never settled reads "never" instead of a number
interpolated with infinity.
"""

import numpy as np


def summarize_population(rows: list[dict], controllers: list[str], tolerance_m: float) -> dict:
    """Per controller: how many trials, how many failed, and the figures over the rest.

    Args:
        rows: the table's rows (``trial``, ``controller``, ``reachable``, the metrics in mm).
        controllers: in the order to report.
        tolerance_m: the clinical band (m), for the fraction of trials within it.

    Returns:
        {"tolerance_mm", "per_controller": {controller: figures}}; a figure over no trials is None.
    """
    tolerance_mm = tolerance_m * 1e3
    return {
        "tolerance_mm": tolerance_mm,
        "per_controller": {
            controller: _figures([r for r in rows if r["controller"] == controller], tolerance_mm)
            for controller in controllers
        },
    }


def _figures(rows: list[dict], tolerance_mm: float) -> dict:
    figures = _run_figures(rows, tolerance_mm)
    # The same, over the trials whose drawn plant can hold both reference levels at all: what a
    # controller could have done.
    reachable = _run_figures([r for r in rows if r["reachable"]], tolerance_mm)
    figures["reachable_targets_only"] = {
        key: reachable[key]
        for key in (
            "runs",
            "p95_within_tolerance_fraction",
            "p95_abs_error_mm",
            "time_within_tolerance_fraction",
        )
    }
    return figures


def _run_figures(rows: list[dict], tolerance_mm: float) -> dict:
    # A failed run counts as the worst a trial can be (an infinite error, never within the band,
    # never settled): a bar is met by runs, not by their absence.
    p95 = _column(rows, "p95_abs_error_mm", failed=np.inf)
    settle = _column(rows, "settle_time_s", failed=np.inf, missing=np.inf)
    ran = [r for r in rows if not r["error"]]
    return {
        "patients": len({r["trial"] for r in rows}),
        "runs": len(rows),
        "failed": len(rows) - len(ran),
        "unreachable_targets": sum(not r["reachable"] for r in rows),
        "p95_within_tolerance_fraction": _share(p95 <= tolerance_mm),
        "p95_abs_error_mm": _spread(p95, high=True),
        "max_abs_error_mm": _spread(_column(rows, "max_abs_error_mm", failed=np.inf), high=True),
        "rms_error_mm": _spread(_column(rows, "rms_error_mm", failed=np.inf), high=True),
        "time_within_tolerance_fraction": _spread(
            _column(rows, "time_within_tolerance_fraction", failed=0.0), high=False
        ),
        "settled_fraction": _share(np.isfinite(settle)),
        "settle_time_s": _spread(settle, high=True),
        # Over the runs that ran: a failed run has no trajectory to overshoot.
        "overshoot_mm": _spread(_column(ran, "overshoot_mm", failed=np.nan, missing=0.0), True),
        # The safety supervisor: runs that ended with a reason latched, and that held the air.
        "safety_latched_fraction": _share(np.array([bool(r.get("safety_latched")) for r in ran])),
        "safety_held_air_fraction": _share(np.array([bool(r.get("safety_held_air")) for r in ran])),
    }


def _column(rows: list[dict], name: str, failed: float, missing: float = np.inf) -> np.ndarray:
    """``name`` of each row: ``failed`` for a failed run, ``missing`` for an empty cell."""
    return np.array(
        [failed if r["error"] else missing if r[name] is None else r[name] for r in rows],
        dtype=float,
    )


def _share(flags: np.ndarray) -> float | None:
    return float(np.mean(flags)) if flags.size else None


def _spread(values: np.ndarray, high: bool) -> dict:
    """Median, the tail quantile on the bad side (p90 or p10) and the worst.

    Infinity (never settled, or a failed run) reads None.
    """
    if values.size == 0:
        return {"median": None, "p90" if high else "p10": None, "worst": None}
    tail = np.quantile(values, 0.9 if high else 0.1, method="inverted_cdf")
    worst = values.max() if high else values.min()
    return {
        "median": _finite(np.median(values)),
        "p90" if high else "p10": _finite(tail),
        "worst": _finite(worst),
    }


def _finite(value) -> float | None:
    return float(value) if np.isfinite(value) else None


def summary_table(summary: dict) -> str:
    """The summary as a text table, one column per controller (what the CLI prints)."""
    per = summary["per_controller"]
    tolerance = summary["tolerance_mm"]
    lines = [
        ("patients, runs (failed; step out of the valves' reach)", _runs_cell),
        (
            f"runs with p95 within ±{tolerance:g} mm",
            lambda f: _percent(f["p95_within_tolerance_fraction"]),
        ),
        ("p95 |error| median / p90 / worst (mm)", lambda f: _triple(f["p95_abs_error_mm"], "p90")),
        ("max |error| median / p90 / worst (mm)", lambda f: _triple(f["max_abs_error_mm"], "p90")),
        (
            f"time within ±{tolerance:g} mm median / p10 / worst",
            lambda f: _triple(f["time_within_tolerance_fraction"], "p10", percent=True),
        ),
        ("settled at the end", lambda f: _percent(f["settled_fraction"])),
        (
            f"reachable targets only: p95 within ±{tolerance:g} mm",
            lambda f: _percent(f["reachable_targets_only"]["p95_within_tolerance_fraction"]),
        ),
        (
            "settle time median / p90 / worst (s)",
            lambda f: _triple(f["settle_time_s"], "p90", infinite="never"),
        ),
        ("overshoot median / p90 / worst (mm)", lambda f: _triple(f["overshoot_mm"], "p90")),
        (
            "safety supervisor: a reason latched / held the air",
            lambda f: (
                f"{_percent(f['safety_latched_fraction'])} / "
                f"{_percent(f['safety_held_air_fraction'])}"
            ),
        ),
    ]
    width = max(len(label) for label, _ in lines)
    header = " " * width + "".join(f"  {name:>22}" for name in per)
    body = [
        f"{label:<{width}}" + "".join(f"  {cell(figures):>22}" for figures in per.values())
        for label, cell in lines
    ]
    return "\n".join([header, *body])


def _runs_cell(figures: dict) -> str:
    return (
        f"{figures['patients']}, {figures['runs']} ({figures['failed']}; "
        f"{figures['unreachable_targets']})"
    )


def _percent(value: float | None) -> str:
    return "n/a" if value is None else f"{100 * value:.1f} %"


def _triple(spread: dict, tail: str, percent: bool = False, infinite: str = "failed") -> str:
    def cell(value):
        if value is None:
            return infinite
        return f"{100 * value:.0f}%" if percent else f"{value:.2f}"

    return " / ".join(cell(spread[key]) for key in ("median", tail, "worst"))
