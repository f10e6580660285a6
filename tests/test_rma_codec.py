"""The rma codec (RMAL version 4, sampled in place): a library in one RMAL section, the
tolerance promise on every frame, C vs Python reference agreement, sequential = random =
backward access bit for bit, each clip's bytes where its clip info says, and bad bytes
rejected at open or decoded finite; assets of RMAL versions 2 and 3 still read. (Synthetic
motion shapes run through it in test_spline.py.)"""
from __future__ import annotations

import struct
from pathlib import Path

import numpy as np
import pytest

from mocodec.bitpack import read_bits
from mocodec.codecs.rma_reference import _blocks_track, decode_keys, decode_payload
from mocodec.codecs.rma import section_prefix
from mocodec.codecs.rma_blocks import SLOPE, ZERO_STREAM, track_body
from mocodec.decode import skeleton_from_asset
from mocodec.encode import EncodeError, encode_motions
from mocodec.io import read_bvh
from mocodec.kinematics import forward_kinematics
from mocodec.runtime import Asset, RuntimeResultError
from mocodec.tolerance import Tolerance
from mocodec.units import resolve_units
from runtime_accepts import runtime_accepts

CM = 5.6444  # cm per unit of the CMU samples
SECTION_HEADER = 16  # RMAL: clip count, three reserved words
PAYLOAD_HEADER = 32
DESC_SIZE = {1: 28, 2: 40, 3: 20, 4: 20}  # track descriptor bytes per kind
SECTION_PREFIX = section_prefix(1)  # the section header of a one-clip asset


def _encode(motions, tol, **options):
    units = [resolve_units(m.skeleton, "cmu", None) for m in motions]
    return encode_motions(motions, units, "rma", Tolerance(tol), options)


def _error_cm(asset: Asset, motion) -> np.ndarray:
    _, pos_o = forward_kinematics(motion.skeleton, motion.rotations, motion.translations)
    _, pos_d = asset.sample_frames(motion.name, world=True)
    return np.linalg.norm(pos_o - pos_d, axis=-1) * CM


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


RMAL2_GOLDEN = Path(__file__).resolve().parent / "golden" / "v2" / "rma_rmal2_library.mcd"
RMAL3_GOLDENS = [Path(__file__).resolve().parent / "golden" / "v2" / f"rma_rmal3_{n}.mcd"
                 for n in ("library", "rest_pose", "09_11_dense")]


@pytest.fixture(scope="module")
def rmal2_golden() -> bytes:
    """An rma asset written in RMAL version 2, before version 3 (tests/golden)."""
    return RMAL2_GOLDEN.read_bytes()


def _golden_skeleton(asset: Asset, clip: int):
    return skeleton_from_asset(asset, asset.clips[clip].skeleton)[0]


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


def test_section_and_clip_data_ranges(library):
    """The section: a 16-byte header (clip count, zeros), then the payloads back to back, each
    starting with its size; each clip's data range (mcd_clip_info) is its payload, which is
    all that sampling the clip reads besides the container."""
    motions, result = library
    asset = Asset(result.asset)
    rmal = next(s for s in _sections(result.asset) if s[0] == b"RMAL")
    assert struct.unpack_from("<4I", result.asset, rmal[2]) == (len(motions), 0, 0, 0)
    at = rmal[2] + SECTION_HEADER
    for (start, payload), info in zip(_payloads(result.asset), asset.clips):
        assert start == at and struct.unpack_from("<I", payload)[0] == len(payload)
        assert (info.data_offset, info.data_size) == (start, len(payload))
        at += len(payload)
    assert at == rmal[2] + rmal[3]


