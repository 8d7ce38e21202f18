"""Plots of the loops' stability: poles, Bode plots and margins, in mm, s, dB and degrees."""

from pathlib import Path

import numpy as np

from maskless.analysis.stability.loop_robustness import PaperLoopAnalysis, RobustnessCase
from maskless.systems.units import m_to_mm

# Bode plots span this many decades below the Nyquist frequency.
_BODE_DECADES = 5
_BODE_POINTS = 1200


def _figure(size):
    # A bare Figure needs no GUI backend and no pyplot; matplotlib is imported only to plot.
    from matplotlib.figure import Figure

    return Figure(figsize=size, layout="constrained")


def _unit_circle(axis):
    theta = np.linspace(0.0, 2.0 * np.pi, 721)
    axis.plot(np.cos(theta), np.sin(theta), color="grey", lw=0.8)
    axis.axhline(0.0, color="grey", lw=0.4)
    axis.axvline(0.0, color="grey", lw=0.4)
    axis.set_xlabel("Re z")
    axis.set_ylabel("Im z")
    axis.set_aspect("equal")
    axis.grid(alpha=0.3)


def _bode(loop):
    """(ω (rad/s), |L| (dB), ∠L unwrapped (deg)) of a loop transfer."""
    nyquist = loop.nyquist_rad_s
    omega = np.geomspace(10.0**-_BODE_DECADES * nyquist, nyquist * (1 - 1e-9), _BODE_POINTS)
    response = loop.frequency_response(omega)
    return omega, 20.0 * np.log10(np.abs(response)), np.degrees(np.unwrap(np.angle(response)))


def plot_paper_loop(path: str | Path, paper: PaperLoopAnalysis) -> Path:
    """The paper's loop: its poles, a zoom on the plant's poles, and the loop gain |L|.

    The poles are drawn on the unit circle, the zoom shows the plant's poles open loop against
    regulator, and |L| is drawn against frequency. Returns the written path.

    Args:
        path: the PNG to write.
        paper: ``loop_robustness.analyze_paper_loop``.
    """
    path = Path(path)
    figure = _figure((14, 4.8))
    full, zoom, gain = figure.subplots(1, 3)
    for axis in (full, zoom):
        _unit_circle(axis)
        axis.plot(
            paper.open_loop_poles.real,
            paper.open_loop_poles.imag,
            "x",
            ms=11,
            mew=2,
            label="open loop eig(A)",
        )
        axis.plot(
            paper.regulator_poles.real,
            paper.regulator_poles.imag,
            "o",
            mfc="none",
            ms=11,
            label="regulator eig(A - BK)",
        )
        axis.plot(
            paper.estimator_poles.real,
            paper.estimator_poles.imag,
            "s",
            mfc="none",
            label="estimator eig(A - LC)",
        )
    full.set_title("closed-loop poles (all)")
    full.legend(fontsize=8, loc="lower left")
    centre = paper.open_loop_poles[np.argmax(paper.open_loop_poles.imag)]
    half = 4.0 * abs(centre.imag)
    zoom.set_xlim(centre.real - half, centre.real + half)
    zoom.set_ylim(-half, half)
    zoom.set_title(f"zoom: regulator poles moved {paper.regulator_pole_shift:.1e}")
    omega, magnitude_db, _ = _bode(paper.loop.loop)
    gain.semilogx(omega, magnitude_db, color="tab:blue", label="|L|")
    gain.axhline(0.0, color="tab:red", ls="--", lw=1, label="0 dB (|L| = 1)")
    peak_db = 20.0 * np.log10(paper.peak_loop_gain)
    gain.plot(
        [paper.peak_loop_gain_frequency_rad_s],
        [peak_db],
        "v",
        color="black",
        label=f"max |L| = {paper.peak_loop_gain:.2e}",
    )
    margins = paper.loop.margins
    if np.isfinite(margins.phase_crossover_rad_s):
        gain.plot(
            [margins.phase_crossover_rad_s],
            [-margins.gain_margin_db],
            "o",
            color="tab:orange",
            label=f"-180° crossing: gain margin {margins.gain_margin_db:.1f} dB",
        )
    gain.set_xlabel("frequency (rad/s)")
    gain.set_ylabel("loop gain |L| (dB)")
    gain.set_title("loop gain of the paper's LQG")
    gain.grid(alpha=0.3, which="both")
    gain.legend(fontsize=8)
    figure.suptitle("Paper LQG on the paper's identified model (Eq. 26): nearly open loop")
    figure.savefig(path, dpi=100)
    return path


def _nominal(cases: list[RobustnessCase]) -> list[RobustnessCase]:
    return [c for c in cases if c.mass_factor == 1.0 and c.extra_delay_samples == 0]


