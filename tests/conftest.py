"""Shared fixtures: the shipped configuration."""

import pytest

from maskless.diagrams.config import load_simulation_config
from maskless.diagrams.simulate import run_closed_loop

SHORT_RUN_S = 20.0


@pytest.fixture
def config():
    """A fresh copy of the shipped defaults (tests may change it)."""
    return load_simulation_config()


@pytest.fixture(scope="session")
def short_run():
    """A 20 s closed-loop run of the shipped defaults with the reference step at 2 s."""
    config = load_simulation_config()
    config.duration_s = SHORT_RUN_S
    config.reference.step_times_s = [2.0]
    return run_closed_loop(config)
