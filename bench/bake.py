"""Baking a library, measured: the encoder's rate per core for each codec, the speed-up of 1 and
2 workers (local processes and a Dask LocalCluster), an incremental re-bake from --cache after
one clip changed, and the peak memory and time of a 2,000-clip library.

    nice -n 10 .venv/bin/python bench/bake.py [--data ../shared/data/cmu] [--tolerance 1]
        [--parts codecs speedup incremental library] [--codecs rma spline ...] [--codec-clips 4]
        [--clips N] [--library-clips 2000] [--clip-seconds 2] [--fast] [--json out.json]

Each timed part holds ``flock /tmp/mocodec-bench.lock`` (one timed run on the machine at a
time) and reports the load it ran under. ``--fast`` is the iteration setting: few clips, a
short library.

* codecs: ``bench/encode_throughput.py``'s measure, one core, this process: MB/s of raw input
  in ACL's convention (40 B per bone-sample) and of the BVH float32 channels, per CPU second.
* speedup: wall and CPU of the dev set baked with --jobs 1, --jobs 2 and on a LocalCluster of
  2 worker processes; the assets must be the same bytes. CPU counts this process and its
  reaped children (the --jobs workers), not the cluster's processes.
* incremental: the --jobs 2 bake filled a cache; one clip is changed and the library baked
  again from the cache, against a clean bake of the changed library (same bytes).
* library: a library made here from the dev clips (never committed): ``--library-clips``
  windows of ``--clip-seconds`` cut from the clips at spread start times, every other one
  played backwards, written as BVH files to a temporary folder; ``mocodec encode`` bakes the
  folder in a child process with --jobs 2. Peak memory: sampled every 0.2 s as the sum of the
  resident sets of the bake and its workers, and bounded from the bake's own report (its peak
  plus workers times the largest worker's peak, ``getrusage``).
"""
from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # one core means one core: BLAS, here and in the workers

import argparse
import contextlib
import dataclasses
import fcntl
import json
import resource
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Iterator

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "encoder"))
sys.path.insert(0, str(ROOT / "bench"))

from encode_throughput import measure, pick  # noqa: E402
from mocodec.bake import make_runner  # noqa: E402
from mocodec.bake.library import motion_bytes  # noqa: E402
from mocodec.io import read_bvh  # noqa: E402
from mocodec.encode import encode_motions  # noqa: E402
from mocodec.load import load_all  # noqa: E402
from mocodec.metrics import raw_bvh_bytes  # noqa: E402
from mocodec.tolerance import Tolerance  # noqa: E402
from mocodec.units import resolve_library_units  # noqa: E402

LOCK = "/tmp/mocodec-bench.lock"
TICK = os.sysconf("SC_CLK_TCK")
PAGE = os.sysconf("SC_PAGE_SIZE")
PARTS = ("codecs", "speedup", "incremental", "library")
NO_LOCK = False


