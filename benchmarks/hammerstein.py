"""Hammerstein identification on a pneumatic-plant excitation recording, one JSON line.

The record: the shipped scenario's pneumatic plant driven open loop on both valves by random
levels (``systems.control.valve_level_design``: 0 to --top-ma on each valve, stratified unless
--independent-levels, held --hold-s, seeded), the output the fused camera estimate of the head
height (cameras' noise, latency and filters included). The first --estimation fraction is
fitted, the rest held out.

With --targeted-share F, the record is designed sequentially
(``valve_level_experiment.run_sequential_experiment``): the last F of the fitted part is replaced
by levels inside each valve's starting-current interval as a Hammerstein fit of the record before
it finds it (in --rounds parts, each designed from the record up to it; the valve whose interval
is wider gets more of them), held --targeted-hold-s each, approached alternately from below and
above, the other valve meanwhile shut or held at --other-valve-ma; a --coverage-share of them goes
instead over the rest of the curves: to the top eighth of a valve's range where no settled level
has reached it, then to the widest stretch of either curve, above its interval, that no settled
level has shown (with --cover-under-sections, a valve whose targeted holds keep the other
open counts that stretch from its interval's lowest start, not its highest: those holds are a
section's and show no level of its curve alone; with --section-block those holds come in one run
at each round's start). The rest of the record, the held-out part
included, is the same as without it, and the total length the same. F = 0 (the default) is the
random design alone, bit for bit. A round whose fit found too few settled holds to profile a
valve's start targets that valve's whole range
(``valve_level_experiment.designable_intervals``); with --search-spread-rounds it targets the
joint search's spread instead, as every round did until stop 39 of issue 14.

Each record's scenario is seeded with the record's seed, so each carries noise of its own
(seed 0 is the shipped scenario's record). With --shared-noise every record takes the shipped
scenario's one seed, as every record did until stop 38 of issue 14: the cameras' noise was then
the same in every record, and a population of seeds varied the design alone (the cameras'
error, fused estimate less true height, correlated 0.91-0.92 between any two of four records of
seeds 20-52; seeded each, 0.005 between seeds 20 and 21).

With --oracle-true-height each record is fitted a second time, on the plant's true head height
instead of the cameras' estimate (``oracle_true_height`` in the JSON: an oracle, which no user
has), to tell the cameras' share of a miss from the fit's and the design's.

Figures, against the issue's targets:

- each valve's estimated starting current against the plant's (target: within 5 mA), and the
  interval of starting currents the record cannot tell apart (``starting_current_spread``:
  the 95 % profile interval of a fit from settled holds); its saturation current against the
  plant's, and the interval of saturations the record cannot tell apart
  (``saturation_current_spread_ma``);
- each valve's static curve (the map times the DC gain) against the plant's own steady lift per
  current with the other valve shut (``equilibrium_state``), over the working range from the
  plant's starting to its saturation current: the largest error as a fraction of the curve's
  full scale (target: within 10 %); also the largest distance outside the valve's hysteresis band
  (the curve with the spool at either edge of its play band, where it rests after a rise or a
  fall), and the largest error as a fraction of the plant's whole steady lift range;
- the simulation fit (MATLAB's fit %) on the held-out part, against the best linear model (ARX and
  output error, MISO, of the same and a higher order, fitted on the same part); the margin in fit
  points. Each model is judged as `maskless identify --method hammerstein` judges it, simulated
  from the record's start (``hammerstein.held_out_simulation``, which says why).
"""

import argparse
import dataclasses
import functools
import json
import sys
import time
from pathlib import Path

import numpy as np

from maskless.analysis.identification.fit_metrics import fit_percent
from maskless.analysis.identification.hammerstein import (
    estimate_hammerstein,
    estimate_linear_arx,
    held_out_simulation,
)
from maskless.diagrams.process_pool import pool_results
from maskless.diagrams.scenario import MAX_RANDOM_SEED, load_scenario
from maskless.diagrams.valve_level_experiment import (
    SequentialDesign,
    fit_reading,
    run_sequential_experiment,
    run_two_valve_experiment,
)
from maskless.systems.control.valve_level_design import TOP_CURRENT_A, random_level_currents
from maskless.systems.plant.pneumatic_physics import LIFT
from maskless.systems.plant.pneumatic_plant import (
    equilibrium_state,
    validate_pneumatic_parameters,
)
from maskless.systems.units import a_to_ma, ma_to_a

sys.path.insert(0, str(Path(__file__).parent))
from machine import machine_description  # noqa: E402

VALVES = ("inlet", "outlet")


