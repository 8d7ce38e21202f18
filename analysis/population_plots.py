"""The population Monte Carlo's plot: CDFs across patients and the worst trials' traces."""

from pathlib import Path

import numpy as np


def worst_trials(rows: list[dict], controller: str, count: int) -> list[tuple[int, int]]:
    """(trial, run) of the ``count`` runs of ``controller`` with the largest p95 error.

    A failed run has no trace to show and is left out.
    """
    ran = [r for r in rows if r["controller"] == controller and not r["error"]]

    def badness(row):
        return np.inf if row["p95_abs_error_mm"] is None else row["p95_abs_error_mm"]

    ranked = sorted(ran, key=lambda r: (-badness(r), r["trial"], r["run"]))
    return [(r["trial"], r["run"]) for r in ranked[:count]]


def _cdf(values, total: int) -> tuple[np.ndarray, np.ndarray]:
    """The empirical CDF of ``values`` among ``total`` trials (those missing never reach it)."""
    x = np.sort(np.asarray(values, dtype=float))
    return x, np.arange(1, x.size + 1) / max(total, 1)


def plot_population(
    path: str | Path,
    rows: list[dict],
    controllers: list[str],
    traces: dict[str, list[tuple[int, np.ndarray, np.ndarray]]],
    tolerance_m: float,
) -> Path:
    """Writes the plot to ``path`` (PNG) and returns it.

    Top: CDF across trials of the p95 |error| (log scale) and of the time within the band, one
    line per controller. Below: per controller, head - reference of its worst trials against time
    from the judged step.

    Args:
        path: the PNG to write.
        rows: the sweep's rows.
        controllers: in the order to draw.
        traces: controller -> [((trial, run), time from the step (s), error (mm))].
        tolerance_m: the clinical band (m).
    """
    from matplotlib.figure import Figure

    tolerance_mm = tolerance_m * 1e3
    figure = Figure(figsize=(12, 8), layout="constrained")
    grid = figure.add_gridspec(2, max(2, len(controllers)))
    p95_axes = figure.add_subplot(grid[0, 0])
    within_axes = figure.add_subplot(grid[0, 1:])
    for controller in controllers:
        mine = [r for r in rows if r["controller"] == controller]
        ran = [r for r in mine if not r["error"]]
        # A failed run counts: never within the band, and off the p95 curve, which stops short of 1.
        failed = f", {len(mine) - len(ran)} failed" if len(ran) < len(mine) else ""
        p95 = [max(r["p95_abs_error_mm"], 1e-3) for r in ran if r["p95_abs_error_mm"] is not None]
        p95_axes.step(
            *_cdf(p95, len(mine)), where="post", label=f"{controller} ({len(mine)} trials{failed})"
        )
        within = [
            0.0 if r["error"] else 100 * r["time_within_tolerance_fraction"]
            for r in mine
            if r["error"] or r["time_within_tolerance_fraction"] is not None
        ]
        within_axes.step(*_cdf(within, len(mine)), where="post", label=controller)
    p95_axes.axvline(tolerance_mm, color="tab:red", ls="--", label=f"{tolerance_mm:g} mm")
    p95_axes.set_xscale("log")
    p95_axes.set_xlabel("p95 |head - reference| over the judged window (mm)")
    p95_axes.set_ylabel("fraction of trials")
    p95_axes.set_title("CDF of the p95 error across patients")
    within_axes.set_xlabel(f"time within ±{tolerance_mm:g} mm over the judged window (%)")
    within_axes.set_ylabel("fraction of trials")
    within_axes.set_title("CDF of the time a beam could be on")
    for axes in (p95_axes, within_axes):
        axes.grid(alpha=0.3)
        axes.legend(fontsize=8)
    for column, controller in enumerate(controllers):
        axes = figure.add_subplot(grid[1, column])
        reachable = {
            (r["trial"], r["run"]): r["reachable"] for r in rows if r["controller"] == controller
        }
        for (trial, run), times_s, error_mm in traces.get(controller, []):
            name = f"trial {trial}" + (f", run {run}" if run else "")
            note = "" if reachable.get((trial, run), True) else ", target out of its reach"
            axes.plot(times_s, error_mm, lw=0.7, label=f"{name}{note}")
        axes.axhspan(-tolerance_mm, tolerance_mm, color="tab:green", alpha=0.15)
        axes.axvline(0.0, color="grey", lw=0.8)
        axes.set_title(f"{controller}: its worst trials by p95")
        axes.set_xlabel("time from the judged step (s)")
        axes.set_ylabel("head - reference (mm)")
        axes.grid(alpha=0.3)
        if traces.get(controller):
            axes.legend(fontsize=7)
    path = Path(path)
    figure.savefig(path, dpi=100)
    return path
