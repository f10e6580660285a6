"""Reading glTF 2.0 animations (``.gltf`` with embedded or external buffers, ``.glb``).

The skeleton is every skin's joints, every node an animation channel targets, and all their
ancestors (armature nodes with a static scale or a ``matrix`` move the joints too), in
parent-first order; each node keeps its rest TRS (a ``matrix`` is decomposed). Every leaf gets a
virtual end point (SKEL kind 2) so that the error metric sees how the leaf is turned: it
continues the leaf's parent bone by that bone's length (at least :data:`VIRTUAL_MIN_M`) in the
rest pose. Every animation becomes a clip: translation, rotation and scale channels, LINEAR
(slerp for rotations), STEP and CUBICSPLINE samplers, evaluated at the times the clip is
resampled at; a node a clip does not animate holds its rest. glTF lengths are metres.

Bad input becomes a :class:`GLTFError` that names the file, the item (accessor, buffer,
node, animation channel) and the fault.
"""
from __future__ import annotations

import base64
import math
import os
import urllib.parse
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .. import limits
from .. import rotations as R
from ..kinematics import forward_kinematics
from ..motion import Motion, Skeleton, unique_name
from .files import read_regular_file

__all__ = ["GLTFError", "DEFAULT_RATE", "read_gltf", "gltf_rest_pose"]

DEFAULT_RATE = 60.0
"""Frames per second of a clip whose keys are not evenly spaced (and no rate is given)."""
MIN_KEY_RATE = 24.0
"""Evenly spaced keys slower than this are subdivided (by the smallest whole number that
reaches it): the source's own interpolation between sparse keys is then measured too."""
VIRTUAL_MIN_M = 0.03
"""The shortest virtual end point, metres (ACL's default shell distance, 3 cm)."""
UNIT_TOLERANCE = 1e-3
"""How far from 1 a rotation's length may be (float32 rounding of exporters); beyond it the
file is refused."""

_COMPONENTS = {5120: ("<i1", 127.0), 5121: ("<u1", 255.0), 5122: ("<i2", 32767.0),
               5123: ("<u2", 65535.0), 5125: ("<u4", None), 5126: ("<f4", None)}
_TYPES = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
_PATH_WIDTH = {"translation": 3, "rotation": 4, "scale": 3}
_INTERPOLATIONS = ("LINEAR", "STEP", "CUBICSPLINE")
_COMPRESSION = {"EXT_meshopt_compression", "KHR_meshopt_compression"}  # buffer views we cannot read


class GLTFError(ValueError):
    """A glTF file that cannot be read; ``str(err)`` is ``"{path}: {item}: {message}"``."""

    def __init__(self, message: str, path: str | None = None, item: str | None = None) -> None:
        self.message, self.path, self.item = message, path, item
        super().__init__(str(self))

    def __str__(self) -> str:
        return ": ".join(p for p in (self.path, self.item, self.message) if p)

    def __reduce__(self):
        return (type(self), (self.message, self.path, self.item))


# ------------------------------------------------------------------------------- loading
def _load_document(path: Path):
    """The pygltflib document of ``path``."""
    try:
        from pygltflib import GLTF2
    except ImportError:  # pragma: no cover - a broken install
        raise GLTFError("reading glTF needs pygltflib (pip install pygltflib)", str(path)) from None
    data = read_regular_file(path, "glTF file", lambda message: GLTFError(message, str(path)))
    try:
        with warnings.catch_warnings():  # pygltflib warns and goes on; a fault is ours to report
            warnings.simplefilter("ignore")
            if data[:4] == b"glTF":
                doc = GLTF2.load_from_bytes(data)
            else:
                doc = GLTF2.gltf_from_json(data.decode("utf-8"))
    except GLTFError:
        raise
    except Exception as exc:  # pygltflib raises whatever its parser meets
        text = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise GLTFError(f"not a readable glTF 2.0 file ({text})", str(path)) from None
    if doc is None:
        raise GLTFError("not a readable glTF 2.0 file", str(path))
    version = str(getattr(doc.asset, "version", "") or "")
    if not version.startswith("2."):
        raise GLTFError(f"asset.version is {version!r}; only glTF 2.x is read", str(path))
    compressed = sorted(set(doc.extensionsRequired or []) & _COMPRESSION)
    if compressed:
        raise GLTFError(f"requires {', '.join(compressed)} (compressed buffers), which this reader "
                        "does not decode; export without it", str(path), "extensionsRequired")
    return doc


