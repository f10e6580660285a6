"""A reference decoder of the ``RMAL`` version 2 payload, written from docs/FORMAT.md.

For tests only: it checks the format document and the C runtime against each other (they
must agree to float32 precision). It reads every key of every track in index order, the way
the format defines them, and evaluates the curves in float64.
"""
from __future__ import annotations

import struct

import numpy as np

from .. import rotations as R
from ..bitpack import read_bits
from ..curves import catmull_rom
from ..motion import Skeleton
from .spline_reference import track_rotation

_DESC_SIZE = {1: 28, 2: 40, 3: 20, 4: 20}
_DIMS = {1: 3, 2: 4, 3: 3, 4: 3}


def _signed(u: int, n: int) -> int:
    return u - (1 << n) if u >> (n - 1) else u


def _bits_for(n: int) -> int:
    return max(1, int(n).bit_length())


def decode_keys(payload: bytes) -> tuple[dict, list[dict]]:
    """The payload's header fields and, per track, its kind, key frames (K,), lattice
    integers (K, d), steps (d,), reference and axis."""
    size, frames, nodes, ntracks, nconst = struct.unpack_from("<IIIII", payload)
    pos = 32
    modes = list(payload[pos:pos + nodes])
    pos += (nodes + 3) // 4 * 4
    consts = np.frombuffer(payload, "<f4", nconst, pos).astype(np.float64)
    pos += 4 * nconst
    descs = []
    for _ in range(ntracks):
        kind, flags, offset_bits, seek_shift, K, data_bytes, step = struct.unpack_from("<BBBBIIf", payload, pos)
        d = _DIMS[kind]
        abits = list(payload[pos + 16:pos + 16 + d])
        steps = np.full(d, step, dtype=np.float32)
        ref = axis = None
        if kind in (1, 2):
            ref = R.quat_from_mrp(np.frombuffer(payload, "<i2", 3, pos + 20).astype(np.float64) / 32767.0)
        if kind == 2:
            a = np.frombuffer(payload, "<i2", 3, pos + 28).astype(np.float64)
            axis = a / np.linalg.norm(a)
            steps[0] = struct.unpack_from("<f", payload, pos + 36)[0]
        descs.append(dict(kind=kind, d=d, split=bool(flags & 1), predictor=(flags >> 1) & 3,
                          group_shift=(flags >> 3) & 7, offset_bits=offset_bits,
                          seek_shift=seek_shift, K=K, data_bytes=data_bytes, steps=steps, abits=abits, ref=ref,
                          axis=axis))
        pos += _DESC_SIZE[kind]
    pos = (pos + 3) // 4 * 4
    frame_bits = _bits_for(frames - 1)
    for t in descs:
        d = t["d"]
        G = 1 << t["group_shift"]
        groups = (t["K"] - 1) // G + 1
        seeks = ((frames - 1) >> t["seek_shift"]) + 1
        table_at = pos + 4 * ((seeks * _bits_for(groups - 1) + 31) // 32)
        entry = t["offset_bits"] + frame_bits + 4 * (d + 1) + sum(t["abits"])
        data_at = table_at + 4 * ((groups * entry + 31) // 32)
        pos = data_at + t["data_bytes"]
        table = payload[table_at:data_at] + bytes(8)
        data = payload[data_at:pos] + bytes(8)
        q = np.zeros((t["K"], d), dtype=np.int64)
        key_frames = np.zeros(t["K"], dtype=np.int64)
        for g in range(groups):
            bit = g * entry
            rec = read_bits(table, bit, t["offset_bits"])
            bit += t["offset_bits"]
            k0 = g * G
            key_frames[k0] = read_bits(table, bit, frame_bits)
            bit += frame_bits
            w = [read_bits(table, bit + 4 * c, 4) for c in range(d + 1)]
            bit += 4 * (d + 1)
            for c in range(d):
                q[k0, c] = _signed(read_bits(table, bit, t["abits"][c]), t["abits"][c])
                bit += t["abits"][c]
            n = min(G, t["K"] - k0)
            exc = rec + (n - 1) * sum(w)
            for j in range(1, n):
                k = k0 + j
                gap = read_bits(data, rec, w[0])
                rec += w[0]
                if w[0] and gap == (1 << w[0]) - 1:
                    key_frames[k] = read_bits(data, exc, frame_bits)
                    exc += frame_bits
                else:
                    key_frames[k] = key_frames[k - 1] + gap + 1
                for c in range(d):
                    q1 = q[k - 1, c]
                    q2 = q[k - 2, c] if j >= 2 else q1
                    pred = q1 + ((q1 - q2) * t["predictor"] + 1) // 2
                    wc = w[c + 1]
                    if wc == 0:
                        q[k, c] = pred
                        continue
                    r = _signed(read_bits(data, rec, wc), wc)
                    rec += wc
                    if r == -(1 << (wc - 1)):
                        q[k, c] = _signed(read_bits(data, exc, t["abits"][c]), t["abits"][c])
                        exc += t["abits"][c]
                    else:
                        q[k, c] = pred + r
        t.update(frames=key_frames, q=q)
    header = dict(size=size, frames=frames, nodes=nodes, modes=modes, consts=consts)
    return header, descs


def decode_payload(payload: bytes, skeleton: Skeleton, x: np.ndarray) -> tuple[np.ndarray, ...]:
    """Local rotations (len(x), N, 4), translations and scales (len(x), N, 3) at frame
    positions x."""
    header, descs = decode_keys(payload)
    x = np.asarray(x, dtype=np.float64)
    n, nodes = len(x), header["nodes"]
    values = []
    for t in descs:
        v = (t["q"].astype(np.float64) * t["steps"].astype(np.float64)).astype(np.float32).astype(np.float64)
        values.append(catmull_rom(t["frames"], v, x, split=t["split"]))
    rot = np.broadcast_to(skeleton.rest_rotations.astype(np.float32).astype(np.float64), (n, nodes, 4)).copy()
    trans = np.broadcast_to(skeleton.offsets.astype(np.float32).astype(np.float64), (n, nodes, 3)).copy()
    scale = np.broadcast_to(skeleton.rest_scales.astype(np.float32).astype(np.float64), (n, nodes, 3)).copy()
    track = ci = 0
    consts = header["consts"]
    for i in range(nodes):
        for m, out, width in ((0, rot, 4), (1, trans, 3), (2, scale, 3)):
            mode = header["modes"][i] >> (2 * m) & 3
            if mode == 1:
                out[:, i] = consts[ci:ci + width]
                ci += width
            elif mode == 2:
                t = descs[track]
                out[:, i] = track_rotation(t["kind"], t["ref"], t["axis"], values[track]) if m == 0 else values[track]
                track += 1
    return rot, trans, scale