def _assert_c_matches_reference(result, motions) -> None:
    asset = Asset(result.asset)
    for (_, payload), m, info in zip(_payloads(result.asset), motions, asset.clips):
        x = np.concatenate((np.arange(m.frame_count), np.linspace(0, m.frame_count - 1, 613)))
        rot_py, trans_py, scale_py = decode_payload(payload, m.skeleton, x)
        poses = asset.sample_times(info.index, (x / info.frame_rate).astype(np.float32)).astype(np.float64)
        rot_c, trans_c, scale_c = poses[..., :4], poses[..., 4:7], poses[..., 7:]
        sign = np.sign(np.sum(rot_c * rot_py, axis=-1, keepdims=True))
        assert np.abs(rot_c - sign * rot_py).max() <= 1e-5
        assert np.abs(trans_c - trans_py).max() <= 1e-5 * max(1.0, np.abs(trans_py).max())
        assert np.abs(scale_c - scale_py).max() <= 1e-5


def _first_descriptor(payload: bytes) -> int:
    nodes, consts = struct.unpack_from("<I", payload, 8)[0], struct.unpack_from("<I", payload, 16)[0]
    return PAYLOAD_HEADER + (nodes + 3) // 4 * 4 + 4 * consts


def _descriptors(payload: bytes) -> list[int]:
    """Offset (in the payload) of every track descriptor."""
    tracks = struct.unpack_from("<I", payload, 12)[0]
    pos = _first_descriptor(payload)
    out = []
    for _ in range(tracks):
        out.append(pos)
        pos += DESC_SIZE[payload[pos]]
    return out


def test_c_runtime_and_python_reference_agree(library):
    motions, result = library
    _assert_c_matches_reference(result, motions)


def _row_fields(payload: bytes, t: dict) -> np.ndarray:
    """A decoded track's row fields (rows, streams): gaps, then each component."""
    frames = struct.unpack_from("<I", payload, 4)[0]
    fb = max(1, (frames - 1).bit_length())
    table = payload[t["parts"]["table"]:] + bytes(8)
    return np.array([[read_bits(table, e * t["parts"]["row_bits"] + fb + t["offset_bits"] + 5 * c, 5)
                      for c in range(t["d"] + 1)] for e in range(t["parts"]["rows"])])


def test_dense_keys_decode_alike_in_c_and_python(sample_paths):
    # Tight tolerances give dense keys (gaps of one frame), wide differences and short last
    # blocks; and version 4's slope predictor and streams of zeros (gaps all one frame).
    motions = [read_bvh(p) for p in sample_paths[:1]]
    result = _encode(motions, 0.05)
    (_, payload), = _payloads(result.asset)
    _, tracks = decode_keys(payload)
    assert any(np.any(np.diff(t["frames"]) == 1) for t in tracks)
    fields = np.concatenate([_row_fields(payload, t)[:, 1:] for t in tracks]).ravel()
    gaps = np.concatenate([_row_fields(payload, t)[:, 0] for t in tracks])
    assert np.any(fields & SLOPE) and np.any(fields & ~SLOPE & 15 != ZERO_STREAM)
    assert np.any(gaps == ZERO_STREAM) and not np.any(gaps & SLOPE)
    _assert_c_matches_reference(result, motions)
    assert _error_cm(Asset(result.asset), motions[0]).max() <= 0.05


def test_sequential_random_and_backward_access_give_identical_poses(library):
    """Every clip: forward, shuffled and backward through its frames and quarter frames, and
    all clips interleaved in one shuffled run, local and world: the same bytes."""
    _, result = library
    asset = Asset(result.asset)
    jobs = []
    for flags in (0, 1):
        for info in asset.clips:
            x = np.linspace(0, info.frame_count - 1, 4 * info.frame_count - 3)
            times = (x / info.frame_rate).astype(np.float32)
            forward = asset.sample_times(info.index, times, flags)
            order = np.random.default_rng(7 + info.index).permutation(len(times))
            shuffled = np.empty_like(forward)
            shuffled[order] = asset.sample_times(info.index, times[order], flags)
            backward = asset.sample_times(info.index, times[::-1], flags)[::-1]
            assert np.array_equal(forward, shuffled)
            assert np.array_equal(forward, backward)
            jobs += [(info.index, t, flags, forward[k]) for k, t in enumerate(times) if k % 5 == 0]
    for j in np.random.default_rng(8).permutation(len(jobs)):
        clip, t, flags, want = jobs[j]
        assert np.array_equal(asset.sample(clip, t, flags), want)


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


