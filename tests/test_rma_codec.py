"""The rma codec: a library in one RMAL section, the tolerance promise on every frame, C vs
Python agreement, sequential vs random access, resident memory as documented, and bad bytes
rejected at open. (Synthetic motion shapes run through it in test_spline.py.)"""
from __future__ import annotations

import struct

import numpy as np
import pytest

from mocodec.codecs.rma import resident_bytes
from mocodec.codecs.rma_reference import decode_payload
from mocodec.encode import EncodeError, encode_motions
from mocodec.io import read_bvh
from mocodec.kinematics import forward_kinematics
from mocodec.runtime import Asset, RuntimeResultError
from mocodec.tolerance import Tolerance
from mocodec.units import resolve_units


def _encode(motions, tol, **options):
    units = [resolve_units(m.skeleton, "cmu", None) for m in motions]
    return encode_motions(motions, units, "rma", Tolerance(tol), options)


def _error_cm(asset: Asset, motion) -> np.ndarray:
    _, pos_o = forward_kinematics(motion.skeleton, motion.rotations, motion.translations)
    _, pos_d = asset.sample_frames(motion.name, world=True)
    return np.linalg.norm(pos_o - pos_d, axis=-1) * 5.6444


def _sections(asset_bytes: bytes) -> list[tuple[bytes, int, int, int]]:
    count = struct.unpack_from("<I", asset_bytes, 24)[0]
    return [struct.unpack_from("<4sIII", asset_bytes, 32 + 16 * i) for i in range(count)]


def _payloads(asset_bytes: bytes) -> list[tuple[int, bytes]]:
    """(absolute offset, bytes) of every clip's RMAL payload, via docs/FORMAT.md's layout."""
    sections = _sections(asset_bytes)
    clip = next(s for s in sections if s[0] == b"CLIP")
    n = struct.unpack_from("<I", asset_bytes, clip[2])[0]
    out = []
    for c in range(n):
        _, _, codec, sec, poff, psize = struct.unpack_from("<6I", asset_bytes, clip[2] + 8 + 48 * c)
        assert codec == 2 and sections[sec][0] == b"RMAL"
        start = sections[sec][2] + poff
        out.append((start, asset_bytes[start:start + psize]))
    return out


@pytest.fixture(scope="module")
def library(sample_paths):
    motions = [read_bvh(p) for p in sample_paths]
    return motions, _encode(motions, 1.0)


@pytest.mark.parametrize("tol", [0.3, 3.0])
def test_tolerance_holds_on_every_frame(sample_paths, tol):
    motions = [read_bvh(p) for p in sample_paths]
    asset = Asset(_encode(motions, tol).asset)
    for m in motions:
        err = _error_cm(asset, m)
        assert err.shape == (m.frame_count, 38)
        assert err.max() <= tol, (m.name, err.max())
        assert err.max() > 0.2 * tol  # the codec spends the tolerance


def test_library_is_one_section_with_every_clip_addressable(library):
    motions, result = library
    asset = Asset(result.asset)
    kinds = [s[0] for s in _sections(result.asset)]
    assert kinds.count(b"RMAL") == 1 and b"SPLN" not in kinds
    assert [c.name for c in asset.clips] == [m.name for m in motions]
    assert asset.skeleton_count == 3  # three CMU subjects, three skeletons
    for m in motions:
        assert _error_cm(asset, m).max() <= 1.0


def test_smaller_than_spline_at_the_same_tolerance(library, sample_paths):
    motions, result = library
    units = [resolve_units(m.skeleton, "cmu", None) for m in motions]
    spline = encode_motions(motions, units, "spline", Tolerance(1.0))
    assert len(result.asset) < len(spline.asset)


def test_resident_memory_is_what_the_format_says(library):
    _, result = library
    asset = Asset(result.asset)
    payloads = [p for _, p in _payloads(result.asset)]
    assert asset.resident_size == 16 + sum(resident_bytes(p) for p in payloads)
    # Each payload's resident offset is the running sum of the blocks before it.
    offsets = [struct.unpack_from("<I", p, 24)[0] for p in payloads]
    assert offsets == list(np.cumsum([0] + [resident_bytes(p) for p in payloads[:-1]]))


