"""The ``RMAL`` payload (docs/FORMAT.md), versions 2, 3 and 4: what the runtime samples in place.

Versions 3 and 4 (version 4 is what ``rma`` writes) code each track's keys in blocks
(:mod:`.rma_blocks`). Version 2 (``rma-pca``'s curve sets, and ``rma`` before version 3) lays
every part of a track out for direct reads, so that any key costs a few reads wherever it lies:

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

from ..bitpack import fields_bytes, fields_length
from .rma_blocks import DEFAULT_BLOCK_KEYS, bits_for, descriptor_head, track_body

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
    """Bits of each value (0 for values <= 0): the exponent of its float64, exact below 2**53."""
    x = np.maximum(np.asarray(x, dtype=np.int64), 0)
    out = np.frexp(x.astype(np.float64))[1].astype(np.int64)
    big = x >= np.int64(1) << 53
    if np.any(big):
        out[big] = [int(v).bit_length() for v in x[big]]
    return out


def cell_count(frame_count: int, cell_shift: "int | np.ndarray") -> "int | np.ndarray":
    """Cells of a clip: frame 0, the cells of frames 1 ... F - 2, the last frame."""
    if frame_count == 1:
        return 1
    return ((frame_count - 2 + (1 << cell_shift) - 1) >> cell_shift) + 2


def key_cells(frames: np.ndarray, frame_count: int, cell_shift: "int | np.ndarray") -> np.ndarray:
    """The cell of every key frame (for a column of cell shifts (S, 1), a row per shift)."""
    f = np.asarray(frames, dtype=np.int64)
    cells = np.where(f > 0, ((f - 1) >> cell_shift) + 1, 0)
    if frame_count > 1:
        cells = np.where(f == frame_count - 1, cell_count(frame_count, cell_shift) - 1, cells)
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


def _widths(need: np.ndarray, grp: np.ndarray, groups: int, outlier_bits: np.ndarray) -> np.ndarray:
    """Per group and component the field width (0 ... 15) with the fewest bits for records
    whose values need ``need`` (R, d) bits each (escaped past the width, at ``outlier_bits``
    (d,) each, plus the decoder's penalty), as (groups, d)."""
    d = need.shape[1]
    counts = np.bincount(grp, minlength=groups)
    cell = (grp[:, None] * d + np.arange(d)[None, :]) * 33 + np.minimum(need, 32)
    hist = np.bincount(cell.ravel(), minlength=groups * d * 33).reshape(groups, d, 33)
    over = counts[:, None, None] - np.cumsum(hist, axis=2)  # over[g, c, w]: records needing more than w
    w = np.arange(MAX_WIDTH + 1)
    cost = (counts[:, None, None] * w[None, None, :]
            + over[:, :, : MAX_WIDTH + 1] * (np.asarray(outlier_bits)[None, :, None] + ESCAPE_PENALTY_BITS))
    cost[:, :, 0] = np.where(over[:, :, 0] == 0, 0, np.iinfo(np.int64).max // 4)  # width 0: no escapes
    return np.argmin(cost, axis=2)


@dataclass
class _KeyTimes:
    """Key times in cells of ``2**cell_shift`` frames: each key's cell, its place in the cell,
    the bits of a place (0 when every key is on its cell's first frame) and the bytes they take."""

    cell_shift: int
    cells: np.ndarray
    places: np.ndarray
    in_cell: int
    length: int


def _key_times_each(frames: np.ndarray, frame_count: int, cell_shifts: tuple[int, ...]) -> list[_KeyTimes]:
    """The layouts of key times in cells of ``2**s`` frames for each s of ``cell_shifts``, and
    their lengths in bytes (unary words, rank table, places), without packing them; the shifts
    are worked out together, a row each."""
    K = len(frames)
    shifts = np.asarray(cell_shifts, dtype=np.int64)[:, None]
    where = key_cells(frames, frame_count, shifts)
    places = frames - cell_starts(where, frame_count, shifts)
    placed = np.any(places, axis=1)
    out = []
    for j, cell_shift in enumerate(cell_shifts):
        cells = cell_count(frame_count, cell_shift)
        in_cell = cell_shift if placed[j] else 0
        length = (K + cells + 63) // 64 * 8 + fields_length((cells + 63) // 64 * bits_for(K))
        if in_cell:
            length += fields_length(K * in_cell)
        out.append(_KeyTimes(cell_shift, where[j], places[j], in_cell, length))
    return out


def _key_times_bytes(kt: _KeyTimes, frame_count: int) -> bytes:
    """The key times' bytes: the unary cells (key k's one at bit cell_k + k, each cell closed
    by a zero; 64-bit little-endian words), the rank table (keys in the cells below every
    64th) and the places."""
    K = len(kt.cells)
    cells = cell_count(frame_count, kt.cell_shift)
    words = (K + cells + 63) // 64
    unary = np.zeros(words * 64, dtype=np.uint8)
    unary[kt.cells + np.arange(K)] = 1
    per_cell = np.bincount(kt.cells, minlength=cells)
    rank = np.concatenate(([0], np.cumsum(per_cell)))[np.arange((cells + 63) // 64) * RANK_CELLS]
    out = np.packbits(unary, bitorder="little").tobytes() + fields_bytes(rank, bits_for(K))
    if kt.in_cell:
        out += fields_bytes(kt.places, kt.in_cell)
    assert len(out) == kt.length
    return out


def cell_starts(cells: np.ndarray, frame_count: int, cell_shift: "int | np.ndarray") -> np.ndarray:
    """The first frame of each cell (cell shifts broadcast as in :func:`key_cells`)."""
    c = np.asarray(cells, dtype=np.int64)
    last = cell_count(frame_count, cell_shift) - 1
    return np.where(c == 0, 0, np.where(c == last, frame_count - 1, 1 + (c - 1 << cell_shift)))


@dataclass
class _KeyValues:
    """Key values in groups of ``2**group_shift`` keys: the records (keys other than the
    anchors) with their group and residuals, each group's widths, which residuals escape,
    every group's bit offset (the last entry the end) and the bytes of table and data."""

    group_shift: int
    rec: np.ndarray
    grp: np.ndarray
    residuals: np.ndarray
    widths: np.ndarray
    escaped: np.ndarray
    starts: np.ndarray
    offset_bits: int
    length: int


def _key_values_each(q: np.ndarray, abits: np.ndarray, group_shifts: tuple[int, ...]) -> list[_KeyValues]:
    """The layouts of key values ``q`` (K, d) in groups of ``2**g`` keys for each g of
    ``group_shifts``, and their lengths in bytes (group table and records), without packing
    them. Every layout's groups are numbered on after the previous one's, so that the widths
    of all of them come from one pass over all their records."""
    K, d = q.shape
    parts = [chord_residuals(q, g) for g in group_shifts]
    groups = [(K - 1 + (1 << g) - 1) // (1 << g) for g in group_shifts]  # the rows less the closing one
    first = np.concatenate(([0], np.cumsum(groups)))  # each layout's first group in the numbering
    grp = np.concatenate([(rec >> g) + first[j] for j, ((rec, _), g) in enumerate(zip(parts, group_shifts))])
    r = np.concatenate([res for _, res in parts])
    mag = np.abs(r)
    widths = np.zeros((int(first[-1]), d), dtype=np.int64)
    if len(widths):
        widths = _widths(np.where(mag == 0, 0, _bit_length(mag) + 1), grp, len(widths), abits)
    w_rec = widths[grp]  # (R, d)
    lim = np.where(w_rec > 0, (np.int64(1) << np.maximum(w_rec - 1, 0)) - 1, 0)
    escaped = (mag > lim) & (w_rec > 0)
    record_bits = w_rec.sum(axis=1) + np.where(escaped, abits[None, :], 0).sum(axis=1)
    group_bits = np.bincount(grp, weights=record_bits, minlength=len(widths)).astype(np.int64)
    out, at = [], 0
    for j, ((rec, res), g) in enumerate(zip(parts, group_shifts)):
        mine = slice(first[j], first[j + 1])
        starts = np.concatenate(([0], np.cumsum(group_bits[mine])))  # rows entries: the last is the end
        offset_bits = bits_for(int(starts[-1]))
        rows = groups[j] + 1
        length = fields_length(rows * (offset_bits + d * WIDTH_BITS + int(abits.sum()))) + fields_length(starts[-1])
        out.append(_KeyValues(g, rec, rec >> g, res, np.concatenate((widths[mine], np.zeros((1, d), np.int64))),
                              escaped[at:at + len(rec)], starts, offset_bits, length))
        at += len(rec)
    return out


def _key_values_bytes(kv: _KeyValues, q: np.ndarray, abits: np.ndarray) -> tuple[bytes, bytes]:
    """(group table, records) of a key-value layout: per group its bit offset, widths and
    anchor whole; then by group, each record's fields in record and component order (the
    residual, or the escape code) followed by the group's escaped values whole."""
    one = np.int64(1)
    K, d = q.shape
    G = 1 << kv.group_shift
    rows = len(kv.widths)
    rec, grp = kv.rec, kv.grp
    w_rec = kv.widths[grp]
    field_vals = np.where(kv.escaped, one << np.maximum(w_rec - 1, 0), kv.residuals % (one << w_rec))
    exc_rows, exc_comp = np.nonzero(kv.escaped)
    exc_wids = abits[exc_comp]
    exc_vals = q[rec[exc_rows], exc_comp] & ((one << exc_wids) - 1)
    f_group = np.concatenate((np.repeat(grp, d), grp[exc_rows]))
    f_part = np.concatenate((np.zeros(len(rec) * d, dtype=np.int64), np.ones(len(exc_rows), dtype=np.int64)))
    f_order = np.concatenate((np.arange(len(rec) * d), np.arange(len(exc_rows))))
    order = np.lexsort((f_order, f_part, f_group))
    data = fields_bytes(np.concatenate((field_vals.ravel(), exc_vals))[order],
                        np.concatenate((w_rec.ravel(), exc_wids))[order])
    anchors = q[np.minimum(np.arange(rows) * G, K - 1)]
    e_vals = [kv.starts[:, None], kv.widths, anchors & ((one << abits) - 1)]
    e_wids = [np.full((rows, 1), kv.offset_bits), np.full((rows, d), WIDTH_BITS), np.broadcast_to(abits, (rows, d))]
    table = fields_bytes(np.concatenate(e_vals, axis=1).ravel(), np.concatenate(e_wids, axis=1).ravel())
    assert len(table) + len(data) == kv.length
    return table, data


@dataclass(frozen=True)
class Groups:
    """Version 2's key layout: the group sizes ``2**shifts`` a track may take (the fewest bytes wins)."""

    shifts: tuple[int, ...] = GROUP_SHIFTS
    version = 2


@dataclass(frozen=True)
class Blocks:
    """Version 4's key layout: Rice-coded blocks of ``2**shift`` keys (:mod:`.rma_blocks`)."""

    shift: int = DEFAULT_BLOCK_KEYS.bit_length() - 1
    version = 4


def _checked_keys(t: CurveTrack, frame_count: int) -> tuple[np.ndarray, np.ndarray]:
    """The track's (frames, q) as int64, refused when they break the format's key rules."""
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
    return frames, q


def _descriptor_tail(t: CurveTrack, abits: np.ndarray) -> bytes:
    """A descriptor after its first 16 bytes (the same in both versions): anchor widths, the
    reference rotation, a twist's axis and angle step."""
    d = DIMS[t.kind]
    tail = bytes([int(b) for b in abits] + [0] * (4 - d))
    if t.kind in (KIND_MRP, KIND_TWIST):
        tail += struct.pack("<3hH", *[int(v) for v in t.ref_codes], 0)
    if t.kind == KIND_TWIST:
        tail += struct.pack("<3hHf", *[int(v) for v in t.axis_codes], 0, t.angle_step)
    return tail


def _track_bytes(t: CurveTrack, frame_count: int, layout: "Groups | Blocks") -> tuple[bytes, bytes]:
    """(descriptor, data) of one track in ``layout``. Version 2: of the cell sizes (up to
    ``2**MAX_CELL_SHIFT`` frames) and the group sizes the ones with the fewest bytes (the first
    on a tie), every choice sized before anything is packed and only the chosen one packed."""
    frames, q = _checked_keys(t, frame_count)
    abits = signed_bits(q)
    if isinstance(layout, Blocks):
        offset_bits, data_bytes, table, data = track_body(frames, q, abits, frame_count, layout.shift)
        head = descriptor_head(t.kind, t.split, layout.shift, offset_bits, len(q), data_bytes, t.step)
        body = table + data
    else:
        # The key times and the key values are sized independently: each choice is the smallest of its own.
        kt = min(_key_times_each(frames, frame_count, tuple(range(MAX_CELL_SHIFT + 1))), key=lambda o: o.length)
        kv = min(_key_values_each(q, abits, layout.shifts), key=lambda o: o.length)
        table, data = _key_values_bytes(kv, q, abits)
        body = _key_times_bytes(kt, frame_count) + table + data
        head = struct.pack("<BBBBIIf", t.kind, (1 if t.split else 0) | kt.cell_shift << 1 | kv.group_shift << 3,
                           kv.offset_bits, kt.in_cell, len(q), len(data), t.step)
    head += _descriptor_tail(t, abits)
    assert len(head) == DESC_SIZE[t.kind]
    return head, body


class WrittenTracks:
    """The (descriptor, data) of the tracks of the last payload written, by content: a repair
    round refits a few tracks of a clip and writes the others again unchanged."""

    def __init__(self) -> None:
        self._last: dict[tuple, tuple[bytes, bytes]] = {}

    def write(self, tracks: list[CurveTrack], frame_count: int,
              layout: "Groups | Blocks") -> list[tuple[bytes, bytes]]:
        """Every track's (descriptor, data), those seen in the last call reused; only this
        call's are kept (each moved from the last call's as it is met: the two are not held
        whole at once)."""
        now: dict[tuple, tuple[bytes, bytes]] = {}
        parts = []
        for t in tracks:
            key = _content(t, frame_count, layout)
            part = self._last.pop(key, None) or now.get(key) or _track_bytes(t, frame_count, layout)
            now[key] = part
            parts.append(part)
        self._last = now
        return parts


def _content(t: CurveTrack, frame_count: int, layout: "Groups | Blocks") -> tuple:
    """Everything a track's bytes depend on."""
    q = np.asarray(t.q, dtype=np.int64)
    codes = [b"" if c is None else np.asarray(c, dtype=np.int64).tobytes() for c in (t.ref_codes, t.axis_codes)]
    return (t.kind, t.split, float(t.step), float(t.angle_step), frame_count, layout, q.shape,
            q.tobytes(), np.asarray(t.frames, dtype=np.int64).tobytes(), *codes)


def payload(frame_count: int, node_modes: list[tuple[int, int, int]], constants: list[float],
            tracks: list[CurveTrack], layout: "Groups | Blocks" = Groups(),
            written: WrittenTracks | None = None) -> bytes:
    """The ``RMAL`` payload of one clip, of ``layout.version``: per node (rotation, translation,
    scale) modes (0 rest, 1 constant, 2 animated), the f32 constants they use in node order, the
    animated tracks in node order (rotation, translation, scale), each track's keys laid out as
    ``layout`` says. ``written``: the tracks of the previous payload of this clip, reused where
    unchanged (the bytes are the same)."""
    if isinstance(layout, Groups) and (not layout.shifts or any(not 1 <= g <= 6 for g in layout.shifts)):
        raise ValueError("group shifts must be 1 ... 6")
    nodes = len(node_modes)
    modes = bytes(rm | tm << 2 | sm << 4 for rm, tm, sm in node_modes)
    modes += bytes((-nodes) % 4)
    if written is None:
        written = WrittenTracks()
    parts = written.write(tracks, frame_count, layout)
    descs = b"".join(p[0] for p in parts)
    head_len = PAYLOAD_HEADER + len(modes) + 4 * len(constants) + len(descs)
    body = b"".join(p[1] for p in parts)
    pad = (-head_len) % 4
    size = head_len + pad + len(body) + 8
    size += (-size) % 4
    header = struct.pack("<IIIIIIII", size, frame_count, nodes, len(tracks), len(constants), 0, 0, 0)
    out = b"".join([header, modes, np.asarray(constants, dtype="<f4").tobytes(), descs, bytes(pad), body])
    return out + bytes(size - len(out))