class _Reader:
    """Buffers and accessors of one document, every range checked."""

    def __init__(self, doc, path: Path) -> None:
        self.doc, self.path = doc, path
        self._buffers: dict[int, bytes] = {}

    def error(self, item: str, message: str) -> GLTFError:
        return GLTFError(message, str(self.path), item)

    def buffer(self, index: int) -> bytes:
        if index in self._buffers:
            return self._buffers[index]
        buffers = self.doc.buffers or []
        if not isinstance(index, int) or not 0 <= index < len(buffers):
            raise self.error(f"buffer {index}", f"does not exist (the file has {len(buffers)})")
        buf = buffers[index]
        uri = buf.uri
        item = f"buffer {index}"
        if uri is None:
            blob = self.doc.binary_blob() if index == 0 else None
            if blob is None:
                raise self.error(item, "has no uri and the file has no binary chunk (missing buffer)")
            data = bytes(blob)
        elif uri.startswith("data:"):
            head, _, body = uri.partition(",")
            try:
                data = base64.b64decode(body, validate=True) if head.endswith(";base64") \
                    else urllib.parse.unquote_to_bytes(body)
            except ValueError:
                raise self.error(item, "its data: URI is not valid base64") from None
        else:
            target = self.path.parent / urllib.parse.unquote(uri)
            data = read_regular_file(target, "buffer file", lambda message: self.error(
                f"{item} ({uri})", f"the buffer file: {message} (missing buffer)"))
        length = buf.byteLength
        if not isinstance(length, int) or length < 0:
            raise self.error(item, f"byteLength {length!r} is not a length")
        if len(data) < length:
            raise self.error(item, f"holds {len(data)} bytes, byteLength says {length}")
        self._buffers[index] = data
        return data

    def _view_bytes(self, index, item: str) -> tuple[bytes, int, int, int | None]:
        """(buffer, start, length, stride) of a bufferView."""
        views = self.doc.bufferViews or []
        if not isinstance(index, int) or not 0 <= index < len(views):
            raise self.error(item, f"bufferView {index} does not exist")
        v = views[index]
        data = self.buffer(v.buffer)
        start, length = v.byteOffset or 0, v.byteLength
        if not isinstance(length, int) or start < 0 or start + length > len(data):
            raise self.error(item, f"bufferView {index} (bytes {start} + {length}) runs past its "
                                   f"buffer of {len(data)} bytes")
        return data, start, length, v.byteStride

    def accessor(self, index, item: str) -> np.ndarray:
        """An accessor's elements as float64 ``(count, components)`` (normalized integers
        mapped to [-1, 1] / [0, 1]; sparse substitution applied)."""
        accessors = self.doc.accessors or []
        if not isinstance(index, int) or not 0 <= index < len(accessors):
            raise self.error(item, f"accessor {index} does not exist")
        a = accessors[index]
        item = f"{item}, accessor {index}"
        if a.componentType not in _COMPONENTS or a.type not in _TYPES:
            raise self.error(item, f"unknown componentType {a.componentType} / type {a.type!r}")
        if not isinstance(a.count, int) or a.count < 1:
            raise self.error(item, f"count {a.count!r} is not a positive number")
        dtype, norm = _COMPONENTS[a.componentType]
        width = _TYPES[a.type]
        elem = np.dtype(dtype).itemsize * width
        if a.bufferView is None:
            # All zeros (sparse may replace some): no bytes bound the count, so the format's
            # frame limit does (a rotation a frame: 4 values), before the allocation.
            if a.count * width > 4 * limits.MAX_FRAMES:
                raise self.error(item, f"count {a.count:,} of {width} values with no bufferView (zeros) is "
                                       f"more than the {4 * limits.MAX_FRAMES:,} values a clip can use")
            values = np.zeros((a.count, width))
        else:
            data, start, length, stride = self._view_bytes(a.bufferView, item)
            stride = stride or elem
            offset = a.byteOffset or 0
            end = offset + stride * (a.count - 1) + elem
            if offset < 0 or end > length:
                raise self.error(item, f"{a.count} elements of {elem} bytes (stride {stride}) from "
                                       f"offset {offset} need {end} bytes; its bufferView has {length} "
                                       "(bad accessor bounds)")
            raw = np.ndarray((a.count, width), dtype=dtype, buffer=data, offset=start + offset,
                             strides=(stride, np.dtype(dtype).itemsize))
            values = raw.astype(np.float64)
        if a.normalized and norm is not None:
            values = np.maximum(values / norm, -1.0)
        if a.sparse is not None:
            values = self._sparse(a, values, item)
        return values

    def _sparse(self, a, values: np.ndarray, item: str) -> np.ndarray:
        s = a.sparse
        n = s.count
        if not isinstance(n, int) or not 0 < n <= a.count:
            raise self.error(item, f"sparse count {n!r} out of range")
        idx_dtype = {5121: "<u1", 5123: "<u2", 5125: "<u4"}.get(s.indices.componentType)
        if idx_dtype is None:
            raise self.error(item, f"sparse indices componentType {s.indices.componentType}")
        data, start, length, _ = self._view_bytes(s.indices.bufferView, item + " sparse indices")
        off = s.indices.byteOffset or 0
        size = np.dtype(idx_dtype).itemsize * n
        if off + size > length:
            raise self.error(item, "sparse indices run past their bufferView (bad accessor bounds)")
        idx = np.frombuffer(data, idx_dtype, n, start + off).astype(np.int64)
        if np.any(idx >= a.count) or np.any(np.diff(idx) <= 0):
            raise self.error(item, "sparse indices out of range or not increasing")
        dtype, norm = _COMPONENTS[a.componentType]
        width = values.shape[1]
        data, start, length, _ = self._view_bytes(s.values.bufferView, item + " sparse values")
        off = s.values.byteOffset or 0
        size = np.dtype(dtype).itemsize * width * n
        if off + size > length:
            raise self.error(item, "sparse values run past their bufferView (bad accessor bounds)")
        sub = np.frombuffer(data, dtype, n * width, start + off).astype(np.float64).reshape(n, width)
        if a.normalized and norm is not None:
            sub = np.maximum(sub / norm, -1.0)
        values = values.copy()
        values[idx] = sub
        return values


