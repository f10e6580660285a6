"""The ``RMAL`` version 2 payload (docs/FORMAT.md): what the runtime samples in place.

A track's key times are a bit mask over the cells of its key grid (frames 1 ... F - 1 in cells
of 1, 2, 4 or 8 frames; frame 0 is always key 0) with a rank directory every 256 cells; a cell
holding more than one key is listed once per extra key in a sorted list (the fitter keeps
those rare: ``curves.fit_keys``). Its key values come in groups of ``2**group_shift`` keys: a fixed-size group
entry (bit offset of the group's records, residual widths, the first key whole) and one record
per further key (in-cell offset, then per component a residual from a prediction at the
group's width, or an escape code whose value follows the records whole). Widths are chosen
per group and component for the fewest bits (a patched frame-of-reference code), the
predictor per track.
"""
from __future__ import annotations

import struct
from dataclasses import dataclass

import numpy as np

from ..bitpack import fields_bytes

PAYLOAD_HEADER = 32
DIR_CELLS = 256
WIDTH_BITS = 5
MAX_WIDTH = 30
MAX_Q = 1 << 30
KIND_MRP, KIND_TWIST, KIND_TRANSLATION, KIND_SCALE = 1, 2, 3, 4
DIMS = {KIND_MRP: 3, KIND_TWIST: 4, KIND_TRANSLATION: 3, KIND_SCALE: 3}
DESC_SIZE = {KIND_MRP: 32, KIND_TWIST: 44, KIND_TRANSLATION: 24, KIND_SCALE: 24}
DEFAULT_GROUP_SHIFT = 4


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


def _extra_bits(cells: int) -> int:
    """Bits of a cell index in the extra-key list."""
    return max(1, int(cells - 1).bit_length())


def grid_shift_for(frames: np.ndarray, frame_count: int) -> int:
    """The key grid (shift 0 ... 3) whose mask, in-cell offsets and extra-key list take the
    fewest bits."""
    f = np.asarray(frames, dtype=np.int64)[1:]
    if frame_count < 2 or len(f) == 0:
        return 0
    best, best_bits = 0, None
    for shift in (0, 1, 2, 3):
        cells = ((frame_count - 2) >> shift) + 1
        extras = int(np.sum(np.diff((f - 1) >> shift) == 0))
        bits = cells + shift * len(frames) + extras * _extra_bits(cells)
        if best_bits is None or bits < best_bits:
            best, best_bits = shift, bits
    return best


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


