"""What the estimator checks before it trusts a camera or the fused estimate.

The checks run inside the compiled local filters (``local_kalman_filter``) and the fusion site
(``track_fusion``); this module holds their settings and the one statistic they share.

At each camera, per frame:

- **innovation gate**: a frame whose normalised innovation squared, NIS = (z - ẑ)² / S with
  S = P(k|k-1)[0, 0] + σ_r², exceeds the chi-square bound of ``innovation_gate_probability``
  (1 degree of freedom) is not used; ``rejecting_after_s`` of rejected frames in a row mark the
  camera faulty (``rejecting``);
- **staleness**: no usable frame for ``stale_after_s`` (``stale``);
- **stuck**: the same distance, to the bit, for ``stuck_after_s`` (``stuck``): a real camera's
  noise changes its reading from frame to frame; a frozen one repeats it.

At the fusion site: a camera flagged by any check is left out of the fusion (degraded mode: the
others carry on); two healthy tracks that differ by more than ``disagreement_sigmas`` times the
std of their difference, sqrt(P₁ + P₂), are flagged (``disagreement``: one of them is wrong, and
two cameras cannot say which); a fused std above ``max_fused_std_m`` is flagged (``uncertain``).
"""

import math
from dataclasses import dataclass

from scipy.special import erfinv

from maskless.systems.config_loading import UNSET, refuse_out_of_range
from maskless.systems.units import whole_ticks

# The flags each local filter reports, in its ``health`` output's order.
TRACK_FLAGS = ("stale", "rejecting", "stuck")
# The fusion site's ``health`` output: how many tracks it used, then its flags.
FUSION_HEALTH = ("tracks_used", "disagreement", "uncertain")


@dataclass
class FaultDetectionConfig:
    """The estimator's checks (module docstring); every field is set in assets/simulation.yaml.

    Attributes:
        innovation_gate_probability: a frame is used when its NIS lies inside the chi-square
            bound this probability gives (1 degree of freedom).
        rejecting_after_s: rejected frames in a row for this long mark a camera faulty (s).
        stale_after_s: no usable frame for this long marks a camera faulty (s).
        stuck_after_s: the same reading for this long marks a camera faulty (s).
        disagreement_sigmas: two healthy tracks further apart than this many stds disagree.
        max_fused_std_m: a fused height std above this is not trusted (m).
    """

    innovation_gate_probability: float = UNSET
    rejecting_after_s: float = UNSET
    stale_after_s: float = UNSET
    stuck_after_s: float = UNSET
    disagreement_sigmas: float = UNSET
    max_fused_std_m: float = UNSET


def nis_bound(probability: float) -> float:
    """The chi-square bound (1 degree of freedom) that a NIS stays under with ``probability``.

    For one degree of freedom the chi-square is a squared standard normal: the bound is
    (√2 erf⁻¹(p))².
    """
    return 2.0 * float(erfinv(probability)) ** 2


def frames_in(duration_s: float, frame_rate_hz: float) -> int:
    """Whole frames in ``duration_s`` at ``frame_rate_hz``, at least one."""
    return max(1, whole_ticks(duration_s, 1.0 / frame_rate_hz))


def validate_fault_detection(config: FaultDetectionConfig) -> None:
    """Raises ConfigError naming ``fault_detection.FIELD`` when a value is out of range."""
    positive = "a positive, finite value"
    refuse_out_of_range(
        "fault_detection",
        config,
        [
            (
                0.5 < config.innovation_gate_probability < 1,
                "innovation_gate_probability",
                "a probability in (0.5, 1)",
            ),
            (0 < config.rejecting_after_s < math.inf, "rejecting_after_s", positive),
            (0 < config.stale_after_s < math.inf, "stale_after_s", positive),
            (0 < config.stuck_after_s < math.inf, "stuck_after_s", positive),
            (0 < config.disagreement_sigmas < math.inf, "disagreement_sigmas", positive),
            (0 < config.max_fused_std_m < math.inf, "max_fused_std_m", positive),
        ],
    )
