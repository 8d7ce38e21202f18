"""The operating-range plot: a whole PNG of figsize x dpi pixels, read back by Pillow."""

from pathlib import Path

import pytest
from png_images import assert_png

from maskless.analysis.operating_range import default_operating_ranges
from maskless.analysis.operating_range_plots import plot_operating_range
from maskless.diagrams.scenario import load_scenario


@pytest.fixture(scope="module")
def ranges():
    return default_operating_ranges(load_scenario().pneumatic, 4)


def test_plot_operating_range_writes_the_png_and_returns_its_path(tmp_path, ranges):
    path = tmp_path / "operating_range.png"
    written = plot_operating_range(str(path), ranges)
    assert written == path and isinstance(written, Path)
    assert_png(path, 1100, 750)  # an 11 x 7.5 inch figure at 100 dpi


def test_plot_operating_range_draws_one_valve_alone(tmp_path, ranges):
    path = plot_operating_range(tmp_path / "inlet.png", {"inlet": ranges["inlet"]})
    assert_png(path, 1100, 750)
