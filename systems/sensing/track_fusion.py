"""Track-to-track fusion at the central site (Sec. III-C, Eq. 10).

P_F = (Σ P_s⁻¹)⁻¹ and x_F = P_F Σ P_s⁻¹ x_s: the variance-weighted average of the local tracks,
which treats their errors as independent (the paper's assumption; the tracks share the process
noise, so P_F is optimistic, which the recorded errors let a user check).

A track its filter flags (``fault_detection``) is left out: its covariance is inflated by
``EXCLUDED_VARIANCE`` before it is fused, which gives it no weight, so the loop carries on with
the others; a healthy track's covariance gets exactly 0 added, so healthy tracks are fused with
the same arithmetic as before the checks existed (a default run records the same bytes). With
every track flagged, their fusion's covariance is that large too, and says so.
"""

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from pydrake.symbolic import Expression, MakeVectorVariable, Variable, if_then_else, logical_and
from pydrake.systems.framework import DiagramBuilder

from maskless.systems.named_symbolic_system import (
    PortMap,
    add_named_symbolic_system,
    building_expressions,
    diagram_form,
)
from maskless.systems.sensing.fault_detection import TRACK_FLAGS, FaultDetectionConfig

# Added to a flagged track's variances (m²): a weight 1e-11 of a healthy track's (~1e-5 m²).
EXCLUDED_VARIANCE = 1.0e6


def inverse_2x2(M):
    """The inverse of a 2x2 matrix by the adjugate; works on float and symbolic arrays."""
    determinant = M[0, 0] * M[1, 1] - M[0, 1] * M[1, 0]
    return np.array([[M[1, 1], -M[0, 1]], [-M[1, 0], M[0, 0]]]) / determinant


def fuse_tracks(
    states: Sequence[np.ndarray], covariances: Sequence[np.ndarray], inverse=inverse_2x2
):
    """Eq. 10 on 2-state tracks.

    Computed pairwise with (P₁⁻¹ + P₂⁻¹)⁻¹ = P₁ (P₁ + P₂)⁻¹ P₂, which equals Eq. 10 exactly but
    inverts one matrix per pair instead of three, which keeps the fusion system's expressions small.
    Folding track by track gives Eq. 10 for any number of tracks, since it sums informations.

    Args:
        states: each track's x̂_s (2,).
        covariances: each track's P_s (2, 2).
        inverse: inverts each pair's sum (``inverse_2x2``; the fusion system passes one that
            hands back variables standing for the inverses it computes beforehand).

    Returns:
        (x_F, P_F).
    """
    if len(states) != len(covariances) or not states:
        raise ValueError(
            f"fuse_tracks: need one covariance per state and at least one track, got "
            f"{len(states)} states and {len(covariances)} covariances"
        )
    fused_state, fused_covariance = states[0], covariances[0]
    for x, P in zip(states[1:], covariances[1:], strict=True):
        inverse_sum = inverse(fused_covariance + P)
        fused_state = P @ inverse_sum @ fused_state + fused_covariance @ inverse_sum @ x
        fused_covariance = fused_covariance @ inverse_sum @ P
    return fused_state, fused_covariance


