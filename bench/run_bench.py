"""Rate, error and speed of a codec on a set of clips, beside ACL 2.1 at the same max error.

    python bench/run_bench.py                       # the CMU dev set if ../shared exists, else the samples
    python bench/run_bench.py --codec spline --tolerances 0.02 0.1 1 --data ../shared/data/cmu

For each tolerance: encode every clip into one asset, measure through the C runtime the max,
p99 and mean world-space error (cm) on every frame, the asset's bytes and ratios in both
conventions, encode time, and microseconds per sampled pose in C (sequential and random
access, median of many runs, ``engine_bench speed``). Writes ``<out>/<codec>.json`` and
``<out>/<codec>.md``. ACL's bytes come from ../shared/ACL_REFERENCE.md (measured on these
machines on the same 35 clips); on another clip set that column is left out.
"""
from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
sys.path.insert(0, str(REPO / "encoder"))
sys.path.insert(0, str(HERE))

import acl_reference  # noqa: E402
from engine_bench import RUNTIME_DEFAULT_FLAGS, build_driver, mocodec_speed  # noqa: E402
from mocodec.encode import encode_motions  # noqa: E402
from mocodec.io import read_bvh  # noqa: E402
from mocodec.metrics import combine  # noqa: E402
from mocodec.tolerance import Tolerance, effector_nodes  # noqa: E402
from mocodec.units import resolve_units  # noqa: E402

DEV_SET = REPO.parent / "shared" / "data" / "cmu"
SAMPLES = REPO / "encoder" / "mocodec" / "samples"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", type=Path, default=DEV_SET if DEV_SET.exists() else SAMPLES,
                    help="folder of BVH clips (default: the CMU dev set, else the bundled samples)")
    ap.add_argument("--codec", default="spline")
    ap.add_argument("--tolerances", type=float, nargs="+", default=[0.02, 0.1, 1.0], metavar="CM")
    ap.add_argument("--units", default="cmu", help="units of the BVH files (default: cmu)")
    ap.add_argument("--runs", type=int, default=15, help="speed passes per mode; the median is kept")
    ap.add_argument("-O", "--option", action="append", default=[], metavar="KEY=VALUE",
                    help="codec setting (JSON value), as for `mocodec encode -O`")
    ap.add_argument("--effector-tolerance", type=float, default=None, metavar="CM",
                    help="tighter bound for hands, feet, head and end sites (as `mocodec encode`); "
                         "the results are then written as <codec>_effector<CM>.json / .md")
    ap.add_argument("--pca-variances", type=float, nargs="+", default=None, metavar="F",
                    help="sweep seed 003's variance setting instead of tolerances (codec rma-pca, "
                         "no error promise: the rows report the error reached)")
    ap.add_argument("--out", type=Path, default=HERE / "results")
    args = ap.parse_args(argv)
    if args.pca_variances:
        args.codec = "rma-pca"
    stem = args.codec if args.effector_tolerance is None else f"{args.codec}_effector{args.effector_tolerance:g}"
    if args.pca_variances and options_label(args.option):
        stem += "_" + options_label(args.option)

    args.out.mkdir(parents=True, exist_ok=True)
    paths = sorted(args.data.glob("*.bvh"))
    if not paths:
        print(f"no .bvh files in {args.data}", file=sys.stderr)
        return 1
    motions = [read_bvh(p) for p in paths]
    units = [resolve_units(m.skeleton, args.units, None) for m in motions]
    options = {k: json.loads(v) for k, v in (o.split("=", 1) for o in args.option)}
    names = {m.name for m in motions}
    acl = acl_reference.load()
    whole_dev_set = acl is not None and names == set(acl.per_clip)
    exe = build_driver(RUNTIME_DEFAULT_FLAGS, acl=False)  # the runtime at -O2, like an engine build
    frames = sum(m.frame_count for m in motions)
    print(f"{len(motions)} clips, {frames} frames from {args.data}; codec {args.codec}", file=sys.stderr)

    rows = []
    sweep = [(None, v) for v in args.pca_variances] if args.pca_variances else [(t, None) for t in args.tolerances]
    for tol, variance in sweep:
        started = time.perf_counter()
        opts = options if variance is None else {**options, "variance": variance}
        label = f"{tol} cm" if variance is None else f"variance {variance}"
        result = encode_motions(motions, units, args.codec, Tolerance(tol or 1.0, args.effector_tolerance), opts,
                                progress=lambda n: print(f"  {label}: {n}", file=sys.stderr))
        seconds = time.perf_counter() - started
        asset_path = args.out / (f"{stem}_{tol:g}cm.mcd" if variance is None else f"{stem}_v{variance:g}.mcd")
        asset_path.write_bytes(result.asset)
        err = combine([c.error for c in result.clips])
        sp = mocodec_speed(exe, asset_path, args.runs)
        row = {
            "tolerance_cm": tol, **({"pca_variance": variance, **result.settings} if variance else {}),
            "asset_bytes": len(result.asset),
            **{k: result.size.as_dict()[k] for k in ("ratio_bvh", "ratio_acl", "bytes_per_second",
                                                      "raw_bvh_bytes", "raw_acl_bytes", "seconds")},
            **err, **effector_split(motions, result.clips), "encode_seconds": seconds, **{k: v for k, v in sp.items() if k.startswith("us_")},
            "resident_bytes": sp["resident_bytes"], "scratch_bytes": sp["scratch_bytes"],
        }
        if whole_dev_set:
            row["acl_bytes_at_same_max_error"] = acl.bytes_at_error(err["max_cm"])
            row["acl_nearest_measured"] = dict(zip(("precision_units", "bytes", "max_error_cm"),
                                                   acl.nearest_row(err["max_cm"])))
            row["size_vs_acl"] = len(result.asset) / row["acl_bytes_at_same_max_error"]
        rows.append(row)
        print(json.dumps(row), file=sys.stderr)

    report = {
        "codec": args.codec, "data": str(args.data),
        "label": args.codec if args.effector_tolerance is None
        else f"{args.codec}, effector tolerance {args.effector_tolerance:g} cm", "clips": len(motions), "frames": frames,
        "effector_tolerance_cm": args.effector_tolerance, "options": options, "machine": platform.machine(), "python": platform.python_version(),
        "acl_reference": str(acl_reference.DEFAULT_PATH) if whole_dev_set else None,
        "acl_decode_us_per_pose": acl.decode_us if whole_dev_set else None, "rows": rows,
    }
    (args.out / f"{stem}.json").write_text(json.dumps(report, indent=2))
    md = markdown(report)
    (args.out / f"{stem}.md").write_text(md)
    print(md)
    return 0


