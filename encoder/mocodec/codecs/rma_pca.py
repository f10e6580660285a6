"""Codec ``rma-pca``: seed 003's subspace representation, chosen by a PCA variance fraction
(``mocodec encode --codec rma --pca-variance 0.95``), in one ``RMAP`` section (docs/FORMAT.md,
version 2) that the runtime samples in place.

The pipeline is the seed's: root alignment (§3: heading and root translation out, all six root
DOFs for large tilts), compact virtual markers (Fig. 2b), PPCA behaviour segments and
normalized-cut groups (§4.1), one PCA per group keeping the requested fraction of the variance
(16-bit mean, 12-bit axes, §5.4), and per piece of a clip (a run of frames in one group) the
coefficient trajectories as Catmull-Rom keys with adaptive control points on a quantization
lattice (§5.1-5.2), stored as ``rma`` tracks (:mod:`.rma_bitstream`), three coefficients a
track. The root curves are coded the same way. The runtime rebuilds markers (mean + axes x
coefficients, dequantized from the codes as it samples), joint rotations from the markers by
Gram-Schmidt, and re-applies the root.

A variance fraction is not an error bound: this codec makes **no tolerance promise**. It
reports the error it reaches (measured through the C runtime like every codec).
``docs/RMA_STUDY.md`` measured why the default ``rma`` does not use a subspace: a max-error
promise needs 43-140 of 204 components per group.

Repeated clips (§4.2, eq. 6) are coded with ``-O repeats=true``: measured to cost bytes on the
dev set (docs/CODECS.md), so off by default.
"""
from __future__ import annotations

import struct
import time
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..curves import catmull_rom, fit_keys
from ..keyframes import KIND_TRANSLATION, Track
from ..motion import Motion, Skeleton
from ..quantize import Quantizer, StepQuantizer
from ..rma import pca as P
from ..rma import preprocess as PP
from ..rma import repeats as RP
from ..rma import segment as S
from ..tolerance import Tolerance
from . import CheckFn, CodecOutput, ProgressFn, UnsupportedMotion

if TYPE_CHECKING:
    from ..bake import Runner
from .rma import curve_track, frame0_jumps
from .rma_bitstream import payload as rmal_payload
from .rma_reference import decode_payload

SECTION_HEADER = 32
JOINT_RECORD = 24
GROUP_HEADER = 16
CLIP_HEADER = 16
PIECE_RECORD = 16
NO_INDEX = 0xFFFF
NO_PRIMARY = 0xFFFFFFFF
SHARED_BIT = 0x80000000  # a piece's ``curves`` field names a shared curve set
PER_NODE = 3  # coefficients per curve-set node: its translation's x, y, z
MEAN_BITS, AXIS_BITS = 16, 12
MAX_BLEND = 64


