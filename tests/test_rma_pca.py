"""Codec rma-pca (seed 003's subspace representation, ``--pca-variance``, RMAP version 2): the
error it reaches is reported and falls as the variance kept grows; C and the Python reference
decoder agree; pieces in several groups decode across their borders; sequential, random and
backward sampling agree bit for bit; sampling reads only the clip's bytes and the section's
shared part; the scratch stays small; truncated or corrupt bytes are rejected or decode
finite; the CLI routes ``--codec rma --pca-variance``."""
from __future__ import annotations

import json
import struct
import subprocess
import sys

import numpy as np
import pytest

from mocodec.codecs.rma_pca import RmaPcaSettings
from mocodec.codecs.rma_pca_reference import decode_clip
from mocodec.container import AssetBuilder, ClipEntry
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
    # The run on the walk's bones: only nodes with position channels (the root) take its translations.
    run = a.skeleton.offsets[None].repeat(b.frame_count, axis=0)
    moved = [i for i in range(a.skeleton.node_count) if a.skeleton.position_axes(i)]
    run[:, moved] = b.translations[:, moved]
    return Motion(a.skeleton, np.concatenate([a.rotations[1:], b.rotations[1:], a.rotations[1:]]),
                  np.concatenate([a.translations[1:], run[1:], a.translations[1:]]),
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
        starts = [struct.unpack_from("<I", payload, 16 + 16 * p)[0] for p in range(pieces)]
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


@pytest.fixture(scope="module")
def repeats(library):
    motions, _ = library
    return _encode(motions, groups=2, variance=0.98, repeats=True)


def _poses_in_order(asset: Asset, name: str, times: np.ndarray, order: np.ndarray) -> np.ndarray:
    out = np.empty((len(times), *asset.sample(name, 0.0).shape), dtype=np.float32)
    for i in order:
        out[i] = asset.sample(name, times[i])
    return out


@pytest.mark.parametrize("which", ["direct", "repeats"])
def test_sequential_random_and_backward_sampling_agree_bit_for_bit(library, repeats, which):
    motions, direct = library
    result = direct if which == "direct" else repeats
    a = Asset(result.asset)
    rng = np.random.default_rng(3)
    for m in motions:
        times = np.arange(0, m.frame_count - 1, 0.37) / m.frame_rate
        n = len(times)
        seq = _poses_in_order(a, m.name, times, np.arange(n))
        assert np.array_equal(seq, _poses_in_order(a, m.name, times, rng.permutation(n))), m.name
        assert np.array_equal(seq, _poses_in_order(a, m.name, times, np.arange(n)[::-1])), m.name
        # Each pose on a scratch that another clip used last: prepared afresh every time.
        other = motions[0].name if m.name != motions[0].name else motions[1].name
        for i in rng.permutation(n)[:40]:
            a.sample(other, 0.5)
            assert np.array_equal(seq[i], a.sample(m.name, times[i])), (m.name, times[i])


def test_sampling_reads_only_the_clip_and_the_shared_part(library, repeats):
    """Open the bytes, then overwrite everything a clip's sampling may not read (other clips'
    payloads): its poses do not change by a bit. It reads the container's header, table, SKEL
    and CLIP, the RMAP section's shared part (bases, shared curve sets) and its own payload."""
    from mocodec_runtime import OPEN_PREVALIDATED, ffi, lib

    motions, direct = library
    for result in (direct, repeats):
        data = result.asset
        section, payloads = _rmap(data)
        sec_off = next(s for s in _sections(data) if s[0] == b"RMAP")[2]
        shared_end = struct.unpack_from("<I", section, 24)[0]
        for c, m in enumerate(motions):
            own_at, own = payloads[c]
            buf = bytearray(data)
            mem = ffi.from_buffer(buf)
            asset = ffi.new("mcd_asset*")
            assert lib.mcd_open(mem, len(buf), OPEN_PREVALIDATED, asset) == 0
            size = lib.mcd_scratch_size(asset)
            raw = ffi.new("uint8_t[]", size + 16)
            scratch = raw + (-int(ffi.cast("uintptr_t", raw)) % 16)
            assert lib.mcd_scratch_init(asset, scratch, size) == 0
            times = np.linspace(0.0, (m.frame_count - 1) / m.frame_rate, 97)
            pose = ffi.new("mcd_transform[]", m.skeleton.node_count)

            def poses() -> np.ndarray:
                out = []
                for t in times:
                    assert lib.mcd_sample(asset, c, float(t), 0, pose, m.skeleton.node_count, scratch) == 0
                    out.append(np.frombuffer(ffi.buffer(pose), dtype=np.float32).copy())
                return np.stack(out)

            before = poses()
            info = ffi.new("mcd_clip_info*")
            assert lib.mcd_get_clip_info(asset, c, info) == 0
            assert (info.data_offset, info.data_size) == (own_at, len(own))
            for i in range(sec_off + shared_end, sec_off + len(section)):
                if not own_at <= i < own_at + len(own):
                    buf[i] ^= 0xA5
            lib.mcd_scratch_init(asset, scratch, size)
            assert np.array_equal(before, poses()), m.name


def test_scratch_is_small(repeats):
    """Issue 15: an engine holds the asset and a scratch per playing instance, a few KB."""
    a = Asset(repeats.asset)
    for clip in a.clips:
        assert clip.scratch_size <= 32 * 1024, (clip.name, clip.scratch_size)


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


@pytest.fixture(scope="module")
def small(samples):
    """Two short clips in two groups, with repeats: every part of the format in a few KB."""
    motions = [samples[0].slice(1, 200), _mixed(samples).slice(150, 330)]
    motions[1].name = "mixed_short"
    return motions, _encode(motions, groups=2, variance=0.9, repeats=True)


def test_corrupt_bytes_are_rejected_or_decode_finite(small):
    """A bit flipped anywhere in the section: rejected, or every sample finite. Code values
    (basis codes, key residuals) may take any value, so many flips stay valid; a flip of the
    section header, its offset tables or a clip payload's header never does."""
    motions, result = small
    data = result.asset
    sec = next(s for s in _sections(data) if s[0] == b"RMAP")
    section, payloads = _rmap(data)
    _, groups, _, joints, _, shared, _, _ = struct.unpack_from("<8I", section)
    structural = set(range(sec[2], sec[2] + 32))
    structural |= set(range(sec[2] + 32 + 24 * joints, sec[2] + 32 + 24 * joints + 4 * (groups + shared)))
    for at, _ in payloads:
        structural |= set(range(at, at + 16))
    rng = np.random.default_rng(11)
    rejected = set()
    for pos in range(sec[2], sec[2] + sec[3]):
        bad = bytearray(data)
        bad[pos] ^= 1 << int(rng.integers(0, 8))
        try:
            a = Asset(bytes(bad), skip_checksum=True)
        except RuntimeResultError:
            rejected.add(pos)
            continue
        for m in motions:
            for t in (0.0, 0.37, m.frame_count / m.frame_rate):
                assert np.all(np.isfinite(a.sample(m.name, t))), pos
    assert structural <= rejected, sorted(structural - rejected)[:10]
    assert len(rejected) > 0.25 * sec[3], (len(rejected), sec[3])


def test_truncated_parts_are_rejected(small):
    """A section prefix or payload cut short (in an otherwise well-formed container) is
    refused by the runtime when the asset is built or opened; so is a truncated buffer."""
    motions, result = small
    section, payloads = _rmap(result.asset)
    shared_end = struct.unpack_from("<I", section, 24)[0]
    prefix = section[:shared_end]
    payload = [p for _, p in payloads]

    def build(prefix: bytes, payload: list[bytes]) -> bytes:
        b = AssetBuilder()
        for m, p in zip(motions, payload):
            s = b.add_skeleton(m.skeleton, CM)
            b.add_clip(ClipEntry(m.name, s, "rma-pca", p, m.frame_count, m.frame_rate))
        b.codec_prefix["rma-pca"] = prefix
        return b.build()

    Asset(build(prefix, payload))  # the parts as written: valid
    for cut in range(4, len(prefix), max(4, len(prefix) // 97 // 4 * 4)):
        with pytest.raises(RuntimeResultError):
            Asset(build(prefix[:cut], payload))
    for c in range(len(payload)):
        for cut in range(4, len(payload[c]), max(4, len(payload[c]) // 61 // 4 * 4)):
            with pytest.raises(RuntimeResultError):
                Asset(build(prefix, [p[:cut] if i == c else p for i, p in enumerate(payload)]))
    for cut in (16, 100, len(result.asset) // 2, len(result.asset) - 16):
        with pytest.raises(RuntimeResultError):
            Asset(result.asset[:cut])


def test_settings_reject_bad_values():
    for bad in ({"variance": 0.0}, {"variance": 1.5}, {"groups": 0}, {"coef_cm": -1}, {"key_grid": 9},
                {"key_grid": 3}, {"repeats": "yes"}, {"blend_seconds": 2.0}):
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
