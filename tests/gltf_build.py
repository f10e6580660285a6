"""Small glTF 2.0 files built in tests: a chain of nodes and animation channels from numpy
arrays, written as JSON with the buffer embedded (or beside it), so every reader path and every
kind of damage can be tried without real assets."""
from __future__ import annotations

import base64
import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np


@dataclass
class Doc:
    """A glTF document under construction (a plain dict, so a test can damage any field)."""

    json: dict = field(default_factory=lambda: {"asset": {"version": "2.0"}, "nodes": [], "scenes": [{"nodes": [0]}],
                                                "scene": 0, "animations": [], "accessors": [],
                                                "bufferViews": [], "buffers": []})
    data: bytearray = field(default_factory=bytearray)

    def accessor(self, values, kind: str) -> int:
        v = np.ascontiguousarray(values, dtype="<f4")
        while len(self.data) % 4:
            self.data.append(0)
        self.json["bufferViews"].append({"buffer": 0, "byteOffset": len(self.data), "byteLength": v.nbytes})
        self.data += v.tobytes()
        count = len(v) if v.ndim > 1 else v.size
        acc = {"bufferView": len(self.json["bufferViews"]) - 1, "componentType": 5126, "count": count,
               "type": kind}
        if kind == "SCALAR":
            acc["min"], acc["max"] = [float(v.min())], [float(v.max())]
        self.json["accessors"].append(acc)
        return len(self.json["accessors"]) - 1

    def node(self, name: str, parent: int | None = None, **trs) -> int:
        self.json["nodes"].append({"name": name, **{k: list(map(float, v)) for k, v in trs.items()}})
        i = len(self.json["nodes"]) - 1
        if parent is not None:
            self.json["nodes"][parent].setdefault("children", []).append(i)
        return i

    def skin(self, joints: list[int]) -> None:
        self.json.setdefault("skins", []).append({"joints": joints})

    def animation(self, name: str, channels: list[tuple[int, str, np.ndarray, np.ndarray, str | None]]) -> None:
        """``channels``: (node, path, times (K,), values (K or 3K, d), interpolation or None)."""
        anim = {"name": name, "channels": [], "samplers": []}
        kinds = {3: "VEC3", 4: "VEC4"}
        for node, path, times, values, interp in channels:
            values = np.asarray(values, dtype=np.float64)
            sampler = {"input": self.accessor(times, "SCALAR"), "output": self.accessor(values, kinds[values.shape[1]])}
            if interp is not None:
                sampler["interpolation"] = interp
            anim["samplers"].append(sampler)
            anim["channels"].append({"sampler": len(anim["samplers"]) - 1, "target": {"node": node, "path": path}})
        self.json["animations"].append(anim)

    def write(self, path: Path, external: bool = False) -> Path:
        doc = json.loads(json.dumps(self.json))
        if external:
            bin_path = path.with_suffix(".bin")
            bin_path.write_bytes(bytes(self.data))
            uri = bin_path.name
        else:
            uri = "data:application/octet-stream;base64," + base64.b64encode(bytes(self.data)).decode()
        doc["buffers"] = [{"byteLength": len(self.data), "uri": uri}]
        path.write_text(json.dumps(doc))
        return path


def quat_z(deg) -> np.ndarray:
    """Rotations about Z, ``x y z w``."""
    h = np.radians(np.atleast_1d(deg)) / 2
    return np.stack([np.zeros_like(h), np.zeros_like(h), np.sin(h), np.cos(h)], axis=-1)


def arm(doc: Doc | None = None) -> Doc:
    """A root and a three-bone arm along +Y (1 m bones) with a skin over the arm."""
    doc = doc or Doc()
    root = doc.node("root")
    a = doc.node("shoulder", root, translation=[0, 1, 0])
    b = doc.node("elbow", a, translation=[0, 1, 0])
    doc.node("hand", b, translation=[0, 1, 0])
    doc.skin([1, 2, 3])
    return doc
