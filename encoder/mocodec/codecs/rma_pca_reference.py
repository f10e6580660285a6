"""A reference decoder of the ``RMAP`` section written from docs/FORMAT.md, in float64.

For tests only: it checks the format document and the C runtime against each other. Curve
sets are decoded by the ``RMAL`` reference decoder (:mod:`.rma_reference`).
"""
from __future__ import annotations

import struct

import numpy as np

from .. import rotations as R
from ..motion import Skeleton
from .rma_reference import decode_payload

NO_INDEX = 0xFFFF


def _curves(section: bytes, offset: int, nodes: int, x: np.ndarray) -> np.ndarray:
    """Translations (len(x), nodes, 3) of the curve set at ``offset`` of the RMAL section."""
    size = struct.unpack_from("<I", section, offset)[0]
    sk = Skeleton([f"c{i}" for i in range(nodes)], np.full(nodes, -1), np.zeros((nodes, 3)),
                  [() for _ in range(nodes)], np.zeros(nodes, dtype=bool))
    return decode_payload(section[offset:offset + size], sk, x)[1]


def _unpack12(data: bytes, count: int) -> np.ndarray:
    b = np.frombuffer(data, np.uint8, 3 * ((count + 1) // 2)).reshape(-1, 3).astype(np.int64)
    lo = b[:, 0] | (b[:, 1] & 15) << 8
    hi = b[:, 1] >> 4 | b[:, 2] << 4
    return np.stack((lo, hi), axis=1).ravel()[:count]


def _groups(s: bytes, pos: int, groups: int, dims: int) -> list[tuple[np.ndarray, np.ndarray]]:
    out = []
    for _ in range(groups):
        k, _, lo, step = struct.unpack_from("<IIff", s, pos)
        pairs = np.frombuffer(s, "<f4", 2 * k, pos + 16).reshape(k, 2)
        mean_codes = np.frombuffer(s, "<u2", dims, pos + 16 + 8 * k).astype(np.int64)
        codes = _unpack12(s[pos + 16 + 8 * k + 2 * dims:], dims * k).reshape(k, dims)
        f32 = np.float32
        mean = (f32(lo) + mean_codes.astype(f32) * f32(step)).astype(np.float64)
        axes = (pairs[:, :1].astype(f32) + codes.astype(f32) * pairs[:, 1:].astype(f32)).astype(np.float64)
        out.append((mean, axes))
        size = 16 + 8 * k + 2 * dims + 3 * ((dims * k + 1) // 2)
        pos += (size + 3) // 4 * 4
    return out


def _frames(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    e1 = u / np.maximum(np.linalg.norm(u, axis=-1, keepdims=True), 1e-12)
    v2 = v - np.sum(v * e1, axis=-1, keepdims=True) * e1
    e2 = v2 / np.maximum(np.linalg.norm(v2, axis=-1, keepdims=True), 1e-12)
    return np.stack((e1, e2, np.cross(e1, e2)), axis=-1)


def _rest(axis: np.ndarray) -> np.ndarray:
    a = axis / np.linalg.norm(axis)
    side = np.cross(a, np.eye(3)[int(np.argmin(np.abs(a)))])
    return _frames(a, side)


def decode_clip(section: bytes, payload: bytes, skeleton: Skeleton,
                x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Local rotations (len(x), N, 4) and translations (len(x), N, 3) of one clip at frame
    positions ``x``; ``section`` is the whole ``RMAP`` section (its prefix is read)."""
    clips, groups, markers, joints, basis_bytes, curves_bytes, blend, _ = struct.unpack_from("<8I", section)
    jt = 32
    gt = jt + 24 * joints
    cs = gt + basis_bytes
    curves = section[cs:cs + curves_bytes]
    bases = _groups(section, gt, groups, 3 * markers)
    size, frames, pieces, flags, offset, repeats = struct.unpack_from("<6I", payload)
    table = np.frombuffer(payload, "<u4", 2 * pieces, 24).reshape(pieces, 2).astype(np.int64)
    primary = {int(p): int(o) for p, o in
               np.frombuffer(payload, "<u4", 2 * repeats, 24 + 8 * pieces).reshape(repeats, 2)}
    x = np.asarray(x, dtype=np.float64)
    n = len(x)
    # Root curves.
    root = _curves(curves, offset, 3 if flags else 2, x)
    if flags:
        q = np.concatenate((root[:, 1], root[:, 2, :1]), axis=1)
        removed = q / np.linalg.norm(q, axis=1, keepdims=True)
    else:
        removed = R.quat_from_axis_angle(np.array([0.0, 1.0, 0.0]), root[:, 1, 0])
    # Markers, piece by piece; within `blend` frames of a border the two pieces are mixed
    # with smoothstep weights.
    starts = table[:, 0]
    which = np.searchsorted(starts, x, side="right") - 1
    weight = np.zeros((pieces, n))
    weight[which, np.arange(n)] = 1.0
    if blend:
        for p in range(1, pieces):
            t = np.clip((x - (starts[p] - blend)) / (2.0 * blend), 0.0, 1.0)
            near = np.abs(x - starts[p]) < blend
            w = t * t * (3.0 - 2.0 * t)
            weight[p - 1, near] = 1.0 - w[near]
            weight[p, near] = w[near]
    mk = np.zeros((n, 3 * markers))
    set_off = offset + struct.unpack_from("<I", curves, offset)[0]
    for p in range(pieces):
        lo = starts[p] - blend if p else 0
        hi = starts[p + 1] + blend if p + 1 < pieces else frames - 1
        k = len(bases[table[p, 1]][1])
        sel = weight[p] > 0
        if sel.any():
            local = np.clip(x[sel] - lo, 0, hi - lo)
            if p in primary:
                # Eq. 6: the primary's coefficients at the reference frame, plus differences.
                c = _curves(curves, set_off, k + 1, local)[:, :k + 1, 0]
                pf = struct.unpack_from("<I", curves, primary[p] + 4)[0]
                at = np.clip(c[:, 0], 0, pf - 1)
                c = _curves(curves, primary[p], k, at)[:, :k, 0] + c[:, 1:]
            else:
                c = _curves(curves, set_off, max(k, 1), local)[:, :k, 0]
            mean, axes = bases[table[p, 1]]
            mk[sel] += weight[p, sel, None] * (mean + c @ axes)
        set_off += struct.unpack_from("<I", curves, set_off)[0]
    mk = mk.reshape(n, markers, 3)
    # Joint rotations from markers, then local rotations and the root.
    nodes = skeleton.node_count
    world = np.zeros((n, nodes, 4))
    world[..., 3] = 1.0
    local = world.copy()
    jrec = {}
    for j in range(joints):
        node, child, am, sm, origin, _, bx, by, bz = struct.unpack_from("<6H3f", section, jt + 24 * j)
        jrec[node] = (child, am, sm, origin, np.array([bx, by, bz]))
    for i in range(nodes):
        p = skeleton.parents[i]
        if i in jrec:
            child, am, sm, origin, bdir = jrec[i]
            a = mk[:, origin] if origin != NO_INDEX else np.zeros((n, 3))
            w = _frames(mk[:, am] - a, mk[:, sm] - a)
            axis = skeleton.offsets[child].astype(np.float32).astype(np.float64) if child != NO_INDEX else bdir
            world[:, i] = R.quat_from_matrix(w @ _rest(axis).T)
            local[:, i] = world[:, i] if p < 0 else R.quat_multiply(R.quat_conjugate(world[:, p]), world[:, i])
        elif p >= 0:
            world[:, i] = world[:, p]
    trans = np.broadcast_to(skeleton.offsets.astype(np.float32).astype(np.float64), (n, nodes, 3)).copy()
    local[:, 0] = R.quat_multiply(removed, local[:, 0])
    trans[:, 0] = root[:, 0]
    return local, trans
