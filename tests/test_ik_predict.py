"""Codec ``ik-predict`` (seed 000 §3.2, §5; docs/FORMAT.md IKPR): the closed loop is exact over
thousands of frames, the tolerance holds on every frame, every access order gives the same
bytes, encodes are deterministic, damaged payloads are rejected or sample finite poses, and
bad options fail clearly."""
from __future__ import annotations

import struct

import numpy as np
import pytest

from mocodec.codecs import ClipResult
from mocodec.codecs import ik_predict as I
from mocodec.encode import _single_clip_asset, encode_motions, make_check
from mocodec.io import read_bvh
from mocodec.kinematics import forward_kinematics
from mocodec.motion import Motion
from mocodec.runtime import TRANSFORM_FLOATS, Asset
from mocodec.tolerance import Tolerance, effector_nodes
from mocodec.units import resolve_units
from mocodec_runtime import RuntimeResultError
from runtime_accepts import runtime_accepts

CM = 5.6444


def _sample(sample_paths, name: str) -> Motion:
    return read_bvh(next(p for p in sample_paths if p.stem == name))


def _encode_clip(motion: Motion, tol: Tolerance | float, **options) -> ClipResult:
    tol = tol if isinstance(tol, Tolerance) else Tolerance(tol)
    check = make_check([motion], [CM], "ik-predict")
    return I.encode_clip(motion, CM, I.IkPredictSettings(tol, **options), lambda p: check(0, p))


def _world_error_cm(asset: Asset, motion: Motion, clip: int | str = 0) -> np.ndarray:
    _, pos_o = forward_kinematics(motion.skeleton, motion.rotations, motion.translations)
    _, pos_d = asset.sample_frames(clip, world=True)
    return np.linalg.norm(pos_o - pos_d, axis=-1) * CM


def _looped(motion: Motion, frames: int) -> Motion:
    """The clip played forward and backward until ``frames`` frames (no jump at the seams)."""
    order = np.concatenate((np.arange(motion.frame_count), np.arange(motion.frame_count)[::-1]))
    idx = np.resize(order, frames)
    return Motion(motion.skeleton, motion.rotations[idx], motion.translations[idx],
                  motion.frame_time, f"{motion.name}_looped")


@pytest.fixture(scope="module")
def clip_07_01(sample_paths):
    m = _sample(sample_paths, "07_01")
    return m, _encode_clip(m, 1.0)


# ------------------------------------------------------------------------ closed loop
@pytest.mark.parametrize("max_gap", [1, None])
def test_closed_loop_is_exact_over_5000_frames(sample_paths, max_gap):
    """The encoder's own reconstruction (its closed loop, rerun from the payload's head and
    checked against the payload's codes) equals what the runtime decodes, bit for bit, on
    every coded frame of a 5000-frame clip (every frame with max_gap 1, the seed's IKBP; the
    default skips frames); and the last frames are as accurate as the first."""
    m = _looped(_sample(sample_paths, "02_01"), 5000)
    settings = I.IkPredictSettings(Tolerance(1.0), **({"max_gap": max_gap} if max_gap else {}))
    check = make_check([m], [CM], "ik-predict")
    r = I.encode_clip(m, CM, settings, lambda p: check(0, p))
    mine = I.reconstruction(r.payload, m, CM, settings)
    coded = I.payload_frames(r.payload)
    assert (len(coded) == 5000) == (max_gap == 1)
    asset = Asset(_single_clip_asset(m, CM, "ik-predict", r.payload))
    decoded = asset.sample_times(0, coded / m.frame_rate)
    assert decoded.shape == mine.shape == (len(coded), m.skeleton.node_count, TRANSFORM_FLOATS)
    assert np.array_equal(decoded, mine)
    err = _world_error_cm(asset, m)
    assert err.max() <= 1.0
    # No drift: the error of the last 500 frames is no worse than that of the first 500.
    assert err[-500:].mean() <= 1.5 * err[:500].mean()


def test_reconstruction_rejects_a_payload_of_other_codes(clip_07_01):
    m, r = clip_07_01
    settings = I.IkPredictSettings(Tolerance(1.0), block_frames=32)
    with pytest.raises(ValueError, match="does not reproduce"):
        I.reconstruction(r.payload, m, CM, settings)  # other blocks: other intra frames


# ------------------------------------------------------------------------ the promise
@pytest.mark.parametrize("tol", [1.0, 3.0])
def test_tolerance_holds_on_every_frame_of_every_sample(sample_paths, tol):
    motions = [read_bvh(p) for p in sample_paths]
    units = [resolve_units(m.skeleton, "cmu", None) for m in motions]
    result = encode_motions(motions, units, "ik-predict", Tolerance(tol), {})
    asset = Asset(result.asset)
    for m in motions:
        err = _world_error_cm(asset, m, m.name)
        assert err.shape == (m.frame_count, m.skeleton.node_count)
        assert err.max() <= tol, (m.name, err.max())
        assert err.max() > 0.3 * tol  # the search spends the tolerance
    assert result.max_error_cm <= tol


