"""The closed-loop plot: a whole PNG of figsize x dpi pixels (Pillow); thinning by index counts."""

from pathlib import Path

import numpy as np
from png_images import assert_png

from maskless.analysis.closed_loop_plots import _MAX_POINTS, _thin, plot_closed_loop

PERIOD_S = 0.001


def run_arrays(duration_s=12.0):
    """A made-up run sampled at 1 kHz: long enough to be thinned."""
    times = np.arange(0.0, duration_s, PERIOD_S)
    reference = np.where(times < 4.0, 0.005, 0.009)
    head = reference - 0.004 * np.exp(-(times % 4.0))
    return times, reference, head


def test_plot_closed_loop_with_both_valves_and_the_band(tmp_path):
    times, reference, head = run_arrays()
    path = tmp_path / "run.png"
    written = plot_closed_loop(
        str(path),
        times_s=times,
        reference_m=reference,
        head_m=head,
        local_tracks_m={"left": head + 1e-4, "right": head - 1e-4},
        fused_m=head,
        command_times_s=times[::20],
        command_a=np.linspace(0.06, 0.165, times[::20].size),
        outlet_command_a=np.zeros(times[::20].size),
        tolerance_m=0.001,
        title="made-up run",
    )
    assert written == path and isinstance(written, Path)
    assert_png(path, 1100, 715)  # 10 x 6.5 inches at 110 dpi


def test_plot_closed_loop_with_the_inlet_alone(tmp_path):
    times, reference, head = run_arrays(1.0)
    path = plot_closed_loop(
        tmp_path / "inlet.png",
        times_s=times,
        reference_m=reference,
        head_m=head,
        local_tracks_m={},
        fused_m=head,
        command_times_s=times,
        command_a=np.full(times.size, 0.1),
        title="inlet only",
    )
    assert_png(path, 1100, 715)


def test_thinning_leaves_arrays_up_to_the_limit_whole():
    times = np.arange(_MAX_POINTS) * PERIOD_S
    thinned_times, thinned_values = _thin(times, 2.0 * times)
    np.testing.assert_array_equal(thinned_times, times)
    np.testing.assert_array_equal(thinned_values, 2.0 * times)


def test_thinning_keeps_evenly_spread_pairs():
    samples = 12_345
    times = np.arange(samples) * PERIOD_S
    thinned_times, thinned_values = _thin(times, np.sin(times))
    indices = np.rint(thinned_times / PERIOD_S).astype(int)
    # Strides differ by at most one sample: (n - 1) / (limit - 1) rounded either way.
    assert set(np.diff(indices)) <= {
        (samples - 1) // (_MAX_POINTS - 1),
        -(-(samples - 1) // (_MAX_POINTS - 1)),
    }
    np.testing.assert_array_equal(thinned_values, np.sin(times[indices]))  # pairs stay together


def test_thinning_keeps_at_most_the_limit_and_the_first_and_last_samples():
    samples = 12_345
    times = np.arange(samples) * PERIOD_S
    thinned_times, _ = _thin(times, times)
    indices = np.rint(thinned_times / PERIOD_S).astype(int)
    assert indices.size <= _MAX_POINTS
    assert (indices[0], indices[-1]) == (0, samples - 1)
