"""What an engine pays for each codec, beside ACL 2.1 measured in the same process.

    python bench/engine_bench.py                              # rma at 1 and 0.02 cm, the others at 1 cm
    python bench/engine_bench.py --assets rma:1,0.1 spline:1 --rounds 11
    make bench BENCH_ASSETS="rma:1 spline:1,0.02" ROUNDS=21

Per codec and tolerance: bytes on disk, bytes an engine holds, open time, and µs per full pose
for sequential playback, a game tick (8 instances of different clips at 60 Hz, each with its
own scratch or ACL context) and random access, each in local and world space, beside ACL's
figure from the same run and as a per-round ratio; plus ACL's compression throughput and
mocodec's own encode time.

Steps (every slow one is cached under ``bench/results/assets/``, git-ignored):

1. The clips are read with ``mocodec.io.read_bvh`` and dumped for the C++ driver
   (``bench/engine_bench.cpp``): per clip the nodes' parents, frame rate, local rotation and
   translation per frame as float32 (what ACL compresses) and the double-precision world
   position of every node (the error reference), so the driver needs no BVH reader.
2. One library asset per codec and tolerance: ``mocodec eval CLIPS --codec C --tolerance T``,
   keyed by codec, tolerance, clip set and a hash of the encoder's sources.
3. ACL: per clip, the precision with the fewest bytes whose max world error stays at or under
   each tolerance (the driver's ``tune``), kept per clip set and tolerance.
4. The timed run, under ``flock /tmp/mocodec-bench.lock``: ACL compresses at those precisions
   (throughput), then the driver interleaves ACL and mocodec in rounds (thread-CPU clock).
   Results: ``bench/results/engine_bench/<UTC time>.json`` and ``.md``, with the load average.

Without ``../shared/acl`` the ACL part is skipped, loudly, and mocodec's figures still print.
"""
from __future__ import annotations

import argparse
import datetime as dt
import hashlib
import json
import os
import platform
import resource
import shutil
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
sys.path.insert(0, str(REPO / "encoder"))

from mocodec import __version__ as ENCODER_VERSION  # noqa: E402
from mocodec.io import read_bvh  # noqa: E402
from mocodec.kinematics import world_positions  # noqa: E402
from mocodec.motion import Motion  # noqa: E402

# ../shared beside the checkout; MOCODEC_SHARED points elsewhere (a git worktree has none beside it).
SHARED = Path(os.environ.get("MOCODEC_SHARED", REPO.parent / "shared"))
DEV_SET = SHARED / "data" / "cmu"
SAMPLES = REPO / "encoder" / "mocodec" / "samples"
ACL_INCLUDES = [SHARED / "acl" / "acl-2.1.0" / "includes", SHARED / "acl" / "rtm-2.2.0" / "includes"]
RESULTS = HERE / "results" / "engine_bench"
CACHE = HERE / "results" / "assets"
BUILD = HERE / "results" / "build"
DRIVER_SOURCE = HERE / "engine_bench.cpp"
LOCK = "/tmp/mocodec-bench.lock"
# ACL's documented build; the mocodec runtime gets the same flags in the driver by default.
ACL_FLAGS = ["-O3", "-DNDEBUG", "-march=x86-64-v2"]
RUNTIME_DEFAULT_FLAGS = ["-O2"]  # runtime_c/Makefile's own optimisation level
DUMP_MAGIC = b"MCDBDUMP"
DUMP_VERSION = 1
DEFAULT_ASSETS = ["rma:1,0.02", "spline:1", "fk-wavelet:1", "ik-predict:1", "neural:1"]


