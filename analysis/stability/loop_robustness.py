"""Closed-loop poles and margins of the controllers, and their robustness.

Two loops, each a discrete plant closed by its controller written as a state-space model from the
measured height deviation to the command deviation (``analysis.stability.margins`` conventions):

- the paper's LQG (Eq. 29-34) on the paper's identified model (Eq. 26): ``analyze_paper_loop``
  shows how little this loop does. With B ~ 1e-7 mm/mA the loop gain stays tiny at every
  frequency, the regulator leaves the plant's poles where they were, and the closed loop is the
  open loop plus the estimator's own poles.
- the offset-free LQG on the pneumatic plant linearised at the lift where the head rests
  (``plant_at_lift``), seen through the measurement's delay: ``robustness_cases`` varies the lift,
  the head's mass and extra sensor latency while the controller stays the one designed at its
  operating lift for the nominal head.

Pure functions on models and designs; ``stability_plots`` draws the results.
"""

import itertools
import math
import operator
from dataclasses import dataclass, replace

import numpy as np
from scipy.optimize import brentq, minimize_scalar

from maskless.analysis.stability.margins import (
    LOWEST_FREQUENCY_FRACTION,
    Margins,
    added_delay_samples_loop,
    discrete_margins,
    feedback_loop_poles,
    loop_transfer,
)
from maskless.systems.control.offset_free_lqg import OffsetFreeLqgDesign
from maskless.systems.control.offset_free_lqg import (
    controller_state_space as offset_free_controller_state_space,
)
from maskless.systems.control.paper_lqg import LqgDesign
from maskless.systems.control.paper_lqg import closed_loop_poles as lqg_closed_loop_poles
from maskless.systems.control.paper_lqg import (
    controller_state_space as lqg_controller_state_space,
)
from maskless.systems.control.valve_allocation import SplitRangeAllocation
from maskless.systems.linear_model import LinearModel, stable
from maskless.systems.plant.pneumatic_design import (
    AllocationPoint,
    allocation_point,
    pneumatic_design_model,
)
from maskless.systems.plant.pneumatic_physics import LIFT, PneumaticParameters
from maskless.systems.plant.pneumatic_plant import equilibrium_state

# The holding command is found to this tolerance (m of lift command).
_COMMAND_TOLERANCE_M = 1e-12


@dataclass(frozen=True)
class LoopAnalysis:
    """One plant closed by one controller, u = K(z) y (the controller carries its own sign).

    Attributes:
        plant: G, from the command deviation to the measured output deviation.
        controller: K, from the measured output deviation to the command deviation.
        loop: the loop transfer L = -K G, broken at the plant input (``loop_transfer``).
        poles: the closed loop's poles, every mode of plant and controller (complex).
        margins: gain, phase and delay margins of ``loop``.
    """

    plant: LinearModel
    controller: LinearModel
    loop: LinearModel
    poles: np.ndarray
    margins: Margins

    @property
    def max_pole_magnitude(self) -> float:
        """The largest closed-loop pole magnitude; below 1 when the loop is stable."""
        return float(np.max(np.abs(self.poles)))

    @property
    def stable(self) -> bool:
        """Every closed-loop pole strictly inside the unit circle."""
        return stable(self.poles)


def analyze_loop(
    plant: LinearModel, controller: LinearModel, n_frequencies: int = 4000
) -> LoopAnalysis:
    """Closed-loop poles and margins of ``plant`` closed by ``controller`` as written.

    Args:
        plant: G (the sample period shared with the controller).
        controller: K, with its own sign (u = K(z) y).
        n_frequencies: the margins' frequency grid (``discrete_margins``).
    """
    loop = loop_transfer(plant, controller)
    return LoopAnalysis(
        plant=plant,
        controller=controller,
        loop=loop,
        poles=feedback_loop_poles(plant, controller),
        margins=discrete_margins(loop, n_frequencies),
    )


def loop_gain_peak(loop: LinearModel, n_frequencies: int = 4000) -> tuple[float, float]:
    """(max |L|, the frequency where it occurs (rad/s)) over the margins' band.

    The maximum of a log grid of ``n_frequencies`` points from 1e-6 of the Nyquist frequency up to
    it, refined by a bounded search between the grid points either side.

    Args:
        loop: L, with no pole on the unit circle.
        n_frequencies: grid points, at least 3.

    Raises:
        ValueError: ``n_frequencies`` < 3.
    """
    if n_frequencies < 3:
        raise ValueError(f"n_frequencies = {n_frequencies}: expected at least 3")
    nyquist = loop.nyquist_rad_s
    # The margins' band (``discrete_margins``).
    omega = np.geomspace(LOWEST_FREQUENCY_FRACTION * nyquist, nyquist, n_frequencies)
    magnitude = np.abs(loop.frequency_response(omega))
    best = int(np.argmax(magnitude))
    low, high = omega[max(best - 1, 0)], omega[min(best + 1, omega.size - 1)]
    refined = minimize_scalar(
        lambda w: -abs(loop.frequency_response(w)),
        bounds=(low, high),
        method="bounded",
        options={"xatol": 1e-9 * high},
    )
    if -refined.fun > magnitude[best]:
        return float(-refined.fun), float(refined.x)
    return float(magnitude[best]), float(omega[best])


