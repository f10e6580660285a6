"""Seed 001's Figure 3 on our clips, and where the ``neural`` codec stands.

    PYTHONPATH=encoder .venv/bin/python bench/bench_neural.py                 # the 3 samples
    PYTHONPATH=encoder .venv/bin/python bench/bench_neural.py --dev 09_01 09_06 02_03 --no-samples --name neural_dev

1. Error vs compression ratio (Figure 3): max joint position error (% of skeleton height, every
   joint and end site, every frame) against ratio = raw pose numbers (F x BVH channels) /
   stored numbers, for the seed's SVD baseline (rank r of the pose-parameter matrix), naive
   frequencies (Omega = {1..K}) and adaptive frequencies (Algorithm 1), K = 1 ... --kmax.
   The networks are evaluated with the Python model of the 16-bit quantized payload.
2. ``neural`` against ``spline`` (and ``rma`` when registered) at 1 cm and 3 cm: asset bytes,
   ratio to the raw BVH numbers, measured max error, encode seconds per clip.
3. C evaluation: microseconds per pose (bench/sample_speed.c) on the neural assets.

Writes bench/results/<name>.json and .md (--name, default "neural").
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
sys.path.insert(0, str(REPO / "encoder"))

from mocodec import codecs  # noqa: E402
from mocodec.codecs import neural as N  # noqa: E402
from mocodec.encode import EncodeError, encode_motions  # noqa: E402
from mocodec.io import read_bvh  # noqa: E402
from mocodec.kinematics import forward_kinematics  # noqa: E402
from mocodec.motion import Motion  # noqa: E402
from mocodec.tolerance import Tolerance  # noqa: E402
from mocodec.units import resolve_units, skeleton_height  # noqa: E402


def _max_pct(motion: Motion, rot: np.ndarray, trans: np.ndarray) -> float:
    world = forward_kinematics(motion.skeleton, motion.rotations, motion.translations)[1]
    pos = forward_kinematics(motion.skeleton, rot, trans)[1]
    return float(100.0 * np.max(np.linalg.norm(pos - world, axis=-1)) / skeleton_height(motion.skeleton))


def svd_curve(motion: Motion, ranks: list[int]) -> list[dict[str, float]]:
    """The seed's baseline: the (F, M) pose-parameter matrix (same parameters as the network)
    cut to rank r around its column means; stored numbers r (F + M) + M."""
    layout = N.pose_layout(motion)
    y = layout.targets
    mean = y.mean(axis=0)
    u, s, vt = np.linalg.svd(y - mean, full_matrices=False)
    raw = motion.frame_count * motion.skeleton.channel_count
    out = []
    for r in ranks:
        if r > len(s):
            break
        rec = mean + (u[:, :r] * s[:r]) @ vt[:r]
        rot, trans = N.local_pose(layout, motion, rec)
        stored = r * (y.shape[0] + y.shape[1]) + y.shape[1]
        out.append({"rank": r, "ratio": raw / stored, "max_pct_height": _max_pct(motion, rot, trans)})
    return out


def network_curve(motion: Motion, mode: str, k_max: int, iterations: int) -> list[dict[str, float]]:
    """Stored numbers: every weight, plus the per-output scale and offset and K frequencies."""
    raw = motion.frame_count * motion.skeleton.channel_count
    x = np.arange(motion.frame_count, dtype=np.float64)
    out = []
    started = time.perf_counter()
    for model in N.fit_stages(motion, mode, k_max, iterations):
        k = len(model.freqs)
        stored = sum(c.size for c in model.net.codes.values()) + 2 * model.layout.outputs + k
        rot, trans = N.local_pose(model.layout, motion, model.parameters(x))
        out.append({"K": k, "ratio": raw / stored, "max_pct_height": _max_pct(motion, rot, trans),
                    "seconds": time.perf_counter() - started})
    return out


def codec_rows(motion: Motion, codec: str, tol: float, tmp: Path, speed: Path | None) -> dict:
    units = [resolve_units(motion.skeleton, "cmu", None)]
    t0 = time.perf_counter()
    try:
        r = encode_motions([motion], units, codec, Tolerance(tol))
    except EncodeError as exc:
        return {"codec": codec, "tolerance_cm": tol, "met": False, "note": str(exc),
                "seconds": time.perf_counter() - t0}
    row = {"codec": codec, "tolerance_cm": tol, "met": True, "asset_bytes": len(r.asset),
           "payload_bytes": r.clips[0].stats.get("payload_bytes"),
           "ratio_raw": motion.skeleton.channel_count * motion.frame_count * 4 / len(r.asset),
           "max_error_cm": r.clips[0].error.max_cm, "mean_error_cm": r.clips[0].error.mean_cm,
           "seconds": time.perf_counter() - t0}
    if codec == "neural":
        row["frequencies"] = r.clips[0].stats.get("frequencies")
        row["weight_bits"] = r.clips[0].stats.get("weight_bits")
    if speed is not None:
        path = tmp / f"{motion.name}_{codec}_{tol}.mcd"
        path.write_bytes(r.asset)
        out = subprocess.run([str(speed), str(path), "7"], capture_output=True, text=True, check=True)
        row["speed"] = json.loads(out.stdout)
    return row


def build_speed(tmp: Path) -> Path | None:
    exe = tmp / "sample_speed"
    cmd = ["cc", "-std=c99", "-O2", f"-I{REPO / 'runtime_c' / 'include'}", str(HERE / "sample_speed.c"),
           *map(str, sorted((REPO / "runtime_c" / "src").glob("*.c"))), "-lm", "-o", str(exe)]
    return exe if subprocess.run(cmd).returncode == 0 else None


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--dev", nargs="*", default=[], help="also these clips (file stems) of ../shared/data/cmu")
    ap.add_argument("--frames", type=int, default=0, help="cut every clip to this many frames (0: whole)")
    ap.add_argument("--kmax", type=int, default=12)
    ap.add_argument("--iterations", type=int, default=500)
    ap.add_argument("--tolerances", type=float, nargs="*", default=[1.0, 3.0])
    ap.add_argument("--no-samples", action="store_true", help="leave out the bundled samples")
    ap.add_argument("--out", type=Path, default=HERE / "results")
    ap.add_argument("--name", default="neural", help="results file stem")
    args = ap.parse_args()

    paths = [] if args.no_samples else sorted((REPO / "encoder" / "mocodec" / "samples").glob("*.bvh"))
    dev = (REPO / ".." / "shared" / "data" / "cmu").resolve()
    if args.dev and dev.is_dir():
        paths += [dev / f"{stem}.bvh" for stem in args.dev]
    motions = [read_bvh(p) for p in paths]
    if args.frames:
        motions = [m.slice(0, min(args.frames, m.frame_count)) for m in motions]
    compare = [c for c in ("neural", "spline", "rma") if c in codecs.available()]
    results: dict = {"clips": {}, "settings": vars(args) | {"out": str(args.out)}}
    with tempfile.TemporaryDirectory() as td:
        tmp = Path(td)
        speed = build_speed(tmp)
        for m in motions:
            print(f"{m.name}: {m.frame_count} frames", flush=True)
            clip = {"frames": m.frame_count,
                    "svd": svd_curve(m, [1, 2, 3, 4, 6, 8, 12, 16, 24, 32]),
                    "naive": network_curve(m, "naive", args.kmax, args.iterations),
                    "adaptive": network_curve(m, "adaptive", args.kmax, args.iterations),
                    "codecs": [codec_rows(m, c, t, tmp, speed) for t in args.tolerances for c in compare]}
            results["clips"][m.name] = clip
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / f"{args.name}.json").write_text(json.dumps(results, indent=1))
    (args.out / f"{args.name}.md").write_text(report(results))
    print(report(results))


def report(results: dict) -> str:
    lines = ["# neural codec (seed 001) on our clips", "",
             "## Figure 3: max joint error (% of height) vs compression ratio", ""]
    for name, c in results["clips"].items():
        lines += [f"### {name} ({c['frames']} frames)", "", "| method | setting | ratio | max error % height |",
                  "| --- | --- | --- | --- |"]
        for r in c["svd"]:
            lines.append(f"| SVD | rank {r['rank']} | {r['ratio']:.1f} | {r['max_pct_height']:.2f} |")
        for mode in ("naive", "adaptive"):
            for r in c[mode]:
                lines.append(f"| {mode} | K = {r['K']} ({r['seconds']:.1f} s) | {r['ratio']:.1f} | {r['max_pct_height']:.2f} |")
        lines += ["", "| codec | tolerance cm | bytes | ratio (raw f32) | max cm | mean cm | encode s | µs/pose seq | µs/pose rand |",
                  "| --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
        for r in c["codecs"]:
            if not r["met"]:
                lines.append(f"| {r['codec']} | {r['tolerance_cm']} | not met | | | | {r['seconds']:.1f} | | |")
                continue
            sp = r.get("speed", {})
            lines.append(f"| {r['codec']} | {r['tolerance_cm']} | {r['asset_bytes']} | {r['ratio_raw']:.1f} | "
                         f"{r['max_error_cm']:.3f} | {r['mean_error_cm']:.3f} | {r['seconds']:.1f} | "
                         f"{_speed(sp, 'seq')} | {_speed(sp, 'rand')} |")
        lines.append("")
    return "\n".join(lines)


def _speed(sp: dict, kind: str) -> str:
    for k, v in sp.items():
        if kind in k and "local" in k and isinstance(v, (int, float)):
            return f"{v:.2f}"
    return ""


if __name__ == "__main__":
    main()