def _group_plan(r: np.ndarray, group_shift: int, abits: np.ndarray) -> tuple[np.ndarray, int]:
    """Per group and component the residual width with the fewest bits (records at that
    width plus escaped outliers whole) and the total bits."""
    K, d = r.shape
    G = 1 << group_shift
    groups = (K - 1) // G + 1
    pos = np.arange(K) & (G - 1)
    grp = np.arange(K) >> group_shift
    mag = np.abs(r)
    need = np.where(mag == 0, 0, _bit_length(mag) + 1)  # width that holds r without escaping
    widths = np.zeros((groups, d), dtype=np.int64)
    total = 0
    body = pos > 0
    counts = np.bincount(grp[body], minlength=groups)  # records per group
    for c in range(d):
        hist = np.zeros((groups, 33), dtype=np.int64)
        np.add.at(hist, (grp[body], np.minimum(need[body, c], 32)), 1)
        over = counts[:, None] - np.cumsum(hist, axis=1)  # over[:, w] = records needing more than w
        w = np.arange(MAX_WIDTH + 1)
        cost = counts[:, None] * w[None, :] + over[:, : MAX_WIDTH + 1] * abits[c]
        cost[:, 0] = np.where(over[:, 0] == 0, 0, np.iinfo(np.int64).max // 4)  # width 0: no escapes
        widths[:, c] = np.argmin(cost, axis=1)
        total += int(cost[np.arange(groups), widths[:, c]].sum())
    return widths, total


def _track_bytes(t: CurveTrack, frame_count: int, group_shift: int) -> tuple[bytes, bytes]:
    """(descriptor, data) of one track."""
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
    gs = grid_shift_for(frames, frame_count)
    abits = signed_bits(q)
    G = 1 << group_shift
    groups = (K - 1) // G + 1
    # Key times: a mask over cells, a directory every 256 cells.
    cells = ((frame_count - 2) >> gs) + 1 if frame_count > 1 else 0
    words = (cells + 63) // 64
    mask = np.zeros(words * 64, dtype=np.uint8)
    key_cell = (frames[1:] - 1) >> gs
    offset = np.concatenate(([0], (frames[1:] - 1) & ((1 << gs) - 1)))
    mask[key_cell] = 1
    mask_bytes = np.packbits(mask, bitorder="little").tobytes()
    extra_cells = key_cell[1:][np.diff(key_cell) == 0]  # a key sharing its cell with the one before
    extra_bytes = fields_bytes(extra_cells, _extra_bits(cells)) if len(extra_cells) else b""
    per_word = mask.reshape(-1, 64).sum(axis=1) if words else np.zeros(0, dtype=np.int64)
    ranks = np.concatenate(([0], np.cumsum(per_word)))[: words][::4] if words else np.zeros(0, dtype=np.int64)
    dir_bytes = np.asarray(ranks, dtype="<u4").tobytes()
    # Values: the predictor with the fewest bits.
    best = None
    for predictor in (0, 1, 2):
        r = _residuals(q, group_shift, predictor)
        widths, bits = _group_plan(r, group_shift, abits)
        if best is None or bits < best[0]:
            best = (bits, predictor, r, widths)
    _, predictor, r, widths = best
    pos = np.arange(K) & (G - 1)
    grp = np.arange(K) >> group_shift
    rec = np.flatnonzero(pos > 0)
    w_rec = widths[grp[rec]]  # (R, d)
    escaped = np.zeros((len(rec), d), dtype=bool)
    field_vals = np.zeros((len(rec), d), dtype=np.int64)
    for c in range(d):
        w = w_rec[:, c]
        rc = r[rec, c]
        lim = np.where(w > 0, (np.int64(1) << np.maximum(w - 1, 0)) - 1, 0)
        escaped[:, c] = (np.abs(rc) > lim) & (w > 0)
        mod = np.int64(1) << w
        field_vals[:, c] = np.where(escaped[:, c], np.int64(1) << np.maximum(w - 1, 0), rc % mod)
    # Records of each group, then its outliers; groups back to back.
    rec_vals = np.concatenate((offset[rec][:, None], field_vals), axis=1)
    rec_wids = np.concatenate((np.full((len(rec), 1), gs), w_rec), axis=1)
    rec_bits = rec_wids.sum(axis=1)
    exc_rows, exc_comp = np.nonzero(escaped)
    exc_vals = q[rec[exc_rows], exc_comp] & ((np.int64(1) << abits[exc_comp]) - 1)
    exc_wids = abits[exc_comp]
    group_bits = np.bincount(grp[rec], weights=rec_bits, minlength=groups).astype(np.int64)
    group_bits += np.bincount(grp[rec[exc_rows]], weights=exc_wids, minlength=groups).astype(np.int64)
    starts = np.concatenate(([0], np.cumsum(group_bits)[:-1]))
    # Order fields: by group, records before outliers, in record order, then component.
    f_group = np.concatenate((np.repeat(grp[rec], d + 1), grp[rec[exc_rows]]))
    f_part = np.concatenate((np.zeros(len(rec) * (d + 1), dtype=np.int64), np.ones(len(exc_rows), dtype=np.int64)))
    f_order = np.concatenate((np.arange(len(rec) * (d + 1)), np.arange(len(exc_rows))))
    order = np.lexsort((f_order, f_part, f_group))
    data = fields_bytes(np.concatenate((rec_vals.ravel(), exc_vals))[order],
                        np.concatenate((rec_wids.ravel(), exc_wids))[order])
    # Group table: bit offset, widths, the first key's in-cell offset and value.
    offset_bits = max(1, int(_bit_length(np.array([int(starts.max())]))[0]))
    first = np.arange(groups) * G
    e_vals = [starts[:, None], widths, offset[first][:, None], q[first] & ((np.int64(1) << abits) - 1)]
    e_wids = [np.full((groups, 1), offset_bits), np.full((groups, d), WIDTH_BITS), np.full((groups, 1), gs),
              np.broadcast_to(abits, (groups, d))]
    table = fields_bytes(np.concatenate(e_vals, axis=1).ravel(), np.concatenate(e_wids, axis=1).ravel())
    body = mask_bytes + dir_bytes + extra_bytes + table + data
    head = struct.pack("<BBBBIIIf", t.kind, gs | (4 if t.split else 0), predictor, offset_bits, K, len(data),
                       len(extra_cells), t.step)
    head += bytes([int(b) for b in abits] + [0] * (4 - d))
    if t.kind in (KIND_MRP, KIND_TWIST):
        head += struct.pack("<3hH", *[int(v) for v in t.ref_codes], 0)
    if t.kind == KIND_TWIST:
        head += struct.pack("<3hHf", *[int(v) for v in t.axis_codes], 0, t.angle_step)
    assert len(head) == DESC_SIZE[t.kind]
    return head, body


def payload(frame_count: int, node_modes: list[tuple[int, int, int]], constants: list[float],
            tracks: list[CurveTrack], group_shift: int = DEFAULT_GROUP_SHIFT) -> bytes:
    """The ``RMAL`` v2 payload of one clip: per node (rotation, translation, scale) modes (0
    rest, 1 constant, 2 animated), the f32 constants they use in node order, the animated
    tracks in node order (rotation, translation, scale), keys grouped by ``2**group_shift``."""
    if not 1 <= group_shift <= 6:
        raise ValueError("group_shift must be 1 ... 6")
    nodes = len(node_modes)
    modes = bytes(rm | tm << 2 | sm << 4 for rm, tm, sm in node_modes)
    modes += bytes((-nodes) % 4)
    parts = [_track_bytes(t, frame_count, group_shift) for t in tracks]
    descs = b"".join(p[0] for p in parts)
    head_len = PAYLOAD_HEADER + len(modes) + 4 * len(constants) + len(descs)
    body = b"".join(p[1] for p in parts)
    pad = (-head_len) % 4
    size = head_len + pad + len(body) + 8
    size += (-size) % 4
    header = struct.pack("<IIIIIBBBBII", size, frame_count, nodes, len(tracks), len(constants), group_shift,
                         0, 0, 0, 0, 0)
    out = b"".join([header, modes, np.asarray(constants, dtype="<f4").tobytes(), descs, bytes(pad), body])
    return out + bytes(size - len(out))
