"""Codec ``fk-wavelet``: seed 000 §4 (FKBC) — per-channel 9/7 wavelet coding of the joint
curves with per-joint quantization steps and forward-kinematics compensation, written as
docs/FORMAT.md's ``FKWV`` payload (version 2), which the runtime samples in place.

Channels: each animated joint's local rotation as a sign-continuous quaternion (4 channels,
normalised at decode), each translated node's local translation (3 channels). The clip is cut
into blocks of B frames; in each block every channel is transformed with the CDF 9/7 wavelet
(the filter pair PyWavelets calls ``bior4.4``) in lifting form with whole-sample symmetric
extension at the block's ends: non-expansive (n coefficients for n frames, any n), and the C
decoder repeats the same float32 lifting steps, so the encoder knows the decoded curves to the
last bit on x86-64. Each block's coefficients are one entropy stream of its own, so the runtime
decodes one block into its scratch for a random access and one block every B frames when
playing (B is chosen so that the scratch stays within ``max_scratch_bytes``).

Coefficients are quantized with ``step = 2^((track_code + band_code) / 4 - 64)``: one code per
track (the paper's hierarchical per-joint step sizes) and one per band (equalising each band's
reconstruction noise). A block's stream holds its bands coarsest first, so a decoder that stops
early in a block has its coarser bands (progressive order, §4; see :func:`progressive_errors`).

Forward-kinematics compensation (§4.3): joints are coded parents first; a joint's rotation
target is re-solved against its parent's *decoded* pose so that it re-aims its children at
their original positions (:class:`mocodec.keyframes.Compensation`, the Wahba fit the key-frame
codecs use too), so a parent's quantization error is not carried down the chain.

The encoder meets a world-space tolerance on every frame of every node as measured by the C
runtime: encode, check, lower the step codes of the tracks that move failing nodes, repeat.
"""
from __future__ import annotations

import struct
import time
from dataclasses import dataclass, field

import numpy as np

from .. import rotations as R
from ..entropy import MAX_ABS, entropy_decode, entropy_encode
from ..keyframes import Compensation
from ..motion import Motion, Skeleton
from ..tolerance import (Attempt, ClipCheck, Tolerance, ToleranceNotMet, ancestors_matrix,
                         effector_nodes, initial_budgets, meet_tolerance)
from . import ClipResult

ROT_REST, ROT_QUATERNION = 0, 2
TRANS_REST, TRANS_CHANNELS = 0, 2
HEADER = 16
MAX_LEVELS = 12
MAX_BLOCK = 4096
MAX_BLOCK_VALUES = 1 << 20
MAX_CODE_SUM = 296
CODE_BIAS = 64  # step = 2^(code_sum / 4 - CODE_BIAS)
BAND_BIAS = 64  # band codes are 64 + round(4 log2(1 / synthesis gain))
MAX_ROI = 30    # ROI gain and per-band max-shift
CLAMP = np.float32(1e7)
SCRATCH_HEADER = 64  # MCD_SCRATCH_HEADER_SIZE: the runtime's part of every scratch buffer

# CDF 9/7 lifting constants, as the float32 values the C decoder uses.
ALPHA = np.float32(-1.5861343)
BETA = np.float32(-0.052980117)
GAMMA = np.float32(0.8829111)
DELTA = np.float32(0.44350687)
SCALE = np.float32(1.2301741)
INV_SCALE = np.float32(0.81289306)
MANTISSA = np.array([1.0, 1.1892071, 1.4142135, 1.6817929], dtype=np.float32)


