"""Codec ``spline``: per-track Catmull-Rom keys with adaptive control points and range-aware
quantization (seed 003 §5.1-5.2 applied per joint, before PCA), bit-packed as docs/FORMAT.md's
``SPLN`` payload.

The fitting is the key-frame engine's (:mod:`mocodec.keyframes`: compensated top-down fitting,
per-track budgets, repair through the C runtime); this module is the storage: every block of
2**block_shift frames starts with a key of every track, so the runtime samples the asset's own
bytes with no resident memory.
"""
from __future__ import annotations

import struct
from dataclasses import dataclass

import numpy as np

from ..bitpack import BitWriter
from ..keyframes import DIMS, KIND_TWIST, KeyframeFitter, KeyframeSettings, Track, fit_clip, node_modes
from ..motion import Motion
from ..tolerance import ClipCheck
from . import ClipResult


@dataclass
class SplineSettings(KeyframeSettings):
    """Settings of the ``spline`` codec: those of :class:`~mocodec.keyframes.KeyframeSettings`
    (tolerance, quant_fraction, budget_scales, max_repairs, shell_cm) and

    Parameters
    ----------
    block_shift : int, default 5
        Blocks of 2**block_shift frames; every block start is a key of every track.
    """

    block_shift: int = 5


# ------------------------------------------------------------------------ serialization
# ------------------------------------------------------------------------ serialization
def _block_starts(frames: int, shift: int) -> np.ndarray:
    blocks = (frames - 1 + (1 << shift) - 1) // (1 << shift) + 1
    return np.minimum(np.arange(blocks, dtype=np.int64) << shift, frames - 1)




def serialize(motion: Motion, tracks: list[Track], shift: int) -> bytes:
    """The ``SPLN`` payload of a clip (docs/FORMAT.md)."""
    sk = motion.skeleton
    frames = motion.frame_count
    starts = _block_starts(frames, shift)
    nb = len(starts)
    rows, constants, animated = node_modes(motion, tracks)
    if any(row[2] for row in rows):  # the codec refuses animated scale before it fits
        raise ValueError("the SPLN payload has no scale tracks")
    node_rows = [struct.pack("<BBHHH", rm, tm, ri, ti, 0) for rm, tm, _, ri, ti, _ in rows]

    descs = []
    qvals = []
    for t in animated:
        d = DIMS[t.kind]
        qz = t.quantizer
        bits = [int(b) for b in qz.bits]
        head = struct.pack(f"<B{d}B", t.kind, *bits).ljust(8 if d == 4 else 4, b"\0")
        desc = head + struct.pack(f"<{d}f{d}f", *qz.minimum.tolist(), *qz.step.tolist())
        if t.is_rotation:
            desc += struct.pack("<3hH", *t.ref_codes.tolist(), 0)
        if t.kind == KIND_TWIST:
            desc += struct.pack("<3hH", *t.axis_codes.tolist(), 0)
        descs.append(desc)
        qvals.append(qz.encode(t.key_values).astype(np.uint64))

    stream, block_table = _pack_blocks(animated, qvals, starts, shift)


    desc_bytes = b"".join(descs)
    header = struct.pack("<IIIBBBBIIII", frames, sk.node_count, len(animated), shift, 0, 0, 0,
                         nb, len(constants), len(stream), len(desc_bytes))
    return b"".join([
        header,
        b"".join(node_rows),
        np.asarray(constants, dtype="<f4").tobytes(),
        desc_bytes,
        np.asarray(block_table, dtype="<u4").tobytes(),
        stream,
    ])


def _pack_blocks(tracks: list[Track], qvals: list[np.ndarray], starts: np.ndarray,
                 shift: int) -> tuple[bytes, list[int]]:
    """The bit stream and block table. Fields are generated per track with numpy, tagged
    with (block, track, position) and put in stream order with one sort."""
    nb = len(starts)
    block_len = 1 << shift
    tags_block, tags_track, tags_pos, values, widths = [], [], [], [], []

    def emit(block, track, pos, vals, wids):
        tags_block.append(np.asarray(block, dtype=np.int64))
        tags_track.append(np.full(len(tags_block[-1]), track, dtype=np.int64))
        tags_pos.append(np.asarray(pos, dtype=np.int64))
        values.append(np.asarray(vals, dtype=np.uint64))
        widths.append(np.asarray(wids, dtype=np.int64))

    for u, (t, q) in enumerate(zip(tracks, qvals)):
        keys = t.keys
        d = q.shape[1]
        kblock = np.minimum(np.searchsorted(starts, keys, side="right") - 1, nb - 1)
        first = np.searchsorted(keys, starts)              # key index at each block start
        n = np.diff(first) - 1                             # extra keys of blocks 0 .. nb-2
        body = np.arange(nb - 1)
        emit(body, u, np.zeros(nb - 1), n, np.full(nb - 1, shift))
        extra = keys != starts[kblock]
        kidx = np.flatnonzero(extra)
        eb = kblock[extra]
        offs = keys[extra] - starts[eb]
        listed = n[eb] * shift < block_len - 1
        if listed.any():
            rank = kidx - first[eb]                        # 1-based index among the block's extras
            emit(eb[listed], u, rank[listed], offs[listed], np.full(int(listed.sum()), shift))
        mask_blocks = np.flatnonzero(n * shift >= block_len - 1)
        for j in mask_blocks:
            m = 0
            for o in offs[eb == j].tolist():
                m |= 1 << (o - 1)
            parts = list(range(0, block_len - 1, 32))
            emit(np.full(len(parts), j), u, 1 + np.arange(len(parts)),
                 [(m >> p) & ((1 << min(32, block_len - 1 - p)) - 1) for p in parts],
                 [min(32, block_len - 1 - p) for p in parts])
        # Values, key-major then component: position 100 + running index keeps them after times.
        vb = np.repeat(kblock, d)
        emit(vb, u, 100 + np.arange(q.size), q.ravel(), np.tile(t.quantizer.bits, len(keys)))
    if not tracks:
        return bytes(8), [0] * nb
    blk = np.concatenate(tags_block)
    order = np.lexsort((np.concatenate(tags_pos), np.concatenate(tags_track), blk))
    vals = np.concatenate(values)[order]
    wids = np.concatenate(widths)[order]
    blk = blk[order]
    w = BitWriter()
    w.write(vals, wids)
    ends = np.cumsum(wids)
    starts_bits = np.concatenate(([0], ends))[np.searchsorted(blk, np.arange(nb), side="left")]
    return w.getvalue(tail_bytes=8), [int(x) for x in starts_bits]


# ------------------------------------------------------------------------ encoding one clip
class SplineFitter(KeyframeFitter):
    """The key-frame engine on the SPLN block grid (key frames coded as they are)."""

    def mandatory_keys(self) -> np.ndarray:
        """The block starts of the SPLN layout."""
        return _block_starts(self.frames, self.settings.block_shift)

    def payload(self, tracks: list[Track]) -> bytes:
        return serialize(self.motion, tracks, self.settings.block_shift)


def encode_clip(motion: Motion, cm_per_unit: float, settings: SplineSettings,
                check: ClipCheck) -> ClipResult:
    """Encode one clip within the tolerance on every frame (``check``: payload -> error)."""
    return fit_clip(motion, cm_per_unit, settings, check, SplineFitter)
