"""A reference decoder of the ``SPLN`` payload written from docs/FORMAT.md alone, in float64.

For study and for tests only: it checks the format document and the C runtime against each
other (they must agree to float32 precision). The runtime stays the judge of every error the
encoder reports.
"""
from __future__ import annotations

import struct

import numpy as np

from .. import rotations as R
from ..bitpack import read_bits
from ..curves import catmull_rom
from ..motion import Skeleton

_DESC_SIZE = {1: 36, 2: 56, 3: 28}


def track_rotation(kind: int, ref: np.ndarray, axis: np.ndarray | None, v: np.ndarray) -> np.ndarray:
    """Rotations a track's values mean (docs/FORMAT.md, SPLN "What a track value means")."""
    if kind == 1:
        return R.quat_multiply(ref, R.quat_from_mrp(v))
    tw = R.quat_from_axis_angle(axis, v[:, 0])
    return R.quat_multiply(tw, R.quat_multiply(ref, R.quat_from_mrp(v[:, 1:])))


def decode_payload(payload: bytes, skeleton: Skeleton, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Local rotations (len(x), N, 4) and translations (len(x), N, 3) at frame positions x."""
    frames, nodes, tracks, shift = struct.unpack_from("<IIIB", payload, 0)
    blocks, nconst, stream_size, desc_bytes = struct.unpack_from("<IIII", payload, 16)
    pos = 32
    node_rows = [struct.unpack_from("<BBHHH", payload, pos + 8 * i) for i in range(nodes)]
    pos += 8 * nodes
    consts = np.frombuffer(payload, dtype="<f4", count=nconst, offset=pos).astype(np.float64)
    pos += 4 * nconst
    descs = []
    for _ in range(tracks):
        kind = payload[pos]
        d = 4 if kind == 2 else 3
        bits = list(payload[pos + 1:pos + 1 + d])
        head = 8 if d == 4 else 4
        mins = np.frombuffer(payload, "<f4", d, pos + head).astype(np.float32)
        steps = np.frombuffer(payload, "<f4", d, pos + head + 4 * d).astype(np.float32)
        ref = axis = None
        if kind != 3:
            codes = np.frombuffer(payload, "<i2", 3, pos + head + 8 * d).astype(np.float64) / 32767.0
            ref = R.quat_from_mrp(codes)
            if kind == 2:
                a = np.frombuffer(payload, "<i2", 3, pos + head + 8 * d + 8).astype(np.float64)
                axis = a / np.linalg.norm(a)
        descs.append((kind, d, bits, mins, steps, ref, axis))
        pos += _DESC_SIZE[kind]
    table = np.frombuffer(payload, "<u4", blocks, pos)
    pos += 4 * blocks
    stream = payload[pos:pos + stream_size]

    # Walk every block: key frames and quantized values per track.
    block_len = 1 << shift
    starts = np.minimum(np.arange(blocks) << shift, frames - 1)
    key_frames: list[list[int]] = [[] for _ in range(tracks)]
    key_q: list[list[list[int]]] = [[] for _ in range(tracks)]
    for j in range(blocks):
        bit = int(table[j])
        last = j == blocks - 1
        for u, (kind, d, bits, *_rest) in enumerate(descs):
            offsets: list[int] = []
            if not last:
                n = read_bits(stream, bit, shift)
                bit += shift
                if n * shift < block_len - 1:
                    for _ in range(n):
                        offsets.append(read_bits(stream, bit, shift))
                        bit += shift
                else:
                    mask = read_bits(stream, bit, block_len - 1)
                    bit += block_len - 1
                    offsets = [k + 1 for k in range(block_len - 1) if mask >> k & 1]
            for off in [0] + offsets:
                key_frames[u].append(int(starts[j]) + off)
                vals = []
                for c in range(d):
                    vals.append(read_bits(stream, bit, bits[c]))
                    bit += bits[c]
                key_q[u].append(vals)

    x = np.asarray(x, dtype=np.float64)
    values = []
    for u, (kind, d, bits, mins, steps, ref, axis) in enumerate(descs):
        q = np.asarray(key_q[u], dtype=np.float32)
        v = (mins + q * steps).astype(np.float64)  # binary32 dequantisation, as specified
        values.append(catmull_rom(np.asarray(key_frames[u]), v, x))

    n = len(x)
    rot = np.broadcast_to(skeleton.rest_rotations.astype(np.float32).astype(np.float64), (n, nodes, 4)).copy()
    trans = np.broadcast_to(skeleton.offsets.astype(np.float32).astype(np.float64), (n, nodes, 3)).copy()
    for i, (rm, tm, ri, ti, _) in enumerate(node_rows):
        if rm == 1:
            rot[:, i] = consts[ri:ri + 4]
        elif rm == 2:
            kind, _, _, _, _, ref, axis = descs[ri]
            rot[:, i] = track_rotation(kind, ref, axis, values[ri])
        if tm == 1:
            trans[:, i] = consts[ti:ti + 3]
        elif tm == 2:
            trans[:, i] = values[ti]
    return rot, trans