# ------------------------------------------------------------------------ the transform
def level_length(frames: int, level: int) -> int:
    """Samples of the level-``level`` approximation: ceil(F / 2^level)."""
    return -(-frames // (1 << level))


def max_levels(frames: int, cap: int = MAX_LEVELS) -> int:
    """Most levels, up to ``cap``, such that every level splits a signal of at least two
    samples (the levels of a block of ``frames`` frames when the payload says ``cap``)."""
    levels = 0
    while levels < cap and level_length(frames, levels) >= 2:
        levels += 1
    return levels


def band_rows(frames: int, levels: int) -> list[int]:
    """Rows of each band, coarse to fine: the approximation, then details of level L ... 1."""
    rows = [level_length(frames, levels)]
    for l in range(levels, 0, -1):
        rows.append(level_length(frames, l - 1) - level_length(frames, l))
    return rows


def _mirror_indices(ns: int, nd: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Neighbour indices of the whole-sample symmetric extension: d[k-1], d[k] for each s[k]
    (d[-1] = d[0], d[nd] = d[nd-1]) and s[k+1] for each d[k] (s[ns] = s[ns-1])."""
    k = np.arange(ns)
    dl = np.maximum(k - 1, 0)
    dr = np.minimum(k, nd - 1)
    sn = np.minimum(np.arange(nd) + 1, ns - 1)
    return dl, dr, sn


def forward(x: np.ndarray, levels: int) -> list[np.ndarray]:
    """Analysis of the columns of ``x`` (F, C), float64. Returns the bands coarse to fine."""
    a = np.asarray(x, dtype=np.float64)
    details = []
    k_scale, k_inv = float(SCALE), float(INV_SCALE)
    for _ in range(levels):
        s, d = a[0::2].copy(), a[1::2].copy()
        dl, dr, sn = _mirror_indices(len(s), len(d))
        d += float(ALPHA) * (s[: len(d)] + s[sn])
        s += float(BETA) * (d[dl] + d[dr])
        d += float(GAMMA) * (s[: len(d)] + s[sn])
        s += float(DELTA) * (d[dl] + d[dr])
        s /= k_scale
        d /= k_inv
        details.append(d)
        a = s
    return [a] + details[::-1]


def _inverse_level(s: np.ndarray, d: np.ndarray) -> np.ndarray:
    """The decoder's float32 undoing of one level (same operations as the C runtime)."""
    s = s * SCALE
    d = d * INV_SCALE
    dl, dr, sn = _mirror_indices(len(s), len(d))
    nd = len(d)
    s = s - DELTA * (d[dl] + d[dr])
    d = d - GAMMA * (s[:nd] + s[sn])
    s = s - BETA * (d[dl] + d[dr])
    d = d - ALPHA * (s[:nd] + s[sn])
    out = np.empty((len(s) + nd,) + s.shape[1:], dtype=np.float32)
    out[0::2] = np.clip(s, -CLAMP, CLAMP)
    out[1::2] = np.clip(d, -CLAMP, CLAMP)
    return out


def inverse_f32(bands: list[np.ndarray]) -> np.ndarray:
    """Synthesis from dequantized float32 bands (coarse to fine), exactly as the runtime."""
    a = np.clip(np.asarray(bands[0], dtype=np.float32), -CLAMP, CLAMP)
    for d in bands[1:]:
        a = _inverse_level(a, np.asarray(d, dtype=np.float32))
    return a


def step_value(code_sum: np.ndarray | int) -> np.ndarray:
    """The float32 step of a code sum, as the runtime computes it (ldexpf of a mantissa)."""
    e = np.asarray(code_sum, dtype=np.int64)
    return np.ldexp(MANTISSA[e & 3], (e >> 2) - CODE_BIAS).astype(np.float32)


def dequantize(q: np.ndarray, step: np.ndarray, shift: int, gain: int) -> np.ndarray:
    """The runtime's dequantization: ``q × step``, or for ``|q| >= 2^shift`` (an ROI value,
    when ``shift`` > 0) ``q × step × 2^-(shift + gain)``; float32, clamped to ±1e7."""
    step = np.asarray(step, dtype=np.float32)
    if shift:
        fine = np.ldexp(step, -(shift + gain)).astype(np.float32)
        step = np.where(np.abs(np.asarray(q, dtype=np.int64)) >= (1 << shift), fine, step)
    return np.clip(np.asarray(q).astype(np.float32) * step, -CLAMP, CLAMP)


def synthesis_gains(frames: int, levels: int) -> np.ndarray:
    """L2 norm of one coefficient's synthesis function, per band (measured mid-signal)."""
    rows = band_rows(frames, levels)
    gains = np.empty(len(rows))
    for b, n in enumerate(rows):
        bands = [np.zeros((r, 1), dtype=np.float32) for r in rows]
        bands[b][n // 2, 0] = 1.0
        gains[b] = float(np.linalg.norm(inverse_f32(bands).astype(np.float64)))
    return gains


# ------------------------------------------------------------------------ blocks
@dataclass(frozen=True)
class Group:
    """Consecutive blocks of one length: ``count`` blocks of ``frames`` frames from frame
    ``first``, each with ``levels`` levels."""

    first: int
    count: int
    frames: int
    levels: int

    def columns(self, x: np.ndarray) -> np.ndarray:
        """Frames (count × frames, w) of a signal -> (frames, count × w): one column per block
        and component, so a transform over the columns works on every block at once."""
        w = x.shape[1]
        part = x[self.first: self.first + self.count * self.frames]
        return part.reshape(self.count, self.frames, w).transpose(1, 0, 2).reshape(self.frames, -1)

    def frames_of(self, cols: np.ndarray, w: int) -> np.ndarray:
        """The inverse of :meth:`columns`."""
        return cols.reshape(len(cols), self.count, w).transpose(1, 0, 2).reshape(-1, w)

    def band_keys(self) -> list[tuple[str, int]]:
        """Band b -> the code-table entry it uses: ('a', levels) for the approximation,
        ('d', l) for the details of level l."""
        return [("a", self.levels)] + [("d", l) for l in range(self.levels, 0, -1)]


def block_groups(frames: int, block: int, levels: int) -> list[Group]:
    """The clip's blocks: the full ones, then the shorter last one (when F is not a multiple
    of B) with the levels its length allows."""
    full, tail = divmod(frames, block)
    out = []
    if full:
        out.append(Group(0, full, block, levels))
    if tail:
        out.append(Group(full * block, 1, tail, max_levels(tail, levels)))
    return out


@dataclass
class BandCodes:
    """Step codes of the bands: ``approx[l]`` for the approximation of a block with l
    levels, ``detail[l - 1]`` for the details of level l (per block length B)."""

    approx: np.ndarray
    detail: np.ndarray

    def of(self, key: tuple[str, int]) -> int:
        kind, l = key
        return int(self.approx[l] if kind == "a" else self.detail[l - 1])

    def max(self) -> int:
        return int(max(self.approx.max(), self.detail.max(initial=0)))


def band_codes(block: int, levels: int, tilt: float = 0.0) -> BandCodes:
    """Band codes that give every band of a B-frame block the same reconstruction noise per
    unit step; ``tilt`` (codes per level) makes finer bands coarser."""
    g = synthesis_gains(block, levels)
    detail = np.array([BAND_BIAS + np.rint(-4.0 * np.log2(g[levels + 1 - l]) + tilt * (levels + 1 - l))
                       for l in range(1, levels + 1)])
    approx = np.array([BAND_BIAS + np.rint(-4.0 * np.log2(synthesis_gains(block, l)[0])) for l in range(levels + 1)])
    return BandCodes(np.clip(approx, 0, 255).astype(np.int64), np.clip(detail, 0, 255).astype(np.int64))


def scratch_bytes(block: int, channels: int) -> int:
    """The codec scratch of a clip (docs/FORMAT.md, FKWV "Scratch"): state, row table, a
    block's rows, the edge row and the approximation offsets, each 16-aligned."""
    def align16(n: int) -> int:
        return -(-n // 16) * 16

    return 16 + align16(2 * block) + align16(4 * block * channels) + 2 * align16(4 * channels)


def choose_block(block_frames: int, channels: int, max_scratch: int) -> int:
    """The largest block length up to ``block_frames`` whose whole scratch (the runtime's
    64-byte header plus the codec's part) fits in ``max_scratch`` bytes; 1 at the least.
    (Measured on CMU clips: a longer block beats a shorter one of length 2^k + 1, 29 frames
    against 17, although 33 beats 29.)"""
    b = max(1, min(int(block_frames), MAX_BLOCK))
    while b > 1 and (SCRATCH_HEADER + scratch_bytes(b, channels) > max_scratch or b * channels > MAX_BLOCK_VALUES):
        b -= 1
    return b


# ------------------------------------------------------------------------ tracks
@dataclass
class _Track:
    node: int
    is_rotation: bool
    code: int                       # the track's step code
    values: np.ndarray | None = None  # (F, 4|3) the signal coded last
    # Per block group, per band (rows, count × width): quantized values (background step),
    # ROI values (finer step, 0 elsewhere) and where the ROI values replace the others.
    q: list[list[np.ndarray]] = field(default_factory=list)
    q_roi: list[list[np.ndarray]] = field(default_factory=list)
    roi: list[list[np.ndarray]] = field(default_factory=list)

    @property
    def width(self) -> int:
        return 4 if self.is_rotation else 3


def _quantize(track: _Track, values: np.ndarray, groups: list[Group], codes: BandCodes,
              roi: list[list[np.ndarray]] | None = None, gain: int = 0) -> np.ndarray:
    """Quantize ``values`` (F, w) for ``track``, block by block; returns what the runtime
    decodes (F, w) float32.

    ``roi`` (per group, per band, bool (rows, count)) marks the coefficients of constraint
    frames: they are quantized with the step / 2^gain and later written max-shifted
    (:func:`serialize`)."""
    w = values.shape[1]
    track.values = values
    track.q, track.q_roi, track.roi = [], [], []
    out = []
    for gi, g in enumerate(groups):
        bands = forward(g.columns(values), g.levels)
        q, qr, masks, deq = [], [], [], []
        for b, (coef, key) in enumerate(zip(bands, g.band_keys())):
            step = step_value(track.code + codes.of(key))
            qi = np.rint(coef / float(step))
            mask = np.zeros(coef.shape, dtype=bool)
            qf = np.zeros(coef.shape)
            if roi is not None and gain > 0:
                mask = np.repeat(roi[gi][b], w, axis=1)
                qf = np.where(mask, np.rint(coef * 2.0 ** gain / float(step)), 0.0)
                mask &= qf != 0  # an ROI zero is a background zero
            for arr in (qi, qf):
                if arr.size and np.abs(arr).max() > MAX_ABS:
                    raise ToleranceNotMet(f"node {track.node}: step too small for the entropy coder")
            q.append(qi.astype(np.int64))
            qr.append(qf.astype(np.int64))
            masks.append(mask)
            fine = np.ldexp(step, -gain).astype(np.float32)
            deq.append(np.clip(np.where(mask, qf.astype(np.float32) * fine, qi.astype(np.float32) * step),
                               -CLAMP, CLAMP))
        track.q.append(q)
        track.q_roi.append(qr)
        track.roi.append(masks)
        out.append(g.frames_of(inverse_f32(deq), w))
    return np.concatenate(out)


def _normalize_f32(q: np.ndarray) -> np.ndarray:
    """The runtime's quaternion normalisation in float32 (identity for a zero vector)."""
    q = q.astype(np.float32)
    n2 = np.float32(0.0) + q[:, 0] * q[:, 0]
    n2 = n2 + q[:, 1] * q[:, 1]
    n2 = n2 + q[:, 2] * q[:, 2]
    n2 = n2 + q[:, 3] * q[:, 3]
    ok = n2 > np.float32(1e-30)
    inv = np.float32(1.0) / np.sqrt(np.where(ok, n2, np.float32(1.0)))
    out = q * inv[:, None]
    out[~ok] = np.array([0, 0, 0, 1], dtype=np.float32)
    return out


# ------------------------------------------------------------------------ payload
def roi_shifts(groups: list[Group], levels: int, tracks: list[_Track]) -> BandCodes:
    """Max-shift per code-table entry: the bit length of the largest background value of the
    bands that use it (so every background value is below 2^shift), 0 where no band has ROI
    values."""
    shifts = BandCodes(np.zeros(levels + 1, dtype=np.int64), np.zeros(levels, dtype=np.int64))
    top: dict[tuple[str, int], int] = {}
    used: set[tuple[str, int]] = set()
    for gi, g in enumerate(groups):
        for b, key in enumerate(g.band_keys()):
            for t in tracks:
                background = np.where(t.roi[gi][b], 0, t.q[gi][b])
                top[key] = max(top.get(key, 0), int(np.abs(background).max(initial=0)))
                if t.roi[gi][b].any():
                    used.add(key)
    for kind, l in used:
        table = shifts.approx if kind == "a" else shifts.detail
        table[l if kind == "a" else l - 1] = max(1, top[(kind, l)].bit_length())
    if max(shifts.max(), 0) > MAX_ROI:
        raise ToleranceNotMet("ROI shift past the format's bound")
    return shifts


def _coded(t: _Track, gi: int, b: int, shift: int) -> np.ndarray:
    """Band b of group gi of a track as written: background values, ROI values scaled up by
    2^shift."""
    if not t.roi[gi][b].any():
        return t.q[gi][b]
    out = np.where(t.roi[gi][b], t.q_roi[gi][b] << shift, t.q[gi][b])
    if np.abs(out).max() > MAX_ABS:
        raise ToleranceNotMet(f"node {t.node}: max-shifted ROI values exceed the entropy coder's range")
    return out


def serialize(skeleton: Skeleton, frames: int, block: int, levels: int, codes: BandCodes,
              tracks: dict[tuple[int, bool], _Track], gain: int = 0) -> bytes:
    """The ``FKWV`` version 2 payload (docs/FORMAT.md)."""
    n = skeleton.node_count
    groups = block_groups(frames, block, levels)
    ordered: list[_Track] = []
    nodes = []
    for i in range(n):
        rot, tr = tracks.get((i, True)), tracks.get((i, False))
        nodes.append(struct.pack("<BBBB", ROT_QUATERNION if rot else ROT_REST,
                                 TRANS_CHANNELS if tr else TRANS_REST,
                                 rot.code if rot else 0, tr.code if tr else 0))
        ordered += [t for t in (rot, tr) if t is not None]
    channels = sum(t.width for t in ordered)
    if gain:
        shifts = roi_shifts(groups, levels, ordered)
    else:
        shifts = BandCodes(np.zeros(levels + 1, dtype=np.int64), np.zeros(levels, dtype=np.int64))
    # Per group, per band (rows, count, C): every track's columns side by side in channel order.
    coded = [[np.concatenate([_coded(t, gi, b, int(shifts.of(key))).reshape(-1, g.count, t.width)
                              for t in ordered], axis=2) if channels else np.zeros((0, g.count, 0), dtype=np.int64)
              for b, key in enumerate(g.band_keys())] for gi, g in enumerate(groups)]
    offsets = approx_offsets(groups, levels, coded, channels)
    streams = [entropy_encode(offsets, 1) if channels else b""]
    for gi, g in enumerate(groups):
        if not channels:
            streams += [b""] * g.count
            continue
        bands = list(coded[gi])
        if g.levels == levels:
            bands[0] = bands[0] - offsets
        values = np.concatenate(bands, axis=0)  # (frames, count, C): block j's values in band order
        if np.abs(values).max(initial=0) > MAX_ABS:
            raise ToleranceNotMet("approximation offsets exceed the entropy coder's range")
        for j in range(g.count):
            streams.append(entropy_encode(values[:, j].reshape(-1), 1))
    tables = bytes(int(c) for c in list(codes.approx) + list(codes.detail)
                   + list(shifts.approx) + list(shifts.detail))
    tables += bytes((-len(tables)) % 4)
    ends = np.cumsum([len(s) for s in streams]).astype(np.int64)
    body = b"".join([
        struct.pack("<IIIHBB", frames, n, channels, block, levels, gain),
        b"".join(nodes),
        tables,
        struct.pack(f"<{len(ends)}I", *[int(e) for e in ends]),
        b"".join(streams),
    ])
    return body + bytes((-len(body)) % 4)


def approx_offsets(groups: list[Group], levels: int, coded: list[list[np.ndarray]], channels: int) -> np.ndarray:
    """Per channel, the integer the runtime adds to the approximation band of every block with
    ``levels`` levels: the median of those values, so that what is coded is their deviation
    from the clip's typical pose (a block's approximation is otherwise its channels' mean,
    coded from scratch in every block)."""
    full = [coded[gi][0].reshape(-1, channels) for gi, g in enumerate(groups) if g.levels == levels]
    if not full or not channels:
        return np.zeros(channels, dtype=np.int64)
    return np.rint(np.median(np.concatenate(full), axis=0)).astype(np.int64)


@dataclass
class ParsedPayload:
    frames: int
    nodes: int
    channels: int
    block: int
    levels: int
    roi_gain: int
    node_table: np.ndarray      # (N, 4) uint8
    codes: BandCodes
    shifts: BandCodes
    ends: np.ndarray            # (K + 1,) end of each stream (offsets, then blocks) within the streams
    streams_offset: int         # where the first stream starts
    tables_offset: int          # where the code tables start

    @property
    def groups(self) -> list[Group]:
        return block_groups(self.frames, self.block, self.levels)

    def stream(self, payload: bytes, k: int) -> bytes:
        """Block k's stream."""
        return self._stream(payload, k + 1)

    def offsets(self, payload: bytes) -> np.ndarray:
        """The approximation offset of every channel (C,)."""
        return entropy_decode(self._stream(payload, 0), self.channels, 1).astype(np.int64)

    def _stream(self, payload: bytes, i: int) -> bytes:
        start = int(self.ends[i - 1]) if i else 0
        return payload[self.streams_offset + start: self.streams_offset + int(self.ends[i])]


def parse(payload: bytes) -> ParsedPayload:
    """The header and tables of a payload (no checks: the runtime validates)."""
    frames, nodes, channels, block, levels, gain = struct.unpack_from("<IIIHBB", payload, 0)
    nt = np.frombuffer(payload, dtype=np.uint8, count=4 * nodes, offset=HEADER).reshape(nodes, 4)
    off = HEADER + 4 * nodes
    t = np.frombuffer(payload, dtype=np.uint8, count=4 * levels + 2, offset=off).astype(np.int64)
    L = levels
    codes = BandCodes(t[:L + 1].copy(), t[L + 1:2 * L + 1].copy())
    shifts = BandCodes(t[2 * L + 1:3 * L + 2].copy(), t[3 * L + 2:4 * L + 2].copy())
    tables = off
    off += -(-(4 * levels + 2) // 4) * 4
    blocks = -(-frames // block)
    ends = np.frombuffer(payload, dtype="<u4", count=blocks + 1, offset=off).astype(np.int64)
    off += 4 * (blocks + 1)
    return ParsedPayload(frames, nodes, channels, block, levels, gain, nt.copy(), codes, shifts, ends, off, tables)


def _track_codes(p: ParsedPayload) -> np.ndarray:
    """The step code of every channel (C,), in channel order."""
    codes: list[int] = []
    for i in range(p.nodes):
        if p.node_table[i, 0] == ROT_QUATERNION:
            codes += [int(p.node_table[i, 2])] * 4
        if p.node_table[i, 1] == TRANS_CHANNELS:
            codes += [int(p.node_table[i, 3])] * 3
    return np.asarray(codes, dtype=np.int64)


def decode_channels(payload: bytes, bands: int | None = None) -> tuple[ParsedPayload, np.ndarray]:
    """Every channel on every frame (F, C) float32, as the runtime reconstructs a block in its
    scratch. ``bands`` < L + 1 keeps only the first bands of each block (its coarser ones;
    the finer are taken as zero): what a decoder that stops early in every block's stream
    gets (progressive decoding, :func:`progressive_errors`)."""
    p = parse(payload)
    track_codes = _track_codes(p)
    out = np.zeros((p.frames, p.channels), dtype=np.float32)
    if not p.channels:
        return p, out
    offsets = p.offsets(payload)
    k = 0
    for g in p.groups:
        ints = np.stack([entropy_decode(p.stream(payload, k + j), g.frames * p.channels, 1)
                         .reshape(g.frames, p.channels) for j in range(g.count)], axis=1).astype(np.int64)
        k += g.count
        if g.levels == p.levels:
            ints[:band_rows(g.frames, g.levels)[0]] += offsets
        deq, r0 = [], 0
        for b, (rows, key) in enumerate(zip(band_rows(g.frames, g.levels), g.band_keys())):
            q = ints[r0:r0 + rows]
            r0 += rows
            v = dequantize(q, step_value(track_codes + p.codes.of(key)), p.shifts.of(key), p.roi_gain)
            if bands is not None and b >= bands:
                v = np.zeros_like(v)
            deq.append(v.reshape(rows, -1))
        out[g.first: g.first + g.count * g.frames] = g.frames_of(inverse_f32(deq), p.channels)
    return p, out


def decode_payload(payload: bytes, skeleton: Skeleton, x: np.ndarray | None = None,
                   bands: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Reference decoder: local rotations (K, N, 4) and translations (K, N, 3) at frame
    positions ``x`` (default: every frame), computed in float32 as the runtime does
    (channels interpolated linearly between frames, quaternions normalised; nodes without
    channels at the skeleton's rest pose)."""
    p, ch = decode_channels(payload, bands)
    x = np.arange(p.frames, dtype=np.float32) if x is None else np.asarray(x, dtype=np.float32)
    i0 = np.minimum(x.astype(np.int64), p.frames - 1)
    t = (x - i0.astype(np.float32))
    i1 = np.where(t > 0, np.minimum(i0 + 1, p.frames - 1), i0)
    a, b = ch[i0], ch[i1]
    v = np.where((i1 == i0)[:, None], a, a + (b - a) * t[:, None])
    n = len(x)
    rot = np.broadcast_to(skeleton.rest_rotations.astype(np.float32).astype(np.float64), (n, p.nodes, 4)).copy()
    trans = np.broadcast_to(np.asarray(skeleton.offsets, dtype=np.float32).astype(np.float64),
                            (n, p.nodes, 3)).copy()
    c = 0
    for i in range(p.nodes):
        if p.node_table[i, 0] == ROT_QUATERNION:
            rot[:, i] = _normalize_f32(v[:, c:c + 4])
            c += 4
        if p.node_table[i, 1] == TRANS_CHANNELS:
            trans[:, i] = v[:, c:c + 3]
            c += 3
    return rot, trans


def prefix_bytes(payload: bytes, bands: int) -> int:
    """Bytes a decoder reads to use the first ``bands`` bands of every block: the header and
    tables, and of each block's stream the bytes the range decoder has read once those bands'
    values are decoded. That is the length of the stream of those values alone (docs/FORMAT.md,
    entropy coder: a decoder has read 4 bytes plus one per encoder ``shift_low``, and a stream
    is 4 bytes longer than its ``shift_low`` count), found by coding them again."""
    p = parse(payload)
    total = p.streams_offset + int(p.ends[0])  # and the offsets stream
    k = 0
    for g in p.groups:
        keep = sum(band_rows(g.frames, g.levels)[:bands]) * p.channels
        for _ in range(g.count):
            stream = p.stream(payload, k)
            if keep >= g.frames * p.channels or not p.channels:
                total += len(stream)
            else:
                values = entropy_decode(stream, g.frames * p.channels, 1)
                total += len(entropy_encode(values[:keep], 1))
            k += 1
    return total


def progressive_errors(payload: bytes, motion: Motion, cm_per_unit: float) -> list[dict[str, float]]:
    """Error against ``motion`` when every block keeps only its first k bands (k = 1 ... L + 1,
    the finer bands taken as zero): the bytes read (:func:`prefix_bytes`) and the max / p99 /
    mean world position error (cm) over every frame and node, decoded with
    :func:`decode_payload`."""
    from ..kinematics import forward_kinematics

    sk = motion.skeleton
    _, pos_o = forward_kinematics(sk, motion.rotations, motion.translations)
    p = parse(payload)
    out = []
    for k in range(1, p.levels + 2):
        rot, trans = decode_payload(payload, sk, bands=k)
        _, pos = forward_kinematics(sk, rot, trans)
        err = np.linalg.norm(pos - pos_o, axis=-1) * cm_per_unit
        out.append({"bands": k, "bytes": prefix_bytes(payload, k), "max_cm": float(err.max()),
                    "p99_cm": float(np.percentile(err, 99)), "mean_cm": float(err.mean())})
    return out


# ------------------------------------------------------------------------ encoder
@dataclass
class FkWaveletSettings:
    """Settings of the ``fk-wavelet`` codec.

    Parameters
    ----------
    tolerance : Tolerance
        Max world-space position error per node, every frame (cm).
    block_frames : int, default 65
        Frames per block (each an independent wavelet signal and entropy stream; the runtime
        decodes one block per random access and one every B frames when playing), shortened
        while the scratch would exceed ``max_scratch_bytes``. A length 2^k + 1 stays odd at
        every level, so the symmetric extension of each level's approximation matches the one
        the next level applies; even lengths measured 10-15 % larger (docs/CODECS.md).
    max_scratch_bytes : int, default 32768
        The most a playing instance's scratch may take for this clip (the runtime's 64-byte
        header included, without contacts).
    max_levels : int, default 8
        Decomposition levels of a block (fewer when the block is too short).
    budget_scale : float, default 6.0
        Scale on the per-track error budgets of ``tolerance.initial_budgets`` (errors along a
        chain rarely add up worst-case).
    band_tilt : float, default -0.5
        Step codes added per band from coarse to fine (0: equal noise per band).
    compensate : bool, default True
        Forward-kinematics compensation (§4.3); False codes the original local rotations.
    max_repairs : int, default 40
        Rounds of check-through-the-runtime and step refinement before giving up.
    shell_cm : float, default 3.0
        Virtual vertices this far from a joint fix its twist in the compensation fit.
    coarsen, coarsen_tries, coarsen_repairs : int, default 2, 6, 4
        Once the clip passes, every track's step code is raised by ``coarsen`` (a factor
        2^(coarsen/4)) up to ``coarsen_tries`` times, each try refined at most
        ``coarsen_repairs`` rounds; the smallest passing payload is kept.
    relax_tries, relax_below : int, float, default 4, 0.8
        Then, up to ``relax_tries`` times, the tracks whose points all stay under
        ``relax_below`` of their tolerance get coarser steps; kept when smaller and passing.
    roi_frames : tuple of (first, last) frame ranges, default ()
        Constraint frames (§4.2): region-of-interest coding by the max-shift method. The
        detail coefficients whose synthesis reaches these frames, on the tracks of the
        constraint nodes and their ancestors, are quantized 2^gain times finer and written
        scaled up past every other value of their band, so the decoder tells them apart by
        magnitude alone; the coarsest band is made 2^gain times finer as a whole.
    roi_nodes : tuple of str, default ()
        Constraint joints (default: the end effectors, ``tolerance.effector_nodes``).
    roi_tolerance_cm : float or None
        The tolerance held on constraint frames at constraint joints (default: the clip's).
    roi_gain, roi_max_gain : int, default 1, 14
        First ROI gain (octaves) and the most the refinement may raise it to.
    """

    tolerance: Tolerance
    block_frames: int = 65
    max_scratch_bytes: int = 32768
    max_levels: int = 8
    budget_scale: float = 6.0
    band_tilt: float = -0.5
    compensate: bool = True
    max_repairs: int = 40
    shell_cm: float = 3.0
    coarsen: int = 2
    coarsen_tries: int = 6
    coarsen_repairs: int = 4
    relax_tries: int = 4
    relax_below: float = 0.8
    roi_frames: tuple = ()
    roi_nodes: tuple = ()
    roi_tolerance_cm: float | None = None
    roi_gain: int = 1
    roi_max_gain: int = 14


class _Encoder:
    def __init__(self, motion: Motion, cm_per_unit: float, settings: FkWaveletSettings) -> None:
        self.motion = motion
        self.settings = settings
        self.frames = motion.frame_count
        sk = motion.skeleton
        self.compensation = Compensation(motion, cm_per_unit, settings.shell_cm)
        self.tol_units = settings.tolerance.per_node_cm(sk) / cm_per_unit
        channels = sum(4 if rot else 3 for i, rot in self._coded_tracks())
        self.block = choose_block(settings.block_frames, channels, settings.max_scratch_bytes)
        self.levels = max_levels(self.block, min(settings.max_levels, MAX_LEVELS))
        self.groups = block_groups(self.frames, self.block, self.levels)
        self.bcodes = band_codes(self.block, self.levels, settings.band_tilt)
        budgets = initial_budgets(self.compensation.reach, self.tol_units, settings.budget_scale)
        self._setup_roi(cm_per_unit)
        self.tracks: dict[tuple[int, bool], _Track] = {}
        self.rows: dict[tuple[int, bool], int] = {}
        coded = set(self._coded_tracks())
        for k, (i, rot) in enumerate(zip(self.compensation.track_nodes, self.compensation.track_is_rot)):
            if (i, rot) not in coded:
                continue
            step = (0.5 if rot else 1.0) * budgets[k]
            code = int(np.clip(np.floor(4.0 * (np.log2(max(step, 1e-30)) + CODE_BIAS)) - BAND_BIAS, 0, 255))
            self.tracks[(i, rot)] = _Track(i, rot, code)
            self.rows[(i, rot)] = k

    def _coded_tracks(self) -> list[tuple[int, bool]]:
        """The tracks that get channels: every one of the compensation's, except a rotation
        that stays at its rest rotation on every frame (rotation mode 0 gives it)."""
        sk, out = self.motion.skeleton, []
        for i, rot in zip(self.compensation.track_nodes, self.compensation.track_is_rot):
            if rot and np.all(self.motion.rotations[:, i] == sk.rest_rotations[i]):
                continue
            out.append((i, rot))
        return out

    def _setup_roi(self, cm_per_unit: float) -> None:
        """Constraint cells (frame, node), their tolerance, the ROI tracks and band masks."""
        s, sk, f = self.settings, self.motion.skeleton, self.frames
        self.tol_fn = np.broadcast_to(self.tol_units, (f, sk.node_count)).copy()
        self.roi_cells = np.zeros((f, sk.node_count), dtype=bool)
        self.gain, self.roi_bands, self.roi_nodes_of = 0, None, np.zeros(sk.node_count, dtype=bool)
        if not s.roi_frames:
            return
        frames = np.zeros(f, dtype=bool)
        for first, last in s.roi_frames:
            frames[max(0, int(first)): min(f, int(last) + 1)] = True
        nodes = ([sk.index(n) for n in s.roi_nodes] if s.roi_nodes
                 else list(np.flatnonzero(effector_nodes(sk))))
        self.roi_cells[np.ix_(frames, nodes)] = True
        if s.roi_tolerance_cm is not None:
            self.tol_fn[self.roi_cells] = np.minimum(self.tol_fn[self.roi_cells], s.roi_tolerance_cm / cm_per_unit)
        self.roi_nodes_of = ancestors_matrix(sk)[:, nodes].any(axis=1)  # tracks of these nodes
        self.gain = int(s.roi_gain)
        self.roi_bands = [roi_band_masks(g.frames, g.levels, g.columns(frames[:, None])) for g in self.groups]

    def _band_codes(self) -> BandCodes:
        """Band codes in use: with ROI every block's approximation is 2^gain times finer as a
        whole."""
        approx = self.bcodes.approx.copy()
        if self.gain:
            approx = np.maximum(0, approx - 4 * self.gain)
        return BandCodes(approx, self.bcodes.detail.copy())

    def _clamp_codes(self) -> None:
        top = MAX_CODE_SUM - int(self.bcodes.max())
        for t in self.tracks.values():
            t.code = int(np.clip(t.code, 0, top))

    def code_pass(self) -> bytes:
        """Quantize every track parents first (each rotation re-solved against the decoded
        parent when compensating) and return the payload."""
        self._clamp_codes()
        bcodes = self._band_codes()
        sk = self.motion.skeleton
        n = sk.node_count
        rot_d = np.empty((self.frames, n, 4))
        pos_d = np.empty((self.frames, n, 3))
        for i in range(n):
            p = sk.parents[i]
            t = self.tracks.get((i, False))
            if t is not None:
                local_t = _quantize(t, self.motion.translations[:, i], self.groups, bcodes,
                                    *self._roi_for(i)).astype(np.float64)
            else:
                local_t = np.broadcast_to(np.asarray(sk.offsets[i], dtype=np.float32).astype(np.float64), (self.frames, 3))
            pos_d[:, i] = local_t if p < 0 else pos_d[:, p] + R.quat_rotate(rot_d[:, p], local_t)
            t = self.tracks.get((i, True))
            if t is not None:
                if self.settings.compensate:
                    target = self.compensation.rotation_target(i, rot_d[:, p] if p >= 0 else None, pos_d[:, i])
                else:
                    target = self.motion.rotations[:, i]
                target = R.quat_make_continuous(target)
                local_q = _normalize_f32(_quantize(t, target, self.groups, bcodes,
                                                   *self._roi_for(i))).astype(np.float64)
            else:
                rest = np.asarray(sk.rest_rotations[i], dtype=np.float32).astype(np.float64)
                local_q = np.broadcast_to(rest, (self.frames, 4))
            rot_d[:, i] = local_q if p < 0 else R.quat_multiply(rot_d[:, p], local_q)
        return serialize(sk, self.frames, self.block, self.levels, bcodes, self.tracks, self.gain)

    def _roi_for(self, node: int) -> tuple[list[np.ndarray] | None, int]:
        if self.roi_bands is None or not self.roi_nodes_of[node]:
            return None, 0
        return self.roi_bands, self.gain

    def refine(self, errors: np.ndarray) -> bool:
        """Where the check fails: raise the ROI gain for failing constraint cells (until its
        cap); lower the step codes of tracks that move other failing nodes — by the code
        distance of the worst ratio on the failing nodes the track moves most, else by one."""
        over = errors > self.tol_fn
        if not over.any():
            return False
        background = over
        if self.gain and (over & self.roi_cells).any():
            if self.gain < min(self.settings.roi_max_gain, MAX_ROI):
                self.gain += 1
                background = over & ~self.roi_cells
        ratio = np.max(np.where(background, errors / self.tol_fn, 0.0), axis=0)  # (N,)
        failing = ratio > 1.0
        reach = self.compensation.reach
        for key, t in self.tracks.items():
            k = self.rows[key]
            hit = failing & reach.affects[k]
            if not hit.any():
                continue
            # The points this track moves most (largest lever) carry its error best.
            lever = np.where(hit, reach.lever[k], 0.0)
            worst = float(np.max(np.where(lever >= 0.5 * lever.max(), ratio, 0.0)))
            drop = int(np.clip(np.ceil(4.0 * np.log2(max(worst, 1.0 + 1e-9))), 1, 8))
            t.code -= drop
        return True


    def relax(self, errors: np.ndarray, below: float) -> bool:
        """Raise the step codes of tracks whose points all keep headroom: the worst ratio of
        error to tolerance over the points a track moves most under ``below``. Returns
        whether any code changed."""
        ratio = np.max(errors / self.tol_fn, axis=0)  # (N,)
        reach = self.compensation.reach
        changed = False
        for key, t in self.tracks.items():
            k = self.rows[key]
            hit = reach.affects[k]
            if not hit.any():
                continue
            lever = np.where(hit, reach.lever[k], 0.0)
            worst = float(np.max(np.where(lever >= 0.5 * lever.max(), ratio, 0.0)))
            if worst < below:
                t.code += int(np.clip(np.floor(4.0 * np.log2(below / max(worst, 1e-9))), 1, 4))
                changed = True
        return changed


def roi_band_masks(frames: int, levels: int, roi_frames: np.ndarray) -> list[np.ndarray]:
    """Per band, the coefficients whose synthesis reaches a constraint frame, for blocks of
    ``frames`` frames with ``levels`` levels; ``roi_frames`` (frames, count) marks the
    constraint frames of each block, and each band's mask is (rows, count). A level-l
    coefficient sits at frame k 2^l (approximation) or (2k + 1) 2^(l-1) (detail) and its
    synthesis spans less than 4 · 2^l frames either side (7- and 9-tap filters at every
    level). The approximation is never marked (it is made finer as a whole)."""
    marks = np.asarray(roi_frames, dtype=np.int64)
    hits = np.concatenate((np.zeros((1, marks.shape[1]), dtype=np.int64), np.cumsum(marks, axis=0)))
    rows = band_rows(frames, levels)
    out = [np.zeros((rows[0], marks.shape[1]), dtype=bool)]
    for b in range(1, levels + 1):
        l = levels + 1 - b
        centre = (2 * np.arange(rows[b]) + 1) << (l - 1)
        r = 4 << l
        lo = np.clip(centre - r, 0, frames)
        hi = np.clip(centre + r + 1, 0, frames)
        out.append(hits[hi] - hits[lo] > 0)
    return out


def _meet(enc: _Encoder, check: ClipCheck, rounds: int) -> Attempt:
    """Code, check through the runtime and refine until every node is within tolerance, at
    most ``rounds`` refinements (:func:`mocodec.tolerance.meet_tolerance`)."""
    return meet_tolerance(enc.code_pass, check, enc.tol_fn, enc.refine, rounds)


def encode_clip(motion: Motion, cm_per_unit: float, settings: FkWaveletSettings,
                check: ClipCheck) -> ClipResult:
    """Encode one clip so that every node's error measured by ``check`` (through the C
    runtime) is within the tolerance on every frame (stats: levels, tracks, repairs).

    From the initial per-track steps the encoder refines until the clip passes, then tries
    coarser steps for every track at once (``settings.coarsen`` codes, one quarter octave each,
    per try), refining each try, and keeps the smallest payload that passes."""
    started = time.perf_counter()
    enc = _Encoder(motion, cm_per_unit, settings)
    found = _meet(enc, check, settings.max_repairs)
    if not found.met:
        raise ToleranceNotMet(f"{motion.name}: still {found.worst(enc.tol_fn):.3f}x over the tolerance after "
                              f"{settings.max_repairs} refinements")
    best, best_errors, repairs = found.payload, found.errors_units, found.adjustments
    best_codes = {k: t.code for k, t in enc.tracks.items()}
    for _ in range(settings.coarsen_tries):
        for k, t in enc.tracks.items():
            t.code = best_codes[k] + settings.coarsen
        found = _meet(enc, check, settings.coarsen_repairs)
        if not found.met or len(found.payload) >= len(best):
            break
        best, best_errors = found.payload, found.errors_units
        repairs += found.adjustments + 1
        best_codes = {k: t.code for k, t in enc.tracks.items()}
    # Then track by track: coarser steps where a track's points keep headroom.
    for _ in range(settings.relax_tries):
        for k, t in enc.tracks.items():
            t.code = best_codes[k]
        if not enc.relax(best_errors, settings.relax_below):
            break
        found = _meet(enc, check, settings.coarsen_repairs)
        if not found.met or len(found.payload) >= len(best):
            break
        best, best_errors = found.payload, found.errors_units
        repairs += found.adjustments + 1
        best_codes = {k: t.code for k, t in enc.tracks.items()}
    return ClipResult(best, best_errors, {"block": enc.block, "levels": enc.levels, "tracks": len(enc.tracks), "repairs": repairs},
                      time.perf_counter() - started)
