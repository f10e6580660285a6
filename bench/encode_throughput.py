"""Encoder throughput on one core: CPU seconds per codec and MB/s of raw data in ACL's convention
(40 B per bone-sample, :func:`mocodec.metrics.raw_acl_bytes`), for ACL's compression rate in
``../shared/ACL_REFERENCE.md`` and ``make bench``.

Each codec encodes the clips as one library, as ``mocodec encode`` does, in this process (one
core: no worker processes; BLAS is held to one thread before numpy loads), ``--repeats`` times;
the report gives the median CPU time and the spread. Run it under the benchmark lock:

    flock /tmp/mocodec-bench.lock nice -n 10 .venv/bin/python bench/encode_throughput.py \
        --codec rma --tolerance 1 ../shared/data/cmu/*.bvh

``--clips N`` takes every k-th clip of the list so that N remain (a subset for the slow codecs;
the report names the clips and their raw size).
"""
from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import hashlib  # noqa: E402
import json  # noqa: E402
import statistics  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "encoder"))

from mocodec.encode import encode_motions  # noqa: E402
from mocodec.io import read_bvh  # noqa: E402
from mocodec.metrics import raw_acl_bytes  # noqa: E402
from mocodec.tolerance import Tolerance  # noqa: E402
from mocodec.units import resolve_units  # noqa: E402


def pick(paths: list[Path], clips: int | None) -> list[Path]:
    """Every k-th path so that ``clips`` remain (all of them when None)."""
    if clips is None or clips >= len(paths):
        return paths
    step = len(paths) / clips
    return [paths[int(i * step)] for i in range(clips)]


def measure(paths: list[Path], codec: str, tolerance: float, options: dict, repeats: int) -> dict:
    """Encode ``paths`` as one library ``repeats`` times: CPU seconds (process time, reading
    the BVH files excluded), the asset's size and digest, MB/s raw."""
    motions = [read_bvh(p) for p in paths]
    units = [resolve_units(m.skeleton, "cmu", None) for m in motions]
    raw = sum(raw_acl_bytes(m) for m in motions)
    cpu, digests, size = [], set(), 0
    for _ in range(repeats):
        start = time.process_time()
        result = encode_motions(motions, units, codec, Tolerance(tolerance), dict(options))
        cpu.append(time.process_time() - start)
        size = len(result.asset)
        digests.add(hashlib.sha256(result.asset).hexdigest()[:16])
    med = statistics.median(cpu)
    return {"codec": codec, "tolerance_cm": tolerance, "options": options, "clips": [p.stem for p in paths],
            "raw_acl_bytes": raw, "asset_bytes": size, "asset_sha256_16": sorted(digests),
            "cpu_seconds": cpu, "cpu_median": med, "cpu_min": min(cpu), "cpu_max": max(cpu),
            "mb_per_s": raw / med / 1e6}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("bvh", nargs="+", type=Path)
    ap.add_argument("--codec", default="rma")
    ap.add_argument("--tolerance", type=float, default=1.0)
    ap.add_argument("-O", dest="options", action="append", default=[], metavar="KEY=VALUE",
                    help="codec option (a number or a string)")
    ap.add_argument("--clips", type=int, default=None, help="a subset of this many clips, spread over the list")
    ap.add_argument("--repeats", type=int, default=1)
    ap.add_argument("--json", type=Path, default=None, help="append the result to this JSON-lines file")
    args = ap.parse_args(argv)
    options = {}
    for item in args.options:
        key, _, value = item.partition("=")
        try:
            options[key] = float(value) if "." in value or "e" in value else int(value)
        except ValueError:
            options[key] = value
    r = measure(pick(sorted(args.bvh), args.clips), args.codec, args.tolerance, options, args.repeats)
    print(f"{r['codec']} at {r['tolerance_cm']} cm, {len(r['clips'])} clips, raw {r['raw_acl_bytes']:,} B: "
          f"CPU {r['cpu_median']:.1f} s (min {r['cpu_min']:.1f}, max {r['cpu_max']:.1f}, {len(r['cpu_seconds'])} runs), "
          f"{r['mb_per_s']:.2f} MB/s raw, asset {r['asset_bytes']:,} B {','.join(r['asset_sha256_16'])}")
    if args.json:
        with args.json.open("a") as f:
            f.write(json.dumps(r) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
