"""Foot (and hand) contacts: detection on the original motion and the ``CNTC`` section that
lets the runtime pull contacts back in place by IK (seed 003 §5.3, docs/FORMAT.md "Contacts").

Pipeline, per clip:

1. :func:`floor_height` — the floor is the lowest dense mode of the heights (Y, BVH up) of the
   foot/toe/ankle joints; each effector also gets its own contact level (the lowest dense mode
   of its own height: an ankle rests higher above the floor than a toe).
2. :func:`detect_contacts` — an effector is in contact on frames where it is within
   ``height_cm`` of its contact level AND slower than ``speed_cm_s``; runs shorter than
   ``min_run_s`` are dropped.
3. :func:`build_clip_contacts` — per contact run, the original world positions, stored as
   integer offsets (in steps of ``step_cm``) from the *decoded* pre-IK position of the same
   joint at the same frame: the first frame of a segment as an ``i8`` triple, each next frame as
   a 4-bit delta of that offset (closed-loop quantised, so the error never accumulates). A new
   segment starts where the original point jumps by more than ``jump_cm`` between frames, where
   a delta does not fit 4 bits, and every 1024 frames.

With the default step of 0.1 cm every stored target is within ``0.05·√3 ≈ 0.087`` cm of the
original position.
"""
from __future__ import annotations

import re
import struct
from dataclasses import dataclass, field

import numpy as np

from .motion import Skeleton

FOOT_RE = re.compile(r"foot|toe|ankle", re.IGNORECASE)
HAND_RE = re.compile(r"hand|wrist", re.IGNORECASE)
TOE_RE = re.compile(r"toe", re.IGNORECASE)

SOLVER_TWO_BONE = 1
SOLVER_DLS = 2
MAX_EFFECTORS = 16
MAX_SEGMENT = 1024
START_RANGE = (-128, 127)
DELTA_RANGE = (-8, 7)


@dataclass(frozen=True)
class ContactSettings:
    height_cm: float = 3.0
    """Above the joint's own contact level."""
    speed_cm_s: float = 30.0
    min_run_s: float = 0.05
    step_cm: float = 0.1
    """Quantization step of the stored offsets."""
    blend_s: float = 0.03
    """IK fades in before and out after a segment over this long."""
    jump_cm: float = 2.5
    hands: bool = False


@dataclass
class Segment:
    start: int
    offsets: np.ndarray
    """(L, 3) int: the reconstructed integer offsets, frame by frame."""
    raw: np.ndarray | None = None
    """(L, 3) float: the exact offsets (in steps) the integers approximate."""
    axis: np.ndarray | None = None
    """(L, 3) unit vectors from the IK chain's root to the effector (decoded pose): the
    direction in which a correction makes the limb bend or stretch."""
    scale: np.ndarray | None = None
    """(L,) per frame, in [-1, 1], 1 by default: how much of the correction is stored. The
    encoder lowers it where the IK moves another node past the tolerance. From 1 to 0 it
    shrinks the part along ``axis`` (stretching a nearly straight limb swings the knee far);
    from 0 to -1 it shrinks the rest."""

    def rescale(self, scale: np.ndarray) -> None:
        """Re-quantise the shrunk correction closed-loop (deltas clipped to 4 bits)."""
        assert self.raw is not None
        sc = np.asarray(scale, dtype=np.float64)
        axis = self.axis if self.axis is not None else np.zeros_like(self.raw)
        along = np.sum(self.raw * axis, axis=-1, keepdims=True) * axis
        across = self.raw - along
        want = along * np.clip(sc, 0.0, 1.0)[:, None] + across * np.clip(1.0 + sc, 0.0, 1.0)[:, None]
        q = np.empty(want.shape, dtype=np.int64)
        q[0] = np.clip(np.rint(want[0]), *START_RANGE)
        for k in range(1, len(want)):
            q[k] = q[k - 1] + np.clip(np.rint(want[k] - q[k - 1]), *DELTA_RANGE)
        self.offsets, self.scale = q, sc

    def current_scale(self) -> np.ndarray:
        return np.ones(self.length) if self.scale is None else self.scale

    @property
    def length(self) -> int:
        return int(len(self.offsets))

    @property
    def end(self) -> int:
        """Last frame (inclusive)."""
        return self.start + self.length - 1


@dataclass
class EffectorContacts:
    node: int
    solver: int
    chain: int
    segments: list[Segment] = field(default_factory=list)


@dataclass
class ClipContacts:
    frame_count: int
    step: float
    """File units per offset step."""
    blend_frames: float
    effectors: list[EffectorContacts]
    contact_masks: dict[int, np.ndarray] = field(default_factory=dict)
    """Per effector node, the detected contact frames of the original (F,) bool."""

    @property
    def segment_count(self) -> int:
        return sum(len(e.segments) for e in self.effectors)

    def prune(self) -> "ClipContacts":
        """Without effectors that have no segment left."""
        self.effectors = [e for e in self.effectors if e.segments]
        return self


