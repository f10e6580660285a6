"""World error half-way between frames, where engines sample too.

    PYTHONPATH=encoder .venv/bin/python bench/between_frames.py ASSET.mcd [ASSET.mcd ...] [--out NAME]
        [--tolerance CM]

Every codec promises its tolerance on the frames of the clip. An engine running at its own frame
rate samples between them, so this samples each clip of each asset through the C runtime at
x + 0.5 for every frame x and compares with the original there: rotations half-way (normalised
lerp, which at one half is exactly slerp), translations half-way, then forward kinematics. The
reference is the original's own smooth path, so a codec that only fits the frames and swings in
between shows up here (the key-frame codecs hold it to 1.5 x the tolerance, ``halfway_factor``).

Excepted, and listed with their reason, are the capture's glitches (the original's own point
step over GLITCH_STEP_CM or joint turn over GLITCH_TURN_DEG in one frame, where half-way is no
pose anyone recorded) and the intervals next to one (a Catmull-Rom tangent there spans the
jump): the encoder's :func:`mocodec.kinematics.held_intervals`. Every other interval counts;
one over 1.5 x ``--tolerance`` is a miss, listed too. Clips are read from ../shared/data/cmu (or
$MOCODEC_SHARED/data/cmu) by name. Writes bench/results/<NAME>.md and .json.
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
from mocodec.kinematics import (GLITCH_STEP_CM, GLITCH_TURN_DEG, halfway_positions,  # noqa: E402
                                interval_motion_per_node, world_positions)
from mocodec.runtime import Asset  # noqa: E402
from results_files import write_results  # noqa: E402
from mocodec.units import UNITS  # noqa: E402

DEV = Path(os.environ.get("MOCODEC_SHARED") or HERE.parent.parent / "shared") / "data" / "cmu"
CM = UNITS["cmu"]
HALF_FACTOR = 1.5  # the promise half-way: this multiple of the tolerance


def excepted_intervals(clip: str, names: list[str], step_cm: np.ndarray, turn: np.ndarray) -> list[dict]:
    """The intervals not held, one row each (clip, frame: the interval frame ... frame + 1,
    joint, why), from every point's step (F-1, N) in cm and every node's turn (F-1, N) in
    degrees: ``turn`` (a joint turns over GLITCH_TURN_DEG), ``step`` (a point steps over
    GLITCH_STEP_CM, no joint over the turn limit), ``next to a glitch`` (either neighbour is
    one; the joint is the neighbour's)."""
    turned, stepped = turn.max(axis=1) > GLITCH_TURN_DEG, step_cm.max(axis=1) > GLITCH_STEP_CM
    glitch = turned | stepped

    def why(f: int) -> tuple[str, str, str]:
        if turned[f]:
            j = int(np.argmax(turn[f]))
            return "turn", names[j], f"turns {turn[f, j]:.0f} deg"
        j = int(np.argmax(step_cm[f]))
        return "step", names[j], f"steps {step_cm[f, j]:.1f} cm"

    rows = []
    for f in range(len(glitch)):
        if glitch[f]:
            reason, joint, detail = why(f)
            rows.append({"clip": clip, "frame": f, "joint": joint, "reason": reason, "why": detail,
                         "turn_deg": float(turn[f].max())})
        else:
            near = [g for g in (f - 1, f + 1) if 0 <= g < len(glitch) and glitch[g]]
            if near:
                _, joint, detail = why(near[0])
                rows.append({"clip": clip, "frame": f, "joint": joint, "reason": "next to a glitch",
                             "why": f"interval {near[0]} {detail}", "turn_deg": float(turn[f].max())})
    return rows


def _summary(errors: list[np.ndarray]) -> dict:
    """max, p99, mean (cm) of the half-way errors of the intervals held."""
    flat = np.concatenate([e.ravel() for e in errors]) if errors else np.zeros(0)
    if not flat.size:
        return {"max_cm": None, "p99_cm": None, "mean_cm": None}
    return {"max_cm": float(flat.max()), "p99_cm": float(np.percentile(flat, 99)), "mean_cm": float(flat.mean())}


def asset_errors(path: Path, tolerance: float | None = None) -> dict:
    """Half-way errors of every clip of an asset outside the excepted intervals (max, p99,
    mean, per clip max), the excepted intervals by reason and listed, and the misses: held
    intervals over HALF_FACTOR x ``tolerance`` (clip, frame, worst joint, cm)."""
    asset = Asset(path.read_bytes())
    held_err, per_clip, excepted, misses = [], {}, [], []
    next_to_max = 0.0
    half_frames = 0
    for clip in (c.name for c in asset.clips):
        bvh = DEV / f"{clip}.bvh"
        if not bvh.exists():
            print(f"between_frames: {clip}: no {bvh}, skipped", file=sys.stderr)
            continue
        m = read_bvh(bvh)
        names = m.skeleton.names
        ref = halfway_positions(m)
        step, turn = interval_motion_per_node(m, world_positions(m))
        rows = excepted_intervals(clip, names, step * CM, turn)
        held = np.ones(len(ref), dtype=bool)
        held[[r["frame"] for r in rows]] = False
        excepted += rows
        _, pos = asset.sample_frames(clip, np.arange(len(ref), dtype=np.float64) + 0.5, world=True)
        err = np.linalg.norm(pos - ref, axis=-1) * CM
        near = [r["frame"] for r in rows if r["reason"] == "next to a glitch"]
        if near:
            next_to_max = max(next_to_max, float(err[near].max()))
        held_err.append(err[held])
        half_frames += int(held.sum())
        per_clip[clip] = float(err[held].max()) if held.any() else None
        if tolerance is not None:
            for f in np.flatnonzero(held & (err.max(axis=1) > HALF_FACTOR * tolerance)):
                j = int(np.argmax(err[f]))
                misses.append({"clip": clip, "frame": int(f), "joint": names[j], "cm": float(err[f, j])})
    reasons = {}
    for r in excepted:
        reasons[r["reason"]] = reasons.get(r["reason"], 0) + 1
    over_90 = sum(1 for r in excepted if r["reason"] == "turn" and r["turn_deg"] > 90.0)
    return {"asset": path.name, "bytes": path.stat().st_size, "clips": len(per_clip), "tolerance_cm": tolerance,
            "half_frames": half_frames, **_summary(held_err), "per_clip_max_cm": per_clip,
            "excepted": len(excepted), "excepted_by_reason": reasons, "turns_over_90_deg": over_90,
            "next_to_glitch_max_cm": next_to_max, "misses": misses, "excepted_intervals": excepted}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("assets", nargs="+", type=Path, help="assets of dev clips (.mcd)")
    ap.add_argument("--out", default="between_frames", help="results name under bench/results")
    ap.add_argument("--tolerance", type=float, default=None,
                    help=f"the assets' tolerance (cm): list the held half frames over {HALF_FACTOR:g} x it")
    args = ap.parse_args(argv)
    if not DEV.is_dir():
        print(f"between_frames: {DEV} not found (the dev clips)", file=sys.stderr)
        return 2
    rows = [asset_errors(p, args.tolerance) for p in args.assets]
    lines = ["# World error half-way between frames", "",
             "Sampled through the C runtime at x + 0.5 for every frame x of every clip, against the "
             "original half-way (slerp, lerp, FK). cm. Excepted: the capture's glitches (the original's own "
             f"point step over {GLITCH_STEP_CM:g} cm or joint turn over {GLITCH_TURN_DEG:g} degrees in one "
             "frame) and the intervals next to one (a curve's tangent there spans the jump), listed below; "
             f"every other interval counts, and one over {HALF_FACTOR:g} x the tolerance is a miss. "
             "`bench/between_frames.py`.", "",
             "| asset | bytes | half frames | max cm | p99 cm | mean cm | misses | excepted: turn / step / "
             "next to one | turns over 90 deg | max next to a glitch cm |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        by = r["excepted_by_reason"]
        misses = "" if args.tolerance is None else f"{len(r['misses'])}"
        lines.append(f"| {Path(r['asset']).name} | {r['bytes']:,} | {r['half_frames']:,} | {r['max_cm']:.3f} | "
                     f"{r['p99_cm']:.3f} | {r['mean_cm']:.3f} | {misses} | {r['excepted']} = {by.get('turn', 0)} / "
                     f"{by.get('step', 0)} / {by.get('next to a glitch', 0)} | {r['turns_over_90_deg']} | "
                     f"{r['next_to_glitch_max_cm']:.1f} |")
    for r in rows:
        name = Path(r["asset"]).name
        if args.tolerance is not None:
            lines += ["", f"## {name}: misses (held, over {HALF_FACTOR:g} x {args.tolerance:g} cm)", ""]
            lines += [f"- {m['clip']} @ {m['frame']}.5: {m['joint']} {m['cm']:.2f} cm" for m in r["misses"]] or ["none"]
        lines += ["", f"## {name}: excepted intervals (frame f: between f and f + 1)", ""]
        lines += [f"- {e['clip']} @ {e['frame']}: {e['joint']}, {e['reason']} ({e['why']})"
                  for e in r["excepted_intervals"]]
    write_results(HERE / "results" / args.out, rows, lines)
    return 0


if __name__ == "__main__":
    sys.exit(main())
