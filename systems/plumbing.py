"""Removing the Multiplexers and Demultiplexers a built loop does not need, before it is built.

Components give their SymbolicVectorSystem named ports by splitting its one output vector with a
Demultiplexer and gathering its inputs with a Multiplexer (``named_symbolic_system``). Where one
component's whole output feeds the next in order (a camera's distance and validity into its
filter, a filter's three outputs into the fusion, a component's outputs into a log), the split is
gathered again at once. Each such system costs every simulation step its cache-invalidation work
whether its values are read or not (measured: a Demultiplexer nobody reads, about 1.5 µs a step
in the closed loop), so ``remove_plumbing`` connects the whole vector instead, which gives the
consumer the same numbers in the same order.
"""

from collections.abc import Collection

from pydrake.systems.framework import DiagramBuilder, OutputPort, System
from pydrake.systems.primitives import Demultiplexer, Multiplexer

_Source = tuple[str, int]  # (system name, output port index)


def remove_plumbing(builder: DiagramBuilder, kept: Collection[OutputPort] = ()) -> None:
    """Connects whole vectors where a Demultiplexer's outputs feed a Multiplexer in order.

    A Multiplexer whose consecutive inputs take every output of one Demultiplexer, in order,
    takes that Demultiplexer's input instead (one port for the run); one left with a single input
    is bypassed. A Demultiplexer left with no output connected is removed.

    Args:
        builder: a builder not yet built; changed in place.
        kept: output ports to keep (those the diagram exports: the builder does not list them).
    """
    kept_sources = {(port.get_system().get_name(), int(port.get_index())) for port in kept}
    systems = {system.get_name(): system for system in builder.GetSystems()}
    for mux in [s for s in systems.values() if isinstance(s, Multiplexer)]:
        _gather_whole_vectors(builder, systems, mux, kept_sources)
    connections = _sources_by_input(builder)
    read = set(connections.values())
    for demux in [s for s in builder.GetSystems() if isinstance(s, Demultiplexer)]:
        name = demux.get_name()
        outputs = {(name, index) for index in range(demux.num_output_ports())}
        if not (outputs & (read | kept_sources)):
            builder.RemoveSystem(demux)


def _sources_by_input(builder: DiagramBuilder) -> dict[tuple[str, int], _Source]:
    """(consumer name, input index) -> (source name, output index) for every connection."""
    return {
        (consumer.get_name(), int(input_index)): (source.get_name(), int(output_index))
        for (consumer, input_index), (source, output_index) in builder.connection_map().items()
    }


def _gather_whole_vectors(
    builder: DiagramBuilder, systems: dict[str, System], mux: Multiplexer, kept_sources
) -> None:
    connections = _sources_by_input(builder)
    name = mux.get_name()
    inputs = [connections.get((name, i)) for i in range(mux.num_input_ports())]
    if None in inputs:
        return  # an input exported or left open: not ours to rewire
    gathered, sizes, index = [], [], 0
    while index < len(inputs):
        source_name, output_index = inputs[index]
        demux = systems[source_name]
        whole = isinstance(demux, Demultiplexer) and output_index == 0
        count = demux.num_output_ports() if whole else 1
        if whole and inputs[index : index + count] == [(source_name, i) for i in range(count)]:
            gathered.append(connections[(source_name, 0)])
            sizes.append(demux.get_input_port(0).size())
            index += count
        else:
            gathered.append(inputs[index])
            sizes.append(mux.get_input_port(index).size())
            index += 1
    if len(gathered) == len(inputs):
        return
    consumers = [
        (consumer, input_index)
        for (consumer, input_index), source in connections.items()
        if source == (name, 0)
    ]
    if (name, 0) in kept_sources:
        return  # its output is exported: the Multiplexer must stay, as it is
    builder.RemoveSystem(mux)
    del systems[name]
    if len(gathered) == 1:
        output = _output_port(systems, gathered[0])
    else:
        replacement = builder.AddNamedSystem(name, Multiplexer(sizes))
        systems[name] = replacement
        for port_index, source in enumerate(gathered):
            builder.Connect(_output_port(systems, source), replacement.get_input_port(port_index))
        output = replacement.get_output_port()
    for consumer, input_index in consumers:
        builder.Connect(output, systems[consumer].get_input_port(input_index))


def _output_port(systems: dict[str, System], source: _Source) -> OutputPort:
    return systems[source[0]].get_output_port(source[1])
