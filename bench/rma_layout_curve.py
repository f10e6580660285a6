"""Where `rma`'s size and speed pull apart: bytes against µs per pose over its layout choices.

    python bench/rma_layout_curve.py                     # dev set, 1 and 0.02 cm, every choice
    python bench/rma_layout_curve.py --tolerances 1 --rounds 9

The writer codes each track's keys in blocks of ``block_keys`` keys (32 by default) and puts
keys on cells of ``key_grid`` frames (4 at 0.25 cm and up, else 1); docs/FORMAT.md, RMAL
version 4. A block costs a row (its first key whole, where its codes start, their Rice
parameters), so smaller blocks take more bytes, but a random access decodes half a block on
average; keys on a coarser grid of cells need more keys but have more regular gaps. This
bench encodes the dev set as one library once per choice (``mocodec eval -O ...``, cached in
``bench/results/assets/``), then times every asset through the runtime in rounds, the subject
order rotated every round (the driver of ``bench/engine_bench.py``, built like ACL), and
reports disk bytes, max error and µs per local pose (median of the rounds' medians, and the
spread): sequential playback and random access. ACL is not run here: ``engine_bench.py`` puts
the chosen default beside it.

Writes ``bench/results/rma_layout_curve.json`` and ``.md`` (``--out`` for other names).
"""
from __future__ import annotations

import argparse
import fcntl
import json
import os
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
from engine_bench import (CACHE, DEV_SET, LOCK, REPO, build_driver, encoder_key, fingerprint,  # noqa: E402
                          mocodec_speed, now_utc, uptime)

CMU_CM_PER_UNIT = 5.644  # the dev set's BVH units (engine_bench's --cm-per-unit default)


@dataclass(frozen=True)
class Choice:
    """One layout choice: ``mocodec eval`` options and how the table names it."""

    label: str
    options: tuple[str, ...]  # KEY=VALUE for -O; empty: the encoder's defaults


def choices(tol: float) -> list[Choice]:
    """The defaults, each other block size 4 ... 64 keys, and (where the default cells are 4
    frames) cells of 1, 2 and 8 frames."""
    out = [Choice("default", ())]
    out += [Choice(f"blocks of {n}", (f"block_keys={n}",)) for n in (4, 8, 16, 64)]
    if tol >= 0.25:
        out += [Choice(f"cells of {g}", (f"key_grid={g}",)) for g in (1, 2, 8)]
    return out


