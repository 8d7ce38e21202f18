"""Plots of an identification: the record, measured against predicted output, residuals.

Every axis carrying a signal names the record's unit as given (a temperature in degC stays degC).
They draw what they are given (``part_curves``) and import only numpy and matplotlib: the plotting
process `maskless identify` starts early need not import the estimators.
"""

from pathlib import Path

import numpy as np

from maskless.analysis.identification.fit_metrics import fit_percent
from maskless.analysis.identification.part_curves import PartCurves

# Margins around and between the axes (inches): room for tick labels, axis labels and titles.
# Fixed rather than a layout engine's: "constrained" measures every text twice per figure, which
# doubled the plots' time (1.7 s against 0.9 s for the three on a 20,000-sample record), and the
# plots wait on it at the end of `maskless identify`.
_MARGIN_IN = {"left": 0.85, "right": 0.2, "top": 0.45, "bottom": 0.55}
# Between rows: tick labels and a title; with an x label on every row, that too.
_ROW_GAP_IN, _LABELLED_ROW_GAP_IN, _COLUMN_GAP_IN = 0.8, 1.05, 0.7
# A long signal is drawn from the first, last, lowest and highest sample of each of 2,000 equal
# stretches, two per pixel column of an 11-inch axes at 100 dpi (M4: Jugel et al., "M4: A
# Visualization-Oriented Time Series Data Aggregation", VLDB 2014). On a 20,000-sample record
# that colours 0.3 % of the pixels differently from drawing every sample (every fifth sample:
# 8.8 %), and Agg's time grows with the points: the record plot took 0.24-0.26 s of CPU from
# every sample, 0.16 s from these; of 130,000 samples 0.45 s against 0.18 s.
_M4_POINTS = 4 * 2000
# How the PNGs are written: zlib at level 3, not Pillow's 6. The pixels are the same; on a
# 20,000-sample record the three plots took 0.15-0.16 s each against 0.16-0.18 s (level 6
# spent 0.064 s of the compare plot's 0.27 s, profiled, in the encoder), for files 4-9 % larger.
_SAVE_OPTIONS = {"dpi": 100, "pil_kwargs": {"compress_level": 3}}


def _figure(width, height, rows, columns=1, *, top_in=_MARGIN_IN["top"], row_gap_in=_ROW_GAP_IN):
    """A ``width`` x ``height`` inch Figure whose ``rows`` x ``columns`` grid has fixed margins.

    ``top_in`` makes room above the first row (a figure title); ``row_gap_in`` between rows.
    """
    # Imported here: matplotlib is slow to import and only these functions need it. A bare Figure
    # needs no GUI backend and no pyplot.
    from matplotlib.figure import Figure

    row_height = (height - top_in - _MARGIN_IN["bottom"] - (rows - 1) * row_gap_in) / rows
    column_width = (
        width - _MARGIN_IN["left"] - _MARGIN_IN["right"] - (columns - 1) * _COLUMN_GAP_IN
    ) / columns
    figure = Figure(figsize=(width, height))
    figure.subplots_adjust(
        left=_MARGIN_IN["left"] / width,
        right=1.0 - _MARGIN_IN["right"] / width,
        top=1.0 - top_in / height,
        bottom=_MARGIN_IN["bottom"] / height,
        hspace=row_gap_in / row_height,
        wspace=_COLUMN_GAP_IN / column_width,
    )
    return figure


def drawn_samples(signal: np.ndarray) -> np.ndarray:
    """The indices of ``signal``'s samples a line draws: all, or M4's (see ``_M4_POINTS``).

    NaN samples are kept (``NaNM4Downsampler``), so a line still breaks where the signal does.
    """
    if signal.size <= _M4_POINTS:
        return np.arange(signal.size)
    from tsdownsample import NaNM4Downsampler

    return NaNM4Downsampler().downsample(np.ascontiguousarray(signal), n_out=_M4_POINTS)


def _plot_line(axis, time_s: np.ndarray, signal: np.ndarray, **style) -> None:
    """``axis.plot(time_s, signal, **style)`` from ``drawn_samples``: nearly the same pixels."""
    drawn = drawn_samples(signal)
    axis.plot(time_s[drawn], signal[drawn], **style)


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
    figure = _figure(11, 6.0, 2, row_gap_in=0.3)  # shared time axis: no labels between
    axes = figure.subplots(2, 1, sharex=True)
    time_s = np.arange(u.size) * sample_period_s
    clipping = diagnostics["clipping"]
    signals = (
        ("input", u, units[0], diagnostics["input_trend"], diagnostics["input_hold"]),
        ("output", y, units[1], diagnostics["output_trend"], diagnostics["output_hold"]),
    )
    for axis, (name, signal, unit, trend, hold) in zip(axes, signals, strict=True):
        _plot_line(axis, time_s, signal, lw=0.6, color="black", label=name)
        ends = np.array([0, signal.size - 1])  # a straight line: its ends draw it
        line = trend["mean"] + trend["slope_per_sample"] * (ends - (signal.size - 1) / 2)
        axis.plot(
            time_s[ends],
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
    figure.savefig(path, **_SAVE_OPTIONS)
    return Path(path)


def plot_compare(
    path: str | Path, curves: list[PartCurves], model_name: str, sample_period_s: float, unit: str
) -> Path:
    """Measured output against the one-step prediction and the simulation, a row per part.

    Args:
        path: the PNG to write.
        curves: per part, the model's curves (``part_curves``: the prediction and the simulation
            start from the same initial states as the report's figures).
        model_name: how the titles name the model (e.g. "pem order 2, UNSTABLE").
        sample_period_s: Ts (s).
        unit: the output's unit, shown as given.
    """
    figure = _figure(11, 3.2 * len(curves), len(curves))
    axes = figure.subplots(len(curves), 1, squeeze=False)[:, 0]
    for axis, part in zip(axes, curves, strict=True):
        time_s = np.arange(part.measured.size) * sample_period_s
        _plot_line(axis, time_s, part.one_step, lw=1.2, color="tab:blue", label="1-step prediction")
        _plot_line(axis, time_s, part.simulated, lw=1.2, color="tab:orange", label="simulation")
        _plot_line(axis, time_s, part.measured, lw=0.6, color="black", label="measured")  # on top
        axis.set_title(
            f"{model_name}, {part.name} part: fit 1-step "
            f"{fit_percent(part.measured, part.one_step):.3f} %, "
            f"sim {fit_percent(part.measured, part.simulated):.1f} %"
        )
        axis.set_ylabel(f"output - offset {unit_label(unit)}")
        axis.legend(loc="upper right", fontsize=8)
    axes[-1].set_xlabel("time from the part's start (s)")
    figure.savefig(path, **_SAVE_OPTIONS)
    return Path(path)


def plot_residuals(path: str | Path, curves: list[PartCurves], model_name: str) -> Path:
    """Per part, the one-step residuals' autocorrelation and cross-correlation with each input.

    Each is drawn with its 99 % band; with m inputs, one cross-correlation per input on one axis.
    """
    figure = _figure(
        12, 3.0 * len(curves), len(curves), 2, top_in=0.75, row_gap_in=_LABELLED_ROW_GAP_IN
    )
    grid = figure.subplots(len(curves), 2, squeeze=False)
    for (auto, cross), part in zip(grid, curves, strict=True):
        every = part.correlations
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
    figure.suptitle(f"{model_name}: residual analysis")
    figure.savefig(path, **_SAVE_OPTIONS)
    return Path(path)
