"""A track of the ``RMAL`` version 3 payload (docs/FORMAT.md): keys in Rice-coded blocks.

A track's keys come in blocks of ``2**shift`` keys. A block's row, at a fixed bit stride,
holds its first key whole (frame and lattice integers), the bit offset of its codes and a Rice
parameter per stream (frame gaps, then each component); every later key of the block is its
frame gap less one and its zigzag differences from the key before, Rice coded. Random access
reads one row and decodes on from it, so the block size trades bytes for random-access time
(bench/rma_layout_curve.py measures the curve).
"""
from __future__ import annotations

import struct

import numpy as np

from ..bitpack import fields_bytes

RICE_CAP = 16  # a quotient of 16 or more is an escape: 16 zero bits, then the value in 32 bits
RICE_RAW = 32
PARAM_BITS = 5  # Rice parameters 0 ... 31
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


def best_parameters(z: np.ndarray, block: np.ndarray, blocks: int) -> tuple[np.ndarray, np.ndarray]:
    """Per block and stream the Rice parameter with the fewest bits (the smallest on a tie) for
    values ``z`` (n, streams) in blocks ``block`` (n,), ascending; returns (parameters
    (blocks, streams), bits (blocks, streams))."""
    streams = z.shape[1]
    params = np.zeros((blocks, streams), dtype=np.int64)
    best = np.zeros((blocks, streams), dtype=np.int64)
    if len(z) == 0:
        return params, best
    top = min(31, int(z.max()).bit_length())  # past the widest value's bits every k only costs more
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


def track_body(frames: np.ndarray, q: np.ndarray, abits: np.ndarray, frame_count: int,
               shift: int) -> tuple[int, int, bytes, bytes]:
    """(offset_bits, data_bytes, row table, data area) of a track's keys (checked by the caller:
    frames increasing from 0 to the last frame, ``|q| < 2**30``, anchors within ``abits``) in
    blocks of ``2**shift`` keys."""
    if not 1 <= shift <= MAX_BLOCK_SHIFT:
        raise ValueError(f"block shift must be 1 ... {MAX_BLOCK_SHIFT}")
    K, d = q.shape
    B = 1 << shift
    rows = (K + B - 1) // B
    steps = np.column_stack([np.diff(frames) - 1, zigzag(np.diff(q, axis=0))])  # step j: key j to key j + 1
    into = np.arange(1, K)
    coded = (into & (B - 1)) != 0  # the step into a block's first key is its row
    z, block = steps[coded], into[coded] >> shift
    assert z.size == 0 or z.max() < 1 << RICE_RAW
    params, bits = best_parameters(z, block, rows)
    block_bits = bits.sum(axis=1)
    offsets = np.concatenate(([0], np.cumsum(block_bits)))[:-1]
    total = int(block_bits.sum())
    offset_bits = bits_for(total)
    one = np.int64(1)
    cols = [frames[::B, None], offsets[:, None], params, q[::B] & ((one << abits) - 1)]
    widths = [bits_for(frame_count - 1), offset_bits] + [PARAM_BITS] * (d + 1) + [int(a) for a in abits]
    table = fields_bytes(np.concatenate(cols, axis=1).ravel(), np.tile(widths, rows))
    unary, uw, low, lw = rice_fields(z, params[block])
    data = fields_bytes(np.stack([unary, low], -1).ravel(), np.stack([uw, lw], -1).ravel())
    assert len(data) == (total + 31) // 32 * 4
    if len(data) > MAX_DATA_BYTES:
        raise ValueError(f"a track's codes take {len(data):,} bytes (the format allows {MAX_DATA_BYTES:,})")
    return offset_bits, len(data), table, data


def descriptor_head(kind: int, split: bool, shift: int, offset_bits: int, keys: int, data_bytes: int,
                    step: float) -> bytes:
    """The first 16 bytes of a version 3 track descriptor."""
    return struct.pack("<BBBBIIf", kind, (1 if split else 0) | shift << 1, offset_bits, 0, keys, data_bytes, step)
