"""Designing the controllers a scenario runs, and what a controller may know of the plant.

The offset-free LQG is designed on the nominal pneumatic plant's linearisation or on a linear model
(identified, or the paper's). A controller knows the plant's nominal parameters, never the
simulated patient's.

``design_controller`` is the public entry point; ``closed_loop.build_closed_loop`` and the
stability analysis design through ``offset_free_design``, so all three get the same gains.
"""

import dataclasses
from dataclasses import dataclass

from maskless.analysis.identification.model_file import load_identified_model
from maskless.diagrams.scenario import (
    OffsetFreeLqg,
    PneumaticPlant,
    Scenario,
    shorthand,
)
from maskless.diagrams.scenario_plant import linear_plant_model
from maskless.errors import ModelError
from maskless.systems.control.offset_free_lqg import (
    OffsetFreeLqgDesign,
    OffsetFreeLqgWeights,
    design_offset_free_lqg,
)
from maskless.systems.control.valve_allocation import (
    SplitRangeAllocation,
    current_split_allocation,
    static_curve_inverse,
)
from maskless.systems.hammerstein_model import HammersteinModel
from maskless.systems.linear_model import LinearModel
from maskless.systems.plant.pneumatic_design import pneumatic_allocation, pneumatic_design_model
from maskless.systems.plant.pneumatic_physics import PneumaticParameters
from maskless.systems.sensing.depth_sensor import latency_frames

# An identified model's output is the fused estimate as logged at a tick, after that tick's
# update; the controller reads it one tick later.
IDENTIFIED_MODEL_DELAY_SAMPLES = 1


@dataclass
class NominalPneumatic:
    """What a controller may know of the pneumatic plant: the nominal head's parameters.

    With them goes their Hammerstein inverse (``allocation``). Built once per loop: the inverse
    samples 400 steady states.
    """

    parameters: PneumaticParameters
    allocation: SplitRangeAllocation

    @classmethod
    def of(cls, config: Scenario) -> "NominalPneumatic":
        """``config.pneumatic`` at its nominal head mass, and the allocation that inverts it."""
        p = config.pneumatic
        nominal = dataclasses.replace(p, head_mass_kg=p.nominal_head_mass_kg)
        allocation = pneumatic_allocation(nominal, config.offset_free_lqg.outlet_full_open_below_m)
        return cls(nominal, allocation)


def measurement_delay_samples(config: Scenario) -> int:
    """Controller ticks between the head's height and the fused estimate the controller reads.

    That is the slowest camera's latency (whole frames), plus one tick because the controller
    reads the local filters' state as it was before its own tick (fusion passes it straight
    through).
    """
    period_s = config.offset_free_lqg.sample_period_s
    latency_s = max(
        latency_frames(camera) / camera.frame_rate_hz for camera in config.cameras.values()
    )
    return round(latency_s / period_s) + 1


def pneumatic_offset_free_design(config: Scenario, nominal: "NominalPneumatic"):
    """The offset-free LQG for the pneumatic plant.

    It is designed on the nominal head's plant linearised at the configured operating lift, for
    the configured cameras' measurement delay (the model's output is the head height itself).
    """
    settings = config.offset_free_lqg
    model = pneumatic_design_model(
        nominal.parameters,
        nominal.allocation,
        settings.operating_lift_m,
        settings.sample_period_s,
    )
    return design_offset_free_lqg(model, settings.weights, measurement_delay_samples(config))


def offset_free_design(
    config: Scenario, nominal: NominalPneumatic | None = None
) -> tuple[OffsetFreeLqgDesign, SplitRangeAllocation]:
    """(design, allocation) of the offset-free LQG as ``config``'s closed loop runs it.

    The design is on the nominal pneumatic plant's linearisation, or on the linear model the
    controller's ``design_model_file`` (or else the model plant) holds; for a Hammerstein model,
    on its inlet's linear part behind the inverse of its valves' static curves.

    Args:
        config: a validated scenario; its controller is taken as ``OffsetFreeLqg()`` unless it
            is one.
        nominal: ``NominalPneumatic.of(config)`` when the caller has it already.

    Raises:
        ModelError: naming the controller, when the model cannot carry the design.
    """
    controller = config.controller if isinstance(config.controller, OffsetFreeLqg) else None
    controller = controller or OffsetFreeLqg()
    if not controller.design_model_file and isinstance(config.plant, PneumaticPlant):
        nominal = nominal or NominalPneumatic.of(config)
        return pneumatic_offset_free_design(config, nominal), nominal.allocation
    if controller.design_model_file:
        identified, camera_height_m = load_identified_model(controller.design_model_file), None
    else:
        identified, camera_height_m = linear_plant_model(config)
    # The design's output is the head height: a camera distance (the paper's model) is turned
    # into one with the camera's height.
    if camera_height_m is not None:
        identified = identified.output_subtracted_from(camera_height_m)
    try:
        if isinstance(identified, HammersteinModel):
            # The command is the steady height change the maps' inverse opens a valve for; the
            # design sees the inlet's linear part with unit DC gain behind it.
            allocation = static_curve_inverse(identified)
            identified = identified.valve_linear_model(0)
        else:
            allocation = current_split_allocation(config.pneumatic.inlet, config.pneumatic.outlet)
        design = design_controller(identified, identified_model_weights(config, identified))
    except ModelError as error:
        raise ModelError(f"controller {shorthand(controller)!r}: {error}") from None
    return design, allocation


def identified_model_weights(config: Scenario, model: LinearModel) -> OffsetFreeLqgWeights:
    """The scenario's weights for a design on ``model``, an identified model.

    An innovations form (a model with K, as PEM and N4SID fit) carries its noise in the
    innovation, so its states get ``identified_model_process_noise_m2`` (none). A model without a
    noise model (K None: a Hammerstein model's linear part, an output-error fit) keeps the
    pneumatic design's process noise, as the nominal plant's model does: with none, the filter
    would trust its states entirely and learn every model error through the slow disturbance
    estimate alone.
    """
    settings = config.offset_free_lqg
    if model.K is None:
        return settings.weights
    return dataclasses.replace(
        settings.weights, process_noise_m2=settings.identified_model_process_noise_m2
    )


def design_controller(
    model: LinearModel | Scenario,
    weights: OffsetFreeLqgWeights | None = None,
    measurement_delay_samples: int = IDENTIFIED_MODEL_DELAY_SAMPLES,
) -> OffsetFreeLqgDesign:
    """The offset-free LQG (Drake's discrete LQR and Riccati solvers) on a model or a scenario.

    Args:
        model: a LinearModel whose output is the head height and whose input is the inlet
            command (say ``maskless.identify(...).model``); or a Scenario, designed as its
            closed loop designs it (``offset_free_design``).
        weights: LQR and Kalman weights; None for the shipped scenario's for this model
            (``identified_model_weights``). Ignored for a Scenario.
        measurement_delay_samples: controller ticks between the height and the estimate the
            controller reads; 1 for a model identified from a maskless recording (the sensing
            chain is already inside it). Ignored for a Scenario.

    Raises:
        ModelError: an integrating model, one with feedthrough, or one whose input holds no
            height in steady state.
    """
    if isinstance(model, Scenario):
        return offset_free_design(model)[0]
    if weights is None:
        from maskless.diagrams.scenario import default_scenario

        weights = identified_model_weights(default_scenario(), model)
    return design_offset_free_lqg(model, weights, measurement_delay_samples)
