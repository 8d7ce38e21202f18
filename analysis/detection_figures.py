"""When the estimator's checks fired in a run, and how soon after each injected fault.

Pure functions on logged flags (``systems/sensing/fault_detection.py`` names them): a flag is set
where its value is above 0.5.
"""

import numpy as np


def first_set_s(times_s: np.ndarray, flag: np.ndarray, from_s: float = 0.0) -> float | None:
    """The first sample time at or after ``from_s`` where ``flag`` is set (None if never)."""
    times_s, flag = np.asarray(times_s, float), np.asarray(flag, float)
    set_after = np.flatnonzero((flag > 0.5) & (times_s >= from_s))
    return float(times_s[set_after[0]]) if set_after.size else None


def rises(flag: np.ndarray) -> np.ndarray:
    """1 where ``flag`` becomes set (set, and not set at the sample before), 0 elsewhere.

    A latched flag is set from its first tick to its reset: when it fired is its rise, and one
    latched before some later moment did not fire at that moment.
    """
    now = np.asarray(flag, float) > 0.5
    before = np.concatenate([[False], now[:-1]])
    return (now & ~before).astype(float)


def set_fraction(flag: np.ndarray) -> float:
    """The fraction of samples where ``flag`` is set."""
    return float(np.mean(np.asarray(flag, float) > 0.5))


def flag_figures(times_s: np.ndarray, flags: dict[str, np.ndarray]) -> dict:
    """Per flag: when it was first set (s; None if never) and the fraction of the run it was."""
    return {
        name: {"first_set_s": first_set_s(times_s, flag), "set_fraction": set_fraction(flag)}
        for name, flag in flags.items()
    }


def detection_latency_s(
    times_s: np.ndarray, flags: dict[str, np.ndarray], start_s: float
) -> tuple[str, float] | tuple[None, None]:
    """The first flag set at or after ``start_s`` and how long after (s); (None, None) if none."""
    found = [
        (first, name)
        for name, flag in flags.items()
        if (first := first_set_s(times_s, flag, start_s)) is not None
    ]
    if not found:
        return None, None
    first, name = min(found)
    return name, first - start_s