def plant_static_curves(parameters, currents_a, spool_offset_a=0.0) -> np.ndarray:
    """(2, currents) steady lift change (m) per valve current, the other valve shut.

    The spool rests at the coil current plus ``spool_offset_a``: 0 is the centre of its play band
    (``equilibrium_state``), minus or plus the band's half-width the edge it rests at when the
    current was approached from below or above (the valve's hysteresis).
    """
    rest = equilibrium_state(parameters, 0.0, 0.0)[LIFT]
    spools = np.maximum(np.asarray(currents_a) + spool_offset_a, 0.0)
    return np.array(
        [
            [equilibrium_state(parameters, i, 0.0)[LIFT] - rest for i in spools],
            [equilibrium_state(parameters, 0.0, i)[LIFT] - rest for i in spools],
        ]
    )


def pneumatic_record(config, args, seed):
    """(currents (N, 2) mA, fused height (N,) m, true height (N,) m, wall time s, design rounds).

    The design reads the valves' datasheet range only (0 to --top-ma), never the plant's own
    starting current; a sequential design (--targeted-share) reads the record too. Its rounds:
    per round the starting-current intervals (mA) it targeted, one (2, 2) list each; else none.
    """
    period_s = config.offset_free_lqg.sample_period_s
    samples = round(args.duration_s / period_s)
    tops = (ma_to_a(args.top_ma),) * 2
    currents = random_level_currents(
        samples,
        period_s,
        tops,
        (args.hold_s[0], args.hold_s[1]),
        seed,
        args.arrangement,
        stratified=not args.independent_levels,
    )
    started = time.perf_counter()
    if args.targeted_share == 0.0:
        applied, height_m, run = run_two_valve_experiment(config, currents, period_s)
        rounds = []
    else:
        stretch = SequentialDesign(
            fitted_share=args.estimation, targeted_share=args.targeted_share
        ).stretch(samples)

        def start_intervals_a(u_a, y):
            fit = fitted_hammerstein(u_a, y, period_s, args, input_unit="A")
            # Without settled holds' intervals the spread is the joint search's ends, which
            # only --search-spread-rounds takes for one.
            if args.search_spread_rounds:
                return fit.starting_current_spread(), fit.settled_currents or ((), ())
            return fit_reading(fit)

        applied, height_m, run, intervals = run_sequential_experiment(
            config,
            currents,
            period_s,
            tops,
            stretch,
            start_intervals_a,
            args.targeted_hold_s,
            seed,
            args.rounds,
            args.coverage_share,
            tuple(ma_to_a(np.asarray(args.other_valve_ma))),
            args.tops_from_long_holds,
            args.cover_under_sections,
            args.section_block,
        )
        rounds = [a_to_ma(found).tolist() for found in intervals]
    # mA: the model's map is read in the record's units.
    return (
        a_to_ma(applied.T),
        height_m,
        true_height_at(run, height_m.size),
        time.perf_counter() - started,
        rounds,
    )


def true_height_at(run, samples: int) -> np.ndarray:
    """(samples,) the plant's head height (m) at the times the fused estimate was logged."""
    fused_times = run.signals["fusion.estimated_state"].times_s[:samples]
    head = run.signals["head_height_m"]
    return np.interp(fused_times, head.times_s, head.values[0])


def valve_figures(fit, parameters) -> dict:
    """Per valve, the estimate against the plant's truth (see the module docstring)."""
    model = fit.model
    valves = [getattr(parameters, name) for name in VALVES]
    # The plant's whole steady lift range: outlet fully open to inlet fully open.
    lift_range = float(np.ptp(plant_static_curves(parameters, [valves[0].saturation_current_a])))
    figures = {}
    spread = fit.starting_current_spread()
    for index, (name, valve) in enumerate(zip(VALVES, valves, strict=True)):
        working = np.linspace(valve.starting_current_a, valve.saturation_current_a, 211)
        truth = plant_static_curves(parameters, working)[index]
        band = [
            plant_static_curves(parameters, working, sign * valve.play_half_width_a)[index]
            for sign in (-1.0, 1.0)
        ]
        estimate = model.static_curve(index, a_to_ma(working))
        outside_band = np.maximum(np.minimum(*band) - estimate, estimate - np.maximum(*band))
        full_scale = float(np.max(np.abs(truth)))
        figures[name] = {
            "starting_current_ma": model.maps[index].starting_current,
            "starting_current_error_ma": model.maps[index].starting_current
            - a_to_ma(valve.starting_current_a),
            "starting_current_spread_ma": list(spread[index]),
            "saturation_current_ma": model.maps[index].saturation_current,
            "saturation_current_error_ma": model.maps[index].saturation_current
            - a_to_ma(valve.saturation_current_a),
            "saturation_current_spread_ma": (
                list(fit.saturation_intervals[index]) if fit.saturation_intervals else None
            ),
            "full_scale_lift_mm": 1e3 * full_scale,
            "static_curve_max_error_of_full_scale": float(
                np.max(np.abs(estimate - truth)) / full_scale
            ),
            "static_curve_rms_error_of_full_scale": float(
                np.sqrt(np.mean((estimate - truth) ** 2)) / full_scale
            ),
            "static_curve_max_outside_hysteresis_band_of_full_scale": float(
                np.max(np.maximum(outside_band, 0.0)) / full_scale
            ),
            "static_curve_max_error_of_lift_range": float(
                np.max(np.abs(estimate - truth)) / lift_range
            ),
        }
    return figures


