"""How far a ``neural`` pose jumps where one window's network hands over to the next.

    PYTHONPATH=encoder .venv/bin/python bench/neural_border_jumps.py bench/results/neural_dev_all.json

Windows share their border frame, and each network meets the tolerance there on its own, so the
two reconstructions of that frame may differ by up to twice the tolerance; the runtime switches
from one to the other at the border without blending. For every border of every clip of the
assets a ``bench_neural.py`` run kept, this samples the world pose through the C runtime just
before the border (x - 0.01 frames, the earlier window) and on it (the later window), and reports
the largest joint displacement of that step against the tolerance and against the original's
own motion over one frame there. Borders right after a capture glitch (the interval before the
border steps a point more than 10 cm or turns a joint more than 45 degrees, as in
``between_frames.py``) are counted apart: there the earlier window is the straight line across the
glitch and 0.01 frames of it is itself a large move. Writes ``<results>_borders.md``.
"""
from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "encoder"))

from mocodec.io import read_bvh  # noqa: E402
from between_frames import CM, DEV, MAX_STEP_CM, MAX_TURN_DEG  # noqa: E402
from mocodec.kinematics import halfway_world  # noqa: E402
from mocodec.runtime import Asset  # noqa: E402
from results_files import write_results  # noqa: E402

STEP = 0.01  # frames before the border: well inside the earlier window, past the runtime's 1e-4 snap


def border_jumps(asset: Asset, clip: str, windows: list, cm: float) -> list[dict]:
    motion = read_bvh(DEV / f"{clip}.bvh")
    _, step_units, turn = halfway_world(motion)
    out = []
    for start, *_ in windows[1:]:
        x = np.array([start - STEP, start], dtype=np.float64)
        _, pos = asset.sample_frames(clip, x, world=True)
        jump = float(np.max(np.linalg.norm(pos[1] - pos[0], axis=-1)) * cm)
        step = float(step_units[start - 1] * cm)
        glitch = bool(step > MAX_STEP_CM or turn[start - 1] > MAX_TURN_DEG)
        out.append({"clip": clip, "frame": int(start), "jump_cm": jump, "original_step_cm": step,
                    "glitch": glitch})
    return out


def main() -> int:
    results = Path(sys.argv[1] if len(sys.argv) > 1 else HERE / "results" / "neural_dev_all.json")
    data = json.loads(results.read_text())
    lines = [f"# `neural` window borders ({results.name})", "",
             "Largest joint displacement (cm) between x = border - 0.01 frames (earlier window) and the "
             "border frame (later window), through the C runtime, against the tolerance and against "
             "the original's largest joint motion over the frame before the border. Borders after a "
             "capture glitch are apart (last two columns).", "",
             "| tolerance cm | borders | jump max cm | jump median | jump p90 | max jump / tolerance | "
             "borders where the jump exceeds the original's frame step | worst | glitch borders | "
             "their jump max cm |", "|---|---|---|---|---|---|---|---|---|---|"]
    rows = []
    for s in data["sets"]:
        if s["codec"] != "neural" or not s.get("met") or "asset" not in s:
            continue
        asset = Asset(Path(s["asset"]).read_bytes())
        jumps = []
        for clip, c in s["clips"].items():
            jumps += border_jumps(asset, clip, c["windows"], CM)
        calm = [b for b in jumps if not b["glitch"]]
        glitch = [b["jump_cm"] for b in jumps if b["glitch"]]
        j = np.array([b["jump_cm"] for b in calm])
        over = sum(b["jump_cm"] > b["original_step_cm"] for b in calm)
        worst = max(calm, key=lambda b: b["jump_cm"])
        tol = s["tolerance_cm"]
        rows.append({"tolerance_cm": tol, "borders": jumps})
        lines.append(f"| {tol:g} | {len(j)} | {j.max():.3f} | {np.median(j):.3f} | {np.percentile(j, 90):.3f} | "
                     f"{j.max() / tol:.2f} | {over} ({100.0 * over / len(j):.0f} %) | "
                     f"{worst['clip']} @ {worst['frame']} | {len(glitch)} | {max(glitch, default=0.0):.3f} |")
    out = results.with_name(results.stem + "_borders")
    write_results(out, rows, lines)
    return 0


if __name__ == "__main__":
    sys.exit(main())
