"""The population plot: the worst trials chosen by p95, and a PNG written with failures in it."""

import numpy as np

from maskless.analysis.population_plots import _cdf, plot_population, worst_trials
from tests.test_population_summary import failed, row


def test_the_worst_trials_are_those_with_the_largest_p95_and_a_failure_has_no_trace():
    rows = [row(0, p95=0.3), row(1, p95=2.0), row(2, p95=0.9), failed(3), row(4, "other", 9.0)]
    assert worst_trials(rows, "c", 2) == [(1, 0), (2, 0)]
    assert worst_trials(rows, "c", 10) == [(1, 0), (2, 0), (0, 0)]


def test_the_plot_is_written(tmp_path):
    rows = [row(0), row(1, p95=3.0, reachable=False), failed(2)]
    t = np.linspace(-5, 10, 50)
    path = plot_population(
        tmp_path / "p.png", rows, ["c"], {"c": [((1, 0), t, np.sin(t)), ((0, 1), t, 0 * t)]}, 0.001
    )
    assert path.read_bytes()[:4] == b"\x89PNG"


def test_a_cdf_counts_every_trial_so_a_curve_missing_runs_stops_short_of_one():
    x, y = _cdf([3.0, 1.0, 2.0], total=4)
    np.testing.assert_array_equal(x, [1.0, 2.0, 3.0])
    np.testing.assert_array_equal(y, [0.25, 0.5, 0.75])
