"""Track-to-track fusion at the central site (Sec. III-C, Eq. 10).

P_F = (Σ P_s⁻¹)⁻¹ and x_F = P_F Σ P_s⁻¹ x_s: the variance-weighted average of the local tracks,
which treats their errors as independent (the paper's assumption; the tracks share the process
noise, so P_F is optimistic, which the recorded errors let a user check).
"""

from collections.abc import Sequence

import numpy as np
from pydrake.symbolic import MakeVectorVariable
from pydrake.systems.framework import DiagramBuilder

from maskless.systems.named_symbolic_system import (
    PortMap,
    add_named_symbolic_system,
    building_expressions,
    diagram_form,
)


def inverse_2x2(M):
    """The inverse of a 2x2 matrix by the adjugate; works on float and symbolic arrays."""
    determinant = M[0, 0] * M[1, 1] - M[0, 1] * M[1, 0]
    return np.array([[M[1, 1], -M[0, 1]], [-M[1, 0], M[0, 0]]]) / determinant


def fuse_tracks(states: Sequence[np.ndarray], covariances: Sequence[np.ndarray]):
    """Eq. 10 on 2-state tracks.

    Computed pairwise with (P₁⁻¹ + P₂⁻¹)⁻¹ = P₁ (P₁ + P₂)⁻¹ P₂, which equals Eq. 10 exactly but
    inverts one matrix per pair instead of three, which keeps the fusion system's expressions small.
    Folding track by track gives Eq. 10 for any number of tracks, since it sums informations.

    Args:
        states: each track's x̂_s (2,).
        covariances: each track's P_s (2, 2).

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
        inverse_sum = inverse_2x2(fused_covariance + P)
        fused_state = P @ inverse_sum @ fused_state + fused_covariance @ inverse_sum @ x
        fused_covariance = fused_covariance @ inverse_sum @ P
    return fused_state, fused_covariance


@building_expressions
def add_track_fusion(
    builder: DiagramBuilder, track_names: Sequence[str], name: str = "fusion"
) -> PortMap:
    """Adds the fusion site for the named local tracks to ``builder``.

    .. pydrake_system::

        name: fusion
        input_ports:
        - kinect_v1_estimated_state
        - kinect_v1_covariance
        - kinect_v2_estimated_state
        - kinect_v2_covariance
        output_ports:
        - estimated_state
        - covariance

    Args:
        builder: where the fusion's systems go.
        track_names: one name per local track; the inputs are ``{name}_estimated_state`` (2) and
            ``{name}_covariance`` (4, row-major).
        name: the fusion system's name.

    The output is a direct function of the inputs (no state), so it always fuses the tracks as they
    are at that instant.
    """
    if not track_names:
        raise ValueError("make_track_fusion: track_names is empty; fusion needs at least one track")
    inputs, states, covariances = [], [], []
    for track in track_names:
        x = MakeVectorVariable(2, f"{track}_x")
        p = MakeVectorVariable(4, f"{track}_P")
        inputs += [(f"{track}_estimated_state", list(x)), (f"{track}_covariance", list(p))]
        states.append(np.array(list(x)))
        covariances.append(np.array(list(p)).reshape(2, 2))
    fused_state, fused_covariance = fuse_tracks(states, covariances)
    return add_named_symbolic_system(
        builder,
        name,
        inputs=inputs,
        outputs=[
            ("estimated_state", list(fused_state)),
            ("covariance", list(fused_covariance.flatten())),
        ],
    )


make_track_fusion = diagram_form(add_track_fusion)