@building_expressions
def add_track_fusion(
    builder: DiagramBuilder,
    track_names: Sequence[str],
    detection: FaultDetectionConfig,
    name: str = "fusion",
) -> PortMap:
    """Adds the fusion site for the named local tracks to ``builder``.

    .. pydrake_system::

        name: fusion
        input_ports:
        - kinect_v1_estimated_state
        - kinect_v1_covariance
        - kinect_v1_health
        - kinect_v2_estimated_state
        - kinect_v2_covariance
        - kinect_v2_health
        output_ports:
        - estimated_state
        - covariance
        - health

    Args:
        builder: where the fusion's systems go.
        track_names: one name per local track; the inputs are ``{name}_estimated_state`` (2),
            ``{name}_covariance`` (4, row-major) and ``{name}_health`` (``TRACK_FLAGS``).
        detection: the disagreement and uncertainty bounds.
        name: the fusion system's name; its other system is ``{name}.inverses`` (each pair's
            inverse, computed once).

    The output is a direct function of the inputs (no state), so it always fuses the tracks as they
    are at that instant. ``health`` is ``FUSION_HEALTH``: the tracks used, then 1 where a flag is
    set (the tracks disagree; the fused std is above ``max_fused_std_m``).
    """
    if not track_names:
        raise ValueError("make_track_fusion: track_names is empty; fusion needs at least one track")
    inputs, states, covariances, raw_covariances, flag_counts = [], [], [], [], []
    for track in track_names:
        x = MakeVectorVariable(2, f"{track}_x")
        p = MakeVectorVariable(4, f"{track}_P")
        flags = MakeVectorVariable(len(TRACK_FLAGS), f"{track}_health")
        inputs += [
            (f"{track}_estimated_state", list(x)),
            (f"{track}_covariance", list(p)),
            (f"{track}_health", list(flags)),
        ]
        states.append(np.array(list(x)))
        raw_covariances.append(np.array(list(p)).reshape(2, 2))
        # Any flag set inflates the track out of the fusion (a count of 0/1 flags).
        flag_counts.append(sum(flags))
        covariances.append(raw_covariances[-1] + flag_counts[-1] * EXCLUDED_VARIANCE * np.eye(2))
    # With no flag set (nearly always) only Eq. 10 on the tracks as they are is evaluated: an
    # if-then-else evaluates the branch it takes, and the controller reads this every tick.
    all_healthy = sum(flag_counts) < 0.5
    # A symbolic system re-evaluates every copy of a sub-expression, and each pair's inverse
    # (P₁ + P₂)⁻¹ appears in every entry of the fused state and covariance (eight copies of its
    # determinant in one entry of the state). So a first system, ``{name}.inverses``, computes
    # each inverse once, from the same expressions (so to the same bits), and passes the tracks
    # on; the fusion reads the inverses as variables, with the arithmetic around them unchanged
    # (tests/test_track_fusion.py compares the expressions node by node).
    inverse_variables = list(MakeVectorVariable(4 * (len(track_names) - 1), "inverse"))
    plain, flagged = (
        fusion_expressions(states, chosen, inverse_variables)
        for chosen in (raw_covariances, covariances)
    )
    track_variables = [v for _, variables in inputs for v in variables]
    healthy = Variable("all_tracks_healthy")
    inverses = add_named_symbolic_system(
        builder,
        f"{name}.inverses",
        inputs=inputs,
        outputs=[
            (
                "fusion_input",
                [
                    *track_variables,
                    *(
                        if_then_else(all_healthy, a, b)
                        for a, b in zip(plain.inverses, flagged.inverses, strict=True)
                    ),
                    if_then_else(all_healthy, 1.0, 0.0),
                ],
            )
        ],
    )
    fused_covariance = [
        if_then_else(healthy > 0.5, a, b) for a, b in _pairs(plain.covariance, flagged.covariance)
    ]
    # The health is part of the fusion's output: every tick the safety supervisor reads it beside
    # the estimate, and a system of its own (with the Multiplexer its inputs need) cost more per
    # tick than its few nodes here. Its "uncertain" flag reads the fused variance from the same
    # expression as the covariance output, so to the same bits.
    used = [if_then_else(count < 0.5, 1.0, 0.0) for count in flag_counts]
    fusion = add_named_symbolic_system(
        builder,
        name,
        inputs=[("fusion_input", [*track_variables, *inverse_variables, healthy])],
        outputs=[
            (
                "estimated_state",
                [if_then_else(healthy > 0.5, a, b) for a, b in _pairs(plain.state, flagged.state)],
            ),
            ("covariance", fused_covariance),
            (
                "health",
                [
                    sum(used),
                    _disagreement(states, raw_covariances, used, detection.disagreement_sigmas),
                    if_then_else(fused_covariance[0] > detection.max_fused_std_m**2, 1.0, 0.0),
                ],
            ),
        ],
    )
    builder.Connect(inverses.outputs["fusion_input"], fusion.inputs.pop("fusion_input"))
    fusion.inputs = inverses.inputs
    return fusion


@dataclass
class FusionExpressions:
    """Eq. 10 with each pair's inverse (P₁ + P₂)⁻¹ as a variable (``fusion_expressions``).

    Attributes:
        state: x_F (2,) in the tracks' and the inverses' variables.
        covariance: P_F (2, 2), likewise.
        inverses: the entries of each pair's inverse in the tracks' variables, in the order of
            the variables given.
    """

    state: np.ndarray
    covariance: np.ndarray
    inverses: list[Expression]


@building_expressions
def fusion_expressions(states, covariances, variables: Sequence[Variable]) -> FusionExpressions:
    """``fuse_tracks`` on symbolic tracks, each inverse it takes replaced by variables.

    Args:
        states: each track's x̂_s (2,), symbolic.
        covariances: each track's P_s (2, 2), symbolic.
        variables: 4 per pair (one fewer pair than tracks), each inverse's entries row-major.
    """
    inverses = []
    # The inverses in the tracks' variables, as fuse_tracks builds them (a later pair's sum
    # holds the earlier fusion).
    fuse_tracks(states, covariances, lambda M: inverses.append(inverse_2x2(M)) or inverses[-1])
    stand_ins = iter(np.array(list(variables), dtype=object).reshape(-1, 2, 2))
    state, covariance = fuse_tracks(states, covariances, lambda M: next(stand_ins))
    return FusionExpressions(state, covariance, [e for M in inverses for e in M.ravel()])


def _pairs(first: np.ndarray, second: np.ndarray):
    """The entries of two equal-shaped arrays side by side, row-major."""
    return zip(np.ravel(first), np.ravel(second), strict=True)


def _disagreement(states, covariances, used, sigmas: float):
    """1 when two healthy tracks' heights lie more than ``sigmas`` stds of their gap apart."""
    flag = Expression(0.0)
    for i in range(len(states)):
        for j in range(i + 1, len(states)):
            difference = states[i][0] - states[j][0]
            variance = covariances[i][0, 0] + covariances[j][0, 0]
            apart = logical_and(
                used[i] * used[j] > 0.5, difference * difference > sigmas**2 * variance
            )
            flag = if_then_else(apart, 1.0, flag)
    return flag


make_track_fusion = diagram_form(add_track_fusion)
