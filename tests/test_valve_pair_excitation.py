"""Two-valve excitation: the split range against its specification, the outlet's own seed."""

import numpy as np
import pytest

from maskless.systems.control.excitation import uniform_white_noise
from maskless.systems.control.valve_allocation import current_split_allocation
from maskless.systems.control.valve_pair_excitation import (
    outlet_seed,
    split_range_clipped_fractions,
    split_range_currents,
)
from maskless.systems.plant.pneumatic_physics import ValveParameters

TS = 1.0 / 15.0
# Unequal valves, so a mix-up of the inlet's and the outlet's numbers shows.
INLET = ValveParameters(starting_current_a=0.060, saturation_current_a=0.165)
OUTLET = ValveParameters(starting_current_a=0.050, saturation_current_a=0.130)


def _command(offset_a, amplitude_a, seed=0, samples=4000):
    return uniform_white_noise(amplitude_a, samples * TS, TS, seed, offset=offset_a)


def _recombined(inlet, outlet):
    """The command the two currents stand for, from current_split_allocation's specification.

    At or above the inlet's starting current the inlet carries the command itself; below it the
    outlet opens from its starting current, reaching saturation one inlet span lower.
    """
    outlet_fraction = (outlet - OUTLET.starting_current_a) / OUTLET.current_span_a
    below = INLET.starting_current_a - INLET.current_span_a * outlet_fraction
    return np.where(inlet >= INLET.starting_current_a, inlet, below)


@pytest.mark.parametrize("offset_a, amplitude_a", [(0.060, 0.050), (0.060, 0.150), (0.120, 0.030)])
def test_split_range_never_opens_both_valves_and_recombines_to_the_command(offset_a, amplitude_a):
    command = _command(offset_a, amplitude_a)
    inlet, outlet = split_range_currents(command, current_split_allocation(INLET, OUTLET))
    inlet_open = inlet.values > INLET.starting_current_a
    outlet_open = outlet.values > OUTLET.starting_current_a
    assert not np.any(inlet_open & outlet_open)
    low_a = INLET.starting_current_a - INLET.current_span_a
    expected = np.clip(command.values, low_a, INLET.saturation_current_a)
    # To the allocation's hair-wide knot above the split (1e-6 of the span, valve_allocation).
    np.testing.assert_allclose(
        _recombined(inlet.values, outlet.values),
        expected,
        rtol=0.0,
        atol=1e-6 * INLET.current_span_a,
    )
    # Each valve within its own range; a shut valve carries no current at all.
    assert inlet.values.max() <= INLET.saturation_current_a
    assert outlet.values.max() <= OUTLET.saturation_current_a
    assert np.all(inlet.values[outlet_open] == 0.0) and np.all(outlet.values[inlet_open] == 0.0)
    np.testing.assert_array_equal(inlet.times_s, command.times_s)


def test_split_range_about_the_split_opens_each_valve_about_half_the_time():
    command = _command(INLET.starting_current_a, 0.050)
    inlet, outlet = split_range_currents(command, current_split_allocation(INLET, OUTLET))
    above = np.count_nonzero(command.values > INLET.starting_current_a)
    assert np.count_nonzero(inlet.values > INLET.starting_current_a) == above
    assert (
        np.count_nonzero(outlet.values > OUTLET.starting_current_a) == command.num_samples - above
    )
    assert above / command.num_samples == pytest.approx(0.5, abs=0.03)


def test_split_range_clipped_fractions_are_the_samples_beyond_each_end():
    command = _command(0.060, 0.200)
    allocation = current_split_allocation(INLET, OUTLET)
    inlet_clipped, outlet_clipped = split_range_clipped_fractions(command, allocation)
    low_a = INLET.starting_current_a - INLET.current_span_a
    assert inlet_clipped == np.count_nonzero(command.values > 0.165) / command.num_samples
    assert outlet_clipped == np.count_nonzero(command.values < low_a) / command.num_samples
    # The same fractions sit at each valve's saturation current once split.
    inlet, outlet = split_range_currents(command, allocation)
    assert inlet_clipped == pytest.approx(np.mean(inlet.values == 0.165), abs=1e-12)
    assert outlet_clipped == pytest.approx(np.mean(outlet.values == 0.130), abs=1e-12)
    assert 0.1 < inlet_clipped < 0.4 and 0.1 < outlet_clipped < 0.4


def test_outlet_seed_is_fixed_and_its_noise_uncorrelated_with_the_inlets():
    assert outlet_seed(3) == outlet_seed(3)
    assert len({outlet_seed(seed) for seed in range(50)} | set(range(50))) == 100
    inlet = _command(0.1, 0.05, seed=3, samples=20_000).values
    outlet = _command(0.1, 0.05, seed=outlet_seed(3), samples=20_000).values
    # Independent draws: |r| below 4 / sqrt(N) (four standard errors of a null correlation).
    assert abs(np.corrcoef(inlet, outlet)[0, 1]) < 4 / np.sqrt(inlet.size)