@dataclass
class RmaPcaSettings:
    """Settings of ``rma-pca`` (lengths in cm).

    Parameters
    ----------
    variance : float, default 0.95
        Fraction of each group's marker variance its PCA keeps (the seed: 0.95 and 0.98).
    groups : int or None, default None
        None: the seed's §4.1, PPCA segments grouped by normalized cut, the group count chosen
        by the PCA bit-cost model (1 ... 12). 1: one PCA for the whole library, no
        segmentation. n > 1: n groups by normalized cut.
    coef_cm : float, default 1.0
        Max deviation of each coefficient curve (keys and quantization) from the projected
        coefficients; a coefficient moves the markers by this much at most.
    root_cm : float, default 0.1
        Max error of the root translation curve, and of the heading curve at 1 m from the root.
    quant_fraction : float, default 0.6
        Share of a curve's budget given to quantization.
    key_grid : int, default 4
        New keys prefer the first frames of cells of this many frames (1, 2, 4 or 8: the
        ``RMAL`` key cells, as in ``rma``).
    repeats : bool, default False
        Seed 003 §4.2 and eq. 6: run the repeated-motion analysis per group and code each
        repeated interval as a reference curve into its primary (the primary as the runtime
        reconstructs it) plus coefficient differences. Off by default: measured to cost
        bytes on the dev set (docs/CODECS.md).
    repeat_threshold_cm : float, default 5.0
        Self-distance threshold of the analysis, RMS distance per marker.
    ref_frames : float, default 0.25
        Max error of a repeated piece's reference curve, in frames of its primary.
    blend_seconds : float, default 0.06
        Width of the cross-fade between two pieces of a clip (the seed's clip-boundary
        smoothing, ~60 ms): each piece's curves reach half of it into the neighbour and the
        runtime blends the two reconstructions there. 0: no blending (a pose may jump at a
        border by the two pieces' reconstruction errors).
    """

    tolerance: Tolerance | None = None  # unused: this codec makes no promise
    variance: float = 0.95
    groups: int | None = None
    coef_cm: float = 1.0
    root_cm: float = 0.1
    quant_fraction: float = 0.6
    key_grid: int = 4
    repeats: bool = False
    repeat_threshold_cm: float = 5.0
    ref_frames: float = 0.25
    blend_seconds: float = 0.06

    def __post_init__(self) -> None:
        self.variance = float(self.variance)
        if not 0.0 < self.variance <= 1.0:
            raise ValueError(f"variance must be in (0, 1], got {self.variance}")
        if self.groups is not None:
            self.groups = int(self.groups)
            if not 1 <= self.groups <= 64:
                raise ValueError(f"groups must be 1 ... 64, got {self.groups}")
        for name in ("coef_cm", "root_cm"):
            v = float(getattr(self, name))
            if not (np.isfinite(v) and v > 0):
                raise ValueError(f"{name} must be a positive number of cm, got {v}")
            setattr(self, name, v)
        if not 0.0 < float(self.quant_fraction) < 1.0:
            raise ValueError(f"quant_fraction must be in (0, 1), got {self.quant_fraction}")
        self.key_grid = int(self.key_grid)
        if self.key_grid not in (1, 2, 4, 8):
            raise ValueError(f"key_grid must be 1, 2, 4 or 8, got {self.key_grid}")
        if not isinstance(self.repeats, bool):
            raise ValueError(f"repeats must be true or false, got {self.repeats!r}")
        self.blend_seconds = float(self.blend_seconds)
        if not 0.0 <= self.blend_seconds <= 0.5:
            raise ValueError(f"blend_seconds must be 0 ... 0.5, got {self.blend_seconds}")

    def blend_frames(self, frame_time: float) -> int:
        """Half-width of the cross-fade in frames (the format's ``blend``, at most 64)."""
        return min(int(round(0.5 * self.blend_seconds / frame_time)), MAX_BLEND)


@dataclass
class Piece:
    """Frames ``[start, stop]`` of clip ``clip`` (inclusive: a piece shares its last frame with
    the next piece's first, so the curve spans the step between them) coded in ``group``."""

    clip: int
    start: int
    stop: int
    group: int


# ------------------------------------------------------------------------ analysis (§3, §4.1)
def _long_enough(pieces: list[Piece], span: int) -> list[Piece]:
    """Merge pieces shorter than ``span`` frames into their predecessor in the clip (or, for a
    clip's first piece, its successor), so cross-fades neither overlap nor leave the clip."""
    out: list[Piece] = []
    for p in pieces:
        q = out[-1] if out else None
        if q is not None and q.clip == p.clip and (q.group == p.group or min(q.stop - q.start, p.stop - p.start) < span):
            # The merged piece keeps the group of the longer part.
            group = q.group if q.stop - q.start >= p.stop - p.start else p.group
            out[-1] = Piece(p.clip, q.start, p.stop, group)
        else:
            out.append(Piece(p.clip, p.start, p.stop, p.group))
    return out


