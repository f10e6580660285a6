"""The ``RMAL`` version 2 payload (docs/FORMAT.md): what the runtime samples in place.

A track's keys come in groups of ``2**group_shift`` (16 or 32, per track). A fixed-size group
entry holds the bit offset of the group's records, its first key whole (frame and value) and the
widths of the records' fields; each further key is one record: its gap to the key before and,
per component, its residual from a prediction (the key before, or its slope), at the group's
widths, or an escape code whose value follows the records whole (a patched frame-of-reference
code, widths chosen per group and field for the fewest bits, the predictor per track). A seek
table names the group of every ``2**seek_shift``-th frame.
"""
from __future__ import annotations

import struct
from dataclasses import dataclass

import numpy as np

from ..bitpack import fields_bytes

PAYLOAD_HEADER = 32
WIDTH_BITS = 4
MAX_WIDTH = 15
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


def _residuals(q: np.ndarray, group_shift: int, predictor: int) -> np.ndarray:
    """Residuals (K, d) of every key from its group's prediction (rows of group anchors: 0)."""
    K = len(q)
    pos = np.arange(K) & ((1 << group_shift) - 1)
    prev = np.vstack((q[:1], q[:-1]))
    prev2 = np.vstack((q[:1], q[:1], q[:-2]))[:K]
    slope = prev - prev2
    slope[pos == 1] = 0  # the second key of a group is predicted by the first alone
    r = q - (prev + (slope * predictor + 1) // 2)
    r[pos == 0] = 0
    return r


def _widths(need: np.ndarray, grp: np.ndarray, groups: int, outlier_bits: int) -> tuple[np.ndarray, int]:
    """Per group the field width (0 ... 15) with the fewest bits for records whose values
    need ``need`` bits each (escaped past the width, at ``outlier_bits`` each), and the bits."""
    counts = np.bincount(grp, minlength=groups)
    hist = np.zeros((groups, 33), dtype=np.int64)
    np.add.at(hist, (grp, np.minimum(need, 32)), 1)
    over = counts[:, None] - np.cumsum(hist, axis=1)  # over[:, w]: records needing more than w
    w = np.arange(MAX_WIDTH + 1)
    cost = counts[:, None] * w[None, :] + over[:, : MAX_WIDTH + 1] * outlier_bits
    cost[:, 0] = np.where(over[:, 0] == 0, 0, np.iinfo(np.int64).max // 4)  # width 0: no escapes
    best = np.argmin(cost, axis=1)
    return best, int(cost[np.arange(groups), best].sum())


def _group_plan(r: np.ndarray, gaps: np.ndarray, group_shift: int, abits: np.ndarray,
                frame_bits: int) -> tuple[np.ndarray, int]:
    """Per group the widths of the gap and of each component, and the total record bits."""
    K, d = r.shape
    groups = (K - 1 >> group_shift) + 1
    body = (np.arange(K) & ((1 << group_shift) - 1)) > 0
    grp = (np.arange(K) >> group_shift)[body]
    widths = np.zeros((groups, d + 1), dtype=np.int64)
    # A gap escapes when it needs the all-ones code or more; a residual when it is outside
    # [-(2^(w-1) - 1), 2^(w-1) - 1].
    g = gaps[body]
    widths[:, 0], total = _widths(np.where(g == 0, 0, _bit_length(g + 1)), grp, groups, frame_bits)
    mag = np.abs(r[body])
    for c in range(d):
        widths[:, c + 1], bits = _widths(np.where(mag[:, c] == 0, 0, _bit_length(mag[:, c]) + 1), grp, groups,
                                         int(abits[c]))
        total += bits
    return widths, total


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
    abits = signed_bits(q)
    frame_bits = bits_for(frame_count - 1)
    gaps = np.concatenate(([0], np.diff(frames) - 1))
    best = None
    for predictor in (0, 1, 2):
        r = _residuals(q, group_shift, predictor)
        widths, bits = _group_plan(r, gaps, group_shift, abits, frame_bits)
        if best is None or bits < best[0]:
            best = (bits, predictor, r, widths)
    _, predictor, r, widths = best
    pos = np.arange(K) & (G - 1)
    grp = np.arange(K) >> group_shift
    rec = np.flatnonzero(pos > 0)
    w_rec = widths[grp[rec]]  # (R, d + 1): gap, components
    # Fields of each record (gap, then components) and which of them escape.
    raw = np.concatenate((gaps[rec][:, None], r[rec]), axis=1)
    whole = np.concatenate((frames[rec][:, None], q[rec]), axis=1)
    whole_bits = np.concatenate(([frame_bits], abits))
    escaped = np.zeros(raw.shape, dtype=bool)
    field_vals = np.zeros(raw.shape, dtype=np.int64)
    one = np.int64(1)
    wg = w_rec[:, 0]
    escaped[:, 0] = (wg > 0) & (raw[:, 0] >= (one << wg) - 1)
    field_vals[:, 0] = np.where(escaped[:, 0], (one << wg) - 1, raw[:, 0])
    for c in range(1, d + 1):
        w = w_rec[:, c]
        lim = np.where(w > 0, (one << np.maximum(w - 1, 0)) - 1, 0)
        escaped[:, c] = (np.abs(raw[:, c]) > lim) & (w > 0)
        field_vals[:, c] = np.where(escaped[:, c], one << np.maximum(w - 1, 0), raw[:, c] % (one << w))
    rec_bits = w_rec.sum(axis=1)
    exc_rows, exc_field = np.nonzero(escaped)
    exc_wids = whole_bits[exc_field]
    exc_vals = whole[exc_rows, exc_field] & ((one << exc_wids) - 1)
    group_bits = np.bincount(grp[rec], weights=rec_bits, minlength=groups).astype(np.int64)
    group_bits += np.bincount(grp[rec[exc_rows]], weights=exc_wids, minlength=groups).astype(np.int64)
    starts = np.concatenate(([0], np.cumsum(group_bits)[:-1]))
    # Order fields: by group, records before outliers, in record order, then field.
    f_group = np.concatenate((np.repeat(grp[rec], d + 1), grp[rec[exc_rows]]))
    f_part = np.concatenate((np.zeros(len(rec) * (d + 1), dtype=np.int64), np.ones(len(exc_rows), dtype=np.int64)))
    f_order = np.concatenate((np.arange(len(rec) * (d + 1)), np.arange(len(exc_rows))))
    order = np.lexsort((f_order, f_part, f_group))
    data = fields_bytes(np.concatenate((field_vals.ravel(), exc_vals))[order],
                        np.concatenate((w_rec.ravel(), exc_wids))[order])
    # Group table: bit offset, first key's frame, widths, first key's value.
    offset_bits = bits_for(int(starts.max()))
    first = np.arange(groups) * G
    e_vals = [starts[:, None], frames[first][:, None], widths, q[first] & ((one << abits) - 1)]
    e_wids = [np.full((groups, 1), offset_bits), np.full((groups, 1), frame_bits),
              np.full((groups, d + 1), WIDTH_BITS), np.broadcast_to(abits, (groups, d))]
    table = fields_bytes(np.concatenate(e_vals, axis=1).ravel(), np.concatenate(e_wids, axis=1).ravel())
    # Seek table: the group of every 2^s-th frame, s about two groups' span.
    span = max(1.0, frame_count / groups)
    seek_shift = min(24, max(0, int(np.floor(np.log2(2.0 * span)))))
    seek_frames = np.arange(((frame_count - 1) >> seek_shift) + 1) << seek_shift
    seek = np.searchsorted(frames[first], seek_frames, side="right") - 1
    seek_bytes = fields_bytes(seek, bits_for(groups - 1))
    body = seek_bytes + table + data
    head = struct.pack("<BBBBIIf", t.kind, (1 if t.split else 0) | predictor << 1 | group_shift << 3, offset_bits,
                       seek_shift, K, len(data), t.step)
    head += bytes([int(b) for b in abits] + [0] * (4 - d))
    if t.kind in (KIND_MRP, KIND_TWIST):
        head += struct.pack("<3hH", *[int(v) for v in t.ref_codes], 0)
    if t.kind == KIND_TWIST:
        head += struct.pack("<3hHf", *[int(v) for v in t.axis_codes], 0, t.angle_step)
    assert len(head) == DESC_SIZE[t.kind]
    return head, body


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