def plot_offset_free_loops(path: str | Path, cases: list[RobustnessCase]) -> Path:
    """The offset-free loop at each lift (head mass factor 1, no extra latency): poles and Bode.

    Draws the closed-loop poles (all, and near z = 1), and the loop's Bode magnitude and phase
    with the gain and phase crossings marked. Returns the written path.

    Args:
        path: the PNG to write.
        cases: ``loop_robustness.robustness_cases``; those with mass factor 1 and no extra
            latency are drawn.
    """
    path = Path(path)
    figure = _figure((12, 9))
    (full, zoom), (magnitude, phase) = figure.subplots(2, 2)
    for axis in (full, zoom):
        _unit_circle(axis)
    zoom.set_xlim(0.8, 1.02)
    zoom.set_ylim(-0.11, 0.11)
    for index, case in enumerate(_nominal(cases)):
        color = f"C{index}"
        label = f"lift {m_to_mm(case.lift_m):g} mm"
        poles = case.analysis.poles
        for axis in (full, zoom):
            axis.plot(poles.real, poles.imag, "x", color=color, label=label)
        omega, magnitude_db, phase_deg = _bode(case.analysis.loop)
        m = case.analysis.margins
        magnitude.semilogx(omega, magnitude_db, color=color, label=label)
        phase.semilogx(omega, phase_deg, color=color, label=label)
        if np.isfinite(m.gain_crossover_rad_s):
            crossing = np.interp(np.log(m.gain_crossover_rad_s), np.log(omega), phase_deg)
            magnitude.plot([m.gain_crossover_rad_s], [0.0], "o", color=color)
            phase.plot(
                [m.gain_crossover_rad_s],
                [crossing],
                "o",
                color=color,
                label=f"PM {m.phase_margin_deg:.0f}°, delay margin {m.delay_margin_s:.2f} s",
            )
        if np.isfinite(m.phase_crossover_rad_s):
            magnitude.plot(
                [m.phase_crossover_rad_s],
                [-m.gain_margin_db],
                "s",
                color=color,
                label=f"GM {m.gain_margin_db:.1f} dB",
            )
    full.set_title("closed-loop poles")
    zoom.set_title("closed-loop poles near z = 1")
    full.legend(fontsize=8, loc="lower left")
    magnitude.axhline(0.0, color="black", lw=0.8)
    magnitude.set_ylabel("|L| (dB)")
    magnitude.set_xlabel("frequency (rad/s)")
    magnitude.legend(fontsize=7, ncol=2)
    magnitude.grid(alpha=0.3, which="both")
    # The -180° lines a phase crossing can meet, within the plotted phase.
    low, high = phase.get_ylim()
    for turn in range(int(np.ceil((low + 180) / 360)), int(np.floor((high + 180) / 360)) + 1):
        phase.axhline(-180 + 360 * turn, color="black", lw=0.8, ls="--")
    phase.set_ylabel("∠L (deg)")
    phase.set_xlabel("frequency (rad/s)")
    phase.legend(fontsize=7)
    phase.grid(alpha=0.3, which="both")
    magnitude.set_title("loop gain (circles: |L| = 1, squares: ∠L = -180°)")
    phase.set_title("loop phase (circles: phase margin at |L| = 1)")
    figure.suptitle("Offset-free LQG on the linearised pneumatic plant with its measurement delay")
    figure.savefig(path, dpi=100)
    return path


def plot_robustness(
    path: str | Path, cases: list[RobustnessCase], latency_requirement_s: float
) -> Path:
    """Gain, phase and delay margins against lift, per head mass and per extra latency.

    One line per head mass (no extra latency, solid) and per extra latency (nominal mass,
    dashed); unstable cases are crossed out in red. Returns the written path.

    Args:
        path: the PNG to write.
        cases: ``loop_robustness.robustness_cases``.
        latency_requirement_s: drawn on the delay-margin panel (s).
    """
    path = Path(path)
    figure = _figure((14, 4.8))
    gain, phase, delay = figure.subplots(1, 3, sharex=True)
    masses = sorted({c.mass_factor for c in cases})
    delays = sorted({c.extra_delay_samples for c in cases if c.extra_delay_samples > 0})
    series = [
        (
            f"head x{f:g}",
            "-",
            [c for c in cases if c.mass_factor == f and not c.extra_delay_samples],
        )
        for f in masses
    ] + [
        (
            f"+{d} tick latency",
            "--",
            [c for c in cases if c.extra_delay_samples == d and c.mass_factor == 1.0],
        )
        for d in delays
    ]
    for label, style, chosen in series:
        if not chosen:
            continue
        if chosen[0].extra_delay_samples:
            label += f" ({1000 * chosen[0].extra_delay_s:.0f} ms)"
        else:
            label += f" ({chosen[0].head_mass_kg:.2f} kg)"
        lifts = m_to_mm(np.array([c.lift_m for c in chosen]))
        values = {
            gain: [c.analysis.margins.gain_margin_db for c in chosen],
            phase: [c.analysis.margins.phase_margin_deg for c in chosen],
            delay: [c.analysis.margins.delay_margin_s for c in chosen],
        }
        for axis, ys in values.items():
            axis.plot(lifts, ys, style, marker="o", label=label)
            unstable = [i for i, c in enumerate(chosen) if not c.analysis.stable]
            axis.plot(lifts[unstable], np.asarray(ys)[unstable], "x", color="red", ms=12)
    delay.axhline(
        latency_requirement_s,
        color="tab:red",
        ls=":",
        label=f"{1000 * latency_requirement_s:.0f} ms latency",
    )
    delay.set_yscale("log")
    for axis, label in (
        (gain, "gain margin (dB)"),
        (phase, "phase margin (deg)"),
        (delay, "delay margin (s)"),
    ):
        axis.set_ylabel(label)
        axis.set_xlabel("lift the head rests at (mm)")
        axis.grid(alpha=0.3, which="both")
    delay.legend(fontsize=8)
    figure.suptitle(
        "Offset-free LQG (designed for the nominal head at its operating lift): margins against "
        "head mass and sensor latency"
    )
    figure.savefig(path, dpi=100)
    return path
