"""Expression nodes a closed-loop tick evaluates, per SymbolicVectorSystem; one JSON line.

Drake's SymbolicVectorSystem walks each of its expressions on its own at every evaluation:
through an if-then-else it evaluates the condition and one branch, through an ``and`` or an
``or`` its operands in the order the formula holds them, until one decides. This script builds
the default closed loop (``record=False``), runs it to ``--time`` s, and walks every system's
outputs and update the same way on the values its Context holds then, counting the operation
nodes visited and the variables read (each read is a hash-table lookup in Drake).

The expressions are captured as the components add them (``add_named_symbolic_system``), so a
component that builds its system some other way is not counted.
"""

import argparse
import json
import math
import sys
from pathlib import Path

from pydrake.common import RandomGenerator
from pydrake.symbolic import ExpressionKind, Formula, FormulaKind, Variable
from pydrake.systems.analysis import Simulator

import maskless.systems.named_symbolic_system as named

sys.path.insert(0, str(Path(__file__).parent))
from machine import machine_description  # noqa: E402

_RELATIONS = {
    FormulaKind.Eq: lambda a, b: a == b,
    FormulaKind.Neq: lambda a, b: a != b,
    FormulaKind.Gt: lambda a, b: a > b,
    FormulaKind.Geq: lambda a, b: a >= b,
    FormulaKind.Lt: lambda a, b: a < b,
    FormulaKind.Leq: lambda a, b: a <= b,
}


class _Walk:
    """Evaluates expressions as Drake does, counting the nodes visited and the variables read."""

    def __init__(self, values: dict[int, float]):
        self.values, self.nodes, self.reads = values, 0, 0

    def __call__(self, e):
        if isinstance(e, Variable):
            self.reads += 1
            return self.values[e.get_id()]
        if isinstance(e, (float, int)):
            return e
        if isinstance(e, Formula):
            return self._formula(e)
        kind = e.get_kind()
        if kind == ExpressionKind.Constant:
            return e.Evaluate()
        if kind == ExpressionKind.Var:
            (variable,) = list(e.GetVariables())
            return self(variable)
        self.nodes += 1
        function, arguments = e.Unapply()
        if kind == ExpressionKind.IfThenElse:
            condition, then, otherwise = arguments
            return self(then) if self(condition) else self(otherwise)
        values = [self(a) for a in arguments]
        try:
            result = function(*values)
        except ZeroDivisionError:
            result = math.inf
        return float(result.Evaluate()) if hasattr(result, "Evaluate") else result

    def _formula(self, f):
        kind = f.get_kind()
        if kind in (FormulaKind.True_, FormulaKind.False_):
            return kind == FormulaKind.True_
        self.nodes += 1
        _, arguments = f.Unapply()
        if kind == FormulaKind.And:
            return all(self(a) for a in arguments)
        if kind == FormulaKind.Or:
            return any(self(a) for a in arguments)
        if kind == FormulaKind.Not:
            return not self(arguments[0])
        return _RELATIONS[kind](self(arguments[0]), self(arguments[1]))


def _capture_expressions():
    """Builds the default loop's systems through a wrapper that keeps each one's expressions."""
    captured = {}
    add = named.add_named_symbolic_system

    def capturing(builder, name, **kwargs):
        captured.setdefault(name, kwargs)
        return add(builder, name, **kwargs)

    def patch():
        # Every module that imported the function by name calls it through its own reference.
        for module in list(sys.modules.values()):
            if getattr(module, "add_named_symbolic_system", None) is add:
                module.add_named_symbolic_system = capturing

    patch()
    from maskless.diagrams.closed_loop import build_closed_loop
    from maskless.diagrams.scenario import load_scenario

    patch()
    return build_closed_loop(load_scenario(), record=False).diagram, captured


def _walk_system(system, context, parts):
    """{nodes, variable_reads} of one evaluation of ``system``'s outputs and update."""
    values = {}
    inputs = [v for _, variables in parts["inputs"] for v in variables]
    if inputs:
        # The port may carry the constants of a ParameterSource after these (not captured).
        port = system.get_input_port().Eval(context)
        values |= dict(zip([v.get_id() for v in inputs], port[: len(inputs)], strict=True))
    state = list(parts.get("state", ()))
    if state:
        vector = context.get_discrete_state_vector().CopyToVector()
        values |= dict(zip([v.get_id() for v in state], vector, strict=True))
    if parts.get("time") is not None:
        values[parts["time"].get_id()] = context.get_time()
    walk = _Walk(values)
    expressions = [e for _, part in parts["outputs"] for e in part]
    expressions += list(parts.get("dynamics", ()))
    try:
        for expression in expressions:
            walk(named.as_expression(expression))
    except KeyError:
        return "not walked: it reads constants from its parameters"
    return {"nodes": walk.nodes, "variable_reads": walk.reads}


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument(
        "--time", type=float, default=60.0, help="simulated seconds before the walk"
    )
    args = parser.parse_args()
    if not args.time >= 0:
        raise ValueError(f"--time {args.time}: expected a time >= 0")
    diagram, captured = _capture_expressions()
    simulator = Simulator(diagram)
    diagram.SetRandomContext(simulator.get_mutable_context(), RandomGenerator(0))
    simulator.AdvanceTo(args.time)
    figures = {
        name: _walk_system(
            diagram.GetSubsystemByName(name),
            diagram.GetSubsystemContext(diagram.GetSubsystemByName(name), simulator.get_context()),
            parts,
        )
        for name, parts in captured.items()
    }
    print(
        json.dumps(
            {
                "benchmark": "expression_nodes",
                "time_s": args.time,
                "systems": figures,
                "machine": machine_description(),
            }
        )
    )


if __name__ == "__main__":
    main()