def encode(choice: Choice, tol: float, paths: list[Path], data_key: str) -> tuple[Path, dict]:
    """The cached library asset of ``choice`` at ``tol`` cm and its ``mocodec eval`` report."""
    tag = "_".join(o.replace("=", "") for o in choice.options) or "default"
    stem = f"curve_rma_{tag}_{tol:g}cm_{data_key}_{encoder_key()}"
    mcd, info = CACHE / f"{stem}.mcd", CACHE / f"{stem}.json"
    if not (mcd.exists() and info.exists()):
        CACHE.mkdir(parents=True, exist_ok=True)
        print(f"encoding rma {choice.label} at {tol:g} cm ...", file=sys.stderr, flush=True)
        env = {**os.environ, "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
        cmd = [sys.executable, "-m", "mocodec", "eval", *map(str, paths), "--codec", "rma", "--tolerance", f"{tol:g}",
               "--cm-per-unit", f"{CMU_CM_PER_UNIT:g}", "--json", "-q", "-o", str(mcd) + ".tmp"]
        for o in choice.options:
            cmd += ["-O", o]
        started = time.perf_counter()
        r = subprocess.run(["nice", "-n", "10", *cmd], capture_output=True, text=True, env=env,
                           cwd=REPO / "encoder")
        if r.returncode != 0:
            Path(str(mcd) + ".tmp").unlink(missing_ok=True)
            last = (r.stderr.strip().splitlines() or [f"exit status {r.returncode}"])[-1]
            raise SystemExit(f"rma_layout_curve: {choice.label} at {tol:g} cm: mocodec eval failed: {last}")
        report = json.loads(r.stdout)
        report["wall_seconds"] = time.perf_counter() - started
        Path(str(mcd) + ".tmp").replace(mcd)
        info.write_text(json.dumps(report, indent=1))
    return mcd, json.loads(info.read_text())


def spread(values: list[float]) -> dict:
    a = np.asarray(values)
    return {"median": float(np.median(a)), "p25": float(np.percentile(a, 25)), "p75": float(np.percentile(a, 75))}


def table(rows: list[dict]) -> list[str]:
    L = ["| tolerance | layout | disk bytes | vs default | max cm | seq µs/pose | random µs/pose | random vs default |",
         "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        d = next(x for x in rows if x["tolerance_cm"] == r["tolerance_cm"] and x["label"] == "default")
        seq, rnd = r["local_sequential"], r["local_random"]
        L.append(f"| {r['tolerance_cm']:g} cm | {r['label']} | {r['bytes']:,} | {r['bytes'] / d['bytes']:.3f} | "
                 f"{r['max_cm']:.4f} | {seq['median']:.3f} ({seq['p25']:.3f}–{seq['p75']:.3f}) | "
                 f"{rnd['median']:.3f} ({rnd['p25']:.3f}–{rnd['p75']:.3f}) | "
                 f"{rnd['median'] / d['local_random']['median']:.3f} |")
    return L


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--cmu", type=Path, default=DEV_SET, help="folder of the dev set's BVH files")
    ap.add_argument("--tolerances", type=float, nargs="+", default=[1.0, 0.02], metavar="CM")
    ap.add_argument("--rounds", type=int, default=5, help="timed rounds (each times every asset once)")
    ap.add_argument("--runs", type=int, default=5, help="passes per asset per round (the driver's median)")
    ap.add_argument("--encode-only", action="store_true", help="fill the asset cache and stop")
    ap.add_argument("--out", type=Path, default=HERE / "results" / "rma_layout_curve", help="stem of .json/.md")
    args = ap.parse_args()
    paths = sorted(args.cmu.glob("*.bvh"))
    if not paths:
        raise SystemExit(f"rma_layout_curve: no .bvh files in {args.cmu} (set MOCODEC_SHARED or --cmu)")
    data_key = fingerprint(paths, CMU_CM_PER_UNIT)
    subjects = []
    for tol in args.tolerances:
        for c in choices(tol):
            mcd, report = encode(c, tol, paths, data_key)
            subjects.append({"tolerance_cm": tol, "label": c.label, "options": list(c.options), "asset": mcd,
                             "bytes": mcd.stat().st_size, "max_cm": float(report["error"]["max_cm"])})
    if args.encode_only:
        return
    if args.rounds < 1 or args.runs < 1:
        raise SystemExit("rma_layout_curve: --rounds and --runs must be at least 1")
    exe = build_driver()
    times: dict[int, dict[str, list[float]]] = {i: {"local_sequential": [], "local_random": []}
                                                 for i in range(len(subjects))}
    load_before = uptime()
    with open(LOCK, "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        for rnd in range(args.rounds):
            order = list(range(len(subjects)))
            order = order[rnd % len(order):] + order[:rnd % len(order)]
            for i in order:
                s = mocodec_speed(exe, subjects[i]["asset"], args.runs)
                for mode in times[i]:
                    times[i][mode].append(s[f"us_per_pose_{mode}"])
            print(f"round {rnd + 1}/{args.rounds} done", file=sys.stderr, flush=True)
    load_after = uptime()
    rows = []
    for i, s in enumerate(subjects):
        rows.append({**{k: v for k, v in s.items() if k != "asset"}, "asset": s["asset"].name,
                     **{m: spread(v) for m, v in times[i].items()}})
    cpu = next((ln.split(":", 1)[1].strip() for ln in open("/proc/cpuinfo") if ln.startswith("model name")), "?")
    rep = {"date": now_utc(), "cpu": cpu, "load_before": load_before, "load_after": load_after,
           "rounds": args.rounds, "runs": args.runs, "clips": len(paths), "rows": rows,
           "command": "python bench/rma_layout_curve.py " + " ".join(sys.argv[1:])}
    args.out.with_suffix(".json").write_text(json.dumps(rep, indent=1))
    md = [f"# rma layout choices: bytes against µs per pose ({rep['date']})", "",
          f"{len(paths)} dev clips as one library; runtime built like ACL (-O3 -DNDEBUG -march=x86-64-v2); "
          f"µs per local pose, median (p25–p75) over {args.rounds} rounds of {args.runs} passes, subjects rotated "
          f"every round. CPU: {cpu}. Load before: {load_before}; after: {load_after}.", "", *table(rows), "",
          f"Command: `{rep['command']}`"]
    args.out.with_suffix(".md").write_text("\n".join(md) + "\n")
    print("\n".join(md))


if __name__ == "__main__":
    main()
