"""design_controller: one entry point that gives the gains the closed loop runs.

It designs on a scenario or on a model, and names a model that cannot carry the design.
"""

import numpy as np
import pytest
import scipy.linalg
import yaml

from maskless.diagrams.cli import main
from maskless.diagrams.closed_loop import build_closed_loop
from maskless.diagrams.controller_design import design_controller, identified_model_weights
from maskless.diagrams.scenario import PaperPlant, load_scenario
from maskless.errors import ModelError
from maskless.systems.linear_model import LinearModel


@pytest.mark.parametrize("plant", [None, PaperPlant()], ids=["pneumatic", "paper"])
def test_a_scenario_design_is_the_one_its_closed_loop_runs(plant):
    scenario = load_scenario(plant=plant)
    design = design_controller(scenario)
    running = build_closed_loop(scenario, record=False).design
    np.testing.assert_array_equal(design.K, running.K)
    np.testing.assert_array_equal(design.M, running.M)


def test_a_model_design_regulates_with_the_riccati_gain_of_its_weights():
    model = LinearModel(A=[[0.95]], B=[[0.01]], C=[[1.0]], D=[[0.0]], sample_period_s=0.1)
    weights = identified_model_weights(load_scenario(), model)
    design = design_controller(model)
    # Scalar first-order case against scipy's DARE: Q on the height (with C = 1 the state is the
    # height, so the state fraction adds to it), R on the command's height equivalent g u, with
    # g = 0.01 / 0.05 = 0.2 m per unit.
    g = 0.2
    Q = weights.output_error_weight_per_m2 * (1.0 + weights.state_weight_fraction)
    R = weights.command_weight_per_m2 * g**2
    P = scipy.linalg.solve_discrete_are([[0.95]], [[0.01]], [[Q]], [[R]])
    K = 0.01 * P[0, 0] * 0.95 / (R + 0.01**2 * P[0, 0])
    assert design.K[0, 0] == pytest.approx(K, rel=1e-9)
    assert design.command_per_reference == pytest.approx(1 / g)


def test_an_integrating_model_is_refused_naming_its_pole(tmp_path, capsys):
    integrator = LinearModel(A=[[1.0]], B=[[0.01]], C=[[1.0]], D=[[0.0]], sample_period_s=0.1)
    with pytest.raises(ModelError, match="z = 1"):
        design_controller(integrator)
    model_file = tmp_path / "integrator.yaml"
    model_file.write_text(
        yaml.safe_dump(
            {
                "A": [[1.0]], "B": [[0.01]], "C": [[1.0]], "D": [[0.0]], "K": [[0.1]],
                "sample_period_s": 1 / 15, "input": {"unit": "A", "offset": 0.1},
                "output": {"unit": "m", "offset": 0.2},
            }
        )
    )  # fmt: skip
    argv = ["simulate", "--controller", f"offset-free-lqg:{model_file}", "--duration", "1"]
    assert main([*argv, "--out", str(tmp_path / "out")]) == 2
    error = capsys.readouterr().err
    assert "controller 'offset-free-lqg:" in error and "z = 1" in error