# ---------------------------------------------------------------------------- detection
def _depth(skeleton: Skeleton, node: int) -> int:
    d, p = 0, int(skeleton.parents[node])
    while p >= 0:
        d, p = d + 1, int(skeleton.parents[p])
    return d


def effector_joints(skeleton: Skeleton, hands: bool = False) -> list[int]:
    """Joints (not end sites) whose names say foot/toe/ankle (and hand/wrist when asked) and
    that have the two ancestors the IK needs."""
    out = []
    for i, name in enumerate(skeleton.names):
        if skeleton.is_end_site[i] or _depth(skeleton, i) < 2:
            continue
        if FOOT_RE.search(name) or (hands and HAND_RE.search(name)):
            out.append(i)
    return out[:MAX_EFFECTORS]


def lowest_mode(values: np.ndarray, bin_width: float, share: float = 0.2) -> float:
    """Mean of the lowest dense cluster of 1-D ``values``: histogram with ``bin_width`` bins,
    take the lowest bin holding at least ``share`` of the fullest bin's count, and average
    the values within one bin of it."""
    v = np.asarray(values, dtype=np.float64).ravel()
    v = v[np.isfinite(v)]
    if v.size == 0:
        raise ValueError("no values")
    lo, hi = float(v.min()), float(v.max())
    bins = max(1, int(np.ceil((hi - lo) / bin_width)) + 1)
    counts, edges = np.histogram(v, bins=bins, range=(lo, lo + bins * bin_width))
    first = int(np.nonzero(counts >= share * counts.max())[0][0])
    near = (v >= edges[first] - bin_width) & (v <= edges[first + 1] + bin_width)
    return float(v[near].mean())


def floor_height(skeleton: Skeleton, positions: np.ndarray, cm_per_unit: float) -> float:
    """Floor height (file units) of a clip: the lowest dense mode of its foot joints' heights."""
    feet = [i for i, n in enumerate(skeleton.names) if FOOT_RE.search(n) and not skeleton.is_end_site[i]]
    if not feet:
        raise ValueError("the skeleton has no foot/toe/ankle joint")
    return lowest_mode(positions[:, feet, 1], 1.0 / cm_per_unit)


def _drop_short_runs(mask: np.ndarray, min_len: int) -> np.ndarray:
    out = mask.copy()
    for s, e in runs(mask):
        if e - s + 1 < min_len:
            out[s:e + 1] = False
    return out


def runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """Inclusive (first, last) frames of each run of True."""
    m = np.concatenate([[False], np.asarray(mask, dtype=bool), [False]])
    d = np.diff(m.astype(np.int8))
    starts = np.nonzero(d == 1)[0]
    ends = np.nonzero(d == -1)[0] - 1
    return [(int(s), int(e)) for s, e in zip(starts, ends)]


def detect_contacts(skeleton: Skeleton, positions: np.ndarray, frame_rate: float, cm_per_unit: float,
                    settings: ContactSettings = ContactSettings()) -> dict[int, np.ndarray]:
    """Per effector joint, the frames (F,) bool where it touches the floor and holds still."""
    pos = np.asarray(positions, dtype=np.float64)
    frames = pos.shape[0]
    out: dict[int, np.ndarray] = {}
    if frames < 2:
        return out
    min_len = max(1, int(np.ceil(settings.min_run_s * frame_rate - 1e-9)))
    for node in effector_joints(skeleton, settings.hands):
        p = pos[:, node]
        level = lowest_mode(p[:, 1], 1.0 / cm_per_unit)
        near = (p[:, 1] - level) * cm_per_unit <= settings.height_cm
        speed = np.linalg.norm(np.gradient(p, axis=0), axis=-1) * frame_rate * cm_per_unit
        mask = _drop_short_runs(near & (speed <= settings.speed_cm_s), min_len)
        if mask.any():
            out[node] = mask
    return out


# ---------------------------------------------------------------------------- encoding
def _solver(skeleton: Skeleton, node: int) -> tuple[int, int]:
    """Two-bone IK for ankles and wrists; damped least squares over three joints for toes."""
    depth = _depth(skeleton, node)
    if TOE_RE.search(skeleton.names[node]):
        return SOLVER_DLS, min(3, depth)
    return SOLVER_TWO_BONE, 2


