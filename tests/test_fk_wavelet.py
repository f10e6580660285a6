"""Codec ``fk-wavelet`` (seed 000 §4, docs/FORMAT.md FKWV version 2): the transform and the
blocks, the tolerance promise through the C runtime on every frame, C vs the Python reference
decoder, the same poses in any access order, the scratch budget, progressive band order, and
rejection of damaged payloads."""
from __future__ import annotations

import platform
import struct

import numpy as np
import pytest
import pywt

from mocodec.codecs import fk_wavelet as W
from mocodec.encode import _single_clip_asset, encode_motions, make_check
from mocodec.io import read_bvh
from mocodec.kinematics import forward_kinematics
from mocodec.motion import Motion
from mocodec.runtime import Asset
from mocodec.tolerance import Tolerance
from mocodec.units import resolve_units
from mocodec_runtime import RuntimeResultError

CM = 5.6444
X86_64 = platform.machine().lower() in ("x86_64", "amd64")


def _encode(motions, tol, **options):
    units = [resolve_units(m.skeleton, "cmu", None) for m in motions]
    return encode_motions(motions, units, "fk-wavelet", Tolerance(tol), options)


def _world_error_cm(asset: Asset, motion) -> np.ndarray:
    _, pos_o = forward_kinematics(motion.skeleton, motion.rotations, motion.translations)
    _, pos_d = asset.sample_frames(motion.name, world=True)
    return np.linalg.norm(pos_o - pos_d, axis=-1) * CM


def _encode_clip(motion, tol, **options):
    check = make_check([motion], [CM], "fk-wavelet")
    settings = W.FkWaveletSettings(Tolerance(tol), **options)
    return W.encode_clip(motion, CM, settings, lambda p: check(0, p))


def _head(motion, frames: int) -> Motion:
    return Motion(motion.skeleton, motion.rotations[:frames].copy(), motion.translations[:frames].copy(),
                  motion.frame_time, motion.name)


@pytest.fixture(scope="module")
def clip_07_01(sample_paths):
    m = read_bvh(next(p for p in sample_paths if p.stem == "07_01"))
    return m, _encode_clip(m, 1.0)


@pytest.fixture(scope="module")
def small_clip(sample_paths):
    """56 frames of 09_11 at 3 cm in blocks of 16: three full blocks and a last one of 8 frames
    with one level fewer (no approximation offsets)."""
    m = _head(read_bvh(next(p for p in sample_paths if p.stem == "09_11")), 56)
    return m, _encode_clip(m, 3.0, block_frames=16)


# ------------------------------------------------------------------------ transform
@pytest.mark.parametrize("frames", [1, 2, 3, 4, 5, 7, 8, 9, 16, 17, 31, 100, 257])
def test_lifting_reconstructs_every_length(frames):
    rng = np.random.default_rng(frames)
    x = rng.standard_normal((frames, 3))
    levels = W.max_levels(frames)
    bands = W.forward(x, levels)
    assert [len(b) for b in bands] == W.band_rows(frames, levels)
    assert sum(len(b) for b in bands) == frames  # non-expansive
    y = W.inverse_f32([b.astype(np.float32) for b in bands])
    assert np.abs(y - x).max() < 1e-5


def test_lifting_is_the_bior44_filter_pair():
    """Away from the ends, one level equals PyWavelets' bior4.4 up to a fixed scale."""
    x = np.random.default_rng(0).standard_normal(256)
    s, d = (b[:, 0] for b in W.forward(x[:, None], 1))
    ca, cd = pywt.dwt(x, "bior4.4", mode="periodization")
    inner = slice(20, 100)
    np.testing.assert_allclose(ca[inner], np.sqrt(2.0) * s[inner], rtol=0, atol=1e-6)  # float32 constants
    np.testing.assert_allclose(cd[inner], -d[inner] / np.sqrt(2.0), rtol=0, atol=1e-6)  # float32 constants


def test_step_codes_match_the_documented_formula():
    for e in [0, 1, 2, 3, 200, 257, 296]:
        assert W.step_value(e) == np.float32(2.0 ** (e / 4 - 64))


