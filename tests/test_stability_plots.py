"""The stability plots: whole PNGs of figsize x dpi pixels, read back by Pillow."""

from pathlib import Path

import pytest
from png_images import assert_png

from maskless.analysis.stability.loop_robustness import analyze_paper_loop, robustness_cases
from maskless.analysis.stability.stability_plots import (
    plot_offset_free_loops,
    plot_paper_loop,
    plot_robustness,
)
from maskless.diagrams.plant_analysis import offset_free_setup
from maskless.diagrams.scenario import load_scenario
from maskless.systems.control.paper_lqg import paper_lqg


@pytest.fixture(scope="module")
def scenario():
    return load_scenario()


@pytest.fixture(scope="module")
def cases(scenario):
    """One lift, the nominal and a heavier head, with and without a tick of extra latency."""
    _, allocation, design = offset_free_setup(scenario)
    return robustness_cases(scenario.pneumatic, allocation, design, [0.009], [1.0, 1.2], [0, 1])


def test_plot_paper_loop(tmp_path, scenario):
    paper = analyze_paper_loop(*paper_lqg(scenario.paper))
    path = tmp_path / "paper.png"
    written = plot_paper_loop(str(path), paper)
    assert written == path and isinstance(written, Path)
    assert_png(path, 1400, 480)  # 14 x 4.8 inches at 100 dpi


def test_plot_offset_free_loops(tmp_path, cases):
    path = tmp_path / "offset_free.png"
    written = plot_offset_free_loops(str(path), cases)
    assert written == path and isinstance(written, Path)
    assert_png(path, 1200, 900)  # 12 x 9 inches at 100 dpi


def test_plot_robustness(tmp_path, cases):
    path = tmp_path / "margins.png"
    written = plot_robustness(str(path), cases, 0.1)
    assert written == path and isinstance(written, Path)
    assert_png(path, 1400, 480)  # 14 x 4.8 inches at 100 dpi
