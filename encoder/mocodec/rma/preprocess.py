"""Root alignment (seed 003 §3) and compact virtual markers (Fig. 2b), with their inverse.

Root alignment takes the heading (rotation about world Y) and the root translation out of every
frame, so the same step walked in different directions and places gives the same markers. A clip
whose root tilts far (somersault, breakdance, lying down) has its whole root rotation taken out
instead, because a tilt that large is not "posture" the subspace should learn (§3).

Markers live in that aligned frame. Per rotating joint ``j`` (Fig. 2b):

- ``a``: the joint's position (shared with its parent's "child" marker);
- ``a'``: the position of its main child (the child with the longest bone), also a position
  marker, so it costs nothing extra;
- ``c``: one extra marker off the bone axis, which fixes the twist about the bone;
- ``b``: a marker along the bone, only where the bone is too short for ``a'`` to define a
  direction (zero-length hip/shoulder/hand joints in CMU skeletons).

The inverse builds each joint's world frame from (bone direction, off-axis direction) by
Gram-Schmidt, so markers that a lossy code has moved still give valid rotations.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .. import rotations as R

from ..kinematics import forward_kinematics
from ..motion import Motion, Skeleton

UP = np.array([0.0, 1.0, 0.0])


# ------------------------------------------------------------------------ root alignment
@dataclass
class RootTrack:
    """What alignment took out of a clip: kept losslessly here, coded separately by the codec
    (Catmull-Rom keys, §3).

    ``yaw`` (F,) radians about world Y, unwrapped; ``translation`` (F, 3) file units;
    ``full`` True when the whole root rotation was taken out (then ``rotation`` (F, 4) holds it
    and ``yaw`` is unused).
    """

    yaw: np.ndarray
    translation: np.ndarray
    full: bool
    rotation: np.ndarray

    def removed_rotation(self) -> np.ndarray:
        """(F, 4) rotation that alignment divided out of the root."""
        if self.full:
            return self.rotation
        return R.quat_from_axis_angle(UP, self.yaw)


def split_yaw(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Swing-twist split ``q = Ry(yaw) * tilt`` about world Y. Returns (yaw (F,) unwrapped,
    tilt (F, 4)). Where the Y-twist is undefined (tilt of exactly 180 degrees) yaw is 0."""
    q = np.asarray(q, dtype=np.float64)
    half = np.arctan2(q[:, 1], q[:, 3])
    undefined = np.hypot(q[:, 1], q[:, 3]) < 1e-9
    half = np.where(undefined, 0.0, half)
    # Unwrap the full angle: a root that turns several times keeps a continuous heading curve.
    yaw = np.unwrap(2.0 * half)
    tilt = R.quat_multiply(R.quat_conjugate(R.quat_from_axis_angle(UP, yaw)), q)
    return yaw, tilt


def tilt_angle(tilt: np.ndarray) -> np.ndarray:
    """Angle (radians) of the tilt rotations (F, 4)."""
    return 2.0 * np.arctan2(np.linalg.norm(tilt[:, :3], axis=1), np.abs(tilt[:, 3]))


def align_root(motion: Motion, large_tilt_deg: float = 60.0) -> tuple[np.ndarray, RootTrack]:
    """Aligned root rotations (F, 4) and the :class:`RootTrack` taken out.

    The clip counts as a large-Rx/Rz motion when its root tilts more than ``large_tilt_deg``
    on any frame (a standing or walking subject stays well under 30 degrees; cartwheels and
    floor work go past 90); then all six root DOFs are taken out and the aligned root
    rotation is the identity.
    """
    root = _single_root(motion.skeleton)
    q = R.quat_make_continuous(motion.rotations[:, root])
    yaw, tilt = split_yaw(q)
    full = bool(np.max(tilt_angle(tilt)) > np.radians(large_tilt_deg))
    trans = motion.translations[:, root].copy()
    if full:
        aligned = np.zeros_like(q)
        aligned[:, 3] = 1.0
    else:
        aligned = R.quat_make_continuous(tilt)
    return aligned, RootTrack(yaw, trans, full, q.copy())


def _single_root(sk: Skeleton) -> int:
    roots = np.flatnonzero(sk.parents < 0)
    if len(roots) != 1:
        raise ValueError(f"rma analysis needs one root joint, the skeleton has {len(roots)}")
    return int(roots[0])