def _assert_c_matches_reference(result, motions) -> None:
    asset = Asset(result.asset)
    for (_, payload), m, info in zip(_payloads(result.asset), motions, asset.clips):
        x = np.concatenate((np.arange(m.frame_count), np.linspace(0, m.frame_count - 1, 613)))
        rot_py, trans_py = decode_payload(payload, m.skeleton, x)
        poses = asset.sample_times(info.index, (x / info.frame_rate).astype(np.float32))
        rot_c, trans_c = poses[..., :4].astype(np.float64), poses[..., 4:].astype(np.float64)
        sign = np.sign(np.sum(rot_c * rot_py, axis=-1, keepdims=True))
        assert np.abs(rot_c - sign * rot_py).max() <= 1e-5
        assert np.abs(trans_c - trans_py).max() <= 1e-5 * max(1.0, np.abs(trans_py).max())


def _first_descriptor(payload: bytes) -> int:
    nodes, consts = struct.unpack_from("<I", payload, 8)[0], struct.unpack_from("<I", payload, 16)[0]
    return 32 + (nodes + 3) // 4 * 4 + 4 * consts


def _descriptor_byte1(payload: bytes) -> list[int]:
    """Byte 1 of every track descriptor: key grid | predictor << 4."""
    tracks = struct.unpack_from("<I", payload, 12)[0]
    pos = _first_descriptor(payload)
    out = []
    for _ in range(tracks):
        out.append(payload[pos + 1])
        pos += {1: 20, 2: 32, 3: 16}[payload[pos]]
    return out


def test_c_runtime_and_python_reference_agree(library):
    motions, result = library
    _assert_c_matches_reference(result, motions)


def test_slope_predictors_are_chosen_and_decode_alike_in_c_and_python(sample_paths):
    # Tight tolerances give dense keys, where carrying the slope over predicts best.
    motions = [read_bvh(p) for p in sample_paths[:1]]
    result = _encode(motions, 0.05)
    (_, payload), = _payloads(result.asset)
    predictors = {b >> 4 for b in _descriptor_byte1(payload)}
    assert predictors <= {0, 1, 2} and predictors & {1, 2}
    _assert_c_matches_reference(result, motions)
    assert _error_cm(Asset(result.asset), motions[0]).max() <= 0.05


def test_sequential_and_random_access_give_identical_poses(library):
    _, result = library
    asset = Asset(result.asset)
    info = asset.clips[1]
    x = np.linspace(0, info.frame_count - 1, 4 * info.frame_count)
    times = (x / info.frame_rate).astype(np.float32)
    forward = asset.sample_times(info.index, times)
    order = np.random.default_rng(7).permutation(len(times))
    shuffled = np.empty_like(forward)
    shuffled[order] = asset.sample_times(info.index, times[order])
    backward = asset.sample_times(info.index, times[::-1])[::-1]
    assert np.array_equal(forward, shuffled)
    assert np.array_equal(forward, backward)


def test_two_encodes_are_byte_identical(sample_paths):
    motions = [read_bvh(p) for p in sample_paths[:2]]
    assert _encode(motions, 0.7).asset == _encode(motions, 0.7).asset


def test_tolerance_that_cannot_be_met_is_an_error(sample_paths):
    with pytest.raises(EncodeError, match="tolerance"):
        _encode([read_bvh(sample_paths[2])], 1e-7, max_repairs=3)


def test_bad_options_are_errors(sample_paths):
    with pytest.raises(ValueError, match="quant_fraction"):
        _encode([read_bvh(sample_paths[2])], 1.0, quant_fraction=1.5)


def _rewrite(asset_bytes: bytes, at: int, new: bytes) -> bytes:
    """Patch bytes and fix the checksum, so only the structural checks can catch it."""
    import zlib

    b = bytearray(asset_bytes)
    b[at:at + len(new)] = new
    struct.pack_into("<I", b, 20, zlib.crc32(bytes(b[24:])) & 0xFFFFFFFF)
    return bytes(b)


