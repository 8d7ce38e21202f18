"""The compare and residual plots: whole PNGs of figsize x dpi pixels, read back by Pillow."""

from pathlib import Path

import pytest
from identification_records import simulate_record
from png_images import assert_png

from maskless.analysis.identification.fit_plots import plot_compare, plot_residuals
from maskless.analysis.identification.report import Part, fit


@pytest.fixture(scope="module")
def parts():
    u, y, _, _ = simulate_record(2, "white", 2000)
    return [Part("estimation", u[:1000], y[:1000]), Part("validation", u[1000:], y[1000:])]


# "pem" estimates the initial state, "arx" keeps it at zero: both ways of starting the figures.
@pytest.mark.parametrize("method", ["pem", "arx"])
def test_plot_compare_draws_a_row_per_part(tmp_path, parts, method):
    fitted = fit(method, parts[0], 2, 0.1)
    path = tmp_path / "compare.png"
    written = plot_compare(str(path), fitted, parts, 0.1, "mm")
    assert written == path and isinstance(written, Path)
    assert_png(path, 1100, 640)  # 11 x (3.2 per part) inches at 100 dpi
    assert_png(plot_compare(tmp_path / "one.png", fitted, parts[:1], 0.1, "mm"), 1100, 320)


@pytest.mark.parametrize("method", ["pem", "arx"])
def test_plot_residuals_draws_a_row_per_part(tmp_path, parts, method):
    fitted = fit(method, parts[0], 2, 0.1)
    path = tmp_path / "residuals.png"
    written = plot_residuals(str(path), fitted, parts)
    assert written == path and isinstance(written, Path)
    assert_png(path, 1200, 600)  # 12 x (3 per part) inches at 100 dpi
