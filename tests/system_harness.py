"""Helpers for testing one Drake system: its port layout, and a run with constant inputs."""

import numpy as np
from pydrake.common import RandomGenerator
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource, VectorLogSink


def simulate_with_constant_inputs(system, inputs: dict, outputs: dict, duration_s, seed=0):
    """Feeds constant values into named input ports, logs named output ports every ``period`` s.

    Args:
        system: the system under test.
        inputs: port name -> constant value (list).
        outputs: port name -> log period (s).
        duration_s: simulated time.
        seed: the seed of the diagram's random context (``SetRandomContext``).

    Returns:
        port name -> (times, data) of each log.
    """
    builder = DiagramBuilder()
    builder.AddSystem(system)
    for port_name, value in inputs.items():
        source = builder.AddSystem(ConstantVectorSource(np.atleast_1d(value)))
        builder.Connect(source.get_output_port(), system.GetInputPort(port_name))
    sinks = {}
    for port_name, period in outputs.items():
        port = system.GetOutputPort(port_name)
        sinks[port_name] = builder.AddSystem(VectorLogSink(port.size(), period))
        builder.Connect(port, sinks[port_name].get_input_port())
    diagram = builder.Build()
    simulator = Simulator(diagram)
    context = simulator.get_mutable_context()
    diagram.SetRandomContext(context, RandomGenerator(seed))
    simulator.AdvanceTo(duration_s)
    return {
        name: (sink.FindLog(context).sample_times(), sink.FindLog(context).data())
        for name, sink in sinks.items()
    }


def port_layout(system):
    """{input name: size}, {output name: size} of a system."""
    inputs = {
        system.get_input_port(i).get_name(): system.get_input_port(i).size()
        for i in range(system.num_input_ports())
    }
    outputs = {
        system.get_output_port(i).get_name(): system.get_output_port(i).size()
        for i in range(system.num_output_ports())
    }
    return inputs, outputs
