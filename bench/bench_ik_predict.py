"""Choose the ``ik-predict`` settings by measurement on a clip set (default: the CMU dev set).

    .venv/bin/python bench/bench_ik_predict.py [--tolerance 1] [--sweep k gap ik block]

Each variant encodes every clip into one asset at the tolerance (through the C runtime's
check, as ``mocodec encode`` does) and reports bytes, max / p99 / mean world error (cm), encode
seconds, and — for the block-length sweep — microseconds per pose in C, sequential and random
access (``engine_bench speed``: random access is the seek cost). The default variant also gets the
end-effector vs inner-joint mean error. Writes ``results/ik_predict_variants.{json,md}``.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "encoder"))
sys.path.insert(0, str(HERE))

from engine_bench import RUNTIME_DEFAULT_FLAGS, build_driver, mocodec_speed  # noqa: E402
from run_bench import DEV_SET, SAMPLES  # noqa: E402

from mocodec.encode import encode_motions  # noqa: E402
from mocodec.io import read_bvh  # noqa: E402
from mocodec.kinematics import forward_kinematics  # noqa: E402
from mocodec.metrics import combine  # noqa: E402
from mocodec.runtime import Asset  # noqa: E402
from mocodec.tolerance import Tolerance, effector_nodes  # noqa: E402
from mocodec.units import resolve_units  # noqa: E402

SWEEPS = {
    "k": [{"k": 0.0}, {"k": 1.0}, {"k": 2.0}],
    "gap": [{"max_gap": 1}, {"max_gap": 4}, {"max_gap": 8}, {"max_gap": 8, "gap_fraction": 0.5}],
    "ik": [{"ik": False}, {"ik": False, "max_gap": 1}],
    "block": [{"block_frames": n} for n in (4, 8, 16, 32, 64)],
}


def effector_split(asset: Asset, motions, units) -> dict:
    """Mean world error (cm) over every frame of the end effectors (hands, feet, head, end
    sites) and of the other joints."""
    eff_sum = eff_n = inner_sum = inner_n = 0.0
    for m, u in zip(motions, units):
        _, pos_o = forward_kinematics(m.skeleton, m.rotations, m.translations)
        _, pos_d = asset.sample_frames(m.name, world=True)
        err = np.linalg.norm(pos_o - pos_d, axis=-1) * u.cm_per_unit
        eff = effector_nodes(m.skeleton)
        eff_sum += err[:, eff].sum()
        eff_n += err[:, eff].size
        inner_sum += err[:, ~eff].sum()
        inner_n += err[:, ~eff].size
    return {"effector_mean_cm": eff_sum / eff_n, "inner_mean_cm": inner_sum / inner_n}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", type=Path, default=DEV_SET if DEV_SET.exists() else SAMPLES)
    ap.add_argument("--tolerance", type=float, default=1.0)
    ap.add_argument("--sweep", nargs="+", default=list(SWEEPS), choices=list(SWEEPS))
    ap.add_argument("--runs", type=int, default=7)
    ap.add_argument("--out", type=Path, default=HERE / "results")
    args = ap.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    motions = [read_bvh(p) for p in sorted(args.data.glob("*.bvh"))]
    units = [resolve_units(m.skeleton, "cmu", None) for m in motions]
    exe = build_driver(RUNTIME_DEFAULT_FLAGS, acl=False)
    variants = [{}] + [v for s in args.sweep for v in SWEEPS[s]]
    rows = []
    for options in variants:
        started = time.perf_counter()
        result = encode_motions(motions, units, "ik-predict", Tolerance(args.tolerance), options)
        seconds = time.perf_counter() - started
        err = combine([c.error for c in result.clips])
        row = {"options": options, "bytes": len(result.asset), "max_cm": err["max_cm"],
               "p99_cm": err["p99_cm"], "mean_cm": err["mean_cm"], "encode_seconds": seconds}
        if not options or "block_frames" in options:
            path = args.out / "ik_predict_variant.mcd"
            path.write_bytes(result.asset)
            sp = mocodec_speed(exe, path, args.runs)
            row.update({k: v for k, v in sp.items() if k.startswith("us_")})
            row["scratch_bytes"] = sp["scratch_bytes"]
            path.unlink()
        if not options:
            row.update(effector_split(Asset(result.asset), motions, units))
        rows.append(row)
        print(json.dumps(row), file=sys.stderr)
    report = {"data": str(args.data), "clips": len(motions),
              "frames": sum(m.frame_count for m in motions), "tolerance_cm": args.tolerance, "rows": rows}
    (args.out / "ik_predict_variants.json").write_text(json.dumps(report, indent=2))
    lines = [f"`ik-predict` variants on {report['clips']} clips ({report['frames']:,} frames) from "
             f"`{report['data']}` at {args.tolerance:g} cm (options over the defaults)", "",
             "| options | bytes | max cm | p99 cm | mean cm | encode s | µs/pose seq | µs/pose random |",
             "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        us = [f"{r[k]:.2f}" if k in r else "" for k in ("us_per_pose_local_sequential", "us_per_pose_local_random")]
        lines.append(f"| {json.dumps(r['options']) if r['options'] else 'defaults'} | {r['bytes']:,} | "
                     f"{r['max_cm']:.3f} | {r['p99_cm']:.3f} | {r['mean_cm']:.3f} | {r['encode_seconds']:.0f} | "
                     f"{us[0]} | {us[1]} |")
    base = rows[0]
    if "effector_mean_cm" in base:
        lines += ["", f"Defaults: end-effector mean error {base['effector_mean_cm']:.3f} cm, inner joints "
                      f"{base['inner_mean_cm']:.3f} cm."]
    (args.out / "ik_predict_variants.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
