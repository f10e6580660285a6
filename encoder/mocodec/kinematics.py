"""Forward kinematics, vectorised over frames.

One pass over the nodes in parent-first order; every step works on all frames at once, so a
5000-frame clip costs ``N`` numpy operations on ``(F, 3)`` / ``(F, 4)`` arrays.
"""
from __future__ import annotations

import weakref
from typing import Iterator

import numpy as np

from .motion import CHANNEL_FRAMES_BYTES, Motion, Skeleton
from .rotations import quat_multiply, quat_rotate


def forward_kinematics(
    skeleton: Skeleton, rotations: np.ndarray, translations: np.ndarray,
    scales: np.ndarray | None = None, world_scales: bool = False,
) -> tuple[np.ndarray, ...]:
    """World rotations ``(F, N, 4)`` and positions ``(F, N, 3)`` from local transforms (and
    with ``world_scales`` the world scales ``(F, N, 3)``).

    ``rotations`` (F, N, 4), ``translations`` and ``scales`` (F, N, 3, default 1) are local
    (parent-relative). Composed as the runtime does (``mcd_compose``): rotation ``p.r c.r``,
    translation ``p.t + p.r (p.s * c.t)``, scale ``p.s * c.s`` component-wise. With a
    non-uniform scale above a rotated child this differs from a glTF matrix product (which
    would shear); the positions of the nodes are the same wherever the scale is uniform.
    """
    rotations = np.asarray(rotations, dtype=np.float64)
    translations = np.asarray(translations, dtype=np.float64)
    world_rot = node_major(rotations.shape)
    world_pos = node_major(translations.shape)
    world_scale = None
    if scales is not None:
        scales = np.broadcast_to(np.asarray(scales, dtype=np.float64), translations.shape)
        if scales.strides[0] == 0 and np.all(scales[0] == 1.0):
            scales = None  # the rest scales of a clip without scales: x 1 changes no number
    if scales is not None:
        world_scale = node_major(translations.shape)
    for i, p in enumerate(skeleton.parents):
        # Each node's inputs made contiguous one node at a time (the same numbers), not the
        # whole clip's copied node-major at once: a long clip's copies stay one node's.
        rot_i, trans_i = _node_rows(rotations, i), _node_rows(translations, i)
        if p < 0:
            world_rot[:, i] = rot_i
            world_pos[:, i] = trans_i
            if world_scale is not None:
                world_scale[:, i] = _node_rows(scales, i)
        else:
            world_rot[:, i] = quat_multiply(world_rot[:, p], rot_i)
            t = trans_i if world_scale is None else world_scale[:, p] * trans_i
            world_pos[:, i] = world_pos[:, p] + quat_rotate(world_rot[:, p], t)
            if world_scale is not None:
                world_scale[:, i] = world_scale[:, p] * _node_rows(scales, i)
    if world_scales:
        if world_scale is None:
            world_scale = np.ones_like(translations)
        return world_rot, world_pos, world_scale
    return world_rot, world_pos


def _node_rows(a: np.ndarray, i: int) -> np.ndarray:
    """Node ``i``'s rows ``a[:, i]`` of an (F, N, d) array, contiguous (copied when they are
    not; a row broadcast over the frames stays a view)."""
    rows = a[:, i]
    return rows if rows.strides[0] == 0 else np.ascontiguousarray(rows)


def node_major(shape: tuple[int, ...]) -> np.ndarray:
    """An uninitialised (F, N, d) array whose memory holds node after node: ``a[:, i]`` is
    contiguous, as the node loops here and in the key-frame engine read and write it."""
    if len(shape) != 3:
        return np.empty(shape)
    return np.empty((shape[1], shape[0], shape[2])).transpose(1, 0, 2)


def motion_world(motion: Motion) -> tuple[np.ndarray, np.ndarray]:
    """World rotations ``(F, N, 4)`` and positions ``(F, N, 3)`` of a motion, its scales
    composed."""
    return forward_kinematics(motion.skeleton, motion.rotations, motion.translations, motion.scales)


def shared_world_positions(motion: Motion) -> np.ndarray:
    """World positions ``(F, N, 3)`` of a motion as a read-only array, the same one for every
    caller that asks while some caller still holds it (the key-frame fitter's compensation and
    the encoder's runtime check of a clip both need it: one copy of a long clip's, not two)."""
    inputs = (motion.rotations, motion.translations, motion.scales)
    held = _SHARED_WORLD.get(id(motion))
    if held is not None:
        owner, sources, pos_ref = held
        pos = pos_ref()
        if owner() is motion and all(r() is a for r, a in zip(sources, inputs)) and pos is not None:
            return pos
    pos = node_major(motion.translations.shape)
    for rows, part in world_position_chunks(motion):  # the world rotations a run at a time
        pos[rows] = part
    pos.flags.writeable = False
    key = id(motion)
    _SHARED_WORLD[key] = (weakref.ref(motion, lambda _, k=key: _SHARED_WORLD.pop(k, None)),
                          tuple(weakref.ref(a) for a in inputs), weakref.ref(pos))
    return pos


