"""The codec registry: one table of names, ids, section kinds and versions that the container
and the command line read, that agrees with the C runtime's own table, and one clear error for
a codec or a setting that does not exist."""
from __future__ import annotations

import dataclasses
import struct
import subprocess
import sys

import numpy as np
import pytest
from mocodec_runtime._native import lib

from mocodec import codecs, runtime
from mocodec.container import AssetBuilder, ClipEntry
from mocodec.encode import encode_motions
from mocodec.io import read_bvh
from mocodec.motion import Motion, Skeleton
from mocodec.runtime import Asset, Result, validate
from mocodec.tolerance import Tolerance, ToleranceNotMet
from mocodec.units import resolve_units

# Settings that keep each codec quick on a 30-frame slice (the tolerance is loose).
QUICK = {"rma-pca": {"groups": 1}, "neural": {"max_frequencies": 2, "iterations": 60}}


def test_names_ids_and_section_kinds_are_unique():
    names = [c.name for c in codecs.CODECS]
    assert names == codecs.available()
    for attr in ("name", "id", "section_kind"):
        values = [getattr(c, attr) for c in codecs.CODECS]
        assert len(set(values)) == len(values), attr
    for c in codecs.CODECS:
        assert len(c.section_kind) == 4 and c.section_kind.isascii(), c
        assert c.section_kind not in (b"SKEL", b"CLIP", b"META", b"CNTC"), c
        assert c.section_version >= 1 and codecs.by_id(c.id) is c


def test_unknown_codec_is_one_error_listing_the_codecs(sample_paths):
    with pytest.raises(ValueError) as info:
        codecs.get("mp3")
    message = str(info.value)
    assert "'mp3'" in message and all(name in message for name in codecs.available())
    m = read_bvh(sample_paths[2]).slice(0, 10)
    with pytest.raises(ValueError, match="unknown codec 'mp3'; available: spline, rma"):
        encode_motions([m], [resolve_units(m.skeleton, "cmu", None)], "mp3", Tolerance(1.0))
    assert codecs.by_id(99) is None


def test_command_line_lists_the_registry():
    def run(*args: str) -> subprocess.CompletedProcess:
        return subprocess.run([sys.executable, "-m", "mocodec", *args], capture_output=True, text=True)

    top = run("--help").stdout
    for c in codecs.CODECS:
        assert f"  {c.name}" in top and c.summary in top, c.name
    encode = "".join(run("encode", "--help").stdout.split())  # argparse wraps lines at hyphens
    assert "oneof:" + ",".join(codecs.available()) in encode
    bad = run("encode", "x.bvh", "-o", "x.mcd", "--codec", "mp3")
    assert bad.returncode == 2 and "invalid choice: 'mp3'" in bad.stderr and "ik-predict" in bad.stderr


@pytest.mark.parametrize("codec", codecs.CODECS, ids=lambda c: c.name)
def test_settings_type_and_unknown_settings(codec):
    kind = codec.settings_type
    assert dataclasses.is_dataclass(kind) and dataclasses.fields(kind)[0].name == "tolerance"
    settings = codec.settings(Tolerance(1.0))
    assert isinstance(settings, kind) and settings.tolerance == Tolerance(1.0)
    with pytest.raises(TypeError) as info:
        codec.settings(Tolerance(1.0), bogus=1)
    message = str(info.value)
    assert f"codec {codec.name!r} has no setting 'bogus'" in message
    assert all(f.name in message for f in dataclasses.fields(kind)[1:])


def test_the_container_takes_ids_kinds_and_versions_from_the_registry(monkeypatch, sample_paths):
    """Change the registry's row for spline: the container writes what the row says (and the
    scratch figure the runtime gives for the clip, here asked of a stand-in: the runtime does
    not know codec 42)."""
    m = read_bvh(sample_paths[2]).slice(0, 4)
    moved = dataclasses.replace(codecs.get("spline"), id=42, section_kind=b"TEST", section_version=9)
    monkeypatch.setitem(codecs._BY_NAME, "spline", moved)
    asked = []

    def scratch(codec, section, offset, size, skeleton, frames, rate):
        asked.append((codec, bytes(section[offset:offset + size]), frames))
        return 4096

    monkeypatch.setattr(runtime, "clip_scratch_size", scratch)
    b = AssetBuilder()
    b.add_skeleton(m.skeleton, 5.6444)
    b.add_clip(ClipEntry(m.name, 0, "spline", b"\0" * 8, m.frame_count, m.frame_rate))
    data = b.build()
    table = _sections(data)
    assert (b"TEST", 9) in [(k, v) for k, v, _, _ in table]
    clip = next(off for k, _, off, _ in table if k == b"CLIP")
    assert struct.unpack_from("<I", data, clip + 8 + 8)[0] == 42
    assert asked == [(42, b"\0" * 8, m.frame_count)]
    assert struct.unpack_from("<I", data, clip + 8 + 40)[0] == 4096


