"""if_all: the choice a logical_and makes, with its conditions tested in order."""

import itertools
import math

import numpy as np
import pytest
from pydrake.symbolic import Variable, if_then_else, logical_and
from pydrake.systems.primitives import SymbolicVectorSystem

from maskless.systems.ordered_conditions import if_all

x, y, z = Variable("x"), Variable("y"), Variable("z")


@pytest.mark.parametrize(
    "values", list(itertools.product([-1.0, 1.0, math.nan], repeat=3)), ids=str
)
def test_it_chooses_what_a_logical_and_chooses(values):
    # Evaluated as a SymbolicVectorSystem evaluates them (a Python Environment refuses NaN).
    conditions = [x > 0, y <= 0.5, z >= -2]
    system = SymbolicVectorSystem(
        input=np.array([x, y, z]),
        output=np.array(
            [
                if_then_else(logical_and(*conditions), 1.0, 2.0),
                if_all(conditions, 1.0, 2.0),
            ]
        ),
    )
    context = system.CreateDefaultContext()
    system.get_input_port().FixValue(context, np.array(values))
    expected, got = system.get_output_port().Eval(context)
    assert got == expected


def test_a_false_condition_stops_the_tests_after_it():
    # Evaluation needs a value for every variable it reaches, so a missing one shows which
    # conditions were tested.
    chosen = if_all([x > 0, y > 0], 1.0, 2.0)
    assert chosen.Evaluate({x: -1.0}) == 2.0
    with pytest.raises(RuntimeError):
        chosen.Evaluate({x: 1.0})


def test_no_condition_is_refused():
    with pytest.raises(ValueError, match="at least one condition"):
        if_all([], 1.0, 0.0)