POSE_CHUNK = 8192
"""Frames :func:`shared_world_positions` poses at a time."""


def world_position_chunks(motion: Motion, chunk: int | None = None) -> Iterator[tuple[slice, np.ndarray]]:
    """World positions of a motion a run of ``chunk`` frames (default :data:`POSE_CHUNK`) at a
    time, ``(rows, positions)`` (each frame's numbers are its own: the same as whole)."""
    chunk = chunk or POSE_CHUNK
    for start in range(0, motion.frame_count, chunk):
        rows = slice(start, min(start + chunk, motion.frame_count))
        yield rows, forward_kinematics(motion.skeleton, motion.rotations[rows], motion.translations[rows],
                                       motion.scales[rows])[1]

SHORT_CLIP_BYTES = CHANNEL_FRAMES_BYTES
"""A clip whose world rotations (F x N x 4 float64) take at most this many bytes (about 13,000
frames of a 38-node skeleton; every dev clip) keeps its world rotations and half-way reference
whole, computed once, rather than rebuilt where they are read: the same numbers, faster. The
size past which a clip read from channels keeps them alone, so such a clip is never short."""


def short_clip(motion: Motion) -> bool:
    """Whether ``motion`` is short enough to hold its whole-clip poses (:data:`SHORT_CLIP_BYTES`)."""
    return motion.frame_count * motion.skeleton.node_count * 32 <= SHORT_CLIP_BYTES


def world_rotations(motion: Motion) -> np.ndarray:
    """World rotations ``(F, N, 4)`` of a motion: :func:`forward_kinematics`' own products,
    without the positions."""
    rotations = np.asarray(motion.rotations, dtype=np.float64)
    out = node_major(rotations.shape)
    for i, p in enumerate(motion.skeleton.parents):
        rot_i = _node_rows(rotations, i)
        out[:, i] = rot_i if p < 0 else quat_multiply(out[:, p], rot_i)
    return out

# id(motion) -> weak references to it, to the arrays its world positions were computed from,
# and to those positions: kept only while someone else holds them (shared_world_positions).
_SHARED_WORLD: dict[int, tuple] = {}


def world_positions(motion: Motion) -> np.ndarray:
    """World positions ``(F, N, 3)`` of every joint and end site, file units."""
    return motion_world(motion)[1]


def lever_arms(skeleton: Skeleton, positions: np.ndarray) -> np.ndarray:
    """Per node, the largest distance from it to any of its descendants over all frames
    ``(N,)``: how far a rotation error at the node can move a point (0 for leaves)."""
    positions = np.asarray(positions, dtype=np.float64)
    n = skeleton.node_count
    out = np.zeros(n)
    # Walk children before parents, carrying each subtree's max distance to the node.
    for i in range(n - 1, -1, -1):
        desc = skeleton.descendants(i)
        if desc:
            d = np.linalg.norm(positions[:, desc] - positions[:, i:i + 1], axis=-1)
            out[i] = float(d.max())
    return out


def halfway_world(motion: Motion) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The original half-way between consecutive frames, where engines also sample.

    Returns world positions ``(F-1, N, 3)`` (:func:`halfway_positions`), and per interval the
    largest point step between its two frames ``(F-1,)`` in file units and the largest local
    joint turn ``(F-1,)`` in degrees (:func:`interval_motion`): large ones mark capture
    glitches, where no half-way pose was recorded.
    """
    return (halfway_positions(motion), *interval_motion(motion, world_positions(motion)))


HALFWAY_CHUNK = 8192
"""Intervals :func:`halfway_positions` builds at a time."""


def halfway_positions(motion: Motion) -> np.ndarray:
    """World positions ``(F-1, N, 3)`` of the original half-way between consecutive frames:
    local rotations by slerp at one half (the normalised sum of the two quaternions on one
    hemisphere), translations and scales averaged, then forward kinematics; built a run of
    intervals at a time (:func:`halfway_chunks`), so a long clip's temporaries stay small."""
    out = np.empty((motion.frame_count - 1, motion.rotations.shape[1], 3))
    for rows, pos in halfway_chunks(motion):
        out[rows] = pos
    return out


