"""A reference decoder of the ``RMAL`` payload, versions 2, 3 and 4, written from docs/FORMAT.md.

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


def _rice(data: bytes, bit: int, k: int) -> tuple[int, int]:
    """The Rice code at ``bit`` with parameter ``k``: (value, the bit after it)."""
    q = 0
    while q < 16 and not read_bits(data, bit + q, 1):
        q += 1
    if q == 16:
        return read_bits(data, bit + 16, 32), bit + 48
    return q << k | read_bits(data, bit + q + 1, k), bit + q + 1 + k


def _unzigzag(z: int) -> int:
    return z >> 1 if z % 2 == 0 else -(z >> 1) - 1


def _blocks_track(payload: bytes, pos: int, t: dict, frames: int, version: int) -> int:
    """Versions 3 and 4: a track's rows and Rice-coded blocks from ``pos``; fills ``t`` and
    returns where the next track starts. Version 4's fields: k in bits 0-3 (15: a stream of
    zeros, no codes), a component's slope predictor in bit 4."""
    d, K, B = t["d"], t["K"], 1 << t["block_shift"]
    rows = (K + B - 1) // B
    fb = _bits_for(frames - 1)
    row_bits = fb + t["offset_bits"] + 5 * (d + 1) + sum(t["abits"])
    table = payload[pos:pos + 4 * ((rows * row_bits + 31) // 32)] + bytes(8)
    t["parts"] = dict(table=pos, row_bits=row_bits, rows=rows)
    pos += 4 * ((rows * row_bits + 31) // 32)
    t["parts"]["data"] = pos
    data = payload[pos:pos + t["data_bytes"]] + bytes(8)
    key_frames = np.zeros(K, dtype=np.int64)
    q = np.zeros((K, d), dtype=np.int64)
    for e in range(rows):
        bit = e * row_bits
        fields = []
        for w in [fb, t["offset_bits"]] + [5] * (d + 1):
            fields.append(read_bits(table, bit, w))
            bit += w
        j = e * B
        key_frames[j] = fields[0]
        for c in range(d):
            q[j, c] = _signed(read_bits(table, bit, t["abits"][c]), t["abits"][c])
            bit += t["abits"][c]
        at, k = fields[1], fields[2:]
        slope = [version == 4 and bool(f & 16) for f in k]
        if slope[0]:
            raise ValueError(f"row {e}: the slope predictor on the frame gaps (FORMAT.md forbids it)")
        if version == 4:
            k = [None if f & 15 == 15 else f & 15 for f in k]  # None: a stream of zeros
        before = [0] * d  # the difference into the key before; 0 at the block's first key
        for j in range(e * B + 1, min(K, e * B + B)):
            gap, at = (0, at) if k[0] is None else _rice(data, at, k[0])
            key_frames[j] = key_frames[j - 1] + gap + 1
            for c in range(d):
                z, at = (0, at) if k[1 + c] is None else _rice(data, at, k[1 + c])
                before[c] = _unzigzag(z) + (before[c] if slope[1 + c] else 0)
                q[j, c] = q[j - 1, c] + before[c]
    t.update(frames=key_frames, q=q)
    return pos + t["data_bytes"]


def decode_keys(payload: bytes, version: int = 4) -> tuple[dict, list[dict]]:
    """The payload's header fields and, per track, its kind, key frames (K,), lattice
    integers (K, d), steps (d,), reference and axis, and where its parts start (``parts``:
    byte offsets; version 2: the bitmap, rank table, group table and data area; versions 3 and 4:
    the row table and data area)."""
    size, frames, nodes, ntracks, nconst = struct.unpack_from("<IIIII", payload)
    pos = 32
    modes = list(payload[pos:pos + nodes])
    pos += (nodes + 3) // 4 * 4
    consts = np.frombuffer(payload, "<f4", nconst, pos).astype(np.float64)
    pos += 4 * nconst
    descs = []
    for _ in range(ntracks):
        kind, flags, offset_bits, in_cell_bits, K, data_bytes, step = struct.unpack_from("<BBBBIIf", payload, pos)
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
        descs.append(dict(kind=kind, d=d, split=bool(flags & 1), cell_shift=(flags >> 1) & 3,
                          group_shift=(flags >> 3) & 7, block_shift=(flags >> 1) & 7,
                          offset_bits=offset_bits, in_cell_bits=in_cell_bits, K=K,
                          data_bytes=data_bytes,
                          steps=steps, abits=abits, ref=ref, axis=axis))
        pos += _DESC_SIZE[kind]
    pos = (pos + 3) // 4 * 4
    for t in descs:
        if version in (3, 4):
            pos = _blocks_track(payload, pos, t, frames, version)
            continue
        d, K, G = t["d"], t["K"], 1 << t["group_shift"]
        # Key times: the unary cells, the rank table (not needed reading in order), the places.
        C = 1 << t["cell_shift"]
        inner = (frames - 2 + C - 1) // C if frames > 1 else -1
        cells = inner + 2
        words = (K + cells + 63) // 64
        bits = np.unpackbits(np.frombuffer(payload, np.uint8, words * 8, pos), bitorder="little")
        cell = np.flatnonzero(bits) - np.arange(K)  # key k's one is at bit cell_k + k
        key_frames = np.where(cell == 0, 0, np.where(cell > inner, frames - 1, 1 + (cell - 1) * C))
        parts = dict(bitmap=pos, rank=pos + words * 8)
        pos += words * 8 + 4 * ((((cells + 63) // 64) * _bits_for(K) + 31) // 32)
        parts["in_cell"] = pos
        ib = t["in_cell_bits"]
        if ib:
            places = payload[pos:pos + 4 * ((K * ib + 31) // 32)] + bytes(8)
            key_frames = key_frames + np.array([read_bits(places, k * ib, ib) for k in range(K)], dtype=np.int64)
            pos += 4 * ((K * ib + 31) // 32)
        # Key values: the group table (offset, widths, anchor per row), then the records.
        rows = (K - 1 + G - 1) // G + 1
        row_bits = t["offset_bits"] + 4 * d + sum(t["abits"])
        table = payload[pos:pos + 4 * ((rows * row_bits + 31) // 32)] + bytes(8)
        parts.update(table=pos, row_bits=row_bits, rows=rows)
        pos += 4 * ((rows * row_bits + 31) // 32)
        parts["data"] = pos
        data = payload[pos:pos + t["data_bytes"]] + bytes(8)
        pos += t["data_bytes"]
        entry = []
        for e in range(rows):
            bit = e * row_bits
            off = read_bits(table, bit, t["offset_bits"])
            bit += t["offset_bits"]
            w = [read_bits(table, bit + 4 * c, 4) for c in range(d)]
            bit += 4 * d
            a = []
            for c in range(d):
                a.append(_signed(read_bits(table, bit, t["abits"][c]), t["abits"][c]))
                bit += t["abits"][c]
            entry.append((off, w, a))
        q = np.zeros((K, d), dtype=np.int64)
        for e in range(rows):
            q[min(e * G, K - 1)] = entry[e][2]
        for e in range(rows - 1):
            bit, w, a0 = entry[e]
            a1 = entry[e + 1][2]
            span = min(G, K - 1 - e * G)
            exc = bit + (span - 1) * sum(w)
            for i in range(1, span):
                for c in range(d):
                    pred = a0[c] + ((a1[c] - a0[c]) * i) // span
                    if w[c] == 0:
                        q[e * G + i, c] = pred
                        continue
                    r = _signed(read_bits(data, bit, w[c]), w[c])
                    bit += w[c]
                    if r == -(1 << (w[c] - 1)):
                        q[e * G + i, c] = _signed(read_bits(data, exc, t["abits"][c]), t["abits"][c])
                        exc += t["abits"][c]
                    else:
                        q[e * G + i, c] = pred + r
        t.update(frames=key_frames.astype(np.int64), q=q, parts=parts)
    header = dict(size=size, frames=frames, nodes=nodes, modes=modes, consts=consts)
    return header, descs


def decode_payload(payload: bytes, skeleton: Skeleton, x: np.ndarray, version: int = 4) -> tuple[np.ndarray, ...]:
    """Local rotations (len(x), N, 4), translations and scales (len(x), N, 3) at frame
    positions x of a version ``version`` payload."""
    header, descs = decode_keys(payload, version)
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
