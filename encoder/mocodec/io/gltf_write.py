"""Writing decoded clips as glTF 2.0 (``.glb``, or ``.gltf`` with the buffer embedded).

Each skeleton becomes its node hierarchy (names, rest TRS; the virtual end points the reader
added are left out) with a skin over its joints (inverse bind matrices of the rest pose), so
Blender and Godot import it as an armature; each clip becomes an animation on those nodes with
a key on every frame (LINEAR), timed from the clip's source start (META ``start_s``). A node's
translation, rotation or scale gets a channel in every clip where any clip of its skeleton moves
it from its rest.
"""
from __future__ import annotations

import base64
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Sequence

import numpy as np

from ..motion import Motion, Skeleton
from ..rotations import quat_make_continuous, quat_to_matrix

__all__ = ["gltf_document", "write_gltf"]

_FLOAT, _VEC = 5126, {1: "SCALAR", 3: "VEC3", 4: "VEC4", 16: "MAT4"}


@dataclass
class _Blob:
    """The one binary buffer and its views and accessors."""

    data: bytearray = field(default_factory=bytearray)
    views: list = field(default_factory=list)
    accessors: list = field(default_factory=list)

    def add(self, values: np.ndarray, with_bounds: bool = False) -> int:
        from pygltflib import Accessor, BufferView

        v = np.ascontiguousarray(values, dtype="<f4")
        v2 = v.reshape(len(v), -1)
        while len(self.data) % 4:
            self.data.append(0)
        self.views.append(BufferView(buffer=0, byteOffset=len(self.data), byteLength=v.nbytes))
        self.data += v.tobytes()
        acc = Accessor(bufferView=len(self.views) - 1, componentType=_FLOAT, count=len(v2),
                       type=_VEC[v2.shape[1]])
        if with_bounds:
            acc.min = [float(x) for x in v2.min(axis=0)]
            acc.max = [float(x) for x in v2.max(axis=0)]
        self.accessors.append(acc)
        return len(self.accessors) - 1


def _rest_matrices(sk: Skeleton) -> np.ndarray:
    """World matrices (N, 4, 4) of the rest pose, composed as glTF composes them."""
    local = np.zeros((sk.node_count, 4, 4))
    local[:, :3, :3] = quat_to_matrix(sk.rest_rotations) * sk.rest_scales[:, None, :]
    local[:, :3, 3] = sk.offsets
    local[:, 3, 3] = 1.0
    world = np.empty_like(local)
    for i, p in enumerate(sk.parents):
        world[i] = local[i] if p < 0 else world[p] @ local[i]
    return world


def _moved_paths(sk: Skeleton, m: Motion, nodes: dict[int, int]) -> set[tuple[int, str]]:
    """(node, path) pairs whose float32 values leave the node's rest somewhere in the clip; the
    first root's rotation when nothing does (an animation needs a channel)."""
    out = set()
    for i in nodes:
        for path, values, rest in (("translation", m.translations[:, i], sk.offsets[i]),
                                   ("rotation", m.rotations[:, i], sk.rest_rotations[i]),
                                   ("scale", m.scales[:, i], sk.rest_scales[i])):
            f32, rest32 = values.astype(np.float32), np.asarray(rest, dtype=np.float32)
            if not (np.all(f32 == rest32) or (path == "rotation" and np.all(f32 == -rest32))):
                out.add((i, path))
    if not out:
        out.add((min(nodes), "rotation"))
    return out


