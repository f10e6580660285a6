"""Design probe for an RMAL version 3 layout: exact bytes of candidate layouts of the same keys.

The keys (frames and lattice integers of every track of every clip) are read from an ``rma``
asset through the Python reference reader (``mocodec.codecs.rma_reference.decode_keys``), so the
curves, and with them the error, are the asset's own; only the layout changes. For each
candidate the probe counts every byte a payload would hold (header, node modes, constants,
descriptors, block rows, records, padding) the way docs/RMAL_V3_STUDY.md defines it, and can
write the chosen layout to a file that bench/rmal_v3_proto.c samples.

Candidate family "frame blocks" (FB): each track is cut into blocks of B = 2^b frames (block j
is frames [jB, jB + B)), so the block of a frame is a shift. One row per block, at a fixed
stride in the track's row table, holds the block's key count n, the width of its key-time
fields, the bit offset of its data, and per component the width of its residual fields and
its anchor (a multiple of 2^k). A block's data (none when n = 0) is its key times, then n
fixed-width records (per component a residual, no escapes):

- key times (per track): ``mask``, B bits, bit o set for a key at frame jB + o (dense tracks);
  or ``gaps``, n fields of the block's width: the first key's offset in the block, then each
  next key's distance from the one before less 1 (sparse tracks);
- values (per track): ``for``, frame of reference, q = anchor + u (u unsigned); or ``knot``, the
  residual from the linear spline through anchors at frames jB (rows j and j + 1),
  p = A_j + floor((A_{j+1} - A_j) (f - jB) / B), a shift; the anchors a least-squares fit of the
  keys rounded to the track's anchor lattice 2^k.

- ``prev``: the block's first key is the anchor, each next key a difference from the one before
  (a random access sums the block's differences up to its key; the prototype keeps the running
  sum, so the window's four consecutive keys cost one pass).

``FB prev (size reference)`` (the same predictor with v2's anchor widths, every block shift and
time mode) and the ``entropy floor`` are printed for comparison.

Candidate family "entropy-coded blocks" (EB, ``--eb``): each track's keys are cut into blocks of
K = 2^b keys (keys eK ... eK + K - 1 form block e; the last block may be shorter; K fixed per
file, 8 ... 64, or per track the K in 8 ... 128 with the fewest bytes). One row per block, at a
fixed bit stride in the track's row table: the frame of the block's first key (bits of the clip's
last frame), the bit offset of the block's data, in the "gaps first" and "two-way" orders the bit
length of the block's first part, a 5-bit Rice parameter for the gaps then one per component, and
each component's anchor (the block's first key's lattice integer, whole, at v2's anchor width).
A block's data holds, for each key after its first, gap - 1 (gap: the frame difference to the key
before) and each component's difference from the key before, zigzag-mapped, each a Rice code with
its stream's parameter k: the quotient z >> k as that many 0 bits closed by a 1 (least
significant bit first), then the k low bits; a quotient of 16 or more is an escape, 16 zeros
then z in 32 raw bits (so a code is at most 48 bits: one 64-bit load holds it). Each block's
parameters are the fewest bits, escapes counted. Code orders: ``interleaved``, per key its gap
code then its component codes; ``gaps first``, the block's gap codes, then per key its component
codes; ``two-way``, keys 1 ... K/2 forward (interleaved), then keys K - 1 ... K/2 + 1 backward, each
from the key after it (the step into key K, the next row's anchor, is stored; the one from key K/2
to K/2 + 1 is not; the last block is all forward). Track bytes: the row table and the data area,
each padded to 4 bytes, in a payload counted as for FB.

Run: ``python bench/rmal_v3_probe.py [--write DIR]`` (sizes of both dev assets; ``--write``
also writes ``DIR/<asset>.v3p`` for the prototype decoder); ``--eb [--write DIR]`` the EB
candidates and ``DIR/rma_<tolerance>_<K>_v<order>.v3e`` for bench/rmal_v3_eb.c.
"""
from __future__ import annotations

import argparse
import json
import struct
import sys
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "encoder"))

from mocodec.bitpack import BitWriter  # noqa: E402
from mocodec.codecs.rma_reference import decode_keys  # noqa: E402
from mocodec.container import read_summary  # noqa: E402

ASSETS = {
    "1cm": Path("/work/main/bench/results/assets/rma_1cm_796bbeadd2_72a1863447.mcd"),
    "0.02cm": Path("/work/main/bench/results/assets/rma_0.02cm_796bbeadd2_72a1863447.mcd"),
}
# Issue 15's disk targets: 1.15 x the entropy-coded format 1 asset (whole asset bytes).
TARGETS = {"1cm": 351_955, "0.02cm": 2_663_455}
V2_DESC = {1: 28, 2: 40, 3: 20, 4: 20}
DIMS = {1: 3, 2: 4, 3: 3, 4: 3}
# A v3 descriptor is the v2 one (kind, flags, step, anchor bits, reference, axis) with the
# block fields instead of the group fields: 4 bytes more (block shift, cell shift, width bits,
# offset bits, per-component knot shifts, the row's bit count).
V3_DESC_EXTRA = 4
PREDICTORS = ("for", "knot", "prev")  # the prototype's predictor codes
WIDTH_BITS = 5  # a record field's width, 0 ... 31 (no escapes)
BLOCK_SHIFTS = (3, 4, 5, 6, 7, 8)
MAX_RECORD_BITS = 57  # one unaligned 64-bit load reads a record at any bit


