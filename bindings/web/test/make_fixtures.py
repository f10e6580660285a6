"""Test fixtures for the web binding and the viewer, made with the encoder and the NATIVE runtime.

    python bindings/web/test/make_fixtures.py OUT_DIR

For every codec of the encoder's registry: one asset of two short sample clips
(``<codec>.mcd``) and what the native C runtime (the Python binding) says about it
(``<codec>.json``: clip and node infos, and poses at whole, fractional, clamped and looped times,
local and world, cubic and nearest; a rig with other rest rotations and units, renamed bones
and a pair, and the native retargeting of local poses onto it; and the encoder's error figures per clip, measured through
the native runtime). A codec that cannot be encoded here (its runtime side is
not in this build) is listed in ``skipped.json`` with the reason, for the tests to print. The
clips' originals are written as BVH (``<clip>.bvh``) for ``mocodec view --original``.
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

from mocodec import codecs
from mocodec.encode import encode_motions
from mocodec.io import read_bvh, write_bvh
from mocodec.tolerance import Tolerance
from mocodec.units import resolve_units
import mocodec_runtime as rt

SAMPLES = Path(__file__).resolve().parents[3] / "encoder" / "mocodec" / "samples"
CLIPS = (("02_01", 0, 120), ("07_01", 40, 140))  # short slices: every codec encodes them in seconds
# rma-pca makes no tolerance promise; it is driven by the variance kept (the paper's setting).
OPTIONS = {"rma-pca": {"variance": 0.98}}


def motions():
    out = []
    for name, start, stop in CLIPS:
        m = read_bvh(SAMPLES / f"{name}.bvh").slice(start, stop)
        m.name = name
        out.append(m)
    return out


def sample_times(info: rt.ClipInfo) -> list[tuple[float, int]]:
    """(time, flags) pairs that cover whole frames, between frames, both ends and beyond."""
    dt = 1.0 / info.frame_rate
    times = [0.0, dt, 0.37 * dt, 10.5 * dt, 0.5 * info.duration, info.duration - 0.25 * dt,
             info.duration, info.duration + 1.0, -0.5]
    out = [(t, 0) for t in times] + [(t, rt.SAMPLE_WORLD) for t in times]
    out += [(info.duration * 1.3, rt.SAMPLE_LOOP | rt.SAMPLE_WORLD), (10.5 * dt, rt.SAMPLE_NEAREST)]
    return out


def describe(asset: rt.Asset) -> dict:
    clips = [{"index": c.index, "name": c.name, "skeleton": c.skeleton, "codec": c.codec,
              "frameCount": c.frame_count, "frameRate": c.frame_rate, "duration": c.duration,
              "nodeCount": c.node_count, "scratchSize": c.scratch_size,
              "dataOffset": c.data_offset, "dataSize": c.data_size} for c in asset.clips]
    skeletons = []
    for s in range(asset.skeleton_count):
        count, cm = asset.skeleton_info(s)
        skeletons.append({"nodeCount": count, "cmPerUnit": cm, "nodes": [
            {"name": n.name, "parent": n.parent, "kind": n.kind, "restTranslation": list(n.rest_translation),
             "restRotation": list(n.rest_rotation), "restScale": list(n.rest_scale), "channels": list(n.channels)}
            for n in asset.nodes(s)]})
    poses = []
    for c in asset.clips:
        for t, flags in sample_times(c):
            pose = asset.sample(c.index, t, flags)
            poses.append({"clip": c.index, "time": float(np.float32(t)), "flags": int(flags),
                          "pose": [float(v) for v in pose.ravel()]})
    return {"size": asset.size, "scratchSize": asset.scratch_size, "clips": clips,
            "skeletons": skeletons, "poses": poses, "retarget": retarget_case(asset)}


def _qmul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return np.array([aw * bx + ax * bw + ay * bz - az * by, aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw, aw * bw - ax * bx - ay * by - az * bz])


def retarget_case(asset: rt.Asset) -> dict:
    """Skeleton 0 as a rig with every rest rotation turned (a rig from another tool), in half the
    units, bones renamed ("rig:<name>", found by the loose match) but one, driven by a pair."""
    turn = np.array([0.0, np.sin(0.3), 0.0, np.cos(0.3)])
    nodes = asset.nodes(0)
    bones = []
    for i, n in enumerate(nodes):
        q = _qmul(turn, np.asarray(n.rest_rotation, dtype=float)) if n.parent >= 0 else np.asarray(n.rest_rotation)
        rest = [*map(float, q), *(0.5 * float(t) for t in n.rest_translation), *map(float, n.rest_scale)]
        name = "PairedBone" if i == 1 else f"rig:{n.name}"
        bones.append({"name": name, "parent": n.parent, "rest": rest})
    options = {"pairs": {"PairedBone": nodes[1].name}, "unitScale": 0.5, "rootMotion": False}
    r = rt.Retarget(asset, 0, [rt.RigBone(b["name"], b["parent"], tuple(b["rest"])) for b in bones],
                    pairs=options["pairs"], unit_scale=0.5, root_motion=False)
    clip = next(c for c in asset.clips if c.skeleton == 0)
    cases = []
    for t in (0.0, 0.5 * clip.duration, clip.duration):
        local = asset.sample(clip.index, t, 0)
        cases.append({"clip": clip.index, "time": float(np.float32(t)),
                      "pose": [float(v) for v in r.pose(local).ravel()]})
    return {"bones": bones, "options": options, "matched": r.matched, "nodeOf": [r.node_of(i) for i in range(len(bones))],
            "cases": cases}


def main(out: Path) -> int:
    out.mkdir(parents=True, exist_ok=True)
    ms = motions()
    units = [resolve_units(m.skeleton, "cmu", None) for m in ms]
    for m in ms:
        write_bvh(m, out / f"{m.name}.bvh")
    skipped = {}
    for codec in codecs.available():
        try:
            result = encode_motions(ms, units, codec, Tolerance(1.0), OPTIONS.get(codec))
            data = result.asset
            asset = rt.Asset(data)
        except Exception as exc:  # a codec whose runtime side is not in this build
            skipped[codec] = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
            print(f"make_fixtures: SKIPPED codec {codec}: {skipped[codec]}", file=sys.stderr)
            continue
        (out / f"{codec}.mcd").write_bytes(data)
        errors = {c.name: {"max": c.error.max_cm, "p99": c.error.p99_cm, "mean": c.error.mean_cm}
                  for c in result.clips}
        (out / f"{codec}.json").write_text(json.dumps({"codec": codec, "errors": errors, **describe(asset)}))
        print(f"make_fixtures: {codec}: {len(data)} bytes", file=sys.stderr)
    (out / "skipped.json").write_text(json.dumps(skipped, indent=1))
    return 0


if __name__ == "__main__":
    if len(sys.argv) != 2:
        print(__doc__, file=sys.stderr)
        sys.exit(2)
    sys.exit(main(Path(sys.argv[1])))
