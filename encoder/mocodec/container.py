"""Writing and reading the asset container (docs/FORMAT.md): header, section table, skeleton
and clip-directory sections, META. Codec payloads are opaque bytes here; a codec's id, section
kind and section version come from the codec registry (:mod:`mocodec.codecs`).

The runtime is the judge of an asset's validity; :func:`read_sections` only parses enough for
the tools (``mocodec info``) and checks bounds as it goes.
"""
from __future__ import annotations

import json
import struct
import zlib
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from . import codecs
from .motion import Skeleton

MAGIC = b"\x89MCD\r\n\x1a\n"
FORMAT_MAJOR = 2
FORMAT_MINOR = 0
HEADER_SIZE = 32
SKEL_VERSION = 2
CLIP_VERSION = 2
SKEL_NODE_SIZE = 32
SKEL_REST_SIZE = 28
NODE_JOINT, NODE_END_SITE, NODE_VIRTUAL = 0, 1, 2


class ContainerError(ValueError):
    """Bytes that are not a readable mocodec asset."""


def _align(n: int, a: int) -> int:
    return (n + a - 1) // a * a


@dataclass
class Section:
    kind: bytes
    data: bytes
    version: int = 1


@dataclass
class ClipEntry:
    """One clip of the directory, with its codec payload."""

    name: str
    skeleton: int
    codec: str
    payload: bytes
    frame_count: int
    frame_rate: float


def skeleton_section(skeleton: Skeleton, cm_per_unit: float) -> bytes:
    """``SKEL`` section bytes for a skeleton (version 2: node records, then the rest rotations
    and scales when any is not the identity)."""
    n = skeleton.node_count
    strings = bytearray()
    name_offsets = []
    for name in skeleton.names:
        name_offsets.append(len(strings))
        strings += name.encode("utf-8") + b"\0"
    rot = np.asarray(skeleton.rest_rotations, dtype=np.float32)
    scale = np.asarray(skeleton.rest_scales, dtype=np.float32)
    has_rest = not (np.all(rot == np.float32([0, 0, 0, 1])) and np.all(scale == 1))
    out = bytearray(struct.pack("<IIfI", n, 1 if has_rest else 0, cm_per_unit,
                                16 + (SKEL_NODE_SIZE + (SKEL_REST_SIZE if has_rest else 0)) * n))
    for i in range(n):
        ch = list(skeleton.channels[i]) + [0xFF] * (6 - len(skeleton.channels[i]))
        kind = NODE_VIRTUAL if skeleton.is_virtual[i] else NODE_END_SITE if skeleton.is_end_site[i] else NODE_JOINT
        out += struct.pack("<iI3fBB6BI", int(skeleton.parents[i]), name_offsets[i],
                           *np.asarray(skeleton.offsets[i], dtype=np.float32).tolist(), kind,
                           len(skeleton.channels[i]), *ch, 0)
    if has_rest:
        out += np.concatenate((rot, scale), axis=1).astype("<f4").tobytes()
    return bytes(out + strings)


def clip_section(entries: list[ClipEntry], section_index: dict[str, int],
                 payload_offsets: list[int], scratch: list[int]) -> bytes:
    """``CLIP`` section bytes; ``section_index`` maps codec name to its section's index,
    ``scratch`` gives each clip's codec scratch bytes (the runtime's own figure)."""
    count = len(entries)
    strings = bytearray()
    out = bytearray(struct.pack("<II", count, 8 + 48 * count))
    for e, off, need in zip(entries, payload_offsets, scratch):
        name_off = len(strings)
        strings += e.name.encode("utf-8") + b"\0"
        rate = np.float32(e.frame_rate)
        duration = np.float32((e.frame_count - 1) / float(rate))
        out += struct.pack(
            "<IIIIIIIffIII",
            name_off, e.skeleton, codecs.get(e.codec).id, section_index[e.codec], off,
            len(e.payload), e.frame_count, float(rate), float(duration), 0, need, 0,
        )
    return bytes(out + strings)


def build_asset(sections: list[Section]) -> bytes:
    """Pack sections into a complete asset: header, table, 16-aligned sections, CRC."""
    count = len(sections)
    offsets = []
    pos = _align(HEADER_SIZE + 16 * count, 16)
    for s in sections:
        offsets.append(pos)
        pos = _align(pos + len(s.data), 16)
    total = pos
    buf = bytearray(total)
    buf[0:8] = MAGIC
    struct.pack_into("<HHIIIII", buf, 8, FORMAT_MAJOR, FORMAT_MINOR, HEADER_SIZE, total, 0, count, 0)
    for i, (s, off) in enumerate(zip(sections, offsets)):
        if len(s.kind) != 4:
            raise ValueError(f"section kind must be 4 bytes, got {s.kind!r}")
        struct.pack_into("<4sIII", buf, HEADER_SIZE + 16 * i, s.kind, s.version, off, len(s.data))
        buf[off:off + len(s.data)] = s.data
    struct.pack_into("<I", buf, 20, zlib.crc32(bytes(buf[24:])) & 0xFFFFFFFF)
    return bytes(buf)


