"""The CLI's own pieces: one parser per command, built lazily, and flags turned into a scenario.

The scenario names only the flags given. SIGINT and SIGTERM stop a command with one line.
"""

import argparse
import signal
import sys

import pytest

from maskless.diagrams.cli import build_parser, main, scenario_from_flags
from maskless.diagrams.scenario import IdentifiedPlant, PaperLqg
from maskless.errors import ConfigError


def test_only_the_chosen_command_module_is_imported():
    for name in list(sys.modules):
        if name.startswith("maskless.diagrams.commands."):
            del sys.modules[name]
    build_parser(["simulate", "--help"])
    loaded = {name for name in sys.modules if name.startswith("maskless.diagrams.commands.")}
    assert loaded == {"maskless.diagrams.commands.simulate"}


def test_every_command_has_its_parser():
    for command in ("simulate", "excite", "identify", "analyze", "workflow"):
        parser = build_parser([command])
        with pytest.raises(SystemExit):
            parser.parse_args([command, "--help"])


def flags(**values):
    defaults = {"config": None, "duration": None, "seed": None, "plant": None, "controller": None}
    return argparse.Namespace(**{**defaults, **values})


def test_flags_build_the_scenario_variants_they_abbreviate(tmp_path):
    model = tmp_path / "m.yaml"
    model.write_text(
        "{A: [[0.9]], B: [[0.01]], C: [[1.0]], D: [[0.0]], K: [[0.1]], sample_period_s: 0.1,"
        " input: {unit: A, offset: 0.1}, output: {unit: m, offset: 0.2}}"
    )
    scenario = scenario_from_flags(
        flags(duration=7.0, plant=f"identified:{model}", controller="paper-lqg"),
        {"--duration": "duration_s", "--plant": "plant", "--controller": "controller"},
    )
    assert scenario.duration_s == 7.0
    assert scenario.plant == IdentifiedPlant(model_file=str(model))
    assert scenario.controller == PaperLqg()


def test_an_error_names_the_flags_given_and_no_other():
    with pytest.raises(ConfigError) as raised:
        scenario_from_flags(
            flags(duration=-1.0), {"--duration": "duration_s", "--seed": "random_seed"}
        )
    assert "command line (--duration)" in str(raised.value)
    assert "--seed" not in str(raised.value)


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_a_signal_stops_a_command_with_one_line_and_its_exit_code(signum, monkeypatch, capsys):
    def stopped(args):
        try:
            signal.raise_signal(signum)  # handled at once, in this (the main) thread
        except KeyboardInterrupt as stop:
            stop.add_note("what the run wrote is in out/run.partial.mcap")
            raise
        raise AssertionError("the signal did not stop the command")

    def unhandled(signum, frame):
        raise RuntimeError("the command left the signal to the test")  # not the test's end

    monkeypatch.setattr("maskless.diagrams.commands.simulate.run_command", stopped)
    previous = signal.signal(signal.SIGTERM, unhandled)
    try:
        code = main(["simulate"])
    except KeyboardInterrupt:
        pytest.fail("KeyboardInterrupt escaped the command")
    finally:
        assert signal.signal(signal.SIGTERM, previous) is unhandled  # the command's handler went
    assert code == 128 + signum
    assert capsys.readouterr().err == (
        f"maskless simulate: stopped by {signum.name}; what the run wrote is in "
        "out/run.partial.mcap\n"
    )