def measure_record(u, y, period_s, parameters, args) -> dict:
    """The Hammerstein fit and the linear baselines on one record, judged against the truth."""
    split = estimation_samples(u.shape[0], args)
    u_est, y_est = u[:split], y[:split]

    def held_out_fit(model) -> float:
        return fit_percent(y[split:], held_out_simulation(model, u, slice(split, None)))

    started = time.perf_counter()
    fit = fitted_hammerstein(u_est, y_est, period_s, args)
    fit_s = time.perf_counter() - started
    hammerstein_fit = held_out_fit(fit.model)
    linear = {}
    for order in (args.order, args.order + 2):
        oe = estimate_hammerstein(
            u_est, y_est, order, period_s, input_delay_samples=args.delay, linear=True
        )
        arx = estimate_linear_arx(u_est, y_est, order, period_s, input_delay_samples=args.delay)
        linear[f"oe{order}"] = held_out_fit(oe.model)
        linear[f"arx{order}"] = held_out_fit(arx)
    best_linear = max(linear, key=linear.get)
    return {
        "estimation_samples": split,
        "valves": valve_figures(fit, parameters),
        "poles": [[float(p.real), float(p.imag)] for p in fit.model.poles()],
        "converged": fit.converged,
        "message": fit.message,
        "warnings": list(fit.warnings),
        "fit_wall_s": fit_s,
        "validation_simulation_fit_percent": {"hammerstein": hammerstein_fit, **linear},
        "best_linear": best_linear,
        "margin_over_best_linear_points": hammerstein_fit - linear[best_linear],
    }


def worst_over_seeds(runs: list[dict]) -> dict:
    """The worst figure of each target over the seeds."""
    worst = {}
    for name in VALVES:
        figures = [run["valves"][name] for run in runs]
        worst[name] = {
            "starting_current_abs_error_ma": max(
                abs(f["starting_current_error_ma"]) for f in figures
            ),
            "static_curve_max_error_of_full_scale": max(
                f["static_curve_max_error_of_full_scale"] for f in figures
            ),
        }
    worst["margin_over_best_linear_points"] = min(
        run["margin_over_best_linear_points"] for run in runs
    )
    worst["fit_wall_s"] = max(run["fit_wall_s"] for run in runs)
    return worst


def measure_seed(config, args, seed: int) -> dict:
    """One seed's record, fit and figures."""
    if not args.shared_noise:
        config = dataclasses.replace(config, random_seed=seed)
    u, y, true_height, simulated_s, rounds = pneumatic_record(config, args, seed)
    period_s = config.offset_free_lqg.sample_period_s
    run = measure_record(u, y, period_s, config.pneumatic, args)
    design = {"targeted_start_intervals_ma": rounds} if rounds else {}
    oracle = {}
    if args.oracle_true_height:
        oracle = {
            "oracle_true_height": oracle_figures(u, true_height, period_s, config.pneumatic, args)
        }
    return {
        "seed": seed,
        "samples": int(u.shape[0]),
        "simulation_wall_s": simulated_s,
        **design,
        **run,
        **oracle,
    }


def oracle_figures(u, true_height, period_s, parameters, args) -> dict:
    """An oracle: the same fit on the plant's true head height in place of the cameras' estimate.

    It reads what no user has, so it judges nothing but where a miss comes from: a miss the
    camera record makes and the true height does not is the cameras' noise (a level's mean
    scatters by a tenth of a millimetre, a tenth of the outlet's whole steady lift), not the
    fit's or the design's. The design still read only the cameras.
    """
    split = estimation_samples(u.shape[0], args)
    fit = fitted_hammerstein(u[:split], true_height[:split], period_s, args)
    return {"valves": valve_figures(fit, parameters), "warnings": list(fit.warnings)}


