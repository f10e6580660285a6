"""World error half-way between frames, where engines sample too and no codec checks.

    PYTHONPATH=encoder .venv/bin/python bench/between_frames.py ASSET.mcd [ASSET.mcd ...] [--out NAME]

Every codec promises its tolerance on the frames of the clip. An engine running at its own frame
rate samples between them, so this samples each clip of each asset through the C runtime at
x + 0.5 for every frame x and compares with the original there: rotations half-way (normalised
lerp, which at one half is exactly slerp), translations half-way, then forward kinematics. The
reference is the original's own smooth path, so a codec that only fits the frames and swings in
between shows up here and nowhere else. Clips are read from ../shared/data/cmu by name.
Writes bench/results/<NAME>.md and .json.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "encoder"))

from mocodec.io import read_bvh  # noqa: E402
from mocodec.kinematics import halfway_world  # noqa: E402
from mocodec.runtime import Asset  # noqa: E402
from results_files import write_results  # noqa: E402
from mocodec.units import UNITS  # noqa: E402

DEV = HERE.parent.parent / "shared" / "data" / "cmu"
CM = UNITS["cmu"]
MAX_STEP_CM = 10.0   # a point faster than 12 m/s between two 120 fps frames: a capture glitch
MAX_TURN_DEG = 45.0  # a joint turning faster than 5,400 degrees/s at 120 fps: the same


def half_frame_original(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """World positions (F-1, N, 3) of the original half-way between consecutive frames, and
    which intervals are smooth: no point steps more than MAX_STEP_CM and no joint turns more
    than MAX_TURN_DEG between the two frames."""
    half, step, turn = halfway_world(read_bvh(path))
    return half, (step * CM <= MAX_STEP_CM) & (turn <= MAX_TURN_DEG)


def asset_errors(path: Path) -> dict:
    asset = Asset(path.read_bytes())
    per_clip = {}
    skipped = 0
    for clip in (c.name for c in asset.clips):
        bvh = DEV / f"{clip}.bvh"
        if not bvh.exists():
            print(f"between_frames: {clip}: no {bvh}, skipped", file=sys.stderr)
            continue
        ref, smooth = half_frame_original(bvh)
        x = np.arange(ref.shape[0], dtype=np.float64) + 0.5
        _, pos = asset.sample_frames(clip, x, world=True)
        err = np.linalg.norm(pos - ref, axis=-1) * CM
        # Where the capture itself jumps (a marker swap, a foot flipping 149 degrees for two
        # frames in 05_17, the CMU T-pose frame) half-way is not a pose anyone recorded and any
        # path between the two is as good: those intervals are counted, not measured.
        skipped += int(np.sum(~smooth))
        per_clip[clip] = np.where(smooth[:, None], err, np.nan)
    flat = np.concatenate([e.ravel() for e in per_clip.values()])
    flat = flat[~np.isnan(flat)]
    worst = max(per_clip, key=lambda c: np.nanmax(per_clip[c]))
    frame = int(np.unravel_index(np.nanargmax(per_clip[worst]), per_clip[worst].shape)[0])
    # Skipped rows are all NaN; NaN > 2 is False, so they count as not over.
    over = {c: int(np.sum(np.any(e > 2.0, axis=1))) for c, e in per_clip.items()}
    return {"asset": str(path), "bytes": path.stat().st_size, "clips": len(per_clip),
            "half_frames": int(sum(e.shape[0] for e in per_clip.values())) - skipped,
            "max_cm": float(flat.max()), "p99_cm": float(np.percentile(flat, 99)),
            "mean_cm": float(flat.mean()), "worst": f"{worst} @ {frame}.5",
            "per_clip_max_cm": {c: float(np.nanmax(e)) for c, e in per_clip.items()},
            "per_clip_over_2cm": over, "half_frames_over_2cm": int(sum(over.values())), "skipped_jumps": skipped}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("assets", nargs="+", type=Path, help="assets of dev clips (.mcd)")
    ap.add_argument("--out", default="between_frames", help="results name under bench/results")
    args = ap.parse_args(argv)
    if not DEV.is_dir():
        print(f"between_frames: {DEV} not found (the dev clips)", file=sys.stderr)
        return 2
    rows = [asset_errors(p) for p in args.assets]
    lines = ["# World error half-way between frames", "",
             "Sampled through the C runtime at x + 0.5 for every frame x of every clip, against the "
             "original half-way (slerp, lerp, FK). cm. Skipped: intervals where the original's own "
             f"point step exceeds {MAX_STEP_CM:g} cm or joint turn {MAX_TURN_DEG:g} degrees (capture glitches). "
             "`bench/between_frames.py`.", "",
             "| asset | bytes | half frames | max cm | p99 cm | mean cm | worst | half frames over 2 cm | skipped |",
             "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {Path(r['asset']).name} | {r['bytes']:,} | {r['half_frames']:,} | {r['max_cm']:.3f} | "
                     f"{r['p99_cm']:.3f} | {r['mean_cm']:.3f} | {r['worst']} | {r['half_frames_over_2cm']:,} | {r['skipped_jumps']} |")
    out = HERE / "results" / args.out
    write_results(out, rows, lines)
    return 0


if __name__ == "__main__":
    sys.exit(main())
