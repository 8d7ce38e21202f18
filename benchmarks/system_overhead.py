"""Why the closed loop is built the way it is: three ratios measured in one run, one JSON line.

1. A local Kalman filter step (Eq. 8-9) as a Python LeafSystem vs as the SymbolicVectorSystem the
   toolkit uses (systems/sensing/local_kalman_filter.py), per update.
2. A chain of 20 SymbolicVectorSystems added flat to one Diagram vs each wrapped in its own
   Diagram, per simulation step (diagrams/closed_loop.py adds components flat).
3. MCAP payload encoding: the writer's %-template path vs json.dumps (a NaN in every channel
   forces the json.dumps path), for the same 600 s closed-loop recording.
"""

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from pydrake.symbolic import Variable
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder, LeafSystem
from pydrake.systems.primitives import ConstantVectorSource, SymbolicVectorSystem

from maskless.diagrams.scenario import load_scenario
from maskless.diagrams.simulation import simulate
from maskless.recording import Channel, write_recording
from maskless.systems.sensing.local_kalman_filter import (
    LocalFilterConfig,
    make_local_kalman_filter,
    predict,
    update,
)

sys.path.insert(0, str(Path(__file__).parent))
from machine import machine_description  # noqa: E402

PERIOD_S = 1 / 15
SIGMA_A2, SIGMA_R2 = 2e-3, 7e-5


class PythonKalmanFilter(LeafSystem):
    """The same filter step with numpy in a Python callback (the alternative we measured)."""

    def __init__(self):
        super().__init__()
        self._distance = self.DeclareVectorInputPort("distance_m", 1)
        self._valid = self.DeclareVectorInputPort("valid", 1)
        state = self.DeclareDiscreteState([0.2, 0.0, 1e-4, 0.0, 4e-4])
        self.DeclarePeriodicDiscreteUpdateEvent(PERIOD_S, 0.0, self._step)
        self.DeclareStateOutputPort("state", state)

    def _step(self, context, discrete_state):
        s = context.get_discrete_state_vector().CopyToVector()
        x, P = s[:2], np.array([[s[2], s[3]], [s[3], s[4]]])
        x, P = predict(x, P, PERIOD_S, SIGMA_A2)
        if self._valid.Eval(context)[0] > 0.5:
            x, P = update(x, P, 1.0 - self._distance.Eval(context)[0], SIGMA_R2)
        discrete_state.set_value([x[0], x[1], P[0, 0], P[0, 1], P[1, 1]])


def seconds_per_filter_update(make_filter, duration_s):
    builder = DiagramBuilder()
    local_filter = builder.AddSystem(make_filter())
    for port, value in (("distance_m", 0.8), ("valid", 1.0)):
        source = builder.AddSystem(ConstantVectorSource([value]))
        builder.Connect(source.get_output_port(), local_filter.GetInputPort(port))
    simulator = Simulator(builder.Build())
    simulator.Initialize()
    start = time.perf_counter()
    simulator.AdvanceTo(duration_s)
    return (time.perf_counter() - start) / simulator.get_num_discrete_updates()


def symbolic_filter():
    return make_local_kalman_filter(
        "kf",
        camera_height_m=1.0,
        frame_period_s=PERIOD_S,
        acceleration_variance_m2_s4=SIGMA_A2,
        measurement_variance_m2=SIGMA_R2,
        initial_height_m=0.2,
        valid_range_m=(0.4, 4.0),
        config=LocalFilterConfig(initial_position_std_m=0.01, initial_velocity_std_m_s=0.02),
        detection=load_scenario().fault_detection,
    )


def seconds_per_step(nested, count=20, duration_s=100.0):
    def core(i):
        x, u = Variable(f"x{i}"), Variable(f"u{i}")
        return SymbolicVectorSystem(
            state=[x],
            input=[u],
            dynamics=[0.5 * x + u],
            output=[x],
            time_period=0.01 * (1 + 0.1 * (i % 3)),
        )

    def wrapped(i):
        inner = DiagramBuilder()
        system = inner.AddSystem(core(i))
        inner.ExportInput(system.get_input_port(), "in")
        inner.ExportOutput(system.get_output_port(), "out")
        return inner.Build()

    builder = DiagramBuilder()
    previous = builder.AddSystem(ConstantVectorSource([1.0])).get_output_port()
    for i in range(count):
        system = builder.AddSystem(wrapped(i) if nested else core(i))
        builder.Connect(previous, system.get_input_port())
        previous = system.get_output_port()
    simulator = Simulator(builder.Build())
    simulator.Initialize()
    start = time.perf_counter()
    simulator.AdvanceTo(duration_s)
    return (time.perf_counter() - start) / simulator.get_num_steps_taken()


def seconds_to_write(channels, repeats):
    best = float("inf")
    with tempfile.TemporaryDirectory() as folder:
        for _ in range(repeats):
            start = time.perf_counter()
            write_recording(Path(folder) / "run.mcap", channels)
            best = min(best, time.perf_counter() - start)
    return best


def with_a_nan(channel):
    columns = {}
    for name, column in channel.columns.items():
        column = np.array(column)
        if column.dtype.kind == "f":
            column.flat[0] = np.nan
        columns[name] = column
    return Channel(channel.topic, channel.times_ns, columns)


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--repeats", type=int, default=3, help="runs per figure; the best counts")
    args = parser.parse_args()
    python_s = min(seconds_per_filter_update(PythonKalmanFilter, 300) for _ in range(args.repeats))
    symbolic_s = min(seconds_per_filter_update(symbolic_filter, 300) for _ in range(args.repeats))
    flat_s = min(seconds_per_step(nested=False) for _ in range(args.repeats))
    nested_s = min(seconds_per_step(nested=True) for _ in range(args.repeats))
    config = load_scenario()
    config.duration_s = 600.0
    channels = simulate(config).recording_channels()
    template_s = seconds_to_write(channels, args.repeats)
    json_s = seconds_to_write([with_a_nan(c) for c in channels], args.repeats)
    print(
        json.dumps(
            {
                "benchmark": "system_overhead",
                "filter_update_us": {
                    "python_leaf_system": python_s * 1e6,
                    "symbolic": symbolic_s * 1e6,
                },
                "python_over_symbolic": python_s / symbolic_s,
                "step_us_20_systems": {"flat": flat_s * 1e6, "each_in_own_diagram": nested_s * 1e6},
                "nested_over_flat": nested_s / flat_s,
                "mcap_write_s": {
                    "template": template_s,
                    "json_dumps": json_s,
                    "messages": sum(len(c.times_ns) for c in channels),
                },
                "json_dumps_over_template": json_s / template_s,
                "machine": machine_description(),
            }
        )
    )


if __name__ == "__main__":
    main()
