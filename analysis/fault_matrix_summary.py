"""The fault matrix's rows as figures per case, and the issue's targets met or not.

A case's figures: its runs and errors, how many were detected and how soon (median and worst),
how soon the supervisor latched its safe state, the head's worst excursion after the fault, the
tracking p95, and the beam's times (on while the true error exceeded the tolerance; held while it
did not). Rows are ``diagrams/fault_matrix.py``'s; a figure no run has is None.
"""

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

# The bounds (issue 13, "Targets").
BEAM_ON_OFF_TARGET_MAX_FRACTION = 0.001
ONE_CAMERA_DETECTION_MAX_S = 1.0
ONE_CAMERA_P95_MAX_MM = 1.5
BOTH_CAMERAS_SAFE_STATE_MAX_S = 0.5
BOTH_CAMERAS_EXCURSION_MAX_MM = 2.0
# The fault kinds the one-camera targets speak of: a camera lost, biased or frozen.
ONE_CAMERA_KINDS = {"camera_dead", "camera_bias", "camera_frozen"}


@dataclass(frozen=True)
class CaseFaults:
    """What a case injects: (kind, target) per fault; empty for the nominal case."""

    faults: tuple[tuple[str, str], ...] = ()

    @property
    def nominal(self) -> bool:
        """No fault at all."""
        return not self.faults

    @property
    def one_camera(self) -> bool:
        """Faults of the one-camera kinds, all on the same camera."""
        kinds = {kind for kind, _ in self.faults}
        targets = {target for _, target in self.faults}
        return bool(self.faults) and kinds <= ONE_CAMERA_KINDS and len(targets) == 1

    def cameras_lost(self, camera_count: int) -> bool:
        """Every camera dead."""
        dead = {target for kind, target in self.faults if kind == "camera_dead"}
        return camera_count > 1 and len(dead) == camera_count


def _values(rows, key) -> np.ndarray:
    return np.array([row[key] for row in rows if row.get(key) is not None], dtype=float)


def _median(values) -> float | None:
    return float(np.median(values)) if len(values) else None


def _worst(values) -> float | None:
    return float(np.max(values)) if len(values) else None


def _spread(rows, key) -> dict:
    values = _values(rows, key)
    return {"median": _median(values), "worst": _worst(values)}


def case_figures(rows: Sequence[dict]) -> dict:
    """One case's figures over its runs."""
    ran = [row for row in rows if not row["error"]]
    return {
        "runs": len(rows),
        "errors": len(rows) - len(ran),
        "error_examples": sorted({row["error"] for row in rows if row["error"]})[:3],
        "detected": len(_values(ran, "detection_latency_s")),
        "detection_latency_s": _spread(ran, "detection_latency_s"),
        "safe_state": len(_values(ran, "safe_state_latency_s")),
        "safe_state_reasons": sorted(
            {r["safe_state_reason"] for r in ran if r["safe_state_reason"]}
        ),
        "safe_state_latency_s": _spread(ran, "safe_state_latency_s"),
        "worst_excursion_mm": _worst(_values(ran, "worst_excursion_mm")),
        "p95_abs_error_mm": _spread(ran, "p95_abs_error_mm"),
        "beam_on_while_off_target_fraction": _spread(ran, "beam_on_while_off_target_fraction"),
        "beam_held_while_on_target_fraction": _spread(ran, "beam_held_while_on_target_fraction"),
        "valve_currents_out_of_range": int(_values(ran, "valve_currents_out_of_range").sum()),
        "max_gauge_pressure_kpa": _worst(_values(ran, "max_gauge_pressure_kpa")),
    }


def summarize_fault_matrix(
    rows: Sequence[dict],
    cases: dict[str, CaseFaults],
    *,
    camera_count: int,
    pressure_limit_kpa: float,
) -> dict:
    """Each case's figures and the targets, each with whether it was met and the worst value."""
    figures = {case: case_figures([row for row in rows if row["case"] == case]) for case in cases}
    all_figures = list(figures.values())

    def worst(case_filter, pick):
        values = [pick(figures[case]) for case in cases if case_filter(cases[case])]
        values = [v for v in values if v is not None]
        return max(values) if values else None

    def target(text, value, bound, applies=True, must_detect=None):
        met = applies and value is not None and value <= bound
        if must_detect is not None:
            met = met and must_detect
        return {
            "target": text,
            "worst": value,
            "bound": bound,
            "met": bool(met),
            "applies": applies,
        }

    faulty = [case for case in cases if not cases[case].nominal]
    one_camera = [case for case in cases if cases[case].one_camera]
    lost = [case for case in cases if cases[case].cameras_lost(camera_count)]
    targets = [
        target("runs that raised", sum(f["errors"] for f in all_figures), 0),
        target(
            "valve currents non-finite or outside [0, saturation]",
            sum(f["valve_currents_out_of_range"] for f in all_figures),
            0,
        ),
        target(
            "bladder pressure (kPa)",
            worst(lambda c: True, lambda f: f["max_gauge_pressure_kpa"]),
            pressure_limit_kpa,
            applies=any(f["max_gauge_pressure_kpa"] is not None for f in all_figures),
        ),
        target(
            "beam on while |error| > tolerance, fraction of the run, any fault",
            worst(
                lambda c: not c.nominal, lambda f: f["beam_on_while_off_target_fraction"]["worst"]
            ),
            BEAM_ON_OFF_TARGET_MAX_FRACTION,
            applies=bool(faulty),
        ),
        target(
            "beam on while |error| > tolerance, fraction of the run, nominal",
            worst(lambda c: c.nominal, lambda f: f["beam_on_while_off_target_fraction"]["worst"]),
            0.0,
            applies=any(cases[c].nominal for c in cases),
        ),
        target(
            "one camera lost, biased or frozen: detection (s)",
            worst(lambda c: c.one_camera, lambda f: f["detection_latency_s"]["worst"]),
            ONE_CAMERA_DETECTION_MAX_S,
            applies=bool(one_camera),
            must_detect=all(figures[c]["detected"] == figures[c]["runs"] for c in one_camera),
        ),
        target(
            "one camera lost, biased or frozen: p95 |error| on the other (mm)",
            worst(lambda c: c.one_camera, lambda f: f["p95_abs_error_mm"]["worst"]),
            ONE_CAMERA_P95_MAX_MM,
            applies=bool(one_camera),
        ),
        target(
            "every camera lost: time to the safe state (s)",
            worst(
                lambda c: c.cameras_lost(camera_count), lambda f: f["safe_state_latency_s"]["worst"]
            ),
            BOTH_CAMERAS_SAFE_STATE_MAX_S,
            applies=bool(lost),
            must_detect=all(figures[c]["safe_state"] == figures[c]["runs"] for c in lost),
        ),
        target(
            "every camera lost: head excursion (mm)",
            worst(lambda c: c.cameras_lost(camera_count), lambda f: f["worst_excursion_mm"]),
            BOTH_CAMERAS_EXCURSION_MAX_MM,
            applies=bool(lost),
        ),
    ]
    return {
        "runs": len(rows),
        "seeds": max((row["seed"] for row in rows), default=-1) + 1,
        "cases": figures,
        "targets": [t for t in targets if t["applies"]],
        "all_targets_met": all(t["met"] for t in targets if t["applies"]),
    }
