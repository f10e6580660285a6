"""Codec rma-pca (seed 003's subspace representation, ``--pca-variance``): the error it reaches
is reported and falls as the variance kept grows; C and the Python reference decoder agree;
pieces in several groups decode across their borders; random = sequential access; bad bytes
are rejected at open; the CLI routes ``--codec rma --pca-variance``."""
from __future__ import annotations

import json
import struct
import subprocess
import sys

import numpy as np
import pytest

from mocodec.codecs.rma_pca import RmaPcaSettings
from mocodec.codecs.rma_pca_reference import decode_clip
from mocodec.encode import encode_motions
from mocodec.io import read_bvh
from mocodec.kinematics import forward_kinematics
from mocodec.motion import Motion
from mocodec.runtime import Asset, RuntimeResultError
from mocodec.tolerance import Tolerance
from mocodec.units import resolve_units

CM = 5.6444


def _encode(motions, **options):
    units = [resolve_units(m.skeleton, "cmu", None) for m in motions]
    return encode_motions(motions, units, "rma-pca", Tolerance(1.0), options)


def _sections(data: bytes) -> list[tuple[bytes, int, int, int]]:
    count = struct.unpack_from("<I", data, 24)[0]
    return [struct.unpack_from("<4sIII", data, 32 + 16 * i) for i in range(count)]


def _rmap(data: bytes) -> tuple[bytes, list[tuple[int, bytes]]]:
    """The RMAP section and (absolute offset, payload) of every clip, via docs/FORMAT.md."""
    sections = _sections(data)
    clip = next(s for s in sections if s[0] == b"CLIP")
    sec = next(s for s in sections if s[0] == b"RMAP")
    n = struct.unpack_from("<I", data, clip[2])[0]
    out = []
    for c in range(n):
        _, _, codec, index, poff, psize = struct.unpack_from("<6I", data, clip[2] + 8 + 48 * c)
        assert codec == 6 and sections[index][0] == b"RMAP"
        out.append((sec[2] + poff, data[sec[2] + poff:sec[2] + poff + psize]))
    return data[sec[2]:sec[2] + sec[3]], out


def _world_error_cm(motion, rot, trans) -> np.ndarray:
    _, pos_o = forward_kinematics(motion.skeleton, motion.rotations, motion.translations)
    _, pos_d = forward_kinematics(motion.skeleton, rot, trans)
    return np.linalg.norm(pos_o - pos_d, axis=-1) * CM


@pytest.fixture(scope="module")
def samples(sample_paths):
    return [read_bvh(p) for p in sample_paths]


def _mixed(samples):
    """A walk, a run and the walk again on one skeleton: PPCA cuts it (at frames 191 and 576),
    so it has pieces in both groups."""
    a, b = samples[0], samples[2]
    return Motion(a.skeleton, np.concatenate([a.rotations[1:], b.rotations[1:], a.rotations[1:]]),
                  np.concatenate([a.translations[1:], b.translations[1:], a.translations[1:]]),
                  a.frame_time, "mixed")


@pytest.fixture(scope="module")
def library(samples):
    motions = [*samples, _mixed(samples)]
    return motions, _encode(motions, groups=2, variance=0.98)


def test_error_is_reported_and_falls_with_the_variance_kept(samples):
    low = _encode(samples, groups=1, variance=0.9)
    high = _encode(samples, groups=1, variance=0.995)
    assert not low.promise and low.settings["pca_variance"] == 0.9
    k_low, k_high = low.settings["components"][0], high.settings["components"][0]
    assert 1 <= k_low < k_high
    mean = lambda r: np.average([c.error.mean_cm for c in r.clips], weights=[c.frames for c in r.clips])
    assert mean(high) < mean(low)
    assert high.max_error_cm < low.max_error_cm
    # Bigger bases and more curves cost bytes.
    assert len(high.asset) > len(low.asset)
    # The report is what the runtime decodes.
    a = Asset(high.asset)
    for m, c in zip(samples, high.clips):
        _, pos_d = a.sample_frames(m.name, world=True)
        _, pos_o = forward_kinematics(m.skeleton, m.rotations, m.translations)
        err = np.linalg.norm(pos_o - pos_d, axis=-1) * CM
        assert err.max() == pytest.approx(c.error.max_cm, rel=1e-4)


