"""Encoder throughput on one core: CPU seconds per codec and MB/s of raw data in ACL's convention
(40 B per bone-sample, :func:`mocodec.metrics.raw_acl_bytes`), for ACL's compression rate in
``../shared/ACL_REFERENCE.md`` and ``make bench``.

Each codec encodes the clips as one library, as ``mocodec encode`` does, in this process (one
core: no worker processes; BLAS is held to one thread before numpy loads), ``--repeats`` times;
the report gives the median CPU time and the spread. Run it under the benchmark lock:

    flock /tmp/mocodec-bench.lock nice -n 10 .venv/bin/python bench/encode_throughput.py \
        --codec rma --tolerance 1 ../shared/data/cmu/*.bvh

``--clips N`` takes every k-th clip of the list so that N remain (a subset for the slow codecs;
the report names the clips and their raw size). ``--acl`` times ACL 2.1's ``compress_track_list``
on the same clips in the same run, before the encode (``bench/engine_bench.py``'s driver, ACL from
``../shared/acl``, at the per-clip precisions that meet the tolerance, cached under
``bench/results/assets/``), and reports the encoder's rate as a fraction of ACL's.
"""
from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import argparse  # noqa: E402
import hashlib  # noqa: E402
import json  # noqa: E402
import statistics  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
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


def acl_compress(paths: list[Path], tolerance: float, repeats: int) -> dict:
    """ACL's ``compress_track_list`` over ``paths`` at the per-clip precisions whose max error
    meets ``tolerance`` (the engine bench's driver: its ``run`` with one decode round): thread-CPU
    seconds of each pass over the set (median, min, max) and MB/s raw in ACL's convention."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import engine_bench as eb

    cm_per_unit = 5.644  # engine_bench's, so that its cached dump and ACL precisions serve here too
    exe = eb.build_driver(acl=True)
    dump_key = f"{eb.fingerprint(paths, cm_per_unit)}_{eb.reader_key()}"
    dump = eb.CACHE / f"clips_{dump_key}.bin"
    if not dump.exists():
        eb.CACHE.mkdir(parents=True, exist_ok=True)
        eb.write_dump([read_bvh(p) for p in paths], cm_per_unit, dump)
    precisions = eb.ensure_acl_precisions(exe, dump, tolerance, dump_key, 3.0)
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "acl.json"
        subprocess.run([str(exe), "run", str(dump), "--acl", f"{tolerance:g}={precisions}", "--rounds", "1",
                        "--compress-reps", str(repeats), "--open-reps", "1", "--json", str(out)],
                       check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        run = json.loads(out.read_text())
    cpu = run["acl"]["targets"][0]["compress_cpu_s"]
    return {"acl_cpu_median": cpu["median"], "acl_cpu_min": cpu["min"], "acl_cpu_max": cpu["max"],
            "acl_raw_acl_bytes": run["raw_acl_bytes"], "acl_mb_per_s": run["raw_acl_bytes"] / cpu["median"] / 1e6}


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
    ap.add_argument("--acl", action="store_true",
                    help="time ACL's compressor on the same clips first (3 passes) and give the ratio")
    args = ap.parse_args(argv)
    options = {}
    for item in args.options:
        key, _, value = item.partition("=")
        try:
            options[key] = float(value) if "." in value or "e" in value else int(value)
        except ValueError:
            options[key] = value
    paths = pick(sorted(args.bvh), args.clips)
    acl = acl_compress(paths, args.tolerance, 3) if args.acl else None
    if acl:
        print(f"ACL 2.1 compress_track_list at {args.tolerance:g} cm: CPU {acl['acl_cpu_median']:.2f} s "
              f"(min {acl['acl_cpu_min']:.2f}, max {acl['acl_cpu_max']:.2f}, 3 passes), {acl['acl_mb_per_s']:.2f} MB/s raw")
    r = measure(paths, args.codec, args.tolerance, options, args.repeats)
    if acl:
        r.update(acl, of_acl=r["mb_per_s"] / acl["acl_mb_per_s"])
    print(f"{r['codec']} at {r['tolerance_cm']} cm, {len(r['clips'])} clips, raw {r['raw_acl_bytes']:,} B: "
          f"CPU {r['cpu_median']:.1f} s (min {r['cpu_min']:.1f}, max {r['cpu_max']:.1f}, {len(r['cpu_seconds'])} runs), "
          f"{r['mb_per_s']:.2f} MB/s raw, asset {r['asset_bytes']:,} B {','.join(r['asset_sha256_16'])}"
          + (f"; 1/{1 / r['of_acl']:.2f} of ACL's rate" if acl else ""))
    if args.json:
        with args.json.open("a") as f:
            f.write(json.dumps(r) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