def _header_cases(payload: bytes) -> dict[str, tuple[int, bytes]]:
    """Rules both versions share, one broken per case: (offset in the payload, new bytes)."""
    size, frames, nodes, tracks, consts = struct.unpack_from("<5I", payload)
    modes = PAYLOAD_HEADER
    descs = _descriptors(payload)
    rot = next(d for d in descs if payload[d] in (1, 2))  # a rotation track's descriptor
    trans = next(d for d in descs if payload[d] == 3)
    u32 = lambda v: struct.pack("<I", v)  # noqa: E731
    return {
        "size not the clip record's": (0, u32(size + 4)),
        "frame count not the clip's": (4, u32(frames + 1)),
        "node count not the skeleton's": (8, u32(nodes - 1)),
        "one track more than the modes use": (12, u32(tracks + 1)),
        "one constant more than the modes use": (16, u32(consts + 1)),
        "first reserved word": (20, u32(1)),
        "reserved word": (24, u32(1)),
        "last reserved word": (28, u32(1)),
        "node mode 3 (undefined)": (modes, bytes([payload[modes] | 3])),
        "node mode bits 6-7": (modes, bytes([payload[modes] | 0x40])),
        "a rotation track of translation kind": (rot, bytes([3])),
        "track kind 5": (rot, bytes([5])),
        "offset bits 0": (rot + 2, bytes([0])),
        "offset bits 33": (rot + 2, bytes([33])),
        "descriptor byte 3 (v3: reserved; v2: place bits) 1": (rot + 3, bytes([1])),
        "no keys": (rot + 4, u32(0)),
        "more keys than frames": (rot + 4, u32(frames + 1)),
        "one key in a clip of many frames": (rot + 4, u32(1)),
        "data bytes not a multiple of 4": (rot + 8, u32(struct.unpack_from("<I", payload, rot + 8)[0] + 2)),
        "step NaN": (trans + 12, struct.pack("<f", float("nan"))),
        "step negative": (trans + 12, struct.pack("<f", -0.01)),
        "component bits 0": (trans + 16, bytes([0])),
        "component bits 32": (trans + 16, bytes([32])),
        "bits of a fourth component a translation lacks": (trans + 19, bytes([1])),
        "reference padding": (rot + 26, struct.pack("<H", 1)),
        "trailing zero bytes not zero": (size - 1, bytes([1])),
    }


def _assert_each_case_rejected(asset_bytes: bytes, start: int, payload: bytes, cases: dict) -> None:
    for why, (at, new) in cases.items():
        assert payload[at:at + len(new)] != new, why
        with pytest.raises(RuntimeResultError):
            Asset(_rewrite(asset_bytes, start + at, new))
            pytest.fail(why)