def test_c_and_python_reference_agree(library):
    motions, result = library
    a = Asset(result.asset)
    section, payloads = _rmap(result.asset)
    for m, (_, payload) in zip(motions, payloads):
        x = np.arange(m.frame_count, dtype=np.float64)
        rot_r, trans_r = decode_clip(section, payload, m.skeleton, x)
        _, pos_c = a.sample_frames(m.name, world=True)
        _, pos_r = forward_kinematics(m.skeleton, rot_r, trans_r)
        assert np.abs(pos_c - pos_r).max() * CM < 5e-3, m.name


def test_pieces_cover_the_clip_and_decode_across_borders(library):
    motions, result = library
    stats = {c.name: c.stats for c in result.clips}
    assert stats["mixed"]["pieces"] >= 2 and len(stats["mixed"]["groups"]) == 2
    section, payloads = _rmap(result.asset)
    a = Asset(result.asset)
    for m, (_, payload) in zip(motions, payloads):
        pieces = struct.unpack_from("<I", payload, 8)[0]
        starts = [struct.unpack_from("<I", payload, 24 + 8 * p)[0] for p in range(pieces)]
        for s in starts[1:]:
            # Just before, on and just after a border: C and the reference agree.
            x = np.array([s - 1, s - 0.5, s - 0.01, s, s + 0.5])
            rot_r, trans_r = decode_clip(section, payload, m.skeleton, x)
            _, pos_r = forward_kinematics(m.skeleton, rot_r, trans_r)
            _, pos_c = a.sample_frames(m.name, x, world=True)
            assert np.abs(pos_c - pos_r).max() * CM < 5e-3
            # Within a piece the pose moves continuously up to the border frame.
            assert np.abs(pos_c[2] - pos_c[3]).max() * CM < 1.0


def test_repeated_pieces_decode_alike_in_c_and_python(samples, library):
    """Seed 003 eq. 6: with ``repeats``, the second walk of the mixed clip (and steps of the
    walks) are coded against their primaries; C follows the reference into the primary's
    curves as the reference decoder does, and the error stays that of direct coding."""
    motions, direct = library
    result = _encode(motions, groups=2, variance=0.98, repeats=True)
    stats = {c.name: c.stats for c in result.clips}
    assert stats["mixed"]["repeated_pieces"] >= 1
    assert stats["mixed"]["repeated_frames"] > 0.3 * motions[-1].frame_count
    a = Asset(result.asset)
    section, payloads = _rmap(result.asset)
    for m, (_, payload), c, d in zip(motions, payloads, result.clips, direct.clips):
        x = np.arange(0, m.frame_count - 1, 0.5)
        rot_r, trans_r = decode_clip(section, payload, m.skeleton, x)
        _, pos_r = forward_kinematics(m.skeleton, rot_r, trans_r)
        _, pos_c = a.sample_frames(m.name, x, world=True)
        assert np.abs(pos_c - pos_r).max() * CM < 5e-3, m.name
        assert c.error.mean_cm < 1.05 * d.error.mean_cm + 0.05, m.name
    # Sequential and random access agree through the primaries too.
    m = motions[-1]
    times = np.arange(0, m.frame_count - 1, 0.7) / m.frame_rate
    seq = np.stack([a.sample(m.name, t) for t in times])
    rand = np.empty_like(seq)
    for i in np.random.default_rng(5).permutation(len(times)):
        rand[i] = a.sample(m.name, times[i])
    assert np.array_equal(seq, rand)