def pieces_and_groups(flats: list[np.ndarray], groups: int | None, blend: int = 0,
                      runner: "Runner | None" = None) -> list[Piece]:
    """Cut every clip into behaviour segments and group them (seed 003 §4.1); consecutive
    segments of one clip in the same group become one piece, and pieces are at least
    ``2 blend + 1`` frames long. Each clip's cuts are searched on ``runner``'s workers."""
    if groups == 1:
        labels = np.zeros(len(flats), dtype=np.int64)
        segs = [S.Segment(i, 0, len(x)) for i, x in enumerate(flats)]
    else:
        segs = S.segment_library(flats, map_clips=runner.map if runner else None)
        blocks = [flats[s.clip][s.start:s.stop] for s in segs]
        feats = [S.segment_feature(b) for b in blocks]
        labels = S.group_segments(feats, n_groups=groups, cost=S.pca_group_cost(blocks))
    pieces: list[Piece] = []
    for s, g in zip(segs, labels):
        if pieces and pieces[-1].clip == s.clip and pieces[-1].group == g:
            pieces[-1].stop = s.stop
        else:
            pieces.append(Piece(s.clip, s.start, s.stop, int(g)))
    # Inclusive stops: each piece reaches the next one's first frame (or the clip's last).
    for p in pieces:
        p.stop = min(p.stop, len(flats[p.clip]) - 1)
    pieces = _long_enough(pieces, 2 * blend + 1)
    # Group numbers dense from 0 in order of first use.
    order = {g: i for i, g in enumerate(dict.fromkeys(p.group for p in pieces))}
    for p in pieces:
        p.group = order[p.group]
    return pieces


@dataclass
class GroupBasis:
    k: int
    mean_q: Quantizer
    mean_codes: np.ndarray   # (D,)
    axis_q: list[Quantizer]
    axis_codes: np.ndarray   # (k, D)
    mean: np.ndarray         # (D,) as the runtime decodes it
    axes: np.ndarray         # (D, k) as the runtime decodes them


def _fixed(values: np.ndarray, bits: int) -> tuple[Quantizer, np.ndarray, np.ndarray]:
    lo, hi = float(values.min()), float(values.max())
    step = max(hi - lo, 1e-30) / ((1 << bits) - 1) * (1.0 + 1e-6)
    q = Quantizer.for_range(np.array([lo]), np.array([hi]), np.array([step]))
    codes = q.encode(values[:, None])[:, 0]
    return q, codes, q.decode(codes[:, None])[:, 0]


def group_basis(rows: np.ndarray, variance: float) -> GroupBasis:
    """PCA of a group's marker rows keeping ``variance``: 16-bit mean, 12-bit axes (§5.4)."""
    dec = P.decompose(rows)
    k = dec.components_for_variance(variance)
    mq, mc, mean = _fixed(dec.mean, MEAN_BITS)
    qs, codes, cols = [], [], []
    for i in range(k):
        q, c, v = _fixed(dec.vectors[:, i], AXIS_BITS)
        qs.append(q)
        codes.append(c)
        cols.append(v)
    axes = np.stack(cols, axis=1) if k else np.zeros((len(mean), 0))
    return GroupBasis(k, mq, mc, qs, np.asarray(codes, dtype=np.int64).reshape(k, -1), mean, axes)


def project(basis: GroupBasis, rows: np.ndarray) -> np.ndarray:
    """Coefficients (F, k): least squares on the decoded (quantized) axes."""
    if basis.k == 0:
        return np.zeros((len(rows), 0))
    a = basis.axes
    return np.linalg.solve(a.T @ a, a.T @ (rows - basis.mean).T).T


# ------------------------------------------------------------------------ curves
def _curve_track(values: np.ndarray, budget: float, quant_fraction: float, grid: int, split: bool = False) -> Track:
    """One scalar (or 3-vector) curve as an ``rma`` translation track within ``budget`` on
    every frame (max abs deviation per component); ``split``: its first segment detached (the
    capture jumps from frame 0 to frame 1, as CMU's added T-pose does)."""
    values = np.asarray(values, dtype=np.float64)
    if values.ndim == 1:
        values = np.stack((values, np.zeros_like(values), np.zeros_like(values)), axis=1)
    frames = len(values)
    step = np.full(3, 2.0 * quant_fraction * budget)
    reach = np.abs(values).max(axis=0)
    # Keep |q| well inside the lattice: a very small budget on a long root path is legal input.
    step = np.maximum(step, reach / (StepQuantizer.MAX_Q / 4))
    q = StepQuantizer.for_range(-reach, reach, step.max() * np.ones(3))
    split = split and frames >= 3
    mandatory = np.unique([0, 1, frames - 1] if split else [0, frames - 1])
    keys, kv, _ = fit_keys(values, np.full(frames, budget * 1.0000001),
                           lambda r: np.max(np.abs(r - values), axis=1), mandatory, q.roundtrip,
                           grid=grid if frames > 4 * grid else 1, split=split)
    t = Track(node=0, kind=KIND_TRANSLATION, values=values, target=values,
              ref=np.zeros(4), axis=np.zeros(3), split=split)
    t.keys, t.key_values, t.quantizer = keys, kv, q
    return t


