"""A track of the ``RMAL`` version 4 payload (docs/FORMAT.md): keys in Rice-coded blocks.

A track's keys come in blocks of ``2**shift`` keys. A block's row, at a fixed bit stride,
holds its first key whole (frame and lattice integers), the bit offset of its codes and a field
per stream (frame gaps, then each component): its Rice parameter, or that the block's values of
the stream are all zero and have no codes, and for a component its predictor. Every later key
of the block is its frame gap less one and, per component, the zigzag of its difference from the
key before less the prediction (0, or with the slope predictor the difference before, 0 at the
block's first key), Rice coded. Random access reads one row and decodes on from it, so the
block size trades bytes for random-access time (bench/rma_layout_curve.py measures the curve).
"""
from __future__ import annotations

import struct

import numpy as np

from ..bitpack import fields_bytes

RICE_CAP = 16  # a quotient of 16 or more is an escape: 16 zero bits, then the value in 32 bits
RICE_RAW = 32
PARAM_BITS = 5  # a row's field per stream
MAX_K = 14  # Rice parameters 0 ... 14; a field's k of 15 marks a stream of zeros
ZERO_STREAM = 15
SLOPE = 16  # a component field's bit 4: the slope predictor
MAX_BLOCK_SHIFT = 6  # blocks of 2 ... 64 keys
DEFAULT_BLOCK_KEYS = 32
MAX_DATA_BYTES = (1 << 29) - 16  # every bit position of a track's codes fits 32 bits


def zigzag(v: np.ndarray) -> np.ndarray:
    """Signed to unsigned, small magnitudes first: 0, -1, 1, -2 ... -> 0, 1, 2, 3 ..."""
    v = np.asarray(v, dtype=np.int64)
    return np.where(v >= 0, 2 * v, -2 * v - 1)


def rice_lengths(z: np.ndarray, k: "int | np.ndarray") -> np.ndarray:
    """Bits of each value's Rice code with parameter ``k`` (escapes included)."""
    q = z >> k
    return np.where(q < RICE_CAP, q + 1 + k, RICE_CAP + RICE_RAW)


