"""Converted angle format of seed 000 §3.2: per joint, the world direction of its bone as two
spherical angles (φ polar from +Z, ϕ azimuth in the XY plane, eq. 5) and the orientation ψ
about that bone (eq. 6–7).

Conventions (the seed leaves them open; these are ours):

* **Which bone.** A joint's bone axis ``u`` is a fixed unit vector of the joint's own frame:
  the rest offset of its first child (file order) with a non-zero offset. When every child
  offset is zero (CMU's Hips, Spine1, LeftHand ... whose children start at the joint itself),
  ``u`` is the rest-pose direction from the joint to the first descendant at a non-zero
  distance, following first children; this is then a pseudo-bone, fixed in the joint's frame,
  not the live direction to that descendant (the zero-length child rotates on its own). A
  joint with no descendant at any distance uses +Y. Only joints with rotation channels are
  converted; the others keep the identity.
* **World, not local.** φ, ϕ describe ``d = W u`` with ``W`` the joint's *world* rotation,
  because eq. 18 sums link vectors in one frame: that is what makes the Jacobian closed form.
* **ψ.** ``W = A(ψ, d) · R_cross(u → d)`` (eq. 7), with ``R_cross`` the shortest rotation
  taking ``u`` to ``d``; ``A`` then fixes ``d`` so it is a rotation by ψ about ``d`` (eq. 6).
  This is singular only when the bone points exactly opposite to ``u`` (a 180° swing from
  rest); :func:`min_cross_margin` reports how close a clip comes.
* **Unwrapping.** ϕ and ψ are unwrapped over frames (period 2π) so they move smoothly for
  prediction; φ comes from ``atan2`` in [0, π] and is left as is, so a bone passing through
  the ±Z pole shows a φ reflection and a π jump in ϕ (not smoothed here).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..kinematics import forward_kinematics
from ..motion import Motion, Skeleton
from ..rotations import (
    quat_conjugate,
    quat_from_axis_angle,
    quat_multiply,
    quat_normalize,
    quat_rotate,
)

_ZERO = 1e-12  # offsets shorter than this (file units) count as zero-length


@dataclass
class ConvertedAngles:
    """φ, ϕ, ψ (radians, (F, J)) for the ``joints`` (J,) of a skeleton, plus the bone axes."""

    joints: np.ndarray  # (J,) node indices with rotation channels
    axes: np.ndarray    # (J, 3) unit bone axis u in each joint's own frame
    polar: np.ndarray   # (F, J) φ
    azimuth: np.ndarray  # (F, J) ϕ, unwrapped
    twist: np.ndarray   # (F, J) ψ, unwrapped

    def directions(self) -> np.ndarray:
        """World bone directions ``d`` (F, J, 3) from φ, ϕ (eq. 5 with r = 1)."""
        return spherical_to_direction(self.polar, self.azimuth)


def bone_axes(skeleton: Skeleton) -> np.ndarray:
    """Unit bone axis ``u`` (N, 3) of every node, in the node's own frame (rule in the module
    docstring)."""
    n = skeleton.node_count
    axes = np.tile(np.array([0.0, 1.0, 0.0]), (n, 1))
    first_child = np.full(n, -1)
    for i in range(n - 1, -1, -1):
        p = skeleton.parents[i]
        if p >= 0:
            first_child[p] = i  # walking backwards leaves the first child in file order
    for i in range(n):
        kids = skeleton.children(i)
        direct = [c for c in kids if np.linalg.norm(skeleton.offsets[c]) > _ZERO]
        if direct:
            v = skeleton.offsets[direct[0]]
        else:
            # Follow first children through zero-length offsets, summing rest offsets
            # (rest pose: every rotation is the identity, so offsets add up in i's frame).
            v = np.zeros(3)
            c = first_child[i]
            while c >= 0 and np.linalg.norm(v) <= _ZERO:
                v = v + skeleton.offsets[c]
                c = first_child[c]
            if np.linalg.norm(v) <= _ZERO:
                continue
        axes[i] = v / np.linalg.norm(v)
    return axes


def direction_to_spherical(d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """φ (polar from +Z) and ϕ (azimuth) of unit vectors ``d`` (..., 3), eq. 5 inverted."""
    rho = np.hypot(d[..., 0], d[..., 1])
    # atan2 rather than arccos(z): accurate near the poles, where arccos loses half the digits.
    return np.arctan2(rho, d[..., 2]), np.arctan2(d[..., 1], d[..., 0])


def spherical_to_direction(polar: np.ndarray, azimuth: np.ndarray) -> np.ndarray:
    """Unit vectors (..., 3) for φ, ϕ (eq. 5 with r = 1)."""
    s = np.sin(polar)
    return np.stack((s * np.cos(azimuth), s * np.sin(azimuth), np.cos(polar)), axis=-1)


def shortest_arc(u: np.ndarray, d: np.ndarray) -> np.ndarray:
    """Quaternion of the shortest rotation taking unit ``u`` to unit ``d`` (R_cross of eq. 7)."""
    u, d = np.broadcast_arrays(np.asarray(u, float), np.asarray(d, float))
    q = np.concatenate((np.cross(u, d), 1.0 + np.sum(u * d, axis=-1, keepdims=True)), axis=-1)
    return quat_normalize(q)


def to_converted(motion: Motion) -> ConvertedAngles:
    """φ, ϕ, ψ of every joint with rotation channels, over all frames of ``motion``."""
    sk = motion.skeleton
    joints = np.array([i for i in range(sk.node_count) if sk.rotation_order(i)], dtype=np.int64)
    axes = bone_axes(sk)[joints]
    world_rot, _ = forward_kinematics(sk, motion.rotations, motion.translations)
    w = world_rot[:, joints]                       # (F, J, 4)
    u = np.broadcast_to(axes, w.shape[:-1] + (3,))
    d = quat_rotate(w, u)
    d = d / np.linalg.norm(d, axis=-1, keepdims=True)
    polar, azimuth = direction_to_spherical(d)
    # A = W · R_cross⁻¹ is a rotation about d, so its vector part is d·sin(ψ/2).
    a = quat_multiply(w, quat_conjugate(shortest_arc(u, d)))
    twist = 2.0 * np.arctan2(np.sum(a[..., :3] * d, axis=-1), a[..., 3])
    return ConvertedAngles(
        joints=joints,
        axes=axes,
        polar=polar,
        azimuth=np.unwrap(azimuth, axis=0),
        twist=np.unwrap(twist, axis=0),
    )


def world_rotations(conv: ConvertedAngles) -> np.ndarray:
    """World rotations (F, J, 4) of the converted joints: W = A(ψ, d) · R_cross(u → d)."""
    d = conv.directions()
    u = np.broadcast_to(conv.axes, d.shape)
    return quat_multiply(quat_from_axis_angle(d, conv.twist), shortest_arc(u, d))


def from_converted(conv: ConvertedAngles, template: Motion) -> Motion:
    """The motion whose converted angles are ``conv``: local rotations rebuilt from the world
    ones, translations (root position, offsets) taken from ``template``."""
    sk = template.skeleton
    frames = conv.polar.shape[0]
    w_conv = world_rotations(conv)
    identity = np.zeros((frames, 4))
    identity[:, 3] = 1.0
    world = np.empty((frames, sk.node_count, 4))
    local = np.broadcast_to(identity[:, None], world.shape).copy()
    slot = {int(j): k for k, j in enumerate(conv.joints)}
    # Parent-first walk: a joint's local rotation is its parent's world rotation undone.
    for i, p in enumerate(sk.parents):
        parent_world = world[:, p] if p >= 0 else identity
        if i in slot:
            world[:, i] = w_conv[:, slot[i]]
            local[:, i] = quat_multiply(quat_conjugate(parent_world), world[:, i])
        else:
            world[:, i] = parent_world  # no rotation channels: identity local rotation
    return Motion(sk, local, template.translations.copy(), template.frame_time, template.name)


def min_cross_margin(conv: ConvertedAngles) -> float:
    """Smallest ``1 + u·d`` over the clip: how close a bone comes to the R_cross singularity
    (0 = exactly opposite to its rest axis; round-trip error grows like 1/margin)."""
    d = conv.directions()
    return float(np.min(1.0 + np.sum(np.broadcast_to(conv.axes, d.shape) * d, axis=-1)))
