"""The static input nonlinearity of the paper's Hammerstein structure (Sec. VI, Fig. 9).

Two forms: ``effective_valve_current``, the paper plant's assumed dead zone and clip, and
``ValveMap``, a monotone map identified from data (``analysis.identification.hammerstein``).

A normally closed SMC PVQ proportional valve passes no air below its starting current and saturates
above its largest current; in between, the identified model's current enters linearly. The
identification record's currents are 0 or 60-191 mA and clipped at 165 mA (shared/DESIGN.md).
"""

import sys
from dataclasses import dataclass

import numpy as np

from maskless.errors import ModelError


def _is_symbolic(value) -> bool:
    """Whether ``value`` is a ``pydrake.symbolic`` expression or variable.

    Asked of the loaded module, not imported: no symbolic value exists before its maker imported
    pydrake, and a float caller (`maskless identify` loading a model file) never pays for Drake.
    """
    symbolic = sys.modules.get("pydrake.symbolic")
    return symbolic is not None and isinstance(value, symbolic.Expression | symbolic.Variable)


def effective_valve_current(current, starting_current, saturation_current):
    """The current that reaches the linear dynamics (A).

    It is 0 below ``starting_current``, clipped above ``saturation_current``, unchanged in between.

    Works on floats and on ``pydrake.symbolic`` expressions, so the same map runs inside a
    SymbolicVectorSystem and in analysis code.
    """
    if _is_symbolic(current):
        from pydrake.symbolic import Expression, if_then_else
        from pydrake.symbolic import min as symbolic_min

        return if_then_else(
            current < starting_current, Expression(0.0), symbolic_min(current, saturation_current)
        )
    if current < starting_current:
        return 0.0
    return min(float(current), saturation_current)


@dataclass(frozen=True, eq=False)  # eq=False: element-wise array equality has no single truth
class ValveMap:
    """A valve's identified static map: coil current to effective opening, monotone, 0 to 1.

    Piecewise linear through the knots, flat beyond them: no opening at or below the first knot
    (the starting current) and full opening at and above the last (the saturation current). A
    Hammerstein model's linear part multiplies the opening, so the map carries no gain: its scale
    is fixed by the opening being 1 at saturation.

    Attributes:
        currents: increasing knot currents (the model's input unit), at least two; the first is the
            starting current, the last the saturation current.
        openings: the opening at each knot, non-decreasing from exactly 0 to exactly 1.

    Raises:
        ModelError: naming the field, for a shape, a non-finite entry or a map that is not
            monotone from 0 to 1.
    """

    currents: np.ndarray
    openings: np.ndarray

    def __post_init__(self):
        """Checks the knots (ModelError) and stores them as read-only float arrays."""
        currents = np.array(self.currents, dtype=float)
        openings = np.array(self.openings, dtype=float)
        if currents.ndim != 1 or currents.size < 2 or openings.shape != currents.shape:
            raise ModelError(
                f"currents and openings must be 1-D of one length >= 2, got shapes "
                f"{currents.shape} and {openings.shape}"
            )
        if not (np.all(np.isfinite(currents)) and np.all(np.isfinite(openings))):
            raise ModelError("currents and openings must be finite")
        if not np.all(np.diff(currents) > 0):
            raise ModelError(f"currents = {currents.tolist()}: expected increasing knots")
        if openings[0] != 0.0 or openings[-1] != 1.0 or np.any(np.diff(openings) < 0):
            raise ModelError(
                f"openings = {openings.tolist()}: expected non-decreasing from 0 to 1 (monotone)"
            )
        for name, value in (("currents", currents), ("openings", openings)):
            value.setflags(write=False)
            object.__setattr__(self, name, value)

    @property
    def starting_current(self) -> float:
        """The current below which the valve passes nothing (the first knot)."""
        return float(self.currents[0])

    @property
    def saturation_current(self) -> float:
        """The current above which the valve opens no further (the last knot)."""
        return float(self.currents[-1])

    def opening(self, current):
        """The opening (0..1) at ``current``: a float, an array, or a symbolic expression."""
        if _is_symbolic(current):
            from pydrake.symbolic import Expression
            from pydrake.symbolic import max as symbolic_max
            from pydrake.symbolic import min as symbolic_min

            result = Expression(0.0)
            for k in range(self.currents.size - 1):
                low, high = float(self.currents[k]), float(self.currents[k + 1])
                slope = (self.openings[k + 1] - self.openings[k]) / (high - low)
                if slope != 0.0:
                    segment = symbolic_min(symbolic_max(current, low), high) - low
                    result = result + float(slope) * segment
            return result
        return np.interp(current, self.currents, self.openings)

    def current_for_opening(self, opening):
        """The smallest current that gives ``opening`` (0..1): the map's inverse, per element.

        A flat run of the map is a jump of its inverse: its own opening goes to the run's first
        knot, anything above it to the segment after the run's last knot.
        """
        opening = np.clip(np.asarray(opening, dtype=float), 0.0, 1.0)
        upper = np.clip(np.searchsorted(self.openings, opening, side="left"), 1, None)
        lower = upper - 1
        low, high = self.openings[lower], self.openings[upper]
        at_knot = self.openings[np.clip(upper, None, self.openings.size - 1)] == opening
        fraction = np.divide(opening - low, high - low, out=np.ones_like(opening), where=high > low)
        between = self.currents[lower] + fraction * (self.currents[upper] - self.currents[lower])
        return np.where(
            at_knot | (opening == 0.0), self.currents[np.where(opening == 0.0, 0, upper)], between
        )

    def scaled(self, factor: float) -> "ValveMap":
        """The same map with its currents in another unit (``factor`` new units per old unit)."""
        return ValveMap(self.currents * factor, self.openings)