@dataclass
class Track:
    """One animated track: its v2 descriptor fields and its keys."""

    kind: int
    d: int
    split: bool
    frame_count: int
    frames: np.ndarray  # (K,) int64
    q: np.ndarray  # (K, d) int64 lattice integers
    abits: list[int]
    desc: bytes  # the v2 descriptor bytes (step, reference, axis are reused as they are)
    node: int = 0
    slot: int = 0  # 0 rotation, 1 translation, 2 scale


@dataclass
class Clip:
    frame_count: int
    v2_size: int
    fixed_bytes: int  # header, node modes, constants: what v3 keeps as it is
    tracks: list[Track] = field(default_factory=list)
    v2_parts: dict[str, int] = field(default_factory=dict)  # where the v2 payload's bytes go


def load_asset(path: Path) -> tuple[int, list[Clip]]:
    """The asset's bytes outside its RMAL payloads (container, other sections, the section
    header, end padding), and every clip's keys (in payload order)."""
    data = path.read_bytes()
    summary = read_summary(data)
    _name, _version, off, _size = next(s for s in summary.sections if s[0] == "RMAL")
    count = struct.unpack_from("<I", data, off)[0]
    pos = off + 16
    clips = []
    for _ in range(count):
        psize = struct.unpack_from("<I", data, pos)[0]
        payload = data[pos:pos + psize]
        header, descs = decode_keys(payload)
        nodes, nconst = header["nodes"], len(header["consts"])
        fixed = 32 + (nodes + 3) // 4 * 4 + 4 * nconst
        clip = Clip(header["frames"], psize, fixed)
        parts = dict(header_modes_constants_descriptors=descs[0]["parts"]["bitmap"] if descs else psize,
                     unary=0, rank=0, places=0, group_table=0, records=0)
        for t in descs:
            pr = t["parts"]
            parts["unary"] += pr["rank"] - pr["bitmap"]
            parts["rank"] += pr["in_cell"] - pr["rank"]
            parts["places"] += pr["table"] - pr["in_cell"]
            parts["group_table"] += pr["data"] - pr["table"]
            parts["records"] += t["data_bytes"]
        parts["end_padding"] = psize - sum(parts.values())
        clip.v2_parts = parts
        dpos = fixed
        slots = [(i, m) for i in range(nodes) for m in range(3) if (header["modes"][i] >> (2 * m)) & 3 == 2]
        for t, (node, slot) in zip(descs, slots):
            dsize = V2_DESC[t["kind"]]
            clip.tracks.append(Track(t["kind"], t["d"], t["split"], header["frames"], t["frames"].astype(np.int64),
                                     t["q"].astype(np.int64), list(t["abits"][:t["d"]]), payload[dpos:dpos + dsize],
                                     node, slot))
            dpos += dsize
        clips.append(clip)
        pos += psize
    return len(data) - sum(c.v2_size for c in clips), clips  # every byte outside the payloads


