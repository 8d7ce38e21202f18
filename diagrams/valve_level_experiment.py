"""An amplitude-rich experiment on both valves, for identifying their static maps (Hammerstein).

A binary or small-amplitude signal sees one slope of a valve's curve; a Hammerstein fit needs the
whole curve, from below the starting current to past saturation. So each valve is driven through
random levels spread uniformly over ``[0, top]``, each held for a random time comparable to the
plant's time constants (so the head settles often enough to show the steady curve, and moves
often enough to show the dynamics).

Two arrangements:

- ``split_range``: at each level one valve (inlet or outlet), or neither, is driven over its whole
  range while the other is held at a random level below its starting current. That is how the
  controller's split-range allocation uses the valves (never both open), where the plant is a sum
  of one valve's effect at a time and each valve's curve is its curve with the other shut. The
  levels where neither is driven keep "this valve below its start" from always meaning "the
  other valve open", which would confound one valve's starting current with the other's curve.
- ``independent``: both valves draw their levels independently, so both are often open together;
  the bladder's pressure then balances both flows at once, which no sum of per-valve maps
  describes exactly.

The run is the excitation loop of ``maskless excite`` (cameras, local filters and fusion watching
the head), with its two valve commands from the designed signals.

``excitation.multilevel_prbs`` draws levels from a grid for one valve at a time; its split range
(``valve_pair_excitation``) never applies a current between 0 and a valve's starting current,
where the map's flat part is, so this design draws its own: continuous levels, and the idle
valve held at random below its start.
"""

import dataclasses

import numpy as np

from maskless.diagrams.excitation_run import build_excitation_loop
from maskless.diagrams.scenario import Scenario
from maskless.diagrams.simulation import SimulationRun, simulate_loop
from maskless.systems.control.excitation import ExcitationSignal

ARRANGEMENTS = ("split_range", "independent")


def random_level_currents(
    samples: int,
    sample_period_s: float,
    top_currents_a: tuple[float, float],
    starting_currents_a: tuple[float, float],
    hold_range_s: tuple[float, float],
    seed: int,
    arrangement: str = "split_range",
) -> np.ndarray:
    """(2, samples) inlet and outlet currents (A): random levels held for random times.

    Args:
        samples: the record's length.
        sample_period_s: the period of a sample (s).
        top_currents_a: each valve's highest level (A): past its saturation to show the flat top.
        starting_currents_a: each valve's starting current (A); ``split_range`` holds the idle
            valve below it.
        hold_range_s: (shortest, longest) time a level is held (s), drawn uniformly.
        seed: the random generator's seed (same seed, same signal).
        arrangement: one of ``ARRANGEMENTS`` (see the module docstring).

    Raises:
        ValueError: naming the argument out of range.
    """
    if arrangement not in ARRANGEMENTS:
        raise ValueError(f"arrangement = {arrangement!r}: expected one of {ARRANGEMENTS}")
    if not (isinstance(samples, int) and samples >= 2):
        raise ValueError(f"samples = {samples!r}: expected an integer >= 2")
    shortest, longest = hold_range_s
    if not 0 < shortest <= longest:
        raise ValueError(f"hold_range_s = {hold_range_s}: expected 0 < shortest <= longest")
    if not all(0 < s < t for s, t in zip(starting_currents_a, top_currents_a, strict=True)):
        raise ValueError(
            f"starting_currents_a = {starting_currents_a}, top_currents_a = {top_currents_a}: "
            "expected 0 < starting current < top for each valve"
        )
    rng = np.random.default_rng(seed)
    currents = np.empty((2, samples))
    start = 0
    while start < samples:
        hold = max(1, round(rng.uniform(shortest, longest) / sample_period_s))
        levels = [rng.uniform(0.0, top) for top in top_currents_a]
        if arrangement == "split_range":
            active = rng.integers(3)  # the inlet, the outlet, or neither
            for idle in {0, 1} - {active}:
                levels[idle] = rng.uniform(0.0, starting_currents_a[idle])
        currents[:, start : start + hold] = np.array(levels)[:, None]
        start += hold
    return currents


def run_two_valve_experiment(
    config: Scenario, currents_a: np.ndarray, sample_period_s: float
) -> tuple[np.ndarray, np.ndarray, SimulationRun]:
    """Runs ``currents_a`` on the plant: (currents as applied (2, N), fused height (N,), the run).

    The fused height is the fusion's estimate (m) logged at each command sample: what the cameras
    measured of the head, noise, latency and filtering included.
    """
    duration_s = currents_a.shape[1] * sample_period_s
    experiment = dataclasses.replace(config, duration_s=duration_s)
    inlet, outlet = (
        ExcitationSignal(np.arange(row.size) * sample_period_s, row, sample_period_s, "levels")
        for row in currents_a
    )
    run = simulate_loop(build_excitation_loop(experiment, inlet, outlet=outlet), experiment)
    applied = np.vstack(
        [run.signals[f"{valve}_valve_current_a"].values[0] for valve in ("inlet", "outlet")]
    )
    fused = run.signals["fusion.estimated_state"].values[0]
    count = min(applied.shape[1], fused.size, currents_a.shape[1])
    return applied[:, :count], fused[:count], run
