"""The container the Python side writes is what the C runtime reads (docs/FORMAT.md)."""
from __future__ import annotations

import struct
import zlib

import numpy as np
import pytest

from mocodec.container import AssetBuilder, ClipEntry, ContainerError, read_summary
from mocodec.decode import skeleton_from_asset
from mocodec.io import read_bvh
from mocodec.runtime import Asset, Result, RuntimeResultError, validate


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
    assert (major, minor, header, flags) == (1, 0, 32, 0)
    assert total == len(data) and total % 16 == 0
    assert crc == zlib.crc32(data[24:]) & 0xFFFFFFFF
    expect = (32 + 16 * count + 15) // 16 * 16
    for i in range(count):
        kind, version, off, size = struct.unpack_from("<4sIII", data, 32 + 16 * i)
        assert off == expect and off % 16 == 0 and version == 1
        expect = (off + size + 15) // 16 * 16
    assert expect == total
    assert validate(data) == Result.OK


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