# ------------------------------------------------------------------------------- the node graph
@dataclass
class _Rest:
    translation: np.ndarray
    rotation: np.ndarray
    scale: np.ndarray


def _node_label(doc, i: int) -> str:
    name = doc.nodes[i].name
    return f"node {i} ({name!r})" if name else f"node {i}"


def _parents(doc, path: Path) -> np.ndarray:
    """Parent of every node (-1 for roots); a node with two parents, a child index out of
    range or a cycle is a GLTFError."""
    n = len(doc.nodes)
    parent = np.full(n, -1, dtype=np.int64)
    for i, node in enumerate(doc.nodes):
        for c in node.children or []:
            if not isinstance(c, int) or not 0 <= c < n:
                raise GLTFError(f"child {c!r} does not exist", str(path), _node_label(doc, i))
            if c == i:
                raise GLTFError("is its own child (cycle in the node graph)", str(path), _node_label(doc, i))
            if parent[c] >= 0:
                raise GLTFError(f"has two parents (nodes {parent[c]} and {i})", str(path),
                                _node_label(doc, c))
            parent[c] = i
    for i in range(n):  # a cycle: walking up never reaches a root
        seen, j = set(), i
        while j >= 0:
            if j in seen:
                raise GLTFError("lies on a cycle in the node graph", str(path), _node_label(doc, j))
            seen.add(j)
            j = int(parent[j])
    return parent


