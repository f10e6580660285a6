"""The ``RMAL`` version 2 payload (docs/FORMAT.md): what the runtime samples in place.

A track's keys come in groups of ``2**group_shift``. A fixed-size group entry holds the bit
offset of the group's data, its first key's frame, the widths of its fields and, per component,
the group's smallest value; the data holds the gaps between the group's keys (a patched
frame-of-reference code: a gap too wide for the group's width escapes, its frame follows whole),
then each key's value above the group's smallest at the group's widths, so any key's value is
one read. A seek table names the group of every ``2**seek_shift``-th frame.
"""
from __future__ import annotations

import struct
from dataclasses import dataclass

import numpy as np

from ..bitpack import fields_bytes

PAYLOAD_HEADER = 32
GAP_WIDTH_BITS = 4
VALUE_WIDTH_BITS = 5
MAX_GAP_WIDTH = 15
MAX_VALUE_WIDTH = 30
MAX_Q = 1 << 30
KIND_MRP, KIND_TWIST, KIND_TRANSLATION, KIND_SCALE = 1, 2, 3, 4
DIMS = {KIND_MRP: 3, KIND_TWIST: 4, KIND_TRANSLATION: 3, KIND_SCALE: 3}
DESC_SIZE = {KIND_MRP: 28, KIND_TWIST: 40, KIND_TRANSLATION: 20, KIND_SCALE: 20}
GROUP_SHIFTS = (4, 5)  # the group sizes the writer tries per track (16 and 32 keys), smallest bytes wins


@dataclass
class CurveTrack:
    """One animated track as the payload stores it.

    Parameters
    ----------
    kind : 1 MRP rotation, 2 twist + MRP rotation, 3 translation, 4 scale.
    frames : (K,) strictly increasing key frames, ``frames[0] == 0`` and, when K > 1,
        ``frames[-1] == frame_count - 1``.
    q : (K, d) lattice integers, ``|q| < 2**30``; component c of a key is ``q * step[c]``.
    step : step of the MRP / translation / scale components (binary32-exact).
    angle_step : a twist's angle step (kind 2).
    ref_codes, axis_codes : int16 reference MRPs (rotations) and twist axis (kind 2).
    split : the first segment is detached (frame 0 jumps into frame 1, as CMU's T-pose does):
        it is the straight line from key 0 to key 1, and key 0 is no neighbour of key 1.
    """

    kind: int
    frames: np.ndarray
    q: np.ndarray
    step: float
    angle_step: float = 0.0
    ref_codes: np.ndarray | None = None
    axis_codes: np.ndarray | None = None
    split: bool = False


def signed_bits(a: np.ndarray) -> np.ndarray:
    """Two's complement width holding every value of ``a`` along axis 0 (at least 1)."""
    a = np.asarray(a, dtype=np.int64)
    hi = np.maximum(a.max(axis=0), 0)
    lo = np.maximum(-a.min(axis=0) - 1, 0)
    return 1 + np.maximum(_bit_length(hi), _bit_length(lo))


def _bit_length(x: np.ndarray) -> np.ndarray:
    x = np.asarray(x, dtype=np.int64)
    out = np.zeros(x.shape, dtype=np.int64)
    nz = x > 0
    out[nz] = np.floor(np.log2(x[nz].astype(np.float64))).astype(np.int64) + 1
    # log2 rounding near powers of two: fix up exactly.
    too_small = nz & ((np.int64(1) << np.maximum(out, 0)) <= x)
    out[too_small] += 1
    too_big = nz & ((np.int64(1) << np.maximum(out - 1, 0)) > x)
    out[too_big] -= 1
    return out


def bits_for(n: int) -> int:
    """Bits that hold every value 0 ... n (at least 1), as the runtime computes them."""
    return max(1, int(n).bit_length())


