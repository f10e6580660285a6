"""The container the Python side writes is what the C runtime reads (docs/FORMAT.md)."""
from __future__ import annotations

import struct
import zlib

import numpy as np
import pytest

from mocodec import codecs
from mocodec.container import AssetBuilder, ClipEntry, ContainerError, read_summary
from mocodec.decode import skeleton_from_asset
from mocodec.io import read_bvh
from mocodec.runtime import Asset, Result, RuntimeResultError, clip_scratch_size, validate

SCRATCH_HEADER = 64  # bytes every scratch starts with (the runtime's MCD_SCRATCH_HEADER_SIZE)


def _asset(sample_paths):
    from mocodec.encode import encode_motions
    from mocodec.tolerance import Tolerance
    from mocodec.units import resolve_units

    motions = [read_bvh(p) for p in sample_paths]
    units = [resolve_units(m.skeleton, None, None) for m in motions]
    return motions, encode_motions(motions, units, "spline", Tolerance(1.0)).asset


def test_layout_rules(sample_paths):
    _, data = _asset(sample_paths)
    assert data[:8] == b"\x89MCD\r\n\x1a\n"
    major, minor, header, total, crc, count, flags = struct.unpack_from("<HHIIIII", data, 8)
    assert (major, minor, header, flags) == (2, 0, 32, 0)
    assert total == len(data) and total % 16 == 0
    assert crc == zlib.crc32(data[24:]) & 0xFFFFFFFF
    expect = (32 + 16 * count + 15) // 16 * 16
    versions = {b"SKEL": 2, b"CLIP": 2, b"META": 1, b"SPLN": codecs.get("spline").section_version}
    for i in range(count):
        kind, version, off, size = struct.unpack_from("<4sIII", data, 32 + 16 * i)
        assert off == expect and off % 16 == 0 and version == versions[kind]
        expect = (off + size + 15) // 16 * 16
    assert expect == total
    assert validate(data) == Result.OK


def _section(data: bytes, kind: bytes, nth: int = 0) -> tuple[int, int, int]:
    """(index, offset, size) of the nth section of ``kind``."""
    count = struct.unpack_from("<I", data, 24)[0]
    found = [(i, *struct.unpack_from("<II", data, 32 + 16 * i + 8)) for i in range(count)
             if data[32 + 16 * i:36 + 16 * i] == kind]
    return found[nth]


def test_skel_version_2_records(sample_paths):
    """SKEL v2: node count, flags 0 (a BVH skeleton has no rest table), cm per unit, string
    block at 16 + 32 N; per node parent, name offset, rest translation (+8), kind (+20),
    channel count and codes padded with 0xFF, reserved 0."""
    motions, data = _asset(sample_paths)
    for s, m in enumerate(motions):
        sk = m.skeleton
        _, off, size = _section(data, b"SKEL", s)
        n, flags, cm, strings = struct.unpack_from("<IIfI", data, off)
        assert (n, flags, strings) == (sk.node_count, 0, 16 + 32 * sk.node_count)
        assert cm == pytest.approx(5.6444, rel=1e-6)
        block = data[off + strings:off + size]
        for i in range(n):
            rec = struct.unpack_from("<iI3fBB6BI", data, off + 16 + 32 * i)
            parent, name_at, t = rec[0], rec[1], rec[2:5]
            kind, channels, codes, reserved = rec[5], rec[6], rec[7:13], rec[13]
            assert parent == sk.parents[i]
            assert block[name_at:block.index(b"\0", name_at)].decode() == sk.names[i]
            assert np.allclose(t, sk.offsets[i], atol=1e-5)
            assert kind == (1 if sk.is_end_site[i] else 0)
            assert channels == len(sk.channels[i])
            assert codes == tuple(sk.channels[i]) + (0xFF,) * (6 - channels)
            assert reserved == 0


