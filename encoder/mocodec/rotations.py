"""Rotation arithmetic on arrays of quaternions, vectorised over leading axes.

Quaternions are stored ``x y z w`` (the runtime's and scipy's order). Rotations act on column
vectors, ``a * b`` applies ``b`` first, and every function accepts arrays of any leading shape.
Euler angles follow BVH: the rotation order is the order of the channels in the file, so
``"ZYX"`` means ``R = Rz @ Ry @ Rx`` (intrinsic rotations, scipy's upper-case convention).
"""
from __future__ import annotations

import numpy as np

EULER_ORDERS = ("XYZ", "XZY", "YXZ", "YZX", "ZXY", "ZYX")
_AXIS_INDEX = {"X": 0, "Y": 1, "Z": 2}


def quat_multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product ``a * b`` (apply ``b`` first)."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    ax, ay, az, aw = a[..., 0], a[..., 1], a[..., 2], a[..., 3]
    bx, by, bz, bw = b[..., 0], b[..., 1], b[..., 2], b[..., 3]
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    out[..., 0] = aw * bx + ax * bw + ay * bz - az * by
    out[..., 1] = aw * by - ax * bz + ay * bw + az * bx
    out[..., 2] = aw * bz + ax * by - ay * bx + az * bw
    out[..., 3] = aw * bw - ax * bx - ay * by - az * bz
    return out


def quat_conjugate(q: np.ndarray) -> np.ndarray:
    """Inverse of a unit quaternion."""
    return np.asarray(q, dtype=np.float64) * _CONJUGATE


_CONJUGATE = np.array([-1.0, -1.0, -1.0, 1.0])


def quat_normalize(q: np.ndarray) -> np.ndarray:
    q = np.asarray(q, dtype=np.float64)
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def quat_rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rotate vectors ``v`` (..., 3) by unit quaternions ``q`` (..., 4)."""
    q = np.asarray(q, dtype=np.float64)
    v = np.asarray(v, dtype=np.float64)
    u = q[..., :3]
    w = q[..., 3:4]
    t = 2.0 * _cross(u, v)
    return v + w * t + _cross(u, t)


def rotate_axis(q: np.ndarray, axis: int, length: float) -> np.ndarray:
    """``quat_rotate(q, v)`` for ``v`` = ``length`` along coordinate ``axis`` (0, 1, 2): the same
    arithmetic with the products by v's zeros left out, so the same numbers (but for the sign
    of a zero) at about a third of the work."""
    q = np.asarray(q, dtype=np.float64)
    k, i, j = axis, (axis + 1) % 3, (axis + 2) % 3
    uk, ui, uj, w = q[..., k], q[..., i], q[..., j], q[..., 3]
    ti = 2.0 * (uj * length)  # 2 (u x v): zero along the axis itself
    tj = -(2.0 * (ui * length))
    out = np.empty(q.shape[:-1] + (3,))
    out[..., k] = length + (ui * tj - uj * ti)
    out[..., i] = w * ti - uk * tj
    out[..., j] = w * tj + uk * ti
    return out


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``np.cross`` of (..., 3) vectors, the same arithmetic without its axis handling (the
    fitters rotate short arrays many times, where that handling is most of the cost)."""
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    out = np.empty(np.broadcast_shapes(a.shape, b.shape))
    out[..., 0] = a1 * b2 - a2 * b1
    out[..., 1] = a2 * b0 - a0 * b2
    out[..., 2] = a0 * b1 - a1 * b0
    return out