def estimation_samples(samples: int, args) -> int:
    """The record's first samples the fits read (--estimation of them); the rest is held out."""
    return round(args.estimation * samples)


def fitted_hammerstein(u_est, y_est, period_s, args, input_unit="mA"):
    """The benchmark's Hammerstein fit of a record (currents in ``input_unit``, output in m).

    The design rounds fit their records so too, in A.
    """
    return estimate_hammerstein(
        u_est,
        y_est,
        args.order,
        period_s,
        map_segments=args.segments,
        input_delay_samples=args.delay,
        input_unit=input_unit,
        output_unit="m",
        **fit_options(args),
    )


def fit_options(args) -> dict:
    """The settled levels' reading the design rounds and the fits share (the flags)."""
    return {
        # A designed record's sections (--other-valve-ma) are read; a random one has none.
        "read_sections": any(args.other_valve_ma),
        "settle_by_holds": args.settle_by_holds,
        "settle_from_maps": args.settle_from_maps,
        # A section held in one run is read from its levels approached from within it.
        "sections_from_within": args.section_block,
    }


def measure(args) -> dict:
    config = load_scenario()
    if args.plant_starts_ma is not None:
        config = with_plant_starts(config, args.plant_starts_ma)
    parameters = config.pneumatic
    period_s = config.offset_free_lqg.sample_period_s
    sequential = {}
    if args.targeted_share > 0.0:
        sequential = {
            "targeted_share": args.targeted_share,
            "rounds": args.rounds,
            "coverage_share": args.coverage_share,
            "targeted_hold_s": args.targeted_hold_s,
            "other_valve_ma": list(args.other_valve_ma),
            "tops_from_long_holds": args.tops_from_long_holds,
            "cover_under_sections": args.cover_under_sections,
            "section_block": args.section_block,
        }
    runs = []
    started = time.perf_counter()
    workers = min(args.jobs, len(args.seeds))
    # A process per seed: a seed's figures are then the same whichever seeds share the command.
    for run in pool_results(
        functools.partial(measure_seed, config, args), args.seeds, workers, True
    ):
        runs.append(run)
        print(
            f"seed {run['seed']} done ({len(runs)} of {len(args.seeds)}, "
            f"{time.perf_counter() - started:.0f} s)",
            file=sys.stderr,
            flush=True,
        )
    runs.sort(key=lambda run: args.seeds.index(run["seed"]))
    return {
        "benchmark": "hammerstein",
        "record": {
            "sample_period_s": period_s,
            "duration_s": args.duration_s,
            "estimation": args.estimation,
            "arrangement": args.arrangement,
            "top_ma": args.top_ma,
            "hold_s": list(args.hold_s),
            "stratified_levels": not args.independent_levels,
            **sequential,
        },
        "order": args.order,
        "input_delay_samples": args.delay,
        "map_segments": args.segments,
        "settle_by_holds": args.settle_by_holds,
        "settle_from_maps": args.settle_from_maps,
        "noise_per_record": not args.shared_noise,
        "search_spread_rounds": args.search_spread_rounds,
        "plant_starts_ma": [
            a_to_ma(getattr(parameters, name).starting_current_a) for name in VALVES
        ],
        "working_range_ma": [
            a_to_ma(parameters.inlet.starting_current_a),
            a_to_ma(parameters.inlet.saturation_current_a),
        ],
        "runs": runs,
        "worst": worst_over_seeds(runs),
        "machine": machine_description(),
    }


