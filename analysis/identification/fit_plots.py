"""Plots of an identification: the record, measured against predicted output, residuals.

Every axis carrying a signal names the record's unit as given (a temperature in degC stays degC).
"""

from pathlib import Path

import numpy as np

from maskless.analysis.identification.fit_metrics import fit_percent
from maskless.analysis.identification.report import FittedModel, Part, initial_state_for_part
from maskless.analysis.identification.residual_analysis import residual_correlations


def _figure(width, height):
    # Imported here: matplotlib is slow to import and only these functions need it. A bare Figure
    # needs no GUI backend and no pyplot.
    from matplotlib.figure import Figure

    return Figure(figsize=(width, height), layout="constrained")


def unit_label(unit: str) -> str:
    """How an axis names a signal's unit: as given, or that it was not given."""
    return f"({unit})" if unit else "(unit not given)"


def plot_record(
    path: str | Path,
    u: np.ndarray,
    y: np.ndarray,
    sample_period_s: float,
    units: tuple[str, str],
    diagnostics: dict,
) -> Path:
    """The whole record as read, with what the data diagnostics found in it.

    The input with its limits and the share of samples at each, the output with its trend line
    and each signal's longest hold marked.

    Args:
        path: the PNG to write.
        u: the input as read (its unit).
        y: the output as read (its unit).
        sample_period_s: Ts (s).
        units: (input unit, output unit), shown as given.
        diagnostics: the report's ``diagnostics["record"]`` entry (``RecordDiagnostics`` as a
            dict).
    """
    figure = _figure(11, 6.0)
    axes = figure.subplots(2, 1, sharex=True)
    time_s = np.arange(u.size) * sample_period_s
    clipping = diagnostics["clipping"]
    signals = (
        ("input", u, units[0], diagnostics["input_trend"], diagnostics["input_hold"]),
        ("output", y, units[1], diagnostics["output_trend"], diagnostics["output_hold"]),
    )
    for axis, (name, signal, unit, trend, hold) in zip(axes, signals, strict=True):
        axis.plot(time_s, signal, lw=0.6, color="black", label=name)
        line = trend["mean"] + trend["slope_per_sample"] * (
            np.arange(signal.size) - (signal.size - 1) / 2
        )
        axis.plot(
            time_s,
            line,
            lw=1.2,
            color="tab:orange",
            label=f"trend line ({trend['drift_share']:.0%} of the variance)",
        )
        held = slice(hold["start"], hold["start"] + hold["samples"])
        axis.plot(
            time_s[held],
            signal[held],
            lw=3,
            color="tab:red",
            label=f"longest hold: {hold['samples']} samples",
        )
        axis.set_ylabel(f"{name} {unit_label(unit)}")
        axis.legend(loc="upper right", fontsize=8)
    for limit in ("minimum", "maximum"):
        clipped = limit in clipping["clipped_at"]
        axes[0].axhline(
            clipping[limit],
            lw=1.0,
            ls="--",
            color="tab:purple" if clipped else "tab:gray",
            label=f"{limit} {clipping[limit]:.6g}: {clipping[f'share_at_{limit}']:.1%} of samples"
            + (", CLIPPED" if clipped else ""),
        )
    axes[0].legend(loc="upper right", fontsize=8)  # again, with the limits
    axes[0].set_title("the record as read, before detrending")
    axes[-1].set_xlabel("time (s)")
    figure.savefig(path, dpi=100)
    return Path(path)


def plot_compare(
    path: str | Path, fitted: FittedModel, parts: list[Part], sample_period_s: float, unit: str
) -> Path:
    """Measured output against the one-step prediction and the simulation, on each part.

    The prediction and the simulation start from the same initial states as the report's figures.
    """
    model = fitted.polynomials
    figure = _figure(11, 3.2 * len(parts))
    axes = figure.subplots(len(parts), 1, squeeze=False)[:, 0]
    estimation = parts[0]
    for axis, part in zip(axes, parts, strict=True):
        one_step = model.predict(
            part.u, part.y, initial_state_for_part(fitted, part, estimation, "one_step")
        )
        simulated = model.simulate(
            part.u, initial_state_for_part(fitted, part, estimation, "simulation")
        )
        time_s = np.arange(part.y.size) * sample_period_s
        axis.plot(time_s, one_step, lw=1.2, color="tab:blue", label="1-step prediction")
        axis.plot(time_s, simulated, lw=1.2, color="tab:orange", label="simulation")
        axis.plot(time_s, part.y, lw=0.6, color="black", label="measured")  # drawn on top
        stability = "" if fitted.linear_models[0].is_stable() else ", UNSTABLE"
        axis.set_title(
            f"{fitted.method} order {model.order}{stability}, {part.name} part: fit 1-step "
            f"{fit_percent(part.y, one_step):.3f} %, sim {fit_percent(part.y, simulated):.1f} %"
        )
        axis.set_ylabel(f"output - offset {unit_label(unit)}")
        axis.legend(loc="upper right", fontsize=8)
    axes[-1].set_xlabel("time from the part's start (s)")
    figure.savefig(path, dpi=100)
    return Path(path)


def plot_residuals(path: str | Path, fitted: FittedModel, parts: list[Part]) -> Path:
    """For each part, the one-step residuals' autocorrelation and cross-correlation with the input.

    Each is drawn with its 99 % band.
    """
    model = fitted.polynomials
    figure = _figure(12, 3.0 * len(parts))
    grid = figure.subplots(len(parts), 2, squeeze=False)
    for (auto, cross), part in zip(grid, parts, strict=True):
        x0 = initial_state_for_part(fitted, part, parts[0], "one_step")
        residuals = part.y - model.predict(part.u, part.y, x0)
        # With m inputs, one cross-correlation per input on one axis.
        inputs = [part.u] if part.u.ndim == 1 else list(part.u.T)
        every = [residual_correlations(residuals, u) for u in inputs]
        c = every[0]
        auto.stem(c.lags, c.autocorrelation, basefmt=" ")
        auto.axhspan(-c.band, c.band, color="tab:blue", alpha=0.15, label="99 % band")
        auto.set_title(f"{part.name}: autocorrelation of residuals")
        auto.set_xlabel("lag (samples)")
        auto.legend(loc="upper right", fontsize=8)
        for index, correlations in enumerate(every):
            cross.stem(
                correlations.cross_lags,
                correlations.cross_correlation,
                basefmt=" ",
                linefmt=f"C{index}-",
                markerfmt=f"C{index}o",
                label=f"input {index + 1}" if len(every) > 1 else None,
            )
        cross.axhspan(-c.cross_band, c.cross_band, color="tab:blue", alpha=0.15)
        if len(every) > 1:
            cross.legend(loc="upper right", fontsize=8)
        cross.set_title(f"{part.name}: cross-correlation of input and residuals")
        cross.set_xlabel("lag (samples; > 0: input leads)")
    figure.suptitle(f"{fitted.method} order {model.order}: residual analysis")
    figure.savefig(path, dpi=100)
    return Path(path)
