"""Sizes and errors on the development glTF set beside the CMU set, per codec and tolerance.

    python bench/gltf_set.py                               # rma and spline at 1 cm
    python bench/gltf_set.py --codecs rma --tolerances 0.5 1 2

Each glTF file's clips (resampled as `mocodec encode` does) go into one asset; the CMU set's
35 clips into another (units cmu). Per file: the asset's bytes, the bytes of the file's own
animation data (its sampler accessors, float32), the asset against the raw 40 bytes per node and
frame (ACL's convention, virtual end points left out), and the error through the C runtime (max,
p99, mean, cm) in the runtime's composition (scale multiplied per axis, what the promise is
about) and, beside it, in glTF's matrix composition of the same decoded local transforms (what
an engine that imports the decoded glTF would show). A codec without scale tracks refuses the
files that animate scale; the row says so. Writes ``<out>/<name>.json`` and ``.md`` (name
``gltf_set`` by default; ``--cmu`` pointing at no BVH files leaves the CMU rows out).
Sizes and errors only; speed is bench/run_bench.py's.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
sys.path.insert(0, str(REPO / "encoder"))

from mocodec.codecs import UnsupportedMotion  # noqa: E402
from mocodec.encode import EncodeError, encode_motions  # noqa: E402
from mocodec.io import read_bvh, read_gltf  # noqa: E402
from mocodec.io.gltf import _load_document, _Reader  # noqa: E402
from mocodec.kinematics import motion_world  # noqa: E402
from mocodec.metrics import combine  # noqa: E402
from mocodec.rotations import quat_to_matrix  # noqa: E402
from mocodec.runtime import Asset  # noqa: E402
from mocodec.tolerance import Tolerance  # noqa: E402
from mocodec.units import resolve_library_units, resolve_units  # noqa: E402

SHARED = REPO.parent / "shared" / "data"


def animation_bytes(path: Path) -> int:
    """Bytes of the file's animation data: every sampler accessor (input and output) once."""
    doc = _load_document(path)
    reader = _Reader(doc, path)
    seen: set[int] = set()
    total = 0
    for anim in doc.animations or []:
        for s in anim.samplers or []:
            for a in (s.input, s.output):
                if a not in seen:
                    seen.add(a)
                    total += reader.accessor(a, "bench").size * 4
    return total


def matrix_positions(sk, rot, trans, scale) -> np.ndarray:
    """World positions by 4x4 matrix products, as glTF composes them."""
    local = np.zeros(rot.shape[:2] + (4, 4))
    local[..., :3, :3] = quat_to_matrix(rot) * scale[..., None, :]
    local[..., :3, 3] = trans
    local[..., 3, 3] = 1.0
    world = np.empty_like(local)
    for i, p in enumerate(sk.parents):
        world[:, i] = local[:, i] if p < 0 else world[:, p] @ local[:, i]
    return world[..., :3, 3]