def _rest_of(doc, i: int, path: Path) -> _Rest:
    """A node's rest TRS (its ``matrix`` decomposed)."""
    node = doc.nodes[i]
    item = _node_label(doc, i)

    def vec(value, n, default):
        if value is None:
            return np.array(default, dtype=np.float64)
        a = np.asarray(value, dtype=np.float64)
        if a.shape != (n,) or not np.all(np.isfinite(a)):
            raise GLTFError(f"rest value {value!r} is not {n} finite numbers", str(path), item)
        return a

    t = vec(node.translation, 3, [0.0, 0.0, 0.0])
    q = vec(node.rotation, 4, [0.0, 0.0, 0.0, 1.0])
    s = vec(node.scale, 3, [1.0, 1.0, 1.0])
    norm = float(np.linalg.norm(q))
    if abs(norm - 1.0) > UNIT_TOLERANCE:
        raise GLTFError(f"rest rotation {node.rotation} is not a unit quaternion (length {norm:.6g})",
                        str(path), item)
    q = q / norm
    if node.matrix is not None:
        m = np.asarray(node.matrix, dtype=np.float64)
        if m.shape != (16,) or not np.all(np.isfinite(m)):
            raise GLTFError("matrix is not 16 finite numbers", str(path), item)
        t, q, s = _decompose(m.reshape(4, 4).T, path, item)
    return _Rest(t, q, s)


