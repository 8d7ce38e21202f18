"""The paper's identified plant (Eq. 25-26) behind the static valve map: the "paper" plant.

x(k+1) = A x(k) + B (g(i(k)) - i_op), distance(k) = d_op + C x(k), where g is the valve map and the
model's output is the fused camera-to-head distance in the Kinect v2 frame (the frame the authors
identified in). The plant reports the head height above the table, h = camera height - distance,
so a positive B moving the distance down lifts the head. The innovations term K e is the model's
noise description, not a physical input, so the plant runs noise-free; sensors add the noise.

With B of order 1e-7 m/A this plant barely moves: that is the paper's own model, kept faithful.
"""

from pydrake.symbolic import MakeVectorVariable, Variable
from pydrake.systems.framework import DiagramBuilder

from maskless.errors import ModelError
from maskless.systems.linear_model import LinearModel
from maskless.systems.named_symbolic_system import (
    PortMap,
    add_named_symbolic_system,
    building_expressions,
    diagram_form,
)
from maskless.systems.plant.valve_map import effective_valve_current


@building_expressions
def add_linear_model_plant(
    builder: DiagramBuilder,
    model: LinearModel,
    camera_height_m: float | None,
    valve_starting_current_a: float,
    valve_saturation_current_a: float,
    name: str = "linear_model_plant",
) -> PortMap:
    """Adds the paper plant to ``builder``.

    .. pydrake_system::

        name: linear_model_plant
        input_ports:
        - inlet_valve_current_a
        - outlet_valve_current_a
        output_ports:
        - head_height_m

    Args:
        builder: where the plant's system goes.
        model: the identified model in SI, from the valve current (A) to the distance or height
            (m), without feedthrough (see ``paper_identified_model``).
        camera_height_m: height of the camera whose frame the model's output is in, above the
            table (m); converts distance to head height. None for a model whose output is the
            head height itself (one identified from a maskless recording).
        valve_starting_current_a: no flow below this current (A).
        valve_saturation_current_a: the current is clipped here (A).
        name: the system's name.

    The model state starts at zero: the head at the operating point, at rest. Every plant has
    the same ports; a model identified from the inlet alone has no outlet, so its
    ``outlet_valve_current_a`` is read by nothing.

    Raises:
        ModelError: the model has a feedthrough D, which would tie the height to the current
            within one step.
    """
    if model.D[0, 0] != 0.0:
        raise ModelError(
            f"D = {model.D[0, 0]}: a linear-model plant needs a model without feedthrough"
        )
    n = model.A.shape[0]
    x = MakeVectorVariable(n, "x")
    current = Variable("inlet_valve_current_a")
    u = effective_valve_current(current, valve_starting_current_a, valve_saturation_current_a)
    next_x = model.A @ x + model.B[:, 0] * (u - model.operating_input)
    model_output = model.operating_output + (model.C @ x)[0]
    height = model_output if camera_height_m is None else camera_height_m - model_output
    return add_named_symbolic_system(
        builder,
        name,
        inputs=[
            ("inlet_valve_current_a", [current]),
            ("outlet_valve_current_a", [Variable("outlet_valve_current_a")]),
        ],
        outputs=[("head_height_m", [height])],
        state=list(x),
        dynamics=list(next_x),
        time_period=model.sample_period_s,
    )


def operating_head_height_m(model: LinearModel, camera_height_m: float | None) -> float:
    """Head height above the table at the model's operating point (m).

    ``camera_height_m`` is as in ``add_linear_model_plant``.
    """
    if camera_height_m is None:
        return model.operating_output
    return camera_height_m - model.operating_output


make_linear_model_plant = diagram_form(add_linear_model_plant)
