"""A scenario's plant: the paper's model in its camera's frame, a model file, the valve ranges."""

import pytest

from maskless.diagrams.scenario import PaperPlant
from maskless.diagrams.scenario_plant import inlet_current_range_a, linear_plant_model


def test_the_paper_plant_is_eq_26_seen_from_its_camera(config):
    config.plant = PaperPlant(camera="kinect_v1")
    model, camera_height_m = linear_plant_model(config)
    assert camera_height_m == config.cameras["kinect_v1"].mount_height_m
    # Eq. 26 as printed in assets/paper.yaml, with the operating distance in m.
    assert model.A.tolist() == config.paper.A
    assert model.operating_output == pytest.approx(config.paper.operating_distance_mm / 1000)


def test_the_inlet_range_is_the_driven_valves(config):
    inlet = config.pneumatic.inlet
    assert inlet_current_range_a(config) == (inlet.starting_current_a, inlet.saturation_current_a)
    config.plant = PaperPlant()
    paper = config.paper
    expected = (paper.valve_starting_current_ma / 1000, paper.valve_saturation_current_ma / 1000)
    assert inlet_current_range_a(config) == pytest.approx(expected)