# ------------------------------------------------------------------------ marker layout
@dataclass
class MarkerLayout:
    """Which virtual markers a skeleton gets and how each joint's frame is rebuilt.

    Attributes
    ----------
    position_nodes : (P,) nodes whose positions are markers (every node off its parent).
    position_source : (N,) index into ``position_nodes`` giving each node's position, -1 for
        the root (the aligned origin); zero-offset nodes share their ancestor's marker.
    joints : (J,) rotating joints (a rotation channel and a child or an off-axis marker).
    axis_marker : (J,) marker index of the bone-direction point (``a'`` or ``b``).
    side_marker : (J,) marker index of the off-axis point ``c``.
    rest_axis, rest_side : (J, 3) unit vectors in the joint's local frame the two markers lie on.
    b_length, c_length : (J,) distances of ``b`` (0 where ``a'`` is used) and ``c``, file units.
    marker_count : int
    """

    position_nodes: np.ndarray
    position_source: np.ndarray
    joints: np.ndarray
    axis_marker: np.ndarray
    side_marker: np.ndarray
    rest_axis: np.ndarray
    rest_side: np.ndarray
    b_length: np.ndarray
    c_length: np.ndarray
    marker_count: int

    @property
    def b_count(self) -> int:
        return int(np.count_nonzero(self.b_length > 0))


def marker_layout(sk: Skeleton, cm_per_unit: float, min_bone_cm: float = 5.0,
                  marker_cm: float = 10.0) -> MarkerLayout:
    """Compact marker set of Fig. 2b for ``sk``.

    A bone shorter than ``min_bone_cm`` gets marker ``b`` at ``marker_cm`` along it (a short
    bone turns small marker errors into large angle errors); ``c`` sits ``max(bone,
    marker_cm)`` off the axis for the same reason.
    """
    root = _single_root(sk)
    n = sk.node_count
    lengths = np.linalg.norm(sk.offsets, axis=1)
    for i in range(n):
        if i != root and sk.position_axes(i):
            raise ValueError(f"node {sk.names[i]!r} has position channels; only the root may "
                             "(markers would not carry its translation)")
    off_parent = (lengths > 1e-9) & (np.arange(n) != root)
    position_nodes = np.flatnonzero(off_parent)
    source = np.full(n, -1, dtype=np.int64)
    slot = {int(v): k for k, v in enumerate(position_nodes)}
    for i in range(n):
        if i == root:
            continue
        source[i] = slot[i] if off_parent[i] else source[sk.parents[i]]
    min_bone = min_bone_cm / cm_per_unit
    mark = marker_cm / cm_per_unit
    joints, axis_m, side_m, r_axis, r_side, b_len, c_len = [], [], [], [], [], [], []
    count = len(position_nodes)
    for j in range(n):
        if sk.is_end_site[j] or not sk.rotation_order(j):
            continue
        kids = sk.children(j)
        main = max(kids, key=lambda c: lengths[c]) if kids else -1
        bone = lengths[main] if main >= 0 else 0.0
        if bone >= min_bone:
            axis = sk.offsets[main] / bone
            axis_m.append(int(source[main]))
            b_len.append(0.0)
        else:
            axis = sk.offsets[main] / bone if bone > 1e-9 else UP.copy()
            axis_m.append(count)
            count += 1
            b_len.append(mark)
        # Off-axis direction: perpendicular to the bone, built from the rest axis least aligned
        # with it so the cross product is well conditioned.
        helper = np.eye(3)[int(np.argmin(np.abs(axis)))]
        side = np.cross(axis, helper)
        side /= np.linalg.norm(side)
        joints.append(j)
        r_axis.append(axis)
        r_side.append(side)
        side_m.append(count)
        count += 1
        c_len.append(max(bone, mark))
    return MarkerLayout(position_nodes, source, np.asarray(joints, dtype=np.int64),
                        np.asarray(axis_m, dtype=np.int64), np.asarray(side_m, dtype=np.int64),
                        np.asarray(r_axis).reshape(-1, 3), np.asarray(r_side).reshape(-1, 3),
                        np.asarray(b_len), np.asarray(c_len), count)