def signed_width(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Bits of the smallest two's complement field holding every value in [lo, hi] (0 when
    both are 0)."""
    need = np.maximum(hi, -lo - 1)
    w = np.where(need > 0, np.floor(np.log2(np.maximum(need, 1))).astype(np.int64) + 2, 1)
    return np.where((lo == 0) & (hi == 0), 0, w)


def unsigned_width(span: np.ndarray) -> np.ndarray:
    return np.where(span > 0, np.floor(np.log2(np.maximum(span, 1))).astype(np.int64) + 1, 0)


def bits_for(n: int) -> int:
    return max(1, int(n).bit_length())


def knot_fit(frames: np.ndarray, q: np.ndarray, b: int, blocks: int) -> np.ndarray:
    """Least-squares linear spline with knots at frames j * 2^b (j = 0 ... blocks) through the
    keys, (blocks + 1, d) floats; a small pull towards the neighbours' mean keeps knots that no
    key constrains defined."""
    from scipy.linalg import solve_banded

    j = frames >> b
    u = (frames - (j << b)) / (1 << b)
    n = blocks + 1
    w0, w1 = 1 - u, u
    diag = np.bincount(j, w0 * w0, n) + np.bincount(j + 1, w1 * w1, n)
    off = np.bincount(j, w0 * w1, n)[:-1]
    rhs = np.zeros((n, q.shape[1]))
    np.add.at(rhs, j, w0[:, None] * q)
    np.add.at(rhs, j + 1, w1[:, None] * q)
    lam = 1e-6
    diag[:-1] += lam
    diag[1:] += lam
    off = off - lam
    ab = np.zeros((3, n))
    ab[0, 1:] = off
    ab[1] = diag + 1e-9
    ab[2, :-1] = off
    return solve_banded((1, 1), ab, rhs)


class PackedSize:
    """A track's bytes in a v3 payload: its row table and its data area, each padded to 4."""

    rows: int
    row_bits: int
    data_bits: int

    @property
    def table_bytes(self) -> int:
        return 4 * ((self.rows * self.row_bits + 31) // 32)

    @property
    def data_bytes(self) -> int:
        return 4 * ((self.data_bits + 31) // 32)

    @property
    def bytes(self) -> int:
        return self.table_bytes + self.data_bytes


@dataclass
class BlockLayout(PackedSize):
    """One track in the frame-block layout: everything the writer packs, and its bytes."""

    b: int
    tmode: int  # 0 mask, 1 gaps
    pred: str  # "for", "knot" or "prev"
    kshift: list[int]  # per component: anchors are multiples of 2^k
    abits: list[int]  # bits of each stored anchor (anchor >> k, two's complement)
    nbits: int
    offset_bits: int
    rows: int
    row_bits: int
    counts: np.ndarray  # (blocks,) keys per block
    gap_widths: np.ndarray  # (blocks,) (gaps mode)
    gaps: np.ndarray  # (K,) gap fields (gaps mode)
    widths: np.ndarray  # (blocks, d)
    anchors: np.ndarray  # (rows, d) anchors (multiples of 2^k)
    residuals: np.ndarray  # (K, d) field values
    block_of_key: np.ndarray
    offsets: np.ndarray  # (rows,) data bit offset per row (a knot layout's last row: the end)
    data_bits: int
    time_bits: int
    value_bits: int


def _runs(j: np.ndarray, blocks: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    counts = np.bincount(j, minlength=blocks)
    nonempty = np.flatnonzero(counts)
    return counts, nonempty, np.searchsorted(j, nonempty)


def key_times(frames: np.ndarray, b: int, blocks: int, tmode: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per block the bits of its key times, the gap width (gaps mode) and the gap fields."""
    j = frames >> b
    counts, nonempty, starts = _runs(j, blocks)
    o = frames - (j << b)
    gaps = np.diff(o, prepend=0) - 1
    first = np.zeros(len(j), dtype=bool)
    first[starts] = True
    gaps[first] = o[first]
    gw = np.zeros(blocks, dtype=np.int64)
    if tmode == 0:
        return np.where(counts > 0, 1 << b, 0), gw, gaps
    gw[nonempty] = unsigned_width(np.maximum.reduceat(gaps, starts))
    return counts * gw, gw, gaps


def block_layout(t: Track, b: int, pred: str, tmode: int, kmax: int = 10, fit: np.ndarray | None = None) -> BlockLayout:
    """The frame-block layout of a track at block shift b with time mode ``tmode`` and predictor
    ``pred``, each component's anchor lattice 2^k chosen for the fewest bits."""
    F, d = t.frame_count, t.d
    frames, q = t.frames, t.q
    blocks = int((F - 1) >> b) + 1
    j = frames >> b
    counts, nonempty, starts = _runs(j, blocks)
    tbits, gw, gaps = key_times(frames, b, blocks, tmode)
    if pred == "knot" and fit is None:
        fit = knot_fit(frames, q.astype(np.float64), b, blocks)
    off = frames - (j << b)
    records = counts - (counts > 0) if pred == "prev" else counts  # prev: the first key is the anchor
    widths_all, anchors_all, res_all, abits_all, kshift = [], [], [], [], []
    for c in range(d):
        cand = None
        for k in range(0, kmax + 1):
            w = np.zeros(blocks, dtype=np.int64)
            if pred == "knot":
                A = np.round(fit[:, c] / (1 << k)).astype(np.int64) << k
                r = q[:, c] - (A[j] + (((A[j + 1] - A[j]) * off) >> b))
                w[nonempty] = signed_width(np.minimum.reduceat(r, starts), np.maximum.reduceat(r, starts))
                fieldv = r & ((1 << w[j]) - 1)
            elif pred == "prev":  # the block's first key whole, each next one from the one before
                if k > 0:
                    break
                A = np.zeros(blocks, dtype=np.int64)
                A[nonempty] = q[starts, c]
                r = np.diff(q[:, c], prepend=q[0, c])
                r[starts] = 0
                w[nonempty] = signed_width(np.minimum.reduceat(r, starts), np.maximum.reduceat(r, starts))
                fieldv = r & ((1 << w[j]) - 1)
            else:
                A = np.zeros(blocks, dtype=np.int64)
                A[nonempty] = (np.minimum.reduceat(q[:, c], starts) >> k) << k
                w[nonempty] = unsigned_width(np.maximum.reduceat(q[:, c], starts) - A[nonempty])
                fieldv = q[:, c] - A[j]
            stored = A >> k
            abits = max(1, int(signed_width(np.array([stored.min()]), np.array([stored.max()]))[0]))
            bits = int((records * w).sum()) + len(A) * abits
            if cand is None or bits < cand[0]:
                cand = (bits, k, w, A, fieldv, abits)
            if k > 0 and w.max(initial=0) == 0:
                break
        _, k, w, A, fieldv, abits = cand
        kshift.append(k)
        widths_all.append(w)
        anchors_all.append(A)
        res_all.append(fieldv)
        abits_all.append(abits)
    widths = np.stack(widths_all, 1)
    value_bits = int((records * widths.sum(1)).sum())
    block_bits = tbits + records * widths.sum(1)
    offsets = np.concatenate([[0], np.cumsum(block_bits)])
    data_bits = int(offsets[-1])
    rows = blocks + 1 if pred == "knot" else blocks
    nbits = bits_for(int(counts.max()))
    offset_bits = bits_for(data_bits)
    row_bits = nbits + 4 * tmode + offset_bits + WIDTH_BITS * d + sum(abits_all)
    return BlockLayout(b, tmode, pred, kshift, abits_all, nbits, offset_bits, rows, row_bits, counts, gw, gaps,
                       widths, np.stack(anchors_all, 1), np.stack(res_all, 1), j, offsets[:rows], data_bits,
                       int(tbits.sum()), value_bits)


def prev_bits(t: Track, b: int, tmode: int) -> int:
    """Bits of the ``prev`` reference at block shift b: the FB rows and key times, each
    block's first key its anchor, every other key its difference from the one before at the
    block's width."""
    F, d = t.frame_count, t.d
    blocks = int((F - 1) >> b) + 1
    j = t.frames >> b
    counts, nonempty, starts = _runs(j, blocks)
    tbits, _, _ = key_times(t.frames, b, blocks, tmode)
    dq = np.diff(t.q, axis=0, prepend=t.q[:1])
    dq[starts] = 0
    total = int(tbits.sum())
    for c in range(d):
        w = np.zeros(blocks, dtype=np.int64)
        w[nonempty] = signed_width(np.minimum.reduceat(dq[:, c], starts), np.maximum.reduceat(dq[:, c], starts))
        total += int(((counts - 1).clip(0) * w).sum())
    row = bits_for(int(counts.max())) + 4 * tmode + bits_for(total) + WIDTH_BITS * d + sum(t.abits)
    return 8 * 4 * ((blocks * row + 31) // 32) + 8 * 4 * ((total + 31) // 32)


def entropy_bits(t: Track) -> float:
    """A floor for a coder that reads keys in order: per track, the zero-order entropy of each
    component's key-to-key difference and of the frame gaps (each with its own histogram, the
    tables themselves not counted). Not a layout: what an entropy coder of format 1's kind
    could approach, for comparison with the fixed-width layouts."""
    def h(v: np.ndarray) -> float:
        if v.size == 0:
            return 0.0
        _, n = np.unique(v, return_counts=True)
        p = n / v.size
        return float(-(n * np.log2(p)).sum())
    total = h(np.diff(t.frames))
    for c in range(t.d):
        total += h(np.diff(t.q[:, c]))
    return total


def best_layout(t: Track, preds: tuple[str, ...], shifts: tuple[int, ...] = BLOCK_SHIFTS,
                tmodes: tuple[int, ...] = (0, 1), max_record: int = MAX_RECORD_BITS) -> BlockLayout:
    """The fewest bytes over block shifts, time modes and predictors, among layouts whose
    records one 64-bit load reads (a mask: B <= 64)."""
    best = None
    for pred in preds:
        for b in shifts:
            if b > bits_for(t.frame_count) + 1:
                continue
            fit = knot_fit(t.frames, t.q.astype(np.float64), b, int((t.frame_count - 1) >> b) + 1) if pred == "knot" else None
            for tm in tmodes:
                if tm == 0 and b > 6:
                    continue
                L = block_layout(t, b, pred, tm, fit=fit)
                if L.widths.sum(1).max(initial=0) > max_record:
                    continue
                if best is None or L.bytes < best.bytes:
                    best = L
    assert best is not None
    return best


def payload_bytes(clip: Clip, track_bytes: list[int]) -> int:
    """A v3 payload: the v2 header, modes and constants as they are, v3 descriptors, padding
    to 4, the tracks' rows and records, 8 zero bytes (64-bit loads), aligned to 4."""
    desc = sum(V2_DESC[t.kind] + V3_DESC_EXTRA for t in clip.tracks)
    at = (clip.fixed_bytes + desc + 3) // 4 * 4 + sum(track_bytes)
    return (at + 8 + 3) // 4 * 4


def tally(name: str, clips: list[Clip], prefix: int, choose, parts_of, label) -> dict:
    """Asset bytes of a candidate whose layout of a track is ``choose(t)``, and where they go:
    ``parts_of(L)`` a track's parts in bits (rows and head in bytes), ``label(L)`` its choice."""
    total = prefix
    parts: dict[str, int] = {}
    choice: dict[str, int] = {}
    layouts = []
    for clip in clips:
        ls = [choose(t) for t in clip.tracks]
        layouts.append(ls)
        p = payload_bytes(clip, [L.bytes for L in ls])
        total += p
        parts["rows"] = parts.get("rows", 0) + sum(L.table_bytes for L in ls)
        clip_bits: dict[str, int] = {}
        for L in ls:
            for k, v in parts_of(L).items():
                clip_bits[k] = clip_bits.get(k, 0) + v
            choice[label(L)] = choice.get(label(L), 0) + 1
        for k, v in clip_bits.items():  # whole bytes per clip
            parts[k] = parts.get(k, 0) + v // 8
        parts["head"] = parts.get("head", 0) + p - sum(L.bytes for L in ls)
    return dict(candidate=name, asset_bytes=total, **parts,
                choices=dict(sorted(choice.items(), key=lambda kv: -kv[1])[:6]), layouts=layouts)


def evaluate(name: str, clips: list[Clip], prefix: int, preds: tuple[str, ...], **kw: object) -> dict:
    """Asset bytes of the candidate and where they go."""
    return tally(name, clips, prefix, lambda t: best_layout(t, preds, **kw),  # type: ignore[arg-type]
                 lambda L: dict(times=L.time_bits, values=L.value_bits),
                 lambda L: f"{L.pred} B={1 << L.b} {('mask', 'gaps')[L.tmode]}")


def track_record(t: Track, layout_bytes: tuple[int, int, int, int], words: tuple[int, ...], abits: list[int],
                 extra: list[int]) -> bytes:
    """A track's 68-byte record in the prototypes' input (bench/rmal_v3_shared.h, load): kind,
    d, split, slot, node and v2's step, reference, twist axis and angle step, and the layout's
    own fields (bytes 3, 4, 5, 7; six 32-bit words; four anchor widths; four more bytes)."""
    pad = lambda v: list(v) + [0] * (4 - len(v))  # noqa: E731
    b3, b4, b5, b7 = layout_bytes
    rec = struct.pack("<8B2H6I4B4B", t.kind, t.d, int(t.split), b3, b4, b5, t.slot, b7, t.node, 0, *words,
                      *pad(abits), *pad(extra))
    dd = t.desc + bytes(40 - len(t.desc))
    return rec + dd[12:16] + dd[20:40]  # step, reference, twist axis, angle step as v2 stores them


def write_file(path: Path, magic: bytes, clips: list[Clip], layouts: list[list], pack) -> None:
    """A prototype's input (bench/rmal_v3_shared.h, load), little-endian: ``magic``, clip count;
    per clip frame count, track count, blob bytes, one 68-byte record per track, then the blob:
    every track's row table and data area exactly as a v3 payload would hold them, then 8 zero
    bytes. ``pack(t, L)`` gives a track's table, data and record fields."""
    out = bytearray(struct.pack("<4sI", magic, len(clips)))
    for clip, ls in zip(clips, layouts):
        blob = bytearray()
        recs = bytearray()
        for t, L in zip(clip.tracks, ls):
            table, data, layout_bytes, words, abits, extra = pack(t, L)
            assert len(table) == L.table_bytes and len(data) == L.data_bytes
            words = (len(t.frames), *words, len(blob), len(blob) + len(table))
            recs += track_record(t, layout_bytes, words, abits, extra)
            blob += table + data
        blob += bytes(8)
        out += struct.pack("<III", clip.frame_count, len(clip.tracks), len(blob)) + recs + blob
    path.write_bytes(bytes(out))


def padded(w: BitWriter, nbytes: int) -> bytes:
    b = w.getvalue()
    return b + bytes(nbytes - len(b))


def fb_pack(t: Track, L: BlockLayout):
    """An FB track for bench/rmal_v3_proto.c ("V3P1")."""
    d = t.d
    blocks = len(L.counts)
    rw = BitWriter()
    for e in range(L.rows):
        inside = e < blocks
        rw.write(int(L.counts[e]) if inside else 0, L.nbits)
        if L.tmode:
            rw.write(int(L.gap_widths[e]) if inside else 0, 4)
        rw.write(int(L.offsets[e]), L.offset_bits)
        for c in range(d):
            rw.write(int(L.widths[e, c]) if inside else 0, WIDTH_BITS)
        for c in range(d):
            a = int(L.anchors[e, c]) >> L.kshift[c]
            rw.write(a & ((1 << L.abits[c]) - 1), L.abits[c])
    dw = BitWriter()
    o = t.frames - (L.block_of_key << L.b)
    k0 = 0
    for e in range(blocks):
        n = int(L.counts[e])
        if n == 0:
            continue
        sl = slice(k0, k0 + n)
        if L.tmode == 0:
            m = 0
            for x in o[sl]:
                m |= 1 << int(x)
            for h in range(0, 1 << L.b, 32):
                dw.write((m >> h) & 0xFFFFFFFF, min(32, (1 << L.b) - h))
        else:
            dw.write(L.gaps[sl], int(L.gap_widths[e]))
        w = L.widths[e]
        first = 1 if L.pred == "prev" else 0  # prev: the first key is the row's anchor
        dw.write(L.residuals[sl][first:].ravel(), np.tile(w, n - first))
        k0 += n
    assert dw.bit_length == L.data_bits, (dw.bit_length, L.data_bits)
    return (padded(rw, L.table_bytes), padded(dw, L.data_bytes), (L.b, L.tmode, PREDICTORS.index(L.pred), L.nbits),
            (L.rows, L.row_bits, L.offset_bits), L.abits, L.kshift)


def write_proto(path: Path, clips: list[Clip], layouts: list[list[BlockLayout]]) -> None:
    """The FB prototype's input (bench/rmal_v3_proto.c)."""
    write_file(path, b"V3P1", clips, layouts, fb_pack)


# ---------------------------------------------------------------- EB: entropy-coded blocks
EB_SHIFTS = (3, 4, 5, 6, 7)  # K = 8 ... 128 keys per block
EB_VARIANTS = ("interleaved", "gaps first", "two-way")
RICE_CAP = 16  # a quotient of 16 or more is an escape: 16 zeros, then the symbol in 32 raw bits
RICE_RAW = 32
RICE_KMAX = 31  # 5-bit parameters
PARAM_BITS = 5
HEAD_BITS_MAX = 57  # first frame, offset (and gap stream length): one 64-bit load; the parameters another


def zigzag(x: np.ndarray) -> np.ndarray:
    return np.where(x >= 0, 2 * x, -2 * x - 1)


def rice_bits(z: np.ndarray, k: np.ndarray) -> np.ndarray:
    q = z >> k
    return np.where(q < RICE_CAP, q + 1 + k, RICE_CAP + RICE_RAW)


def rice_fields(z: np.ndarray, k: np.ndarray) -> tuple[np.ndarray, ...]:
    """Each code as two fields, least significant bit first: the quotient q as q zeros closed by
    a one (a count of trailing zeros finds it), then the k low bits; an escape is RICE_CAP zeros,
    then the symbol in RICE_RAW bits. Returns (unary value, width, low value, width)."""
    q = z >> k
    esc = q >= RICE_CAP
    uv = np.where(esc, 0, np.left_shift(1, np.minimum(q, RICE_CAP - 1)))
    return uv, np.where(esc, RICE_CAP, q + 1), np.where(esc, z, z & ((1 << k) - 1)), np.where(esc, RICE_RAW, k)


@dataclass
class EBLayout(PackedSize):
    """One track in the entropy-coded-block layout (module docstring, "EB")."""

    rows: int
    row_bits: int
    data_bits: int
    shift: int  # K = 2^shift keys per block
    variant: int  # EB_VARIANTS index
    fbits: int
    obits: int
    lbits: int  # bits of the gap stream's length (gaps first) or the forward part's (two-way), else 0
    first_frames: np.ndarray  # (rows,)
    offsets: np.ndarray  # (rows,) bit offset of the block's data
    gap_len: np.ndarray  # (rows,) bits of the block's gap codes (gaps first) or forward part (two-way)
    anchors: np.ndarray  # (rows, d) the block's first key whole
    abits: list[int]
    params: np.ndarray  # (rows, d + 1) Rice parameters: gaps, then each component
    symbols: np.ndarray  # (n, d + 1) gap - 1 and zigzag differences of the keys after each block's first
    sym_block: np.ndarray  # (n,) block of each symbol
    gap_bits: int
    value_bits: int
    escapes: int


def eb_layout(t: Track, shift: int, variant: int = 0) -> EBLayout:
    """Blocks of K = 2^shift keys; per block and stream the Rice parameter with the fewest bits."""
    K, f, d = 1 << shift, t.frames, t.d
    N = len(f)
    rows = (N + K - 1) // K
    T = np.column_stack([np.diff(f) - 1, zigzag(np.diff(t.q, axis=0))])  # T[k]: from key k to key k + 1
    tix = np.arange(N - 1)
    blk_t, j = tix >> shift, tix & (K - 1)
    if variant == 2:  # two-way: keys 1 ... K/2 forward from the anchor, K/2 + 1 ... K - 1 backward from the
        # next row's anchor (the last block: all forward); the step from key K/2 to K/2 + 1 is not stored
        inner = blk_t < rows - 1
        back = inner & (j > K // 2)
        order = np.lexsort((np.where(back, -j, j), back, blk_t))
        sel = order[~(inner & (j == K // 2))[order]]
    else:
        sel = tix[j != K - 1]  # the step into a block's first key is its row's anchor
        back = np.zeros(N - 1, dtype=bool)
    S, blk, back = T[sel], blk_t[sel], back[sel]
    assert S.size == 0 or (S.min() >= 0 and S.max() < 1 << RICE_RAW)
    ks = np.arange(RICE_KMAX + 1)
    cost = rice_bits(S[:, None, :], ks[None, :, None])  # (n, k, stream)
    cs = np.concatenate([np.zeros((1,) + cost.shape[1:], np.int64), np.cumsum(cost, 0)])
    e = np.arange(rows)
    per = cs[np.searchsorted(blk, e, "right")] - cs[np.searchsorted(blk, e)]  # (rows, k, stream)
    params = per.argmin(1)
    bits = np.take_along_axis(per, params[:, None, :], 1)[:, 0, :]
    block_bits = bits.sum(1)
    offsets = np.concatenate([[0], np.cumsum(block_bits)])[:-1]
    data_bits = int(block_bits.sum())
    anchors = t.q[::K]
    for c in range(d):  # the anchor is a key whole: v2's anchor width holds it
        lim = 1 << (t.abits[c] - 1)
        assert -lim <= anchors[:, c].min() and anchors[:, c].max() < lim, (c, t.abits[c])
    fbits, obits = bits_for(t.frame_count - 1), bits_for(data_bits)
    if variant == 2:  # the row says where the backward part starts: the forward part's length
        fwd = rice_bits(S, params[blk]).sum(1) if S.size else np.zeros(0, np.int64)
        part = np.bincount(blk[~back], fwd[~back], minlength=rows).astype(np.int64)
    else:
        part = bits[:, 0]  # gaps first: the gap codes' length
    lbits = bits_for(int(part.max(initial=0))) if variant else 0
    assert fbits + obits + lbits <= HEAD_BITS_MAX
    row_bits = fbits + obits + lbits + PARAM_BITS * (d + 1) + sum(t.abits[:d])
    esc = int((S >> params[blk] >= RICE_CAP).sum()) if S.size else 0
    return EBLayout(rows, row_bits, data_bits, shift, variant, fbits, obits, lbits, f[::K], offsets, part,
                    anchors, list(t.abits[:d]), params, S, blk, int(bits[:, 0].sum()), int(bits[:, 1:].sum()), esc)


def best_eb(t: Track, shifts: tuple[int, ...], variant: int) -> EBLayout:
    return min((eb_layout(t, b, variant) for b in shifts), key=lambda L: L.bytes)


def eb_pack(t: Track, L: EBLayout):
    """An EB track for bench/rmal_v3_eb.c ("V3E1"). Row: first frame, data offset, (gap stream
    length,) Rice parameters (gaps, then each component), anchors. Data per block: interleaved,
    per key its gap code then each component's code; gaps first, every gap code of the block,
    then per key each component's code; two-way, interleaved, keys 1 ... K/2 then K ... K/2 + 2 (the
    steps into them from the key before)."""
    d = t.d
    cols = [L.first_frames, L.offsets] + ([L.gap_len] if L.lbits else []) + [L.params[:, c] for c in range(d + 1)]
    cols += [L.anchors[:, c] & ((1 << L.abits[c]) - 1) for c in range(d)]
    widths = [L.fbits, L.obits] + ([L.lbits] if L.lbits else []) + [PARAM_BITS] * (d + 1) + L.abits
    rw = BitWriter()
    rw.write(np.stack(cols, 1).ravel(), np.tile(widths, L.rows))
    uv, uw, lv, lw = rice_fields(L.symbols, L.params[L.sym_block])
    v, w = np.stack([uv, lv], -1), np.stack([uw, lw], -1)  # (n, stream, part)
    dw = BitWriter()
    if L.variant != 1:
        dw.write(v.ravel(), w.ravel())
    else:
        for e in range(L.rows):
            sl = L.sym_block == e
            dw.write(v[sl, 0].ravel(), w[sl, 0].ravel())
            dw.write(v[sl, 1:].ravel(), w[sl, 1:].ravel())
    assert dw.bit_length == L.data_bits, (dw.bit_length, L.data_bits)
    return (padded(rw, L.table_bytes), padded(dw, L.data_bytes), (L.shift, L.variant, 0, L.fbits),
            (L.rows, L.row_bits, L.obits), L.abits, [L.lbits])


def evaluate_eb(name: str, clips: list[Clip], prefix: int, shifts: tuple[int, ...], variant: int) -> dict:
    """Asset bytes of an EB candidate (the fewest bytes over ``shifts`` per track) and where
    they go (data padding: the data areas' padding to 4 bytes; escapes: a count, not bytes)."""
    return tally(name, clips, prefix, lambda t: best_eb(t, shifts, variant),
                 lambda L: dict(gaps=L.gap_bits, values=L.value_bits, data_padding=8 * L.data_bytes - L.data_bits,
                                escapes=8 * L.escapes),
                 lambda L: f"K={1 << L.shift}")


EB_CANDIDATES = (("EB K=8", (3,)), ("EB K=16", (4,)), ("EB K=32", (5,)), ("EB K=64", (6,)),
                 ("EB best K (8 ... 128)", EB_SHIFTS), ("EB best K (16, 32, 64)", (4, 5, 6)))


def eb_main(args: argparse.Namespace) -> None:
    """Bytes of the EB candidates on the dev assets, and the prototype's input files."""
    report = {}
    for tol in args.tolerances.split(","):
        path = ASSETS[tol]
        prefix, clips = load_asset(path)
        v2 = prefix + sum(c.v2_size for c in clips)
        assert v2 == path.stat().st_size, (v2, path.stat().st_size)
        keys = sum(len(t.frames) for c in clips for t in c.tracks)
        print(f"## {tol}: v2 {v2:,} B, {keys:,} keys, target {TARGETS[tol]:,} B", flush=True)
        rows = []
        for variant in (int(v) for v in args.eb_variants.split(",")):
            for name, shifts in EB_CANDIDATES:
                r = evaluate_eb(f"{name}, {EB_VARIANTS[variant]}", clips, prefix, shifts, variant)
                layouts = r.pop("layouts")
                if args.write:
                    args.write.mkdir(parents=True, exist_ok=True)
                    tag = name.split()[1].replace("=", "") if len(shifts) == 1 else f"best{len(shifts)}"
                    write_file(args.write / f"rma_{tol}_{tag}_v{variant}.v3e", b"V3E1", clips, layouts, eb_pack)
                r["vs_v2"] = r["asset_bytes"] / v2
                r["vs_target"] = r["asset_bytes"] / TARGETS[tol]
                rows.append(r)
                print(f"{r['candidate']:38s} {r['asset_bytes']:>10,} B  x{r['vs_v2']:.3f} v2  x{r['vs_target']:.3f} "
                      f"target  rows {r['rows']:,} gaps {r['gaps']:,} values {r['values']:,} data padding "
                      f"{r['data_padding']:,} head {r['head']:,} escapes {r['escapes']:,}  {r['choices']}", flush=True)
        report[tol] = dict(v2=v2, target=TARGETS[tol], keys=keys, outside_payloads=prefix, candidates=rows)
    if args.json:
        args.json.write_text(json.dumps(report, indent=1))


CANDIDATES: tuple[tuple[str, tuple[str, ...], dict], ...] = (
    ("FB for, mask|gaps", ("for",), {}),
    ("FB knot, mask|gaps", ("knot",), {}),
    ("FB knot|for, mask|gaps", ("knot", "for"), {}),
    ("FB for, gaps only", ("for",), dict(tmodes=(1,))),
    ("FB for, mask only", ("for",), dict(tmodes=(0,))),
    ("FB prev, mask|gaps", ("prev",), {}),
    ("FB knot|for|prev, mask|gaps", ("knot", "for", "prev"), {}),
)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--write", type=Path, help="write rma_<tolerance>.v3p for bench/rmal_v3_proto.c here")
    ap.add_argument("--proto", default="FB knot|for, mask|gaps", help="the candidate written for the prototype")
    ap.add_argument("--json", type=Path, help="write the figures here")
    ap.add_argument("--clips", type=int, default=0, help="only the first N clips (quick looks)")
    ap.add_argument("--max-block-shift", type=int, default=BLOCK_SHIFTS[-1],
                    help="largest block shift tried (a shorter key-time scan for more bytes)")
    ap.add_argument("--only-proto", action="store_true", help="evaluate only the --proto candidate")
    ap.add_argument("--tolerances", default="1cm,0.02cm", help="which dev assets (1cm, 0.02cm)")
    ap.add_argument("--eb", action="store_true", help="the entropy-coded block (EB) candidates instead; --write "
                    "writes rma_<tolerance>_<K>_v<variant>.v3e for bench/rmal_v3_eb.c")
    ap.add_argument("--eb-variants", default="0,1,2", help="EB code orders: 0 interleaved, 1 gaps first, 2 two-way")
    args = ap.parse_args()
    if args.eb:
        eb_main(args)
        return
    report = {}
    shifts = tuple(b for b in BLOCK_SHIFTS if b <= args.max_block_shift)
    for tol in args.tolerances.split(","):
        path = ASSETS[tol]
        prefix, clips = load_asset(path)
        v2 = prefix + sum(c.v2_size for c in clips)
        if args.clips:
            clips = clips[:args.clips]
            v2 = prefix + sum(c.v2_size for c in clips)
        else:
            assert v2 == path.stat().st_size, (v2, path.stat().st_size)
        keys = sum(len(t.frames) for c in clips for t in c.tracks)
        print(f"## {tol}: v2 {v2:,} B, {keys:,} keys, target {TARGETS[tol]:,} B", flush=True)
        v2_parts = {k: sum(c.v2_parts[k] for c in clips) for k in clips[0].v2_parts}
        print(f"v2 payload bytes by part (outside the payloads: {prefix:,}): {v2_parts}")
        rows = []
        for name, preds, kw in CANDIDATES:
            if args.only_proto and name != args.proto:
                continue
            r = evaluate(name, clips, prefix, preds, shifts=shifts, **kw)
            if name == args.proto and args.write:
                args.write.mkdir(parents=True, exist_ok=True)
                write_proto(args.write / f"rma_{tol}.v3p", clips, r["layouts"])
            r.pop("layouts")
            r["vs_v2"] = r["asset_bytes"] / v2
            r["vs_target"] = r["asset_bytes"] / TARGETS[tol]
            rows.append(r)
            print(f"{name:26s} {r['asset_bytes']:>10,} B  x{r['vs_v2']:.3f} v2  x{r['vs_target']:.3f} target  rows "
                  f"{r['rows']:,} times {r['times']:,} values {r['values']:,} head {r['head']:,}  {r['choices']}",
                  flush=True)
        if args.only_proto:
            report[tol] = dict(v2=v2, target=TARGETS[tol], keys=keys, max_block_shift=args.max_block_shift,
                               v2_parts=v2_parts, candidates=rows)
            continue
        ref = prefix
        for clip in clips:
            tb = [min(prev_bits(t, b, tm) for b in BLOCK_SHIFTS for tm in (0, 1)
                      if b <= bits_for(t.frame_count) + 1 and not (tm == 0 and b > 6)) // 8 for t in clip.tracks]
            ref += payload_bytes(clip, tb)
        floor = prefix + sum(payload_bytes(c, [0] * len(c.tracks)) for c in clips) + sum(
            entropy_bits(t) for c in clips for t in c.tracks) / 8
        print(f"{'entropy floor (in order)':26s} {floor:>12,.0f} B  x{floor / v2:.3f} v2  x{floor / TARGETS[tol]:.3f} target")
        rows.append(dict(candidate="entropy floor (in order)", asset_bytes=int(floor), vs_v2=floor / v2,
                         vs_target=floor / TARGETS[tol]))
        print(f"{'FB prev (size reference)':26s} {ref:>10,} B  x{ref / v2:.3f} v2  x{ref / TARGETS[tol]:.3f} target")
        rows.append(dict(candidate="FB prev (size reference)", asset_bytes=ref, vs_v2=ref / v2, vs_target=ref / TARGETS[tol]))
        report[tol] = dict(v2=v2, target=TARGETS[tol], keys=keys, v2_parts=v2_parts, candidates=rows)
    if args.json:
        args.json.write_text(json.dumps(report, indent=1))


if __name__ == "__main__":
    main()