def _set_bit(payload: bytes, bit: int) -> tuple[int, bytes]:
    """(offset, byte) that sets bit ``bit`` of the payload (a bit that is clear)."""
    assert not payload[bit // 8] >> bit % 8 & 1
    return bit // 8, bytes([payload[bit // 8] | 1 << bit % 8])


def test_inconsistent_payloads_are_rejected_at_open(library):
    """One rule of the RMAL v4 payload broken at a time, the checksum rewritten."""
    _, result = library
    start, payload = _payloads(result.asset)[1]
    frames = struct.unpack_from("<I", payload, 4)[0]
    rot = next(d for d in _descriptors(payload) if payload[d] in (1, 2))
    cases = _header_cases(payload)
    cases.update({
        "block shift 0 in a descriptor": (rot + 1, bytes([payload[rot + 1] & 1])),
        "block shift 7 in a descriptor": (rot + 1, bytes([payload[rot + 1] & 1 | 7 << 1])),
        "descriptor flag bit 4": (rot + 1, bytes([payload[rot + 1] | 0x10])),
    })
    # The track parts: row table, Rice codes.
    _, decoded = decode_keys(payload)
    t = max(decoded, key=lambda t: t["K"])
    assert t["parts"]["rows"] >= 3
    table, data = 8 * t["parts"]["table"], 8 * t["parts"]["data"]
    fb = max(1, (frames - 1).bit_length())
    row1 = table + t["parts"]["row_bits"]
    desc = next(d for d in _descriptors(payload) if payload[d + 4:d + 8] == struct.pack("<I", t["K"]))
    gap_param = next(b for b in range(5) if not payload[(row1 + fb + t["offset_bits"] + b) // 8] >> (
        (row1 + fb + t["offset_bits"] + b) % 8) & 1)
    cases.update({
        "row 0's key not frame 0": _set_bit(payload, table),
        "row 0's codes not at bit 0": _set_bit(payload, table + fb),
        "a block's gap parameter changed": _set_bit(payload, row1 + fb + t["offset_bits"] + gap_param),
        "data bytes one word more": (desc + 8, struct.pack("<I", t["data_bytes"] + 4)),
        "a padding bit after the codes": _set_bit(payload, data + 8 * t["data_bytes"] - 1),
    })
    _assert_each_case_rejected(result.asset, start, payload, cases)


def test_inconsistent_version_2_payloads_are_rejected_at_open(rmal2_golden):
    """Assets written before version 3 are still read, and still checked in full: one rule of
    the RMAL v2 payload broken at a time, the checksum rewritten."""
    asset_bytes = rmal2_golden
    start, payload = _payloads(asset_bytes)[0]
    rot = next(d for d in _descriptors(payload) if payload[d] in (1, 2))
    cases = _header_cases(payload)
    cases.update({
        "group shift 0 in a descriptor": (rot + 1, bytes([payload[rot + 1] & 7])),
        "group shift 7 in a descriptor": (rot + 1, bytes([payload[rot + 1] & 7 | 7 << 3])),
        "descriptor flag bit 6": (rot + 1, bytes([payload[rot + 1] | 0x40])),
    })
    _, decoded = decode_keys(payload, version=2)
    t = max(decoded, key=lambda t: t["K"])
    parts = t["parts"]
    word = int.from_bytes(payload[parts["bitmap"]:parts["bitmap"] + 8], "little")
    spare = next(c for c in range(1, 64) if not word >> c & 1)  # a cell without a key
    last_widths = (t["parts"]["rows"] - 1) * t["parts"]["row_bits"] + t["offset_bits"]
    at = parts["table"] + last_widths // 8
    cases.update({
        "frame 0 not a key cell": (parts["bitmap"], bytes([payload[parts["bitmap"]] & 0xFE])),
        "one key cell more than keys": (parts["bitmap"], (word | 1 << spare).to_bytes(8, "little")),
        "the group table's first offset not 0": (parts["table"], bytes([payload[parts["table"]] | 1])),
        "the last row's widths not 0": (at, bytes([payload[at] | 1 << last_widths % 8])),
    })
    _assert_each_case_rejected(asset_bytes, start, payload, cases)


def _assert_decodes_as_the_reference(data: bytes, version: int) -> None:
    """The C runtime samples every clip of an asset as the Python reference of RMAL version
    ``version`` decodes it, at quarter frames."""
    asset = Asset(data)
    for (_, payload), info in zip(_payloads(data), asset.clips):
        sk = _golden_skeleton(asset, info.index)
        x = np.linspace(0, info.frame_count - 1, 4 * info.frame_count - 3)
        rot_py, trans_py, _ = decode_payload(payload, sk, x, version=version)
        poses = asset.sample_times(info.index, (x / info.frame_rate).astype(np.float32)).astype(np.float64)
        sign = np.sign(np.sum(poses[..., :4] * rot_py, axis=-1, keepdims=True))
        assert np.abs(poses[..., :4] - sign * rot_py).max() <= 1e-5
        assert np.abs(poses[..., 4:7] - trans_py).max() <= 1e-5 * max(1.0, np.abs(trans_py).max())


def test_version_2_assets_decode_as_the_reference_says(rmal2_golden):
    """An asset written before version 3: the C runtime samples it as the Python reference of
    version 2 decodes it, between frames too."""
    _assert_decodes_as_the_reference(rmal2_golden, 2)


@pytest.mark.parametrize("path", RMAL3_GOLDENS, ids=lambda p: p.stem)
def test_version_3_assets_decode_as_the_reference_says(path):
    """An asset written before version 4: the C runtime samples it as the Python reference of
    version 3 decodes it, between frames too."""
    _assert_decodes_as_the_reference(path.read_bytes(), 3)


def _blocks_round_trip(frames: np.ndarray, q: np.ndarray, shift: int) -> tuple[dict, np.ndarray]:
    """A track's keys written as version 4 blocks and read back by the reference: (the decoded
    track, its row fields)."""
    abits = np.array([max(1, int(np.abs(q[:, c]).max()).bit_length() + 1) for c in range(q.shape[1])])
    offset_bits, data_bytes, table, data = track_body(frames, q, abits, int(frames[-1]) + 1, shift)
    payload = table + data
    t = dict(d=q.shape[1], K=len(q), block_shift=shift, offset_bits=offset_bits, abits=list(abits),
             data_bytes=data_bytes)
    _blocks_track(payload, 0, t, int(frames[-1]) + 1, 4)
    header = struct.pack("<II", 0, int(frames[-1]) + 1)  # what _row_fields reads of a payload
    t["parts"]["table"] += len(header)
    return t, _row_fields(header + payload, t)


def test_blocks_choose_a_predictor_per_block_and_component():
    """A component that moves evenly takes the slope (its residuals are 0 after a block's first
    step), one that stands still a stream of zeros, one that jitters the key before; every key
    comes back as written."""
    K = 64
    frames = np.arange(K, dtype=np.int64)
    jitter = np.random.default_rng(3).integers(-40, 40, K)
    q = np.column_stack([7 * np.arange(K) - 100, np.full(K, 12), jitter]).astype(np.int64)
    t, fields = _blocks_round_trip(frames, q, 4)
    assert np.array_equal(t["frames"], frames) and np.array_equal(t["q"], q)
    assert np.all(fields[:, 0] == ZERO_STREAM)  # keys a frame apart: no gap codes
    assert np.all(fields[:, 1] & SLOPE)
    assert np.all(fields[:, 2] == ZERO_STREAM)
    assert not np.any(fields[:, 3] & SLOPE) and not np.any(fields[:, 3] == ZERO_STREAM)


def test_a_slope_residual_past_32_bits_takes_the_key_before():
    """A ramp (the slope's) that ends in a swing from -(2^30 - 1) to 2^30 - 1: the slope's
    residual there would need 33 bits, past an escape, so the block takes the key before as its
    predictor though the slope would be shorter; the keys come back."""
    top = (1 << 30) - 1
    q = np.array([1000 * i for i in range(30)] + [-top, top, 5], dtype=np.int64)[:, None]
    frames = np.arange(len(q), dtype=np.int64)
    t, fields = _blocks_round_trip(frames, q, 5)
    assert np.array_equal(t["q"], q)
    assert not fields[0, 1] & SLOPE
    t, fields = _blocks_round_trip(frames[:30], q[:30], 5)  # the ramp alone takes the slope
    assert fields[0, 1] & SLOPE


@pytest.fixture(scope="module")
def small_clip(sample_paths):
    """A short rma clip (09_11, 30 frames, 1 cm) and its payload, for the byte sweeps."""
    m = read_bvh(sample_paths[2]).slice(0, 30)
    result = _encode([m], 1.0)
    (_, payload), = _payloads(result.asset)
    return m, result.asset, payload


def test_every_truncation_of_a_payload_is_rejected(small_clip):
    m, _, payload = small_clip
    assert runtime_accepts(m, CM, "rma", payload, prefix=SECTION_PREFIX)
    for cut in range(len(payload)):
        assert not runtime_accepts(m, CM, "rma", payload[:cut], prefix=SECTION_PREFIX), cut


def test_byte_flips_are_rejected_or_decode_finite(small_clip):
    """Every byte of a small payload, each of four flips (checksum rewritten): the asset is
    refused, or every frame and midpoint samples (it cannot fail once validated) to finite
    transforms and unit quaternions."""
    m, data, payload = small_clip
    (start, _), = _payloads(data)
    times = (np.arange(2 * m.frame_count - 1) * 0.5 / m.frame_rate).astype(np.float32)
    rejected = accepted = 0
    for at in range(len(payload)):
        for mask in (0x01, 0x10, 0x80, 0xFF):
            flipped = _rewrite(data, start + at, bytes([payload[at] ^ mask]))
            try:
                asset = Asset(flipped)
            except RuntimeResultError:
                rejected += 1
                continue
            accepted += 1
            for flags in (0, 1):
                poses = asset.sample_times(0, times, flags)
                assert np.isfinite(poses).all(), (at, mask)
                assert np.abs(np.linalg.norm(poses[..., :4], axis=-1) - 1.0).max() <= 1e-3, (at, mask)
    assert rejected > 0 and accepted > 0, (rejected, accepted)


def test_corrupt_streams_are_rejected_or_decode_to_finite_poses(library):
    """Bytes of a clip's track data flipped in turn (every 7th): open fails cleanly, or the
    asset decodes to finite transforms (not every change breaks a rule)."""
    _, result = library
    start, payload = _payloads(result.asset)[2]
    descs = _descriptors(payload)
    last = descs[-1] + DESC_SIZE[payload[descs[-1]]]
    first = start + (last + 3) // 4 * 4
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


@pytest.mark.parametrize("grid", [1, 2, 4, 8])
def test_key_grid_puts_keys_on_cell_starts_and_the_tolerance_holds(sample_paths, grid):
    """Most keys sit on the first frames of cells of ``grid`` frames (1 ... 8: 100 % ... 82 %
    on 09_11)."""
    m = read_bvh(sample_paths[0])
    result = _encode([m], 1.0, key_grid=grid)
    (_, payload), = _payloads(result.asset)
    _, tracks = decode_keys(payload)
    kept = total = 0
    for t in tracks:
        inner = t["frames"][(t["frames"] > 0) & (t["frames"] < m.frame_count - 1)]
        kept += int(np.sum((inner - 1) % grid == 0))
        total += len(inner)
    assert kept >= 0.75 * total, (kept, total)
    assert _error_cm(Asset(result.asset), m).max() <= 1.0


def test_key_grid_default_follows_the_tolerance():
    from mocodec.codecs.rma import RMASettings

    assert RMASettings(Tolerance(1.0)).key_grid == 4
    assert RMASettings(Tolerance(1.0, 0.1)).key_grid == 1
    assert RMASettings(Tolerance(0.02)).key_grid == 1
    for bad in (3, 9):
        with pytest.raises(ValueError, match="key_grid"):
            RMASettings(Tolerance(1.0), key_grid=bad)


def _random_track(rng, kind: int, keys: int, step: float, frames: int):
    from mocodec.codecs.rma_bitstream import KIND_TWIST, CurveTrack

    f = np.unique(np.concatenate(([0, frames - 1], rng.integers(1, frames - 1, keys))))
    d = 4 if kind == KIND_TWIST else 3
    q = np.cumsum(rng.integers(-40, 41, (len(f), d)), axis=0)
    return CurveTrack(kind, f, q, step, 0.01 if kind == KIND_TWIST else 0.0, np.array([10, -20, 300]),
                      np.array([0, 32767, 0]) if kind == KIND_TWIST else None)


@pytest.mark.parametrize("layout", ["groups", "blocks of 32", "blocks of 2"])
def test_reused_track_bytes_equal_fresh_ones(layout):
    # A repair round writes its clip again with the previous round's tracks at hand: a track
    # that changed in anything (keys, values, step, twist axis) is written anew, so the payload
    # is the one written from scratch.
    from mocodec.codecs.rma_bitstream import KIND_MRP, KIND_TWIST, Blocks, CurveTrack, Groups, WrittenTracks, payload

    rng = np.random.default_rng(5)
    frames = 97
    how = {"groups": Groups(), "blocks of 32": Blocks(5), "blocks of 2": Blocks(1)}[layout]
    tracks = [_random_track(rng, KIND_MRP, 30, 1e-3, frames), _random_track(rng, KIND_TWIST, 12, 2e-3, frames),
              _random_track(rng, KIND_MRP, 50, 5e-4, frames)]
    modes = [(2, 0, 0), (2, 0, 0), (2, 0, 0)]
    written = WrittenTracks()
    assert payload(frames, modes, [], tracks, how, written) == payload(frames, modes, [], tracks, how)
    changed = [CurveTrack(t.kind, t.frames, t.q.copy(), t.step, t.angle_step, t.ref_codes, t.axis_codes)
               for t in tracks]
    changed[0].step = 2e-3
    changed[1].axis_codes = np.array([0, 0, 32767])
    changed[2].q[7, 1] += 1
    assert payload(frames, modes, [], changed, how, written) == payload(frames, modes, [], changed, how)
    assert payload(frames, modes, [], changed, how, written) != payload(frames, modes, [], tracks, how)


@pytest.mark.parametrize("shift", [1, 2, 3, 4, 5, 6])
def test_block_writer_and_reference_agree_on_every_key(shift):
    """RMAL v4 as written is what the format document says (the reference decoder): every key's
    frame and lattice integers, for every block size, with escaped codes (a jump of 2**29 steps
    among steps of tens), a gap of most of the clip, a last block of one key and a one-frame clip."""
    from mocodec.codecs.rma_bitstream import KIND_MRP, KIND_SCALE, KIND_TWIST, Blocks, CurveTrack, payload
    rng = np.random.default_rng(shift)
    frames = 3000
    jumpy = _random_track(rng, KIND_MRP, 200, 1e-3, frames)
    jumpy.q[len(jumpy.q) // 2:, 1] += 1 << 29
    sparse = CurveTrack(KIND_SCALE, np.array([0, 1, frames - 1]), np.array([[5, 6, 7], [8, 9, 10], [-3, 0, 2]]), 1e-2)
    block = 1 << shift
    exact = _random_track(rng, KIND_TWIST, 4 * block, 1e-3, frames)  # the last block one key long
    exact.frames, exact.q = exact.frames[:block + 1], exact.q[:block + 1]
    exact.frames[-1] = frames - 1
    tracks = [jumpy, sparse, exact]
    data = payload(frames, [(2, 0, 0), (0, 0, 2), (2, 0, 0)], [], tracks, Blocks(shift))
    _, decoded = decode_keys(data)
    for t, d in zip(tracks, decoded):
        assert d["block_shift"] == shift
        assert np.array_equal(d["frames"], t.frames) and np.array_equal(d["q"], t.q)
    one = CurveTrack(KIND_MRP, np.array([0]), np.array([[1, -2, 3]]), 1e-3, 0.0, np.array([1, 2, 3]))
    _, (d,) = decode_keys(payload(1, [(2, 0, 0)], [], [one], Blocks(shift)))
    assert np.array_equal(d["frames"], [0]) and np.array_equal(d["q"], one.q)