def test_inconsistent_payloads_are_rejected_at_open(library):
    _, result = library
    start, payload = _payloads(result.asset)[1]
    resident_offset = struct.unpack_from("<I", payload, 24)[0]
    gap_bytes = struct.unpack_from("<I", payload, 28)[0]
    key_total = struct.unpack_from("<I", payload, 20)[0]
    cases = {
        "resident offset off the running sum": (start + 24, struct.pack("<I", resident_offset + 16)),
        "resident offset not a multiple of 16": (start + 24, struct.pack("<I", resident_offset + 4)),
        "key total that the tracks do not add up to": (start + 20, struct.pack("<I", key_total + 1)),
        "gap stream size moved into the value streams": (start + 28, struct.pack("<I", gap_bytes + 1)),
        "value predictor 3 (undefined)": (start + _first_descriptor(payload) + 1,
                                          bytes([_descriptor_byte1(payload)[0] & 15 | 3 << 4])),
    }
    for why, (at, new) in cases.items():
        with pytest.raises(RuntimeResultError):
            Asset(_rewrite(result.asset, at, new))
            pytest.fail(why)


def test_corrupt_streams_are_rejected_or_decode_to_finite_poses(library):
    """Every byte of a clip's entropy streams flipped in turn: open fails cleanly, or the
    asset decodes to finite transforms (a range coder cannot tell every change)."""
    _, result = library
    start, payload = _payloads(result.asset)[2]
    nodes, tracks, consts = struct.unpack_from("<III", payload, 8)[0], *struct.unpack_from("<II", payload, 12)
    descs = 0
    pos = 32 + (nodes + 3) // 4 * 4 + 4 * consts
    for _ in range(tracks):
        descs += {1: 20, 2: 32, 3: 16}[payload[pos + descs]]
    first = start + pos + descs
    rejected = opened = 0
    for at in range(first, start + len(payload), 7):
        data = _rewrite(result.asset, at, bytes([result.asset[at] ^ 0x5A]))
        try:
            asset = Asset(data)
        except RuntimeResultError:
            rejected += 1
            continue
        opened += 1
        poses = asset.sample_times(2, np.linspace(0, asset.clips[2].duration, 23).astype(np.float32))
        assert np.isfinite(poses).all()
    assert rejected > 0


def test_dev_set_meets_one_cm_on_every_frame_as_one_library(shared_cmu_dir):
    if shared_cmu_dir is None:
        pytest.skip("../shared/data/cmu not present: dev-set rma tolerance check skipped")
    paths = sorted(shared_cmu_dir.glob("*.bvh"))
    motions = [read_bvh(p) for p in paths]
    result = _encode(motions, 1.0)
    asset = Asset(result.asset)
    assert len(asset.clips) == len(paths) == 35
    assert sum(s[0] == b"RMAL" for s in _sections(result.asset)) == 1
    for m in motions:
        assert _error_cm(asset, m).max() <= 1.0, m.name


@pytest.mark.parametrize("grid", [1, 4, 7])
def test_key_grid_is_stored_and_the_tolerance_holds(sample_paths, grid):
    m = read_bvh(sample_paths[0])
    result = _encode([m], 1.0, key_grid=grid)
    (_, payload), = _payloads(result.asset)
    grids = [b & 15 for b in _descriptor_byte1(payload)]
    assert set(grids) == {grid}
    assert _error_cm(Asset(result.asset), m).max() <= 1.0


def test_key_grid_default_follows_the_tolerance():
    from mocodec.codecs.rma import RMASettings

    assert RMASettings(Tolerance(1.0)).key_grid == 4
    assert RMASettings(Tolerance(1.0, 0.1)).key_grid == 1
    assert RMASettings(Tolerance(0.02)).key_grid == 1
    with pytest.raises(ValueError, match="key_grid"):
        RMASettings(Tolerance(1.0), key_grid=9)