@pytest.mark.parametrize("frames, block, levels", [(1, 64, 6), (60, 16, 4), (64, 64, 6), (130, 64, 6), (1000, 70, 7)])
def test_blocks_cover_the_clip_once(frames, block, levels):
    groups = W.block_groups(frames, block, levels)
    covered = np.concatenate([np.arange(g.first, g.first + g.count * g.frames) for g in groups])
    assert np.array_equal(covered, np.arange(frames))
    for g in groups:
        assert g.levels == W.max_levels(g.frames, levels) and sum(W.band_rows(g.frames, g.levels)) == g.frames
        x = np.random.default_rng(frames).standard_normal((frames, 4))
        assert np.array_equal(g.frames_of(g.columns(x), 4), x[g.first: g.first + g.count * g.frames])


def test_block_length_keeps_the_scratch_within_its_budget():
    # CMU (38 nodes, 27 rotations and the root translation) and 64 nodes that all rotate.
    assert W.choose_block(65, 111, 32768) == 65
    assert W.SCRATCH_HEADER + W.scratch_bytes(65, 111) == 29984
    b = W.choose_block(65, 4 * 64 + 3, 32768)
    assert b == 29 and W.SCRATCH_HEADER + W.scratch_bytes(b, 259) == 32272 <= 32768
    assert W.SCRATCH_HEADER + W.scratch_bytes(b + 1, 259) > 32768
    assert W.choose_block(65, 111, 1) == 1


# ------------------------------------------------------------------------ the promise
@pytest.mark.parametrize("tol", [1.0, 3.0])
def test_tolerance_holds_on_every_frame_of_every_sample(sample_paths, tol):
    motions = [read_bvh(p) for p in sample_paths]
    result = _encode(motions, tol)
    asset = Asset(result.asset)
    for m in motions:
        err = _world_error_cm(asset, m)
        assert err.shape == (m.frame_count, m.skeleton.node_count)
        assert err.max() <= tol, (m.name, err.max())
        assert err.max() > 0.3 * tol  # the codec spends the tolerance
    # Each clip's record states the scratch the runtime computes, within the 32 KiB budget.
    for info in asset.clips:
        assert info.scratch_size <= 32768
    assert asset.scratch_size == max(info.scratch_size for info in asset.clips)


def test_looser_tolerance_gives_a_smaller_asset(sample_paths):
    motions = [read_bvh(p) for p in sample_paths]
    assert len(_encode(motions, 3.0).asset) < 0.8 * len(_encode(motions, 1.0).asset)


def test_fk_compensation_makes_the_clip_smaller(clip_07_01):
    m, r = clip_07_01
    plain = _encode_clip(m, 1.0, compensate=False)
    assert len(r.payload) < len(plain.payload)


def test_a_smaller_scratch_budget_gives_shorter_blocks_and_keeps_the_promise(clip_07_01):
    m, r = clip_07_01
    small = _encode_clip(m, 1.0, max_scratch_bytes=8192)
    p = W.parse(small.payload)
    assert p.block < W.parse(r.payload).block and W.SCRATCH_HEADER + W.scratch_bytes(p.block, p.channels) <= 8192
    asset = Asset(_single_clip_asset(m, CM, "fk-wavelet", small.payload))
    assert asset.clips[0].scratch_size <= 8192
    assert _world_error_cm(asset, m).max() <= 1.0


# ------------------------------------------------------------------------ C vs Python
def _runtime_positions(info, times: np.ndarray) -> np.ndarray:
    """The frame positions the runtime samples at for ``times`` (binary32 time × rate)."""
    return (times.astype(np.float32) * np.float32(info.frame_rate)).astype(np.float32)


def test_c_runtime_and_python_reference_agree(clip_07_01):
    m, r = clip_07_01
    asset = Asset(_single_clip_asset(m, CM, "fk-wavelet", r.payload))
    info = asset.clips[0]
    assert info.scratch_size == W.SCRATCH_HEADER + W.scratch_bytes(W.parse(r.payload).block, W.parse(r.payload).channels)
    # Every frame, then 501 positions in between (most on the segments inside blocks, some
    # between blocks), at the frame positions the runtime computes from the times.
    rot_c, trans_c = asset.sample_frames(0, world=False)
    rot_py, trans_py = W.decode_payload(r.payload, m.skeleton)
    times = (np.linspace(0, m.frame_count - 1, 501) / info.frame_rate).astype(np.float32)
    poses = asset.sample_times(0, times).astype(np.float64)
    mid_rot, mid_trans = W.decode_payload(r.payload, m.skeleton, _runtime_positions(info, times))
    for c, py in ((rot_c, rot_py), (trans_c, trans_py), (poses[..., :4], mid_rot), (poses[..., 4:7], mid_trans)):
        assert np.abs(c - py).max() <= 1e-5 * max(1.0, np.abs(py).max())
        if X86_64:  # the same binary32 operations in the same order: the same bits
            assert np.array_equal(c, py)


