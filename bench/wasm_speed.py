"""Microseconds per pose: the runtime compiled to WebAssembly under node, beside the native C build,
in one run on the same assets.

    python bench/wasm_speed.py [--runs 15] [--codecs spline rma ...] [--out bench/results]

Builds both with the project's make targets (``make -C runtime_c lib`` for bench/pose_speed.c,
``make -C runtime_c wasm`` for bench/pose_speed.mjs), encodes the bundled sample clips once per
codec at 1 cm, then times each asset natively and under node one after the other, under
``flock /tmp/mocodec-bench.lock``. Writes ``wasm_speed.json`` and ``wasm_speed.md``.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
sys.path.insert(0, str(REPO / "encoder"))

from mocodec import codecs  # noqa: E402
from mocodec.encode import encode_motions  # noqa: E402
from mocodec.io import read_bvh  # noqa: E402
from mocodec.tolerance import Tolerance  # noqa: E402
from mocodec.units import resolve_units  # noqa: E402

SAMPLES = REPO / "encoder" / "mocodec" / "samples"
LOCK = "/tmp/mocodec-bench.lock"
MODES = ("local_sequential", "local_random", "world_sequential", "world_random")


def build(tmp: Path) -> tuple[Path, Path]:
    """The native timing tool and the wasm, both from runtime_c's make targets."""
    subprocess.run(["make", "-s", "-C", str(REPO / "runtime_c"), "lib", "wasm"], check=True)
    exe = tmp / "pose_speed"
    subprocess.run(["cc", "-std=c99", "-O2", "-I", str(REPO / "runtime_c" / "include"), str(HERE / "pose_speed.c"),
                    str(REPO / "runtime_c" / "build" / "libmocodec.a"), "-lm", "-o", str(exe)], check=True)
    return exe, REPO / "runtime_c" / "build" / "wasm" / "mocodec.wasm"


def assets(tmp: Path, names: list[str]) -> dict[str, Path]:
    motions = [read_bvh(p) for p in sorted(SAMPLES.glob("*.bvh"))]
    units = [resolve_units(m.skeleton, "cmu", None) for m in motions]
    out = {}
    for codec in names:
        try:
            result = encode_motions(motions, units, codec, Tolerance(1.0))
        except Exception as exc:  # a codec whose runtime side is not in this build
            print(f"wasm_speed: SKIPPED codec {codec}: {str(exc).splitlines()[0]}", file=sys.stderr)
            continue
        out[codec] = tmp / f"{codec}.mcd"
        out[codec].write_bytes(result.asset)
    return out


def measure(exe: Path, wasm: Path, asset: Path, runs: int) -> dict:
    """Native then wasm on one asset, inside one hold of the benchmark lock."""
    script = (f"{exe} {asset} {runs} && node {HERE / 'pose_speed.mjs'} {asset} {runs} {wasm}")
    r = subprocess.run(["flock", LOCK, "sh", "-c", script], check=True, capture_output=True, text=True)
    native, web = (json.loads(line) for line in r.stdout.strip().splitlines())
    return {"native": native, "wasm": web}


def table(results: dict) -> list[str]:
    rows = ["| codec | mode | native C µs | wasm µs (export) | wasm µs (binding) | wasm / native (min, median) |",
            "| --- | --- | ---: | ---: | ---: | ---: |"]
    for codec, r in results.items():
        for mode in MODES:
            n, d, b = r["native"][mode], r["wasm"]["direct"][mode], r["wasm"]["binding"][mode]
            cell = lambda s: f"{s['min']:.3f} / {s['median']:.3f} / {s['max']:.3f}"  # noqa: E731
            rows.append(f"| {codec} | {mode.replace('_', ' ')} | {cell(n)} | {cell(d)} | {cell(b)} | "
                        f"{d['min'] / n['min']:.2f}×, {d['median'] / n['median']:.2f}× |")
    return rows


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--runs", type=int, default=15)
    ap.add_argument("--codecs", nargs="+", default=codecs.available())
    ap.add_argument("--out", type=Path, default=HERE / "results")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp_name:
        tmp = Path(tmp_name)
        exe, wasm = build(tmp)
        encoded = assets(tmp, args.codecs)
        load_before = os.getloadavg()
        results = {codec: measure(exe, wasm, path, args.runs) for codec, path in encoded.items()}
        load_after = os.getloadavg()
    node = subprocess.run(["node", "--version"], capture_output=True, text=True).stdout.strip()
    report = {"machine": platform.platform(), "cpu": platform.processor() or platform.machine(), "node": node,
              "clips": [p.stem for p in sorted(SAMPLES.glob("*.bvh"))], "tolerance_cm": 1.0,
              "runs": args.runs,
              "load_average_1min": [round(load_before[0], 2), round(load_after[0], 2)], "results": results}
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "wasm_speed.json").write_text(json.dumps(report, indent=1))
    any_result = next(iter(results.values()))
    lines = [
        "# µs per pose: wasm under node beside native C",
        "",
        f"`python bench/wasm_speed.py --runs {args.runs}` on {report['machine']}, node {node}. Assets: the "
        f"{len(report['clips'])} bundled sample clips ({', '.join(report['clips'])}; "
        f"{any_result['native']['poses_per_pass']} poses per pass) encoded at 1 cm per codec. Native: "
        "bench/pose_speed.c linked with `make -C runtime_c lib` (-O2); wasm: `make -C runtime_c wasm` "
        "(clang -O2, wasm32) in node's V8, bench/pose_speed.mjs. *export*: the wasm's mcd_sample called "
        "directly; *binding*: bindings/web's Instance.sample into a Float32Array (what a page pays). "
        "Each cell: min / median / max over the runs of the per-pose mean of one pass, after 500 ms of "
        "warm-up passes (V8 tiers the wasm up meanwhile); one thread, one scratch; native and wasm of "
        "one codec run back to back under one hold of the benchmark lock. Sequential: every frame in "
        "order; random: as many uniform times (the same times on both sides). The lock keeps other "
        "benchmarks out, not other work: the 1-minute load average was "
        f"{load_before[0]:.1f} before and {load_after[0]:.1f} after on {os.cpu_count()} cores, so the "
        "min is the figure least disturbed by it.",
        "",
        *table(results),
        "",
    ]
    (args.out / "wasm_speed.md").write_text("\n".join(lines))
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