def rice_fields(z: np.ndarray, k: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Each code as two fields, least significant bit first: the quotient as that many zeros
    closed by a one, then the k low bits; an escape is 16 zeros, then the value in 32 bits.
    Returns (unary values, their widths, low values, their widths)."""
    q = z >> k
    esc = q >= RICE_CAP
    unary = np.where(esc, 0, np.left_shift(np.int64(1), np.minimum(q, RICE_CAP - 1)))
    return (unary, np.where(esc, RICE_CAP, q + 1), np.where(esc, z, z & ((np.int64(1) << k) - 1)),
            np.where(esc, RICE_RAW, k))


def best_parameters(z: np.ndarray, block: np.ndarray, blocks: int,
                    max_k: int = MAX_K) -> tuple[np.ndarray, np.ndarray]:
    """Per block and stream the Rice parameter (0 ... ``max_k``) with the fewest bits (the
    smallest on a tie) for values ``z`` (n, streams) in blocks ``block`` (n,), ascending;
    returns (parameters (blocks, streams), bits (blocks, streams))."""
    streams = z.shape[1]
    params = np.zeros((blocks, streams), dtype=np.int64)
    best = np.zeros((blocks, streams), dtype=np.int64)
    if len(z) == 0:
        return params, best
    top = min(max_k, int(z.max()).bit_length())  # past the widest value's bits every k only costs more
    for k in range(top + 1):
        bits = np.stack([np.bincount(block, rice_lengths(z[:, s], k), blocks) for s in range(streams)], 1)
        bits = bits.astype(np.int64)
        better = bits < best if k else np.ones_like(bits, dtype=bool)
        params = np.where(better, k, params)
        best = np.where(better, bits, best)
    return params, best


def bits_for(n: int) -> int:
    """Bits that hold every value 0 ... n (at least 1), as the runtime computes them."""
    return max(1, int(n).bit_length())


def _streams(z: np.ndarray, block: np.ndarray, rows: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per block and stream of values ``z`` (n, streams): (Rice parameter, bits, all zero), a
    stream of zeros costing no bits; a block with no codes is not a stream of zeros."""
    params, bits = best_parameters(z, block, rows)
    nonzero = np.zeros(params.shape, dtype=np.int64)
    np.add.at(nonzero, block, z != 0)
    zero = (nonzero == 0) & (np.bincount(block, minlength=rows) > 0)[:, None]
    return params, np.where(zero, 0, bits), zero


def track_body(frames: np.ndarray, q: np.ndarray, abits: np.ndarray, frame_count: int,
               shift: int) -> tuple[int, int, bytes, bytes]:
    """(offset_bits, data_bytes, row table, data area) of a track's keys (checked by the caller:
    frames increasing from 0 to the last frame, ``|q| < 2**30``, anchors within ``abits``) in
    blocks of ``2**shift`` keys. Per block and component the predictor with the fewer bits (the
    previous key's on a tie)."""
    if not 1 <= shift <= MAX_BLOCK_SHIFT:
        raise ValueError(f"block shift must be 1 ... {MAX_BLOCK_SHIFT}")
    K, d = q.shape
    B = 1 << shift
    rows = (K + B - 1) // B
    into = np.arange(1, K)  # step j - 1 goes into key j
    coded = (into & (B - 1)) != 0  # the step into a block's first key is its row
    block = into[coded] >> shift
    diff = np.diff(q, axis=0)
    before = np.zeros_like(diff)  # the difference into the key before; 0 at a block's first key
    before[1:] = np.where(coded[:-1, None], diff[:-1], 0)
    gaps = (np.diff(frames) - 1)[coded, None]
    z_prev, z_slope = zigzag(diff)[coded], zigzag(diff - before)[coded]
    k_gap, bits_gap, zero_gap = _streams(gaps, block, rows)
    k_prev, bits_prev, zero_prev = _streams(z_prev, block, rows)
    k_slope, bits_slope, zero_slope = _streams(z_slope, block, rows)
    wide = np.zeros((rows, d), dtype=bool)  # a slope residual past an escape's 32 bits
    np.logical_or.at(wide, block, z_slope >= 1 << RICE_RAW)
    slope = (bits_slope < bits_prev) & ~wide
    k = np.concatenate([k_gap, np.where(slope, k_slope, k_prev)], axis=1)
    zero = np.concatenate([zero_gap, np.where(slope, zero_slope, zero_prev)], axis=1)
    bits = np.concatenate([bits_gap, np.where(slope, bits_slope, bits_prev)], axis=1)
    z = np.concatenate([gaps, np.where(slope[block], z_slope, z_prev)], axis=1)
    assert z.size == 0 or z.max() < 1 << RICE_RAW
    fields = np.where(zero, ZERO_STREAM, k)
    fields[:, 1:] |= np.where(slope, SLOPE, 0)
    block_bits = bits.sum(axis=1)
    offsets = np.concatenate(([0], np.cumsum(block_bits)))[:-1]
    total = int(block_bits.sum())
    offset_bits = bits_for(total)
    one = np.int64(1)
    cols = [frames[::B, None], offsets[:, None], fields, q[::B] & ((one << abits) - 1)]
    widths = [bits_for(frame_count - 1), offset_bits] + [PARAM_BITS] * (d + 1) + [int(a) for a in abits]
    table = fields_bytes(np.concatenate(cols, axis=1).ravel(), np.tile(widths, rows))
    unary, uw, low, lw = rice_fields(z, k[block])
    none = zero[block]  # a stream of zeros has no codes: fields of width 0, value 0
    unary, uw, low, lw = (np.where(none, 0, a) for a in (unary, uw, low, lw))
    data = fields_bytes(np.stack([unary, low], -1).ravel(), np.stack([uw, lw], -1).ravel())
    assert len(data) == (total + 31) // 32 * 4
    if len(data) > MAX_DATA_BYTES:
        raise ValueError(f"a track's codes take {len(data):,} bytes (the format allows {MAX_DATA_BYTES:,})")
    return offset_bits, len(data), table, data


def descriptor_head(kind: int, split: bool, shift: int, offset_bits: int, keys: int, data_bytes: int,
                    step: float) -> bytes:
    """The first 16 bytes of a version 3 or 4 track descriptor."""
    return struct.pack("<BBBBIIf", kind, (1 if split else 0) | shift << 1, offset_bits, 0, keys, data_bytes, step)