def _decompose(m: np.ndarray, path: Path, item: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Translation, rotation and scale of an affine matrix without shear (glTF requires that)."""
    if not np.allclose(m[3], [0.0, 0.0, 0.0, 1.0], atol=1e-6):
        raise GLTFError("matrix is not affine (bottom row is not 0 0 0 1)", str(path), item)
    a = m[:3, :3]
    s = np.linalg.norm(a, axis=0)
    if np.any(s < 1e-12):
        raise GLTFError("matrix has a zero scale", str(path), item)
    if np.linalg.det(a) < 0:
        s[0] = -s[0]
    rot = a / s
    if not np.allclose(rot.T @ rot, np.eye(3), atol=1e-4):
        raise GLTFError("matrix has shear; it cannot be a translation, rotation and scale",
                        str(path), item)
    q = R.quat_from_matrix(rot[None])[0]
    return m[:3, 3].copy(), q / np.linalg.norm(q), s


# ------------------------------------------------------------------------------- channels
@dataclass
class _Channel:
    node: int
    path: str
    times: np.ndarray        # (K,)
    values: np.ndarray       # (K, d), or (3K, d) for CUBICSPLINE
    interpolation: str


def _channels(doc, reader: _Reader, a: int) -> list[_Channel]:
    anim = doc.animations[a]
    label = f"animation {a}" + (f" ({anim.name!r})" if anim.name else "")
    out: list[_Channel] = []
    seen: dict[tuple[int, str], int] = {}
    samplers = anim.samplers or []
    for c, ch in enumerate(anim.channels or []):
        item = f"{label} channel {c}"
        target = ch.target
        if target is None or target.node is None or target.path not in _PATH_WIDTH:
            continue  # morph weights, or a channel without a node: not a transform
        if not 0 <= target.node < len(doc.nodes):
            raise reader.error(item, f"targets node {target.node}, which does not exist")
        if not isinstance(ch.sampler, int) or not 0 <= ch.sampler < len(samplers):
            raise reader.error(item, f"sampler {ch.sampler!r} does not exist")
        key = (target.node, target.path)
        if key in seen:
            raise reader.error(item, f"animates the {target.path} of {_node_label(doc, target.node)} "
                                     f"again (channel {seen[key]} does already)")
        seen[key] = c
        smp = samplers[ch.sampler]
        interp = smp.interpolation or "LINEAR"
        if interp not in _INTERPOLATIONS:
            raise reader.error(item, f"unknown interpolation {interp!r}")
        times = reader.accessor(smp.input, f"{item} input")
        values = reader.accessor(smp.output, f"{item} output")
        if times.shape[1] != 1:
            raise reader.error(item, "key times are not scalars")
        times = times[:, 0]
        width = _PATH_WIDTH[target.path]
        if values.shape[1] != width:
            raise reader.error(item, f"{target.path} output has {values.shape[1]} components, "
                                     f"expected {width}")
        k = len(times)
        expect = 3 * k if interp == "CUBICSPLINE" else k
        if len(values) != expect:
            raise reader.error(item, f"{len(values)} output values for {k} key times "
                                     f"({interp} needs {expect})")
        bad = np.flatnonzero(~np.isfinite(times))
        if bad.size:
            raise reader.error(item, f"key time {int(bad[0])} is {times[bad[0]]} (NaN key)")
        bad_rows = np.flatnonzero(~np.all(np.isfinite(values), axis=1))
        if bad_rows.size:
            r = int(bad_rows[0])
            key_index = r // 3 if interp == "CUBICSPLINE" else r
            raise reader.error(item, f"key {key_index} value {values[r].tolist()} is not finite (NaN key)")
        if np.any(np.diff(times) <= 0):
            j = int(np.flatnonzero(np.diff(times) <= 0)[0])
            raise reader.error(item, f"key times do not increase (key {j + 1} at {times[j + 1]:.6g} s "
                                     f"after {times[j]:.6g} s)")
        if target.path == "rotation":
            points = values[1::3] if interp == "CUBICSPLINE" else values
            norms = np.linalg.norm(points, axis=1)
            off = np.flatnonzero(np.abs(norms - 1.0) > UNIT_TOLERANCE)
            if off.size:
                j = int(off[0])
                raise reader.error(item, f"key {j} rotation {points[j].tolist()} is not a unit "
                                         f"quaternion (length {norms[j]:.6g})")
            if interp != "CUBICSPLINE":
                values = values / norms[:, None]
        out.append(_Channel(target.node, target.path, times, values, interp))
    return out


def _evaluate(ch: _Channel, t: np.ndarray) -> np.ndarray:
    """The channel's value at times ``t`` by its own interpolation (held before the first
    and after the last key)."""
    times, k = ch.times, len(ch.times)
    if ch.interpolation == "CUBICSPLINE":
        inn, val, out = ch.values[0::3], ch.values[1::3], ch.values[2::3]
    else:
        val = ch.values
    if k == 1:
        return np.broadcast_to(val[0], (len(t), val.shape[1])).copy()
    if ch.interpolation == "STEP":  # a key a microsecond off (float32 times) is still reached
        return val[np.clip(np.searchsorted(times, t + 1e-6, side="right") - 1, 0, k - 1)]
    i = np.clip(np.searchsorted(times, t, side="right") - 1, 0, k - 2)
    dt = times[i + 1] - times[i]
    u = np.clip((t - times[i]) / dt, 0.0, 1.0)[:, None]
    a, b = val[i], val[i + 1]
    if ch.interpolation == "CUBICSPLINE":
        u2, u3 = u * u, u * u * u
        res = ((2 * u3 - 3 * u2 + 1) * a + dt[:, None] * (u3 - 2 * u2 + u) * out[i]
               + (-2 * u3 + 3 * u2) * b + dt[:, None] * (u3 - u2) * inn[i + 1])
        return R.quat_normalize(res) if ch.path == "rotation" else res
    if ch.path != "rotation":
        return a + u * (b - a)
    return _slerp(a, b, u[:, 0])


def _slerp(a: np.ndarray, b: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Shortest-path spherical interpolation of unit quaternions."""
    dot = np.sum(a * b, axis=1)
    b = np.where(dot[:, None] < 0, -b, b)
    dot = np.abs(dot)
    theta = np.arccos(np.clip(dot, -1.0, 1.0))
    small = theta < 1e-6
    sin = np.where(small, 1.0, np.sin(theta))
    wa = np.where(small, 1.0 - u, np.sin((1.0 - u) * theta) / sin)
    wb = np.where(small, u, np.sin(u * theta) / sin)
    return R.quat_normalize(wa[:, None] * a + wb[:, None] * b)


