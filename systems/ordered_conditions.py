"""A choice on several conditions, tested in the order given, for SymbolicVectorSystem expressions.

A SymbolicVectorSystem walks its expressions at every evaluation, and shares nothing between
them. Drake evaluates an ``if_then_else`` lazily (the condition, then one branch), but tests a
``logical_and``'s operands in an order of its own, each one until one fails. A check whose
conditions are written as nested choices, the one most often false first, therefore stops at
that one on most ticks and never evaluates the others: in the safety supervisor, the
conditions that need the valves' currents or the pressure tracker's residual.

The choice is on truth values only, so its number is the same whichever order the conditions
are tested in: a rewrite from ``logical_and`` keeps a simulation's bits.
"""

from collections.abc import Sequence

from pydrake.symbolic import Expression, Formula, if_then_else

from maskless.systems.named_symbolic_system import as_expression


def if_all(conditions: Sequence[Formula], then, otherwise) -> Expression:
    """``then`` when every condition holds, else ``otherwise``; tested first to last.

    Args:
        conditions: the conditions, the one most often false (and cheap) first.
        then: the value when all hold.
        otherwise: the value when one fails (written once per condition, evaluated once).
    """
    if not conditions:
        raise ValueError("if_all: expected at least one condition")
    result = as_expression(then)
    for condition in reversed(conditions):
        result = if_then_else(condition, result, as_expression(otherwise))
    return result