def with_plant_starts(config, starts_ma):
    """``config`` with its plant's valves starting at ``starts_ma`` (inlet, outlet; mA).

    The design and the fit read no starting current, so a plant whose valves start elsewhere
    than the shipped 60 mA tests whether what they were tuned on carries over. Each valve's play
    band stays the same fraction of its (now different) span.
    """
    valves = {
        name: dataclasses.replace(
            getattr(config.pneumatic, name), starting_current_a=ma_to_a(start)
        )
        for name, start in zip(VALVES, starts_ma, strict=True)
    }
    pneumatic = dataclasses.replace(config.pneumatic, **valves)
    # The plant's own checks (a positive start, below the saturation current), naming the flag.
    validate_pneumatic_parameters(pneumatic, prefix=f"--plant-starts-ma {starts_ma}: pneumatic")
    return dataclasses.replace(config, pneumatic=pneumatic)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--duration-s", type=float, default=3600.0)
    parser.add_argument("--estimation", type=float, default=0.7)
    parser.add_argument("--order", type=int, default=2)
    parser.add_argument("--delay", type=int, default=1)
    parser.add_argument("--segments", type=int, default=6)
    parser.add_argument("--top-ma", type=float, default=a_to_ma(TOP_CURRENT_A))
    parser.add_argument("--hold-s", type=float, nargs=2, default=(5.0, 60.0))
    parser.add_argument("--arrangement", default="split_range")
    parser.add_argument(
        "--independent-levels",
        action="store_true",
        help="each level drawn independently (the earlier design), not stratified",
    )
    parser.add_argument(
        "--targeted-share",
        type=float,
        default=0.0,
        help="the share of the fitted part designed sequentially (0: none, the random design)",
    )
    parser.add_argument(
        "--rounds", type=int, default=1, help="sequential designs of the targeted share"
    )
    parser.add_argument(
        "--coverage-share",
        type=float,
        default=0.0,
        help="the share of targeted holds over the rest of each curve, above its start's interval",
    )
    parser.add_argument(
        "--other-valve-ma",
        type=float,
        nargs=2,
        default=(0.0, 0.0),
        metavar=("INLET", "OUTLET"),
        help="per valve, the other valve's current during its targeted holds (mA; 0 0: shut, "
        "the split range; 0 190: the outlet's start sought with the inlet open)",
    )
    parser.add_argument(
        "--targeted-hold-s",
        type=float,
        default=None,
        help="each targeted level's hold (s); default the longest of --hold-s",
    )
    parser.add_argument(
        "--tops-from-long-holds",
        action="store_true",
        help="a valve's top eighth counts as seen by the design only where a hold as long as "
        "--targeted-hold-s showed it",
    )
    parser.add_argument(
        "--cover-under-sections",
        action="store_true",
        help="a valve whose targeted holds keep the other open (--other-valve-ma) gets its "
        "holds over the curve from its interval's lowest start up, not its highest",
    )
    parser.add_argument(
        "--settle-by-holds",
        action="store_true",
        help="every fit (the design's rounds' too) reads where each hold settled from the hold "
        "itself (hold_settling), not four time constants of its ARX model's slowest pole",
    )
    parser.add_argument(
        "--settle-from-maps",
        action="store_true",
        help="every fit takes its settling time from the ARX model through each valve's "
        "piecewise-linear map, not a linear ARX model",
    )
    parser.add_argument(
        "--section-block",
        action="store_true",
        help="a valve whose targeted holds keep the other open (--other-valve-ma) gets them in "
        "one run at each round's start, and every fit reads its section's start from the "
        "levels approached from within it",
    )
    parser.add_argument(
        "--oracle-true-height",
        action="store_true",
        help="also fit each record's plant's true head height (an oracle: no user has it), to "
        "tell the cameras' share of a miss from the fit's and the design's",
    )
    parser.add_argument(
        "--shared-noise",
        action="store_true",
        help="every record takes the shipped scenario's seed (the same camera noise in each), "
        "not its own seed (the default)",
    )
    parser.add_argument(
        "--search-spread-rounds",
        action="store_true",
        help="a design round whose fit has no settled holds' interval targets its joint "
        "search's spread, as every round did until stop 39 of issue 14, not the valve's whole "
        "range (the default)",
    )
    parser.add_argument(
        "--seeds", type=int, nargs="+", default=[0], help="one record and fit per seed"
    )
    parser.add_argument(
        "--plant-starts-ma",
        type=float,
        nargs=2,
        metavar=("INLET", "OUTLET"),
        default=None,
        help="the plant's valves' starting currents (mA); default the scenario's (60 60)",
    )
    parser.add_argument(
        "--jobs",
        type=int,
        default=1,
        help="seeds run at once, each in a process of its own (a seed's figures do not "
        "depend on this)",
    )
    args = parser.parse_args()
    if args.jobs < 1:
        raise ValueError(f"--jobs = {args.jobs}: expected at least 1")
    if len(set(args.seeds)) != len(args.seeds):
        raise ValueError(f"--seeds {args.seeds}: expected each seed once")
    if not args.shared_noise and not all(0 <= seed <= MAX_RANDOM_SEED for seed in args.seeds):
        raise ValueError(
            f"--seeds {args.seeds}: expected each a scenario seed, 0 to {MAX_RANDOM_SEED} "
            "(or --shared-noise)"
        )
    if not 0.0 <= args.targeted_share < 1.0:
        raise ValueError(f"--targeted-share = {args.targeted_share}: expected 0 <= share < 1")
    if args.targeted_hold_s is None:
        args.targeted_hold_s = args.hold_s[1]
    print(json.dumps(measure(args)))


if __name__ == "__main__":
    main()