# ------------------------------------------------------------------------------- the skeleton
@dataclass
class _Layout:
    """The nodes kept, in skeleton order, and the virtual end points after them."""

    skeleton: Skeleton
    gltf_nodes: list[int]        # skeleton index -> glTF node index (joints and ancestors)
    joints: set[int]             # glTF node indices that are skin joints


def _layout(doc, path: Path, animated_nodes: set[int]) -> _Layout:
    parent = _parents(doc, path)
    joints: set[int] = set()
    for s, skin in enumerate(doc.skins or []):
        for j in skin.joints or []:
            if not isinstance(j, int) or not 0 <= j < len(doc.nodes):
                raise GLTFError(f"joint {j!r} does not exist", str(path), f"skin {s}")
            joints.add(j)
    keep = np.zeros(len(doc.nodes), dtype=bool)
    for j in joints | animated_nodes:
        while j >= 0 and not keep[j]:
            keep[j] = True
            j = int(parent[j])
    # Depth first from the roots, children in file order: parents come first.
    children: list[list[int]] = [[] for _ in doc.nodes]
    for i, node in enumerate(doc.nodes):
        children[i] = [c for c in node.children or [] if keep[c]]
    order: list[int] = []
    stack = [i for i in range(len(doc.nodes)) if keep[i] and parent[i] < 0][::-1]
    while stack:
        i = stack.pop()
        order.append(i)
        stack.extend(reversed(children[i]))
    index = {g: k for k, g in enumerate(order)}
    rests = [_rest_of(doc, g, path) for g in order]
    names = _unique_names([doc.nodes[g].name or f"node{g}" for g in order])
    parents = [index[int(parent[g])] if parent[g] >= 0 else -1 for g in order]
    offsets = [r.translation for r in rests]
    rots = [r.rotation for r in rests]
    scales = [r.scale for r in rests]
    base = Skeleton(names, parents, offsets, [()] * len(order), [False] * len(order), rots, scales)
    return _Layout(_with_end_points(base), order, joints)


def _unique_names(names: list[str]) -> list[str]:
    used: set[str] = set()
    out = []
    for raw in names:
        name = "".join(c if c.isprintable() else "_" for c in raw).strip() or "node"
        out.append(unique_name(name.encode("utf-8")[:200].decode("utf-8", "ignore"), used))
    return out


def gltf_rest_pose(skeleton: Skeleton) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """World rotations (N, 4), positions (N, 3) and scales (N, 3) of the rest pose."""
    rot, pos, scale = forward_kinematics(skeleton, skeleton.rest_rotations[None], skeleton.offsets[None],
                                         skeleton.rest_scales[None], world_scales=True)
    return rot[0], pos[0], scale[0]