def halfway_chunks(motion: Motion, chunk: int = HALFWAY_CHUNK) -> Iterator[tuple[slice, np.ndarray]]:
    """:func:`halfway_positions` a run of ``chunk`` intervals at a time, ``(rows, positions)``
    (each interval's numbers do not depend on the run it is in): for a check that needs
    them once per repair round, so that a long clip's are never held whole."""
    intervals = motion.frame_count - 1
    scales = motion.scales
    rest_scales = scales.ndim == 3 and scales.strides[0] == 0  # one row broadcast: its own mean
    for start in range(0, intervals, chunk):
        stop = min(start + chunk, intervals)
        a, b = slice(start, stop), slice(start + 1, stop + 1)
        # Both ends read once (a long clip's are computed from its channels when read).
        q, t = motion.rotations[start:stop + 1], motion.translations[start:stop + 1]
        q0, q1 = q[:-1], q[1:]
        dot = np.sum(q0 * q1, axis=-1, keepdims=True)
        rot = q0 + np.where(dot < 0.0, -1.0, 1.0) * q1
        rot = rot / np.linalg.norm(rot, axis=-1, keepdims=True)
        trans = 0.5 * (t[:-1] + t[1:])
        if rest_scales:  # 0.5 (s + s) is s: a broadcast row, which forward kinematics skips at 1
            scale = np.broadcast_to(0.5 * (scales[0] + scales[0]), trans.shape)
        else:
            scale = 0.5 * (scales[a] + scales[b])
        yield a, forward_kinematics(motion.skeleton, rot, trans, scale)[1]


def interval_motion(motion: Motion, world: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    """Per interval between frames, the largest point step ``(F-1,)`` (file units) of the
    world positions ``world`` (F, N, 3; None: posed here a run at a time) and the largest local
    joint turn ``(F-1,)`` (degrees)."""
    intervals = max(motion.frame_count - 1, 0)
    step, turn = np.empty(intervals), np.empty(intervals)
    for start in range(0, intervals, HALFWAY_CHUNK):  # per node (F-1, N) only a run at a time
        rows = slice(start, min(start + HALFWAY_CHUNK, intervals))
        span = slice(start, rows.stop + 1)
        rot = motion.rotations[span]  # read once (a long clip's are computed when read)
        pos = (world[span] if world is not None else
               forward_kinematics(motion.skeleton, rot, motion.translations[span], motion.scales[span])[1])
        s, t = _steps_and_turns(rot, pos)
        step[rows], turn[rows] = s.max(axis=1), t.max(axis=1)
    return step, turn


def interval_motion_per_node(motion: Motion, world: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`interval_motion` per node: every point's step ``(F-1, N)`` and every node's
    local turn ``(F-1, N)`` between consecutive frames."""
    return _steps_and_turns(motion.rotations, world)


def _steps_and_turns(rotations: np.ndarray, world: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`interval_motion_per_node` of local ``rotations`` (F, N, 4) and world positions
    ``world`` (F, N, 3)."""
    step = np.linalg.norm(world[1:] - world[:-1], axis=-1)
    # The angle from the dot product: imprecise near 0 degrees, exact enough at the glitch
    # thresholds (6e-13 degrees from quat_angle over 10 degrees on CMU 01_03), a tenth of its time.
    dot = np.abs(np.einsum("fnk,fnk->fn", rotations[:-1], rotations[1:]))
    turn = np.degrees(2.0 * np.arccos(np.minimum(dot, 1.0)))
    return step, turn


GLITCH_STEP_CM = 10.0   # a point faster than 12 m/s between two 120 fps frames: a capture glitch
GLITCH_TURN_DEG = 90.0  # a joint turning faster than 10,800 degrees/s at 120 fps: the same (issue 16: "say, 90°")


def smooth_intervals(step: np.ndarray, turn: np.ndarray, cm_per_unit: float) -> np.ndarray:
    """Which intervals between frames the capture moves through smoothly (F-1,) bool, from
    :func:`halfway_world`'s steps and turns: no point steps more than
    :data:`GLITCH_STEP_CM` and no joint turns more than :data:`GLITCH_TURN_DEG`. Across a
    glitch (a marker swap, a foot flipping over for two frames, CMU's T-pose frame 0) half-way
    is no pose anyone recorded, so no path between the two frames is wrong."""
    return (np.asarray(step) * cm_per_unit <= GLITCH_STEP_CM) & (np.asarray(turn) <= GLITCH_TURN_DEG)


def held_intervals(step: np.ndarray, turn: np.ndarray, cm_per_unit: float) -> np.ndarray:
    """The intervals between frames where a curve through the frames can follow the capture's
    own half-way path (F-1,) bool: smooth ones (:func:`smooth_intervals`) whose neighbours are
    smooth too. Next to a glitch a Catmull-Rom segment's end tangent spans the glitch, so even
    keys on every frame overshoot there (31 cm half-way in CMU 05_17 between two flipped
    frames)."""
    smooth = smooth_intervals(step, turn, cm_per_unit)
    held = smooth.copy()
    held[1:] &= smooth[:-1]
    held[:-1] &= smooth[1:]
    return held