# --- The paper's LQG on the paper's model ---------------------------------------------------------


@dataclass(frozen=True)
class PaperLoopAnalysis:
    """The paper's LQG on the paper's model.

    Attributes:
        loop: poles and margins of the closed loop.
        open_loop_poles: eig(A) of the model.
        regulator_poles: eig(A - B K).
        estimator_poles: eig(A - L C).
        regulator_pole_shift: the largest distance from a regulator pole to the nearest
            open-loop pole: how far the state feedback moves the plant's poles.
        peak_loop_gain: max |L| over frequency (``loop_gain_peak``).
        peak_loop_gain_frequency_rad_s: where it occurs (rad/s).
    """

    loop: LoopAnalysis
    open_loop_poles: np.ndarray
    regulator_poles: np.ndarray
    estimator_poles: np.ndarray
    regulator_pole_shift: float
    peak_loop_gain: float
    peak_loop_gain_frequency_rad_s: float


def analyze_paper_loop(
    model: LinearModel, design: LqgDesign, n_frequencies: int = 4000
) -> PaperLoopAnalysis:
    """Poles, loop gain and margins of the paper's LQG closing the loop on ``model``.

    Args:
        model: the paper's identified model (``paper_parameters.paper_identified_model``).
        design: the paper's gains on it (``paper_lqg.design_lqg``).
        n_frequencies: frequency grid of the margins and the loop gain's peak.
    """
    loop = analyze_loop(model, lqg_controller_state_space(model, design), n_frequencies)
    poles = lqg_closed_loop_poles(model, design)
    shift = max(float(np.min(np.abs(poles["open_loop"] - pole))) for pole in poles["regulator"])
    peak, peak_frequency = loop_gain_peak(loop.loop, n_frequencies)
    return PaperLoopAnalysis(
        loop=loop,
        open_loop_poles=poles["open_loop"],
        regulator_poles=poles["regulator"],
        estimator_poles=poles["estimator"],
        regulator_pole_shift=shift,
        peak_loop_gain=peak,
        peak_loop_gain_frequency_rad_s=peak_frequency,
    )


# --- The offset-free LQG on the linearised pneumatic plant ---------------------------------------


def steady_lift_at_command_m(
    p: PneumaticParameters, allocation: SplitRangeAllocation, command_m: float
) -> float:
    """The lift (m) at which the plant ``p`` rests under the allocation's currents for a command.

    The currents are those the allocation gives for ``command_m``.
    """
    inlet, outlet = allocation.currents(command_m)
    return float(equilibrium_state(p, float(inlet), float(outlet))[LIFT])


def holdable_lift_range_m(
    p: PneumaticParameters, allocation: SplitRangeAllocation
) -> tuple[float, float]:
    """(lowest, highest) lift (m) the plant ``p`` rests at over the allocation's command range.

    The lowest is with the outlet fully open (inlet shut), the highest with the inlet fully open
    (outlet shut).
    """
    low, high = allocation.command_range
    return (
        steady_lift_at_command_m(p, allocation, low),
        steady_lift_at_command_m(p, allocation, high),
    )


def command_holding_lift_m(
    p: PneumaticParameters, allocation: SplitRangeAllocation, lift_m: float
) -> float:
    """The lift command (m) whose allocated currents hold the plant ``p`` at rest at ``lift_m``.

    This is where the offset-free controller's command settles (its disturbance estimate absorbs
    any difference between the plant and the nominal head the allocation inverts).

    Args:
        p: the plant (say, a heavier head than the nominal one).
        allocation: the controller's split-range allocation.
        lift_m: the lift to hold (m).

    Raises:
        ValueError: ``lift_m`` lies outside ``holdable_lift_range_m``.
    """
    lowest, highest = holdable_lift_range_m(p, allocation)
    if not (math.isfinite(lift_m) and lowest <= lift_m <= highest):
        raise ValueError(
            f"lift_m = {lift_m}: a {p.head_mass_kg:g} kg head rests between {lowest:.6g} and "
            f"{highest:.6g} m over the allocation's range"
        )
    low, high = allocation.command_range
    return float(
        brentq(
            lambda command: steady_lift_at_command_m(p, allocation, command) - lift_m,
            low,
            high,
            xtol=_COMMAND_TOLERANCE_M,
        )
    )


