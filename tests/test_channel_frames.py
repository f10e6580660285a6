"""A long clip's rotations and translations computed from its channels where they are read
(mocodec.channel_frames): the numbers Motion.from_channels holds for a short clip, bit for bit,
however they are indexed; read-only; and an encode of such a clip never builds them whole."""
from __future__ import annotations

import pickle

import numpy as np
import pytest

import mocodec.channel_frames
import mocodec.motion
from mocodec.channel_frames import ChannelFrames
from mocodec.io import read_bvh
from mocodec.motion import Motion


def _both(path, monkeypatch) -> tuple[Motion, Motion]:
    """The clip at ``path`` held whole, and computed from its channels (signs found in runs
    of 7 frames, so that sign changes fall across runs)."""
    monkeypatch.setattr(mocodec.motion, "CHANNEL_FRAMES_BYTES", 1 << 62)
    held = read_bvh(path)
    monkeypatch.setattr(mocodec.motion, "CHANNEL_FRAMES_BYTES", -1)
    monkeypatch.setattr(mocodec.channel_frames, "SIGN_RUN", 7)
    lazy = Motion.from_channels(held.skeleton, held.source_channels, held.frame_time, held.name)
    lazy.source = held.source  # (the asset records where a clip came from)
    assert isinstance(lazy.rotations, ChannelFrames) and isinstance(lazy.translations, ChannelFrames)
    assert not isinstance(held.rotations, ChannelFrames)
    return held, lazy


def test_every_index_gives_the_held_numbers(sample_paths, monkeypatch) -> None:
    for path in sample_paths:
        held, lazy = _both(path, monkeypatch)
        f = held.frame_count
        rng = np.random.default_rng(f)
        rows = rng.integers(0, f, 50)
        keys = [slice(None), slice(3, 40), slice(f - 5, None), 0, f - 1, -2, rows, rows.tolist(),
                (slice(None), 2), (rows, 0), (5, 3), (slice(10, 20), slice(1, 6)), (slice(None), 1, 2),
                (slice(None), -1), (np.arange(f) % 3 == 0,), (Ellipsis, 0), (rows[:3], [0, 1, 2]),
                (rows[:3], 1, [0, 1, 2]), (slice(None), [0, 2], [0, 1]), (slice(None), np.int64(1)),
                (rows, np.array(2))]
        for key in keys:
            for part in ("rotations", "translations"):
                want, got = getattr(held, part)[key], getattr(lazy, part)[key]
                assert got.shape == want.shape and np.array_equal(got, want), (path.name, part, key)
        assert np.array_equal(np.asarray(lazy.rotations), held.rotations)
        assert lazy.rotations.shape == held.rotations.shape and len(lazy.translations) == f
        assert np.array_equal(lazy.rotations.mean(axis=0), held.rotations.mean(axis=0))  # other ndarray attributes


def test_computed_frames_are_read_only_and_pickle(sample_paths, monkeypatch) -> None:
    held, lazy = _both(sample_paths[0], monkeypatch)
    with pytest.raises(TypeError, match="cannot be changed in place"):
        lazy.rotations[0, 0] = (0.0, 0.0, 0.0, 1.0)
    back = pickle.loads(pickle.dumps(lazy))
    assert np.array_equal(back.rotations[:], held.rotations)
    assert np.array_equal(back.translations[7:9, 0], held.translations[7:9, 0])


def _whole_digest(m: Motion) -> str:
    """motion_digest as it was before it read runs of frames (each array hashed whole), so
    that caches written before still match."""
    import hashlib
    import json
    sk = m.skeleton
    h = hashlib.sha256()
    h.update(json.dumps([sk.names, sk.channels, repr(float(m.frame_time))]).encode())
    for a in (sk.parents, sk.offsets, sk.is_end_site, sk.rest_rotations, sk.rest_scales, sk.is_virtual,
              m.rotations, m.translations, m.scales, m.source_channels):
        a = np.ascontiguousarray(a)
        h.update(f"{a.dtype.str}{a.shape};".encode())
        h.update(a.tobytes())
    return h.hexdigest()


