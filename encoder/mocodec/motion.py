"""The motion model every codec works on: a skeleton and its frames.

A :class:`Skeleton` is a forest of nodes in parent-first order. Nodes are BVH joints and End
Sites (``is_end_site``); each keeps its BVH channel layout so a clip can be written back as the
BVH it came from. A :class:`Motion` holds, per frame and node, the local rotation as a unit
quaternion (``x y z w``, sign-continuous over time), the local translation (the rest offset, or the position channels
where the node has them: BVH position channels replace the OFFSET) and the local scale (the rest
scale, 1 for BVH; glTF animates it). A node's world transform composes the runtime's way
(:mod:`mocodec.kinematics`): rotation ``p.r * c.r``, translation ``p.t + p.r * (p.s * c.t)``,
scale ``p.s * c.s``.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Iterator, Sequence

import numpy as np

from . import rotations
from .channel_frames import ChannelFrames

CHANNEL_NAMES = ("Xposition", "Yposition", "Zposition", "Xrotation", "Yrotation", "Zrotation")
CHANNEL_CODES = {name: code for code, name in enumerate(CHANNEL_NAMES)}


FRAME_RUN = 2048
"""Frames a whole-clip check reads at a time (:func:`frame_runs`): its temporaries stay a few MB
however long the clip (an hours-long capture, issue 16)."""


def frame_runs(frames: int, size: int | None = None) -> Iterator[slice]:
    """Consecutive slices of at most ``size`` (default :data:`FRAME_RUN`) frames covering
    ``range(frames)``, in order.

    >>> list(frame_runs(5, 2))
    [slice(0, 2, None), slice(2, 4, None), slice(4, 5, None)]
    """
    size = size or FRAME_RUN
    for start in range(0, frames, size):
        yield slice(start, min(start + size, frames))


CHANNEL_FRAMES_BYTES = 16 << 20
"""A clip read from channels whose rotations (F x N x 4 float64) would take more than this
(about 13,000 frames of a 38-node skeleton; no dev clip) keeps its channels instead of its
rotations and translations (:meth:`Motion.from_channels`): an hours-long capture's motion in
about a fifth of the memory."""


class MotionError(ValueError):
    """A skeleton or motion breaks an invariant of the model."""


@dataclass
class Skeleton:
    """Joint hierarchy with rest offsets and BVH channel layout.

    Attributes
    ----------
    names : list of str
        Unique node names (End Sites get ``<parent>_End`` unless the file names them).
    parents : (N,) int array
        Parent index, -1 for roots; parents come before children.
    offsets : (N, 3) float array
        Rest offsets (BVH ``OFFSET``), file units.
    channels : list of tuple of int
        Per node, BVH channel codes in file order (see :data:`CHANNEL_NAMES`).
    is_end_site : (N,) bool array
    rest_rotations : (N, 4) float array, default identity
        Rest (bind) rotation of each node, ``x y z w`` (glTF rest TRS; identity for BVH).
    rest_scales : (N, 3) float array, default ones
    is_virtual : (N,) bool array, default all False
        Points the reader added at leaf joints (glTF has no end sites) so the error metric
        sees the leaf's rotation; they are not written back to the source format.
    """

    names: list[str]
    parents: np.ndarray
    offsets: np.ndarray
    channels: list[tuple[int, ...]]
    is_end_site: np.ndarray
    rest_rotations: np.ndarray | None = None
    rest_scales: np.ndarray | None = None
    is_virtual: np.ndarray | None = None

    def __post_init__(self) -> None:
        self.parents = np.asarray(self.parents, dtype=np.int64)
        self.offsets = np.asarray(self.offsets, dtype=np.float64).reshape(-1, 3)
        self.is_end_site = np.asarray(self.is_end_site, dtype=bool)
        self.channels = [tuple(int(c) for c in ch) for ch in self.channels]
        n = len(self.names)
        if self.rest_rotations is None:
            self.rest_rotations = np.tile([0.0, 0.0, 0.0, 1.0], (n, 1))
        self.rest_rotations = np.asarray(self.rest_rotations, dtype=np.float64).reshape(-1, 4)
        if self.rest_scales is None:
            self.rest_scales = np.ones((n, 3))
        self.rest_scales = np.asarray(self.rest_scales, dtype=np.float64).reshape(-1, 3)
        if self.is_virtual is None:
            self.is_virtual = np.zeros(n, dtype=bool)
        self.is_virtual = np.asarray(self.is_virtual, dtype=bool)

    @property
    def node_count(self) -> int:
        return len(self.names)

    @property
    def channel_count(self) -> int:
        return sum(len(c) for c in self.channels)

    def rotation_order(self, node: int) -> str:
        """Axes of the node's rotation channels in file order, e.g. ``"ZYX"`` ("" if none)."""
        return "".join("XYZ"[c - 3] for c in self.channels[node] if c >= 3)

    def position_axes(self, node: int) -> tuple[int, ...]:
        """Axes (0, 1, 2) of the node's position channels in file order."""
        return tuple(c for c in self.channels[node] if c < 3)

    def children(self, node: int) -> list[int]:
        return [int(i) for i in np.flatnonzero(self.parents == node)]

    def descendants(self, node: int) -> list[int]:
        """Indices of all nodes below ``node`` (not including it), parent-first."""
        out: list[int] = []
        inside = np.zeros(self.node_count, dtype=bool)
        inside[node] = True
        for i in range(node + 1, self.node_count):
            p = self.parents[i]
            if p >= 0 and inside[p]:
                inside[i] = True
                out.append(i)
        return out

    def index(self, name: str) -> int:
        try:
            return self.names.index(name)
        except ValueError:
            raise KeyError(f"no node named {name!r}") from None

    def validate(self) -> None:
        """Raise :class:`MotionError` if the skeleton breaks an invariant."""
        n = self.node_count
        if n == 0:
            raise MotionError("skeleton has no nodes")
        if self.parents.shape != (n,) or self.offsets.shape != (n, 3):
            raise MotionError("parents/offsets do not match the node count")
        if len(self.channels) != n or self.is_end_site.shape != (n,):
            raise MotionError("channels/is_end_site do not match the node count")
        if len(set(self.names)) != n:
            raise MotionError("node names are not unique")
        if any(not name for name in self.names):
            raise MotionError("empty node name")
        for i, p in enumerate(self.parents):
            if not (-1 <= p < i):
                raise MotionError(f"node {self.names[i]!r}: parent {p} does not come before it")
            if p >= 0 and self.is_end_site[p]:
                raise MotionError(f"node {self.names[i]!r} hangs below an end site")
        for i, ch in enumerate(self.channels):
            if len(set(ch)) != len(ch) or any(not 0 <= c < 6 for c in ch):
                raise MotionError(f"node {self.names[i]!r}: bad channel layout {ch}")
            if self.is_end_site[i] and ch:
                raise MotionError(f"end site {self.names[i]!r} has channels")
        if not np.all(np.isfinite(self.offsets)):
            raise MotionError("non-finite offset")

    def same_layout(self, other: "Skeleton") -> bool:
        """True when names, parents, channels and end sites match (offsets may differ)."""
        return (
            self.names == other.names
            and np.array_equal(self.parents, other.parents)
            and self.channels == other.channels
            and np.array_equal(self.is_end_site, other.is_end_site)
        )

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Skeleton):
            return NotImplemented
        return (self.same_layout(other) and np.array_equal(self.offsets, other.offsets)
                and np.array_equal(self.rest_rotations, other.rest_rotations)
                and np.array_equal(self.rest_scales, other.rest_scales)
                and np.array_equal(self.is_virtual, other.is_virtual))


