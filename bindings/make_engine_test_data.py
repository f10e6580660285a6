"""Write the assets and reference poses that the engine bindings test and benchmark against.

    python bindings/make_engine_test_data.py OUT_DIR

OUT_DIR receives the golden assets of tests/golden/v2 (format 2, the shared vectors every binding
replays; MCD_GOLDEN_DIR names another folder) as golden_<name>.mcd / .poses.txt, and, for every
codec the encoder offers, fresh assets encoded now from the sample BVH clips, each with a
``.poses.txt`` made by the Python binding of the C runtime (format: tests/golden/make_golden.py).
A codec whose encoder fails, and a golden whose codec this runtime was built without, are
reported on stderr, one line each, and left out; the script fails when spline does.
"""
from __future__ import annotations

import os
import shutil
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "encoder"))
sys.path.insert(0, str(REPO / "tests" / "golden"))

from make_golden import SAMPLES, write_poses  # noqa: E402
from mocodec import codecs  # noqa: E402
from mocodec.encode import encode_motions  # noqa: E402
from mocodec.io import read_bvh  # noqa: E402
from mocodec.tolerance import Tolerance  # noqa: E402
from mocodec.units import resolve_units  # noqa: E402
from mocodec_runtime import Asset, Result, RuntimeResultError  # noqa: E402

GOLDEN = Path(os.environ.get("MCD_GOLDEN_DIR") or REPO / "tests" / "golden" / "v2")


def copy_goldens(out: Path) -> int:
    """Copies every golden this runtime can open; returns how many."""
    copied = 0
    for f in sorted(GOLDEN.glob("*.mcd")):
        try:
            Asset(f.read_bytes())
        except RuntimeResultError as exc:
            if exc.code == Result.UNSUPPORTED:  # a codec not built into this runtime (yet)
                print(f"make_engine_test_data: golden {f.name} left out: {exc}", file=sys.stderr)
                continue
            raise SystemExit(f"make_engine_test_data: {f}: the runtime refuses a golden asset: {exc}")
        shutil.copyfile(f, out / f"golden_{f.name}")
        shutil.copyfile(f.with_suffix(".poses.txt"), out / f"golden_{f.stem}.poses.txt")
        copied += 1
    return copied


def main(out: Path) -> int:
    out.mkdir(parents=True, exist_ok=True)
    if copy_goldens(out) == 0:
        print(f"make_engine_test_data: no golden asset in {GOLDEN}", file=sys.stderr)
        return 1
    run = read_bvh(SAMPLES / "09_11.bvh")  # 31 joints + 7 end sites: the benchmark clip
    walk = read_bvh(SAMPLES / "07_01.bvh").slice(0, 121)
    walk.name = "07_01_head"
    failed = []
    # Each codec at a tolerance it meets on these clips; neural at 3 cm because it trains in
    # seconds there (bench/results/neural_windows.md), so every binding samples a real asset.
    tolerance_cm = {"neural": 3.0}
    for codec in codecs.available():
        motions = [run, walk]
        try:
            units = [resolve_units(m.skeleton, "cmu", None) for m in motions]
            result = encode_motions(motions, units, codec, Tolerance(tolerance_cm.get(codec, 1.0)))
        except Exception as exc:  # reported, never silent: another codec's bug is not ours
            print(f"make_engine_test_data: codec {codec} failed to encode: {exc}", file=sys.stderr)
            failed.append(codec)
            continue
        (out / f"{codec}.mcd").write_bytes(result.asset)
        write_poses(result.asset, out / f"{codec}.poses.txt")
        print(f"make_engine_test_data: {codec}.mcd {len(result.asset)} bytes, "
              f"{len(motions)} clips, max error {result.max_error_cm:.3f} cm")
    return 1 if "spline" in failed else 0


if __name__ == "__main__":
    sys.exit(main(Path(sys.argv[1])))