# ------------------------------------------------------------------------------ the driver
def build_driver(runtime_flags: list[str] | None = None, acl: bool | None = None) -> Path:
    """Compile ``bench/engine_bench.cpp`` with the runtime sources; rebuilt when a source is newer.

    Parameters
    ----------
    runtime_flags : list of str, optional
        Optimisation flags for the mocodec runtime (default: ACL's, so both sides of a ratio
        are built alike). The driver itself always uses ACL's flags.
    acl : bool, optional
        Compile the ACL part (default: when ``../shared/acl`` is there).

    Returns
    -------
    Path
        The executable, under ``bench/results/build/`` (one per flag set).
    """
    runtime_flags = list(ACL_FLAGS if runtime_flags is None else runtime_flags)
    acl = all(p.is_dir() for p in ACL_INCLUDES) if acl is None else acl
    tag = hashlib.sha256(" ".join(runtime_flags + [str(acl)]).encode()).hexdigest()[:8]
    exe = BUILD / f"engine_bench_{'acl' if acl else 'noacl'}_{tag}"
    sources = sorted((REPO / "runtime_c" / "src").glob("*.c"))
    inputs = [DRIVER_SOURCE, *sources, *(REPO / "runtime_c" / "src").glob("*.h"),
              REPO / "runtime_c" / "include" / "mocodec.h"]
    if exe.exists() and all(p.stat().st_mtime <= exe.stat().st_mtime for p in inputs):
        return exe
    objdir = BUILD / f"runtime_{tag}"
    objdir.mkdir(parents=True, exist_ok=True)
    include = ["-I", str(REPO / "runtime_c" / "include")]
    objects = []
    for src in sources:
        obj = objdir / (src.stem + ".o")
        subprocess.run(["nice", "-n", "10", "cc", "-std=c99", *runtime_flags, *include, "-c", str(src), "-o", str(obj)],
                       check=True)
        objects.append(str(obj))
    acl_args = [a for p in ACL_INCLUDES for a in ("-isystem", str(p))] + ["-DMCD_BENCH_ACL=1"] if acl else []
    define = f'-DMCD_BENCH_RUNTIME_FLAGS="{" ".join(runtime_flags)}"'
    subprocess.run(["nice", "-n", "10", "c++", "-std=c++17", *ACL_FLAGS, "-Wall", "-Wextra", *include, *acl_args,
                    define, str(DRIVER_SOURCE), *objects, "-lm", "-o", str(exe)], check=True)
    return exe


def mocodec_speed(exe: Path, asset: Path, runs: int) -> dict:
    """µs per pose of one asset through the runtime alone (the driver's ``speed`` command):
    local and world, sequential and random, median of ``runs`` passes. Keys as
    ``us_per_pose_local_sequential``, plus ``asset_bytes``, ``resident_bytes``, ``scratch_bytes``."""
    r = subprocess.run([str(exe), "speed", str(asset), str(runs)], check=True, capture_output=True, text=True)
    return json.loads(r.stdout)


# --------------------------------------------------------------------------- cached inputs
def fingerprint(paths: list[Path], cm_per_unit: float) -> str:
    """Short hash of the clip set (names and bytes) and the unit scale."""
    h = hashlib.sha256(f"{cm_per_unit!r}".encode())
    for p in paths:
        h.update(p.name.encode() + b"\0" + hashlib.sha256(p.read_bytes()).digest())
    return h.hexdigest()[:10]


def source_key(files: list[Path]) -> str:
    """Short hash of some of the encoder's sources (names and bytes)."""
    h = hashlib.sha256(ENCODER_VERSION.encode())
    root = REPO / "encoder" / "mocodec"
    for p in sorted(files):
        h.update(str(p.relative_to(root)).encode() + b"\0" + p.read_bytes())
    return h.hexdigest()[:10]


def encoder_key() -> str:
    """Every Python source of the encoder: an asset is re-encoded when any of them changes."""
    return source_key(list((REPO / "encoder" / "mocodec").rglob("*.py")))


def reader_key() -> str:
    """What the clip dump (ACL's input and the error reference) depends on: the BVH reader and
    the motion model."""
    root = REPO / "encoder" / "mocodec"
    return source_key([*(root / "io").glob("*.py"), *(root / n for n in ("motion.py", "rotations.py", "kinematics.py"))])


def write_dump(motions: list[Motion], cm_per_unit: float, path: Path) -> None:
    """The clips as the driver reads them (little-endian; see ``read_dump`` in the driver)."""
    tmp = path.with_suffix(".tmp")
    with open(tmp, "wb") as f:
        f.write(DUMP_MAGIC + np.array([DUMP_VERSION, len(motions)], "<u4").tobytes()
                + np.array([cm_per_unit], "<f8").tobytes())
        for m in motions:
            sk = m.skeleton
            name = m.name.encode()
            f.write(np.array([len(name)], "<u4").tobytes() + name)
            f.write(np.array([sk.node_count, m.frame_count, sk.channel_count], "<u4").tobytes())
            f.write(np.array([m.frame_rate], "<f8").tobytes())
            f.write(sk.parents.astype("<i4").tobytes())
            f.write(np.concatenate([m.rotations, m.translations], axis=-1).astype("<f4").tobytes())
            f.write(world_positions(m).astype("<f8").tobytes())
    tmp.replace(path)


