"""The neural codec (seed 001): the tolerance on every frame through the C runtime (window
borders included), the runtime against the Python model of the quantized networks, determinism,
and rejection of corrupted NEUR payloads (window table included). Clips are short slices of the
samples in short windows so the training stays a few seconds."""
from __future__ import annotations

import struct

import numpy as np
import pytest

import mocodec_runtime
from mocodec import codecs
from mocodec.codecs import neural as N
from mocodec.encode import EncodeError, _single_clip_asset, encode_motions, make_check
from mocodec.io import read_bvh
from mocodec.kinematics import forward_kinematics
from mocodec.motion import Motion
from mocodec.runtime import Asset
from mocodec.tolerance import Tolerance
from mocodec.units import resolve_units
from runtime_accepts import runtime_accepts

CM = 5.6444  # the CMU samples' centimetres per unit
# Short windows: several windows (and borders) even in a short slice, each trained quickly.
OPTIONS = {"max_frequencies": 8, "iterations": 300, "window_frames": 24}


def _clip(sample_paths, index: int, frames: int = 60, first: int = 0) -> Motion:
    return read_bvh(sample_paths[index]).slice(first, first + frames)


def _encode_payload(m: Motion, tol: float, **options) -> N.NeuralClipResult:
    check = make_check([m], [CM], "neural")
    settings = N.NeuralSettings(Tolerance(tol), **{**OPTIONS, **options})
    return N.encode_clip(m, CM, settings, lambda p: check(0, p))


@pytest.fixture(scope="module")
def encoded(sample_paths) -> tuple[Motion, N.NeuralClipResult]:
    m = _clip(sample_paths, 2, 60, first=1)
    r = _encode_payload(m, 4.0)
    assert len(r.windows) >= 2 and any(w["K"] > 0 for w in r.windows)
    return m, r


def test_tolerance_holds_on_every_frame_of_the_samples(sample_paths):
    motions = [_clip(sample_paths, i) for i in range(3)]
    units = [resolve_units(m.skeleton, "cmu", None) for m in motions]
    result = encode_motions(motions, units, "neural", Tolerance(5.0), OPTIONS)
    asset = Asset(result.asset)
    for m, clip in zip(motions, result.clips):
        _, pos_o = forward_kinematics(m.skeleton, m.rotations, m.translations)
        _, pos_d = asset.sample_frames(m.name, world=True)
        err = np.linalg.norm(pos_o - pos_d, axis=-1) * CM
        assert err.shape == (m.frame_count, m.skeleton.node_count)
        assert err.max() <= 5.0, (m.name, err.max())
        assert err.max() > 0.5, m.name  # a lossy network, not an accidental raw copy
        windows = clip.stats["windows"]
        assert len(windows) >= 3, windows
        # The windows tile the clip, sharing their border frames, which are within tolerance.
        starts = [w[0] for w in windows]
        assert starts[0] == 0 and windows[-1][0] + windows[-1][1] == m.frame_count
        assert all(s + n - 1 == nxt for (s, n, _, _), nxt in zip(windows, starts[1:]))
        assert err[starts].max() <= 5.0


def test_frame_zero_t_pose_gets_its_own_window(sample_paths):
    m = _clip(sample_paths, 0, 100)
    world = forward_kinematics(m.skeleton, m.rotations, m.translations)[1]
    windows = N.initial_windows(world, CM, 40, 20.0)
    assert windows[0] == (0, 2)  # CMU's synthetic frame 0, a jump into frame 1
    assert windows[-1][0] + windows[-1][1] == m.frame_count
    assert max(n for _, n in windows) <= 40
    assert all(s + n - 1 == nxt for (s, n), (nxt, _) in zip(windows, windows[1:]))


def test_runtime_agrees_with_the_python_model(encoded):
    m, r = encoded
    asset = Asset(_single_clip_asset(m, CM, "neural", r.payload))
    # Frames and positions between them: the network is defined at any t.
    borders = np.array([w["start"] for w in r.windows[1:]], dtype=np.float64)
    x = np.concatenate((np.arange(m.frame_count, dtype=np.float64), np.linspace(0.25, m.frame_count - 1.5, 37),
                        borders - 0.5, borders + 0.25))
    times = (x / m.frame_rate).astype(np.float32)
    # Local transforms, chained in float64 on both sides: the comparison is of the network's
    # evaluation, not of the runtime's float32 local-to-world pass (which alone moves an end
    # site by ~1e-4 cm at these distances from the origin).
    pose_c = asset.sample_times(m.name, times, 0).astype(np.float64)
    # The frame position the runtime forms from a float32 time (integers snap back).
    xc = (times * np.float32(m.frame_rate)).astype(np.float64)
    xc = np.where(np.abs(xc - np.rint(xc)) < 1e-4, np.rint(xc), xc)
    rot, trans = N.reference_pose(r.payload, m, xc)
    _, pos_ref = forward_kinematics(m.skeleton, rot, trans)
    _, pos_c = forward_kinematics(m.skeleton, pose_c[..., :4], pose_c[..., 4:7])
    diff_cm = np.abs(pos_c - pos_ref).max() * CM
    assert diff_cm <= 1e-4, diff_cm


