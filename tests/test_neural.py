"""The neural codec (seed 001): the tolerance on every frame through the C runtime, the runtime
against the Python model of the quantized network, determinism, and rejection of corrupted
NEUR payloads. Clips are short slices of the samples so the training stays a few seconds."""
from __future__ import annotations

import struct

import numpy as np
import pytest

import mocodec_runtime
from mocodec.codecs import neural as N
from mocodec.encode import EncodeError, _single_clip_asset, encode_motions, make_check
from mocodec.io import read_bvh
from mocodec.kinematics import forward_kinematics
from mocodec.motion import Motion
from mocodec.runtime import Asset
from mocodec.tolerance import Tolerance
from mocodec.units import resolve_units

CM = 5.6444  # the CMU samples' centimetres per unit
OPTIONS = {"max_frequencies": 12, "iterations": 500}


def _clip(sample_paths, index: int, frames: int = 60) -> Motion:
    return read_bvh(sample_paths[index]).slice(0, frames)


def _encode_payload(m: Motion, tol: float, **options) -> N.NeuralClipResult:
    check = make_check([m], [CM], "neural")
    settings = N.NeuralSettings(Tolerance(tol), **{**OPTIONS, **options})
    return N.encode_clip(m, CM, settings, lambda p: check(0, p))


@pytest.fixture(scope="module")
def encoded(sample_paths) -> tuple[Motion, N.NeuralClipResult]:
    m = _clip(sample_paths, 2)
    return m, _encode_payload(m, 4.0)


def test_tolerance_holds_on_every_frame_of_the_samples(sample_paths):
    motions = [_clip(sample_paths, i) for i in range(3)]
    units = [resolve_units(m.skeleton, "cmu", None) for m in motions]
    result = encode_motions(motions, units, "neural", Tolerance(5.0), OPTIONS)
    asset = Asset(result.asset)
    for m in motions:
        _, pos_o = forward_kinematics(m.skeleton, m.rotations, m.translations)
        _, pos_d = asset.sample_frames(m.name, world=True)
        err = np.linalg.norm(pos_o - pos_d, axis=-1) * CM
        assert err.shape == (m.frame_count, m.skeleton.node_count)
        assert err.max() <= 5.0, (m.name, err.max())
        assert err.max() > 0.5, m.name  # a lossy network, not an accidental raw copy


def test_runtime_agrees_with_the_python_model(encoded):
    m, r = encoded
    asset = Asset(_single_clip_asset(m, CM, "neural", r.payload))
    # Frames and positions between them: the network is defined at any t.
    x = np.concatenate((np.arange(m.frame_count, dtype=np.float64), np.linspace(0.25, m.frame_count - 1.5, 37)))
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
    m = _clip(sample_paths, 0, 40)
    units = [resolve_units(m.skeleton, "cmu", None)]
    with pytest.raises(EncodeError, match="cannot meet the tolerance"):
        encode_motions([m], units, "neural", Tolerance(0.01), {"max_frequencies": 1, "iterations": 50})


def _validate(m: Motion, payload: bytes) -> mocodec_runtime.Result:
    return mocodec_runtime.validate(_single_clip_asset(m, CM, "neural", payload), skip_checksum=True)


def _flip(payload: bytes, byte: int, bit: int) -> bytes:
    b = bytearray(payload)
    b[byte] ^= 1 << bit
    return bytes(b)


def test_corrupted_payload_is_rejected(encoded):
    m, r = encoded
    p = r.payload
    assert _validate(m, p) == mocodec_runtime.Result.OK
    n = m.skeleton.node_count
    k = struct.unpack_from("<H", p, 8)[0]
    truncated = [p[:-4], p[:-8], p[: len(p) // 2], p[:40], p + bytes(4)]
    flips = [
        _flip(p, 0, 0),                  # frame count
        _flip(p, 4, 1),                  # node count
        _flip(p, 8, 6),                  # K past the format's limit
        _flip(p, 12, 0),                 # output count: the sizes no longer add up
        _flip(p, 16, 4),                 # bits = 31 or so
        _flip(p, 17, 0),                 # reserved byte
        _flip(p, 23, 7),                 # first step negative
        _flip(p, 23, 6),                 # first step huge (weights out of bounds)
        _flip(p, 44, 3),                 # node 0 rotation mode unknown
        _flip(p, 44 + 8 * 3 + 2, 7),     # node 3 output index past M
        _flip(p, 44 + 8 * n + 2 * k + (2 if k % 2 else 0) + 3, 6),  # reference quaternion not unit
    ]
    freq = 44 + 8 * n
    assert k > 0
    zero_freq = p[:freq] + bytes(2) + p[freq + 2:]               # frequency 0 is not allowed
    extra = [zero_freq]
    if k % 2:  # the alignment padding after an odd number of frequencies must be zero
        extra.append(p[:freq + 2 * k] + b"\1\0" + p[freq + 2 * k + 2:])
    for bad in truncated + flips + extra:
        assert _validate(m, bad) != mocodec_runtime.Result.OK


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
