"""The fault matrix as one picture: each figure per case, a dot per seed, the bounds dashed."""

from pathlib import Path

import numpy as np

from maskless.analysis.fault_matrix_summary import (
    BEAM_ON_OFF_TARGET_MAX_FRACTION,
    BOTH_CAMERAS_SAFE_STATE_MAX_S,
    ONE_CAMERA_DETECTION_MAX_S,
)

# (row key, axis label, scale to the plotted unit, the bound in that unit or None)
_PANELS = (
    (
        "detection_latency_s",
        "detection latency (s)\n(bound: one camera)",
        1.0,
        ONE_CAMERA_DETECTION_MAX_S,
    ),
    (
        "safe_state_latency_s",
        "time to the safe state (s)\n(bound: every camera lost)",
        1.0,
        BOTH_CAMERAS_SAFE_STATE_MAX_S,
    ),
    ("worst_excursion_mm", "worst head excursion\nafter the fault (mm)", 1.0, None),
    (
        "beam_on_while_off_target_fraction",
        "beam on while |error| > 1 mm\n(% of the run)",
        100.0,
        100.0 * BEAM_ON_OFF_TARGET_MAX_FRACTION,
    ),
    ("beam_held_while_on_target_fraction", "beam held needlessly\n(% of the run)", 100.0, None),
)


def plot_fault_matrix(path: str | Path, rows: list[dict], cases: list[str], summary: dict) -> Path:
    """Writes the plot to ``path`` (PNG) and returns it.

    One panel per figure, the cases along the bottom; a case whose runs never gave the figure
    (never detected, say) shows "none" at its place. Runs that raised are counted in the title.
    """
    from matplotlib.figure import Figure

    figure = Figure(figsize=(13, 12), layout="constrained")
    axes = figure.subplots(len(_PANELS), 1, sharex=True)
    positions = np.arange(len(cases))
    for axis, (key, label, scale, bound) in zip(axes, _PANELS, strict=True):
        for x, case in zip(positions, cases, strict=True):
            values = [
                scale * row[key] for row in rows if row["case"] == case and row[key] is not None
            ]
            if values:
                jitter = np.linspace(-0.2, 0.2, len(values)) if len(values) > 1 else [0.0]
                axis.plot(
                    x + np.asarray(jitter), values, "o", color=f"C{x % 10}", markersize=3, alpha=0.6
                )
            else:
                axis.annotate("none", (x, 0.5), xycoords=("data", "axes fraction"), ha="center")
        if bound is not None:
            axis.axhline(bound, color="k", linestyle="--", linewidth=0.8)
        axis.set_ylabel(label)
        axis.grid(True, axis="y", alpha=0.3)
    axes[-1].set_xticks(positions, cases, rotation=30, ha="right")
    errors = sum(f["errors"] for f in summary["cases"].values())
    met = sum(t["met"] for t in summary["targets"])
    figure.suptitle(
        f"Fault matrix: {len(cases)} cases x {summary['seeds']} seeds, {errors} runs raised; "
        f"targets met {met} of {len(summary['targets'])} (dashed: the issue's bounds)"
    )
    figure.savefig(path, dpi=90)
    return Path(path)
