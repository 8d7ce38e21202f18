"""Plausibility limits on what a user may ask for, each with the reason it is there.

Every cap lies far beyond what a study of a head positioner needs. Each exists so that a slip (a
duration typed in ms, a rate in kHz, a mass in g) is refused before anything runs, with its reason,
instead of hanging, exhausting memory or running nonsense to a plausible-looking summary.
"""

import math
from dataclasses import dataclass

from maskless.errors import ConfigError, MasklessError


@dataclass(frozen=True)
class Limit:
    """A closed range [low, high] in ``unit``, and why a value outside it is refused.

    Attributes:
        low, high: the smallest and largest plausible values.
        unit: the unit of both, as written in the message ("s", "Hz", "kg").
        reason: why the range is what it is, in a clause the message quotes.
    """

    low: float
    high: float
    unit: str
    reason: str

    def contains(self, value) -> bool:
        """Whether ``value`` is a finite number in [low, high] (NaN and infinities are not)."""
        number = isinstance(value, int | float) and not isinstance(value, bool)
        return number and math.isfinite(value) and self.low <= value <= self.high

    def expected(self) -> str:
        """What a message says was expected: the range, its unit and the reason."""
        return f"{self.low:g} to {self.high:g} {self.unit} ({self.reason})"

    def check(self, value, name: str, error: type[MasklessError] = ConfigError) -> None:
        """Raises ``error`` naming ``name``, its value, the range and the reason.

        A flag reads as typed (``--ts 1e+300``), a field as set (``duration_s = 1e+300``).
        """
        if not self.contains(value):
            given = f"{name} {value!r}" if name.startswith("--") else f"{name} = {value!r}"
            raise error(f"{given}: expected {self.expected()}")


# Measured (2 cores): a simulated hour writes about 57 MB of recording, takes about 5 s and adds
# about 16 MB of logs in memory; a day, 1.4 GB, 2 minutes and 0.4 GB. A treatment session is
# under an hour, and a day covers any warm-up or drift study.
DURATION_S = Limit(
    0.0,
    24 * 3600.0,
    "s",
    "at most 24 h of simulated time: a day already writes about 1.4 GB of recording and holds "
    "0.4 GB of logs in memory",
)
# The cameras' frame latency is tens of ms up to ~100 ms (shared/DESIGN.md); the delay line holds
# latency x frame rate frames, so an unbounded latency is unbounded state.
LATENCY_S = Limit(
    0.0, 1.0, "s", "a depth camera's frame latency is tens of ms, at most ~0.1 s; 1 s is ten times"
)
# A latency spike (fault_injection) delays a camera's frames through a delay line of one frame per
# frame period of the spike, held in the Context; the cap keeps that line short.
LATENCY_SPIKE_S = Limit(
    0.0,
    1.0,
    "s",
    "a spike of 1 s is ten times a depth camera's worst frame latency (~0.1 s), and the delay "
    "line holds one frame per frame period of it (30 at 30 Hz)",
)
# The Kinects deliver 30 Hz; every frame is a step of the simulator, so a rate typed in Hz for
# kHz multiplies the run's time. Below 1 Hz half a frame (the least latency) would exceed the
# latency's own cap.
FRAME_RATE_HZ = Limit(
    1.0,
    1000.0,
    "Hz",
    "depth cameras deliver 30 Hz; every frame is a simulator step, and below 1 Hz half a frame "
    "of latency would exceed 1 s",
)
# A rendered image costs milliseconds to draw and lands in the recording.
IMAGE_RATE_HZ = Limit(
    0.0, 30.0, "Hz", "a depth camera delivers at most 30 images a second, each a rendering"
)
# The identified models sample the positioner every 48 ms; its valves and cameras need nothing
# faster than 1 kHz, and its slowest time constants (~100 s) vanish from a model sampled less than
# once a minute. A plant model also runs a simulator step per sample.
SAMPLE_PERIOD_S = Limit(
    1e-3,
    60.0,
    "s",
    "the positioner's valves and cameras need no sampling faster than 1 kHz, and a model sampled "
    "less than once a minute misses its dynamics (seconds to ~100 s)",
)
# An adult head weighs 4.5-5 kg (shared/DESIGN.md), a child's from about 1 kg.
HEAD_MASS_KG = Limit(
    1.0,
    20.0,
    "kg",
    "a child's head weighs about 1 kg, an adult's 4.5-5 kg; 20 kg is four adult heads",
)
# Each point is a steady-state solve and a linearisation, about 7 ms; 1000 is a point every
# 0.1 mA over the inlet's 60-165 mA, finer than the valves' 3 % repeatability.
OPERATING_RANGE_POINTS = Limit(
    2,
    1000,
    "currents per valve",
    "1000 is a point every 0.1 mA, finer than the valves' 3 % repeatability; each costs a "
    "steady-state solve",
)


def at_least_half_a_frame(latency_s: float, frame_rate_hz: float, of: str) -> tuple[bool, str]:
    """(in range, what was expected) for a latency rounded to whole frames of ``of``'s rate."""
    half_frame_s = 0.5 / frame_rate_hz
    return (
        latency_s >= half_frame_s,
        f"at least half a frame of {of}, {half_frame_s:.4f} s (it is rounded to whole frames)",
    )
