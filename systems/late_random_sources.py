"""RandomSources added after every other system: switching a model on changes no other draw.

Drake's ``SetRandomContext`` seeds a Diagram's random systems one after another, in the order they
were added. A model that adds a RandomSource in the middle of a loop (the patient's motion before
the cameras, a camera's error between two cameras) would hand every later source a different
seed: a run with the motion switched on, even at zero amplitude, would see other camera noise, and
runs with and without a model could not be compared pair by pair. Models that may be switched on
ask for their sources here instead, and the loop adds them last.
"""

from dataclasses import dataclass, field

from pydrake.systems.framework import DiagramBuilder, InputPort
from pydrake.systems.primitives import RandomSource


@dataclass
class LateRandomSources:
    """RandomSources waiting to be added, each with the input port it feeds."""

    pending: list[tuple[str, RandomSource, InputPort]] = field(default_factory=list)

    def add_all(self, builder: DiagramBuilder) -> None:
        """Adds and connects every waiting source, in the order asked for."""
        for name, source, port in self.pending:
            added = builder.AddNamedSystem(name, source)
            builder.Connect(added.get_output_port(), port)
        self.pending.clear()


def add_random_source(
    builder: DiagramBuilder,
    name: str,
    source: RandomSource,
    port: InputPort,
    late: LateRandomSources | None = None,
) -> None:
    """Adds ``source`` as ``name`` feeding ``port``: now, or with ``late``, when the loop says."""
    if late is None:
        builder.Connect(builder.AddNamedSystem(name, source).get_output_port(), port)
    else:
        late.pending.append((name, source, port))