def _with_end_points(sk: Skeleton) -> Skeleton:
    """``sk`` with a virtual end point below every leaf: along the leaf's parent bone (the
    nearest ancestor away from it) by that bone's length, at least VIRTUAL_MIN_M, in the rest
    pose; a lone node gets one VIRTUAL_MIN_M along its own +Y."""
    n = sk.node_count
    rot, pos, scale = gltf_rest_pose(sk)
    leaves = [i for i in range(n) if not np.any(sk.parents == i)]
    names, parents = list(sk.names), list(sk.parents)
    offsets = list(sk.offsets)
    used = set(names)
    for i in leaves:
        d = None
        p = int(sk.parents[i])
        while p >= 0:
            v = pos[i] - pos[p]
            if np.linalg.norm(v) > 1e-9:
                d = v
                break
            p = int(sk.parents[p])
        if d is None:
            d = R.quat_rotate(rot[i], np.array([0.0, 1.0, 0.0]) * scale[i])
            if np.linalg.norm(d) < 1e-12:
                d = np.array([0.0, 1.0, 0.0])
        length = max(float(np.linalg.norm(d)), VIRTUAL_MIN_M)
        world = d / np.linalg.norm(d) * length
        s = np.where(np.abs(scale[i]) > 1e-9, scale[i], 1.0)
        local = R.quat_rotate(R.quat_conjugate(rot[i]), world) / s
        names.append(unique_name(f"{names[i]}_end", used, sep=""))
        parents.append(i)
        offsets.append(local)
    m = len(names)
    virtual = np.arange(m) >= n
    rest_rot = np.concatenate((sk.rest_rotations, np.tile([0.0, 0.0, 0.0, 1.0], (m - n, 1))))
    rest_scale = np.concatenate((sk.rest_scales, np.ones((m - n, 3))))
    return Skeleton(names, parents, np.array(offsets), [()] * m, virtual, rest_rot, rest_scale,
                    is_virtual=virtual)


# ------------------------------------------------------------------------------- clips
def _key_spacing(channels: list[_Channel]) -> float | None:
    """The spacing of the clip's keys when every key of every channel lies on one even grid
    from the first key, else None."""
    longest = max(channels, key=lambda c: len(c.times))
    if len(longest.times) < 2:
        return None
    # The smallest gap is the grid step to a first approximation; refined over the whole span
    # so that float32 key times (a few ulps each) do not drift off the grid over many keys.
    gaps = np.diff(longest.times)
    steps = np.rint(gaps / gaps.min())
    dt = float((longest.times[-1] - longest.times[0]) / steps.sum())
    t0 = min(float(c.times[0]) for c in channels)
    for c in channels:
        k = (c.times - t0) / dt
        if np.max(np.abs(k - np.rint(k))) > 1e-3:
            return None
    return dt


def _clip_rate(dt: float) -> float:
    """Frames per second of key spacing ``dt`` (snapped to a whole number when within 0.1 %),
    times the smallest whole number that makes it at least MIN_KEY_RATE."""
    rate = 1.0 / dt
    r = round(rate)
    rate = float(r) if r > 0 and abs(rate - r) <= 1e-3 * rate else rate
    return rate * max(1, math.ceil(MIN_KEY_RATE / rate - 1e-9))


def _clip_name(doc, a: int, stem: str) -> str:
    name = doc.animations[a].name
    if not name:
        name = stem if len(doc.animations) == 1 else f"{stem}_{a}"
    # A clip name becomes a file name when decoded: nothing that steers a path.
    name = "".join("_" if c in '/\\:' or not c.isprintable() else c for c in name).strip()
    return name if name not in ("", ".", "..") else f"{stem}_{a}"