def test_clip_version_2_records(sample_paths):
    """CLIP v2: 48-byte records; the scratch a clip needs (+40) is the runtime's own figure,
    and the clip info reports it (plus the scratch header) and the payload's byte range."""
    motions, data = _asset(sample_paths)
    asset = Asset(data)
    index, off, _ = _section(data, b"CLIP")
    count, strings = struct.unpack_from("<II", data, off)
    assert (count, strings) == (len(motions), 8 + 48 * len(motions))
    spln_index, spln_off, spln_size = _section(data, b"SPLN")
    skels = [_section(data, b"SKEL", s) for s in range(asset.skeleton_count)]
    for c, m in enumerate(motions):
        (name_at, skel, codec, section, payload_off, payload_size, frames, rate, duration, clip_flags, need,
         reserved) = struct.unpack_from("<IIIIIIIffIII", data, off + 8 + 48 * c)
        assert (codec, section, frames, clip_flags, reserved) == (codecs.get("spline").id, spln_index, m.frame_count, 0, 0)
        assert payload_off % 4 == 0 and payload_off + payload_size <= spln_size
        _, skel_off, skel_size = skels[skel]
        assert need % 16 == 0 and need == clip_scratch_size(
            codec, data[spln_off:spln_off + spln_size], payload_off, payload_size,
            data[skel_off:skel_off + skel_size], frames, rate)
        info = asset.clips[c]
        assert info.scratch_size == SCRATCH_HEADER + need  # no contacts section here
        assert (info.data_offset, info.data_size) == (spln_off + payload_off, payload_size)
    assert asset.scratch_size == max(c.scratch_size for c in asset.clips)


def test_skeletons_and_clips_round_trip(sample_paths):
    motions, data = _asset(sample_paths)
    asset = Asset(data)
    assert [c.name for c in asset.clips] == [m.name for m in motions]
    assert asset.skeleton_count == 3  # three CMU subjects, three calibrated skeletons
    for m, c in zip(motions, asset.clips):
        sk, cm = skeleton_from_asset(asset, c.skeleton)
        assert cm == pytest.approx(5.6444, rel=1e-6)
        assert sk.names == m.skeleton.names
        assert sk.channels == m.skeleton.channels
        assert np.array_equal(sk.parents, m.skeleton.parents)
        assert np.allclose(sk.offsets, m.skeleton.offsets, atol=1e-5)
        assert c.frame_count == m.frame_count
        assert c.duration == pytest.approx((m.frame_count - 1) * m.frame_time, rel=1e-5)


def test_meta_holds_the_measured_errors(sample_paths):
    motions, data = _asset(sample_paths)
    summary = read_summary(data)
    assert summary.meta["codec"] == "spline"
    for m in motions:
        clip = summary.meta["clips"][m.name]
        assert 0 < clip["max_error_cm"] <= 1.0
        assert clip["raw_bvh_bytes"] == m.frame_count * 96 * 4


def test_identical_skeletons_are_stored_once(sample_paths):
    m = read_bvh(sample_paths[0])
    b = AssetBuilder()
    assert b.add_skeleton(m.skeleton, 5.6444) == 0
    assert b.add_skeleton(m.skeleton, 5.6444) == 0
    assert b.add_skeleton(m.skeleton, 2.54) == 1
    with pytest.raises(ValueError, match="two clips"):
        b.add_clip(ClipEntry("a", 0, "spline", b"", 1, 30.0))
        b.add_clip(ClipEntry("a", 0, "spline", b"", 1, 30.0))


def test_runtime_rejects_what_python_misbuilt(sample_paths):
    _, data = _asset(sample_paths)
    broken = bytearray(data)
    broken[24] ^= 0xFF  # section count
    assert validate(bytes(broken)) == Result.CHECKSUM
    assert validate(bytes(broken), skip_checksum=True) != Result.OK
    with pytest.raises(RuntimeResultError) as exc:
        Asset(bytes(broken))
    assert exc.value.code == Result.CHECKSUM
    assert validate(data + b"\0") == Result.TRAILING_DATA
    assert validate(data[:-1]) == Result.TRUNCATED
    with pytest.raises(ContainerError):
        read_summary(b"not an asset at all, clearly")


def test_skeleton_from_asset_keeps_the_rest_pose(repo_root):
    """SKEL v2 read back by the tools: rest rotations, rest scales and virtual points survive
    (the golden glTF-like leg of tests/golden/make_golden.py)."""
    asset = Asset((repo_root / "tests" / "golden" / "v2" / "spline_rest_pose.mcd").read_bytes())
    nodes = asset.nodes(1)
    sk, _ = skeleton_from_asset(asset, 1)
    assert np.array_equal(sk.rest_rotations, np.array([n.rest_rotation for n in nodes]))
    assert np.array_equal(sk.rest_scales, np.array([n.rest_scale for n in nodes]))
    assert list(sk.is_virtual) == [n.kind == 2 for n in nodes] and sk.is_virtual[-1]
    assert not sk.is_end_site.any()
