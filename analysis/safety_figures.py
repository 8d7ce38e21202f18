"""What the safety supervisor did in a run, judged against the truth it never saw.

Pure functions on logged signals: the supervisor's latched reasons, its mode and its beam hold
(``systems/control/safety_supervisor.py``), the true head height and the reference. The truth is
used here only to judge: how long the beam was on while the head was out of tolerance, and how
long it was held while the head was within it. Each sample stands for the tick that follows it
(the logs are taken at the controller's ticks).
"""

from dataclasses import dataclass

import numpy as np

from maskless.analysis.detection_figures import first_set_s, rises
from maskless.systems.control.safety_supervisor import (
    REASONS,
    SAFE_ACTIONS,
    safety_states,
)


@dataclass(frozen=True)
class SafetyLog:
    """The signals a safety judgement reads, all at the same sample times.

    Attributes:
        times_s: sample times (s).
        head_height_m, reference_m: the true head height and the reference (m).
        beam_hold: 1 where the beam was held.
        reasons: one row of latched flags per ``REASONS`` entry.
        mode: the index in ``MODES`` of what the valves got.
        inlet_a, outlet_a: the currents the valves got (A).
        gauge_pressure_pa: the bladder's pressure, or None for a plant without one.
    """

    times_s: np.ndarray
    head_height_m: np.ndarray
    reference_m: np.ndarray
    beam_hold: np.ndarray
    reasons: np.ndarray
    mode: np.ndarray
    inlet_a: np.ndarray
    outlet_a: np.ndarray
    gauge_pressure_pa: np.ndarray | None = None


def _sample_durations_s(times_s: np.ndarray) -> np.ndarray:
    """Each sample's share of the run: the time to the next sample (the last one's: the period)."""
    if times_s.size < 2:
        return np.zeros_like(times_s)
    steps = np.diff(times_s)
    return np.append(steps, steps[-1])


def safety_figures(log: SafetyLog, tolerance_m: float, from_s: float = 0.0) -> dict:
    """The beam's and the supervisor's figures (s, fractions, mA, kPa) from ``from_s`` on."""
    keep = log.times_s >= from_s
    durations = _sample_durations_s(log.times_s)[keep]
    total_s = float(durations.sum())
    held = np.asarray(log.beam_hold)[keep] > 0.5
    off_target = np.abs(log.head_height_m - log.reference_m)[keep] > tolerance_m

    def seconds(mask):
        return float(durations[mask].sum())

    def fraction(seconds_):
        return seconds_ / total_s if total_s > 0 else 0.0

    beam_on_off_target_s = seconds(~held & off_target)
    held_on_target_s = seconds(held & ~off_target)
    states, reasons = safety_states(log.mode[-1:], log.reasons[:, -1:])
    first = {
        reason: first_set_s(log.times_s, log.reasons[k], from_s) for k, reason in enumerate(REASONS)
    }
    events = sorted(
        ({"reason": r, "first_s": t, "action": SAFE_ACTIONS[r]} for r, t in first.items() if t),
        key=lambda event: event["first_s"],
    )
    currents = np.concatenate([log.inlet_a[keep], log.outlet_a[keep]])
    figures = {
        "state_at_end": str(states[0]),
        "latched_at_end": [r for r in str(reasons[0]).split(",") if r],
        "events": events,
        "beam_on_s": seconds(~held),
        "beam_hold_s": seconds(held),
        "beam_hold_fraction": fraction(seconds(held)),
        "beam_on_while_off_target_s": beam_on_off_target_s,
        "beam_on_while_off_target_fraction": fraction(beam_on_off_target_s),
        "beam_held_while_on_target_s": held_on_target_s,
        "beam_held_while_on_target_fraction": fraction(held_on_target_s),
        "non_finite_valve_currents": int(np.count_nonzero(~np.isfinite(currents))),
        "valve_current_range_ma": [
            float(1e3 * np.nanmin(currents)) if currents.size else None,
            float(1e3 * np.nanmax(currents)) if currents.size else None,
        ],
    }
    if log.gauge_pressure_pa is not None:
        figures["max_gauge_pressure_kpa"] = float(np.max(log.gauge_pressure_pa[keep]) / 1e3)
    return figures


def time_to_safe_state_s(log: SafetyLog, start_s: float) -> tuple[str, float] | tuple[None, None]:
    """The first reason latched at or after ``start_s`` and how long after (s); None if none.

    A reason latched before ``start_s`` (and still latched) does not count: it was no answer to
    what happened at ``start_s``. A latched reason is the safe state: the beam is held from that
    tick, and the valves get the reason's safe action (``SAFE_ACTIONS``).
    """
    found = [
        (first, reason)
        for k, reason in enumerate(REASONS)
        if (first := first_set_s(log.times_s, rises(log.reasons[k]), start_s)) is not None
    ]
    if not found:
        return None, None
    first, reason = min(found)
    return reason, first - start_s
