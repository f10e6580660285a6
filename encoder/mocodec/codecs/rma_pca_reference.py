"""A reference decoder of the ``RMAP`` version 2 section written from docs/FORMAT.md, in float64.

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
NO_PRIMARY = 0xFFFFFFFF
SHARED_BIT = 0x80000000


def _coefficients(data: bytes, at: int, x: np.ndarray) -> np.ndarray:
    """Node translations of the curve set at byte ``at`` of ``data``, flattened: (len(x), 3 n)
    (node j's x y z are entries 3j, 3j + 1, 3j + 2)."""
    size, _, nodes = struct.unpack_from("<III", data, at)
    sk = Skeleton([f"c{i}" for i in range(nodes)], np.full(nodes, -1), np.zeros((nodes, 3)),
                  [() for _ in range(nodes)], np.zeros(nodes, dtype=bool))
    return decode_payload(data[at:at + size], sk, x, version=2)[1].reshape(len(x), -1)


def _unpack12(data: bytes, count: int) -> np.ndarray:
    b = np.frombuffer(data, np.uint8, 3 * ((count + 1) // 2)).reshape(-1, 3).astype(np.int64)
    lo = b[:, 0] | (b[:, 1] & 15) << 8
    hi = b[:, 1] >> 4 | b[:, 2] << 4
    return np.stack((lo, hi), axis=1).ravel()[:count]


def _group(s: bytes, pos: int, dims: int) -> tuple[np.ndarray, np.ndarray]:
    """A group record's mean (D,) and axes (k, D), as binary32 values ``min + code x step``."""
    k, _, lo, step = struct.unpack_from("<IIff", s, pos)
    pairs = np.frombuffer(s, "<f4", 2 * k, pos + 16).reshape(k, 2)
    mean_codes = np.frombuffer(s, "<u2", dims, pos + 16 + 8 * k).astype(np.int64)
    codes = _unpack12(s[pos + 16 + 8 * k + 2 * dims:], dims * k).reshape(k, dims)
    f32 = np.float32
    mean = (f32(lo) + mean_codes.astype(f32) * f32(step)).astype(np.float64)
    axes = (pairs[:, :1].astype(f32) + codes.astype(f32) * pairs[:, 1:].astype(f32)).astype(np.float64)
    return mean, axes


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
    positions ``x``; ``section`` is the whole ``RMAP`` section (its shared part is read)."""
    clips, groups, markers, joints, blend, shared, shared_end, _ = struct.unpack_from("<8I", section)
    jt = 32
    group_at = np.frombuffer(section, "<u4", groups, jt + 24 * joints)
    shared_at = np.frombuffer(section, "<u4", shared, jt + 24 * joints + 4 * groups)
    size, frames, pieces, flags = struct.unpack_from("<4I", payload)
    table = np.frombuffer(payload, "<u4", 4 * pieces, 16).reshape(pieces, 4).astype(np.int64)
    x = np.asarray(x, dtype=np.float64)
    n = len(x)
    # Root curves: the first of the clip's own curve sets.
    root = _coefficients(payload, 16 + 16 * pieces, x)
    if flags:
        q = root[:, 3:7]
        removed = q / np.linalg.norm(q, axis=1, keepdims=True)
    else:
        removed = R.quat_from_axis_angle(np.array([0.0, 1.0, 0.0]), root[:, 3])
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
    for p in range(pieces):
        lo = starts[p] - blend if p else 0
        hi = starts[p + 1] + blend if p + 1 < pieces else frames - 1
        _, group, curves, primary = (int(v) for v in table[p])
        mean, axes = _group(section, int(group_at[group]), 3 * markers)
        k = len(axes)
        sel = weight[p] > 0
        if not sel.any():
            continue
        data, at = (section, int(shared_at[curves & ~SHARED_BIT])) if curves & SHARED_BIT else (payload, curves)
        local = np.clip(x[sel] - lo, 0, hi - lo)
        c = _coefficients(data, at, local)
        if primary != NO_PRIMARY:
            # Eq. 6: the primary's coefficients at the reference frame, plus differences.
            pat = int(shared_at[primary])
            pf = struct.unpack_from("<I", section, pat + 4)[0]
            ref = np.clip(c[:, 0], 0, pf - 1)
            c = _coefficients(section, pat, ref)[:, :k] + c[:, 3:3 + k]
        else:
            c = c[:, :k]
        mk[sel] += weight[p, sel, None] * (mean + c @ axes)
    mk = mk.reshape(n, markers, 3)
    # Joint rotations from markers, then local rotations and the root; nodes without a joint
    # record keep their rest rotation.
    nodes = skeleton.node_count
    rest_rot = skeleton.rest_rotations.astype(np.float32).astype(np.float64)
    world = np.broadcast_to(rest_rot, (n, nodes, 4)).copy()
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
            world[:, i] = R.quat_multiply(world[:, p], local[:, i])
    trans = np.broadcast_to(skeleton.offsets.astype(np.float32).astype(np.float64), (n, nodes, 3)).copy()
    local[:, 0] = R.quat_multiply(removed, local[:, 0])
    trans[:, 0] = root[:, :3]
    return local, trans