def test_effector_tolerance_holds(sample_paths):
    m = _sample(sample_paths, "07_01")
    r = _encode_clip(m, Tolerance(2.0, 0.5))
    asset = Asset(_single_clip_asset(m, CM, "ik-predict", r.payload))
    err = _world_error_cm(asset, m)
    eff = effector_nodes(m.skeleton)
    assert err[:, eff].max() <= 0.5
    assert err.max() <= 2.0


def test_looser_tolerance_gives_a_smaller_payload(clip_07_01):
    m, r = clip_07_01
    assert len(_encode_clip(m, 3.0).payload) < 0.8 * len(r.payload)


@pytest.mark.parametrize("options", [{}, {"k": 1.0}, {"k": 2.0}, {"ik": False}, {"block_frames": 1},
                                     {"block_frames": 500}, {"root_velocity": False},
                                     {"max_gap": 1}, {"max_gap": 2}, {"max_gap": 6, "block_frames": 7},
                                     {"max_gap": 16, "gap_fraction": 0.9}])
def test_every_variant_meets_the_tolerance_and_decodes_exactly(sample_paths, options):
    m = _sample(sample_paths, "09_11")
    r = _encode_clip(m, 1.0, **options)
    asset = Asset(_single_clip_asset(m, CM, "ik-predict", r.payload))
    assert _world_error_cm(asset, m).max() <= 1.0  # every frame, coded or interpolated
    coded = I.payload_frames(r.payload)
    assert coded[0] == 0 and coded[-1] == m.frame_count - 1
    default_gap = I.IkPredictSettings(Tolerance(1.0)).max_gap
    assert np.all(np.diff(coded) >= 1) and np.diff(coded).max() <= options.get("max_gap", default_gap)
    assert np.array_equal(asset.sample_times(0, coded / m.frame_rate),
                          I.reconstruction(r.payload, m, CM, I.IkPredictSettings(Tolerance(1.0), **options)))


def test_ik_option_changes_the_stream(clip_07_01):
    m, r = clip_07_01
    plain = _encode_clip(m, 1.0, ik=False)
    assert struct.unpack_from("<H", r.payload, 20)[0] == 5  # CMU: trunk, two arms, two legs
    assert struct.unpack_from("<H", plain.payload, 20)[0] == 0
    assert plain.payload != r.payload


# ------------------------------------------------------------------------ access orders
def test_sequential_random_and_backward_sampling_agree(clip_07_01):
    m, r = clip_07_01
    asset = Asset(_single_clip_asset(m, CM, "ik-predict", r.payload))
    x = np.linspace(0.0, m.frame_count - 1, 4 * m.frame_count + 3)
    times = (x / m.frame_rate).astype(np.float32)
    forward = asset.sample_times(0, times)
    backward = asset.sample_times(0, times[::-1])[::-1]
    order = np.random.default_rng(3).permutation(len(times))
    scattered = np.empty_like(forward)
    scattered[order] = asset.sample_times(0, times[order])
    assert np.array_equal(forward, backward)
    assert np.array_equal(forward, scattered)
    # Between frames the pose lies between its two frames' poses (interpolated, normalised).
    assert np.all(np.isfinite(forward))
    assert np.allclose(np.linalg.norm(forward[..., :4], axis=-1), 1.0, atol=1e-5)


def test_two_encodes_are_byte_identical(clip_07_01):
    m, r = clip_07_01
    assert _encode_clip(m, 1.0).payload == r.payload


def test_payload_codes_round_trip(clip_07_01):
    """The payload's streams hold exactly the closed loop's codes."""
    m, r = clip_07_01
    settings = I.IkPredictSettings(Tolerance(1.0))
    plan = I.analyse(m, CM, settings)
    head = r.payload[: I.head_size(r.payload)]
    head = head[:40] + bytes(4) + head[44:]
    codes, _ = I.closed_loop(head, I.skeleton_records(m.skeleton), plan.targets, plan.effectors)
    assert np.array_equal(codes, I.payload_codes(r.payload))
    assert np.abs(codes).max() > 0


# ------------------------------------------------------------------------ damaged payloads
def _opens(motion: Motion, payload: bytes) -> bool:
    """The codec samples in place, so validation is all that opening checks."""
    return runtime_accepts(motion, CM, "ik-predict", payload)


def _edited(payload: bytes, offset: int, fmt: str, value) -> bytes:
    out = bytearray(payload)
    struct.pack_into(fmt, out, offset, value)
    return bytes(out)