def test_same_seed_same_asset_other_seed_other_asset(sample_paths):
    m = _clip(sample_paths, 1, 40)
    a = _encode_payload(m, 6.0, seed=3).payload
    b = _encode_payload(m, 6.0, seed=3).payload
    c = _encode_payload(m, 6.0, seed=4).payload
    assert a == b
    assert a != c


def test_unreachable_tolerance_is_an_error(sample_paths):
    # Windows are halved down to two frames; 16-bit weights cannot reach 1e-5 cm there.
    m = _clip(sample_paths, 0, 6, first=1)
    units = [resolve_units(m.skeleton, "cmu", None)]
    with pytest.raises(EncodeError, match="cannot meet the tolerance"):
        encode_motions([m], units, "neural", Tolerance(1e-5), {"max_frequencies": 1, "iterations": 50})


def _accepted(m: Motion, payload: bytes) -> bool:
    return runtime_accepts(m, CM, "neural", payload, skip_checksum=True)


def _flip(payload: bytes, byte: int, bit: int) -> bytes:
    b = bytearray(payload)
    b[byte] ^= 1 << bit
    return bytes(b)


def _offsets(m: Motion, p: bytes) -> dict[str, int]:
    """Where the parts of a NEUR 2 payload start (docs/FORMAT.md)."""
    n = m.skeleton.node_count
    mo, r, w = struct.unpack_from("<HHH", p, 8)
    refs = N.HEADER_SIZE + N.NODE_ENTRY * n
    table = refs + 16 * r + 8 * mo
    return {"nodes": N.HEADER_SIZE, "refs": refs, "table": table, "block0": table + N.WINDOW_ENTRY * w,
            "windows": w}


