"""Seed 000's Tables 1 and 3 on our data: the position error of each joint along the left-arm
chain for IKBP, SPBLF, FKBC, IBKF and DWT at five matched rates, on a walk and a dance clip.

    .venv/bin/python bench/bench_seed000_tables.py              # 07_01 (walk), 05_02 (dance)
    .venv/bin/python bench/bench_seed000_tables.py --rates 0.2 0.4 0.8 1.6 3.2

Rate is the paper's "entropy": coded bits per BVH channel value (frames × channels), and the
ratio is coded bytes / raw BVH float32 bytes in percent, as the paper's "compression ratio %".
Each method is run at a sweep of its own quality setting (step for SPBLF and DWT, key-frame
tolerance for IBKF, world tolerance for the codecs), giving a rate-distortion curve per joint;
the tables report the errors at the five target rates, interpolated linearly in log-rate
between the two measured points around each target ("—" where a method's sweep does not reach
that rate). So the rates are matched exactly and every other figure is interpolated, not
measured at that rate; the measured points are in the JSON.

* IKBP = our `ik-predict` codec, FKBC = our `fk-wavelet` codec (both decoded by the C runtime);
  bytes are the codec's section (the clip's payload and its table), without skeleton and META.
* SPBLF, DWT, IBKF = `mocodec.ikfk.baselines` (Python, the same entropy coder); `spline` is
  added as our reference.
* Errors: world position, cm, mean over every frame (the paper does not say mean or max; the
  effector's max is given too). The chain is LeftShoulder → LeftArm (humerus) → LeftForeArm
  (radius) → LeftHand → the chain's end effector (the hand's end site), CMU names.
* "effectors / inner": mean error of the end effectors (hands, feet, head end sites) over the
  mean error of every other node — our fidelity goal is ≤ 0.5.

Writes bench/results/seed000_tables.{json,md}.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Callable

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "encoder"))

from mocodec import codecs  # noqa: E402
from mocodec.container import read_summary  # noqa: E402
from mocodec.encode import EncodeError, encode_motions  # noqa: E402
from mocodec.ikfk.baselines import (  # noqa: E402
    channel_steps, dwt_decode, dwt_encode, ibkf_decode, ibkf_encode, spblf_decode, spblf_encode,
)
from mocodec.ikfk.chains import motion_chains  # noqa: E402
from mocodec.io.bvh import read_bvh  # noqa: E402
from mocodec.kinematics import forward_kinematics  # noqa: E402
from mocodec.motion import Motion  # noqa: E402
from mocodec.runtime import Asset, decode_world  # noqa: E402
from mocodec.tolerance import Tolerance, effector_nodes  # noqa: E402
from mocodec.units import UNITS, resolve_units  # noqa: E402

DATA = REPO.parent / "shared" / "data" / "cmu"
SAMPLES = REPO / "encoder" / "mocodec" / "samples"
CLIPS = {"07_01": "walk", "05_02": "dance"}
CHAIN = ("LeftShoulder", "LeftArm", "LeftForeArm", "LeftHand")
RATES = (0.25, 0.5, 1.0, 2.0, 4.0)          # bits per channel value (the paper's: 0.7 … 4.1)
STEPS = tuple(float(s) for s in np.geomspace(0.01, 80.0, 20))   # degrees, SPBLF / DWT
IBKF_STEP = 0.02                               # degrees; IBKF's quality is its key count
IBKF_TOLERANCES = (1, 2, 4, 8, 16, 32, 64, 128, 256, 512, 1024, 2048, 4096)  # in steps
CODEC_TOLERANCES = (0.03, 0.06, 0.12, 0.25, 0.5, 1.0, 2.0, 4.0, 8.0, 16.0)  # cm

Point = dict  # {"rate", "bytes", "per_node_mean", "effector_max", "setting"}


def load(stem: str) -> Motion:
    for folder in (SAMPLES, DATA):
        p = folder / f"{stem}.bvh"
        if p.exists():
            return read_bvh(p)
    raise SystemExit(f"{stem}.bvh is in neither {SAMPLES} nor {DATA}")


def point(motion: Motion, world: np.ndarray, nbytes: int, setting: float, cm: float) -> Point:
    _, orig = forward_kinematics(motion.skeleton, motion.rotations, motion.translations)
    err = np.linalg.norm(world - orig, axis=-1) * cm          # (F, N) cm
    values = motion.frame_count * motion.skeleton.channel_count
    return {"setting": setting, "bytes": nbytes, "rate": 8.0 * nbytes / values,
            "ratio_percent": 100.0 * nbytes / (4.0 * values),
            "per_node_mean": err.mean(axis=0).tolist(), "per_node_max": err.max(axis=0).tolist()}


def baseline_sweep(motion: Motion, encode: Callable, decode: Callable, settings, cm: float,
                   steps_of: Callable[[float], np.ndarray],
                   extra: Callable[[float], dict] | None = None) -> list[Point]:
    x = motion.source_channels
    out = []
    for s in settings:
        try:
            stream = encode(x, steps_of(s), **(extra(s) if extra else {}))
        except ValueError:      # a step too fine for the coder's value range
            continue
        dec = Motion.from_channels(motion.skeleton, decode(stream), motion.frame_time)
        _, world = forward_kinematics(motion.skeleton, dec.rotations, dec.translations)
        out.append(point(motion, world, stream.size, s, cm))
    return out


def codec_sweep(motion: Motion, codec: str, cm: float, progress: bool) -> list[Point]:
    units = [resolve_units(motion.skeleton, cm_per_unit=cm)]
    out = []
    for tol in CODEC_TOLERANCES:
        try:
            res = encode_motions([motion], units, codec, Tolerance(tol))
        except EncodeError as exc:
            print(f"  {codec} {tol} cm: {exc}", flush=True)
            continue
        summ = read_summary(res.asset)
        nbytes = sum(size for kind, _v, _o, size in summ.sections
                     if kind not in ("META", "SKEL", "CLIP", "CNTC"))
        _, world = decode_world(Asset(res.asset), 0)
        out.append(point(motion, world.astype(np.float64), nbytes, tol, cm))
        if progress:
            print(f"  {codec} {tol} cm: {nbytes} B, rate {out[-1]['rate']:.3f}", flush=True)
    return out


def at_rate(points: list[Point], rate: float, key: str) -> np.ndarray | None:
    """``key`` (per node) at ``rate``, linear in log-rate between the two nearest points; None
    when ``rate`` is outside the measured range. Points of equal rate keep the better one."""
    pts = sorted(points, key=lambda p: p["rate"])
    r = np.array([p["rate"] for p in pts])
    if len(pts) == 0 or rate < r[0] or rate > r[-1]:
        return None
    i = int(np.searchsorted(r, rate))
    if r[i] == rate or i == 0:
        return np.array(pts[i][key])
    lo, hi = pts[i - 1], pts[i]
    w = (np.log(rate) - np.log(lo["rate"])) / (np.log(hi["rate"]) - np.log(lo["rate"]))
    return (1 - w) * np.array(lo[key]) + w * np.array(hi[key])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--clips", nargs="*", default=list(CLIPS))
    ap.add_argument("--rates", nargs=5, type=float, default=list(RATES),
                    help="five target rates, bits per BVH channel value")
    ap.add_argument("--out", type=Path, default=REPO / "bench" / "results" / "seed000_tables")
    args = ap.parse_args()
    cm = UNITS["cmu"]
    report: dict = {"rates": args.rates, "clips": {}}
    md = [f"# Seed 000 Tables 1 / 3 on our data (`bench/bench_seed000_tables.py`)\n",
          "Rate: coded bits per BVH channel value; errors: world position, cm, mean over frames "
          "(effector max in the last column); interpolated in log-rate between measured points.\n"]
    have_ikp = "ik-predict" in codecs.available()
    for stem in args.clips:
        motion = load(stem)
        sk = motion.skeleton
        arm = [c for c in motion_chains(sk) if sk.index("LeftHand") in c.nodes]
        chain = [sk.index(n) for n in CHAIN] + ([arm[0].effector] if arm else [])
        names = [sk.names[i] for i in chain]
        eff = sorted(effector_nodes(sk))
        inner = [i for i in range(sk.node_count) if i not in eff]
        t0 = time.perf_counter()
        methods: dict[str, list[Point]] = {}
        if have_ikp:
            methods["IKBP (ik-predict)"] = codec_sweep(motion, "ik-predict", cm, True)
        methods["SPBLF"] = baseline_sweep(motion, spblf_encode, spblf_decode, STEPS, cm,
                                          lambda s: channel_steps(sk, s))
        methods["FKBC (fk-wavelet)"] = codec_sweep(motion, "fk-wavelet", cm, True)
        methods["IBKF"] = baseline_sweep(motion, ibkf_encode, ibkf_decode, IBKF_TOLERANCES, cm,
                                         lambda s: channel_steps(sk, IBKF_STEP),
                                         extra=lambda s: {"tolerance": float(s)})
        methods["DWT"] = baseline_sweep(motion, dwt_encode, dwt_decode, STEPS, cm,
                                        lambda s: channel_steps(sk, s))
        methods["spline (ours)"] = codec_sweep(motion, "spline", cm, False)
        report["clips"][stem] = {"kind": CLIPS.get(stem, ""), "frames": motion.frame_count,
                                 "chain": names, "seconds": time.perf_counter() - t0,
                                 "points": methods}
        md.append(f"\n## {stem} ({CLIPS.get(stem, '')}, {motion.frame_count} frames)\n")
        if not have_ikp:
            md.append("IKBP: the `ik-predict` codec is not in this build; its rows are missing.\n")
        md.append("| rate | method | ratio % | " + " | ".join(names) + " | effector max | effectors / inner |")
        md.append("|" + "---|" * (len(names) + 5))
        for rate in args.rates:
            for name, pts in methods.items():
                mean = at_rate(pts, rate, "per_node_mean")
                mx = at_rate(pts, rate, "per_node_max")
                if mean is None:
                    md.append(f"| {rate:g} | {name} | — |" + " — |" * (len(names) + 2))
                    continue
                ratio = 100.0 * rate / 32.0
                cells = " | ".join(f"{mean[i]:.3f}" for i in chain)
                ei = mean[eff].mean() / max(mean[inner].mean(), 1e-12)
                md.append(f"| {rate:g} | {name} | {ratio:.2f} | {cells} | {mx[chain[-1]]:.3f} | {ei:.2f} |")
        print("\n".join(md[-(len(args.rates) * len(methods) + 2):]), flush=True)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.with_suffix(".json").write_text(json.dumps(report, indent=1))
    args.out.with_suffix(".md").write_text("\n".join(md) + "\n")
    print(f"wrote {args.out}.json / .md")


if __name__ == "__main__":
    main()
