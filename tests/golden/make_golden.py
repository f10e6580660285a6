"""Write the golden assets of the current format version and the poses they must sample to.

Run once per released format version (``python tests/golden/make_golden.py v1``); never rewrite
the files of an earlier version (the script only writes files that do not exist yet, so a codec
added within a version gets its golden asset beside the others): every later runtime must read
them and reproduce the poses
(tests/test_golden.py, runtime_c/tests/test_golden.c, the C# and Godot tests).

Poses file format (text, one record per sample):
    sample <clip index> <time seconds, %.9g> <flags>
    then node_count lines: qx qy qz qw tx ty tz (%.9g)
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "encoder"))

from mocodec.encode import encode_motions  # noqa: E402
from mocodec.io import read_bvh  # noqa: E402
from mocodec.motion import Motion  # noqa: E402
from mocodec.runtime import Asset  # noqa: E402
from mocodec.tolerance import Tolerance  # noqa: E402
from mocodec.units import resolve_units  # noqa: E402

SAMPLES = REPO / "encoder" / "mocodec" / "samples"


def write_poses(asset_bytes: bytes, path: Path) -> None:
    asset = Asset(asset_bytes)
    lines = []
    for clip in asset.clips:
        times = [0.0, clip.duration * 0.37, clip.duration * 0.5 + 0.5 / clip.frame_rate,
                 clip.duration, clip.duration * 1.3, -0.25]
        for t in times:
            for flags in (0, 1, 2, 4):  # local, world, loop, nearest
                pose = asset.sample(clip.index, np.float32(t), flags)
                lines.append(f"sample {clip.index} {float(np.float32(t)):.9g} {flags}")
                lines.extend(" ".join(f"{v:.9g}" for v in row) for row in pose)
    path.write_text("\n".join(lines) + "\n")


def main(version: str) -> None:
    out = REPO / "tests" / "golden" / version
    out.mkdir(parents=True, exist_ok=True)
    run = read_bvh(SAMPLES / "09_11.bvh")
    walk = read_bvh(SAMPLES / "07_01.bvh")
    walk2 = read_bvh(SAMPLES / "02_01.bvh").slice(0, 61)
    walk2.name = "02_01_head"
    cases = {
        "spline_09_11": ([run], 1.0, "spline"),
        "spline_library": ([walk, walk2], 0.5, "spline"),  # two clips, two skeletons (subjects 07, 02)
        "rma_library": ([walk, run], 1.0, "rma"),  # two clips, two skeletons (subjects 07, 09)
    }
    # rma-pca: a clip PPCA cuts into pieces of two groups (a walk, a run, the walk again on one
    # skeleton), so the golden poses cover the cross-fade between pieces.
    full = read_bvh(SAMPLES / "02_01.bvh")
    mixed = Motion(full.skeleton, np.concatenate([full.rotations[1:], run.rotations[1:], full.rotations[1:]]),
                   np.concatenate([full.translations[1:], run.translations[1:], full.translations[1:]]),
                   full.frame_time, "mixed")
    options = {"rma_pca_library": {"groups": 2, "variance": 0.98},
               "rma_pca_repeats": {"groups": 2, "variance": 0.98, "repeats": True}}
    cases["rma_pca_library"] = ([walk, mixed], 1.0, "rma-pca")
    cases["rma_pca_repeats"] = ([mixed], 1.0, "rma-pca")  # repeated pieces (seed 003 eq. 6)
    for name, (motions, tol, codec) in cases.items():
        if (out / f"{name}.mcd").exists():
            print(f"{name}: kept (golden files are never rewritten)")
            continue
        units = [resolve_units(m.skeleton, "cmu", None) for m in motions]
        result = encode_motions(motions, units, codec, Tolerance(tol), options.get(name))
        (out / f"{name}.mcd").write_bytes(result.asset)
        write_poses(result.asset, out / f"{name}.poses.txt")
        print(f"{name}: {len(result.asset)} bytes, max error {result.max_error_cm:.4f} cm")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "v1")