def test_damaged_payloads_are_rejected(clip_07_01):
    m, r = clip_07_01
    good = r.payload
    assert _opens(m, good)
    nodes = m.skeleton.node_count
    chains = struct.unpack_from("<H", good, 20)[0]
    table = I.head_size(good)
    coded = next(i for i in range(nodes) if good[I.HEADER + I.NODE_RECORD * i] == I.ROT_CODED)
    rec = I.HEADER + I.NODE_RECORD * coded

    def edit(offset: int, fmt: str, value) -> bytes:
        return _edited(good, offset, fmt, value)

    cases = {
        "frames": edit(0, "<I", m.frame_count + 1),
        "nodes": edit(4, "<I", nodes - 1),
        "block frames zero": edit(8, "<I", 0),
        "block frames other": edit(8, "<I", 17),
        "joint count": edit(12, "<I", 3),
        "track count": edit(16, "<I", 2),
        "chain count": edit(20, "<H", chains + 1),
        "k negative": edit(24, "<f", -1.0),
        "k nan": edit(24, "<f", float("nan")),
        "effector step zero": edit(28, "<f", 0.0),
        "translation step inf": edit(32, "<f", float("inf")),
        "flags": edit(36, "<B", 2),
        "coded frames zero": edit(44, "<I", 0),
        "coded frames past the clip": edit(44, "<I", m.frame_count + 1),
        "coded frames fewer": edit(44, "<I", m.frame_count - 1),
        "stream bytes": edit(40, "<I", struct.unpack_from("<I", good, 40)[0] + 4),
        "rotation mode": edit(rec, "<B", 3),
        "polar axis": edit(rec + 2, "<B", 3),
        "primary child not a child": edit(rec + 4, "<H", 0),
        "bone axis not unit": edit(rec + 8, "<f", 2.0),
        "direction step zero": edit(rec + 24, "<f", 0.0),
        "twist step huge": edit(rec + 28, "<f", 1e9),
        "chain not connected": edit(I.HEADER + I.NODE_RECORD * nodes + 2 * chains + 2, "<H", nodes - 1),
        "first block offset": edit(table, "<I", 4),
        "block sizes past the streams": edit(table + 4, "<I", 1 << 20),
        "truncated": good[:-4],
        "extended": good + bytes(4),
    }
    for name, payload in cases.items():
        assert payload != good, name
        assert not _opens(m, payload), name


def test_corrupt_streams_fail_cleanly_or_stay_finite(clip_07_01):
    """Flip bytes anywhere: the runtime rejects the asset (validation checks every stream), or
    it samples finite poses: sampling a validated asset cannot fail."""
    m, r = clip_07_01
    rng = np.random.default_rng(11)
    outcomes = {"rejected": 0, "finite": 0}
    times = np.linspace(0, m.duration, 40).astype(np.float32)
    for _ in range(200):
        b = bytearray(r.payload)
        for pos in rng.integers(0, len(b), size=int(rng.integers(1, 4))):
            b[pos] ^= int(rng.integers(1, 256))
        try:
            asset = Asset(_single_clip_asset(m, CM, "ik-predict", bytes(b)))
        except RuntimeResultError:
            outcomes["rejected"] += 1
            continue
        poses = asset.sample_times(0, times)
        assert np.all(np.isfinite(poses))
        outcomes["finite"] += 1
    assert outcomes["rejected"] > 0 and sum(outcomes.values()) == 200, outcomes


def test_truncations_are_rejected(clip_07_01):
    m, r = clip_07_01
    for cut in range(4, len(r.payload), max(4, len(r.payload) // 97 * 4)):
        assert not _opens(m, r.payload[:-cut]), cut


# ------------------------------------------------------------------------ options
@pytest.mark.parametrize("options, message", [
    ({"k": -1.0}, "k must be"),
    ({"k": 5.0}, "k must be"),
    ({"block_frames": 0}, "block_frames"),
    ({"block_frames": 2.5}, "block_frames"),
    ({"effector_step_cm": -0.1}, "effector_step_cm"),
    ({"effector_fraction": 0.0}, "effector_fraction"),
    ({"search_steps": 0}, "search_steps"),
    ({"max_gap": 0}, "max_gap"),
    ({"max_gap": 256}, "max_gap"),
    ({"gap_fraction": 1.0}, "gap_fraction"),
    ({"relax_target": 1.5}, "relax_target"),
])
def test_bad_options_fail_clearly(sample_paths, options, message):
    m = _sample(sample_paths, "09_11")
    with pytest.raises(ValueError, match=message):
        _encode_clip(m, 1.0, **options)


def test_unknown_option_is_named(sample_paths):
    m = _sample(sample_paths, "09_11")
    units = [resolve_units(m.skeleton, "cmu", None)]
    with pytest.raises(TypeError, match="bogus"):
        encode_motions([m], units, "ik-predict", Tolerance(1.0), {"bogus": 1})
