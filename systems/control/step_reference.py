"""The head-height reference: steps at fixed times to levels a Context can change.

r(t) = level_k for t_k <= t < t_(k+1), with t_0 = 0 (the start level) and the step times given.
The levels are numeric parameters (``{name}.parameters``, a ``ParameterSource``), so a Monte Carlo
over patients writes each trial's steps into one built loop (``set_step_levels``) instead of
building a loop per trial; the step times shape the system and stay as built. The output is a
SymbolicVectorSystem of time (C++), as cheap per evaluation as the TrajectorySource it replaces,
and it gives the same numbers: each level is the number it was built from, chosen by comparisons
of time alone.
"""

from collections.abc import Sequence

import numpy as np
from pydrake.symbolic import Expression, Variable, if_then_else
from pydrake.systems.framework import Context, Diagram, DiagramBuilder

from maskless.errors import ConfigError
from maskless.systems.named_symbolic_system import (
    PortMap,
    add_named_symbolic_system,
    parameter_source,
)


def add_step_reference(
    builder: DiagramBuilder, step_times_s: Sequence[float], levels: Sequence[float], name: str
) -> PortMap:
    """Adds a step reference holding ``levels[0]`` from t = 0 and ``levels[k]`` from step k.

    .. pydrake_system::

        name: step_reference
        output_ports:
        - reference

    Args:
        builder: where the systems go.
        step_times_s: when each step happens (s), increasing.
        levels: the start level, then the level after each step (one more than the times).
        name: the system's name; ``{name}.parameters`` holds the levels.

    Raises:
        ConfigError: the times are not increasing, or there is not one level more than times.
    """
    times = [float(t) for t in step_times_s]
    if len(levels) != len(times) + 1:
        raise ConfigError(
            f"{name}: {len(levels)} levels for {len(times)} step times; expected the start "
            "level and one level per step"
        )
    if any(later <= earlier for earlier, later in zip(times, times[1:], strict=False)):
        raise ConfigError(f"{name}: step times {times} are not increasing")
    time = Variable("t")
    level_variables = [Variable(f"level_{k}") for k in range(len(levels))]
    output = Expression(level_variables[0])
    # The latest step passed wins: nested so each level is selected whole, never summed.
    for step_time, level in zip(times, level_variables[1:], strict=True):
        output = if_then_else(time >= step_time, level, output)
    return add_named_symbolic_system(
        builder,
        name,
        inputs=(),
        outputs=[("reference", [output])],
        time=time,
        parameters=list(zip(level_variables, (float(v) for v in levels), strict=True)),
    )


def set_step_levels(diagram: Diagram, context: Context, name: str, levels) -> None:
    """Writes new levels (start level first) into the step reference ``name`` of ``diagram``.

    Raises:
        ConfigError: ``levels`` has not one entry per level the reference was built with.
    """
    source = parameter_source(diagram, name)
    source.set_values(diagram.GetMutableSubsystemContext(source, context), np.asarray(levels))


def step_levels(diagram: Diagram, context: Context, name: str) -> np.ndarray:
    """The levels (start level first) the step reference ``name`` holds in ``context``."""
    source = parameter_source(diagram, name)
    return source.get_values(diagram.GetSubsystemContext(source, context))