@dataclass
class AssetBuilder:
    """Collects skeletons, clips and metadata, then writes the asset."""

    skeletons: list[tuple[Skeleton, float]] = field(default_factory=list)
    clips: list[ClipEntry] = field(default_factory=list)
    meta: dict[str, Any] = field(default_factory=dict)
    codec_prefix: dict[str, bytes] = field(default_factory=dict)
    """Bytes a codec keeps at the start of its section, before the clip payloads (data that
    clips share, such as a library's PCA axes)."""
    contacts: bytes | None = None
    """The optional ``CNTC`` section (contact trajectories, :mod:`mocodec.contacts`)."""

    def add_skeleton(self, skeleton: Skeleton, cm_per_unit: float) -> int:
        """Index of the skeleton, added unless an equal one (same offsets) is there."""
        for i, (s, cm) in enumerate(self.skeletons):
            if s == skeleton and cm == cm_per_unit:
                return i
        self.skeletons.append((skeleton, cm_per_unit))
        return len(self.skeletons) - 1

    def add_clip(self, entry: ClipEntry) -> None:
        if any(c.name == entry.name for c in self.clips):
            raise ValueError(f"two clips are named {entry.name!r}")
        self.clips.append(entry)

    def build(self) -> bytes:
        if not self.skeletons or not self.clips:
            raise ValueError("an asset needs at least one skeleton and one clip")
        sections = [Section(b"SKEL", skeleton_section(s, cm), SKEL_VERSION) for s, cm in self.skeletons]
        clip_index = len(sections)
        sections.append(Section(b"CLIP", b""))  # filled below, once codec sections are placed
        if self.meta:
            sections.append(Section(b"META", json.dumps(self.meta, sort_keys=True).encode("utf-8")))
        codec_section: dict[str, int] = {}
        payload_offsets = []
        blobs: dict[str, bytearray] = {}
        for e in self.clips:
            blob = blobs.setdefault(e.codec, bytearray(self.codec_prefix.get(e.codec, b"")))
            while len(blob) % 4:
                blob.append(0)
            payload_offsets.append(len(blob))
            blob += e.payload
        for name, blob in blobs.items():
            codec = codecs.get(name)
            codec_section[name] = len(sections)
            sections.append(Section(codec.section_kind, bytes(blob), codec.section_version))
        # Each clip record states the scratch its codec needs, computed by the runtime itself.
        from .runtime import clip_scratch_size  # the runtime binding, imported only to build
        skel_bytes = [sections[i].data for i in range(len(self.skeletons))]
        section_bytes = {name: sections[i].data for name, i in codec_section.items()}  # one copy, not one a clip
        scratch = [clip_scratch_size(codecs.get(e.codec).id, section_bytes[e.codec], off, len(e.payload),
                                     skel_bytes[e.skeleton], e.frame_count, float(np.float32(e.frame_rate)))
                   for e, off in zip(self.clips, payload_offsets)]
        sections[clip_index] = Section(b"CLIP", clip_section(self.clips, codec_section, payload_offsets, scratch),
                                       CLIP_VERSION)
        if self.contacts:
            sections.append(Section(b"CNTC", self.contacts))
        return build_asset(sections)


# --------------------------------------------------------------------------- reading (tools)
@dataclass
class AssetSummary:
    version: tuple[int, int]
    total_size: int
    sections: list[tuple[str, int, int, int]]  # kind, version, offset, size
    meta: dict[str, Any]


def read_summary(data: bytes) -> AssetSummary:
    """Header, section table and META of an asset (bounds-checked; not a validation)."""
    if len(data) < HEADER_SIZE or data[:8] != MAGIC:
        raise ContainerError("not a mocodec asset (bad magic)")
    major, minor, header_size, total, _crc, count, _flags = struct.unpack_from("<HHIIIII", data, 8)
    if total > len(data) or HEADER_SIZE + 16 * count > len(data):
        raise ContainerError("asset is truncated")
    sections = []
    meta: dict[str, Any] = {}
    for i in range(count):
        kind, version, off, size = struct.unpack_from("<4sIII", data, HEADER_SIZE + 16 * i)
        if off + size > len(data):
            raise ContainerError(f"section {i} runs past the end of the asset")
        name = kind.decode("ascii", "replace")
        sections.append((name, version, off, size))
        if kind == b"META":
            try:
                meta = json.loads(data[off:off + size].decode("utf-8"))
            except (UnicodeDecodeError, json.JSONDecodeError) as exc:
                raise ContainerError(f"META section is not JSON: {exc}") from None
    return AssetSummary((major, minor), total, sections, meta)
