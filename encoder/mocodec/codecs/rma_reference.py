"""A reference decoder of the ``RMAL`` payload written from docs/FORMAT.md, in float64.

For tests only: it checks the format document and the C runtime against each other (they
must agree to float32 precision). The entropy streams are decoded with :mod:`mocodec.entropy`,
whose own tests check it against the format's coder specification.
"""
from __future__ import annotations

import struct

import numpy as np

from .. import rotations as R
from ..curves import catmull_rom
from ..entropy import entropy_decode
from ..motion import Skeleton
from .spline_reference import track_rotation

_DESC_SIZE = {1: 20, 2: 32, 3: 16}


def _values(residual: np.ndarray, frames: np.ndarray, predictor: int) -> np.ndarray:
    """Key lattice integers from their residuals, key by key as FORMAT.md states it."""
    q = np.zeros(residual.shape, dtype=np.int64)
    for i in range(len(q)):
        pred = q[i - 1] if i else 0
        if i >= 2 and predictor:
            num = (q[i - 1] - q[i - 2]) * (frames[i] - frames[i - 1]) * predictor
            den = 2 * (frames[i - 1] - frames[i - 2])
            pred = q[i - 1] + (2 * num + den) // (2 * den)
        q[i] = pred + residual[i]
    return q


def decode_payload(payload: bytes, skeleton: Skeleton, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Local rotations (len(x), N, 4) and translations (len(x), N, 3) at frame positions x."""
    size, frames, nodes, tracks, nconst, keys, _, gap_bytes = struct.unpack_from("<8I", payload)
    pos = 32
    modes = payload[pos:pos + nodes]
    pos += (nodes + 3) // 4 * 4
    consts = np.frombuffer(payload, "<f4", nconst, pos).astype(np.float64)
    pos += 4 * nconst
    descs = []
    for _ in range(tracks):
        kind = payload[pos]
        d = 4 if kind == 2 else 3
        at = 4 if kind == 3 else 8
        count, vbytes, shared = struct.unpack_from("<IIf", payload, pos + at)
        step = np.full(d, shared, dtype=np.float32)
        ref = axis = None
        if kind != 3:
            codes = np.frombuffer(payload, "<i2", 3, pos + 2).astype(np.float64) / 32767.0
            ref = R.quat_from_mrp(codes)
            if kind == 2:
                a = np.frombuffer(payload, "<i2", 3, pos + 20).astype(np.float64)
                axis = a / np.linalg.norm(a)
                step[0] = struct.unpack_from("<f", payload, pos + 28)[0]
        descs.append((kind, d, count, vbytes, step, ref, axis, payload[pos + 1]))
        pos += _DESC_SIZE[kind]
    interior = sum(max(count - 2, 0) for _, _, count, *_ in descs)
    gaps = entropy_decode(payload[pos:pos + gap_bytes], 2 * interior, 2).astype(np.int64).reshape(-1, 2)
    pos += gap_bytes
    x = np.asarray(x, dtype=np.float64)
    values, g = [], 0
    for kind, d, count, vbytes, step, _, _, byte1 in descs:
        grid, predictor = byte1 & 15, byte1 >> 4
        cells = gaps[g:g + max(count - 2, 0)]
        inner = grid * np.cumsum(cells[:, 0]) + cells[:, 1]
        g += max(count - 2, 0)
        frames_k = np.concatenate(([0], inner, [frames - 1] if count > 1 else []))
        q = _values(entropy_decode(payload[pos:pos + vbytes], count * d, d).reshape(count, d),
                    frames_k.astype(np.int64), predictor)
        pos += vbytes
        v = (q.astype(np.float32) * step).astype(np.float64)  # binary32 product, as specified
        values.append(catmull_rom(frames_k, v, x))
    n = len(x)
    rot = np.zeros((n, nodes, 4))
    rot[..., 3] = 1.0
    trans = np.broadcast_to(skeleton.offsets.astype(np.float32).astype(np.float64), (n, nodes, 3)).copy()
    track = ci = 0
    for i in range(nodes):
        rm, tm = modes[i] & 3, modes[i] >> 2 & 3
        if rm == 1:
            rot[:, i] = consts[ci:ci + 4]
            ci += 4
        elif rm == 2:
            kind, _, _, _, _, ref, axis, _ = descs[track]
            rot[:, i] = track_rotation(kind, ref, axis, values[track])
            track += 1
        if tm == 1:
            trans[:, i] = consts[ci:ci + 3]
            ci += 3
        elif tm == 2:
            trans[:, i] = values[track]
            track += 1
    return rot, trans