def _gap_widths(gaps: np.ndarray, grp: np.ndarray, groups: int, outlier_bits: int) -> np.ndarray:
    """Per group the gap field width (0 ... 15) with the fewest bits: gaps at the width, the
    ones that need its all-ones code or more escaped (their frames whole, ``outlier_bits``)."""
    need = np.where(gaps == 0, 0, _bit_length(gaps + 1))
    counts = np.bincount(grp, minlength=groups)
    hist = np.zeros((groups, 34), dtype=np.int64)
    np.add.at(hist, (grp, np.minimum(need, 33)), 1)
    over = counts[:, None] - np.cumsum(hist, axis=1)  # over[:, w]: gaps needing more than w bits
    w = np.arange(MAX_GAP_WIDTH + 1)
    cost = counts[:, None] * w[None, :] + over[:, : MAX_GAP_WIDTH + 1] * outlier_bits
    cost[:, 0] = np.where(over[:, 0] == 0, 0, np.iinfo(np.int64).max // 4)  # width 0: no escapes
    return np.argmin(cost, axis=1)


def _track_bytes(t: CurveTrack, frame_count: int, group_shifts: tuple[int, ...]) -> tuple[bytes, bytes]:
    """(descriptor, data) of one track: of the group sizes ``2**group_shifts`` the smallest."""
    options = [_track_bytes_at(t, frame_count, g) for g in group_shifts]
    return min(options, key=lambda o: len(o[0]) + len(o[1]))


def _track_bytes_at(t: CurveTrack, frame_count: int, group_shift: int) -> tuple[bytes, bytes]:
    """(descriptor, data) of one track in groups of ``2**group_shift`` keys."""
    q = np.asarray(t.q, dtype=np.int64)
    frames = np.asarray(t.frames, dtype=np.int64)
    K, d = q.shape
    if d != DIMS[t.kind] or len(frames) != K:
        raise ValueError("track shape does not match its kind")
    if np.any(np.abs(q) >= MAX_Q):
        raise ValueError("a key value needs 2**30 steps or more")
    if frames[0] != 0 or (K > 1 and frames[-1] != frame_count - 1) or np.any(np.diff(frames) <= 0):
        raise ValueError("key frames must increase from 0 to the last frame")
    if K == 1 and frame_count != 1:
        raise ValueError("a track of a clip of several frames has at least two keys")
    G = 1 << group_shift
    groups = (K - 1) // G + 1
    frame_bits = bits_for(frame_count - 1)
    one = np.int64(1)
    grp = np.arange(K) >> group_shift
    pos = np.arange(K) & (G - 1)
    first = np.arange(groups) * G
    # Values: per group and component the smallest, and the width of the rest above it.
    lo = np.minimum.reduceat(q, first, axis=0)
    hi = np.maximum.reduceat(q, first, axis=0)
    widths = _bit_length(hi - lo)
    if np.any(widths > MAX_VALUE_WIDTH):
        raise ValueError("a group's values span 2**30 steps or more")
    abits = np.maximum(signed_bits(lo), 1)
    # Gaps of every key but the groups' first: frames since the key before, less one.
    gaps = np.concatenate(([0], np.diff(frames) - 1))
    body = pos > 0
    gap_w = _gap_widths(gaps[body], grp[body], groups, frame_bits)
    w_gap = gap_w[grp[body]]
    escaped = (w_gap > 0) & (gaps[body] >= (one << w_gap) - 1)
    gap_fields = np.where(escaped, (one << w_gap) - 1, gaps[body])
    value_fields = q - lo[grp]
    # Per group: gap fields, value fields (key-major), escaped frames.
    fv = [gap_fields, value_fields.ravel(), frames[body][escaped]]
    fw = [w_gap, np.broadcast_to(widths[grp], (K, d)).ravel(), np.full(int(escaped.sum()), frame_bits)]
    f_group = [grp[body], np.repeat(grp, d), grp[body][escaped]]
    f_part = [np.zeros(len(fv[0]), dtype=np.int64), np.ones(len(fv[1]), dtype=np.int64),
              np.full(len(fv[2]), 2, dtype=np.int64)]
    order = np.lexsort((np.concatenate([np.arange(len(v)) for v in fv]), np.concatenate(f_part),
                        np.concatenate(f_group)))
    vals = np.concatenate(fv)[order]
    wids = np.concatenate(fw)[order]
    data = fields_bytes(vals, wids)
    group_bits = np.bincount(np.concatenate(f_group), weights=np.concatenate(fw), minlength=groups).astype(np.int64)
    starts = np.concatenate(([0], np.cumsum(group_bits)[:-1]))
    # Group table: bit offset, first key's frame, widths, smallest values.
    offset_bits = bits_for(int(starts.max()))
    e_vals = [starts[:, None], frames[first][:, None], gap_w[:, None], widths, lo & ((one << abits) - 1)]
    e_wids = [np.full((groups, 1), offset_bits), np.full((groups, 1), frame_bits),
              np.full((groups, 1), GAP_WIDTH_BITS), np.full((groups, d), VALUE_WIDTH_BITS),
              np.broadcast_to(abits, (groups, d))]
    table = fields_bytes(np.concatenate(e_vals, axis=1).ravel(), np.concatenate(e_wids, axis=1).ravel())
    # Seek table: the group of every 2^s-th frame, s about two groups' span.
    span = max(1.0, frame_count / groups)
    seek_shift = min(24, max(0, int(np.floor(np.log2(2.0 * span)))))
    seek_frames = np.arange(((frame_count - 1) >> seek_shift) + 1) << seek_shift
    seek = np.searchsorted(frames[first], seek_frames, side="right") - 1
    seek_bytes = fields_bytes(seek, bits_for(groups - 1))
    head = struct.pack("<BBBBIIf", t.kind, (1 if t.split else 0) | group_shift << 1, offset_bits, seek_shift, K,
                       len(data), t.step)
    head += bytes([int(b) for b in abits] + [0] * (4 - d))
    if t.kind in (KIND_MRP, KIND_TWIST):
        head += struct.pack("<3hH", *[int(v) for v in t.ref_codes], 0)
    if t.kind == KIND_TWIST:
        head += struct.pack("<3hHf", *[int(v) for v in t.axis_codes], 0, t.angle_step)
    assert len(head) == DESC_SIZE[t.kind]
    return head, seek_bytes + table + data


def payload(frame_count: int, node_modes: list[tuple[int, int, int]], constants: list[float],
            tracks: list[CurveTrack], group_shifts: tuple[int, ...] = GROUP_SHIFTS) -> bytes:
    """The ``RMAL`` v2 payload of one clip: per node (rotation, translation, scale) modes (0
    rest, 1 constant, 2 animated), the f32 constants they use in node order, the animated
    tracks in node order (rotation, translation, scale); each track's keys grouped by the size
    of ``2**group_shifts`` that takes the fewest bytes."""
    if not group_shifts or any(not 1 <= g <= 6 for g in group_shifts):
        raise ValueError("group shifts must be 1 ... 6")
    nodes = len(node_modes)
    modes = bytes(rm | tm << 2 | sm << 4 for rm, tm, sm in node_modes)
    modes += bytes((-nodes) % 4)
    parts = [_track_bytes(t, frame_count, tuple(group_shifts)) for t in tracks]
    descs = b"".join(p[0] for p in parts)
    head_len = PAYLOAD_HEADER + len(modes) + 4 * len(constants) + len(descs)
    body = b"".join(p[1] for p in parts)
    pad = (-head_len) % 4
    size = head_len + pad + len(body) + 8
    size += (-size) % 4
    header = struct.pack("<IIIIIIII", size, frame_count, nodes, len(tracks), len(constants), 0, 0, 0)
    out = b"".join([header, modes, np.asarray(constants, dtype="<f4").tobytes(), descs, bytes(pad), body])
    return out + bytes(size - len(out))
