"""The paper's workflow, closed inside the product: excite -> identify -> design -> simulate.

1. `maskless excite` drives the plant's inlet open loop and records the cameras, filters and
   fusion to DIR/excitation/run.mcap;
2. `maskless identify` fits a state-space model (prediction error, the order given) from the
   recorded command to the fused height, into DIR/identification/;
3. `maskless simulate --controller offset-free-lqg:MODEL.yaml` designs the offset-free LQG on that
   model with Drake's Riccati solvers and closes the loop on the plant, into DIR/closed_loop/.

The plant is the scenario's, the pneumatic one by default.

Each stage is one library call; the command line that does the same is printed first, so any
stage can be re-run by hand. The default excitation is a PRBS whose bits last 2 s: the bladder's
time constants are seconds long, and the paper's uniform white noise at the frame rate
(`--signal uniform --clock-periods 1`) puts so little power below 1 Hz that the identified input
gain is noise, as it was for the authors (shared/paper-data/README.md).
"""

import dataclasses
import math
import shlex
from collections.abc import Callable
from pathlib import Path

from maskless.analysis.identification.report import EXPLAINS_VERDICT
from maskless.diagrams.excitation_design import HELD_LEVEL_SIGNALS
from maskless.diagrams.excitation_run import ExcitationRequest, excite_to_files
from maskless.diagrams.identification_run import IdentificationRequest, identify_to_files
from maskless.diagrams.output_folder import RunFolder
from maskless.diagrams.run_summary import tracking_lines
from maskless.diagrams.scenario import (
    OffsetFreeLqg,
    scenario_with_overrides,
    shorthand,
    validate_scenario,
)
from maskless.diagrams.simulation import RUN_FILES, simulate_to_files
from maskless.errors import ConfigError
from maskless.systems.units import a_to_ma

# The workflow's experiment: a PRBS whose 30-sample bits last 2 s at 15 Hz, about 130 mA (mid-way
# up the lift range) +- 25 mA, for 10 minutes.
DEFAULT_EXCITATION = ExcitationRequest(
    signal="prbs", amplitude_a=0.025, offset_a=0.130, duration_s=600.0, clock_periods=30
)


def excite_command(request: ExcitationRequest, seed: int, config: Path | None, out: Path) -> str:
    """The `maskless excite` command line that runs ``request`` again, over the workflow's run."""
    argv = ["--signal", request.signal, "--valve-drive", request.valve_drive]
    if request.amplitude_a is not None:
        argv += ["--amplitude", repr(a_to_ma(request.amplitude_a))]
    if request.offset_a is not None:
        argv += ["--offset", repr(a_to_ma(request.offset_a))]
    argv += ["--clock-periods", str(request.clock_periods), "--duration", repr(request.duration_s)]
    if request.sample_period_s is not None:
        argv += ["--period", repr(request.sample_period_s)]
    if request.band_hz is not None:
        argv += ["--band", f"{request.band_hz[0]!r}:{request.band_hz[1]!r}"]
    if request.signal == "multilevel":
        argv += ["--levels", str(request.levels)]
    if request.signal in HELD_LEVEL_SIGNALS:
        argv += ["--hold", f"{request.hold_s[0]!r}:{request.hold_s[1]!r}"]
    return "maskless excite " + shlex.join([*argv, *_common(seed, config, out)])


def identify_command(request: IdentificationRequest, out: Path) -> str:
    """The `maskless identify` command line that runs ``request``.

    It gives the fields the workflow sets; the rest stay at their defaults.
    """
    argv = ["--input", str(request.input), "--ts", repr(request.ts)]
    argv += ["--orders", ",".join(map(str, request.orders)), "--method", request.method]
    return "maskless identify " + shlex.join([*argv, "--out", str(out)])


def simulate_command(scenario_flags: dict, seed: int, config: Path | None, out: Path) -> str:
    """The `maskless simulate` command line with ``scenario_flags`` (flag -> value), run again."""
    argv = [word for flag, value in scenario_flags.items() for word in (flag, value)]
    return "maskless simulate " + shlex.join([*argv, *_common(seed, config, out)])


def _common(seed: int, config: Path | None, out: Path) -> list[str]:
    # --overwrite: the printed command redoes a stage whose files the workflow wrote.
    out_flags = ["--out", str(out), "--overwrite"]
    return [*out_flags, "--seed", str(seed)] + ([] if config is None else ["--config", str(config)])


