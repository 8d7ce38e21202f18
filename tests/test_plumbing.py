"""remove_plumbing: whole vectors instead of a Demultiplexer gathered again, the same numbers."""

import collections

import numpy as np
import pytest
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import (
    ConstantVectorSource,
    Demultiplexer,
    MatrixGain,
    Multiplexer,
)

import maskless.diagrams.closed_loop as closed_loop
from maskless.diagrams.scenario import load_scenario
from maskless.diagrams.simulation import simulate_loop
from maskless.systems.plumbing import remove_plumbing

A = [1.0, 2.0, 3.0]
B = [10.0, 20.0]


def _split_and_gathered(*, order=(0, 1, 2), with_b=False, export_split=False, apply=True):
    """A (3) split into 1 + 2, gathered by a Multiplexer in ``order`` (then B) into a gain."""
    builder = DiagramBuilder()
    a = builder.AddNamedSystem("a", ConstantVectorSource(A))
    split = builder.AddNamedSystem("split", Demultiplexer([1, 2]))
    builder.Connect(a.get_output_port(), split.get_input_port())
    pieces = {0: split.get_output_port(0), 1: split.get_output_port(1)}
    sizes = [pieces[i].size() for i in order[:2]]
    sources = [pieces[i] for i in order[:2]]
    if with_b:
        b = builder.AddNamedSystem("b", ConstantVectorSource(B))
        sizes.append(2)
        sources.append(b.get_output_port())
    gather = builder.AddNamedSystem("gather", Multiplexer(sizes))
    for index, source in enumerate(sources):
        builder.Connect(source, gather.get_input_port(index))
    width = sum(sizes)
    gain = builder.AddNamedSystem("gain", MatrixGain(np.arange(1.0, width + 1)[None, :]))
    builder.Connect(gather.get_output_port(), gain.get_input_port())
    builder.ExportOutput(gain.get_output_port(), "y")
    kept = []
    if export_split:
        builder.ExportOutput(split.get_output_port(1), "second")
        kept.append(split.get_output_port(1))
    if apply:
        remove_plumbing(builder, kept=kept)
    diagram = builder.Build()
    names = collections.Counter(type(s).__name__ for s in diagram.GetSystems())
    y = diagram.GetOutputPort("y").Eval(diagram.CreateDefaultContext())[0]
    return y, names, diagram


def test_a_split_gathered_again_in_order_becomes_the_whole_vector():
    y, names, _ = _split_and_gathered()
    assert y == pytest.approx(np.dot([1, 2, 3], A))  # the gain on A itself
    assert names["Multiplexer"] == 0 and names["Demultiplexer"] == 0


def test_a_split_beside_another_input_leaves_a_smaller_multiplexer():
    y, names, diagram = _split_and_gathered(with_b=True)
    assert y == pytest.approx(np.dot([1, 2, 3, 4, 5], A + B))
    assert names["Demultiplexer"] == 0
    gather = diagram.GetSubsystemByName("gather")
    assert [gather.get_input_port(i).size() for i in range(gather.num_input_ports())] == [3, 2]


def test_a_split_gathered_out_of_order_is_left_alone():
    y, names, _ = _split_and_gathered(order=(1, 0))
    assert y == pytest.approx(np.dot([1, 2, 3], [2.0, 3.0, 1.0]))
    assert names["Multiplexer"] == 1 and names["Demultiplexer"] == 1


def test_an_exported_split_stays():
    y, names, diagram = _split_and_gathered(export_split=True)
    assert y == pytest.approx(np.dot([1, 2, 3], A))
    assert names["Demultiplexer"] == 1
    second = diagram.GetOutputPort("second").Eval(diagram.CreateDefaultContext())
    np.testing.assert_array_equal(second, A[1:])


def test_the_closed_loop_logs_the_same_bits_with_and_without_the_pass(monkeypatch):
    scenario = load_scenario()
    scenario.duration_s = 4.0
    lean = closed_loop.build_closed_loop(scenario)
    monkeypatch.setattr(closed_loop, "remove_plumbing", lambda builder, kept=(): None)
    plain = closed_loop.build_closed_loop(scenario)
    count = collections.Counter
    assert (
        count(type(s).__name__ for s in lean.diagram.GetSystems())["Multiplexer"]
        < count(type(s).__name__ for s in plain.diagram.GetSystems())["Multiplexer"]
    )
    lean_signals = simulate_loop(lean, scenario).signals
    plain_signals = simulate_loop(plain, scenario).signals
    assert lean_signals.keys() == plain_signals.keys()
    for name, signal in plain_signals.items():
        np.testing.assert_array_equal(lean_signals[name].values, signal.values, err_msg=name)
        np.testing.assert_array_equal(lean_signals[name].times_s, signal.times_s, err_msg=name)
