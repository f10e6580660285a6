"""Encoding one long capture: the dev clips joined end to end (and again from the first when
they run out) into one clip of a given length at 120 Hz, encoded per codec; prints and writes
the encode CPU and wall time, the peak memory against the raw float32 channels (issue 16 asks
at most 4x), the asset's bytes and the error through the C runtime, or the reason it failed.

    python bench/long_clip.py                              # 20 minutes, rma and spline
    python bench/long_clip.py --minutes 120 --codecs rma   # the 2-hour case
    python bench/long_clip.py --codecs rma --via-bvh /tmp/long.bvh   # through a BVH file and the CLI

Each codec runs in its own process; its peak memory includes the interpreter and libraries
(about 40 MB) and the dev clips' channels the motion is built from (38 MB), so short runs
overstate the ratio. Run one at a time on a
shared machine; the times are not a speed benchmark (no lock, no repeats).
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
sys.path.insert(0, str(REPO / "encoder"))


def joined_motion(folder: Path, frames: int):
    """The BVH clips of ``folder`` (one skeleton layout) joined into one motion of ``frames``."""
    import numpy as np

    from mocodec.io import read_bvh
    from mocodec.motion import Motion

    paths = sorted(folder.glob("*.bvh"))
    if not paths:
        raise SystemExit(f"{folder}: no BVH clips (the dev set is ../shared/data/cmu)")
    first = read_bvh(paths[0])
    # Only each clip's channels are kept (not its motion), so the peak is the encode's own.
    sources = [first.source_channels] + [read_bvh(p).source_channels for p in paths[1:]]
    channels, count, k = [], 0, 0
    while count < frames:
        part = sources[k % len(sources)][: frames - count]
        channels.append(part)
        count += len(part)
        k += 1
    del sources
    return Motion.from_channels(first.skeleton, np.concatenate(channels), first.frame_time,
                                f"joined_{frames}")


def run_cli(codec: str, bvh: Path, frames: int, channels: int, tolerance: float) -> dict:
    # (``frames`` and ``channels``: the file's, as the parent wrote it, for the raw size)
    """``mocodec encode`` of the joined clip written as a BVH file: the whole path a user takes
    (the file read, its clip kept by the library, encoded, measured), in this process."""
    import contextlib
    import io
    import tempfile

    from mocodec.cli import _peak_rss_kib
    from mocodec.cli import main as cli

    raw = frames * channels * 4
    row = {"codec": codec, "via": "mocodec encode FILE.bvh", "bvh_bytes": bvh.stat().st_size, "frames": frames,
           "minutes": frames / 120 / 60, "raw_float32_bytes": raw}
    cpu, wall = time.process_time(), time.perf_counter()
    out, err = io.StringIO(), io.StringIO()
    with tempfile.TemporaryDirectory() as tmp, contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        code = cli(["encode", str(bvh), "-o", str(Path(tmp) / "long.mcd"), "--codec", codec,
                    "--tolerance", str(tolerance), "--json", "-q"])
    if code == 0:
        report = json.loads(out.getvalue())
        row.update(ok=True, asset_bytes=report["size"]["asset_bytes"], max_cm=report["error"]["max_cm"])
    else:
        row.update(ok=False, error=f"mocodec encode exited {code}: {err.getvalue().strip()[-300:]}")
    peak = _peak_rss_kib() * 1024
    row.update(cpu_s=time.process_time() - cpu, wall_s=time.perf_counter() - wall, peak_bytes=peak,
               peak_over_raw=peak / raw)
    return row


def run_one(codec: str, folder: Path, frames: int, tolerance: float) -> dict:
    from mocodec.cli import _peak_rss_kib
    from mocodec.encode import encode_motions
    from mocodec.tolerance import Tolerance
    from mocodec.units import resolve_units

    motion = joined_motion(folder, frames)
    raw = motion.frame_count * motion.skeleton.channel_count * 4
    row = {"codec": codec, "frames": motion.frame_count, "minutes": motion.frame_count * motion.frame_time / 60,
           "raw_float32_bytes": raw}
    cpu, wall = time.process_time(), time.perf_counter()
    try:
        result = encode_motions([motion], [resolve_units(motion.skeleton, "cmu")], codec, Tolerance(tolerance))
        row.update(ok=True, asset_bytes=len(result.asset), max_cm=result.clips[0].error.max_cm)
    except Exception as exc:  # the reason is the figure
        row.update(ok=False, error=f"{type(exc).__name__}: {str(exc).splitlines()[0][:300]}")
    peak = _peak_rss_kib() * 1024  # this process's own peak (VmHWM)
    row.update(cpu_s=time.process_time() - cpu, wall_s=time.perf_counter() - wall, peak_bytes=peak,
               peak_over_raw=peak / raw)
    return row


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--minutes", type=float, default=20.0)
    ap.add_argument("--codecs", nargs="+", default=["rma", "spline"])
    ap.add_argument("--tolerance", type=float, default=1.0, help="cm (default 1)")
    ap.add_argument("--cmu", type=Path, default=REPO.parent / "shared" / "data" / "cmu",
                    help="the dev BVH clips (default ../shared/data/cmu)")
    ap.add_argument("--out", type=Path, default=HERE / "results" / "long_clip.json")
    ap.add_argument("--via-bvh", type=Path, metavar="FILE",
                    help="write the joined clip to this BVH file (kept) and measure `mocodec encode FILE` "
                         "instead: reading the file included")
    ap.add_argument("--one", help=argparse.SUPPRESS)  # child: run this codec, print its row
    ap.add_argument("--channels", type=int, help=argparse.SUPPRESS)  # child: the BVH file's
    args = ap.parse_args()
    frames = int(round(args.minutes * 60 * 120))
    if args.one:
        if args.via_bvh:
            print(json.dumps(run_cli(args.one, args.via_bvh, frames, args.channels, args.tolerance)))
        else:
            print(json.dumps(run_one(args.one, args.cmu, frames, args.tolerance)))
        return
    child = [sys.executable, __file__, "--minutes", str(args.minutes), "--tolerance", str(args.tolerance),
             "--cmu", str(args.cmu)]
    if args.via_bvh:
        from mocodec.io.bvh import write_bvh

        motion = joined_motion(args.cmu, frames)
        write_bvh(motion, args.via_bvh)
        child += ["--via-bvh", str(args.via_bvh), "--channels", str(motion.skeleton.channel_count)]
        del motion
    rows = []
    for codec in args.codecs:
        r = subprocess.run(child + ["--one", codec], capture_output=True, text=True)
        row = json.loads(r.stdout.splitlines()[-1]) if r.returncode == 0 else \
            {"codec": codec, "ok": False, "error": r.stderr.strip().splitlines()[-1:]}
        rows.append(row)
        print(json.dumps(row))
    args.out.write_text(json.dumps(rows, indent=2) + "\n")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
