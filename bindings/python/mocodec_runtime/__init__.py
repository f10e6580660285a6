"""Python binding of the mocodec C99 runtime (cffi).

A thin wrapper: every call goes to ``runtime_c``; a result other than ``MCD_OK`` becomes a
:class:`RuntimeResultError` carrying the runtime's code.

>>> asset = Asset(open("walk.mcd", "rb").read())          # doctest: +SKIP
>>> rot, trans = asset.sample_frames(0, world=True)        # doctest: +SKIP
"""
from __future__ import annotations

import threading
from dataclasses import dataclass
from enum import IntEnum

import numpy as np

from ._native import ffi, lib

__all__ = [
    "Asset",
    "ClipInfo",
    "NodeInfo",
    "Result",
    "Retarget",
    "RetargetError",
    "RigBone",
    "RuntimeResultError",
    "SAMPLE_CONTACTS",
    "SAMPLE_LOOP",
    "SAMPLE_NEAREST",
    "SAMPLE_WORLD",
    "OPEN_PREVALIDATED",
    "VALIDATE_SKIP_CHECKSUM",
    "clip_scratch_size",
    "validate",
    "version",
]

SAMPLE_WORLD = lib.MCD_SAMPLE_WORLD
SAMPLE_LOOP = lib.MCD_SAMPLE_LOOP
SAMPLE_NEAREST = lib.MCD_SAMPLE_NEAREST
SAMPLE_CONTACTS = lib.MCD_SAMPLE_CONTACTS
VALIDATE_SKIP_CHECKSUM = lib.MCD_VALIDATE_SKIP_CHECKSUM
OPEN_PREVALIDATED = lib.MCD_OPEN_PREVALIDATED
NODE_JOINT, NODE_END_SITE, NODE_VIRTUAL = lib.MCD_NODE_JOINT, lib.MCD_NODE_END_SITE, lib.MCD_NODE_VIRTUAL
TRANSFORM_FLOATS = 10  # mcd_transform: rotation x y z w, translation x y z, scale x y z


class Result(IntEnum):
    """The runtime's result codes (``mcd_result``)."""

    OK = lib.MCD_OK
    INVALID_ARGUMENT = lib.MCD_ERROR_INVALID_ARGUMENT
    TRUNCATED = lib.MCD_ERROR_TRUNCATED
    BAD_MAGIC = lib.MCD_ERROR_BAD_MAGIC
    VERSION_TOO_NEW = lib.MCD_ERROR_VERSION_TOO_NEW
    VERSION_TOO_OLD = lib.MCD_ERROR_VERSION_TOO_OLD
    CHECKSUM = lib.MCD_ERROR_CHECKSUM
    MALFORMED = lib.MCD_ERROR_MALFORMED
    UNSUPPORTED = lib.MCD_ERROR_UNSUPPORTED
    BUFFER_TOO_SMALL = lib.MCD_ERROR_BUFFER_TOO_SMALL
    OUT_OF_RANGE = lib.MCD_ERROR_OUT_OF_RANGE
    SCRATCH_MISMATCH = lib.MCD_ERROR_SCRATCH_MISMATCH
    TRAILING_DATA = lib.MCD_ERROR_TRAILING_DATA
    NOT_FOUND = lib.MCD_ERROR_NOT_FOUND


class RuntimeResultError(Exception):
    """A runtime call returned an error code."""

    def __init__(self, code: int, context: str = "") -> None:
        self.code = Result(code) if code in Result._value2member_map_ else code
        message = ffi.string(lib.mcd_result_string(code)).decode()
        super().__init__(f"{context}: {message}" if context else message)


def _check(code: int, context: str) -> None:
    if code != lib.MCD_OK:
        raise RuntimeResultError(code, context)


def _aligned16(mem):
    """A pointer into ``mem`` (allocated with 16 bytes of slack) on a 16-byte boundary."""
    addr = int(ffi.cast("uintptr_t", mem))
    return mem + ((-addr) % 16)


def version() -> tuple[int, int, int]:
    """The runtime library's version (major, minor, patch)."""
    v = lib.mcd_version()
    return (v >> 16, (v >> 8) & 0xFF, v & 0xFF)


def validate(data: bytes, skip_checksum: bool = False) -> Result:
    """Validate asset bytes; returns the result code (never raises for bad bytes)."""
    flags = VALIDATE_SKIP_CHECKSUM if skip_checksum else 0
    return Result(lib.mcd_validate(ffi.from_buffer(data), len(data), flags))


