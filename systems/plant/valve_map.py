"""The static input nonlinearity of the paper's Hammerstein structure (Sec. VI, Fig. 9).

A normally closed SMC PVQ proportional valve passes no air below its starting current and saturates
above its largest current; in between, the identified model's current enters linearly. The
identification record's currents are 0 or 60-191 mA and clipped at 165 mA (shared/DESIGN.md).
"""

from pydrake.symbolic import Expression, Variable, if_then_else
from pydrake.symbolic import min as symbolic_min


def effective_valve_current(current, starting_current, saturation_current):
    """The current that reaches the linear dynamics (A).

    It is 0 below ``starting_current``, clipped above ``saturation_current``, unchanged in between.

    Works on floats and on ``pydrake.symbolic`` expressions, so the same map runs inside a
    SymbolicVectorSystem and in analysis code.
    """
    if isinstance(current, Expression | Variable):
        return if_then_else(
            current < starting_current, Expression(0.0), symbolic_min(current, saturation_current)
        )
    if current < starting_current:
        return 0.0
    return min(float(current), saturation_current)
