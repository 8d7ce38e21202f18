"""What a scenario's plant is, as the loop and the controller design need it.

That is the linear model a linear plant runs, and the current range of the valve its inlet
command drives.
"""

from maskless.analysis.identification.model_file import load_identified_model
from maskless.diagrams.scenario import PaperPlant, PneumaticPlant, Scenario
from maskless.systems.hammerstein_model import HammersteinModel
from maskless.systems.linear_model import LinearModel
from maskless.systems.paper_parameters import paper_identified_model
from maskless.systems.units import ma_to_a


def paper_valve_currents_a(paper) -> tuple[float, float]:
    """The paper valve's (starting, saturation) currents (A)."""
    return ma_to_a(paper.valve_starting_current_ma), ma_to_a(paper.valve_saturation_current_ma)


def inlet_current_range_a(config: Scenario) -> tuple[float, float]:
    """The (starting, saturation) currents of the inlet valve of ``config.plant`` (A).

    That is the pneumatic plant's own valve, or the paper's valve in front of a linear model.
    """
    if isinstance(config.plant, PneumaticPlant):
        inlet = config.pneumatic.inlet
        return inlet.starting_current_a, inlet.saturation_current_a
    return paper_valve_currents_a(config.paper)


def linear_plant_model(config: Scenario) -> tuple[LinearModel | HammersteinModel, float | None]:
    """(model, camera height) of a plant that runs a model.

    The model is the paper's, whose output is the distance from ``config.plant.camera`` (at that
    camera's height, m), or a model file's (linear or Hammerstein), whose output is the head
    height (camera height None).
    """
    if isinstance(config.plant, PaperPlant):
        # The model was identified on the fused distance in the Kinect v2 frame (Sec. III-B).
        camera_height_m = config.cameras[config.plant.camera].mount_height_m
        return paper_identified_model(config.paper), camera_height_m
    return load_identified_model(config.plant.model_file), None
