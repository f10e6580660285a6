"""Seed 000 groundwork (mocodec.ikfk): converted angles, motion chains, the chain Jacobian and
IK prediction step, and the SPBLF / DWT / IBKF baselines' round trips."""
from __future__ import annotations

import numpy as np
import pytest

from mocodec.entropy import entropy_decode
from mocodec.ikfk.angles import bone_axes, from_converted, to_converted
from mocodec.ikfk.baselines import (
    channel_steps, dwt_decode, dwt_encode, dwt_error_bound, ibkf_decode, ibkf_encode,
    select_key_frames, spblf_decode, spblf_encode, DWTStream, WAVELET, WAVELET_MODE,
)
from mocodec.ikfk.chains import motion_chains
from mocodec.ikfk.jacobian import (
    closed_loop_decode, closed_loop_encode, effector_offset, jacobian, link_angles, predict_step, residual_energy_ratio,
)
from mocodec.io.bvh import read_bvh
from mocodec.kinematics import world_positions
from mocodec.motion import Motion, Skeleton
from mocodec.rotations import quat_from_axis_angle, quat_multiply
from mocodec.runtime import RuntimeResultError


@pytest.fixture(scope="module")
def samples(sample_paths) -> dict[str, Motion]:
    return {p.stem: read_bvh(p) for p in sample_paths}


def _synthetic_skeleton() -> Skeleton:
    """Root with a long tail, a spine that branches into a head and two arms (one with a
    thumb), and a zero-length joint between spine and head. Z-up-ish offsets on purpose."""
    rows = [  # name, parent, offset, is_end_site
        ("root", -1, (0, 0, 0), False),
        ("tail", 0, (0, -1, -8), False),          # 1
        ("tail_End", 1, (0, 0, -8), True),        # 2
        ("spine", 0, (0, 0, 10), False),          # 3
        ("neck", 3, (0, 0, 0), False),            # 4 zero-length
        ("head", 4, (0, 0, 6), False),            # 5
        ("head_End", 5, (0, 0, 3), True),         # 6
        ("l_arm", 3, (6, 0, 0), False),           # 7
        ("l_hand", 7, (9, 0, 0), False),          # 8
        ("l_hand_End", 8, (2, 0, 0), True),       # 9
        ("l_thumb", 8, (0.5, 1, 0), False),       # 10
        ("l_thumb_End", 10, (0, 1, 0), True),     # 11
        ("r_arm", 3, (-6, 0, 0), False),          # 12
        ("r_hand", 12, (-9, 0, 0), False),        # 13
        ("r_hand_End", 13, (-2, 0, 0), True),     # 14
    ]
    return Skeleton(
        names=[r[0] for r in rows], parents=[r[1] for r in rows],
        offsets=[r[2] for r in rows],
        channels=[() if r[3] else ((0, 1, 2, 5, 3, 4) if r[1] < 0 else (5, 3, 4)) for r in rows],
        is_end_site=[r[3] for r in rows],
    )


# --------------------------------------------------------------------------------- angles
def test_converted_angles_round_trip_all_frames(samples):
    for name, m in samples.items():
        back = from_converted(to_converted(m), m)
        assert np.abs(world_positions(back) - world_positions(m)).max() < 1e-9, name
        same = np.abs(back.rotations - m.rotations).max(-1)
        flipped = np.abs(back.rotations + m.rotations).max(-1)
        assert np.minimum(same, flipped).max() < 1e-9, name
        # And back to the file's Euler order and 360-degree branch.
        channels = back.to_channels(reference=m.source_channels)
        assert np.abs(channels - m.source_channels).max() < 1e-6, name


