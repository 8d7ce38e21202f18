"""The seed paper's parameters: read as printed from assets/paper.yaml, converted to SI here.

This is the one place where the paper's mm, mm² and mA become m, m² and A.
"""

from dataclasses import dataclass, field

import numpy as np

from maskless.errors import ConfigError
from maskless.systems.config_loading import UNSET, asset_path, load_config
from maskless.systems.linear_model import LinearModel
from maskless.systems.units import MA_PER_A, MM_PER_M, ma_to_a, mm2_to_m2, mm_to_m


@dataclass
class PaperParameters:
    """The paper's numbers exactly as printed; see assets/paper.yaml for the source of each."""

    acceleration_variance_mm2: float = UNSET
    measurement_variance_kinect_v1_mm2: float = UNSET
    measurement_variance_kinect_v2_mm2: float = UNSET
    measured_noise_kinect_v1_mm2: float = UNSET
    measured_noise_kinect_v2_mm2: float = UNSET
    sample_period_s: float = UNSET
    A: list[list[float]] = field(default_factory=list)
    B_mm_per_ma: list[float] = field(default_factory=list)
    C: list[float] = field(default_factory=list)
    D: float = UNSET
    K: list[float] = field(default_factory=list)
    operating_distance_mm: float = UNSET
    operating_current_ma: float = UNSET
    valve_starting_current_ma: float = UNSET
    valve_saturation_current_ma: float = UNSET
    lqr_Q_diagonal: float = UNSET
    lqr_R: float = UNSET
    estimator_Qe_diagonal: float = UNSET
    estimator_Re: float = UNSET
    reported_fused_std_mm: float = UNSET
    reported_tracking_band_mm: float = UNSET
    reported_overshoot_mm: float = UNSET
    reported_settle_time_s: float = UNSET


def validate_paper_parameters(paper: PaperParameters) -> None:
    """Raises ConfigError naming the ``paper.*`` field whose value cannot describe Eq. 25-30."""

    def fail(field_name, expected):
        raise ConfigError(f"paper.{field_name} = {getattr(paper, field_name)}: expected {expected}")

    if np.shape(paper.A) != (2, 2):
        fail("A", "a 2x2 matrix (Eq. 26)")
    for field_name in ("B_mm_per_ma", "C", "K"):
        if np.shape(getattr(paper, field_name)) != (2,):
            fail(field_name, "2 numbers (Eq. 26)")
    if paper.D != 0.0:
        fail("D", "0 (Eq. 26; the plant and controller have no feedthrough)")
    positive = [
        "sample_period_s",
        "lqr_Q_diagonal",
        "lqr_R",
        "estimator_Qe_diagonal",
        "estimator_Re",
        "acceleration_variance_mm2",
        "measurement_variance_kinect_v1_mm2",
        "measurement_variance_kinect_v2_mm2",
        "measured_noise_kinect_v1_mm2",
        "measured_noise_kinect_v2_mm2",
        "valve_saturation_current_ma",
    ]
    for field_name in positive:
        if not getattr(paper, field_name) > 0:
            fail(field_name, "a positive number")
    if not 0 <= paper.valve_starting_current_ma < paper.valve_saturation_current_ma:
        fail("valve_starting_current_ma", "0 <= starting current < valve_saturation_current_ma")


def load_paper_parameters() -> PaperParameters:
    """The shipped paper parameters (assets/paper.yaml)."""
    return load_config(PaperParameters, asset_path("paper.yaml"))


def paper_identified_model(paper: PaperParameters) -> LinearModel:
    """Eq. 25-26 in SI: from the valve current (A) to the camera-to-head distance (m).

    x is in mm in the paper; scaling x and y by 1/1000 keeps A, C and K, and B (mm/mA) becomes
    m/A with the same digits, which the conversion below makes explicit. The paper gives no
    innovations variance.
    """
    b_m_per_a = mm_to_m(np.asarray(paper.B_mm_per_ma, float)) * MA_PER_A
    return LinearModel(
        A=np.asarray(paper.A, float).reshape(2, 2),
        B=b_m_per_a.reshape(2, 1),
        C=np.asarray(paper.C, float).reshape(1, 2),
        D=np.array([[mm_to_m(paper.D) * MA_PER_A]]),
        K=np.asarray(paper.K, float).reshape(2, 1),
        sample_period_s=paper.sample_period_s,
        operating_output=mm_to_m(paper.operating_distance_mm),
        operating_input=ma_to_a(paper.operating_current_ma),
        input_unit="A",
        output_unit="m",
    )


@dataclass(frozen=True)
class LqgWeights:
    """LQR weights and estimator noise covariances in SI.

    Attributes:
        Q: state weight, 1/m² (cost-preserving: x in mm -> m multiplies Q by 1000²).
        R: input weight, 1/A² (u in mA -> A multiplies R by 1000²).
        W: process-noise covariance of the estimator, m².
        V: measurement-noise covariance of the estimator, m².
    """

    Q: np.ndarray
    R: np.ndarray
    W: np.ndarray
    V: np.ndarray


def paper_lqg_weights(paper: PaperParameters) -> LqgWeights:
    """Eq. 30 and the estimator variances (Qe, Re) of Sec. V, in SI."""
    return LqgWeights(
        Q=np.eye(2) * paper.lqr_Q_diagonal * MM_PER_M**2,
        R=np.array([[paper.lqr_R * MA_PER_A**2]]),
        W=np.eye(2) * mm2_to_m2(paper.estimator_Qe_diagonal),
        V=np.array([[mm2_to_m2(paper.estimator_Re)]]),
    )


def paper_filter_variances_si(paper: PaperParameters) -> dict[str, float]:
    """The local filters' variances in SI.

    The acceleration variance (m²/s⁴) and, by camera model (``kinect_v1``, ``kinect_v2``), the
    measurement variance (m²).
    """
    return {
        "acceleration_variance_m2_s4": mm2_to_m2(paper.acceleration_variance_mm2),
        "kinect_v1": mm2_to_m2(paper.measurement_variance_kinect_v1_mm2),
        "kinect_v2": mm2_to_m2(paper.measurement_variance_kinect_v2_mm2),
    }
