"""Plots of a closed-loop run, in mm and mA (what clinicians and valve datasheets use)."""

from pathlib import Path

import numpy as np

from maskless.systems.units import a_to_ma, m_to_mm

# More points than a figure's pixels only slows rendering; keep every n-th sample past this.
_MAX_POINTS = 4000


def _thin(times, values):
    """At most ``_MAX_POINTS`` samples, evenly spread, the first and the last kept."""
    if len(times) <= _MAX_POINTS:
        return times, values
    kept = np.linspace(0, len(times) - 1, _MAX_POINTS).round().astype(int)
    return times[kept], values[..., kept]


def plot_closed_loop(
    path: str | Path,
    *,
    times_s: np.ndarray,
    reference_m: np.ndarray,
    head_m: np.ndarray,
    local_tracks_m: dict[str, np.ndarray],
    fused_m: np.ndarray,
    command_times_s: np.ndarray,
    command_a: np.ndarray,
    title: str,
    outlet_command_a: np.ndarray | None = None,
    tolerance_m: float | None = None,
) -> Path:
    """Heights above the valve commands, on a shared time axis; returns the written path.

    The heights are the reference, the true head, each local track and the fused track; the valve
    commands are the inlet's, and the outlet's when given. All height arrays are sampled at
    ``times_s``.
    """
    # Imported here: matplotlib is a third of the command's start-up, and `maskless simulate`
    # renders in a second process. A bare Figure needs no GUI backend and no pyplot.
    from matplotlib.figure import Figure

    path = Path(path)
    figure = Figure(figsize=(10, 6.5), layout="constrained")
    heights, command = figure.subplots(2, 1, sharex=True, height_ratios=[3, 1])
    for name, track in local_tracks_m.items():
        heights.plot(
            *_thin(times_s, m_to_mm(track)), lw=0.7, alpha=0.6, label=f"{name} local track"
        )
    heights.plot(*_thin(times_s, m_to_mm(fused_m)), lw=1.0, color="tab:purple", label="fused track")
    heights.plot(*_thin(times_s, m_to_mm(head_m)), lw=1.8, color="black", label="true head height")
    heights.plot(
        *_thin(times_s, m_to_mm(reference_m)), lw=1.4, ls="--", color="tab:red", label="reference"
    )
    if tolerance_m is not None:
        t, r = _thin(times_s, m_to_mm(reference_m))
        band = m_to_mm(tolerance_m)
        heights.fill_between(
            t,
            r - band,
            r + band,
            color="tab:red",
            alpha=0.08,
            step="post",
            label=f"±{band:g} mm band",
        )
    heights.set_ylabel("height above table (mm)")
    heights.set_title(title)
    heights.legend(loc="best", fontsize=8, ncol=2)
    heights.grid(alpha=0.3)
    command.step(
        *_thin(command_times_s, a_to_ma(command_a)), where="post", color="tab:green", label="inlet"
    )
    if outlet_command_a is not None:
        command.step(
            *_thin(command_times_s, a_to_ma(outlet_command_a)),
            where="post",
            color="tab:orange",
            label="outlet",
        )
        command.legend(loc="best", fontsize=8)
    command.set_ylabel("valve current (mA)")
    command.set_xlabel("time (s)")
    command.grid(alpha=0.3)
    figure.savefig(path, dpi=110)
    return path
