"""Rotation arithmetic against scipy, Euler round trips, and channel branches."""
from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from mocodec.motion import Motion, Skeleton
from mocodec.rotations import (
    EULER_ORDERS,
    euler_nearest,
    euler_to_quat,
    mrp_from_quat,
    quat_conjugate,
    quat_from_mrp,
    quat_make_continuous,
    quat_multiply,
    quat_rotate,
    quat_to_euler,
    quat_to_matrix,
    rotate_axis,
)


def rotation_angle(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angle (radians) of the rotation from ``a`` to ``b``, accurate for tiny angles."""
    half_sin = np.linalg.norm(quat_multiply(quat_conjugate(a), b)[..., :3], axis=-1)
    return 2.0 * np.arcsin(np.minimum(half_sin, 1.0))


def random_quats(n: int, seed: int) -> np.ndarray:
    q = np.random.default_rng(seed).normal(size=(n, 4))
    return q / np.linalg.norm(q, axis=-1, keepdims=True)


def near_lock_angles(order_seed: int) -> np.ndarray:
    """Random first and last angles with the middle angle at and near +-90 degrees."""
    rng = np.random.default_rng(order_seed)
    middle = np.array([90.0, -90.0, 90.0 - 1e-9, -90.0 + 1e-7, 89.999, -89.99, 90.0 + 1e-6])
    angles = rng.uniform(-180.0, 180.0, (len(middle) * 20, 3))
    angles[:, 1] = np.repeat(middle, 20)
    return angles


@pytest.mark.parametrize("order", EULER_ORDERS)
def test_euler_to_quat_matches_scipy(order: str) -> None:
    angles = np.random.default_rng(1).uniform(-360.0, 360.0, (500, 3))
    ours = euler_to_quat(angles, order)
    theirs = Rotation.from_euler(order, angles, degrees=True).as_quat()
    assert np.max(rotation_angle(ours, theirs)) < 1e-12
    np.testing.assert_allclose(np.linalg.norm(ours, axis=-1), 1.0, atol=1e-12)


@pytest.mark.parametrize("axes", ["X", "Y", "Z", "ZX", "YZ", "XY"])
def test_euler_to_quat_fewer_axes_matches_scipy(axes: str) -> None:
    angles = np.random.default_rng(2).uniform(-360.0, 360.0, (100, len(axes)))
    theirs = Rotation.from_euler(axes, angles, degrees=True).as_quat()
    assert np.max(rotation_angle(euler_to_quat(angles, axes), theirs)) < 1e-12


@pytest.mark.parametrize("order", EULER_ORDERS)
def test_quat_to_euler_round_trip(order: str) -> None:
    q = random_quats(1000, 3)
    angles = quat_to_euler(q, order)
    assert np.all(np.abs(angles[:, 1]) <= 90.0)
    assert np.max(rotation_angle(euler_to_quat(angles, order), q)) < 1e-12
    # Away from gimbal lock the triple is unique, so it must equal scipy's.
    theirs = Rotation.from_quat(q).as_euler(order, degrees=True)
    np.testing.assert_allclose(angles, theirs, atol=1e-9)


@pytest.mark.parametrize("order", EULER_ORDERS)
def test_quat_to_euler_near_gimbal_lock(order: str) -> None:
    angles = near_lock_angles(4)
    q = euler_to_quat(angles, order)
    back = quat_to_euler(q, order)
    assert np.all(np.isfinite(back))
    error = rotation_angle(euler_to_quat(back, order), q)
    exact = np.abs(angles[:, 1]) == 90.0
    assert np.max(error[exact]) < 1e-12
    # Within ~1e-4 degrees of the lock, quat_to_euler puts the whole turn on the first axis,
    # which is off by about cos(b) * |c| (cos(b) < 1.5e-6 there).
    assert np.max(error[~exact]) < 5e-6
    # The middle angle itself is well conditioned even at the lock.
    b = angles[:, 1]
    principal = np.where(np.abs(b) <= 90.0, b, np.sign(b) * 180.0 - b)
    np.testing.assert_allclose(back[:, 1], principal, atol=1e-9)


def test_quat_to_euler_rejects_bad_orders() -> None:
    with pytest.raises(ValueError, match="three distinct axes"):
        quat_to_euler(random_quats(2, 5), "XYX")
    with pytest.raises(ValueError, match="three distinct axes"):
        quat_to_euler(random_quats(2, 5), "XY")


def test_quat_multiply_and_rotate_match_scipy() -> None:
    a, b = random_quats(300, 6), random_quats(300, 7)
    v = np.random.default_rng(8).normal(size=(300, 3))
    ra, rb = Rotation.from_quat(a), Rotation.from_quat(b)
    assert np.max(rotation_angle(quat_multiply(a, b), (ra * rb).as_quat())) < 1e-12
    np.testing.assert_allclose(quat_rotate(a, v), ra.apply(v), atol=1e-12)
    np.testing.assert_allclose(quat_to_matrix(a), ra.as_matrix(), atol=1e-12)
    np.testing.assert_allclose(quat_multiply(quat_conjugate(a), a)[:, 3] ** 2, 1.0, atol=1e-12)
    # Broadcasting over leading axes: one rotation applied to many vectors.
    np.testing.assert_allclose(quat_rotate(a[:1], v), ra[0].apply(v), atol=1e-12)


@pytest.mark.parametrize("axis", [0, 1, 2])
def test_rotate_axis_is_quat_rotate_of_that_axis(axis: int) -> None:
    # The shell vertices of the error metric: the same numbers as the general rotation, also
    # where a quaternion has exact zeros (the rest pose) or points the other way.
    q = random_quats(500, seed=axis).reshape(50, 10, 4)
    q[0] = [0.0, 0.0, 0.0, 1.0]
    q[1, :, axis] = 0.0
    q[2] = -q[2]
    v = np.zeros(3)
    v[axis] = 0.53
    assert np.array_equal(rotate_axis(q, axis, 0.53), quat_rotate(q, v))


def test_mrp_round_trip() -> None:
    q = random_quats(1000, 9)
    q[q[:, 3] < 0] *= -1  # scipy's MRP picks the rotation angle <= 180 (w >= 0)
    p = mrp_from_quat(q)
    np.testing.assert_allclose(p, Rotation.from_quat(q).as_mrp(), atol=1e-12)
    np.testing.assert_allclose(quat_from_mrp(p), q, atol=1e-12)
    angle = 2.0 * np.arccos(np.clip(q[:, 3], -1.0, 1.0))
    np.testing.assert_allclose(np.linalg.norm(p, axis=-1), np.tan(angle / 4.0), atol=1e-12)
    # Also exact for the other sign (|p| > 1), except at w = -1.
    np.testing.assert_allclose(quat_from_mrp(mrp_from_quat(-q)), -q, atol=1e-9)


@pytest.mark.parametrize("axis", [0, 1])
def test_quat_make_continuous(axis: int) -> None:
    rng = np.random.default_rng(10)
    # Two tracks of a slowly turning rotation, each stored with random signs.
    t = np.linspace(0.0, 6.0, 200)
    smooth = np.stack([euler_to_quat(np.stack([50 * t, 20 * np.sin(t), 10 * t + k], -1),
                                     "ZYX") for k in (0.0, 30.0)], axis=1)
    signs = rng.choice([-1.0, 1.0], size=smooth.shape[:2])[..., None]
    noisy = np.moveaxis(smooth * signs, 0, axis)
    fixed = np.moveaxis(quat_make_continuous(noisy, axis=axis), axis, 0)
    assert np.all(np.sum(fixed[1:] * fixed[:-1], axis=-1) >= 0.0)
    np.testing.assert_array_equal(fixed[0], (smooth * signs)[0])  # first frame kept
    np.testing.assert_allclose(np.abs(fixed), np.abs(smooth))  # only signs change


@pytest.mark.parametrize("order", EULER_ORDERS)
def test_euler_nearest_restores_any_branch(order: str) -> None:
    rng = np.random.default_rng(11)
    source = rng.uniform(-500.0, 500.0, (400, 3))  # middle angles far outside +-90 too
    # Some at and near gimbal lock, half of them with the middle angle a turn up.
    source[:40] = near_lock_angles(12)[::3][:40] + [0.0, 360.0, 0.0] * rng.integers(0, 2, (40, 1))
    principal = quat_to_euler(euler_to_quat(source, order), order)
    assert np.max(np.abs(principal - source)) > 90.0  # the test needs other branches
    np.testing.assert_allclose(euler_nearest(principal, source, order), source, atol=1e-8)


def test_to_channels_restores_source_branches() -> None:
    # One joint per Euler order, plus one- and two-axis joints, angles on many branches.
    channels = [(0, 1, 2) + tuple(3 + "XYZ".index(a) for a in order) for order in EULER_ORDERS]
    channels += [(4,), (5, 3), (3, 4)]
    n = len(channels)
    sk = Skeleton(names=[f"n{i}" for i in range(n)], parents=[-1] + list(range(n - 1)),
                  offsets=np.ones((n, 3)), channels=channels, is_end_site=[False] * n)
    rng = np.random.default_rng(13)
    source = rng.uniform(-400.0, 400.0, (60, sk.channel_count))
    motion = Motion.from_channels(sk, source, 1 / 30)
    np.testing.assert_allclose(motion.to_channels(source), source, atol=1e-8)
    # Without a reference the angles change branch but describe the same rotations,
    # including two-axis joints whose second angle lies beyond +-90.
    plain = motion.to_channels()
    assert np.max(np.abs(plain - source)) > 90.0
    again = Motion.from_channels(sk, plain, 1 / 30)
    assert np.max(rotation_angle(again.rotations, motion.rotations)) < 1e-9
    np.testing.assert_allclose(again.translations, motion.translations)


def test_quat_from_matrix_matches_scipy_including_near_180_degrees():
    from scipy.spatial.transform import Rotation

    from mocodec.rotations import quat_from_matrix

    rng = np.random.default_rng(7)
    rots = Rotation.random(500, random_state=11)
    flips = Rotation.from_rotvec(np.pi * (1 - 1e-9) * rng.normal(size=(50, 3)) /
                                 np.linalg.norm(rng.normal(size=(50, 3)), axis=1, keepdims=True))
    for r in (rots, flips):
        q = quat_from_matrix(r.as_matrix())
        expect = r.as_quat()
        sign = np.sign(np.sum(q * expect, axis=1, keepdims=True))
        assert np.allclose(q, sign * expect, atol=1e-9)