@dataclass
class Asset:
    """One mocodec library asset and how it was made."""

    codec: str
    tolerance_cm: float
    path: Path
    encode: dict  # the eval report's size/error/encode_seconds, and the encode process's CPU time

    @property
    def label(self) -> str:
        return f"{self.codec}:{self.tolerance_cm:g}"


def ensure_asset(codec: str, tol: float, paths: list[Path], cm_per_unit: float, data_key: str) -> Asset | str:
    """The cached asset for (codec, tolerance, clip set, encoder), encoded now if missing; or,
    when ``mocodec eval`` fails, its last line of error (the bench goes on without it)."""
    stem = f"{codec}_{tol:g}cm_{data_key}_{encoder_key()}"
    mcd, info = CACHE / f"{stem}.mcd", CACHE / f"{stem}.json"
    if not (mcd.exists() and info.exists()):
        CACHE.mkdir(parents=True, exist_ok=True)
        print(f"encoding {codec} at {tol:g} cm ({len(paths)} clips; cached as {mcd.name}) ...", file=sys.stderr)
        env = {**os.environ, "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
        cmd = ["nice", "-n", "10", str(REPO / ".venv" / "bin" / "mocodec"), "eval", *map(str, paths), "--codec", codec,
               "--tolerance", f"{tol:g}", "--cm-per-unit", f"{cm_per_unit:g}", "--json", "-o", str(mcd) + ".tmp"]
        load = uptime()
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        started = time.perf_counter()
        r = subprocess.run(cmd, capture_output=True, text=True, env=env)
        wall = time.perf_counter() - started
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        if r.returncode != 0:
            Path(str(mcd) + ".tmp").unlink(missing_ok=True)
            last = (r.stderr.strip().splitlines() or [f"exit status {r.returncode}"])[-1]
            print(f"engine_bench: WARNING: {codec} at {tol:g} cm left out: mocodec eval failed: {last}", file=sys.stderr)
            return last
        report = json.loads(r.stdout)
        record = {
            "codec": codec, "tolerance_cm": tol, "encoder": f"mocodec {ENCODER_VERSION}", "encoder_key": encoder_key(),
            "size": report["size"], "error": report["error"],
            "encode_seconds": report["encode_seconds"],  # mocodec's own figure: encode + its C error check
            "process_cpu_seconds": (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime),
            "process_wall_seconds": wall, "load_before": load, "date": now_utc(),
            "command": " ".join(cmd[3:]),
        }
        Path(str(mcd) + ".tmp").replace(mcd)
        info.write_text(json.dumps(record, indent=1))
    return Asset(codec, tol, mcd, json.loads(info.read_text()))


def ensure_acl_precisions(exe: Path, dump: Path, tol: float, dump_key: str, shell: float) -> Path:
    """Per clip ACL precisions for a max error of ``tol`` cm (the driver's ``tune``), cached."""
    out = CACHE / f"acl_{tol:g}cm_shell{shell:g}_{dump_key}.csv"
    if not out.exists():
        print(f"ACL: searching per clip precisions for max error <= {tol:g} cm (cached as {out.name}) ...",
              file=sys.stderr)
        tmp = out.with_suffix(".tmp")
        subprocess.run(["nice", "-n", "10", str(exe), "tune", str(dump), "--target-cm", f"{tol:g}",
                        "--shell", f"{shell:g}", "--out", str(tmp)], check=True)
        tmp.replace(out)
    return out


# ------------------------------------------------------------------------------- reporting
def uptime() -> str:
    return subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()


def now_utc() -> str:
    return dt.datetime.now(dt.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ")


def parse_assets(specs: list[str]) -> list[tuple[str, float]]:
    """``rma:1,0.02 spline:1`` -> [(rma, 1), (rma, 0.02), (spline, 1)]."""
    out = []
    for spec in specs:
        codec, sep, tols = spec.partition(":")
        if not sep or not codec or not tols:
            raise SystemExit(f"engine_bench: --assets {spec!r}: expected CODEC:TOL[,TOL...] (e.g. rma:1,0.02)")
        try:
            out += [(codec, float(t)) for t in tols.split(",")]
        except ValueError:
            raise SystemExit(f"engine_bench: --assets {spec!r}: tolerances must be numbers (cm)") from None
    return out


def _q(s: dict, digits: int = 3) -> str:
    """median (p25–p75) of a summary."""
    return f"{s['median']:.{digits}f} ({s['p25']:.{digits}f}–{s['p75']:.{digits}f})"


def _us(s: dict | None) -> str:
    if s is None:
        return "—"
    x = s["median"]
    return f"{x:.2f} µs" if x < 10 else f"{x:,.0f} µs" if x < 10000 else f"{x / 1000:,.1f} ms"


def _load(text: str) -> str:
    return text.split("load average:")[-1].strip()


def markdown(rep: dict) -> str:
    """The report's tables: sizes and engine bytes, open, decode, encode."""
    run, env = rep["run"], rep["environment"]
    acl = run["acl"]
    tick = run["tick"]
    fmt1 = run["runtime"]["format_major"] < 2
    acl_at = {t["target_cm"]: t for t in acl.get("targets", [])}
    L = [f"# engine_bench, {rep['date']}", "",
         f"{run['clips']} clips, {run['frames']:,} frames from `{rep['data']}` (cm = file units × {run['cm_per_unit']:g}). "
         f"mocodec runtime (format {run['runtime']['format_major']}) compiled with `{run['runtime']['cflags']}`"
         + (" like ACL" if run["runtime"]["cflags"] == " ".join(ACL_FLAGS) else f", ACL with `{' '.join(ACL_FLAGS)}`")
         + f" (the runtime's own Makefile uses `-O2`). CPU: {env['cpu']}; {env['compiler']}.",
         f"Load average before the timed run: {_load(env['load_before'])}; after: {_load(env['load_after'])}.", ""]
    if not acl["available"]:
        L += [f"**ACL 2.1 was not measured: {acl['reason']}.** mocodec's figures only.", ""]
    for label, why in rep.get("left_out", {}).items():
        L += [f"**`{label}` left out: `mocodec eval` failed: {why}**", ""]

    has_acl = acl["available"]
    L += ["## Size, and the bytes an engine holds", "",
          "Max error: world position of every joint and end site on every frame, measured here (double FK "
          "against the reference). Engine bytes: mocodec = asset"
          + (" + resident memory (format 1 decodes it at open)" if fmt1 else "") + " + one scratch per instance"
          + (f"; ACL = compressed bytes + one decompression context per instance ({acl['context_bytes']} B)"
             if has_acl else "")
          + f". One instance for sequential and random access, {tick['instances']} for the game tick."
          + (" ACL: per clip the precision with the fewest bytes at max error ≤ the tolerance." if has_acl else ""), ""]
    if has_acl:
        L += ["| asset | disk bytes | max cm | ACL bytes (max cm) | disk / ACL | engine, 1 instance | ACL | ratio "
              f"| engine, {tick['instances']} instances | ACL | ratio |", "|" + "---|" * 11]
    else:
        L += [f"| asset | disk bytes | max cm | engine, 1 instance | engine, {tick['instances']} instances |",
              "|---|---|---|---|---|"]
    for m in run["mcd"]:
        a = acl_at.get(m["tolerance_cm"])
        row = [f"`{m['label']}`", f"{m['asset_bytes']:,}", f"{m['max_cm']:.4f}"]
        if a:
            met = "" if a["all_met"] else f"; {run['clips'] - a['clips_met']} clip(s) cannot reach it"
            row += [f"{a['bytes']:,} ({a['max_cm']:.4f}{met})", f"{m['asset_bytes'] / a['bytes']:.3f}",
                    f"{m['engine_bytes_1']:,}", f"{a['engine_bytes_1']:,}", f"{m['engine_bytes_1'] / a['engine_bytes_1']:.2f}",
                    f"{m['engine_bytes_tick']:,}", f"{a['engine_bytes_tick']:,}",
                    f"{m['engine_bytes_tick'] / a['engine_bytes_tick']:.2f}"]
        elif has_acl:
            row += ["—", "—", f"{m['engine_bytes_1']:,}", "—", "—", f"{m['engine_bytes_tick']:,}", "—", "—"]
        else:
            row += [f"{m['engine_bytes_1']:,}", f"{m['engine_bytes_tick']:,}"]
        L.append("| " + " | ".join(row) + " |")
    checks = [f"`{m['label']}` {m['world_path_max_cm']:.4f}" for m in run["mcd"]]
    checks += [f"ACL {t['target_cm']:g} cm {t['world_path_max_cm']:.4f}" for t in acl.get("targets", [])]
    L += ["", "The timed world-space paths (float), checked against the reference at every frame, max cm: "
          + ", ".join(checks) + "."]

    L += ["", "## Open (whole library, warm caches)", "",
          "Thread-CPU time, median of the repetitions (each repeated until it takes ≥ 0.3 ms, so the clock's own "
          "cost drops out). "
          + ("ACL keeps no library object: its open is `make_compressed_tracks` + `context.initialize` for every "
             "clip (a header check), its full check `is_valid(true)` (hash) of every clip. " if has_acl else "")
          + "mocodec: `mcd_open` with its full check (CRC), with structural checks only "
          "(`MCD_VALIDATE_SKIP_CHECKSUM`), "
          + ("prevalidated: not in format 1" if fmt1 else "and prevalidated (`MCD_OPEN_PREVALIDATED`)")
          + "; per instance, `mcd_scratch_init`."
          + (" Format 1 also needs `mcd_resident_size` first, which validates too: see its column." if fmt1 else ""), "",
          "| subject | full check + open | open, structural checks | open, prevalidated | instance init |"
          + (" mcd_resident_size |" if fmt1 else ""), "|---|---|---|---|---|" + ("---|" if fmt1 else "")]
    for s in run["open"]:
        t = s["times_us"]
        if s["subject"] == "acl":
            full = {"median": t["validate"]["median"] + t["init"]["median"]}
            row = [f"ACL {s['target_cm']:g} cm", f"{_us(full)} (`is_valid(true)` + open)", "—",
                   f"{_us(t['init'])} (all {s['clips']} clips)", "(in open)"]
        else:
            row = [f"`{s['subject']}`", _us(t["open"]), _us(t["open_no_crc"]), _us(t.get("open_prevalidated")),
                   _us(t["scratch_init"])]
        if fmt1:
            row.append(_us(t.get("resident_size")))
        L.append("| " + " | ".join(row) + " |")

    L += ["", "## Decode, µs per full pose", "",
          f"Thread-CPU µs per pose, median (p25–p75) over {run['rounds']} rounds after a warm-up"
          + ("; ACL and mocodec passes interleaved, subject order rotated every round. Ratio = mocodec pass / ACL "
             "pass of the same round at the same tolerance, median (p25–p75)" if has_acl else "")
          + ". Sequential: every frame of every clip in order (one scratch; one "
          f"ACL context initialised per clip). Game tick: {tick['instances']} instances "
          + ("of different clips" if len(set(tick["clips"])) == len(tick["clips"])
             else "(fewer clips than instances: some share a clip)")
          + f" ({', '.join(tick['clips'])}) advanced by 1/{tick['hz']:g} s in turn, looping, {tick['ticks']:,} ticks, one "
          f"scratch or ACL context each. Random: as many uniform random times as frames per clip (seed "
          f"{run['seed']}, the same for every subject). Local: ACL `seek` + `decompress_tracks` (rotation, "
          "translation, scale) vs `mcd_sample` into `mcd_transform`. World: `mcd_sample` with `MCD_SAMPLE_WORLD` vs "
          "ACL's local decode then our own local-to-world (" + f"`{acl.get('world_compose', 'not measured')}`, "
          "parents first: what `MCD_SAMPLE_WORLD` composes).", "",
          "| asset | access | local µs | ACL local µs | local / ACL | world µs | ACL world µs | world / ACL |"
          if has_acl else "| asset | access | local µs | world µs |",
          "|---|---|---|---|---|---|---|---|" if has_acl else "|---|---|---|---|"]
    acl_speed = {s["tolerance_cm"]: s["modes"] for s in run["speed"] if s["subject"] == "acl"}
    access = [("seq", "sequential"), ("tick", "game tick"), ("random", "random")]
    for s in run["speed"]:
        if s["subject"] == "acl":
            continue
        ref = acl_speed.get(s["tolerance_cm"])
        for key, name in access:
            row = [f"`{s['subject']}`", name]
            for space in ("local", "world"):
                mine = s["modes"][f"{key}_{space}"]
                row.append(_q(mine["cpu_us"]))
                if ref:
                    row += [_q(ref[f"{key}_{space}"]["cpu_us"]), _q(mine["ratio"], 2)]
                elif has_acl:
                    row += ["—", "—"]
            L.append("| " + " | ".join(row) + " |")

    L += ["", "## Encode", ""]
    if acl["available"]:
        L += [f"ACL `compress_track_list` alone at the chosen precisions, one thread, thread-CPU seconds for the "
              f"whole set (median, min–max of {acl['compress_reps']} passes, this run). Raw: {run['raw_acl_bytes']:,} B "
              f"at 40 B per bone-sample (ACL's convention), {run['raw_bvh_bytes']:,} B of BVH float32 channels.", "",
              "| ACL at | CPU s | MB/s raw per core, ACL 40 B | MB/s raw per core, BVH float32 |", "|---|---|---|---|"]
        for t in acl["targets"]:
            c = t["compress_cpu_s"]
            L.append(f"| {t['target_cm']:g} cm | {c['median']:.2f} ({c['min']:.2f}–{c['max']:.2f}) | "
                     f"{run['raw_acl_bytes'] / c['median'] / 1e6:.1f} | {run['raw_bvh_bytes'] / c['median'] / 1e6:.2f} |")
        L.append("")
    L += ["mocodec's encoder is Python (numpy, one thread), run as `mocodec eval` when the asset was made (cached "
          "assets keep the figures of that run: see its date and load). `encode s`: mocodec's own wall-clock figure "
          "(encode and its error check through the C runtime); process CPU s: user + system time of the whole "
          "`mocodec eval` process (adds Python start-up and BVH reading; lower than the wall figure when the machine "
          "was busy). MB/s per CPU second of the process.", "",
          "| asset | encode s (wall) | process CPU s | MB/s raw, ACL 40 B | MB/s raw, BVH float32 | encoded | load then |",
          "|---|---|---|---|---|---|---|"]
    for a in rep["assets"]:
        e = a["encode"]
        cpu = e["process_cpu_seconds"]
        L.append(f"| `{a['label']}` | {e['encode_seconds']:.1f} | {cpu:.1f} | {run['raw_acl_bytes'] / cpu / 1e6:.2f} | "
                 f"{run['raw_bvh_bytes'] / cpu / 1e6:.3f} | {e['date']} | {_load(e['load_before'])} |")
    L += ["", f"Command: `{rep['command']}`"]
    return "\n".join(L) + "\n"


# ------------------------------------------------------------------------------------ main
def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", type=Path, default=None,
                    help="folder of BVH clips (default: ../shared/data/cmu, else the bundled samples)")
    ap.add_argument("--assets", nargs="+", default=DEFAULT_ASSETS, metavar="CODEC:TOL[,TOL]",
                    help=f"codecs and tolerances in cm (default: {' '.join(DEFAULT_ASSETS)})")
    ap.add_argument("--cm-per-unit", type=float, default=5.644)
    ap.add_argument("--rounds", type=int, default=11, help="timed rounds after the warm-up (default 11)")
    ap.add_argument("--shell", type=float, default=3.0, help="ACL shell distance, file units (default 3)")
    ap.add_argument("--runtime-flags", default=" ".join(ACL_FLAGS),
                    help="optimisation flags of the mocodec runtime in the driver (default: ACL's)")
    ap.add_argument("--no-acl", action="store_true", help="leave ACL out even when ../shared/acl is there")
    ap.add_argument("--encode-only", action="store_true", help="fill the asset cache and stop")
    ap.add_argument("--out", type=Path, default=RESULTS)
    args = ap.parse_args(argv)

    if args.data is None:
        args.data = DEV_SET if DEV_SET.is_dir() else SAMPLES
        if args.data == SAMPLES:
            print(f"engine_bench: WARNING: {DEV_SET} is absent; measuring the {len(list(SAMPLES.glob('*.bvh')))} "
                  "bundled sample clips instead (figures not comparable with the dev set's)", file=sys.stderr)
    paths = sorted(args.data.glob("*.bvh"))
    if not paths:
        print(f"engine_bench: no .bvh files in {args.data}", file=sys.stderr)
        return 1
    wanted = parse_assets(args.assets)
    data_key = fingerprint(paths, args.cm_per_unit)
    made = {(c, t): ensure_asset(c, t, paths, args.cm_per_unit, data_key) for c, t in wanted}
    assets = [a for a in made.values() if isinstance(a, Asset)]
    left_out = {f"{c}:{t:g}": why for (c, t), why in made.items() if isinstance(why, str)}
    if args.encode_only:
        return 0 if not left_out else 1
    if not assets:
        print("engine_bench: no asset to measure", file=sys.stderr)
        return 1

    acl_reason = ("--no-acl" if args.no_acl else
                  None if all(p.is_dir() for p in ACL_INCLUDES) else f"{ACL_INCLUDES[0].parent.parent} is absent")
    if acl_reason:
        print(f"engine_bench: WARNING: ACL 2.1 skipped ({acl_reason}); mocodec's figures only", file=sys.stderr)
    exe = build_driver(args.runtime_flags.split(), acl=acl_reason is None)
    CACHE.mkdir(parents=True, exist_ok=True)
    dump_key = f"{data_key}_{reader_key()}"  # the dump and ACL's precisions depend on the clips as read
    dump = CACHE / f"clips_{dump_key}.bin"
    if not dump.exists():
        for old in CACHE.glob(f"clips_{data_key}_*.bin"):  # 100 MB each for the dev set
            old.unlink()
        write_dump([read_bvh(p) for p in paths], args.cm_per_unit, dump)
    cmd = [str(exe), "run", str(dump), "--rounds", str(args.rounds)]
    if acl_reason is None:
        for tol in sorted({a.tolerance_cm for a in assets}, reverse=True):
            cmd += ["--acl", f"{tol:g}={ensure_acl_precisions(exe, dump, tol, dump_key, args.shell)}"]
    else:
        cmd += ["--no-acl", acl_reason]
    for a in assets:
        cmd += ["--mcd", f"{a.label}={a.path}"]
    args.out.mkdir(parents=True, exist_ok=True)
    stamp = dt.datetime.now(dt.timezone.utc).strftime("%Y-%m-%dT%H-%M-%SZ")
    raw = args.out / f"{stamp}.run.json"
    load_before = uptime()
    print(f"timing under flock {LOCK} ({args.rounds} rounds) ...", file=sys.stderr)
    subprocess.run(["flock", LOCK, *cmd, "--json", str(raw)], check=True)
    load_after = uptime()
    report = {
        "date": now_utc(), "data": str(args.data), "command": " ".join(["python", "bench/engine_bench.py", *(argv or sys.argv[1:])]),
        "environment": {"load_before": load_before, "load_after": load_after, "machine": platform.machine(),
                        "cpu": _cpu_model(), "compiler": _compiler()},
        "assets": [{"label": a.label, "codec": a.codec, "tolerance_cm": a.tolerance_cm, "file": a.path.name,
                    "encode": a.encode} for a in assets],
        "left_out": left_out,
        "run": json.loads(raw.read_text()),
    }
    raw.unlink()
    (args.out / f"{stamp}.json").write_text(json.dumps(report, indent=1))
    md = markdown(report)
    (args.out / f"{stamp}.md").write_text(md)
    print(md)
    print(f"wrote {args.out / stamp}.json and .md", file=sys.stderr)
    return 0


def _cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor()


def _compiler() -> str:
    cxx = shutil.which("c++")
    return subprocess.run([cxx, "--version"], capture_output=True, text=True).stdout.splitlines()[0] if cxx else "?"


if __name__ == "__main__":
    try:
        sys.exit(main())
    except subprocess.CalledProcessError as exc:  # the tool has said why on stderr already
        print(f"engine_bench: `{' '.join(map(str, exc.cmd[:5]))} ...` failed with exit status {exc.returncode}",
              file=sys.stderr)
        sys.exit(1)
