"""Shared fixtures: the shipped configuration."""

import pytest

from maskless.diagrams.commands.simulate import run_closed_loop
from maskless.diagrams.scenario import load_simulation_config

SHORT_RUN_S = 20.0


@pytest.fixture
def config():
    """A fresh copy of the shipped defaults (tests may change it)."""
    return load_simulation_config()


@pytest.fixture
def paper_config(config):
    """The shipped defaults with the seed paper's plant and controller."""
    config.plant, config.controller = "paper", "paper-lqg"
    return config


def _short_run(plant: str, controller: str):
    config = load_simulation_config()
    config.plant, config.controller = plant, controller
    config.duration_s = SHORT_RUN_S
    config.reference.step_times_s = [2.0]
    return run_closed_loop(config)


@pytest.fixture(scope="session")
def short_run():
    """A 20 s run of the shipped defaults (pneumatic plant, offset-free LQG), step at 2 s."""
    return _short_run("pneumatic", "offset-free-lqg")


@pytest.fixture(scope="session")
def paper_short_run():
    """A 20 s run of the paper's plant and LQG with the reference step at 2 s."""
    return _short_run("paper", "paper-lqg")
