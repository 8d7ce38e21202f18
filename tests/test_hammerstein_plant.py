"""A Hammerstein model file as the plant and as the controller's design, in one object."""

import numpy as np
import pytest
import yaml
from pydrake.systems.analysis import Simulator
from pydrake.systems.primitives import TrajectorySource
from pydrake.trajectories import PiecewisePolynomial

from maskless.analysis.identification.model_file import hammerstein_file_contents
from maskless.diagrams.scenario import IdentifiedPlant, OffsetFreeLqg, load_scenario
from maskless.diagrams.simulation import simulate
from maskless.systems.hammerstein_model import HammersteinModel
from maskless.systems.plant.hammerstein_plant import make_hammerstein_plant
from maskless.systems.plant.valve_map import ValveMap

TS = 1.0 / 15.0
A = np.poly([0.97, 0.6])[1:]
# A plant like the pneumatic one: the inlet lifts the head up to 18 mm, the outlet lowers it 2 mm.
MODEL = HammersteinModel(
    maps=(
        ValveMap([0.060, 0.100, 0.165], [0.0, 0.25, 1.0]),
        ValveMap([0.060, 0.165], [0.0, 1.0]),
    ),
    a=[A, A],
    b=[[0.018 * (1 + A.sum()) * 0.7, 0.018 * (1 + A.sum()) * 0.3], [-0.002 * (1 + A.sum()), 0.0]],
    input_delay_samples=1,
    operating_output=0.2076,
    sample_period_s=TS,
    input_unit="A",
    output_unit="m",
)


def test_the_plant_runs_the_model_as_its_simulation_does():
    diagram = make_hammerstein_plant(MODEL)
    samples = 200
    rng = np.random.default_rng(0)
    currents = np.repeat(rng.uniform(0.0, 0.19, size=(2, samples // 20)), 20, axis=1)
    # The model's simulation starts at rest at u(0): start both valves shut.
    currents[:, :20] = 0.0
    times = np.arange(samples) * TS
    from pydrake.systems.framework import DiagramBuilder

    builder = DiagramBuilder()
    plant = builder.AddSystem(diagram)
    for index, name in enumerate(("inlet_valve_current_a", "outlet_valve_current_a")):
        source = builder.AddSystem(
            TrajectorySource(PiecewisePolynomial.ZeroOrderHold(times, currents[[index]]))
        )
        builder.Connect(source.get_output_port(), plant.GetInputPort(name))
    whole = builder.Build()
    simulator = Simulator(whole)
    context = simulator.get_mutable_context()
    heights = []
    for time_s in times:
        simulator.AdvanceTo(time_s)
        heights.append(
            plant.GetOutputPort("head_height_m").Eval(plant.GetMyContextFromRoot(context))[0]
        )
    np.testing.assert_allclose(heights, MODEL.simulate(currents.T), atol=1e-12)


def test_a_hammerstein_model_file_runs_as_the_plant_and_carries_the_design(tmp_path):
    path = tmp_path / "hammerstein.yaml"
    path.write_text(yaml.safe_dump(hammerstein_file_contents(MODEL, verdict="planted")))
    config = load_scenario(
        plant=IdentifiedPlant(model_file=str(path)),
        controller=OffsetFreeLqg(),
        duration_s=60.0,
    )
    run = simulate(config)
    assert run.closed_loop.plant == "identified"
    height = run.signals["head_height_m"].values[0]
    reference = run.signals["reference_head_height_m"].values[0]
    # The reference steps 5 mm up at 10 s; the design on the inlet's linear part behind the maps'
    # inverse brings the head there and holds it.
    assert reference[-1] - reference[0] == pytest.approx(0.005)
    assert height[0] == pytest.approx(MODEL.operating_output)
    settled = run.signals["head_height_m"].times_s > 40.0
    assert abs(np.mean(height[settled]) - reference[-1]) < 1e-4
    # Held there by the inlet alone, at the current whose static curve gives the 5 mm.
    inlet = run.signals["inlet_valve_current_a"].values[0][settled]
    outlet = run.signals["outlet_valve_current_a"].values[0][settled]
    assert np.all(outlet == 0.0)
    assert np.mean(MODEL.static_curve(0, inlet)) == pytest.approx(0.005, abs=2e-4)
