"""Shared fixtures: the shipped configuration and short runs."""

import os

# Each pytest-xdist worker has a core of its own: OpenBLAS's threads on top of the workers would
# make each wait on the other (a sixth of the suite's time on two cores). Set before the imports
# below load numpy, which reads it once; the tests' own subprocesses inherit it.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import pytest

from maskless.diagrams.background import usable_cores
from maskless.diagrams.scenario import (
    PaperLqg,
    PaperPlant,
    controller_from_shorthand,
    load_scenario,
    plant_from_shorthand,
)
from maskless.diagrams.simulation import simulate

SHORT_RUN_S = 20.0


def pytest_xdist_auto_num_workers(config):
    """One xdist worker per core this process may use (its affinity, as maskless's own pools).

    Not the machine's count, which pytest-xdist takes: in a container or under taskset, more
    workers would share the cores.
    """
    return usable_cores()


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
