"""The CLI's own pieces: one parser per command, built lazily, and flags turned into a scenario.

The scenario names only the flags given.
"""

import argparse
import sys

import pytest

from maskless.diagrams.cli import build_parser, scenario_from_flags
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
