"""The linear-model plant: its ports, Eq. 25 one step at a time, and Drake's Linearize."""

import numpy as np
import pytest
from pydrake.systems.primitives import Linearize
from system_harness import port_layout

from maskless.systems.paper_parameters import load_paper_parameters, paper_identified_model
from maskless.systems.plant.linear_model_plant import (
    make_linear_model_plant,
    operating_head_height_m,
)

CAMERA_HEIGHT_M = 0.9
START_A, SATURATION_A = 0.060, 0.165


@pytest.fixture(scope="module")
def model():
    return paper_identified_model(load_paper_parameters())


@pytest.fixture(scope="module")
def plant(model):
    return make_linear_model_plant(model, CAMERA_HEIGHT_M, START_A, SATURATION_A)


def test_ports(plant):
    assert plant.get_name() == "linear_model_plant"
    inputs = {"inlet_valve_current_a": 1, "outlet_valve_current_a": 1}
    assert port_layout(plant) == (inputs, {"head_height_m": 1})


def eq_25_step_mm(x_mm, current_ma):
    """Eq. 25-26 as printed, noise-free, mm and mA around 81.32508 mA, behind the valve map."""
    A = np.array([[0, 1], [-0.9883, 1.988]])
    B = np.array([-3.03e-07, -4.254e-07])
    effective = 0.0 if current_ma < 60 else min(current_ma, 165.0)
    return A @ x_mm + B * (effective - 81.32508)


@pytest.mark.parametrize(
    "x_mm, current_ma",
    [([0.0, 0.0], 81.32508), ([1.0, -2.0], 100.0), ([3.0, 3.5], 30.0), ([-1.0, 0.5], 400.0)],
)
def test_one_step_matches_eq_25(plant, x_mm, current_ma):
    context = plant.CreateDefaultContext()
    context.SetDiscreteState(np.array(x_mm) / 1000.0)
    plant.GetInputPort("inlet_valve_current_a").FixValue(context, [current_ma / 1000.0])
    plant.GetInputPort("outlet_valve_current_a").FixValue(context, [0.0])
    # Output: head height = camera height - (operating distance + C x), Eq. 26 with C = [1 0].
    expected_height = CAMERA_HEIGHT_M - (692.357479 + x_mm[0]) / 1000.0
    assert plant.GetOutputPort("head_height_m").Eval(context)[0] == pytest.approx(expected_height)
    updated = plant.EvalUniquePeriodicDiscreteUpdate(context).get_vector().CopyToVector()
    np.testing.assert_allclose(
        updated * 1000.0, eq_25_step_mm(np.array(x_mm), current_ma), rtol=1e-12, atol=1e-15
    )


def test_default_state_is_the_operating_point(plant, model):
    context = plant.CreateDefaultContext()
    height = plant.GetOutputPort("head_height_m").Eval(context)[0]
    assert height == pytest.approx(operating_head_height_m(model, CAMERA_HEIGHT_M))
    assert height == pytest.approx(0.9 - 0.692357479)


def test_linearize_recovers_the_model_and_autodiff_works(plant, model):
    context = plant.CreateDefaultContext()
    plant.GetInputPort("inlet_valve_current_a").FixValue(context, [model.operating_input])
    plant.GetInputPort("outlet_valve_current_a").FixValue(context, [0.0])
    linear = Linearize(
        plant,
        context,
        input_port_index=plant.GetInputPort("inlet_valve_current_a").get_index(),
        output_port_index=plant.GetOutputPort("head_height_m").get_index(),
    )
    np.testing.assert_allclose(linear.A(), model.A, atol=1e-15)
    np.testing.assert_allclose(linear.B(), model.B, rtol=1e-12)
    np.testing.assert_allclose(linear.C(), -model.C)  # height falls as distance grows
    assert plant.ToAutoDiffXd() is not None


def test_the_outlet_port_is_read_by_nothing(plant):
    # The paper's model was identified from the inlet alone: the outlet cannot move its head.
    updates = []
    for outlet_a in (0.0, 0.165):
        context = plant.CreateDefaultContext()
        context.SetDiscreteState(np.array([0.001, -0.002]))
        plant.GetInputPort("inlet_valve_current_a").FixValue(context, [0.1])
        plant.GetInputPort("outlet_valve_current_a").FixValue(context, [outlet_a])
        updates.append(plant.EvalUniquePeriodicDiscreteUpdate(context).get_vector().CopyToVector())
    np.testing.assert_array_equal(updates[0], updates[1])