def quat_from_axis_angle(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Unit quaternions for rotations of ``angle`` radians about unit ``axis``."""
    axis = np.asarray(axis, dtype=np.float64)
    half = 0.5 * np.asarray(angle, dtype=np.float64)[..., None]
    return np.concatenate((axis * np.sin(half), np.cos(half)), axis=-1)


def _axis_quat(axis: str, angle: np.ndarray) -> np.ndarray:
    half = 0.5 * angle
    q = np.zeros(angle.shape + (4,))
    q[..., _AXIS_INDEX[axis]] = np.sin(half)
    q[..., 3] = np.cos(half)
    return q


def euler_to_quat(angles_deg: np.ndarray, order: str) -> np.ndarray:
    """Quaternions from Euler angles in degrees, ``angles_deg[..., i]`` about ``order[i]``.

    ``order`` is any arrangement of one to three distinct axes from ``"XYZ"``; the rotation
    is the product of the axis rotations in that order (BVH's convention).
    """
    angles = np.radians(np.asarray(angles_deg, dtype=np.float64))
    if len(order) == 0:
        q = np.zeros(angles.shape[:-1] + (4,))
        q[..., 3] = 1.0
        return q
    q = _axis_quat(order[0], angles[..., 0])
    for i in range(1, len(order)):
        q = quat_multiply(q, _axis_quat(order[i], angles[..., i]))
    return q


def quat_to_matrix(q: np.ndarray) -> np.ndarray:
    q = np.asarray(q, dtype=np.float64)
    x, y, z, w = np.moveaxis(q, -1, 0)
    return np.stack(
        (
            np.stack((1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)), -1),
            np.stack((2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)), -1),
            np.stack((2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)), -1),
        ),
        axis=-2,
    )


def quat_to_euler(q: np.ndarray, order: str) -> np.ndarray:
    """Euler angles in degrees (``order`` of three distinct axes) for quaternions ``q``.

    The middle angle lies in [-90, 90] (Tait-Bryan); use :func:`unwrap_euler` to make a
    sequence continuous or to match a reference.
    """
    if len(order) != 3 or len(set(order)) != 3:
        raise ValueError(f"quat_to_euler needs three distinct axes, got {order!r}")
    m = quat_to_matrix(q)
    i, j, k = (_AXIS_INDEX[a] for a in order)
    # Sign of the permutation (i, j, k): +1 for cyclic orders such as XYZ.
    sign = 1.0 if (j - i) % 3 == 1 else -1.0
    # R = Ri(a) Rj(b) Rk(c): R[i,k] = sign * sin(b).
    sb = np.clip(sign * m[..., i, k], -1.0, 1.0)
    # atan2 rather than arcsin: arcsin loses half the digits of b near +-90 degrees.
    b = np.arctan2(sign * m[..., i, k], np.hypot(m[..., i, i], m[..., i, j]))
    a = np.arctan2(-sign * m[..., j, k], m[..., k, k])
    c = np.arctan2(-sign * m[..., i, j], m[..., i, i])
    # Gimbal lock: put the whole rotation about the first axis.
    lock = np.abs(sb) > 1.0 - 1e-12
    if np.any(lock):
        c = np.where(lock, 0.0, c)
        a_lock = np.arctan2(sign * m[..., k, j], m[..., j, j])
        a = np.where(lock, a_lock, a)
    return np.degrees(np.stack((a, b, c), axis=-1))


def unwrap_euler(angles_deg: np.ndarray, reference_deg: np.ndarray | None = None) -> np.ndarray:
    """Remove 360-degree jumps along axis 0 (frames) of ``(frames, ..., 3)`` Euler angles.

    With ``reference_deg`` (same shape), each angle is instead shifted by whole turns to the
    value nearest the reference, so a decoded clip can be written with the original's branch.
    """
    a = np.asarray(angles_deg, dtype=np.float64)
    if reference_deg is not None:
        ref = np.asarray(reference_deg, dtype=np.float64)
        return a + 360.0 * np.round((ref - a) / 360.0)
    return np.degrees(np.unwrap(np.radians(a), axis=0))


def euler_nearest(angles_deg: np.ndarray, reference_deg: np.ndarray, order: str) -> np.ndarray:
    """Euler angles (three distinct axes ``order``) of the same rotations as ``angles_deg``,
    chosen per element to lie nearest ``reference_deg`` (same shape, ``(..., 3)``).

    A rotation has two triples, ``(a, b, c)`` and ``(a + 180, 180 - b, c + 180)``, each up to
    whole turns, and at gimbal lock (``b = +-90``) only ``a +- c`` is fixed; a source file may
    use any of them, so matching the source needs more than :func:`unwrap_euler`.
    """
    a = np.asarray(angles_deg, dtype=np.float64)
    ref = np.asarray(reference_deg, dtype=np.float64)
    first = unwrap_euler(a, ref)
    second = unwrap_euler(_other_triple(a), ref)
    pick = np.sum(np.abs(second - ref), axis=-1) < np.sum(np.abs(first - ref), axis=-1)
    out = np.where(pick[..., None], second, first)
    # Near gimbal lock only a + s*c matters (s from the axis order and the sign of b): keep
    # the reference's c and move the difference into a.
    b = (a[..., 1] + 180.0) % 360.0 - 180.0
    lock = np.abs(np.abs(b) - 90.0) < 1e-4
    if np.any(lock):
        i, j = (_AXIS_INDEX[x] for x in order[:2])
        s = np.sign(b) * (1.0 if (j - i) % 3 == 1 else -1.0)
        split = a.copy()
        split[..., 0] = a[..., 0] + s * (a[..., 2] - ref[..., 2])
        split[..., 2] = ref[..., 2]
        out = np.where(lock[..., None], unwrap_euler(split, ref), out)
    return out


def _other_triple(a: np.ndarray) -> np.ndarray:
    """``(a + 180, 180 - b, c + 180)``: the second Euler triple of the same rotation."""
    return np.stack((a[..., 0] + 180.0, 180.0 - a[..., 1], a[..., 2] + 180.0), axis=-1)


def quat_make_continuous(q: np.ndarray, axis: int = 0) -> np.ndarray:
    """Flip signs so consecutive quaternions along ``axis`` have a non-negative dot product."""
    q = np.array(q, dtype=np.float64, copy=True)
    moved = axis not in (0, -q.ndim)
    if moved:
        q = np.moveaxis(q, axis, 0)
    if q.shape[0] > 1:
        dots = np.sum(q[1:] * q[:-1], axis=-1)
        flips = np.cumsum(dots < 0, axis=0) % 2
        q[1:] *= np.where(flips[..., None] == 1, -1.0, 1.0)
    return np.moveaxis(q, 0, axis) if moved else q


def quat_angle(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angle in radians between rotations ``a`` and ``b`` (0 ... pi)."""
    # atan2 of the relative rotation's vector and scalar parts: accurate at small angles,
    # where arccos of the dot product loses half the digits.
    rel = quat_multiply(quat_conjugate(a), b)
    return 2.0 * np.arctan2(np.linalg.norm(rel[..., :3], axis=-1), np.abs(rel[..., 3]))


def mrp_from_quat(q: np.ndarray) -> np.ndarray:
    """Modified Rodrigues parameters ``p = v / (1 + w)`` (|p| = tan(angle / 4))."""
    q = np.asarray(q, dtype=np.float64)
    return q[..., :3] / (1.0 + q[..., 3:4])


def quat_from_mrp(p: np.ndarray) -> np.ndarray:
    """Inverse of :func:`mrp_from_quat`: ``(2p, 1 - p.p) / (1 + p.p)``; exactly unit."""
    p = np.asarray(p, dtype=np.float64)
    s = np.sum(p * p, axis=-1, keepdims=True)
    return np.concatenate((2.0 * p, 1.0 - s), axis=-1) / (1.0 + s)


def quat_mean(q: np.ndarray) -> np.ndarray:
    """A unit quaternion near the average rotation of ``q`` (n, 4): the principal
    eigenvector of the sum of outer products (sign-independent), sign chosen with w >= 0."""
    q = np.asarray(q, dtype=np.float64).reshape(-1, 4)
    m = q.T @ q
    _, vecs = np.linalg.eigh(m)
    r = vecs[:, -1]
    if r[3] < 0:
        r = -r
    return r / np.linalg.norm(r)


def euler_continuous(angles_deg: np.ndarray, order: str) -> np.ndarray:
    """Make Euler angles ``(F, ..., 3)`` (three distinct axes) continuous along frames by
    choosing, frame by frame, the triple and whole turns nearest the previous frame: for
    decoded clips, which have no source to follow. Vectorised over everything but frames."""
    a = np.array(angles_deg, dtype=np.float64, copy=True)
    for f in range(1, len(a)):
        a[f] = euler_nearest(a[f], a[f - 1], order)
    return a


def quat_from_matrix(m: np.ndarray) -> np.ndarray:
    """Unit quaternions (x y z w) of rotation matrices (F, 3, 3), numerically robust."""
    t = np.trace(m, axis1=1, axis2=2)
    cand = np.stack((m[:, 0, 0], m[:, 1, 1], m[:, 2, 2], t), axis=1)
    k = np.argmax(cand, axis=1)
    q = np.empty((len(m), 4))
    for case in range(4):
        sel = k == case
        if not sel.any():
            continue
        a = m[sel]
        if case == 3:
            r = np.sqrt(1.0 + t[sel]) * 2.0
            q[sel] = np.stack(((a[:, 2, 1] - a[:, 1, 2]) / r, (a[:, 0, 2] - a[:, 2, 0]) / r,
                               (a[:, 1, 0] - a[:, 0, 1]) / r, 0.25 * r), axis=1)
        else:
            i, j, kk = case, (case + 1) % 3, (case + 2) % 3
            r = np.sqrt(1.0 + a[:, i, i] - a[:, j, j] - a[:, kk, kk]) * 2.0
            out = np.empty((len(a), 4))
            out[:, i] = 0.25 * r
            out[:, j] = (a[:, j, i] + a[:, i, j]) / r
            out[:, kk] = (a[:, kk, i] + a[:, i, kk]) / r
            out[:, 3] = (a[:, kk, j] - a[:, j, kk]) / r
            q[sel] = out
    return quat_normalize(q)
