"""The compare and residual plots: whole PNGs of figsize x dpi pixels, read back by Pillow.

Their margins are fixed rather than a layout engine's, so a test checks that no title, label or
tick label of one axis runs into another's or off the figure.
"""

from pathlib import Path

import numpy as np
import pytest
from identification_records import simulate_record
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from PIL import Image
from png_images import assert_png

from maskless.analysis.identification import fit_plots
from maskless.analysis.identification.fit_plots import (
    drawn_samples,
    plot_compare,
    plot_record,
    plot_residuals,
)
from maskless.analysis.identification.part_curves import part_curves
from maskless.analysis.identification.report import Part, fit, part_figures
from maskless.diagrams.identification_run import identify


@pytest.fixture(scope="module")
def parts():
    u, y, _, _ = simulate_record(2, "white", 2000)
    return [Part("estimation", u[:1000], y[:1000]), Part("validation", u[1000:], y[1000:])]


def curves_of(fitted, parts):
    return [part_curves(fitted, part, parts[0]) for part in parts]


@pytest.fixture
def saved_figures(monkeypatch):
    """Every Figure saved while the test runs, drawn (so its texts have extents)."""
    saved = []
    original = Figure.savefig

    def savefig(figure, *args, **kwargs):
        original(figure, *args, **kwargs)
        saved.append(figure)

    monkeypatch.setattr(Figure, "savefig", savefig)
    return saved


def assert_no_text_collides(figure):
    """Each axis's drawn extent (ticks, labels, title) lies in the figure, clear of the others'."""
    canvas = FigureCanvasAgg(figure)  # a bare Figure saves through a canvas it does not keep
    canvas.draw()
    renderer = canvas.get_renderer()
    width, height = canvas.get_width_height()
    boxes = [axis.get_tightbbox(renderer) for axis in figure.axes]
    for box in boxes:
        assert box.x0 >= 0 and box.y0 >= 0 and box.x1 <= width and box.y1 <= height, box
    for i, box in enumerate(boxes):
        for other in boxes[i + 1 :]:
            assert not box.overlaps(other), (box, other)


# "pem" estimates the initial state, "arx" keeps it at zero: both ways of starting the figures.
@pytest.mark.parametrize("method", ["pem", "arx"])
def test_plot_compare_draws_a_row_per_part(tmp_path, parts, method, saved_figures):
    curves = curves_of(fit(method, parts[0], 2, 0.1), parts)
    path = tmp_path / "compare.png"
    written = plot_compare(str(path), curves, f"{method} order 2", 0.1, "mm")
    assert written == path and isinstance(written, Path)
    assert_png(path, 1100, 640)  # 11 x (3.2 per part) inches at 100 dpi
    assert_png(plot_compare(tmp_path / "one.png", curves[:1], "m", 0.1, "mm"), 1100, 320)
    assert_no_text_collides(saved_figures[0])


@pytest.mark.parametrize("method", ["pem", "arx"])
def test_plot_residuals_draws_a_row_per_part(tmp_path, parts, method, saved_figures):
    curves = curves_of(fit(method, parts[0], 2, 0.1), parts)
    path = tmp_path / "residuals.png"
    written = plot_residuals(str(path), curves, f"{method} order 2")
    assert written == path and isinstance(written, Path)
    assert_png(path, 1200, 600)  # 12 x (3 per part) inches at 100 dpi
    assert_no_text_collides(saved_figures[0])


def test_the_compare_plot_shows_the_reports_fits(tmp_path, parts, saved_figures):
    # The plot's curves and the report's figures come from one function: the titles' fits are
    # the report's, to the digits shown.
    fitted = fit("pem", parts[0], 2, 0.1)
    plot_compare(tmp_path / "compare.png", curves_of(fitted, parts), "pem order 2", 0.1, "mm")
    for axis, part in zip(saved_figures[0].axes, parts, strict=True):
        figures = part_figures(fitted, part, part_curves(fitted, part, parts[0]))
        title = axis.get_title()
        assert f"fit 1-step {figures['fit_percent_1step']:.3f} %" in title
        assert f"sim {figures['fit_percent_sim']:.1f} %" in title


def difference_equation(a, b, u, y=None):
    """The ARX difference equation sample by sample: simulated (y None) or one step ahead."""
    out = np.zeros(u.size)
    for k in range(u.size):
        for i in range(1, a.size + 1):
            if k - i >= 0:
                past = out[k - i] if y is None else y[k - i]
                out[k] += -a[i - 1] * past + b[i - 1] * u[k - i]
    return out


def test_part_curves_are_the_arx_difference_equation(parts):
    # ARX keeps x(0) at zero: its simulation is A(q) y = B(q) u run from rest, and its one-step
    # prediction the same equation fed the measured past outputs.
    fitted = fit("arx", parts[0], 2, 0.1)
    a, b = fitted.polynomials.a, fitted.polynomials.b
    validation = parts[1]
    curves = part_curves(fitted, validation, parts[0])
    np.testing.assert_allclose(curves.simulated, difference_equation(a, b, validation.u), atol=1e-9)
    np.testing.assert_allclose(
        curves.one_step, difference_equation(a, b, validation.u, validation.y), atol=1e-9
    )
    assert curves.measured is validation.y and curves.name == "validation"


def test_a_long_signal_is_drawn_from_each_columns_first_last_lowest_and_highest_sample():
    signal = np.cumsum(np.random.default_rng(0).standard_normal(20_000))
    drawn = drawn_samples(signal)
    assert drawn.size == 8000 and np.all(np.diff(drawn.astype(np.int64)) >= 0)
    # M4 over 2,000 equal stretches of the samples (10 each): each one's extremes and ends.
    for column in np.arange(20_000).reshape(2000, 10):
        kept = drawn[(drawn >= column[0]) & (drawn <= column[-1])]
        assert {column[0], column[-1]} <= set(kept.tolist())
        assert signal[kept].min() == signal[column].min()
        assert signal[kept].max() == signal[column].max()
    # A NaN (a line's break) is kept; a signal of at most 8,000 samples is drawn whole.
    broken = signal.copy()
    broken[12_345] = np.nan
    assert 12_345 in drawn_samples(broken)
    np.testing.assert_array_equal(drawn_samples(signal[:8000]), np.arange(8000))


def test_the_record_plot_of_a_long_record_looks_as_drawn_from_every_sample(tmp_path, monkeypatch):
    u, y, _, _ = simulate_record(2, "coloured", 20_000, seed=7)
    record = identify(u, y, 0.048, 2, "arx").report["diagnostics"]["record"]
    pictures = []
    for points in (fit_plots._M4_POINTS, 10**9):  # M4's samples, then every sample
        monkeypatch.setattr(fit_plots, "_M4_POINTS", points)
        path = plot_record(tmp_path / f"{points}.png", u, y, 0.048, ("mA", "mm"), record)
        pictures.append(np.asarray(Image.open(path).convert("L"), dtype=int))
    # Measured 0.3 % of the pixels a quarter of the grey range apart (the antialiasing at a
    # stretch's ends); every fifth sample instead leaves out 8.8 %, whole runs of a column.
    assert np.mean(np.abs(pictures[0] - pictures[1]) > 64) < 0.01