@dataclass(frozen=True)
class ClipInfo:
    index: int
    name: str
    skeleton: int
    codec: int
    frame_count: int
    frame_rate: float
    duration: float
    node_count: int
    scratch_size: int = 0
    data_offset: int = 0
    data_size: int = 0


@dataclass(frozen=True)
class NodeInfo:
    name: str
    parent: int
    kind: int  # NODE_JOINT, NODE_END_SITE or NODE_VIRTUAL
    rest_translation: tuple[float, float, float]
    rest_rotation: tuple[float, float, float, float]
    rest_scale: tuple[float, float, float]
    channels: tuple[int, ...]

    @property
    def is_end_site(self) -> bool:
        return self.kind == NODE_END_SITE

    @property
    def rest_offset(self) -> tuple[float, float, float]:
        """The BVH name of the rest translation."""
        return self.rest_translation


class Asset:
    """An opened asset, sampled in place from its own copy of the bytes. Safe to share
    between Python threads: each thread samples with its own scratch buffer (the runtime
    releases the GIL while it samples)."""

    def __init__(self, data: bytes, skip_checksum: bool = False) -> None:
        self._data = bytes(data)
        self._buf = ffi.from_buffer(self._data)
        self._asset = ffi.new("mcd_asset*")
        flags = VALIDATE_SKIP_CHECKSUM if skip_checksum else 0
        _check(lib.mcd_open(self._buf, len(self._data), flags, self._asset), "mcd_open")
        self._local = threading.local()
        self.clips = [self._clip_info(i) for i in range(lib.mcd_clip_count(self._asset))]

    @property
    def _scratch(self):
        """This thread's scratch (the runtime's decoder cache; one per thread, made on first use)."""
        scratch = getattr(self._local, "scratch", None)
        if scratch is None:
            size = lib.mcd_scratch_size(self._asset)
            self._local.mem = ffi.new("uint8_t[]", size + 16)
            scratch = _aligned16(self._local.mem)
            _check(lib.mcd_scratch_init(self._asset, scratch, size), "mcd_scratch_init")
            self._local.scratch = scratch
        return scratch

    @property
    def size(self) -> int:
        return len(self._data)

    @property
    def scratch_size(self) -> int:
        return int(lib.mcd_scratch_size(self._asset))

    @property
    def skeleton_count(self) -> int:
        return int(lib.mcd_skeleton_count(self._asset))

    def _clip_info(self, i: int) -> ClipInfo:
        info = ffi.new("mcd_clip_info*")
        _check(lib.mcd_get_clip_info(self._asset, i, info), "mcd_get_clip_info")
        return ClipInfo(
            i,
            ffi.string(info.name).decode("utf-8"),
            info.skeleton,
            info.codec,
            info.frame_count,
            info.frame_rate,
            info.duration,
            info.node_count,
            info.scratch_size,
            info.data_offset,
            info.data_size,
        )

    def clip_index(self, clip: int | str) -> int:
        """Index of a clip given by index or name."""
        if isinstance(clip, str):
            out = ffi.new("uint32_t*")
            _check(lib.mcd_find_clip(self._asset, clip.encode("utf-8"), out), f"clip {clip!r}")
            return int(out[0])
        return int(clip)

    def skeleton_info(self, skeleton: int) -> tuple[int, float]:
        """(node_count, cm_per_unit) of a skeleton."""
        info = ffi.new("mcd_skeleton_info*")
        _check(lib.mcd_get_skeleton_info(self._asset, skeleton, info), "mcd_get_skeleton_info")
        return int(info.node_count), float(info.cm_per_unit)

    def nodes(self, skeleton: int) -> list[NodeInfo]:
        count, _ = self.skeleton_info(skeleton)
        out = []
        info = ffi.new("mcd_node_info*")
        for i in range(count):
            _check(lib.mcd_get_node_info(self._asset, skeleton, i, info), "mcd_get_node_info")
            out.append(
                NodeInfo(
                    ffi.string(info.name).decode("utf-8"),
                    int(info.parent),
                    int(info.kind),
                    tuple(float(info.rest_translation[k]) for k in range(3)),
                    tuple(float(info.rest_rotation[k]) for k in range(4)),
                    tuple(float(info.rest_scale[k]) for k in range(3)),
                    tuple(int(info.channels[k]) for k in range(info.channel_count)),
                )
            )
        return out

    def sample(self, clip: int | str, time: float, flags: int = 0) -> np.ndarray:
        """One pose: ``(node_count, 10)`` float32 rows ``qx qy qz qw tx ty tz sx sy sz``."""
        index = self.clip_index(clip)
        nodes = self.clips[index].node_count if 0 <= index < len(self.clips) else 1
        out = np.empty((nodes, TRANSFORM_FLOATS), dtype=np.float32)
        _check(
            lib.mcd_sample(
                self._asset, index, float(time), flags,
                ffi.cast("mcd_transform*", ffi.from_buffer(out)), nodes, self._scratch,
            ),
            "mcd_sample",
        )
        return out

    def sample_times(self, clip: int | str, times: np.ndarray, flags: int = 0) -> np.ndarray:
        """Poses at many times, in order: ``(len(times), node_count, 10)`` float32."""
        index = self.clip_index(clip)
        if not 0 <= index < len(self.clips):
            raise RuntimeResultError(lib.MCD_ERROR_OUT_OF_RANGE, "mcd_sample")
        nodes = self.clips[index].node_count
        t = np.ascontiguousarray(times, dtype=np.float64)  # seconds as the runtime takes them (double)
        out = np.empty((len(t), nodes, TRANSFORM_FLOATS), dtype=np.float32)
        code = lib.mcdpy_sample_many(
            self._asset, index, ffi.cast("double*", ffi.from_buffer(t)), len(t), flags,
            ffi.cast("mcd_transform*", ffi.from_buffer(out)), nodes, self._scratch,
        )
        _check(code, "mcd_sample")
        return out

    def sample_frames(
        self, clip: int | str, frames: np.ndarray | None = None, world: bool = False,
        contacts: bool = False, scales: bool = False,
    ) -> tuple[np.ndarray, ...]:
        """Rotations ``(F, N, 4)`` and translations ``(F, N, 3)`` (and with ``scales`` the
        scales ``(F, N, 3)``) at integer frames (all frames by default), local or world, as
        float64 arrays; ``contacts`` applies the clip's contact trajectories
        (``SAMPLE_CONTACTS``)."""
        info = self.clips[self.clip_index(clip)]
        if frames is None:
            frames = np.arange(info.frame_count)
        times = np.asarray(frames, dtype=np.float64) / info.frame_rate
        flags = (SAMPLE_WORLD if world else 0) | (SAMPLE_CONTACTS if contacts else 0)
        poses = self.sample_times(info.index, times, flags).astype(np.float64)
        if scales:
            return poses[..., :4], poses[..., 4:7], poses[..., 7:]
        return poses[..., :4], poses[..., 4:7]