def pack_coefficients(coef: np.ndarray) -> list[np.ndarray]:
    """Coefficients (F, k) as the curve-set nodes carry them: node j's translation holds
    coefficients 3j, 3j + 1, 3j + 2 (zeros past k)."""
    frames, k = coef.shape
    padded = np.zeros((frames, PER_NODE * max(-(-k // PER_NODE), 1)))
    padded[:, :k] = coef
    return [padded[:, j:j + PER_NODE] for j in range(0, padded.shape[1], PER_NODE)]


def curve_set(tracks: list[Track | None], frames: int) -> bytes:
    """An ``RMAL`` v2 payload whose node ``i`` translation is ``tracks[i]`` (None: a node at
    rest, whose translation is zero)."""
    modes = [(0, 0 if t is None else 2, 0) for t in tracks]
    return rmal_payload(frames, modes, [], [curve_track(t) for t in tracks if t is not None])


def coefficient_set(coef: np.ndarray, budget: float, s: "RmaPcaSettings", first: list[Track] | None = None,
                    split: bool = False) -> bytes:
    """The curve set of coefficients (F, k) within ``budget`` each, after the tracks ``first``
    (a repeated piece's reference curve); a group without components has one resting node."""
    frames = len(coef)
    tracks: list[Track | None] = list(first or [])
    if coef.shape[1] == 0:
        tracks.append(None)
    else:
        tracks += [_curve_track(c, budget, s.quant_fraction, s.key_grid, split) for c in pack_coefficients(coef)]
    return curve_set(tracks, frames)


def track_curve(t: Track) -> np.ndarray:
    """What the decoder evaluates for a fitted track's first component, on every frame."""
    x = np.arange(len(t.values), dtype=np.float64)
    return catmull_rom(t.keys, t.quantizer.roundtrip(t.key_values), x, split=t.split)[:, 0]


def set_coefficients(payload: bytes, k: int, x: np.ndarray, first: int = 0) -> np.ndarray:
    """Coefficients (len(x), k) the runtime reconstructs from a coefficient curve set at
    ``x`` (its nodes from ``first`` on), with the reference decoder."""
    nodes = struct.unpack_from("<I", payload, 8)[0]
    sk = _carrier(nodes)
    trans = decode_payload(payload, sk, x, version=2)[1][:, first:]
    return trans.reshape(len(x), -1)[:, :k]


def _carrier(nodes: int) -> Skeleton:
    """A skeleton of ``nodes`` unconnected nodes at the origin: what curve sets decode against."""
    return Skeleton([f"c{i}" for i in range(nodes)], np.full(nodes, -1), np.zeros((nodes, 3)),
                    [() for _ in range(nodes)], np.zeros(nodes, dtype=bool))


def root_curves(root: PP.RootTrack, cm_per_unit: float, s: RmaPcaSettings) -> tuple[list[np.ndarray], list[float]]:
    """The root's curves: translation and heading, or translation and the whole rotation
    (quaternion x y z, then w) for a six-DOF clip."""
    trans_budget = s.root_cm / cm_per_unit
    angle_budget = s.root_cm / 100.0  # radians: root_cm at 1 m
    if not root.full:
        return [root.translation, root.yaw], [trans_budget, angle_budget]
    q = root.rotation
    return [root.translation, q[:, :3], q[:, 3]], [trans_budget, 0.5 * angle_budget, 0.5 * angle_budget]


# ------------------------------------------------------------------------ section layout
def _pack12(codes: np.ndarray) -> bytes:
    """12-bit codes, two per three bytes, low code first (docs/FORMAT.md)."""
    c = np.asarray(codes, dtype=np.uint32).ravel()
    if len(c) % 2:
        c = np.append(c, 0)
    a, b = c[0::2], c[1::2]
    out = np.stack((a & 0xFF, (a >> 8) | ((b & 0xF) << 4), b >> 4), axis=1).astype(np.uint8)
    return out.tobytes()


def group_record(b: GroupBasis) -> bytes:
    d = len(b.mean)
    head = struct.pack("<IIff", b.k, 0, float(b.mean_q.minimum[0]), float(b.mean_q.step[0]))
    steps = b"".join(struct.pack("<ff", float(q.minimum[0]), float(q.step[0])) for q in b.axis_q)
    body = head + steps + np.asarray(b.mean_codes, dtype="<u2").tobytes() + _pack12(b.axis_codes)
    assert len(b.mean_codes) == d
    return body + bytes(-len(body) % 4)  # 4-aligned


def joint_table(layout: PP.MarkerLayout) -> bytes:
    out = []
    for j, node in enumerate(layout.joints):
        uses_b = layout.b_length[j] > 0
        child = NO_INDEX if uses_b else int(layout.position_nodes[layout.axis_marker[j]])
        origin = int(layout.position_source[node])
        bdir = layout.rest_axis[j] if uses_b else np.zeros(3)
        out.append(struct.pack("<6H3f", int(node), child, int(layout.axis_marker[j]), int(layout.side_marker[j]),
                               NO_INDEX if origin < 0 else origin, 0, *np.asarray(bdir, dtype=np.float32).tolist()))
    return b"".join(out)


def clip_payload(frames: int, full: bool, pieces: list[tuple[int, int, int, int]], sets: list[bytes]) -> bytes:
    """A clip's payload: its frames, root mode, pieces (first frame, group, curves, primary:
    ``curves`` an offset into ``sets`` or ``SHARED_BIT | s``, ``primary`` a shared set index or
    ``NO_PRIMARY``), then its own curve sets (the root's first) back to back."""
    table = CLIP_HEADER + PIECE_RECORD * len(pieces)
    size = table + sum(len(c) for c in sets)
    head = struct.pack("<4I", size, frames, len(pieces), int(full))
    return head + b"".join(struct.pack("<4I", *p) for p in pieces) + b"".join(sets)


def section_prefix(clips: int, markers: int, joints: bytes, bases: list[GroupBasis], blend: int,
                   shared: list[bytes]) -> bytes:
    """Everything the clips share: header, joint table, the offsets of the group records and
    of the shared curve sets, the group records, the shared curve sets."""
    records = [group_record(b) for b in bases]
    tables = SECTION_HEADER + len(joints) + 4 * (len(records) + len(shared))
    group_at = tables + np.concatenate(([0], np.cumsum([len(r) for r in records])))
    shared_at = int(group_at[-1]) + np.concatenate(([0], np.cumsum([len(c) for c in shared])))
    end = int(shared_at[-1])
    header = struct.pack("<8I", clips, len(records), markers, len(joints) // JOINT_RECORD, blend, len(shared), end, 0)
    out = (header + joints + np.asarray(group_at[:-1], dtype="<u4").tobytes()
           + np.asarray(shared_at[:-1], dtype="<u4").tobytes() + b"".join(records) + b"".join(shared))
    assert len(out) == end
    return out


# ------------------------------------------------------------------------ repetition (§4.2, eq. 6)
@dataclass
class SubPiece:
    """A run of a clip's frames ``[start, stop]`` (stop inclusive, shared with the next) in
    ``group``; a repeated one refers to sub-piece ``primary`` (an index into the plan) through
    ``ref``, the primary clip's frame for each of its frames ``start ... stop``."""

    clip: int
    start: int
    stop: int
    group: int
    primary: int = -1
    ref: np.ndarray | None = None


def repetition_plan(pieces: list[Piece], flats: list[np.ndarray], bases: list[GroupBasis],
                    frame_time: float, cm: float, s: RmaPcaSettings, blend: int) -> list[SubPiece]:
    """Pieces split at the repeated intervals the analysis finds in each group (seed 003 §4.2):
    every repeated interval becomes its own sub-piece, referring to the sub-piece that holds
    its primary. Intervals that cross a piece, whose primary crosses one, or that would leave a
    sub-piece shorter than two blend windows are left as they are (coded directly)."""
    plan = [SubPiece(p.clip, p.start, p.stop, p.group) for p in pieces]
    if not s.repeats:
        return plan
    span = 2 * blend + 1
    cuts: dict[int, list[tuple[int, int, int, np.ndarray]]] = {}   # piece -> (start, stop excl., primary piece, ref)
    for g, b in enumerate(bases):
        members = [i for i, p in enumerate(pieces) if p.group == g]
        if b.k == 0 or not members:
            continue
        ranges = [(pieces[i].start, pieces[i].stop + (pieces[i].stop == len(flats[pieces[i].clip]) - 1))
                  for i in members]
        z = np.concatenate([project(b, flats[pieces[i].clip][a:e]) for i, (a, e) in zip(members, ranges)])
        offsets = np.concatenate([[0], np.cumsum([e - a for a, e in ranges])])
        thr = s.repeat_threshold_cm / cm * np.sqrt(len(b.mean) / 3)
        ra = RP.analyse(z, offsets[1:-1], frame_time, RP.RepeatSettings(threshold=thr))

        def where(row: float) -> tuple[int, float]:
            k = int(np.searchsorted(offsets, row, side="right") - 1)
            return k, ranges[k][0] + (row - offsets[k])

        for c in ra.clips:
            if c.kind != RP.REPEATED:
                continue
            pc = ra.clips[c.primary]
            (k0, f0), (k1, _) = where(c.start), where(c.stop - 1)
            (q0, _), (q1, _) = where(pc.start), where(pc.stop - 1)
            if k0 != k1 or q0 != q1:
                continue
            ref = np.array([where(r)[1] for r in c.ref])
            cuts.setdefault(members[k0], []).append((int(f0), int(f0) + c.frames, members[q0], ref))
    # Accept intervals in order, keeping every sub-piece at least `span` frames long; a primary
    # must stay in a direct sub-piece, so a piece holding an accepted primary is not cut there.
    out: list[SubPiece] = []
    first_sub: dict[int, list[int]] = {}
    accepted: list[tuple[int, int, int, int, np.ndarray]] = []
    for i, p in enumerate(pieces):
        first_sub[i] = []
        at = p.start
        end = p.stop + 1 if p.stop == len(flats[p.clip]) - 1 else p.stop
        for a, e, prim, ref in sorted(cuts.get(i, []), key=lambda r: r[0]):
            if a < at or (a != at and a - at < span) or e - a < span + 1 or (e != end and end - e < span + 1):
                continue
            if a > at:
                first_sub[i].append(len(out))
                out.append(SubPiece(p.clip, at, a, p.group))
            accepted.append((len(out), prim, a, e, ref))
            out.append(SubPiece(p.clip, a, min(e, p.stop), p.group))
            at = e
        if at < end:
            first_sub[i].append(len(out))
            out.append(SubPiece(p.clip, at, p.stop, p.group))
    # Each repeated sub-piece refers to the direct sub-piece of its primary piece that holds
    # its reference frames.
    for idx, prim, a, e, ref in accepted:
        holders = [j for j in first_sub[prim] if out[j].start <= ref.min() and ref.max() <= out[j].stop]
        if holders:
            out[idx].primary, out[idx].ref = holders[0], ref
    return out


# ------------------------------------------------------------------------ per-piece work
# Module-level, one tuple argument each: a runner's workers receive them pickled.
def _direct_set(work: tuple[np.ndarray, float, RmaPcaSettings, bool]) -> bytes:
    """The curve set of a piece coded on its own."""
    coef, budget, s, split = work
    return coefficient_set(coef, budget, s, split=split)


def _repeated_set(work: tuple) -> bytes:
    """Eq. 6: a repeated piece as a reference curve into its primary's curve set (the primary's
    frames, extended by one frame per frame past the interval) and the differences to the
    primary as the runtime reconstructs it at the decoded reference."""
    sp, coef, split, (lo, hi), (plo, phi), primary_set, k, budget, s = work
    x = np.arange(lo, hi + 1, dtype=np.float64)
    ref = np.interp(x, np.arange(sp.start, sp.start + len(sp.ref)), sp.ref - plo)
    ref += np.where(x < sp.start, x - sp.start, 0.0) + np.where(x > sp.start + len(sp.ref) - 1,
                                                                 x - (sp.start + len(sp.ref) - 1), 0.0)
    ref = np.clip(ref, 0.0, phi - plo)
    ref_track = _curve_track(ref, s.ref_frames, s.quant_fraction, s.key_grid, split)
    at = np.clip(track_curve(ref_track), 0.0, phi - plo)
    diff = coef - set_coefficients(primary_set, k, at)
    return coefficient_set(diff, budget, s, first=[ref_track], split=split)


def _root_set(work: tuple[PP.RootTrack, float, RmaPcaSettings, bool, int]) -> bytes:
    """A clip's root curves as one curve set."""
    root, cm, s, split, frames = work
    rc, rb = root_curves(root, cm, s)
    return curve_set([_curve_track(c, bud, s.quant_fraction, s.key_grid, split) for c, bud in zip(rc, rb)], frames)


# ------------------------------------------------------------------------ entry point
def encode(motions: list[Motion], cm_per_unit: list[float], s: RmaPcaSettings, check: CheckFn,
           progress: ProgressFn | None = None, runner: "Runner | None" = None) -> CodecOutput:
    """Encode a library into one ``RMAP`` section (no tolerance promise: see the module). The
    bases span every clip; the per-clip and per-piece work (behaviour cuts, coefficient and
    root curves) runs on ``runner``'s workers (None: here), with the same bytes."""
    from ..bake import SerialRunner

    runner = runner or SerialRunner()
    started = time.perf_counter()
    if len(set(cm_per_unit)) != 1:
        raise ValueError("rma-pca codes one library in one unit: the clips' units differ")
    cm = cm_per_unit[0]
    for m in motions:  # its marker layout is read from BVH channels, which glTF nodes do not have
        moved = m.animated()
        for i in range(m.skeleton.node_count):
            if (moved[i, 0] and not m.skeleton.rotation_order(i)) or (moved[i, 1] and not m.skeleton.position_axes(i)):
                raise UnsupportedMotion(f"codec 'rma-pca' reads BVH channel layouts: clip {m.name!r}, node "
                                        f"{m.skeleton.names[i]!r} moves without channels (a glTF clip); "
                                        "use codec 'rma'")
    try:
        shared = PP.library_layout([m.skeleton for m in motions], cm)
    except ValueError as exc:
        raise ValueError(f"rma-pca needs clips of one skeleton layout ({exc}); encode each skeleton separately") from None
    prepared = [PP.to_markers(m, cm, layout=PP.layout_for(m.skeleton, shared)) for m in motions]
    flats = [p.flat for p in prepared]
    frame_times = {m.frame_time for m in motions}
    blend = s.blend_frames(min(frame_times))
    pieces = pieces_and_groups(flats, s.groups, blend, runner)
    n_groups = max(p.group for p in pieces) + 1
    bases = []
    for g in range(n_groups):
        rows = np.concatenate([flats[p.clip][p.start:p.stop + (p.stop == len(flats[p.clip]) - 1)]
                               for p in pieces if p.group == g])
        bases.append(group_basis(rows, s.variance))
    plan = repetition_plan(pieces, flats, bases, min(frame_times), cm, s, blend)
    budget = s.coef_cm / cm
    # Curves through a capture's jump from frame 0 to 1 (CMU's T-pose) detach that segment.
    jumps = [frame0_jumps(m, cm) for m in motions]
    # Direct sub-pieces first (a repeated one needs its primary's coded curves), then the
    # repeated ones; the sets are laid out per clip afterwards.
    spans: dict[int, tuple[int, int]] = {}
    for idx, sp in enumerate(plan):
        mine = [j for j, q in enumerate(plan) if q.clip == sp.clip]
        pos = mine.index(idx)
        # Curves reach `blend` frames into each neighbour, where the runtime cross-fades.
        spans[idx] = (sp.start - blend if pos else 0, sp.stop + blend if pos + 1 < len(mine) else sp.stop)

    def piece(idx: int) -> tuple[SubPiece, np.ndarray, bool]:
        sp, (lo, hi) = plan[idx], spans[idx]
        return sp, project(bases[sp.group], flats[sp.clip][lo:hi + 1]), bool(jumps[sp.clip] and lo == 0)

    t0 = time.perf_counter()
    direct = [idx for idx, sp in enumerate(plan) if sp.primary < 0]
    sets: dict[int, bytes] = dict(zip(direct, runner.map(_direct_set, [
        (coef, budget, s, split) for _, coef, split in map(piece, direct)])))
    repeated = [idx for idx, sp in enumerate(plan) if sp.primary >= 0]
    sets.update(zip(repeated, runner.map(_repeated_set, [
        (sp, coef, split, spans[idx], spans[sp.primary], sets[sp.primary], bases[sp.group].k, budget, s)
        for idx, (sp, coef, split) in zip(repeated, map(piece, repeated))])))
    # A primary's curve set is shared (in the section's prefix): its own clip and every clip
    # that repeats it read it there. Every other set lies in its clip's payload.
    primaries = sorted({sp.primary for sp in plan if sp.primary >= 0})
    shared_index = {idx: i for i, idx in enumerate(primaries)}
    clip_payloads, stats = [], []
    root_sets = runner.map(_root_set, [(pr.root, cm, s, jumps[ci], m.frame_count)
                                       for ci, (m, pr) in enumerate(zip(motions, prepared))])
    for ci, (m, pr) in enumerate(zip(motions, prepared)):
        own = [root_sets[ci]]
        mine = [j for j, q in enumerate(plan) if q.clip == ci]
        at = CLIP_HEADER + PIECE_RECORD * len(mine) + len(own[0])
        rows = []
        for j in mine:
            sp = plan[j]
            if j in shared_index:
                curves = SHARED_BIT | shared_index[j]
            else:
                curves = at
                own.append(sets[j])
                at += len(sets[j])
            rows.append((sp.start, sp.group, curves, shared_index[sp.primary] if sp.primary >= 0 else NO_PRIMARY))
        clip_payloads.append(clip_payload(m.frame_count, pr.root.full, rows, own))
        repeated = [j for j in mine if plan[j].primary >= 0]
        stats.append({"pieces": len(rows), "groups": sorted({r[1] for r in rows}),
                      "components": [bases[r[1]].k for r in rows], "six_dof_root": pr.root.full,
                      "repeated_pieces": len(repeated),
                      "repeated_frames": int(sum(plan[j].stop - plan[j].start for j in repeated)),
                      "root_curve_bytes": len(own[0])})
        if progress:
            progress(m.name)
    stats[0]["encode_seconds"] = time.perf_counter() - t0
    prefix = section_prefix(len(motions), shared.marker_count, joint_table(shared), bases, blend,
                            [sets[j] for j in primaries])
    for st in stats:
        st["shared_section_bytes"] = len(prefix)
    stats[0]["basis_bytes"] = sum(len(group_record(b)) for b in bases)
    stats[0]["shared_curve_bytes"] = sum(len(sets[j]) for j in primaries)
    stats[0]["analysis_seconds"] = time.perf_counter() - started
    return CodecOutput(payloads=clip_payloads, section_prefix=prefix, stats=stats, promise=False,
                       settings={"pca_variance": s.variance, "groups": n_groups, "blend_frames": blend,
                                 "repeats": s.repeats,
                                 "components": [b.k for b in bases]})