@dataclass
class Motion:
    """A clip: skeleton, per-frame local rotations and translations, and its frame time.

    Attributes
    ----------
    skeleton : Skeleton
    rotations : (F, N, 4) float array
        Local rotations, unit quaternions ``x y z w``, sign-continuous along frames.
        Identity for end sites and nodes without rotation channels.
    translations : (F, N, 3) float array
        Local translations, file units: the rest offset, with the position channels
        substituted on the axes the node has them. A long clip read from channels holds both
        as :class:`~mocodec.channel_frames.ChannelFrames` (:meth:`from_channels`): index them
        by frames (and nodes) as arrays; ``np.asarray`` builds the whole array.
    frame_time : float
        Seconds per frame (BVH ``Frame Time``; for glTF the rate it was resampled at).
    name : str
        Clip name (the file stem for files read from disk, the animation's name for glTF).
    scales : (F, N, 3) float array, default the skeleton's rest scales on every frame
        Local scales (the default is a read-only broadcast view of the rest scales).
    source : dict, optional
        Where the clip came from and how it was sampled (the glTF reader records the file,
        the animation, the resampling rate and the interpolation the error is measured
        against; ``start_s``, the source time of frame 0).
    """

    skeleton: Skeleton
    rotations: np.ndarray
    translations: np.ndarray
    frame_time: float
    name: str = "clip"
    source_channels: np.ndarray | None = field(default=None, repr=False)
    """The channel values as read (F, C), kept so a BVH can be written back exactly and so
    decoded Euler angles can follow the original's 360-degree branch."""
    scales: np.ndarray | None = field(default=None, repr=False)
    source: dict | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        if not isinstance(self.rotations, ChannelFrames):
            self.rotations = np.asarray(self.rotations, dtype=np.float64)
        if not isinstance(self.translations, ChannelFrames):
            self.translations = np.asarray(self.translations, dtype=np.float64)
        if self.scales is None:  # a read-only view: a clip without scales holds none per frame
            self.scales = np.broadcast_to(self.skeleton.rest_scales, self.translations.shape)
        self.scales = np.asarray(self.scales, dtype=np.float64)

    @property
    def frame_count(self) -> int:
        return int(self.rotations.shape[0])

    @property
    def frame_rate(self) -> float:
        return 1.0 / self.frame_time

    @property
    def duration(self) -> float:
        return (self.frame_count - 1) * self.frame_time

    def validate(self) -> None:
        """Raise :class:`MotionError` if the motion breaks an invariant."""
        self.skeleton.validate()
        n = self.skeleton.node_count
        if self.rotations.ndim != 3 or self.rotations.shape[1:] != (n, 4):
            raise MotionError(f"rotations have shape {self.rotations.shape}, expected (F, {n}, 4)")
        if self.translations.shape != self.rotations.shape[:2] + (3,):
            raise MotionError("translations do not match rotations")
        if self.scales.shape != self.translations.shape:
            raise MotionError("scales do not match translations")
        if self.frame_count < 1:
            raise MotionError("motion has no frames")
        if not (np.isfinite(self.frame_time) and self.frame_time > 0):
            raise MotionError(f"frame time {self.frame_time} is not positive")
        # A run of frames at a time, so the temporaries do not grow with the clip.
        for rows in frame_runs(self.frame_count):
            if not (np.all(np.isfinite(self.rotations[rows])) and np.all(np.isfinite(self.translations[rows]))
                    and np.all(np.isfinite(self.scales[rows]))):
                raise MotionError("non-finite values in the motion")
        for rows in frame_runs(self.frame_count):
            norms = np.linalg.norm(self.rotations[rows], axis=-1)
            if np.max(np.abs(norms - 1.0)) > 1e-6:
                raise MotionError("rotations are not unit quaternions")

    def animated(self) -> np.ndarray:
        """(N, 3) bool: per node, whether the clip may move its rotation, translation and
        scale away from the rest pose: a BVH node with rotation / position channels, or any
        node whose value differs from its rest on some frame (glTF nodes have no channels)."""
        sk = self.skeleton
        n = sk.node_count
        out = np.zeros((n, 3), dtype=bool)
        out[:, 0] = [bool(sk.rotation_order(i)) for i in range(n)]
        out[:, 1] = [bool(sk.position_axes(i)) for i in range(n)]
        rest_q = sk.rest_rotations[None]
        at_rest = np.ones(n, dtype=bool)
        for rows in frame_runs(self.frame_count):
            q = self.rotations[rows]
            at_rest &= np.all(np.all(q == rest_q, axis=-1) | np.all(q == -rest_q, axis=-1), axis=0)
            out[:, 1] |= np.any(self.translations[rows] != sk.offsets[None], axis=(0, 2))
            out[:, 2] |= np.any(self.scales[rows] != sk.rest_scales[None], axis=(0, 2))
        out[:, 0] |= ~at_rest
        return out

    # ----------------------------------------------------------------- channels <-> model
    @classmethod
    def from_channels(
        cls,
        skeleton: Skeleton,
        channels: np.ndarray,
        frame_time: float,
        name: str = "clip",
    ) -> "Motion":
        """Build a motion from BVH channel values ``(F, C)`` (degrees, file units). A clip
        whose rotations would take more than :data:`CHANNEL_FRAMES_BYTES` keeps the channels
        alone: its rotations and translations are :class:`~mocodec.channel_frames.ChannelFrames`,
        computed where they are indexed (the same numbers)."""
        channels = np.asarray(channels, dtype=np.float64)
        frames = channels.shape[0]
        n = skeleton.node_count
        if frames * n * 32 > CHANNEL_FRAMES_BYTES:
            channels = channels.view()
            channels.flags.writeable = False  # what the rotations are computed from stays
            return cls(skeleton, ChannelFrames(channels, skeleton, "rotations"),
                       ChannelFrames(channels, skeleton, "translations"), float(frame_time), name,
                       source_channels=channels)
        rot = np.zeros((frames, n, 4))
        rot[..., 3] = 1.0
        trans = np.broadcast_to(skeleton.offsets, (frames, n, 3)).copy()
        col = 0
        for i, ch in enumerate(skeleton.channels):
            cols = np.arange(col, col + len(ch))
            col += len(ch)
            rot_cols = [c for c, code in zip(cols, ch) if code >= 3]
            for c, code in zip(cols, ch):
                if code < 3:
                    trans[:, i, code] = channels[:, c]
            if rot_cols:
                # Continuous per node: temporaries of one node's size, not the clip's.
                rot[:, i] = rotations.quat_make_continuous(
                    rotations.euler_to_quat(channels[:, rot_cols], skeleton.rotation_order(i)), axis=0)
        return cls(skeleton, rot, trans, float(frame_time), name, source_channels=channels)

    def to_channels(self, reference: np.ndarray | None = None) -> np.ndarray:
        """BVH channel values ``(F, C)`` for this motion.

        Euler angles are made continuous over frames; with ``reference`` (an ``(F, C)``
        channel array, e.g. the original clip's) each angle is put on the reference's
        360-degree branch instead, so a decoded clip reads like its source.
        """
        sk = self.skeleton
        out = np.zeros((self.frame_count, sk.channel_count))
        # Without a reference, three-axis joints are made continuous together, grouped by
        # rotation order, so the frame-by-frame pass runs once per order, not once per joint.
        pending: dict[str, list[tuple[list[int], np.ndarray]]] = {}
        col = 0
        for i, ch in enumerate(sk.channels):
            cols = list(range(col, col + len(ch)))
            col += len(ch)
            for c, code in zip(cols, ch):
                if code < 3:
                    out[:, c] = self.translations[:, i, code]
            rot_cols = [c for c, code in zip(cols, ch) if code >= 3]
            if not rot_cols:
                continue
            order = sk.rotation_order(i)
            angles = _euler_any_order(self.rotations[:, i], order)
            if reference is not None and len(order) == 3:
                angles = rotations.euler_nearest(angles, reference[:, rot_cols], order)
            elif reference is not None:
                angles = rotations.unwrap_euler(angles, reference[:, rot_cols])
            elif len(order) == 3:
                pending.setdefault(order, []).append((rot_cols, angles))
                continue
            else:
                angles = rotations.unwrap_euler(angles)
            out[:, rot_cols] = angles
        for order, items in pending.items():
            stacked = rotations.euler_continuous(np.stack([a for _, a in items], axis=1), order)
            for k, (rot_cols, _) in enumerate(items):
                out[:, rot_cols] = stacked[:, k]
        return out

    def slice(self, start: int, stop: int) -> "Motion":
        """Frames ``[start, stop)`` as a new motion."""
        src = None if self.source_channels is None else self.source_channels[start:stop]
        return Motion(
            self.skeleton,
            self.rotations[start:stop],
            self.translations[start:stop],
            self.frame_time,
            self.name,
            source_channels=src,
            scales=self.scales[start:stop],
            source=self.source,
        )


