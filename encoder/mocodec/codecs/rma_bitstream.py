"""The ``RMAL`` version 2 payload (docs/FORMAT.md): what the runtime samples in place.

Every part of a track is laid out for direct reads, so that any key costs a few reads wherever
it lies:

- key times are cells of ``2**cell_shift`` frames (frame 0 and the last frame are cells of
  their own) written in unary, a one per key and a zero closing each cell, with a rank table
  (the keys before every 64th cell) and, unless every key is on its cell's first frame, each
  key's place in its cell: the key at or before a frame is a rank entry and a popcount or two
  away, its neighbours the next ones;
- key values come in groups of ``2**group_shift`` keys (8, 16 or 32, per track): a group's
  entry holds its first key whole (its anchor), the bit offset of its records and their widths;
  every other key is one record, its residual per component from the chord between its
  group's anchor and the next one, at the group's width, or an escape code whose value follows
  the group's records whole (a patched frame-of-reference code, widths chosen per group and
  component for the fewest bits).
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
GROUP_SHIFTS = (3, 4, 5)  # the group sizes the writer tries per track (8, 16, 32 keys), smallest bytes wins
MAX_CELL_SHIFT = 3  # key cells of up to 8 frames
RANK_CELLS = 64  # a rank entry every 64 cells
# An escaped residual costs the decoder a walk over the group's records before it: the widths
# are chosen as if each escape cost this many bits more.
ESCAPE_PENALTY_BITS = 8


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


def cell_count(frame_count: int, cell_shift: int) -> int:
    """Cells of a clip: frame 0, the cells of frames 1 ... F - 2, the last frame."""
    if frame_count == 1:
        return 1
    return ((frame_count - 2 + (1 << cell_shift) - 1) >> cell_shift) + 2


def key_cells(frames: np.ndarray, frame_count: int, cell_shift: int) -> np.ndarray:
    """The cell of every key frame."""
    f = np.asarray(frames, dtype=np.int64)
    cells = np.where(f > 0, ((f - 1) >> cell_shift) + 1, 0)
    if frame_count > 1:
        cells[f == frame_count - 1] = cell_count(frame_count, cell_shift) - 1
    return cells


def chord_residuals(q: np.ndarray, group_shift: int) -> tuple[np.ndarray, np.ndarray]:
    """(record keys, their residuals (R, d)) from the chord between each group's anchor (key
    ``e * G``) and the next (key ``min((e + 1) * G, K - 1)``)."""
    K = len(q)
    G = 1 << group_shift
    idx = np.arange(K)
    rec = idx[(idx & (G - 1) > 0) & (idx < K - 1)]
    first = rec >> group_shift << group_shift
    nxt = np.minimum(first + G, K - 1)
    span = (nxt - first)[:, None]
    a0, a1 = q[first], q[nxt]
    pred = a0 + ((a1 - a0) * (rec - first)[:, None]) // span  # floor division, as the runtime's
    return rec, q[rec] - pred


def _widths(need: np.ndarray, grp: np.ndarray, groups: int, outlier_bits: int) -> tuple[np.ndarray, int]:
    """Per group the field width (0 ... 15) with the fewest bits for records whose values
    need ``need`` bits each (escaped past the width, at ``outlier_bits`` each), and the bits."""
    counts = np.bincount(grp, minlength=groups)
    hist = np.zeros((groups, 33), dtype=np.int64)
    np.add.at(hist, (grp, np.minimum(need, 32)), 1)
    over = counts[:, None] - np.cumsum(hist, axis=1)  # over[:, w]: records needing more than w
    w = np.arange(MAX_WIDTH + 1)
    cost = counts[:, None] * w[None, :] + over[:, : MAX_WIDTH + 1] * (outlier_bits + ESCAPE_PENALTY_BITS)
    cost[:, 0] = np.where(over[:, 0] == 0, 0, np.iinfo(np.int64).max // 4)  # width 0: no escapes
    best = np.argmin(cost, axis=1)
    return best, int((counts * best + over[np.arange(groups), best] * outlier_bits).sum())


def _key_times(frames: np.ndarray, frame_count: int, cell_shift: int) -> tuple[int, int, bytes]:
    """(cell shift, bits of each key's place in its cell (0 when every key is on its cell's
    first frame), bytes): the unary cells (key k's one at bit cell_k + k, each cell closed by
    a zero; 64-bit little-endian words), the rank table (keys in the cells below every 64th)
    and the places."""
    f = np.asarray(frames, dtype=np.int64)
    K = len(f)
    cells = cell_count(frame_count, cell_shift)
    words = (K + cells + 63) // 64
    where = key_cells(f, frame_count, cell_shift)
    unary = np.zeros(words * 64, dtype=np.uint8)
    unary[where + np.arange(K)] = 1
    per_cell = np.bincount(where, minlength=cells)
    rank = np.concatenate(([0], np.cumsum(per_cell)))[np.arange((cells + 63) // 64) * RANK_CELLS]
    out = np.packbits(unary, bitorder="little").tobytes() + fields_bytes(rank, bits_for(K))
    places = f - cell_starts(where, frame_count, cell_shift)
    in_cell = cell_shift if np.any(places) else 0
    if in_cell:
        out += fields_bytes(places, in_cell)
    return cell_shift, in_cell, out


def cell_starts(cells: np.ndarray, frame_count: int, cell_shift: int) -> np.ndarray:
    """The first frame of each cell."""
    c = np.asarray(cells, dtype=np.int64)
    last = cell_count(frame_count, cell_shift) - 1
    return np.where(c == 0, 0, np.where(c == last, frame_count - 1, 1 + (c - 1 << cell_shift)))


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
    one = np.int64(1)
    abits = signed_bits(q)
    # Key times: of the cell sizes, the one with the fewest bytes.
    cell_shift, in_cell, times = min((_key_times(frames, frame_count, cs) for cs in range(MAX_CELL_SHIFT + 1)),
                                     key=lambda o: len(o[2]))
    # Key values: anchors whole in the group table, the others residuals from the chord.
    G = 1 << group_shift
    rows = (K - 1 + G - 1) // G + 1
    groups = rows - 1
    rec, r = chord_residuals(q, group_shift)
    grp = rec >> group_shift
    widths = np.zeros((rows, d), dtype=np.int64)
    mag = np.abs(r)
    for c in range(d if groups else 0):
        widths[:groups, c], _ = _widths(np.where(mag[:, c] == 0, 0, _bit_length(mag[:, c]) + 1), grp, groups,
                                        int(abits[c]))
    w_rec = widths[grp]  # (R, d)
    lim = np.where(w_rec > 0, (one << np.maximum(w_rec - 1, 0)) - 1, 0)
    escaped = (mag > lim) & (w_rec > 0)
    field_vals = np.where(escaped, one << np.maximum(w_rec - 1, 0), r % (one << w_rec))
    exc_rows, exc_comp = np.nonzero(escaped)
    exc_wids = abits[exc_comp]
    exc_vals = q[rec[exc_rows], exc_comp] & ((one << exc_wids) - 1)
    group_bits = np.bincount(grp, weights=w_rec.sum(axis=1), minlength=groups).astype(np.int64)
    group_bits += np.bincount(grp[exc_rows], weights=exc_wids, minlength=groups).astype(np.int64)
    starts = np.concatenate(([0], np.cumsum(group_bits)))  # rows entries: the last is the end
    # Fields in order: by group, records before outliers, in record order, then component.
    f_group = np.concatenate((np.repeat(grp, d), grp[exc_rows]))
    f_part = np.concatenate((np.zeros(len(rec) * d, dtype=np.int64), np.ones(len(exc_rows), dtype=np.int64)))
    f_order = np.concatenate((np.arange(len(rec) * d), np.arange(len(exc_rows))))
    order = np.lexsort((f_order, f_part, f_group))
    data = fields_bytes(np.concatenate((field_vals.ravel(), exc_vals))[order],
                        np.concatenate((w_rec.ravel(), exc_wids))[order])
    offset_bits = bits_for(int(starts[-1]))
    anchors = q[np.minimum(np.arange(rows) * G, K - 1)]
    e_vals = [starts[:, None], widths, anchors & ((one << abits) - 1)]
    e_wids = [np.full((rows, 1), offset_bits), np.full((rows, d), WIDTH_BITS), np.broadcast_to(abits, (rows, d))]
    table = fields_bytes(np.concatenate(e_vals, axis=1).ravel(), np.concatenate(e_wids, axis=1).ravel())
    body = times + table + data
    head = struct.pack("<BBBBIIf", t.kind, (1 if t.split else 0) | cell_shift << 1 | group_shift << 3, offset_bits,
                       in_cell, K, len(data), t.step)
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