def gltf_document(skeletons: Sequence[Skeleton], clips: Sequence[tuple[int, Motion, float]],
                  skin_joints: dict[int, list[int]] | None = None):
    """A pygltflib document: the node hierarchy of every skeleton and one animation per clip.

    ``clips`` holds (skeleton index, decoded motion, start time in seconds); ``skin_joints``
    the skin joints of a skeleton (node indices; default every node that is not virtual).
    """
    from pygltflib import (GLTF2, Animation, AnimationChannel, AnimationChannelTarget,
                           AnimationSampler, Asset, Buffer, Node, Scene, Skin)

    blob = _Blob()
    nodes: list = []
    skins: list = []
    roots: list[int] = []
    node_of: list[dict[int, int]] = []  # per skeleton: skeleton node -> glTF node
    for s, sk in enumerate(skeletons):
        keep = [i for i in range(sk.node_count) if not sk.is_virtual[i]]
        index = {i: len(nodes) + k for k, i in enumerate(keep)}
        node_of.append(index)
        for i in keep:
            node = Node(name=sk.names[i], children=[index[c] for c in sk.children(i) if c in index])
            t, q, sc = sk.offsets[i], sk.rest_rotations[i], sk.rest_scales[i]
            if np.any(t != 0):
                node.translation = [float(x) for x in t]
            if not np.array_equal(q, [0.0, 0.0, 0.0, 1.0]):
                node.rotation = [float(x) for x in q / np.linalg.norm(q)]
            if np.any(sc != 1):
                node.scale = [float(x) for x in sc]
            nodes.append(node)
        roots += [index[i] for i in keep if sk.parents[i] < 0]
        joints = [i for i in (skin_joints or {}).get(s, keep) if i in index]
        inverse = np.linalg.inv(_rest_matrices(sk)[joints])
        # glTF matrices are column-major: the transpose's rows are the columns.
        skins.append(Skin(joints=[index[i] for i in joints], name=f"skeleton {s}",
                          inverseBindMatrices=blob.add(np.transpose(inverse, (0, 2, 1)).reshape(-1, 16))))
    # A (node, path) that any clip of a skeleton moves from its rest gets a channel in every clip
    # of that skeleton: engines keep a node's last pose when the next clip has no channel for it
    # (Blender's actions, Godot's tracks), so every clip states what it holds.
    moved = [set() for _ in skeletons]
    for s, m, _ in clips:
        moved[s] |= _moved_paths(skeletons[s], m, node_of[s])
    animations = []
    for s, m, start in clips:
        times = blob.add(start + np.arange(m.frame_count) / m.frame_rate, with_bounds=True)
        channels, samplers = [], []
        for i, g in node_of[s].items():
            for path, values in (("translation", m.translations[:, i]),
                                 ("rotation", quat_make_continuous(m.rotations[:, i])),
                                 ("scale", m.scales[:, i])):
                if (i, path) not in moved[s]:
                    continue
                samplers.append(AnimationSampler(input=times, output=blob.add(values), interpolation="LINEAR"))
                channels.append(AnimationChannel(sampler=len(samplers) - 1,
                                                 target=AnimationChannelTarget(node=g, path=path)))
        animations.append(Animation(name=m.name, channels=channels, samplers=samplers))
    doc = GLTF2(asset=Asset(version="2.0", generator="mocodec (decoded through the C runtime)"),
                scene=0, scenes=[Scene(nodes=roots)], nodes=nodes, skins=skins,
                animations=animations, accessors=blob.accessors, bufferViews=blob.views,
                buffers=[Buffer(byteLength=len(blob.data))])
    doc.set_binary_blob(bytes(blob.data))
    return doc


def write_gltf(path: str | os.PathLike, skeletons: Sequence[Skeleton],
               clips: Sequence[tuple[int, Motion, float]],
               skin_joints: dict[int, list[int]] | None = None) -> None:
    """Write :func:`gltf_document` to ``path``: binary glTF for ``.glb``, else JSON with the
    buffer embedded as a ``data:`` URI."""
    doc = gltf_document(skeletons, clips, skin_joints)
    path = Path(path)
    if path.suffix.lower() == ".glb":
        doc.save_binary(str(path))
        return
    data = doc.binary_blob()
    doc.buffers[0].uri = "data:application/octet-stream;base64," + base64.b64encode(data).decode("ascii")
    doc.destroy_binary_blob()
    doc.save_json(str(path))