def _euler_any_order(q: np.ndarray, order: str) -> np.ndarray:
    """Euler angles for one to three rotation channels (joints with fewer than three
    rotation channels can only hold rotations about those axes)."""
    if len(order) == 3:
        return rotations.quat_to_euler(q, order)
    if len(order) == 1:
        axis = "XYZ".index(order)
        # Rotation about one axis: angle = 2 atan2(q_axis, w).
        return np.degrees(2.0 * np.arctan2(q[..., axis], q[..., 3]))[..., None]
    # Two axes: complete the order with the missing axis, whose angle must be ~0.
    missing = next(a for a in "XYZ" if a not in order)
    full = rotations.quat_to_euler(q, order + missing)
    # A second angle beyond +-90 comes back as the other triple (a+180, 180-b, ~180): switch
    # back so the dropped third angle is ~0.
    flip = np.abs(full[..., 2]) > 90.0
    full[flip] = np.array([180.0, 180.0, 180.0]) + [1.0, -1.0, 1.0] * full[flip]
    return full[..., :2]


def unique_name(base: str, used: set[str], sep: str = "_") -> str:
    """``base``, or ``base{sep}2``, ``base{sep}3`` ... the first not in ``used`` (added to it)."""
    name, k = base, 1
    while name in used:
        k += 1
        name = f"{base}{sep}{k}"
    used.add(name)
    return name


def concatenate_names(motions: Sequence[Motion]) -> list[str]:
    """Unique clip names for a list of motions (``walk``, ``walk_2`` ...)."""
    seen: dict[str, int] = {}
    out = []
    for m in motions:
        base = m.name or "clip"
        k = seen.get(base, 0)
        seen[base] = k + 1
        out.append(base if k == 0 else f"{base}_{k + 1}")
    return out
