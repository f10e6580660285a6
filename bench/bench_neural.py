"""Seed 001's Figure 3 on our clips, and where the ``neural`` codec stands.

    PYTHONPATH=encoder .venv/bin/python bench/bench_neural.py --figure3 09_06 02_01 --name neural_fig3
    PYTHONPATH=encoder .venv/bin/python bench/bench_neural.py --all-dev --tolerances 3 --name neural_dev3

1. Error vs compression ratio (Figure 3, --figure3 clips): max joint position error (% of
   skeleton height, every joint and end site, every frame) against ratio = raw pose numbers
   (F x BVH channels) / stored numbers, for the seed's SVD baseline (rank r of the
   pose-parameter matrix), naive frequencies (Omega = {1..K}) and adaptive frequencies
   (Algorithm 1), K = 0 ... --kmax, one network on the whole clip (the seed's setting).
   The networks are evaluated with the Python model of the 16-bit quantized payload.
2. ``neural`` (windowed) against ``spline`` and ``rma`` at each tolerance (--dev / --all-dev
   clips): every clip of the set in one asset per codec (rma is a library codec, so sets are
   compared by their totals), per-clip payload bytes, errors through the runtime, training
   seconds, windows and K per window.
3. C evaluation: microseconds per pose (``engine_bench speed``), sequential and random, per asset.

Writes bench/results/<name>.json and .md (--name, default "neural").
"""
from __future__ import annotations

import argparse
import ast
import json
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
sys.path.insert(0, str(REPO / "encoder"))
sys.path.insert(0, str(HERE))

from engine_bench import RUNTIME_DEFAULT_FLAGS, build_driver, mocodec_speed  # noqa: E402
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
        w = model.windows[0]
        k = len(w.freqs)
        stored = sum(c.size for c in w.net.codes.values()) + 2 * model.layout.outputs + k
        rot, trans = N.local_pose(model.layout, motion, model.parameters(x))
        out.append({"K": k, "ratio": raw / stored, "max_pct_height": _max_pct(motion, rot, trans),
                    "seconds": time.perf_counter() - started})
    return out


def codec_set(motions: list[Motion], codec: str, tol: float, keep: Path, speed: Path | None,
              options: dict) -> dict:
    """Every clip of ``motions`` in one asset (rma is a library codec: its figures are per set),
    per-clip payload bytes and errors through the runtime, C speed on the asset."""
    units = [resolve_units(m.skeleton, "cmu", None) for m in motions]
    t0 = time.perf_counter()
    try:
        r = encode_motions(motions, units, codec, Tolerance(tol), options,
                           progress=lambda name: print(f"  {codec} {tol} cm: {name} {time.perf_counter() - t0:.0f} s", flush=True))
    except EncodeError as exc:
        return {"codec": codec, "tolerance_cm": tol, "met": False, "note": str(exc),
                "seconds": time.perf_counter() - t0}
    clips = {}
    for m, c in zip(motions, r.clips):
        clips[m.name] = {"payload_bytes": c.stats.get("payload_bytes"), "max_error_cm": c.error.max_cm,
                         "mean_error_cm": c.error.mean_cm, "frames": m.frame_count,
                         **{k: c.stats[k] for k in ("windows", "frequencies", "splits", "encode_seconds")
                            if k in c.stats}}
    row = {"codec": codec, "tolerance_cm": tol, "met": True, "asset_bytes": len(r.asset),
           "raw_f32_bytes": sum(m.skeleton.channel_count * m.frame_count * 4 for m in motions),
           "max_error_cm": max(c.error.max_cm for c in r.clips),
           "mean_error_cm": float(np.average([c.error.mean_cm for c in r.clips], weights=[m.frame_count for m in motions])),
           "seconds": time.perf_counter() - t0, "clips": clips}
    path = keep.with_name(f"{keep.name}_{codec}_{tol:g}cm.mcd")
    path.write_bytes(r.asset)  # kept (git-ignored) so the speed can be re-measured on an idle machine
    row["asset"] = str(path)
    if speed is not None:
        row["speed"] = mocodec_speed(speed, path, 7)
    return row


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--dev", nargs="*", default=[], help="clips (file stems) of ../shared/data/cmu for the codec comparison")
    ap.add_argument("--all-dev", action="store_true", help="every clip of ../shared/data/cmu for the codec comparison")
    ap.add_argument("--figure3", nargs="*", default=[], help="clips (file stems) for Figure 3 (whole clip, one network)")
    ap.add_argument("--keep-frame0", action="store_true",
                    help="Figure 3 on the whole file; by default frame 0 (CMU's T-pose) is left out")
    ap.add_argument("--kmax", type=int, default=12)
    ap.add_argument("--iterations", type=int, default=500)
    ap.add_argument("--tolerances", type=float, nargs="*", default=[1.0, 3.0])
    ap.add_argument("--codecs", nargs="*", default=["neural", "spline", "rma"])
    ap.add_argument("-O", "--option", action="append", default=[], metavar="KEY=VALUE",
                    help="neural setting (NeuralSettings), value parsed as a Python literal")
    ap.add_argument("--out", type=Path, default=HERE / "results")
    ap.add_argument("--name", default="neural", help="results file stem")
    args = ap.parse_args()

    dev = (REPO / ".." / "shared" / "data" / "cmu").resolve()
    stems = sorted(p.stem for p in dev.glob("*.bvh")) if args.all_dev else args.dev
    options = {k: ast.literal_eval(v) for k, v in (o.split("=", 1) for o in args.option)}
    results: dict = {"figure3": {}, "sets": [], "settings": vars(args) | {"out": str(args.out)}}
    for stem in args.figure3:
        m = read_bvh(dev / f"{stem}.bvh")
        print(f"figure 3: {m.name}: {m.frame_count} frames", flush=True)
        if args.keep_frame0 is False and m.frame_count > 2:
            m = m.slice(1, m.frame_count)  # CMU's frame 0 is the converter's T-pose, not motion
        results["figure3"][m.name] = {
            "frames": m.frame_count, "svd": svd_curve(m, [1, 2, 3, 4, 6, 8, 12, 16, 24, 32]),
            "naive": network_curve(m, "naive", args.kmax, args.iterations),
            "adaptive": network_curve(m, "adaptive", args.kmax, args.iterations)}
        _write(args, results)
    motions = [read_bvh(dev / f"{s}.bvh") for s in stems]
    compare = [c for c in args.codecs if c in codecs.available()]
    if motions:
        speed = build_driver(RUNTIME_DEFAULT_FLAGS, acl=False)
        keep = args.out / args.name
        args.out.mkdir(parents=True, exist_ok=True)
        for tol in args.tolerances:
            for c in compare:
                results["sets"].append(codec_set(motions, c, tol, keep, speed, options if c == "neural" else {}))
                _write(args, results)
    print(report(results))