def test_two_encodes_are_byte_identical(clip_07_01):
    m, r = clip_07_01
    assert _encode_clip(m, 1.0).payload == r.payload


def test_sequential_random_and_backward_sampling_agree_bit_for_bit(small_clip):
    m, r = small_clip
    data = _single_clip_asset(m, CM, "fk-wavelet", r.payload)
    asset = Asset(data)
    info = asset.clips[0]
    # Every frame, every midpoint and the instants just before each block boundary.
    x = np.unique(np.concatenate((np.arange(0, m.frame_count - 0.5, 0.5), np.arange(16, 56, 16) - 0.01)))
    times = (x / info.frame_rate).astype(np.float32)
    forward = asset.sample_times(0, times)
    order = np.random.default_rng(3).permutation(len(times))
    backward = asset.sample_times(0, times[::-1])[::-1]
    shuffled = np.empty_like(forward)
    shuffled[order] = asset.sample_times(0, times[order])
    fresh = np.stack([Asset(data).sample(0, float(t)) for t in times[::7]])
    assert forward.tobytes() == backward.tobytes()
    assert forward.tobytes() == shuffled.tobytes()
    assert forward[::7].tobytes() == fresh.tobytes()
    assert np.all(np.isfinite(forward))


# ------------------------------------------------------------------------ progressive
def test_progressive_band_order_within_blocks(clip_07_01):
    m, r = clip_07_01
    rows = W.progressive_errors(r.payload, m, CM)
    p = W.parse(r.payload)
    assert len(rows) == p.levels + 1 >= 5
    sizes = [row["bytes"] for row in rows]
    means = [row["mean_cm"] for row in rows]
    assert sizes == sorted(sizes) and sizes[-1] == p.streams_offset + int(p.ends[-1]) <= len(r.payload)
    assert all(b < a for a, b in zip(means, means[1:])), means
    assert rows[-1]["max_cm"] <= 1.0
    assert rows[0]["mean_cm"] > 2.0  # each block's approximation alone is far from the motion
    # All bands are the whole decode.
    full = W.decode_payload(r.payload, m.skeleton)
    every = W.decode_payload(r.payload, m.skeleton, bands=p.levels + 1)
    assert np.array_equal(full[0], every[0]) and np.array_equal(full[1], every[1])


# ------------------------------------------------------------------------ damaged payloads
def _opens(motion, payload: bytes) -> bool:
    try:
        Asset(_single_clip_asset(motion, CM, "fk-wavelet", payload))
    except RuntimeResultError:
        return False
    return True


