"""Baking the dev set on 1 and 2 local workers, on a Dask LocalCluster, and again from a cache
after one clip changed: wall and CPU time of each bake, whether the bytes match, and how busy
the machine was meanwhile (its other load makes these figures noisy on a shared machine).

    flock /tmp/mocodec-bench.lock nice -n 10 .venv/bin/python bench/bake_parallel.py \\
        [--data ../shared/data/cmu] [--tolerance 1] [--clips N] [--dask] [--json out.json]

CPU is this process's and its reaped children's (the --jobs workers), user + system; the Dask
workers' CPU is not counted (they are the cluster's processes). "others" is the CPU the rest of
the machine used during the bake, in cores: the load the figures were measured under.
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import os
import resource
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "encoder"))

from mocodec.bake import make_runner  # noqa: E402
from mocodec.encode import encode_motions  # noqa: E402
from mocodec.load import load_all  # noqa: E402
from mocodec.tolerance import Tolerance  # noqa: E402
from mocodec.units import resolve_library_units  # noqa: E402

TICK = os.sysconf("SC_CLK_TCK")


def _machine_busy() -> float:
    """Seconds of CPU the whole machine has used (all cores, not idle or iowait)."""
    with open("/proc/stat") as f:
        fields = [int(x) for x in f.readline().split()[1:]]
    return (sum(fields) - fields[3] - fields[4]) / TICK


def _own_cpu() -> float:
    me, kids = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return me.ru_utime + me.ru_stime + kids.ru_utime + kids.ru_stime


def bake(label: str, motions, units, tolerance: float, jobs=None, scheduler=None, cache=None) -> dict:
    busy0, cpu0, t0 = _machine_busy(), _own_cpu(), time.perf_counter()
    with make_runner(jobs, scheduler, cache) as runner:
        result = encode_motions(motions, units, "rma", Tolerance(tolerance), runner=runner)
    wall = time.perf_counter() - t0
    cpu = _own_cpu() - cpu0
    others = max(0.0, (_machine_busy() - busy0) - cpu) / wall
    row = {"bake": label, "wall_s": round(wall, 2), "cpu_s": round(cpu, 2), "others_cores": round(others, 2),
           "bytes": len(result.asset), "cached": sum(bool(c.stats.get("cached")) for c in result.clips),
           "load1": round(os.getloadavg()[0], 2)}
    print(f"  {label:<34} wall {wall:7.2f} s  cpu {cpu:7.2f} s  others {others:4.2f} cores  "
          f"{len(result.asset):,} B  cached {row['cached']}/{len(motions)}", flush=True)
    row["asset"] = result.asset
    return row


def changed_clip(m):
    """``m`` with its root turned a little over its second half: a clip edited by an artist."""
    rot = m.rotations.copy()
    rot[len(rot) // 2:, 0, 0] += 0.01
    rot[:, 0] /= np.linalg.norm(rot[:, 0], axis=-1, keepdims=True)
    return dataclasses.replace(m, rotations=rot)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", default=str(Path(os.environ.get("MOCODEC_SHARED", ROOT / ".." / "shared")) / "data" / "cmu"))
    ap.add_argument("--tolerance", type=float, default=1.0)
    ap.add_argument("--clips", type=int, default=None, help="only the first N clips (sorted by name)")
    ap.add_argument("--dask", action="store_true", help="also bake on a LocalCluster of 2 worker processes")
    ap.add_argument("--no-cache", action="store_true", help="skip the incremental re-bake")
    ap.add_argument("--json", help="write the figures here")
    args = ap.parse_args()
    paths = sorted(Path(args.data).glob("*.bvh"))[:args.clips]
    if not paths:
        print(f"no BVH clips in {args.data}", file=sys.stderr)
        return 1
    motions = load_all(paths)
    units = resolve_library_units(motions, "cmu", None)
    frames = sum(m.frame_count for m in motions)
    print(f"{len(motions)} clips, {frames:,} frames, tolerance {args.tolerance} cm, {os.cpu_count()} cores, "
          f"load {os.getloadavg()[0]:.2f} at the start")
    cache = tempfile.TemporaryDirectory()
    # The --jobs 2 bake fills the cache (writing it costs milliseconds): the incremental re-bake's start.
    rows = [bake("--jobs 1", motions, units, args.tolerance, jobs=1),
            bake("--jobs 2 (filling --cache)", motions, units, args.tolerance, jobs=2, cache=cache.name)]
    same = rows[0]["asset"] == rows[1]["asset"]
    print(f"  --jobs 1 and --jobs 2 give the same bytes: {same}; speed-up {rows[0]['wall_s'] / rows[1]['wall_s']:.2f}x wall")
    if args.dask:
        from distributed import LocalCluster

        with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0") as c:
            rows.append(bake("--scheduler (LocalCluster, 2 workers)", motions, units, args.tolerance,
                             scheduler=c.scheduler_address))
        same_dask = rows[-1]["asset"] == rows[0]["asset"]
        print(f"  LocalCluster gives the serial bytes: {same_dask}")
    if not args.no_cache:
        edited = [changed_clip(motions[0])] + motions[1:]
        rows.append(bake(f"--jobs 2 --cache, {motions[0].name} changed", edited, units, args.tolerance,
                         jobs=2, cache=cache.name))
        rows.append(bake(f"--jobs 2 clean bake, {motions[0].name} changed", edited, units, args.tolerance, jobs=2))
        print(f"  incremental bake gives the clean bake's bytes: {rows[-2]['asset'] == rows[-1]['asset']}; "
              f"{rows[-2]['wall_s']:.2f} s against {rows[-1]['wall_s']:.2f} s for the full bake "
              f"({motions[0].name}: {motions[0].frame_count} frames)")
    cache.cleanup()
    if args.json:
        Path(args.json).write_text(json.dumps([{k: v for k, v in r.items() if k != "asset"} for r in rows], indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