def run_workflow(
    out: str | Path,
    *,
    excitation: ExcitationRequest = DEFAULT_EXCITATION,
    order: int = 2,
    closed_loop_s: float = 120.0,
    seed: int | None = None,
    config: str | Path | None = None,
    echo: Callable[[str], None] = print,
    labels: dict[str, str] | None = None,
    overwrite: bool = False,
) -> dict:
    """Runs the three stages into ``out`` and returns their summaries.

    Args:
        out: the directory for excitation/, identification/ and closed_loop/.
        excitation: the experiment.
        order: the identified model's order (the paper's is 2).
        closed_loop_s: the closed-loop simulation's duration (s).
        seed: the seed of both simulations; None for the scenario's.
        config: a scenario YAML overriding the shipped one, for both simulations.
        echo: called with each stage's equivalent command line (and a warning, if any).
        labels: argument -> what the user calls it (a flag), for messages.
        overwrite: replace an earlier workflow's excitation and closed-loop runs in ``out``.

    Raises:
        ConfigError: a bad duration or order, a refused excitation/ or closed_loop/ folder
            (``output_folder.RunFolder``; all before anything runs), or a bad scenario.
    """
    out = Path(out)
    config = None if config is None else Path(config)
    labels = labels or {}
    if not (math.isfinite(closed_loop_s) and closed_loop_s > 0):
        raise ConfigError(
            f"{labels.get('closed_loop_s', 'closed_loop_s')} {closed_loop_s}: expected a "
            "positive number of seconds"
        )
    if order < 1:
        raise ConfigError(
            f"{labels.get('order', 'order')} {order}: expected a model order of at least 1"
        )
    scenario = scenario_with_overrides(config, {"random_seed": seed}, labels)
    seed = scenario.random_seed
    for stage in ("excitation", "closed_loop"):
        RunFolder(out / stage, RUN_FILES, overwrite=overwrite).check()
    echo(excite_command(excitation, seed, config, out / "excitation"))
    excited = excite_to_files(scenario, excitation, out / "excitation", overwrite=overwrite)
    identification = IdentificationRequest(
        input=Path(excited["files"]["recording"]),
        ts=excited["sample_period_s"],
        orders=(order,),
        method="pem",
    )
    echo(identify_command(identification, out / "identification"))
    report = identify_to_files(identification, out / "identification")
    (model,) = report["models"]
    warning = None
    if not model["verdict"].startswith(EXPLAINS_VERDICT):
        warning = (
            "the identified model does not show that the input explains the output, so the "
            "controller designed on it is not to be trusted; excite the slow dynamics more (a "
            "PRBS with longer bits, a larger amplitude or a longer record)"
        )
        echo(f"WARNING: {warning}")
    controller = OffsetFreeLqg(design_model_file=model["model_file"])
    closed_loop_scenario = dataclasses.replace(
        scenario, controller=controller, duration_s=closed_loop_s
    )
    flags = {"--controller": shorthand(controller), "--duration": repr(closed_loop_s)}
    echo(simulate_command(flags, seed, config, out / "closed_loop"))
    validate_scenario(closed_loop_scenario)  # the model file identify wrote
    closed_loop = simulate_to_files(closed_loop_scenario, out / "closed_loop", overwrite=overwrite)
    return {
        "excitation": excited,
        "identification": {
            "model_file": model["model_file"],
            "verdict": model["verdict"],
            "warning": warning,
            "dc_gain": model["dc_gain"],
            "poles": model["poles"],
            "validation": model["validation"],
        },
        "closed_loop": closed_loop,
    }


def format_workflow(result: dict) -> str:
    """The three stages' outcomes as text a person reads."""
    excitation, identified = result["excitation"], result["identification"]
    lines = [
        "",
        f"1. excite: {excitation['signal']}, std {excitation['std_ma']:.2f} mA, crest factor "
        f"{excitation['crest_factor']:.3f}, head {excitation['head_height_mm']['min']:.2f}-"
        f"{excitation['head_height_mm']['max']:.2f} mm",
        f"2. identify: {identified['model_file']}",
        f"   {identified['verdict']}",
    ]
    if identified["warning"]:
        lines.append(f"   WARNING: {identified['warning']}")
    closed_loop = result["closed_loop"]
    lines.append(
        f"3. simulate on the {closed_loop['plant']} plant, controller designed on that model:"
    )
    lines += [f"   {line}" for line in tracking_lines(result["closed_loop"]["tracking"])]
    lines.append(f"   plot {result['closed_loop']['files']['plot']}")
    return "\n".join(lines)