def test_damaged_payloads_are_rejected(clip_07_01):
    m, r = clip_07_01
    good = r.payload
    assert _opens(m, good)
    p = W.parse(good)
    L = p.levels
    tables = p.tables_offset
    ends_at = tables + -(-(4 * L + 2) // 4) * 4

    def edit(offset: int, fmt: str, value) -> bytes:
        b = bytearray(good)
        struct.pack_into(fmt, b, offset, value)
        return bytes(b)

    last_stream_byte = p.streams_offset + int(p.ends[-1]) - 1
    cases = {
        "frames": edit(0, "<I", p.frames + 1),
        "nodes": edit(4, "<I", p.nodes - 1),
        "channels": edit(8, "<I", p.channels - 1),
        "block length zero": edit(12, "<H", 0),
        "block length": edit(12, "<H", p.block + 1),
        "levels too many for the block": edit(14, "<B", L + 1),
        "levels fewer": edit(14, "<B", L - 1),
        "roi gain past the bound": edit(15, "<B", 31),
        "rotation mode": edit(W.HEADER, "<B", 1),
        "step code past the bound": edit(W.HEADER + 2, "<B", 255),
        "approximation code past the bound": edit(tables + L, "<B", 255),
        "detail code past the bound": edit(tables + L + 1, "<B", 255),
        "roi shift past the bound": edit(tables + 2 * L + 1, "<B", 31),
        "table padding": edit(tables + 4 * L + 2, "<B", 1),  # 4L + 2 table bytes: always 2 of padding
        "offsets stream end": edit(ends_at, "<I", int(p.ends[0]) + 1),
        "block stream ends out of order": edit(ends_at + 4, "<I", int(p.ends[2]) + 1),
        "stream byte": edit(p.streams_offset + int(p.ends[1]) + 5, "<B", good[p.streams_offset + int(p.ends[1]) + 5] ^ 0x5A),
        "last stream byte": edit(last_stream_byte, "<B", good[last_stream_byte] ^ 0x77),
        "padding": good[:-1] + b"\1" if len(good) > last_stream_byte + 1 else good[:-4],
        "truncated": good[:-4],
        "extended": good + bytes(4),
    }
    for name, payload in cases.items():
        assert payload != good, name
        assert not _opens(m, payload), name


def test_every_truncation_is_rejected(small_clip):
    m, r = small_clip
    data = _single_clip_asset(m, CM, "fk-wavelet", r.payload)
    for n in range(len(data)):
        with pytest.raises(RuntimeResultError):
            Asset(data[:n])
    for n in range(0, len(r.payload), 4):
        assert not _opens(m, r.payload[:n]), n


def test_every_byte_flip_is_rejected_or_samples_finite(small_clip):
    """Each byte of the payload changed (the CRC is rewritten with the asset, so the codec's
    own checks are reached): the runtime rejects the asset or samples finite poses, in order
    and in reverse."""
    m, r = small_clip
    rng = np.random.default_rng(7)
    times = (np.arange(0, 2 * m.frame_count) / (2 * 120.0)).astype(np.float32)
    accepted = 0
    for pos in range(len(r.payload)):
        b = bytearray(r.payload)
        b[pos] ^= int(rng.integers(1, 256))
        try:
            asset = Asset(_single_clip_asset(m, CM, "fk-wavelet", bytes(b)))
        except RuntimeResultError:
            continue
        accepted += 1
        poses = asset.sample_times(0, times)
        assert np.all(np.isfinite(poses)) and np.all(np.isfinite(asset.sample_times(0, times[::-1])))
    assert accepted < len(r.payload) // 2


# ------------------------------------------------------------------------ ROI (max-shift)
FEET = ("LeftFoot", "RightFoot", "LeftToeBase", "RightToeBase")


def test_roi_holds_the_tight_tolerance_on_constraint_frames_only(clip_07_01):
    m, plain = clip_07_01
    roi = _encode_clip(m, 1.0, roi_frames=((150, 180),), roi_nodes=FEET, roi_tolerance_cm=0.1)
    p = W.parse(roi.payload)
    assert p.roi_gain >= 1 and p.shifts.detail.max() >= 1 and not p.shifts.approx.any()
    # Measured through the runtime from the finished asset, not the encoder's own check.
    asset = Asset(_single_clip_asset(m, CM, "fk-wavelet", roi.payload))
    err = _world_error_cm(asset, m)
    feet = [m.skeleton.index(n) for n in FEET]
    assert err[150:181][:, feet].max() <= 0.1
    assert err.max() <= 1.0
    assert err[:140][:, feet].max() > 0.2  # outside the region only the clip tolerance holds
    # Cheaper than holding the feet to 0.1 cm on every frame.
    tight = _encode_clip(m, 1.0, roi_frames=((0, m.frame_count - 1),), roi_nodes=FEET,
                         roi_tolerance_cm=0.1)
    assert len(plain.payload) < len(roi.payload) < len(tight.payload)


def test_roi_values_decode_the_same_in_c_and_python(clip_07_01):
    m, _ = clip_07_01
    roi = _encode_clip(m, 1.0, roi_frames=((40, 60), (200, 230)), roi_tolerance_cm=0.2)
    asset = Asset(_single_clip_asset(m, CM, "fk-wavelet", roi.payload))
    rot_c, trans_c = asset.sample_frames(0, world=False)
    rot_py, trans_py = W.decode_payload(roi.payload, m.skeleton)
    assert np.abs(rot_c - rot_py).max() <= 1e-5
    assert np.abs(trans_c - trans_py).max() <= 1e-5 * max(1.0, np.abs(trans_py).max())
    # The max-shift rule matters: read every value as background and the poses move.
    p = W.parse(roi.payload)
    b = bytearray(roi.payload)
    at = p.tables_offset + 2 * p.levels + 1
    b[at: at + 2 * p.levels + 1] = bytes(2 * p.levels + 1)
    wrong = W.decode_payload(bytes(b), m.skeleton)
    assert np.abs(wrong[0] - rot_py).max() > 1e-3