def test_one_tolerance_error_for_every_codec(sample_paths):
    """Every codec raises the one ToleranceNotMet; encode_motions turns it into EncodeError."""
    m = read_bvh(sample_paths[2]).slice(0, 8)

    def check(i: int, payload: bytes, prefix: bytes = b"", halfway: bool = False) -> np.ndarray:
        return np.full((m.frame_count - int(halfway), m.skeleton.node_count), 1e9)  # never within

    for c in codecs.CODECS:
        if not c.per_clip:
            continue
        with pytest.raises(ToleranceNotMet):
            codecs.encode_each_clip(c.implementation.encode_clip, [m], [5.6444],
                                    c.settings(Tolerance(1.0), **_few_rounds(c.name)), check)
    with pytest.raises(ToleranceNotMet):
        codecs.get("rma").encode([m], [5.6444], Tolerance(1.0), check, {"max_repairs": 1})


def _few_rounds(name: str) -> dict:
    return {"spline": {"max_repairs": 1}, "fk-wavelet": {"max_repairs": 1},
            "ik-predict": {"search_steps": 2}, "neural": {"max_frequencies": 0, "iterations": 5}}.get(name, {})


# ------------------------------------------------------------------ agreement with the C runtime
def _sections(data: bytes) -> list[tuple[bytes, int, int, int]]:
    count = struct.unpack_from("<I", data, 24)[0]
    return [struct.unpack_from("<4sIII", data, 32 + 16 * i) for i in range(count)]


def test_registry_ids_are_the_runtime_enum():
    """``mcd_codec`` as the compiled runtime binding sees it, one entry per registered codec."""
    runtime = {n[len("MCD_CODEC_"):]: getattr(lib, n) for n in dir(lib) if n.startswith("MCD_CODEC_")}
    assert runtime == {c.name.upper().replace("-", "_"): c.id for c in codecs.CODECS}


@pytest.mark.parametrize("codec", codecs.CODECS, ids=lambda c: c.name)
def test_runtime_reads_the_registry_kind_and_version(sample_paths, codec):
    """The runtime opens an asset the registry's row laid out, reports the row's id for the
    clip, and rejects the section once its version or kind is not the row's."""
    m = read_bvh(sample_paths[2]).slice(0, 30)
    units = [resolve_units(m.skeleton, "cmu", None)]
    data = encode_motions([m], units, codec.name, Tolerance(4.0), QUICK.get(codec.name)).asset
    assert validate(data) == Result.OK
    assert Asset(data).clips[0].codec == codec.id
    at = [32 + 16 * i for i, s in enumerate(_sections(data)) if s[0] == codec.section_kind]
    assert len(at) == 1 and struct.unpack_from("<I", data, at[0] + 4)[0] == codec.section_version
    newer = bytearray(data)
    struct.pack_into("<I", newer, at[0] + 4, codec.section_version + 1)
    assert validate(bytes(newer), skip_checksum=True) == Result.UNSUPPORTED
    # The section relabelled as another codec's (kind and version): the clip record names a
    # section of the wrong kind.
    other = next(c for c in codecs.CODECS if c is not codec)
    moved = bytearray(data)
    struct.pack_into("<4sI", moved, at[0], other.section_kind, other.section_version)
    assert validate(bytes(moved), skip_checksum=True) == Result.MALFORMED


def _held_joint(sample_paths) -> Motion:
    """The first 7 nodes of 09_11 (Hips to the left toe, 30 frames) with a rest rotation on
    every joint (its pose on frame 15) and LHipJoint held at the identity on every frame while
    its rest rotation is 0.4 rad about (1, 2, -0.5): a glTF joint that the clip turns away
    from its bind pose and keeps there."""
    m = read_bvh(sample_paths[2]).slice(0, 30)
    n, sk = 7, m.skeleton
    rotations = m.rotations[:, :n].copy()
    rotations[:, 1] = [0.0, 0.0, 0.0, 1.0]
    rest = rotations[15].copy()
    axis = np.array([1.0, 2.0, -0.5]) / np.linalg.norm([1.0, 2.0, -0.5])
    rest[1] = [*(axis * np.sin(0.2)), np.cos(0.2)]
    skeleton = Skeleton(sk.names[:n], sk.parents[:n], sk.offsets[:n], list(sk.channels[:n]), sk.is_end_site[:n],
                        rest_rotations=rest)
    return Motion(skeleton, rotations, m.translations[:, :n].copy(), m.frame_time, "held")


@pytest.mark.parametrize("codec", ["spline", "rma", "ik-predict"])
def test_a_joint_held_off_its_rest_rotation_is_encoded(sample_paths, codec):
    """Rotation mode 0 means the rest rotation now (format 2), not the identity: a joint at
    the identity whose rest rotation is not must be coded, and the tolerance met."""
    m = _held_joint(sample_paths)
    result = encode_motions([m], [resolve_units(m.skeleton, "cmu", None)], codec, Tolerance(1.0))
    rot, _ = Asset(result.asset).sample_frames(0)
    assert np.abs(np.abs(rot[:, 1, 3]) - 1.0).max() <= 1e-3  # LHipJoint at the identity
    assert result.max_error_cm <= 1.0