@contextlib.contextmanager
def bench_lock() -> Iterator[None]:
    """The machine's one timed run at a time (what ``flock /tmp/mocodec-bench.lock`` takes;
    not with ``--no-lock``, for trying the bench out: its figures are not for the record)."""
    if NO_LOCK:
        yield
        return
    with open(LOCK, "a") as f:
        fcntl.flock(f, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(f, fcntl.LOCK_UN)


def _machine_busy() -> float:
    """Seconds of CPU the whole machine has used (all cores, not idle or iowait)."""
    with open("/proc/stat") as f:
        fields = [int(x) for x in f.readline().split()[1:]]
    return (sum(fields) - fields[3] - fields[4]) / TICK


def _own_cpu() -> float:
    me, kids = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return me.ru_utime + me.ru_stime + kids.ru_utime + kids.ru_stime


def _load() -> str:
    return " ".join(f"{x:.2f}" for x in os.getloadavg())


def _autogroup() -> str:
    """Linux's per-session scheduling groups: while on, other sessions' work gets its share of
    the cores however `nice` it is, so a worker speed-up is measured against it."""
    try:
        return {"0": "off", "1": "on"}.get(Path("/proc/sys/kernel/sched_autogroup_enabled").read_text().strip(), "?")
    except OSError:
        return "n/a"


# ----------------------------------------------------------------------------- codecs
def part_codecs(paths: list[Path], codecs: list[str], tolerance: float, clips: int) -> list[dict]:
    """MB/s per core of each codec on ``clips`` of the dev clips."""
    chosen = pick(paths, clips)
    bvh_raw = sum(raw_bvh_bytes(m) for m in load_all(chosen))
    print(f"codecs: {len(chosen)} clips ({', '.join(p.stem for p in chosen)}), one core, tolerance {tolerance} cm")
    rows = []
    for codec in codecs:
        with bench_lock():
            load = _load()
            r = measure(chosen, codec, tolerance, {}, 1)
        r["bvh_mb_per_s"] = bvh_raw / r["cpu_median"] / 1e6
        r["load"] = load
        rows.append(r)
        print(f"  {codec:<11} CPU {r['cpu_median']:7.1f} s  {r['mb_per_s']:6.2f} MB/s raw (ACL 40 B)  "
              f"{r['bvh_mb_per_s']:6.2f} MB/s BVH float32  asset {r['asset_bytes']:,} B  load {load}", flush=True)
    return rows


# ----------------------------------------------------------------------------- speed-up and cache
def bake(label: str, motions, units, tolerance: float, jobs=None, scheduler=None, cache=None) -> dict:
    """One timed bake of ``motions`` with codec rma: wall, CPU, the machine's other load."""
    with bench_lock():
        load = _load()
        busy0, cpu0, t0 = _machine_busy(), _own_cpu(), time.perf_counter()
        with make_runner(jobs, scheduler, cache) as runner:
            result = encode_motions(motions, units, "rma", Tolerance(tolerance), runner=runner)
        wall = time.perf_counter() - t0
        cpu = _own_cpu() - cpu0
        others = max(0.0, (_machine_busy() - busy0) - cpu) / wall
    raw = result.size.raw_acl_bytes
    row = {"bake": label, "wall_s": round(wall, 2), "cpu_s": round(cpu, 2), "others_cores": round(others, 2),
           "mb_per_s_wall": round(raw / wall / 1e6, 3), "bytes": len(result.asset),
           "cached": sum(bool(c.stats.get("cached")) for c in result.clips), "load": load}
    print(f"  {label:<40} wall {wall:7.2f} s  cpu {cpu:7.2f} s  {row['mb_per_s_wall']:5.2f} MB/s  others "
          f"{others:4.2f} cores  {len(result.asset):,} B  cached {row['cached']}/{len(motions)}  load {load}",
          flush=True)
    row["asset"] = result.asset
    return row


def changed_clip(m):
    """``m`` with its root turned a little over its second half: a clip edited by an artist."""
    rot = m.rotations.copy()
    rot[len(rot) // 2:, 0, 0] += 0.01
    rot[:, 0] /= np.linalg.norm(rot[:, 0], axis=-1, keepdims=True)
    return dataclasses.replace(m, rotations=rot)


def part_speedup(paths: list[Path], tolerance: float, incremental: bool, dask: bool) -> tuple[list[dict], dict]:
    motions = load_all(paths)
    units = resolve_library_units(motions, "cmu", None)
    frames = sum(m.frame_count for m in motions)
    print(f"speedup: {len(motions)} clips, {frames:,} frames, tolerance {tolerance} cm, {os.cpu_count()} cores")
    checks: dict = {}
    with tempfile.TemporaryDirectory() as cache:
        # The --jobs 2 bake fills the cache (writing it costs milliseconds): the re-bake's start.
        rows = [bake("--jobs 1", motions, units, tolerance, jobs=1),
                bake("--jobs 2 (filling --cache)", motions, units, tolerance, jobs=2, cache=cache)]
        checks["jobs_same_bytes"] = rows[0]["asset"] == rows[1]["asset"]
        checks["speedup_jobs2"] = round(rows[0]["wall_s"] / rows[1]["wall_s"], 2)
        print(f"  --jobs 2: same bytes {checks['jobs_same_bytes']}, speed-up {checks['speedup_jobs2']:.2f}x wall")
        if dask:
            from distributed import LocalCluster

            for workers in (1, 2):
                with LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                  dashboard_address=":0") as c:
                    rows.append(bake(f"--scheduler (LocalCluster, {workers} worker{'s' * (workers > 1)})",
                                     motions, units, tolerance, scheduler=c.scheduler_address))
                checks[f"dask{workers}_same_bytes"] = rows[-1]["asset"] == rows[0]["asset"]
            checks["speedup_dask2"] = round(rows[-2]["wall_s"] / rows[-1]["wall_s"], 2)
            print(f"  LocalCluster: same bytes {checks['dask1_same_bytes']} / {checks['dask2_same_bytes']}, "
                  f"2 workers against 1: {checks['speedup_dask2']:.2f}x wall")
        if incremental:
            edited = [changed_clip(motions[0])] + motions[1:]
            rows.append(bake(f"--jobs 2 --cache, {motions[0].name} changed", edited, units, tolerance,
                             jobs=2, cache=cache))
            rows.append(bake(f"--jobs 2 clean bake, {motions[0].name} changed", edited, units, tolerance, jobs=2))
            checks["incremental_same_bytes"] = rows[-2]["asset"] == rows[-1]["asset"]
            print(f"  incremental: same bytes as the clean bake {checks['incremental_same_bytes']}; "
                  f"{rows[-2]['wall_s']:.2f} s against {rows[-1]['wall_s']:.2f} s "
                  f"({motions[0].name}: {motions[0].frame_count} frames)")
    return [{k: v for k, v in r.items() if k != "asset"} for r in rows], checks


# ----------------------------------------------------------------------------- a large library
def _bvh_parts(text: str) -> tuple[str, float, list[str]]:
    """(hierarchy up to and with ``MOTION``, frame time, the frame lines) of a BVH file."""
    head, _, motion = text.partition("\nMOTION")
    lines = motion.strip("\n").splitlines()
    frames = int(lines[0].split(":")[1])
    frame_time = float(lines[1].split(":")[1])
    return head + "\nMOTION\n", frame_time, lines[2:2 + frames]


def write_library(paths: list[Path], count: int, seconds: float, folder: Path) -> dict:
    """``count`` BVH files of ``seconds`` each, cut from ``paths`` at start times spread over
    every clip long enough, every other one played backwards (its frames' lines reversed: the
    values stay the file's own)."""
    clips = [(p.stem, *_bvh_parts(p.read_text())) for p in paths]
    windows = []  # (clip, first frame, frames)
    for k, (_, _, frame_time, lines) in enumerate(clips):
        n = int(round(seconds / frame_time))
        if len(lines) >= n:
            windows += [(k, start, n) for start in range(0, len(lines) - n + 1, max(1, n // 8))]
    if not windows:
        raise SystemExit(f"no clip lasts {seconds} s")
    chosen = [windows[int(i * len(windows) / count) % len(windows)] for i in range(count)]
    frames, whole = 0, 0.0
    per_frame = [motion_bytes(read_bvh(p)) / max(1, len(c[3])) for p, c in zip(paths, clips)]
    for i, (k, start, n) in enumerate(chosen):
        stem, head, frame_time, lines = clips[k]
        body = lines[start:start + n]
        if i % 2:
            body = body[::-1]
        (folder / f"{i:05d}_{stem}_{start}{'_rev' if i % 2 else ''}.bvh").write_text(
            f"{head}Frames: {n}\nFrame Time: {frame_time:.7f}\n" + "\n".join(body) + "\n")
        frames += n
        whole += per_frame[k] * n
    return {"clips": count, "clip_seconds": seconds, "frames": frames, "windows_available": len(windows),
            "motions_held_whole_mb": round(whole / 1e6, 1)}


def _tree_rss(pid: int) -> int:
    """Resident bytes of ``pid`` and all its descendants."""
    total, unvisited = 0, [pid]
    while unvisited:
        p = unvisited.pop()
        try:
            with open(f"/proc/{p}/statm") as f:
                total += int(f.read().split()[1]) * PAGE
            for task in os.listdir(f"/proc/{p}/task"):
                with open(f"/proc/{p}/task/{task}/children") as f:
                    unvisited += [int(c) for c in f.read().split()]
        except (OSError, ValueError):
            continue
    return total


def part_library(paths: list[Path], count: int, seconds: float, tolerance: float, jobs: int, codec: str) -> dict:
    with tempfile.TemporaryDirectory(prefix="mocodec-library-") as tmp:
        folder = Path(tmp) / "clips"
        folder.mkdir()
        made = write_library(paths, count, seconds, folder)
        size = sum(f.stat().st_size for f in folder.iterdir())
        print(f"library: {made['clips']} clips of {seconds} s ({made['frames']:,} frames, {size / 1e6:.0f} MB of BVH; "
              f"cut from {len(paths)} dev clips, every other one backwards; held whole its motions alone would take "
              f"{made['motions_held_whole_mb']:.0f} MB), codec {codec}, --jobs {jobs}, "
              f"tolerance {tolerance} cm",
              flush=True)
        out = Path(tmp) / "library.mcd"
        cmd = [sys.executable, "-m", "mocodec", "encode", str(folder), "-o", str(out), "--units", "cmu",
               "--codec", codec, "-t", str(tolerance), "--jobs", str(jobs), "--json"]
        with bench_lock():
            load = _load()
            busy0, t0 = _machine_busy(), time.perf_counter()
            p = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
            peak = [0]
            stop = threading.Event()

            def sample() -> None:
                while not stop.wait(0.2):
                    peak[0] = max(peak[0], _tree_rss(p.pid))

            sampler = threading.Thread(target=sample, daemon=True)
            sampler.start()
            stdout, stderr = p.communicate()
            stop.set()
            sampler.join()
            wall = time.perf_counter() - t0
            cpu_children = resource.getrusage(resource.RUSAGE_CHILDREN)
            machine = (_machine_busy() - busy0) / wall
        if p.returncode != 0:
            raise SystemExit(f"the library bake failed: {stderr.strip()}")
        summary = json.loads(stdout)["bake"]
        rss = summary["peak_rss_mb"]
        bound = rss["main"] + jobs * rss["largest_worker"]
        row = {**made, "bvh_bytes": size, "codec": codec, "jobs": jobs, "wall_s": round(wall, 1), "load": load,
               "machine_busy_cores": round(machine, 2), "asset_bytes": out.stat().st_size,
               "peak_rss_sampled_mb": round(peak[0] / 1e6, 1), "peak_rss_bound_mb": round(bound, 1),
               "children_cpu_s": round(cpu_children.ru_utime + cpu_children.ru_stime, 1), "summary": summary}
    print(f"  wall {wall:.1f} s  peak RSS {row['peak_rss_sampled_mb']:.0f} MB sampled (bake + workers), "
          f"<= {bound:.0f} MB bound (main {rss['main']:.0f} + {jobs} x largest worker {rss['largest_worker']:.0f})  "
          f"asset {row['asset_bytes']:,} B  {summary['mb_per_s']:.2f} MB/s raw  max error "
          f"{summary['error'][codec]['max_cm']:.3f} cm  load {load}", flush=True)
    return row


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", type=Path,
                    default=Path(os.environ.get("MOCODEC_SHARED", ROOT / ".." / "shared")) / "data" / "cmu")
    ap.add_argument("--tolerance", type=float, default=1.0)
    ap.add_argument("--parts", nargs="+", choices=PARTS, default=list(PARTS))
    ap.add_argument("--codecs", nargs="+", default=["rma", "spline", "fk-wavelet", "ik-predict", "neural", "rma-pca"])
    ap.add_argument("--codec-clips", type=int, default=4, help="clips each codec encodes (spread over the dev set)")
    ap.add_argument("--clips", type=int, default=None, help="the speed-up and cache parts: only the first N clips")
    ap.add_argument("--no-dask", action="store_true", help="skip the LocalCluster bakes")
    ap.add_argument("--library-clips", type=int, default=2000)
    ap.add_argument("--clip-seconds", type=float, default=2.0, help="length of each clip of the large library")
    ap.add_argument("--library-jobs", type=int, default=2)
    ap.add_argument("--library-codec", default="rma")
    ap.add_argument("--fast", action="store_true",
                    help="iterate: 2 codec clips, 4 clips for speed-up and cache, a 40-clip library")
    ap.add_argument("--no-lock", action="store_true", help="do not wait for the benchmark lock (a trial run)")
    ap.add_argument("--json", type=Path, help="write every figure here")
    args = ap.parse_args(argv)
    global NO_LOCK
    NO_LOCK = args.no_lock
    if args.fast:
        args.codec_clips, args.clips, args.library_clips = 2, args.clips or 4, 40
    paths = sorted(args.data.glob("*.bvh"))
    if not paths:
        print(f"no BVH clips in {args.data}", file=sys.stderr)
        return 1
    print(f"mocodec bake bench {time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime())}, {os.cpu_count()} cores, "
          f"load {_load()} at the start, autogroup {_autogroup()}", flush=True)
    report: dict = {"date": time.strftime("%Y-%m-%dT%H:%MZ", time.gmtime()), "cores": os.cpu_count(),
                    "autogroup": _autogroup(), "tolerance_cm": args.tolerance, "args": vars(args) | {"data": str(args.data), "json": str(args.json)}}
    if "codecs" in args.parts:
        report["codecs"] = part_codecs(paths, args.codecs, args.tolerance, args.codec_clips)
    if "speedup" in args.parts or "incremental" in args.parts:
        rows, checks = part_speedup(paths[:args.clips], args.tolerance, "incremental" in args.parts,
                                    not args.no_dask and "speedup" in args.parts)
        report["bakes"], report["checks"] = rows, checks
    if "library" in args.parts:
        report["library"] = part_library(paths, args.library_clips, args.clip_seconds, args.tolerance,
                                         args.library_jobs, args.library_codec)
    if args.json:
        args.json.write_text(json.dumps(report, indent=2, default=str))
    failed = [k for k, v in report.get("checks", {}).items() if v is False]
    if failed:
        print(f"bake bench: assets differ: {', '.join(failed)}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
