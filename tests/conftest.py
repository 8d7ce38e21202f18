"""Shared fixtures: the shipped configuration."""

import pytest

from maskless.diagrams.config import load_simulation_config


@pytest.fixture
def config():
    """A fresh copy of the shipped defaults (tests may change it)."""
    return load_simulation_config()
