"""World error half-way between frames, where engines sample too.

    PYTHONPATH=encoder .venv/bin/python bench/between_frames.py ASSET.mcd [ASSET.mcd ...] [--out NAME]
        [--tolerance CM]

Every codec promises its tolerance on the frames of the clip. An engine running at its own frame
rate samples between them, so this samples each clip of each asset through the C runtime at
x + 0.5 for every frame x and compares with the original there: rotations half-way (normalised
lerp, which at one half is exactly slerp), translations half-way, then forward kinematics. The
reference is the original's own smooth path, so a codec that only fits the frames and swings in
between shows up here (the key-frame codecs hold it with ``-O halfway_factor=X``). Clips are
read from ../shared/data/cmu (or $MOCODEC_SHARED/data/cmu) by name.
Writes bench/results/<NAME>.md and .json.
"""
from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "encoder"))

from mocodec.io import read_bvh  # noqa: E402
from mocodec.kinematics import (GLITCH_STEP_CM, GLITCH_TURN_DEG, halfway_world, held_intervals,  # noqa: E402
                                smooth_intervals)
from mocodec.runtime import Asset  # noqa: E402
from results_files import write_results  # noqa: E402
from mocodec.units import UNITS  # noqa: E402

DEV = Path(os.environ.get("MOCODEC_SHARED") or HERE.parent.parent / "shared") / "data" / "cmu"
CM = UNITS["cmu"]


def half_frame_original(path: Path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """World positions (F-1, N, 3) of the original half-way between consecutive frames, which
    intervals are smooth (no point steps more than GLITCH_STEP_CM, no joint turns more than
    GLITCH_TURN_DEG between the two frames) and which are held (smooth, and so are both
    neighbours: the encoder's :func:`mocodec.kinematics.held_intervals`)."""
    half, step, turn = halfway_world(read_bvh(path))
    return half, smooth_intervals(step, turn, CM), held_intervals(step, turn, CM)


def _summary(per_clip: dict[str, np.ndarray], tolerance: float | None) -> dict:
    """max, p99, mean (cm), the worst clip and interval, and the half frames over 2 cm and over
    1.5 x ``tolerance`` of errors (F-1, N) with the intervals not counted NaN."""
    flat = np.concatenate([e.ravel() for e in per_clip.values()])
    flat = flat[~np.isnan(flat)]
    worst = max(per_clip, key=lambda c: np.nanmax(per_clip[c]) if np.any(~np.isnan(per_clip[c])) else -1.0)
    frame = int(np.unravel_index(np.nanargmax(per_clip[worst]), per_clip[worst].shape)[0])
    # Rows not counted are all NaN; NaN > x is False, so they count as not over.
    over = {c: int(np.sum(np.any(e > 2.0, axis=1))) for c, e in per_clip.items()}
    out = {"max_cm": float(flat.max()), "p99_cm": float(np.percentile(flat, 99)), "mean_cm": float(flat.mean()),
           "worst": f"{worst} @ {frame}.5", "per_clip_max_cm": {c: float(np.nanmax(e)) if np.any(~np.isnan(e)) else None
                                                            for c, e in per_clip.items()},
           "per_clip_over_2cm": over, "half_frames_over_2cm": int(sum(over.values()))}
    if tolerance is not None:
        out["half_frames_over_1.5_tolerance"] = int(sum(int(np.sum(np.any(e > 1.5 * tolerance, axis=1)))
                                                        for e in per_clip.values()))
    return out


def asset_errors(path: Path, tolerance: float | None = None) -> dict:
    """Half-way errors of every clip of an asset: on the held intervals (the promise), and on
    the smooth intervals next to a glitch (what the promise leaves out besides the glitches
    themselves), with the excepted intervals listed per clip."""
    asset = Asset(path.read_bytes())
    held_err, near_err, excepted = {}, {}, {}
    glitches = 0
    for clip in (c.name for c in asset.clips):
        bvh = DEV / f"{clip}.bvh"
        if not bvh.exists():
            print(f"between_frames: {clip}: no {bvh}, skipped", file=sys.stderr)
            continue
        ref, smooth, held = half_frame_original(bvh)
        x = np.arange(ref.shape[0], dtype=np.float64) + 0.5
        _, pos = asset.sample_frames(clip, x, world=True)
        err = np.linalg.norm(pos - ref, axis=-1) * CM
        # Where the capture itself jumps (a marker swap, a foot flipping 149 degrees for two
        # frames in 05_17, the CMU T-pose frame) half-way is not a pose anyone recorded and any
        # path between the two is as good; next to one, a curve's tangent spans the jump.
        glitches += int(np.sum(~smooth))
        held_err[clip] = np.where(held[:, None], err, np.nan)
        near_err[clip] = np.where((smooth & ~held)[:, None], err, np.nan)
        excepted[clip] = np.flatnonzero(~held).tolist()
    held_n = int(sum(int(np.sum(~np.isnan(e[:, 0]))) for e in held_err.values()))
    near = _summary(near_err, None) if any(np.any(~np.isnan(e)) for e in near_err.values()) else {}
    return {"asset": str(path), "bytes": path.stat().st_size, "clips": len(held_err), "tolerance_cm": tolerance,
            "half_frames": held_n, **_summary(held_err, tolerance), "glitches": glitches,
            "next_to_glitches": int(sum(int(np.sum(~np.isnan(e[:, 0]))) for e in near_err.values())),
            "next_to_glitches_max_cm": near.get("max_cm"), "excepted_intervals": excepted}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("assets", nargs="+", type=Path, help="assets of dev clips (.mcd)")
    ap.add_argument("--out", default="between_frames", help="results name under bench/results")
    ap.add_argument("--tolerance", type=float, default=None,
                    help="the assets' tolerance (cm): count half frames over 1.5 x it")
    args = ap.parse_args(argv)
    if not DEV.is_dir():
        print(f"between_frames: {DEV} not found (the dev clips)", file=sys.stderr)
        return 2
    rows = [asset_errors(p, args.tolerance) for p in args.assets]
    lines = ["# World error half-way between frames", "",
             "Sampled through the C runtime at x + 0.5 for every frame x of every clip, against the "
             "original half-way (slerp, lerp, FK). cm. Held: every interval but the capture's glitches "
             f"(the original's own point step over {GLITCH_STEP_CM:g} cm or joint turn over {GLITCH_TURN_DEG:g} "
             "degrees) and the intervals next to one (a curve's tangent there spans the jump); those are "
             "counted, listed in the JSON (`excepted_intervals`), and the worst next to a glitch is shown. "
             "`bench/between_frames.py`.", "",
             "| asset | bytes | half frames held | max cm | p99 cm | mean cm | worst | over 2 cm | "
             "over 1.5 x tol | glitches | next to glitches (max cm) |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        over_tol = r.get("half_frames_over_1.5_tolerance")
        near = r["next_to_glitches_max_cm"]
        lines.append(f"| {Path(r['asset']).name} | {r['bytes']:,} | {r['half_frames']:,} | {r['max_cm']:.3f} | "
                     f"{r['p99_cm']:.3f} | {r['mean_cm']:.3f} | {r['worst']} | {r['half_frames_over_2cm']:,} | "
                     f"{'' if over_tol is None else f'{over_tol:,}'} | {r['glitches']} | "
                     f"{r['next_to_glitches']} ({'' if near is None else f'{near:.1f}'}) |")
    out = HERE / "results" / args.out
    write_results(out, rows, lines)
    return 0


if __name__ == "__main__":
    sys.exit(main())
