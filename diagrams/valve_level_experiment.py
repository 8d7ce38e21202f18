"""An amplitude-rich experiment on both valves, for identifying their static maps (Hammerstein).

A binary or small-amplitude signal sees one slope of a valve's curve; a Hammerstein fit needs the
whole curve, from below the starting current to past saturation. So each valve is driven through
random levels spread uniformly over ``[0, top]``, each held for a random time comparable to the
plant's time constants (so the head settles often enough to show the steady curve, and moves
often enough to show the dynamics). The hold lengths are drawn as ``excitation.multilevel_prbs``
draws its own (``excitation.random_holds``).

The design knows only what a valve's datasheet states, its whole current range (0 to ``top``,
past the largest rated current to show the flat top): never the starting current the fit is to
find. Uniform levels are the design that favours no guess of it. They are stratified: each
valve's levels come in blocks of eight, one from each eighth of its range in random order, so
an hour (some 37 levels per valve in a split range, about half of them held long enough to
settle) leaves no stretch of the curve unvisited, as independent draws often do.

Two arrangements:

- ``split_range``: at each level one valve (inlet or outlet), or neither, is driven over its whole
  range while the other is shut (0 A, below any starting current). That is how the controller's
  split-range allocation uses the valves (never both open), where the plant is a sum of one
  valve's effect at a time and each valve's curve is its curve with the other shut. The levels
  where neither is driven, and the driven valve's levels below its start, show the rest output
  the maps' flat parts must explain.
- ``independent``: both valves draw their levels independently, so both are often open together;
  the bladder's pressure then balances both flows at once, which no sum of per-valve maps
  describes exactly.

The run is the excitation loop of ``maskless excite`` (cameras, local filters and fusion watching
the head), with its two valve commands from the designed signals.

``excitation.multilevel_prbs`` draws levels from a grid for one valve at a time; its split range
(``valve_pair_excitation``) never applies a current between 0 and a valve's starting current,
where the map's flat part is, so this design draws its own: continuous levels.
"""

import dataclasses

import numpy as np

from maskless.diagrams.excitation_run import build_excitation_loop
from maskless.diagrams.scenario import Scenario
from maskless.diagrams.simulation import SimulationRun, simulate_loop
from maskless.systems.control.excitation import ExcitationSignal, random_holds

ARRANGEMENTS = ("split_range", "independent")
# Equal parts of a valve's range that each block of its levels visits once (``_stratified``).
_STRATA = 8


def random_level_currents(
    samples: int,
    sample_period_s: float,
    top_currents_a: tuple[float, float],
    hold_range_s: tuple[float, float],
    seed: int,
    arrangement: str = "split_range",
    stratified: bool = True,
) -> np.ndarray:
    """(2, samples) inlet and outlet currents (A): random levels held for random times.

    Args:
        samples: the record's length.
        sample_period_s: the period of a sample (s).
        top_currents_a: each valve's highest level (A): past its rated range to show the flat top.
        hold_range_s: (shortest, longest) time a level is held (s), drawn uniformly in whole
            samples (``excitation.hold_samples``).
        seed: the random generator's seed (same seed, same signal).
        arrangement: one of ``ARRANGEMENTS`` (see the module docstring).
        stratified: levels in blocks that visit every eighth of a valve's range (``_stratified``);
            False: each level drawn independently (the earlier design, bit for bit).

    Raises:
        ValueError: naming the argument out of range.
    """
    if arrangement not in ARRANGEMENTS:
        raise ValueError(f"arrangement = {arrangement!r}: expected one of {ARRANGEMENTS}")
    if isinstance(samples, bool) or not (isinstance(samples, int) and samples >= 2):
        raise ValueError(f"samples = {samples!r}: expected an integer >= 2")
    if not all(np.isfinite(top) and top > 0 for top in top_currents_a):
        raise ValueError(f"top_currents_a = {top_currents_a}: expected a positive current each")
    rng = np.random.default_rng(seed)
    holds = random_holds(rng, samples, hold_range_s, sample_period_s)
    # Independent levels are drawn before the split, as the earlier design drew them.
    levels = np.zeros((holds.size, 2))
    if not stratified:
        levels = rng.uniform(0.0, 1.0, size=(holds.size, 2)) * np.asarray(top_currents_a)
    driven = np.ones((holds.size, 2), dtype=bool)
    if arrangement == "split_range":
        active = rng.integers(3, size=holds.size)  # the inlet, the outlet, or neither
        driven = np.column_stack([active == 0, active == 1])
    for valve, top in enumerate(top_currents_a):
        if stratified:
            levels[driven[:, valve], valve] = top * _stratified(rng, int(driven[:, valve].sum()))
        levels[~driven[:, valve], valve] = 0.0
    return np.repeat(levels, holds, axis=0)[:samples].T


def _stratified(rng, count: int) -> np.ndarray:
    """``count`` fractions of the range, uniform, in blocks that each visit every stratum once.

    Each block of ``_STRATA`` levels is one uniform draw from each of ``_STRATA`` equal parts of
    the range, in random order: i.i.d. levels leave gaps (a dozen settled levels of a valve can
    miss a fifth of its range), and a gap is where the static curve is only guessed.
    """
    blocks = -(-count // _STRATA)
    order = np.concatenate([rng.permutation(_STRATA) for _ in range(blocks)])[:count]
    return (order + rng.uniform(0.0, 1.0, size=count)) / _STRATA


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