# ------------------------------------------------------------------------ forward / inverse
@dataclass
class Prepared:
    """One clip after preprocessing: aligned markers (F, M, 3) and what is needed to undo it."""

    markers: np.ndarray
    root: RootTrack
    layout: MarkerLayout
    aligned_positions: np.ndarray  # (F, N, 3) joint positions in the aligned frame

    @property
    def flat(self) -> np.ndarray:
        """Markers as (F, 3M) rows, the vectors PCA works on."""
        return self.markers.reshape(len(self.markers), -1)


def aligned_pose(motion: Motion, aligned_root: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """World rotations and positions (F, N, ...) with the root rotation replaced by
    ``aligned_root`` and the root at the origin."""
    root = _single_root(motion.skeleton)
    rot = motion.rotations.copy()
    trans = motion.translations.copy()
    rot[:, root] = aligned_root
    trans[:, root] = 0.0
    return forward_kinematics(motion.skeleton, rot, trans)


def to_markers(motion: Motion, cm_per_unit: float, large_tilt_deg: float = 60.0,
               layout: MarkerLayout | None = None) -> Prepared:
    """Align the root and place the compact virtual markers on every frame."""
    layout = layout or marker_layout(motion.skeleton, cm_per_unit)
    aligned_root, track = align_root(motion, large_tilt_deg)
    rot_w, pos_w = aligned_pose(motion, aligned_root)
    f = motion.frame_count
    markers = np.empty((f, layout.marker_count, 3))
    markers[:, :len(layout.position_nodes)] = pos_w[:, layout.position_nodes]
    jr = rot_w[:, layout.joints]                     # (F, J, 4)
    jp = pos_w[:, layout.joints]                     # (F, J, 3)
    has_b = layout.b_length > 0
    if has_b.any():
        b = jp[:, has_b] + R.quat_rotate(jr[:, has_b], layout.rest_axis[has_b] * layout.b_length[has_b, None])
        markers[:, layout.axis_marker[has_b]] = b
    c = jp + R.quat_rotate(jr, layout.rest_side * layout.c_length[:, None])
    markers[:, layout.side_marker] = c
    return Prepared(markers, track, layout, pos_w)


def _frames_from_vectors(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotation matrices (..., 3, 3) whose columns are Gram-Schmidt of (u, v, u x v)."""
    e1 = u / np.maximum(np.linalg.norm(u, axis=-1, keepdims=True), 1e-12)
    v2 = v - np.sum(v * e1, axis=-1, keepdims=True) * e1
    e2 = v2 / np.maximum(np.linalg.norm(v2, axis=-1, keepdims=True), 1e-12)
    e3 = np.cross(e1, e2)
    return np.stack((e1, e2, e3), axis=-1)


def marker_world_rotations(markers: np.ndarray, layout: MarkerLayout) -> np.ndarray:
    """World (aligned-frame) rotations (F, J, 4) of the layout's joints from markers."""
    markers = np.asarray(markers, dtype=np.float64)
    f = markers.shape[0]
    src = layout.position_source[layout.joints]
    a = np.where((src >= 0)[None, :, None], markers[:, np.maximum(src, 0)], 0.0)
    u = markers[:, layout.axis_marker] - a
    v = markers[:, layout.side_marker] - a
    world = _frames_from_vectors(u, v)
    rest = _frames_from_vectors(layout.rest_axis, layout.rest_side)  # (J, 3, 3)
    # world_frame = R * rest_frame  =>  R = world_frame @ rest_frame^T
    mats = world @ np.swapaxes(rest, -1, -2)[None]
    return R.quat_make_continuous(R.quat_from_matrix(mats.reshape(-1, 3, 3)).reshape(f, -1, 4))


def from_markers(markers: np.ndarray, root: RootTrack, layout: MarkerLayout,
                 template: Motion) -> Motion:
    """Rebuild a motion (local rotations, root re-applied) from aligned markers.

    ``template`` gives the skeleton, frame time and non-rotating channels."""
    sk = template.skeleton
    rootj = _single_root(sk)
    world = marker_world_rotations(markers, layout)
    f = world.shape[0]
    n = sk.node_count
    wr = np.zeros((f, n, 4))
    wr[..., 3] = 1.0
    local = np.zeros((f, n, 4))
    local[..., 3] = 1.0
    jslot = np.full(n, -1)
    jslot[layout.joints] = np.arange(len(layout.joints))
    # Parent-first pass: world rotations of non-rotating nodes follow their parent's.
    for i in range(n):
        p = sk.parents[i]
        if jslot[i] >= 0:
            wr[:, i] = world[:, jslot[i]]
            local[:, i] = wr[:, i] if p < 0 else R.quat_multiply(R.quat_conjugate(wr[:, p]), wr[:, i])
        elif p >= 0:
            wr[:, i] = wr[:, p]
    local[:, rootj] = R.quat_multiply(root.removed_rotation(), local[:, rootj])
    local = R.quat_make_continuous(R.quat_normalize(local), axis=0)
    trans = np.broadcast_to(sk.offsets, (f, n, 3)).copy()
    trans[:, rootj] = root.translation
    return Motion(sk, local, trans, template.frame_time, template.name)


def aligned_positions_from_markers(markers: np.ndarray, layout: MarkerLayout,
                                   skeleton: Skeleton) -> np.ndarray:
    """Joint positions (F, N, 3) in the aligned frame the decoder would rebuild from markers
    (rotations from markers, then forward kinematics with the skeleton's bones). Alignment is
    rigid, so distances measured here equal world-space distances when the root track is
    coded losslessly."""
    world = marker_world_rotations(markers, layout)
    sk = skeleton
    f, n = world.shape[0], sk.node_count
    jslot = np.full(n, -1)
    jslot[layout.joints] = np.arange(len(layout.joints))
    wr = np.zeros((f, n, 4))
    wr[..., 3] = 1.0
    pos = np.zeros((f, n, 3))
    for i in range(n):
        p = sk.parents[i]
        if jslot[i] >= 0:
            wr[:, i] = world[:, jslot[i]]
        elif p >= 0:
            wr[:, i] = wr[:, p]
        if p >= 0:
            pos[:, i] = pos[:, p] + R.quat_rotate(wr[:, p], sk.offsets[i])
    return pos



def library_layout(skeletons: list[Skeleton], cm_per_unit: float, min_bone_cm: float = 5.0,
                   marker_cm: float = 10.0) -> MarkerLayout:
    """One marker layout for clips whose skeletons share a layout (names, parents, channels)
    but not bone lengths (several CMU subjects), so one group PCA can span them: a bone gets
    marker ``b`` if it is short in any of the skeletons."""
    first = skeletons[0]
    for sk in skeletons[1:]:
        if not sk.same_layout(first):
            raise ValueError("skeletons differ in layout; analyse them separately")
    lengths = np.stack([np.linalg.norm(sk.offsets, axis=1) for sk in skeletons])
    offsets = first.offsets.copy()
    for i in range(first.node_count):
        offsets[i] = skeletons[int(np.argmin(lengths[:, i]))].offsets[i]
    proxy = Skeleton(list(first.names), first.parents, offsets, first.channels, first.is_end_site)
    # Rest directions differ slightly between subjects: use layout_for() per clip.
    return marker_layout(proxy, cm_per_unit, min_bone_cm, marker_cm)


def layout_for(skeleton: Skeleton, shared: MarkerLayout) -> MarkerLayout:
    """``shared``'s marker structure with rest directions and marker distances of ``skeleton``
    (the same joints, markers and b/c choices; only the geometry of this subject)."""
    r_axis = shared.rest_axis.copy()
    uses_child = shared.b_length == 0
    # a' markers are child positions: their rest direction is this subject's bone; b markers
    # keep the shared direction (any fixed direction works, forward and inverse agree on it).
    child = shared.position_nodes[shared.axis_marker[uses_child]]
    off = skeleton.offsets[child]
    r_axis[uses_child] = off / np.linalg.norm(off, axis=1, keepdims=True)
    r_side = np.empty_like(r_axis)
    for k in range(len(r_axis)):
        helper = np.eye(3)[int(np.argmin(np.abs(r_axis[k])))]
        side = np.cross(r_axis[k], helper)
        r_side[k] = side / np.linalg.norm(side)
    return MarkerLayout(shared.position_nodes, shared.position_source, shared.joints,
                        shared.axis_marker, shared.side_marker, r_axis, r_side,
                        shared.b_length, shared.c_length, shared.marker_count)