# ---------------------------------------------------------------- retargeting
@dataclass(frozen=True)
class RigBone:
    """A bone of a game rig: name, parent index (-1 for a root, parents first), rest local
    transform as 10 floats (``qx qy qz qw tx ty tz sx sy sz``) and ``keep_translation``."""

    name: str
    parent: int
    rest: tuple[float, ...]
    keep_translation: bool = False


class RetargetError(RuntimeResultError):
    """mcd_retarget_init refused an input; ``where`` and ``index`` name it."""

    def __init__(self, code: int, where: str, index: int) -> None:
        self.where, self.index = where, index
        super().__init__(code, f"mcd_retarget_init ({where} {index})" if where != "none" else "mcd_retarget_init")


_ISSUE_WHERE = {lib.MCD_RETARGET_ISSUE_NONE: "none", lib.MCD_RETARGET_ISSUE_BONE: "bone",
                lib.MCD_RETARGET_ISSUE_PAIR: "pair", lib.MCD_RETARGET_ISSUE_CONFIG: "config"}


class Retarget:
    """Poses of one skeleton of ``asset`` onto a rig (the runtime's ``mcd_retarget_*``): bones
    matched to nodes by name, ``pairs`` (bone name -> node name, or None to leave a bone out)
    first. See runtime_c/include/mocodec.h for the rules. One work buffer per thread."""

    def __init__(self, asset: Asset, skeleton: int, bones: list[RigBone], pairs: dict[str, str | None] | None = None,
                 root_motion: bool = True, match_directions: bool = True, up_axis: int = 1, unit_scale: float = 1.0,
                 space_rotation: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 1.0)) -> None:
        self._asset = asset  # the map copies what it needs; kept only so skeleton indices stay meaningful
        keep = []  # the C strings must live through init
        rig = ffi.new("mcd_rig_bone[]", max(len(bones), 1))
        for i, b in enumerate(bones):
            name = ffi.new("char[]", b.name.encode("utf-8"))
            keep.append(name)
            rig[i].name = name
            rig[i].parent = b.parent
            rig[i].flags = lib.MCD_RIG_BONE_KEEP_TRANSLATION if b.keep_translation else 0
            rest = [float(v) for v in b.rest]
            if len(rest) != TRANSFORM_FLOATS:
                raise ValueError(f"bone {i} {b.name!r}: rest needs {TRANSFORM_FLOATS} floats, got {len(rest)}")
            rig[i].rest.rotation = rest[:4]
            rig[i].rest.translation = rest[4:7]
            rig[i].rest.scale = rest[7:]
        items = list((pairs or {}).items())
        cpairs = ffi.new("mcd_retarget_pair[]", max(len(items), 1))
        for i, (bone, node) in enumerate(items):
            cb = ffi.new("char[]", bone.encode("utf-8"))
            keep.append(cb)
            cpairs[i].bone = cb
            if node is None:
                cpairs[i].node = ffi.NULL
            else:
                cn = ffi.new("char[]", node.encode("utf-8"))
                keep.append(cn)
                cpairs[i].node = cn
        config = ffi.new("mcd_retarget_config*")
        lib.mcd_retarget_config_default(config)
        config.flags = (lib.MCD_RETARGET_ROOT_MOTION if root_motion else 0) | (
            lib.MCD_RETARGET_MATCH_DIRECTIONS if match_directions else 0)
        config.up_axis = up_axis
        config.unit_scale = unit_scale
        config.space_rotation = list(space_rotation)
        size = ffi.new("size_t*")
        _check(lib.mcd_retarget_size(asset._asset, skeleton, len(bones), size), "mcd_retarget_size")
        self._map_mem = ffi.new("uint64_t[]", size[0] // 8 + 1)  # 8-byte aligned
        issue = ffi.new("mcd_retarget_issue*")
        code = lib.mcd_retarget_init(asset._asset, skeleton, rig, len(bones), cpairs, len(items), config,
                                     self._map_mem, size[0], issue)
        if code != lib.MCD_OK:
            raise RetargetError(code, _ISSUE_WHERE.get(issue.where, str(issue.where)), int(issue.index))
        info = ffi.new("mcd_retarget_info*")
        _check(lib.mcd_retarget_get_info(self._map_mem, info), "mcd_retarget_get_info")
        self.bone_count, self.node_count, self.matched = int(info.bone_count), int(info.node_count), int(info.matched)
        self._work_size = int(info.work_size)
        self._local = threading.local()

    def node_of(self, bone: int) -> int:
        """The asset node driving rig bone ``bone``, or -1."""
        out = ffi.new("int32_t*")
        _check(lib.mcd_retarget_get_node(self._map_mem, bone, out), "mcd_retarget_get_node")
        return int(out[0])

    def pose(self, local_pose: np.ndarray) -> np.ndarray:
        """The rig's local transforms ``(bone_count, 10)`` float32 for a local pose
        ``(node_count, 10)`` of the asset's skeleton (what :meth:`Asset.sample` returns)."""
        pose = np.ascontiguousarray(local_pose, dtype=np.float32)
        if pose.ndim != 2 or pose.shape[1] != TRANSFORM_FLOATS:
            raise ValueError(f"pose must be (node_count, {TRANSFORM_FLOATS}), got {pose.shape}")
        work = getattr(self._local, "work", None)
        if work is None:
            work = self._local.work = ffi.new("uint64_t[]", self._work_size // 8 + 1)
        out = np.empty((self.bone_count, TRANSFORM_FLOATS), dtype=np.float32)
        _check(lib.mcd_retarget_pose(self._map_mem, ffi.cast("mcd_transform*", ffi.from_buffer(pose)), pose.shape[0],
                                     ffi.cast("mcd_transform*", ffi.from_buffer(out)), self.bone_count,
                                     work, self._work_size), "mcd_retarget_pose")
        return out


# ---------------------------------------------------------------- entropy coder
# The runtime's lossless back-end (docs/FORMAT.md, "Entropy coder"), exposed so the encoder's
# codecs write their streams with the very code mcd_open decodes them with.
__all__ += ["ENTROPY_MAX_ABS", "ENTROPY_MAX_CHANNELS", "entropy_decode", "entropy_encode"]

ENTROPY_MAX_ABS = lib.MCD_ENTROPY_MAX_ABS
ENTROPY_MAX_CHANNELS = lib.MCD_ENTROPY_MAX_CHANNELS


def _entropy_arguments_fit(count: int, channels: int) -> bool:
    """True when count and channels fit the C side's uint32 (it checks the rest)."""
    return 0 <= count <= 0xFFFFFFFF and 0 <= channels <= 0xFFFFFFFF


def entropy_encode(values: np.ndarray, channels: int = 1) -> bytes:
    """Entropy-code integers (``|v| <= 2**30 - 1``, any integer dtype, flattened in C order);
    value ``i`` uses the statistics of channel ``i % channels`` (1 ... 16). Raises
    :class:`RuntimeResultError` (``INVALID_ARGUMENT``) for a value out of range or a bad
    channel count, ``TypeError`` for non-integer values."""
    arr = np.asarray(values)
    if arr.dtype.kind not in "iu":
        raise TypeError(f"entropy_encode needs integers, got dtype {arr.dtype}")
    flat = arr.ravel()
    # Checked before the cast to int32, which would wrap larger values silently.
    if flat.size and (flat.min() < -ENTROPY_MAX_ABS or flat.max() > ENTROPY_MAX_ABS):
        raise RuntimeResultError(lib.MCD_ERROR_INVALID_ARGUMENT, "entropy_encode: value out of range")
    if not _entropy_arguments_fit(flat.size, channels):
        raise RuntimeResultError(lib.MCD_ERROR_INVALID_ARGUMENT, "entropy_encode")
    v = np.ascontiguousarray(flat, dtype=np.int32)
    ptr = ffi.cast("int32_t*", ffi.from_buffer(v))
    size = ffi.new("size_t*")
    # Real data takes a few bytes per value; the worst-case bound is 55, so try small first.
    bound = int(lib.mcd_entropy_bound(v.size))
    for capacity in (min(bound, 8 * v.size + 64), bound):
        out = ffi.new("uint8_t[]", max(capacity, 1))
        code = lib.mcd_entropy_encode(ptr, v.size, channels, out, capacity, size)
        if code != lib.MCD_ERROR_BUFFER_TOO_SMALL:
            break
    _check(code, "mcd_entropy_encode")
    return bytes(ffi.buffer(out, size[0]))


def entropy_decode(data: bytes, count: int, channels: int = 1) -> np.ndarray:
    """Decode exactly ``count`` values (``int32`` array) from a stream of
    :func:`entropy_encode` with the same ``channels``. Raises :class:`RuntimeResultError`:
    ``MALFORMED`` when the stream ends early, has bytes left over or is corrupt,
    ``INVALID_ARGUMENT`` for a bad channel count."""
    if not _entropy_arguments_fit(count, channels):
        raise RuntimeResultError(lib.MCD_ERROR_INVALID_ARGUMENT, "entropy_decode")
    out = np.empty(count, dtype=np.int32)
    code = lib.mcd_entropy_decode(
        ffi.from_buffer(data), len(data), channels, ffi.cast("int32_t*", ffi.from_buffer(out)), count
    )
    _check(code, "mcd_entropy_decode")
    return out


# ---------------------------------------------------------------- encoder support
def clip_scratch_size(codec: int, section: bytes, payload_offset: int, payload_size: int, skeleton: bytes,
                      frame_count: int, frame_rate: float) -> int:
    """The scratch bytes a clip needs (what its clip record stores), from the runtime itself:
    ``section`` is the complete codec section holding the payload, ``skeleton`` a complete
    ``SKEL`` section. Raises :class:`RuntimeResultError` when the payload does not validate."""
    out = ffi.new("size_t*")
    code = lib.mcd_offline_clip_scratch(codec, ffi.from_buffer(section), len(section), payload_offset, payload_size,
                                        ffi.from_buffer(skeleton), len(skeleton), frame_count, frame_rate, out)
    _check(code, "mcd_offline_clip_scratch")
    return int(out[0])