def test_corrupted_payload_is_rejected(encoded):
    m, r = encoded
    p = r.payload
    assert _accepted(m, p)
    o = _offsets(m, p)
    t, b0 = o["table"], o["block0"]
    # The block of the first window with frequencies.
    blocks = [struct.unpack_from("<I", p, t + N.WINDOW_ENTRY * i + 8)[0] for i in range(o["windows"])]
    b1 = next(b for b in blocks if struct.unpack_from("<H", p, b)[0] > 0)
    k1 = struct.unpack_from("<H", p, b1)[0]
    assert o["windows"] >= 2 and k1 > 0
    truncated = [p[:-4], p[:-8], p[: len(p) // 2], p[:t + 8], p[:12], p + bytes(4)]
    flips = [
        _flip(p, 0, 0),                  # frame count
        _flip(p, 4, 1),                  # node count
        _flip(p, 8, 0),                  # output count: the sizes no longer add up
        _flip(p, 12, 0),                 # window count
        _flip(p, 12, 7),                 # window count past the frame count
        _flip(p, 14, 0),                 # reserved
        _flip(p, o["nodes"], 3),         # node 0 rotation mode unknown
        _flip(p, o["nodes"] + 8 * 3 + 2, 7),   # node 3 output index past M
        _flip(p, o["refs"] + 3, 6),      # reference quaternion not unit
        _flip(p, t, 0),                  # first window does not start at frame 0
        _flip(p, t + 4, 0),              # first window's frame count: the next one no longer starts on its last frame
        _flip(p, t + N.WINDOW_ENTRY, 1),   # second window's start
        _flip(p, t + 8, 2),              # first block's offset
        _flip(p, t + 12, 2),             # first block's size
        _flip(p, t + N.WINDOW_ENTRY + 12, 5),  # second block's size past the payload
        _flip(p, b1, 6),                 # K past the format's limit
        _flip(p, b1 + 2, 0),             # H: the block size no longer adds up
        _flip(p, b1 + 4, 4),             # bits = 2^4 + ... past 16
        _flip(p, b1 + 5, 0),             # reserved byte
        _flip(p, b1 + 8 + 3, 7),         # first step negative
        _flip(p, b1 + 8 + 3, 6),         # first step huge (weights out of bounds)
        _flip(p, b0 + 8 + 4 * 5 + 3, 7),   # window 0: last step negative
    ]
    # The last window must end on the last frame: shorten it by one.
    last = t + N.WINDOW_ENTRY * (o["windows"] - 1)
    short = bytearray(p)
    struct.pack_into("<I", short, last + 4, struct.unpack_from("<I", p, last + 4)[0] - 1)
    freq = b1 + N.WINDOW_HEADER
    extra = [bytes(short), p[:freq] + bytes(2) + p[freq + 2:]]  # frequency 0 is not allowed
    if k1 % 2:  # the alignment padding after an odd number of frequencies must be zero
        extra.append(p[:freq + 2 * k1] + b"\1\0" + p[freq + 2 * k1 + 2:])
    # Padding after the last block's weight stream must be zero when there is some.
    for i, bad in enumerate(truncated + flips + extra):
        assert not _accepted(m, bad), i


def test_section_version_1_is_unsupported(encoded):
    m, r = encoded
    data = bytearray(_single_clip_asset(m, CM, "neural", r.payload))
    count = struct.unpack_from("<I", data, 24)[0]
    entries = [32 + 16 * i for i in range(count) if data[32 + 16 * i:36 + 16 * i] == b"NEUR"]
    assert len(entries) == 1 and struct.unpack_from("<I", data, entries[0] + 4)[0] == codecs.get("neural").section_version == 2
    struct.pack_into("<I", data, entries[0] + 4, 1)
    assert mocodec_runtime.validate(bytes(data), skip_checksum=True) == mocodec_runtime.Result.UNSUPPORTED


def test_frequency_choice_naive_and_adaptive(sample_paths):
    m = _clip(sample_paths, 0, 50)
    layout = N.pose_layout(m)
    scale, offset = N._normalisation(layout)
    z = (layout.targets - offset) / scale
    rng = np.random.default_rng(0)
    naive = [f for f, _ in N.algorithm1(z, m.frame_count, "naive", 3, 20, False, rng)]
    assert naive == [[], [1], [1, 2], [1, 2, 3]]
    adaptive = [f for f, _ in N.algorithm1(z, m.frame_count, "adaptive", 4, 20, False, rng)]
    last = adaptive[-1]
    assert len(last) == len(set(last)) == 4 and all(0 < k < m.frame_count for k in last)
    # The DCT peak of a residual made of one cosine is that cosine's bin.
    t = (np.arange(m.frame_count) + 0.5) / m.frame_count
    residual = np.outer(np.cos(np.pi * 7 * t), np.linspace(1.0, 2.0, 5))
    assert N.next_frequency(residual, []) == 7
    assert N.next_frequency(residual + 0.5 * np.outer(np.cos(np.pi * 3 * t), np.ones(5)), [7]) == 3
    # A cap on the bin: the peak above it is not taken, the next one below is; none left, None.
    assert N.next_frequency(residual + 0.5 * np.outer(np.cos(np.pi * 3 * t), np.ones(5)), [], 5) == 3
    assert N.next_frequency(residual, [1, 2], 2) is None


def test_highest_bin_follows_hertz_and_frame_rate():
    # sin(pi k t) over F frames: k / (2 (F - 1)) cycles per frame.
    assert N.highest_bin(121, 120.0, 12.0) == 24      # 12 Hz at 120 fps over 121 frames
    assert N.highest_bin(121, 30.0, 12.0) == 60       # a quarter of 30 fps (7.5 Hz) binds first
    assert N.highest_bin(2, 120.0, 12.0) == 0         # a two-frame window: no frequency at all
    with pytest.raises(ValueError, match="max_frequency_hz"):
        N.NeuralSettings(Tolerance(1.0), max_frequency_hz=0.0)


def test_frequencies_and_half_frames_stay_in_band(encoded):
    m, r = encoded
    for w in r.windows:
        assert all(k <= N.highest_bin(w["frames"], m.frame_rate, 12.0) for k in w["freqs"]), w
    # Half-way between frames, where training never looks, the pose stays near the original's
    # own half-way pose (slerp, lerp): within twice the tolerance, not a swing between samples.
    asset = Asset(_single_clip_asset(m, CM, "neural", r.payload))
    q0, q1 = m.rotations[:-1], m.rotations[1:]
    sign = np.where(np.sum(q0 * q1, axis=-1, keepdims=True) < 0.0, -1.0, 1.0)
    rot = q0 + sign * q1
    rot /= np.linalg.norm(rot, axis=-1, keepdims=True)
    _, ref = forward_kinematics(m.skeleton, rot, 0.5 * (m.translations[:-1] + m.translations[1:]))
    _, pos = asset.sample_frames(m.name, np.arange(m.frame_count - 1) + 0.5, world=True)
    assert np.max(np.linalg.norm(pos - ref, axis=-1)) * CM <= 2.0 * 4.0


def test_rotation_targets_stay_continuous_past_pi(sample_paths):
    # A joint that mostly rests and once turns 250 degrees about one axis: relative to its mean
    # it crosses pi. Folded to w >= 0 the rotation vector flipped there (|dv| ~ 2 pi in one
    # frame), and the network's path between those frames went through the identity.
    from dataclasses import replace

    from mocodec.rotations import quat_from_axis_angle

    m = _clip(sample_paths, 0, 120, first=1)
    joint = next(i for i in range(m.skeleton.node_count) if m.skeleton.parents[i] >= 0
                 and m.skeleton.rotation_order(i))
    angle = np.radians(np.concatenate([np.zeros(84), np.linspace(0.0, 250.0, 36)]))
    rotations = m.rotations.copy()
    rotations[:, joint] = quat_from_axis_angle(np.array([0.0, 0.0, 1.0]), angle)
    layout = N.pose_layout(replace(m, rotations=rotations))
    out = layout.entries[joint, 2]
    v = layout.targets[:, out:out + 3]
    step = np.radians(250.0 / 35)
    assert np.max(np.linalg.norm(np.diff(v, axis=0), axis=1)) <= 1.01 * step
    # The vectors still decode to the joint's rotations (angles past pi included).
    q = N.quat_from_axis_angle_vec(v)
    rel = layout.refs[layout.ref_index[joint]]
    back = np.abs(np.sum(rotations[:, joint] * N.R.quat_multiply(rel, q), axis=-1))
    assert np.min(back) > 1.0 - 1e-7  # the reference is stored as float32


def test_rotation_vectors_stay_well_conditioned():
    # A joint wobbling about the identity, then a capture glitch of three 120 degree steps
    # (a full turn), then wobbling again. Continued through the glitch its quaternions sit on the
    # far hemisphere (w ~ -1), where a vector of angle ~2 pi flips its axis on a small turn (seen
    # on 06_13's left hand: 13 cm off half-way between two frames). Folded, unwrapped only
    # between glitches, the vectors stay small and step no more than the rotation does.
    from mocodec.rotations import quat_from_axis_angle, quat_make_continuous

    t = np.linspace(0.0, 1.0, 30)
    axis = np.stack([np.cos(6.0 * t), np.sin(6.0 * t), 0.3 * np.ones_like(t)], axis=1)
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    wobble = quat_from_axis_angle(axis, np.radians(10.0) * np.sin(9.0 * t))  # through the identity
    glitch = quat_from_axis_angle(np.array([1.0, 0.0, 0.0]), np.radians([120.0, 240.0, 360.0]))
    q = quat_make_continuous(np.concatenate([wobble, glitch, wobble]))
    v = N.continuous_rotation_vectors(q)
    calm = np.r_[0:30, 33:63]
    assert np.max(np.linalg.norm(v[calm], axis=1)) <= np.radians(10.0) + 1e-9
    turn = 2.0 * np.arccos(np.clip(np.abs(np.sum(q[1:] * q[:-1], axis=1)), 0.0, 1.0))
    step = np.linalg.norm(np.diff(v, axis=0), axis=1)
    assert np.all((step <= 1.01 * turn + 1e-12) | (np.degrees(turn) > N.GLITCH_TURN_DEG))
    back = np.abs(np.sum(N.quat_from_axis_angle_vec(v) * q, axis=1))
    assert np.min(back) > 1.0 - 1e-12
    # Past pi the angle unwraps (to 200 degrees), but not across a glitch: a 170 degree jump in
    # one frame to 10 degrees starts afresh instead of carrying 2 pi (370 degrees).
    deg = np.concatenate([np.linspace(0.0, 200.0, 41), [370.0, 372.0]])
    v = N.continuous_rotation_vectors(quat_from_axis_angle(np.array([0.0, 0.0, 1.0]), np.radians(deg)))
    assert np.allclose(np.degrees(v[:41, 2]), deg[:41])
    assert np.allclose(np.degrees(v[41:, 2]), [10.0, 12.0])


def test_two_frame_windows_are_straight_lines(sample_paths):
    m = _clip(sample_paths, 0, 40)  # frame 0 is CMU's T-pose: a two-frame window of its own
    r = _encode_payload(m, 4.0)
    model = N.read_payload(r.payload)
    assert model.windows[0].frames == 2
    y = model.parameters(np.array([0.0, 0.25, 0.5, 0.75, 0.999]))
    line = y[0] + np.outer([0.0, 0.25, 0.5, 0.75, 0.999], model.parameters(np.array([0.999]))[0] - y[0]) / 0.999
    assert np.allclose(y, line, atol=1e-5 * np.max(np.abs(y)))