def _segments_of_run(offsets: np.ndarray, original: np.ndarray, start: int, jump_units: float) -> list[Segment]:
    """Closed-loop quantised segments of one contact run; ``offsets`` (L, 3) in steps."""
    segments: list[Segment] = []
    current: list[np.ndarray] = []
    seg_start = start
    for k in range(len(offsets)):
        want = offsets[k]
        fresh = not current or len(current) >= MAX_SEGMENT
        if not fresh and np.linalg.norm(original[k] - original[k - 1]) > jump_units:
            fresh = True
        if not fresh:
            d = np.rint(want - current[-1]).astype(np.int64)
            if d.min() < DELTA_RANGE[0] or d.max() > DELTA_RANGE[1]:
                fresh = True
            else:
                current.append(current[-1] + d)
                continue
        if current:
            segments.append(Segment(seg_start, np.array(current, dtype=np.int64),
                                    offsets[seg_start - start:k].copy()))
            current = []
        q = np.rint(want).astype(np.int64)
        if q.min() < START_RANGE[0] or q.max() > START_RANGE[1]:
            continue  # further from the decoded pose than an i8 reaches: no contact here
        current = [q]
        seg_start = start + k
    if current:
        segments.append(Segment(seg_start, np.array(current, dtype=np.int64),
                                offsets[seg_start - start:].copy()))
    return segments


def build_clip_contacts(skeleton: Skeleton, masks: dict[int, np.ndarray], original: np.ndarray,
                        decoded: np.ndarray, frame_rate: float, cm_per_unit: float,
                        settings: ContactSettings = ContactSettings()) -> ClipContacts | None:
    """Contact trajectories of one clip. ``original`` and ``decoded`` (pre-IK) are world
    positions (F, N, 3) in file units. None when no contact survives."""
    step = float(np.float32(settings.step_cm / cm_per_unit))
    jump = settings.jump_cm / cm_per_unit
    effectors = []
    for node in sorted(masks):
        solver, chain = _solver(skeleton, node)
        eff = EffectorContacts(node, solver, chain)
        root = node
        for _ in range(chain):
            root = int(skeleton.parents[root])
        limb = decoded[:, node] - decoded[:, root]
        limb /= np.maximum(np.linalg.norm(limb, axis=-1, keepdims=True), 1e-12)
        for s, e in runs(masks[node]):
            offs = (original[s:e + 1, node] - decoded[s:e + 1, node]) / step
            for seg in _segments_of_run(offs, original[s:e + 1, node], s, jump):
                seg.axis = limb[seg.start:seg.end + 1]
                eff.segments.append(seg)
        effectors.append(eff)
    clip = ClipContacts(int(original.shape[0]), step, float(np.float32(settings.blend_s * frame_rate)),
                        effectors, dict(masks))
    clip.prune()
    return clip if clip.effectors else None


def stored_targets(clip: ClipContacts, decoded: np.ndarray) -> dict[int, tuple[np.ndarray, np.ndarray]]:
    """Per effector node: (frames, targets (n, 3)) the runtime aims at on segment frames."""
    out = {}
    for e in clip.effectors:
        frames = np.concatenate([np.arange(s.start, s.end + 1) for s in e.segments])
        offs = np.concatenate([s.offsets for s in e.segments]).astype(np.float64)
        out[e.node] = (frames, decoded[frames, e.node] + np.float32(clip.step) * offs)
    return out


# ---------------------------------------------------------------------------- bytes
def _pack_nibbles(deltas: np.ndarray) -> bytes:
    flat = (np.asarray(deltas, dtype=np.int64).ravel() & 0xF).astype(np.uint8)
    if flat.size % 2:
        flat = np.concatenate([flat, np.zeros(1, dtype=np.uint8)])
    return (flat[0::2] | (flat[1::2] << 4)).astype(np.uint8).tobytes()


def clip_block(clip: ClipContacts) -> bytes:
    """One clip's block of the CNTC section (docs/FORMAT.md), padded to 4 bytes."""
    segs = [s for e in clip.effectors for s in e.segments]
    if not 1 <= len(clip.effectors) <= MAX_EFFECTORS or not 1 <= len(segs) <= 0xFFFF:
        raise ValueError("contact block: effector or segment count out of range")
    out = bytearray(struct.pack("<IffHH", clip.frame_count, clip.step, clip.blend_frames,
                                len(clip.effectors), len(segs)))
    first = 0
    for e in clip.effectors:
        out += struct.pack("<HBBHH", e.node, e.solver, e.chain, first, len(e.segments))
        first += len(e.segments)
    deltas = bytearray()
    for s in segs:
        start = s.offsets[0]
        out += struct.pack("<IIHbbbBH", s.start, len(deltas), s.length, int(start[0]), int(start[1]),
                           int(start[2]), 0, 0)
        deltas += _pack_nibbles(np.diff(s.offsets, axis=0))
    out += deltas
    while len(out) % 4:
        out.append(0)
    return bytes(out)


def contacts_section(clips: dict[int, ClipContacts]) -> bytes:
    """CNTC section bytes: entry table sorted by clip index, then the clip blocks in order."""
    order = sorted(clips)
    blocks = [clip_block(clips[i]) for i in order]
    out = bytearray(struct.pack("<II", len(order), 0))
    off = 8 + 8 * len(order)
    for i, b in zip(order, blocks):
        out += struct.pack("<II", i, off)
        off += len(b)
    for b in blocks:
        out += b
    return bytes(out)