def measure(motions, units, codec: str, tol: float) -> dict:
    started = time.perf_counter()
    try:
        result = encode_motions(motions, units, codec, Tolerance(tol))
    except UnsupportedMotion as exc:
        return {"refused": str(exc).splitlines()[0]}
    except EncodeError as exc:
        return {"failed": str(exc).splitlines()[0]}
    seconds = time.perf_counter() - started
    err = combine([c.error for c in result.clips])
    asset = Asset(result.asset)
    matrix_max = 0.0
    for m, u in zip(motions, units):
        rot, trans, scale = asset.sample_frames(m.name, scales=True)
        # Every node, the virtual end points too (they measure how the leaves are turned).
        a = matrix_positions(m.skeleton, m.rotations, m.translations, m.scales)
        b = matrix_positions(m.skeleton, rot, trans, scale)
        matrix_max = max(matrix_max, float(np.linalg.norm(a - b, axis=-1).max() * u.cm_per_unit))
    real_nodes = sum(int((~m.skeleton.is_virtual).sum()) * m.frame_count for m in motions)
    return {"asset_bytes": len(result.asset), "raw_acl_bytes": 40 * real_nodes,
            "ratio_acl": 40 * real_nodes / len(result.asset), "max_cm": err["max_cm"], "p99_cm": err["p99_cm"],
            "mean_cm": err["mean_cm"], "matrix_max_cm": matrix_max, "encode_seconds": seconds}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--gltf", type=Path, default=SHARED / "gltf")
    ap.add_argument("--cmu", type=Path, default=SHARED / "cmu")
    ap.add_argument("--codecs", nargs="+", default=["rma", "spline"])
    ap.add_argument("--tolerances", type=float, nargs="+", default=[1.0], metavar="CM")
    ap.add_argument("--out", type=Path, default=HERE / "results")
    ap.add_argument("--name", default="gltf_set", help="results file stem (default: %(default)s)")
    args = ap.parse_args(argv)
    files = sorted(p for p in args.gltf.glob("*") if p.suffix.lower() in (".gltf", ".glb"))
    if not files:
        print(f"no glTF files in {args.gltf}", file=sys.stderr)
        return 1
    sets = []
    for p in files:
        motions = read_gltf(p)
        sets.append({"name": p.name, "motions": motions, "units": resolve_library_units(motions),
                     "clips": len(motions), "frames": sum(m.frame_count for m in motions),
                     "animation_bytes": animation_bytes(p)})
    cmu = sorted(args.cmu.glob("*.bvh"))
    if cmu:
        motions = [read_bvh(p) for p in cmu]
        sets.append({"name": f"CMU ({len(cmu)} BVH clips)", "motions": motions,
                     "units": [resolve_units(m.skeleton, "cmu") for m in motions], "clips": len(motions),
                     "frames": sum(m.frame_count for m in motions),
                     "animation_bytes": sum(m.skeleton.channel_count * m.frame_count * 4 for m in motions)})
    rows = []
    for codec in args.codecs:
        for tol in args.tolerances:
            for s in sets:
                r = {"codec": codec, "tolerance_cm": tol, "set": s["name"], "clips": s["clips"],
                     "frames": s["frames"], "source_animation_bytes": s["animation_bytes"],
                     **measure(s["motions"], s["units"], codec, tol)}
                rows.append(r)
                print(json.dumps(r), file=sys.stderr, flush=True)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / f"{args.name}.json").write_text(json.dumps({"gltf": str(args.gltf), "cmu": str(args.cmu), "rows": rows},
                                                       indent=2))
    md = markdown(rows)
    (args.out / f"{args.name}.md").write_text(md)
    print(md)
    return 0


def markdown(rows: list[dict]) -> str:
    head = ["codec", "tol cm", "set", "clips", "frames", "source anim. B", "asset B", "ratio ACL 40B",
            "max cm", "p99 cm", "mean cm", "max cm, glTF matrices", "encode s"]
    lines = ["Sizes and errors on the glTF set and the CMU set (bench/gltf_set.py); errors through the "
             "C runtime, in its composition, and in glTF's matrix composition of the same decoded local "
             "transforms.", "", "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for codec in dict.fromkeys(r["codec"] for r in rows):
        for tol in dict.fromkeys(r["tolerance_cm"] for r in rows):
            group = [r for r in rows if r["codec"] == codec and r["tolerance_cm"] == tol]
            for r in group:
                lines.append(_row(r))
            done = [r for r in group if "asset_bytes" in r and not r["set"].startswith("CMU")]
            if done:
                total = {"codec": codec, "tolerance_cm": tol, "set": f"**glTF, {len(done)} files encoded**",
                         "clips": sum(r["clips"] for r in done), "frames": sum(r["frames"] for r in done),
                         "source_animation_bytes": sum(r["source_animation_bytes"] for r in done),
                         "asset_bytes": sum(r["asset_bytes"] for r in done),
                         "raw_acl_bytes": sum(r["raw_acl_bytes"] for r in done),
                         "max_cm": max(r["max_cm"] for r in done), "p99_cm": float("nan"),
                         "mean_cm": float(np.average([r["mean_cm"] for r in done], weights=[r["frames"] for r in done])),
                         "matrix_max_cm": max(r["matrix_max_cm"] for r in done),
                         "encode_seconds": sum(r["encode_seconds"] for r in done)}
                total["ratio_acl"] = total["raw_acl_bytes"] / total["asset_bytes"]
                lines.append(_row(total))
    return "\n".join(lines) + "\n"


def _row(r: dict) -> str:
    cells = [r["codec"], f"{r['tolerance_cm']:g}", r["set"], str(r["clips"]), f"{r['frames']:,}",
             f"{r['source_animation_bytes']:,}"]
    for key in ("refused", "failed"):
        if key in r:
            return "| " + " | ".join(cells + [f"{key}: {r[key][:90]}"] + [""] * 6) + " |"
    p99 = "—" if r["p99_cm"] != r["p99_cm"] else f"{r['p99_cm']:.3f}"
    cells += [f"{r['asset_bytes']:,}", f"{r['ratio_acl']:.1f}", f"{r['max_cm']:.3f}", p99,
              f"{r['mean_cm']:.3f}", f"{r['matrix_max_cm']:.3f}", f"{r['encode_seconds']:.0f}"]
    return "| " + " | ".join(cells) + " |"


if __name__ == "__main__":
    sys.exit(main())