@dataclass(frozen=True)
class OperatingPoint:
    """Where the loop is linearised.

    Attributes:
        lift_m: the lift the head rests at (m).
        command_m: the lift command that holds it there (m).
        valves: the allocation's currents there and the valve the command moves.
    """

    lift_m: float
    command_m: float
    valves: AllocationPoint


def plant_at_lift(
    p: PneumaticParameters,
    allocation: SplitRangeAllocation,
    lift_m: float,
    sample_period_s: float,
    measurement_delay_samples: int,
) -> tuple[LinearModel, OperatingPoint]:
    """The pneumatic plant as the controller sees it with the head at rest at ``lift_m``.

    That is Drake's linearisation at the holding command (``pneumatic_design_model``), from the
    lift command deviation to the head height deviation (m), followed by the measurement's delay.

    Args:
        p: the plant's parameters (the head being positioned).
        allocation: the controller's split-range allocation.
        lift_m: where the head rests (m).
        sample_period_s: the controller's period (s).
        measurement_delay_samples: whole ticks between the head's height and the measurement
            the controller reads.

    Raises:
        ValueError: ``lift_m`` cannot be held, or the delay is not a whole number >= 0.
    """
    command = command_holding_lift_m(p, allocation, lift_m)
    # Only the dynamics enter the loop: the model's operating output is where the allocation's
    # nominal head would rest at this command, not ``lift_m``.
    plant = pneumatic_design_model(p, allocation, command, sample_period_s)
    point = OperatingPoint(lift_m, command, allocation_point(allocation, command))
    return added_delay_samples_loop(plant, measurement_delay_samples), point


@dataclass(frozen=True)
class RobustnessCase:
    """The offset-free loop at one lift, head mass and extra sensor latency.

    Attributes:
        lift_m: where the head rests (m).
        mass_factor: the head's mass over the given plant's.
        head_mass_kg: the head's mass (kg).
        extra_delay_samples: sensor latency beyond the one designed for (ticks).
        operating_point: the holding command and valve currents.
        analysis: poles and margins.
    """

    lift_m: float
    mass_factor: float
    head_mass_kg: float
    extra_delay_samples: int
    operating_point: OperatingPoint
    analysis: LoopAnalysis

    @property
    def extra_delay_s(self) -> float:
        """The extra latency in seconds."""
        return self.extra_delay_samples * self.analysis.plant.sample_period_s


def robustness_cases(
    p: PneumaticParameters,
    allocation: SplitRangeAllocation,
    design: OffsetFreeLqgDesign,
    lifts_m,
    mass_factors,
    extra_delays_samples,
    n_frequencies: int = 4000,
) -> list[RobustnessCase]:
    """The fixed controller on the plant at every combination of lift, head mass and latency.

    The controller is ``design`` throughout (designed once, for the nominal head at its operating
    lift); the plant is ``p`` with its head mass scaled, linearised where it rests at each lift,
    and its measurement arrives ``design.measurement_delay_samples`` ticks late (the delay the
    closed loop has) plus each extra delay.

    Args:
        p: the plant's parameters.
        allocation: the controller's split-range allocation.
        design: the offset-free LQG design.
        lifts_m: lifts to hold (m).
        mass_factors: factors on ``p.head_mass_kg``, each positive.
        extra_delays_samples: extra sensor latencies (whole ticks), each >= 0.
        n_frequencies: the margins' frequency grid.

    Returns:
        One case per (lift, mass factor, extra delay), in that nesting order.

    Raises:
        ValueError: a lift that a head cannot hold, a mass factor <= 0, or an extra delay that
            is not a whole number >= 0.
    """
    for factor in mass_factors:
        if not (math.isfinite(factor) and factor > 0):
            raise ValueError(f"mass_factors: {factor} is not a positive factor")
    delays = []
    for extra in extra_delays_samples:
        try:
            if isinstance(extra, bool) or operator.index(extra) < 0:
                raise TypeError
        except TypeError:
            raise ValueError(
                f"extra_delays_samples: {extra!r} is not a whole number of ticks >= 0"
            ) from None
        delays.append(operator.index(extra))
    controller = offset_free_controller_state_space(design)
    period = design.model.sample_period_s
    cases = []
    for lift, factor in itertools.product(lifts_m, mass_factors):
        plant_parameters = replace(p, head_mass_kg=factor * p.head_mass_kg)
        plant, point = plant_at_lift(
            plant_parameters, allocation, lift, period, design.measurement_delay_samples
        )
        for extra in delays:
            cases.append(
                RobustnessCase(
                    lift_m=float(lift),
                    mass_factor=float(factor),
                    head_mass_kg=plant_parameters.head_mass_kg,
                    extra_delay_samples=extra,
                    operating_point=point,
                    analysis=analyze_loop(
                        added_delay_samples_loop(plant, extra), controller, n_frequencies
                    ),
                )
            )
    return cases
