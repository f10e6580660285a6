"""Bounded swing parameters for twist tracks of long clips.

A twist track (``KIND_TWIST``) stores an unwrapped twist angle and the swing left after it as
modified Rodrigues parameters relative to one reference rotation per clip. The swing is taken
on the quaternion path continuous from frame 0, so over a long capture (joined takes, a foot
that wanders far from its mean pose) the path can go round to the reference's antipode, where
|p| = tan(angle / 4) grows without bound: a 20-minute clip of the dev takes gave the left foot
MRPs of 2e5 and a range no 24-bit key can cover, though every rotation it stands for is within
180 degrees of the reference. Taking each frame's swing on the reference's own hemisphere
keeps |p| <= 1; the price is a jump of the parameters (not of the rotation: p and
-p / |p|^2 are one rotation) where the swing crosses 180 degrees from the reference, which the
fitter keys like any other fast change.

Only tracks whose continuous swing has gone round (|p| above :data:`SWING_MRP_LIMIT`) are
changed, so clips that never go round keep their parameters and bytes.
"""
from __future__ import annotations

import numpy as np

from . import rotations as R
from .curves import KIND_TWIST

SWING_MRP_LIMIT = 4.0  # |p| > 4: the swing has turned past 304 degrees along its continuous path


def swing_on_reference_hemisphere(kind: int, values: np.ndarray, target: np.ndarray, ref: np.ndarray,
                                  axis: np.ndarray) -> np.ndarray | None:
    """A twist track's values (F, 4) with every frame's swing MRPs on the reference's hemisphere
    (|p| <= 1), recomputed from the target rotations (F, 4); None when the track is not a twist
    track or its swing never goes round (nothing to change)."""
    # Written so that NaN (a frame exactly at the antipode: 0 / 0) counts as gone round.
    if kind != KIND_TWIST or np.all(np.linalg.norm(values[:, 1:], axis=1) <= SWING_MRP_LIMIT):
        return None
    theta = values[:, 0]
    # The same decomposition the track was built with: q = twist(axis, theta) * ref * rel.
    rest = R.quat_multiply(R.quat_conjugate(R.quat_from_axis_angle(axis, theta)), target)
    rel = R.quat_multiply(R.quat_conjugate(np.broadcast_to(ref, rest.shape)), rest)
    rel = np.where(rel[:, 3:4] < 0.0, -rel, rel)
    return np.concatenate((theta[:, None], R.mrp_from_quat(rel)), axis=1)