def read_gltf(path: str | os.PathLike, rate: float | None = None) -> list[Motion]:
    """Every animation of a glTF 2.0 file as a :class:`Motion` (lengths in metres).

    Parameters
    ----------
    path : str or path-like
        A ``.gltf`` (buffers embedded as ``data:`` URIs or in files beside it) or ``.glb``.
    rate : float, optional
        Frames per second to resample every clip at. Default: the clip's key spacing when
        every key lies on one even grid (subdivided up to :data:`MIN_KEY_RATE`), else
        :data:`DEFAULT_RATE`.

    Returns
    -------
    list of Motion
        One per animation, in file order, on one shared skeleton. Frame 0 is the clip's
        first key (``motion.source["start_s"]`` its time in the file); each motion's
        ``source`` says how it was sampled.

    Raises
    ------
    GLTFError
        Naming the file, the item and the fault, for any malformed input.
    """
    path = Path(path)
    if rate is not None and not (math.isfinite(rate) and rate > 0):
        raise GLTFError(f"rate must be a positive number of frames per second, got {rate!r}", str(path))
    doc = _load_document(path)
    if not doc.nodes:
        raise GLTFError("has no nodes", str(path))
    reader = _Reader(doc, path)
    clips = [_channels(doc, reader, a) for a in range(len(doc.animations or []))]
    clips_kept = [(a, chans) for a, chans in enumerate(clips) if chans]
    if not clips_kept:
        raise GLTFError("has no animation of a node's translation, rotation or scale", str(path))
    animated = {c.node for _, chans in clips_kept for c in chans}
    layout = _layout(doc, path, animated)
    sk = layout.skeleton
    if sk.node_count > limits.MAX_NODES:
        raise GLTFError(f"{sk.node_count:,} nodes to animate (joints, end points); the format allows at most "
                        f"{limits.MAX_NODES:,}", str(path), "nodes")
    index = {g: k for k, g in enumerate(layout.gltf_nodes)}
    motions = []
    for a, chans in clips_kept:
        dt = _key_spacing(chans)
        clip_rate = float(rate) if rate is not None else (_clip_rate(dt) if dt else DEFAULT_RATE)
        t0 = min(float(c.times[0]) for c in chans)
        t1 = max(float(c.times[-1]) for c in chans)
        # Frames up to the last key (a frame at or just past it; float32 key times may miss
        # the grid by a few ulps).
        frames = int(math.ceil((t1 - t0) * clip_rate - 1e-3)) + 1
        problem = limits.frames_problem(frames) or limits.frame_rate_problem(clip_rate)
        if problem:  # before the (frames, nodes) arrays exist
            raise GLTFError(f"keys from {t0:g} s to {t1:g} s at {clip_rate:g} Hz: {problem}", str(path),
                            f"animation {a}")
        # Sparse keys over a long span resample to frames no key backs: refused before the
        # arrays exist, the budget counted in keys (one per key time of each channel).
        keys = sum(len(c.times) for c in chans)
        problem = limits.samples_problem(frames, sk.node_count, keys, "keys")
        if problem:
            fit = (limits.samples_allowed(keys) // sk.node_count - 1) / (t1 - t0)  # t1 > t0 here
            raise GLTFError(f"{t1 - t0:,.6g} s of keys at {clip_rate:g} Hz: {problem}; resample at "
                            f"{fit:.3g} Hz or less (--rate)", str(path), f"animation {a}")
        times = t0 + np.arange(frames) / clip_rate
        n = sk.node_count
        rot = np.broadcast_to(sk.rest_rotations, (frames, n, 4)).copy()
        trans = np.broadcast_to(sk.offsets, (frames, n, 3)).copy()
        scale = np.broadcast_to(sk.rest_scales, (frames, n, 3)).copy()
        for c in chans:
            k = index[c.node]
            value = _evaluate(c, times)
            {"translation": trans, "rotation": rot, "scale": scale}[c.path][:, k] = value
        rot = R.quat_make_continuous(rot, axis=0)
        on_grid = sum(int(np.sum(np.abs((c.times - t0) * clip_rate - np.rint((c.times - t0) * clip_rate)) > 1e-3))
                      for c in chans)
        source = {
            "format": "gltf", "file": str(path), "animation": a, "start_s": t0,
            "rate": clip_rate, "rate_from": "given" if rate is not None else ("key spacing" if dt else "default"),
            "interpolation": sorted({c.interpolation for c in chans}),
            "keys_between_frames": on_grid,
            "joints": [k for k, g in enumerate(layout.gltf_nodes) if g in layout.joints],
        }
        m = Motion(sk, rot, trans, 1.0 / clip_rate, _clip_name(doc, a, path.stem), scales=scale, source=source)
        motions.append(m)
    return motions