def test_converted_angles_of_a_known_pose():
    # One joint whose bone is +X at rest, swung to +Z then twisted by 0.3 rad about +Z:
    # φ = 0 (bone on the polar axis), ψ = 0.3.
    sk = Skeleton(["a", "a_End"], [-1, 0], [(0, 0, 0), (1, 0, 0)], [(3, 4, 5), ()], [False, True])
    swing = quat_from_axis_angle(np.array([0.0, -1.0, 0.0]), np.pi / 2)   # +X → +Z
    twist = quat_from_axis_angle(np.array([0.0, 0.0, 1.0]), 0.3)
    rot = np.zeros((1, 2, 4))
    rot[0, 0] = quat_multiply(twist, swing)
    rot[0, 1, 3] = 1.0
    m = Motion(sk, rot, np.broadcast_to(sk.offsets, (1, 2, 3)).copy(), 1 / 30)
    conv = to_converted(m)
    assert conv.polar[0, 0] == pytest.approx(0.0, abs=1e-12)
    assert conv.twist[0, 0] == pytest.approx(0.3, abs=1e-12)


def test_twist_is_unwrapped_over_frames():
    # A bone spinning about itself through two full turns: ψ must come back as the ramp,
    # not folded into (-π, π].
    sk = Skeleton(["a", "a_End"], [-1, 0], [(0, 0, 0), (0, 2, 0)], [(3, 4, 5), ()], [False, True])
    angles = np.linspace(0.0, 4 * np.pi, 200)
    rot = np.zeros((200, 2, 4))
    rot[:, 0] = quat_from_axis_angle(np.array([0.0, 1.0, 0.0]), angles)
    rot[:, 1, 3] = 1.0
    m = Motion(sk, rot, np.broadcast_to(sk.offsets, (200, 2, 3)).copy(), 1 / 30)
    conv = to_converted(m)
    assert np.allclose(conv.twist[:, 0], angles, atol=1e-9)


def test_bone_axis_through_zero_length_children(samples):
    sk = samples["07_01"].skeleton
    axes = bone_axes(sk)
    unit = lambda v: np.asarray(v) / np.linalg.norm(v)  # noqa: E731
    # Hips' children all start at the hip: its axis follows LHipJoint to LeftUpLeg.
    assert np.allclose(axes[sk.index("Hips")], unit(sk.offsets[sk.index("LeftUpLeg")]))
    # Spine1 -> Neck (zero) -> Neck1.
    assert np.allclose(axes[sk.index("Spine1")], unit(sk.offsets[sk.index("Neck1")]))
    # A joint with a direct non-zero child uses it.
    assert np.allclose(axes[sk.index("LeftArm")], unit(sk.offsets[sk.index("LeftForeArm")]))
    # No descendant at any distance: +Y.
    lone = Skeleton(["a", "a_End"], [-1, 0], [(0, 0, 0), (0, 0, 0)], [(3, 4, 5), ()], [False, True])
    assert np.allclose(bone_axes(lone)[0], [0, 1, 0])


# --------------------------------------------------------------------------------- chains
def test_cmu_chains_are_trunk_two_arms_two_legs(samples):
    sk = samples["07_01"].skeleton
    chains = motion_chains(sk)
    effectors = sorted(sk.names[c.effector] for c in chains)
    assert effectors == sorted(["Head_End", "LeftHandIndex1_End", "RightHandIndex1_End",
                                "LeftToeBase_End", "RightToeBase_End"])
    for c in chains:
        assert c.nodes[0] == sk.index("Hips")
        assert all(sk.parents[b] == a for a, b in zip(c.nodes[:-1], c.nodes[1:]))
        assert all(np.linalg.norm(sk.offsets[b]) > 0 for _, b in c.links)
    arm = next(c for c in chains if sk.names[c.effector] == "LeftHandIndex1_End")
    assert sk.index("LThumb") not in arm.nodes and sk.index("Neck") not in arm.nodes
    # Zero-length LHipJoint, LeftShoulder: in the path, not a link.
    assert sk.index("LeftShoulder") in arm.nodes
    assert all(b != sk.index("LeftShoulder") for _, b in arm.links)


