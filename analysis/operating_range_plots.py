"""Plot of the operating range: steady state and linearisation per valve current, mm, mA, kPa, s."""

from pathlib import Path

from maskless.analysis.operating_range import OperatingRange
from maskless.systems.units import a_to_ma, m_to_mm


def plot_operating_range(path: str | Path, ranges: dict[str, OperatingRange]) -> Path:
    """Steady lift, gauge pressure, DC gain and slow time constant against each valve's current.

    Draws 2x2 panels. Returns the written path.

    Args:
        path: the PNG to write.
        ranges: ``operating_range.default_operating_ranges`` (or any valve -> OperatingRange).
    """
    # Imported here: matplotlib is slow to import and only this function needs it. A bare Figure
    # needs no GUI backend and no pyplot.
    from matplotlib.figure import Figure

    path = Path(path)
    figure = Figure(figsize=(11, 7.5), layout="constrained")
    axes = figure.subplots(2, 2, sharex=True)
    panels = [
        (axes[0, 0], "steady lift (mm)", lambda r: m_to_mm(r.lift_m)),
        (axes[0, 1], "steady gauge pressure (kPa)", lambda r: r.gauge_pressure_pa / 1000.0),
        (axes[1, 0], "DC gain, lift per current (mm/mA)", lambda r: r.dc_gain_m_per_a),
        (axes[1, 1], "slow time constant (s)", lambda r: r.slow_time_constant_s),
    ]
    for axis, label, values in panels:
        for valve, sweep in ranges.items():
            held = "outlet" if valve == "inlet" else "inlet"
            axis.plot(
                a_to_ma(sweep.currents_a),
                values(sweep),
                marker=".",
                label=f"{valve} swept, {held} at {a_to_ma(sweep.held_current_a):.0f} mA",
            )
        axis.set_ylabel(label)
        axis.grid(alpha=0.3)
    axes[1, 0].axhline(0.0, color="black", lw=0.6)
    for axis in axes[1]:
        axis.set_xlabel("swept valve's coil current (mA)")
    axes[0, 0].legend(fontsize=8)
    spans = ", ".join(
        f"{valve} span {m_to_mm(r.lift_span_m):.2f} mm" for valve, r in ranges.items()
    )
    figure.suptitle(f"Pneumatic plant operating range ({spans})")
    figure.savefig(path, dpi=100)
    return path
