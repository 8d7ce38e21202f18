"""An identified Hammerstein model as a plant: each valve's static map, then the linear part.

x(k+1) = A x(k) + B [f_inlet(i_inlet(k)), f_outlet(i_outlet(k))], head height(k) = y_op + C x(k),
with (A, B, C) the model's linear part (``HammersteinModel.state_space``) and f its valve maps. The
model's output is the head height a maskless recording logs, so no camera geometry enters.
"""

from pydrake.symbolic import MakeVectorVariable, Variable
from pydrake.systems.framework import DiagramBuilder

from maskless.systems.hammerstein_model import HammersteinModel
from maskless.systems.named_symbolic_system import (
    PortMap,
    add_named_symbolic_system,
    building_expressions,
    diagram_form,
)

INPUT_NAMES = ("inlet_valve_current_a", "outlet_valve_current_a")


@building_expressions
def add_hammerstein_plant(
    builder: DiagramBuilder, model: HammersteinModel, name: str = "hammerstein_plant"
) -> PortMap:
    """Adds the model as a plant to ``builder``.

    .. pydrake_system::

        name: hammerstein_plant
        input_ports:
        - inlet_valve_current_a
        - outlet_valve_current_a
        output_ports:
        - head_height_m

    Args:
        builder: where the plant's system goes.
        model: the model in SI (currents in A, height in m), one or two valves (inlet first).
        name: the system's name.

    The state starts at zero: both valves shut, the head at rest at ``model.operating_output``.
    A model of the inlet alone leaves ``outlet_valve_current_a`` read by nothing.
    """
    A, B, C = model.state_space()
    x = MakeVectorVariable(A.shape[0], "x")
    currents = [Variable(port) for port in INPUT_NAMES]
    openings = [
        valve.opening(current) for valve, current in zip(model.maps, currents, strict=False)
    ]
    next_x = A @ x + B @ openings
    return add_named_symbolic_system(
        builder,
        name,
        inputs=[(port, [current]) for port, current in zip(INPUT_NAMES, currents, strict=True)],
        outputs=[("head_height_m", [model.operating_output + (C @ x)[0]])],
        state=list(x),
        dynamics=list(next_x),
        time_period=model.sample_period_s,
    )


make_hammerstein_plant = diagram_form(add_hammerstein_plant)