def test_synthetic_chains():
    sk = _synthetic_skeleton()
    chains = motion_chains(sk)
    paths = sorted([sk.names[i] for i in c.nodes] for c in chains)
    assert paths == sorted([
        ["root", "tail", "tail_End"],
        ["root", "spine", "neck", "head", "head_End"],      # straight on through zero length
        ["root", "spine", "l_arm", "l_hand", "l_hand_End"],  # thumb too small: no chain
        ["root", "spine", "r_arm", "r_hand", "r_hand_End"],
    ])
    # A higher threshold (0.6 × 34 units) drops the tail (16 units) and the arms (17 units).
    assert [c.nodes for c in motion_chains(sk, min_reach=0.6)] == [(0, 3, 4, 5, 6)]


# ------------------------------------------------------------------------------- jacobian
def test_jacobian_matches_finite_differences():
    rng = np.random.default_rng(4)
    lengths = rng.uniform(0.5, 3.0, 6)
    theta = np.stack((rng.uniform(0.2, 2.9, 6), rng.uniform(-np.pi, np.pi, 6)), axis=-1)
    J = jacobian(theta, lengths)
    h = 1e-6
    numeric = np.zeros_like(J)
    for j in range(6):
        for a in range(2):
            e = np.zeros_like(theta)
            e[j, a] = h
            numeric[:, 2 * j + a] = (effector_offset(theta + e, lengths)
                                     - effector_offset(theta - e, lengths)) / (2 * h)
    assert np.abs(J - numeric).max() < 1e-8


def test_chain_angles_rebuild_effector(samples):
    m = samples["02_01"]
    pos = world_positions(m)
    for c in motion_chains(m.skeleton):
        f = effector_offset(link_angles(c, pos), c.lengths(m.skeleton))
        assert np.abs(f - (pos[:, c.effector] - pos[:, c.nodes[0]])).max() < 1e-9


def test_prediction_hits_the_delta_closest_to_k_times_last_change():
    rng = np.random.default_rng(7)
    lengths = rng.uniform(0.5, 3.0, 4)
    theta = np.stack((rng.uniform(0.3, 2.8, 4), rng.uniform(-3, 3, 4)), axis=-1)
    dprev = rng.normal(0, 0.02, (4, 2))
    dp = rng.normal(0, 0.05, 3)
    J = jacobian(theta, lengths)
    for k in (0.0, 1.0, 2.0):
        pred, dtheta = predict_step(theta, dprev, dp, lengths, k)
        assert np.allclose(pred, theta + dtheta)
        assert np.allclose(J @ dtheta.ravel(), dp, atol=1e-12)   # the linearised constraint
        # Closest to θ₀ = k·Δθ_prev among solutions: adding any null-space move is farther.
        null = np.linalg.svd(J)[2][3:]
        base = np.linalg.norm(dtheta.ravel() - k * dprev.ravel())
        for v in null:
            assert np.linalg.norm(dtheta.ravel() + 0.01 * v - k * dprev.ravel()) > base
    # k = 0 is the plain minimum-norm solution of eq. 13.
    _, d0 = predict_step(theta, dprev, dp, lengths, 0.0)
    assert np.allclose(d0.ravel(), np.linalg.lstsq(J, dp, rcond=None)[0])


def test_ik_prediction_beats_repeating_the_last_frame(samples):
    # Measured on every bundled clip, from frame 1 (CMU's frame 0 jumps): with k = 0 the IK
    # residual carries less link-endpoint energy than "repeat the last frame" on every chain.
    for name, m in samples.items():
        pos = world_positions(m)[1:]
        for c in motion_chains(m.skeleton):
            r = residual_energy_ratio(link_angles(c, pos), c.lengths(m.skeleton), 0.0)
            assert r["ik_link"] < 0.8, (name, m.skeleton.names[c.effector], r)