def options_label(options: list[str]) -> str:
    """``-O`` settings as a file-name part: groups=1 -> groups1."""
    return "_".join(o.replace("=", "") for o in options)


def effector_split(motions: list, clips: list) -> dict:
    """Mean and max error of the end effectors (hands, feet, head, end sites) and of every other
    node, over every frame of every clip: the fidelity goal is effectors at half the inner error."""
    sums = {"effector": [0.0, 0, 0.0], "inner": [0.0, 0, 0.0]}  # sum of errors, samples, max
    for m, c in zip(motions, clips):
        eff = effector_nodes(m.skeleton)
        for key, mask in (("effector", eff), ("inner", ~eff)):
            if mask.any():
                sums[key][0] += float(c.error.per_node_mean_cm[mask].sum()) * m.frame_count
                sums[key][1] += int(mask.sum()) * m.frame_count
                sums[key][2] = max(sums[key][2], float(c.error.per_node_max_cm[mask].max()))
    out = {}
    for key, (total, n, mx) in sums.items():
        out[f"{key}_mean_cm"] = total / n if n else 0.0
        out[f"{key}_max_cm"] = mx
    return out


def markdown(report: dict) -> str:
    acl = report["acl_reference"] is not None
    pca = any(r.get("pca_variance") for r in report["rows"])
    head = ["PCA variance (components per group)" if pca else "tolerance cm", "bytes", "B/s", "ratio BVH f32", "ratio ACL 40B", "max cm", "p99 cm",
            "mean cm", "effector / inner mean cm", "encode s", "µs/pose seq", "µs/pose random",
            "µs world seq", "resident B"]
    if acl:
        head += ["ACL bytes at same max err", "ours / ACL"]
    eff = report.get("effector_tolerance_cm")
    lines = [f"`{report['codec']}`{f' (effector tolerance {eff:g} cm)' if eff else ''} on {report['clips']} clips ({report['frames']:,} frames) from "
             f"`{report['data']}`, options {json.dumps(report['options'])}", "",
             "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in report["rows"]:
        first = (f"{r['pca_variance']:g} ({' '.join(map(str, r['components']))})" if pca
                 else f"{r['tolerance_cm']:g}")
        cells = [first, f"{r['asset_bytes']:,}", f"{r['bytes_per_second']:,.0f}",
                 f"{r['ratio_bvh']:.1f}", f"{r['ratio_acl']:.1f}", f"{r['max_cm']:.4f}",
                 f"{r['p99_cm']:.4f}", f"{r['mean_cm']:.4f}",
                 f"{r['effector_mean_cm']:.3f} / {r['inner_mean_cm']:.3f}" if "effector_mean_cm" in r else "—",
                 f"{r['encode_seconds']:.0f}",
                 f"{r['us_per_pose_local_sequential']:.2f}", f"{r['us_per_pose_local_random']:.2f}",
                 f"{r['us_per_pose_world_sequential']:.2f}", f"{r['resident_bytes']:,}"]
        if acl:
            cells += [f"{r['acl_bytes_at_same_max_error']:,.0f}", f"{r['size_vs_acl']:.3f}"]
        lines.append("| " + " | ".join(cells) + " |")
    if acl:
        lines += ["", f"ACL 2.1 bytes: ../shared/ACL_REFERENCE.md, interpolated log-log at our max "
                      f"error; ACL decodes a pose in {report['acl_decode_us_per_pose']} µs there."]
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    sys.exit(main())