def _write(args: argparse.Namespace, results: dict) -> None:
    """Results so far: a long run leaves what it measured even when stopped."""
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / f"{args.name}.json").write_text(json.dumps(results, indent=1))
    (args.out / f"{args.name}.md").write_text(report(results))


def report(results: dict) -> str:
    lines = ["# neural codec (seed 001) on our clips", ""]
    if results["figure3"]:
        lines += ["## Figure 3: max joint error (% of height) vs compression ratio (whole clip, one network)", ""]
    for name, c in results["figure3"].items():
        lines += [f"### {name} ({c['frames']} frames)", "", "| method | setting | ratio | max error % height |",
                  "| --- | --- | --- | --- |"]
        for r in c["svd"]:
            lines.append(f"| SVD | rank {r['rank']} | {r['ratio']:.1f} | {r['max_pct_height']:.2f} |")
        for mode in ("naive", "adaptive"):
            for r in c[mode]:
                lines.append(f"| {mode} | K = {r['K']} ({r['seconds']:.1f} s) | {r['ratio']:.1f} | {r['max_pct_height']:.2f} |")
        lines.append("")
    if results["sets"]:
        lines += ["## Codecs on one asset per set and tolerance", "",
                  "| codec | tolerance cm | clips | asset bytes | ratio (raw f32) | max cm | mean cm | encode s | µs/pose seq | µs/pose rand |",
                  "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
        for r in results["sets"]:
            if not r["met"]:
                lines.append(f"| {r['codec']} | {r['tolerance_cm']} | | not met: {r['note'][:80]} | | | | {r['seconds']:.0f} | | |")
                continue
            sp = r.get("speed", {})
            lines.append(f"| {r['codec']} | {r['tolerance_cm']} | {len(r['clips'])} | {r['asset_bytes']:,} | "
                         f"{r['raw_f32_bytes'] / r['asset_bytes']:.1f} | {r['max_error_cm']:.3f} | {r['mean_error_cm']:.3f} | "
                         f"{r['seconds']:.0f} | {_speed(sp, 'seq')} | {_speed(sp, 'rand')} |")
        lines.append("")
        for r in results["sets"]:
            if not r["met"] or r["codec"] != "neural":
                continue
            other = {o["codec"]: o for o in results["sets"] if o["met"] and o["tolerance_cm"] == r["tolerance_cm"]}
            lines += [f"### neural per clip at {r['tolerance_cm']} cm", "",
                      "| clip | frames | payload B | spline payload B | max cm | mean cm | train s | windows | splits | K per window | bits per window |",
                      "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
            for name, c in r["clips"].items():
                sp = other.get("spline", {}).get("clips", {}).get(name, {}).get("payload_bytes", "")
                ks = " ".join(str(w[2]) for w in c["windows"])
                bits = " ".join(str(w[3]) for w in c["windows"])
                lines.append(f"| {name} | {c['frames']} | {c['payload_bytes']:,} | {sp:,} | {c['max_error_cm']:.3f} | "
                             f"{c['mean_error_cm']:.3f} | {c['encode_seconds']:.1f} | {len(c['windows'])} | {c['splits']} | {ks} | {bits} |"
                             if sp != "" else
                             f"| {name} | {c['frames']} | {c['payload_bytes']:,} | | {c['max_error_cm']:.3f} | "
                             f"{c['mean_error_cm']:.3f} | {c['encode_seconds']:.1f} | {len(c['windows'])} | {c['splits']} | {ks} | {bits} |")
            lines.append("")
    return "\n".join(lines)


def _speed(sp: dict, kind: str) -> str:
    for k, v in sp.items():
        if kind in k and "local" in k and isinstance(v, (int, float)):
            return f"{v:.2f}"
    return ""


if __name__ == "__main__":
    main()