def test_random_access_matches_sequential(library):
    motions, result = library
    a = Asset(result.asset)
    m = motions[-1]
    times = np.arange(0, m.frame_count - 1, 0.37) / m.frame_rate
    seq = np.stack([a.sample(m.name, t) for t in times])
    rng = np.random.default_rng(3)
    order = rng.permutation(len(times))
    rand = np.empty_like(seq)
    for i in order:
        rand[i] = a.sample(m.name, times[i])
    assert np.array_equal(seq, rand)


def test_six_dof_root_path(samples):
    """A clip whose root tilts past 60 degrees takes all six root DOFs out (§3)."""
    from mocodec import rotations as R
    m = samples[2].slice(1, samples[2].frame_count)
    tilt = R.quat_from_axis_angle(np.array([1.0, 0.0, 0.0]), np.linspace(0, np.radians(120), m.frame_count))
    m.rotations = m.rotations.copy()
    m.rotations[:, 0] = R.quat_multiply(tilt, m.rotations[:, 0])
    r = _encode([m], groups=1, variance=0.99)
    assert r.clips[0].stats["six_dof_root"]
    assert r.clips[0].error.mean_cm < 3.0
    section, payloads = _rmap(r.asset)
    x = np.arange(m.frame_count, dtype=np.float64)
    rot_r, trans_r = decode_clip(section, payloads[0][1], m.skeleton, x)
    _, pos_c = Asset(r.asset).sample_frames(m.name, world=True)
    _, pos_r = forward_kinematics(m.skeleton, rot_r, trans_r)
    assert np.abs(pos_c - pos_r).max() * CM < 5e-3


def test_corrupt_sections_are_rejected_or_decode_finite(library):
    motions, result = library
    data = bytearray(result.asset)
    sections = _sections(bytes(data))
    sec = next(s for s in sections if s[0] == b"RMAP")
    rng = np.random.default_rng(11)
    positions = np.concatenate((np.arange(sec[2], sec[2] + 400), rng.integers(sec[2], sec[2] + sec[3], 300)))
    rejected = 0
    for pos in positions:
        bad = bytearray(data)
        bad[pos] ^= 1 << int(rng.integers(0, 8))
        try:
            a = Asset(bytes(bad), skip_checksum=True)
        except RuntimeResultError:
            rejected += 1
            continue
        for m in motions:
            pose = a.sample(m.name, 0.37)
            assert np.all(np.isfinite(pose))
    assert rejected > 100
    # Truncations inside the section are rejected.
    for cut in (16, 40, sec[3] // 2, sec[3] - 4):
        bad = bytes(data[:sec[2] + cut]) + bytes(data[sec[2] + sec[3]:])
        with pytest.raises((RuntimeResultError, ValueError)):
            Asset(bad, skip_checksum=True)


def test_settings_reject_bad_values():
    for bad in ({"variance": 0.0}, {"variance": 1.5}, {"groups": 0}, {"coef_cm": -1}, {"key_grid": 9},
                {"repeats": "yes"}, {"blend_seconds": 2.0}):
        with pytest.raises(ValueError):
            RmaPcaSettings(**bad)


def test_cli_pca_variance_reports_the_error_reached(tmp_path, sample_paths):
    out = tmp_path / "pca.mcd"
    r = subprocess.run([sys.executable, "-m", "mocodec", "encode", *map(str, sample_paths), "-o", str(out),
                        "--units", "cmu", "--pca-variance", "0.95", "-O", "groups=1", "--json"],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    report = json.loads(r.stdout)
    assert report["codec"] == "rma-pca"
    assert report["tolerance_cm"] is None and report["pca_variance"] == 0.95
    assert report["error"]["max_cm"] > 1.0  # 95 % of the variance is not a 1 cm promise
    bad = subprocess.run([sys.executable, "-m", "mocodec", "encode", str(sample_paths[0]), "-o", str(out),
                          "--pca-variance", "0.95", "--codec", "spline"], capture_output=True, text=True)
    assert bad.returncode == 1 and "--pca-variance" in bad.stderr