def test_bake_cache_digest_and_memory_of_a_clip_computed_from_channels(sample_paths, monkeypatch) -> None:
    """A clip computed from its channels has the digest of the same clip held whole (a bake
    cache keeps its entries), and counts the memory it keeps, not the whole arrays'."""
    from mocodec.bake.fingerprint import motion_digest
    from mocodec.bake.library import motion_bytes

    monkeypatch.setattr(mocodec.motion, "FRAME_RUN", 11)  # the digest reads runs of frames
    held, lazy = _both(sample_paths[1], monkeypatch)
    assert motion_digest(lazy) == motion_digest(held) == _whole_digest(held)
    f, n = held.frame_count, held.skeleton.node_count
    assert motion_bytes(lazy) < motion_bytes(held) - f * n * 7 * 8 + f * n


def test_signs_follow_the_whole_clip(monkeypatch) -> None:
    """A joint turning round several times: its quaternion changes hemisphere, and each run of
    frames keeps the sign the whole clip's continuity gives it."""
    from mocodec.motion import Skeleton
    sk = Skeleton(["Hips", "Arm", "Arm_End"], [-1, 0, 1], [[0, 90, 0], [0, 10, 0], [0, 30, 0]],
                  [(0, 1, 2, 5, 3, 4), (5, 3, 4), ()], [False, False, True])
    f = 500
    channels = np.zeros((f, 9))
    # Arm's Z turns round four times, its angle written in [-180, 180) as capture software
    # does: each wrap negates the quaternion, which continuity flips back.
    channels[:, 6] = (np.linspace(0.0, 1500.0, f) + 180.0) % 360.0 - 180.0
    channels[:, 3] = 30.0 * np.sin(np.arange(f) / 17.0)
    monkeypatch.setattr(mocodec.channel_frames, "SIGN_RUN", 13)
    held = Motion.from_channels(sk, channels, 1 / 120, "turns")
    monkeypatch.setattr(mocodec.motion, "CHANNEL_FRAMES_BYTES", -1)
    lazy = Motion.from_channels(sk, channels, 1 / 120, "turns")
    assert lazy.rotations._negated.any() and not lazy.rotations._negated.all()
    assert np.array_equal(lazy.rotations[:], held.rotations)


def test_a_long_clip_from_channels_encodes_without_its_whole_frames(sample_paths, monkeypatch) -> None:
    """The long-clip encode path reads a clip computed from its channels a run of frames or a
    node at a time, never whole, and writes the bytes of the clip held whole (every run
    shrunk to 97 frames, so that a sample clip is many runs)."""
    import mocodec.clip_plan
    import mocodec.curves
    import mocodec.keyframes
    import mocodec.kinematics
    import mocodec.quantize
    import mocodec.runtime
    import mocodec.tolerance
    from mocodec.encode import encode_motions
    from mocodec.tolerance import Tolerance
    from mocodec.units import resolve_units

    held, lazy = _both(sample_paths[0], monkeypatch)
    units = [resolve_units(held.skeleton, "cmu")]
    run = 97
    monkeypatch.setattr(mocodec.kinematics, "SHORT_CLIP_BYTES", -1)
    for module, name in [(mocodec.curves, "CURVE_CHUNK"), (mocodec.keyframes, "TARGET_CHUNK"),
                         (mocodec.clip_plan, "SPAN_CHUNK"), (mocodec.kinematics, "HALFWAY_CHUNK"),
                         (mocodec.kinematics, "POSE_CHUNK"), (mocodec.motion, "FRAME_RUN"),
                         (mocodec.runtime, "CHUNK_FRAMES"), (mocodec.quantize, "ROUNDTRIP_CHUNK"),
                         (mocodec.tolerance, "RATIO_CHUNK")]:
        monkeypatch.setattr(module, name, run)
    assert held.frame_count > 3 * run
    want = encode_motions([held], units, "rma", Tolerance(1.0)).asset

    def whole(self, *args, **kwargs):
        raise AssertionError(f"the long-clip path built the clip's whole {self.part}")
    read = ChannelFrames.__getitem__

    def bounded(self, key):
        out = read(self, key)
        # A node's column over the clip is F x 4 numbers; more frames than a run (and its
        # neighbour) of more than one node is the clip's frames built whole.
        assert out.ndim < 3 or out.shape[0] <= run + 1, (self.part, out.shape)
        return out
    monkeypatch.setattr(ChannelFrames, "__array__", whole)
    monkeypatch.setattr(ChannelFrames, "__getitem__", bounded)
    assert encode_motions([lazy], units, "rma", Tolerance(1.0)).asset == want
