"""Shared fixtures: the shipped configuration, short runs and a designed excitation."""

import contextlib
import io
import json

import pytest

from maskless.diagrams.cli import main
from maskless.diagrams.scenario import (
    PaperLqg,
    PaperPlant,
    controller_from_shorthand,
    load_scenario,
    plant_from_shorthand,
)
from maskless.diagrams.simulation import simulate

SHORT_RUN_S = 20.0


@pytest.fixture
def config():
    """A fresh copy of the shipped defaults (tests may change it)."""
    return load_scenario()


@pytest.fixture
def paper_config(config):
    """The shipped defaults with the seed paper's plant and controller."""
    config.plant, config.controller = PaperPlant(), PaperLqg()
    return config


def _short_run(plant: str, controller: str):
    config = load_scenario()
    config.plant = plant_from_shorthand(plant)
    config.controller = controller_from_shorthand(controller)
    config.duration_s = SHORT_RUN_S
    config.reference.step_times_s = [2.0]
    # Judged from 10 s after the step: the short run's last 8 s.
    config.metrics.evaluation_delay_s = 10.0
    return simulate(config)


@pytest.fixture(scope="session")
def short_run():
    """A 20 s run of the shipped defaults (pneumatic plant, offset-free LQG), step at 2 s."""
    return _short_run("pneumatic", "offset-free-lqg")


@pytest.fixture(scope="session")
def paper_short_run():
    """A 20 s run of the paper's plant and LQG with the reference step at 2 s."""
    return _short_run("paper", "paper-lqg")


@pytest.fixture(scope="session")
def designed_excitation(tmp_path_factory):
    """(folder, printed summary) of 600 s of `maskless excite --signal designed-levels`, seed 3.

    Shared: the design's rounds fit the record as they go, about 40 s.
    """
    out = tmp_path_factory.mktemp("designed") / "ex"
    args = ["excite", "--valve-drive", "split-range", "--signal", "designed-levels"]
    args += ["--seed", "3", "--duration", "600", "--out", str(out), "--json"]
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed):
        assert main(args) == 0
    return out, json.loads(printed.getvalue())