@pytest.mark.parametrize("k", [None, 1.0, 2.0])
def test_closed_loop_prediction_does_not_drift(samples, k):
    # The decoder rebuilds the encoder's frames from the codes alone, bit for bit, and every
    # frame stays within half a step of the original: errors do not accumulate.
    m = samples["07_01"]
    pos = world_positions(m)
    step, effector_step = np.radians(0.5), 0.01
    for c in motion_chains(m.skeleton):
        theta, lengths = link_angles(c, pos), c.lengths(m.skeleton)
        eff, codes, recon = closed_loop_encode(theta, lengths, k, step, effector_step)
        decoded = closed_loop_decode(eff, codes, lengths, k, step, effector_step)
        assert np.array_equal(decoded, recon)
        assert np.abs(decoded - theta).max() <= 0.5 * step + 1e-12
        if k is not None:  # the effector stream is itself closed-loop DPCM
            f = effector_offset(theta, lengths)
            assert np.abs(np.cumsum(eff, axis=0) * effector_step - f).max() <= 0.005 + 1e-12


# ------------------------------------------------------------------------------ baselines
def _channels_and_steps(samples, step: float) -> tuple[np.ndarray, np.ndarray]:
    """The shortest bundled clip's BVH channels and its per-channel steps for ``step``."""
    m = samples["09_11"]
    return m.source_channels, channel_steps(m.skeleton, step)


@pytest.mark.parametrize("step", [0.05, 0.5, 2.0])
def test_spblf_round_trip_is_the_closed_loop_within_half_a_step(samples, step):
    x, steps = _channels_and_steps(samples, step)
    stream = spblf_encode(x, steps)
    y = spblf_decode(stream)
    assert np.all(np.abs(x - y) <= 0.5 * steps + 1e-9)
    # The decoder's frames follow eq. 21: each is the last decoded frame plus the coded
    # difference, and that difference is the quantized gap to the *decoded* (not original)
    # last frame, so the codes never exceed half a step away from it.
    codes = entropy_decode(stream.data, x.size).reshape(x.shape)
    assert np.allclose(np.diff(y, axis=0), codes[1:] * steps, atol=1e-9)
    assert np.all(np.abs(x[1:] - y[:-1] - codes[1:] * steps) <= 0.5 * steps + 1e-9)
    assert spblf_encode(x, steps).data == stream.data  # deterministic


@pytest.mark.parametrize("step", [0.1, 1.0])
def test_dwt_round_trip_within_its_synthesis_bound(samples, step):
    import pywt
    x, steps = _channels_and_steps(samples, step)
    stream = dwt_encode(x, steps)
    y = dwt_decode(stream)
    bound = dwt_error_bound(len(x), steps)
    err = np.abs(x - y)
    assert np.all(err <= bound + 1e-9)
    # The decoder rebuilds exactly the synthesis of the rounded coefficients.
    coeffs = pywt.wavedec(x, WAVELET, WAVELET_MODE, stream.level, axis=0)
    rounded = [np.rint(c / steps) * steps for c in coeffs]
    assert np.abs(pywt.waverec(rounded, WAVELET, WAVELET_MODE, axis=0)[: len(x)] - y).max() < 1e-9
    # A truncated stream is rejected, not decoded into noise.
    with pytest.raises(RuntimeResultError):
        dwt_decode(DWTStream(stream.data[:-3], stream.frames, stream.level, stream.steps))


@pytest.mark.parametrize("step,tolerance", [(0.2, 2.0), (1.0, 4.0)])
def test_ibkf_round_trip_within_tolerance(samples, step, tolerance):
    x, steps = _channels_and_steps(samples, step)
    stream = ibkf_encode(x, steps, tolerance)
    y = ibkf_decode(stream)
    assert np.all(np.abs(x - y) <= tolerance * steps + 1e-9)
    keys = select_key_frames(x, steps, tolerance)
    assert stream.key_count == len(keys) < len(x)
    assert np.all(np.abs(x[keys] - y[keys]) <= 0.5 * steps + 1e-9)  # keys: quantization only
    assert np.array_equal(np.cumsum(entropy_decode(stream.keys, stream.key_count)), keys)
