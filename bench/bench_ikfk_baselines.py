"""Seed 000 groundwork study: the paper's baselines (SPBLF, DWT, IBKF) on a walk and a dance
clip at five step sizes, and the IK prediction's residual energy for k = 0, 1, 2, 4.

    PYTHONPATH=encoder .venv/bin/python bench/bench_ikfk_baselines.py

Writes bench/results/ikfk_baselines.json and prints the Markdown tables of docs/IKFK_STUDY.md.
Errors are world-space joint positions over every frame and node (cm, 5.6444 cm per CMU unit).
"""
from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Callable

import numpy as np

from mocodec.ikfk.baselines import (
    channel_steps, dwt_decode, dwt_encode, ibkf_decode, ibkf_encode, spblf_decode, spblf_encode,
)
from mocodec.ikfk.chains import motion_chains
from mocodec.entropy import entropy_encode
from mocodec.ikfk.jacobian import closed_loop_encode, link_angles, residual_energy_ratio
from mocodec.io.bvh import read_bvh
from mocodec.kinematics import forward_kinematics, world_positions
from mocodec.metrics import ErrorMetric
from mocodec.motion import Motion
from mocodec.units import UNITS, skeleton_height

REPO = Path(__file__).resolve().parents[1]
CLIPS = {
    "07_01 (walk)": REPO / "encoder/mocodec/samples/07_01.bvh",
    "05_02 (dance)": REPO / "../shared/data/cmu/05_02.bvh",
}
STEPS = (0.05, 0.1, 0.2, 0.5, 1.0)  # degrees (positions: × 0.1 unit)
LIMB = ("LeftShoulder", "LeftArm", "LeftForeArm", "LeftHand")  # Table 1's limb chain, CMU names
K_VALUES = (0.0, 0.5, 1.0, 2.0, 4.0)  # the brief's 0, 1, 2, 4, plus 0.5
CLOSED_LOOP_STEPS = (0.2, 1.0)  # degrees, on link angles
CLOSED_LOOP_K = (None, 0.0, 0.5, 1.0, 2.0)  # None: repeat the last decoded frame
EFFECTOR_STEP = 0.01  # file units (0.056 cm): the effector deltas are coded finely (§5.2)

Codec = tuple[Callable, Callable]
BASELINES: dict[str, Codec] = {
    "SPBLF": (spblf_encode, spblf_decode),
    "DWT": (dwt_encode, dwt_decode),
    "IBKF": (ibkf_encode, ibkf_decode),
}


def study_baselines(motion: Motion) -> list[dict]:
    sk = motion.skeleton
    metric = ErrorMetric(cm_per_unit=UNITS["cmu"], height_units=skeleton_height(sk))
    original = forward_kinematics(sk, motion.rotations, motion.translations)
    x = motion.source_channels
    limb = [sk.index(n) for n in LIMB]
    rows = []
    for step in STEPS:
        steps = channel_steps(sk, step)
        for name, (enc, dec) in BASELINES.items():
            stream = enc(x, steps)
            decoded = Motion.from_channels(sk, dec(stream), motion.frame_time)
            rep = metric.evaluate(sk, original,
                                  forward_kinematics(sk, decoded.rotations, decoded.translations))
            rows.append({
                "step_deg": step, "method": name, "bytes": stream.size,
                "bits_per_value": 8.0 * stream.size / x.size,
                "ratio_bvh_float32": 4.0 * x.size / stream.size,
                "max_cm": rep.max_cm, "mean_cm": rep.mean_cm,
                "limb_mean_cm": [float(rep.per_node_mean_cm[i]) for i in limb],
                "key_frames": getattr(stream, "key_count", None),
            })
    return rows


def study_prediction(motion: Motion, first_frame: int = 1) -> dict[str, dict]:
    """Per k, residual-energy ratios vs "repeat the last frame", pooled over all chains (each
    chain weighted by its "repeat" energy). CMU clips jump between frame 0 and frame 1 (05_02:
    30 degrees on the root), a jump no predictor can see coming and which would dominate
    every sum, so the study starts at ``first_frame`` = 1."""
    sk = motion.skeleton
    pos = world_positions(motion)[first_frame:]
    out = {}
    for k in K_VALUES:
        per_chain = [residual_energy_ratio(link_angles(c, pos), c.lengths(sk), k)
                     for c in motion_chains(sk)]
        pooled = {}
        for kind in ("angle", "link"):
            w = np.array([r[f"repeat_{kind}"] for r in per_chain])
            for pred in ("ik", "velocity"):
                v = np.array([r[f"{pred}_{kind}"] for r in per_chain])
                pooled[f"{pred}_{kind}"] = float(np.dot(w, v) / w.sum())
        pooled["per_chain_ik_link"] = [r["ik_link"] for r in per_chain]
        out[str(k)] = pooled
    return out


def study_closed_loop(motion: Motion, first_frame: int = 1) -> list[dict]:
    """Bytes of the link-angle residual codes (and of the effector stream IK needs), closed
    loop over every chain, per angle step and k; entropy coded one stream per chain."""
    sk = motion.skeleton
    pos = world_positions(motion)[first_frame:]
    chains = [(link_angles(c, pos), c.lengths(sk)) for c in motion_chains(sk)]
    rows = []
    for step in CLOSED_LOOP_STEPS:
        for k in CLOSED_LOOP_K:
            angle_bytes = effector_bytes = 0
            for theta, lengths in chains:
                eff, codes, _ = closed_loop_encode(theta, lengths, k, np.radians(step),
                                                   EFFECTOR_STEP)
                angle_bytes += len(entropy_encode(codes))
                effector_bytes += 0 if k is None else len(entropy_encode(eff))
            rows.append({"step_deg": step, "k": k, "angle_bytes": angle_bytes,
                         "effector_bytes": effector_bytes})
    return rows


def markdown(results: dict) -> str:
    lines = []
    for clip, res in results.items():
        lines += [f"### {clip}: {res['frames']} frames, {res['channels']} channels", "",
                  "| step (deg) | method | bytes | bits/value | max cm | mean cm | frames coded | "
                  + " | ".join(f"{n} mean cm" for n in LIMB) + " |",
                  "|---" * (7 + len(LIMB)) + "|"]
        for r in res["baselines"]:
            lines.append(
                f"| {r['step_deg']} | {r['method']} | {r['bytes']} | {r['bits_per_value']:.3f} | "
                f"{r['max_cm']:.3f} | {r['mean_cm']:.3f} | "
                + (f"{r['key_frames']} | " if r["key_frames"] is not None else "all | ")
                + " | ".join(f"{v:.3f}" for v in r["limb_mean_cm"]) + " |")
        lines += ["", "| k | IK / repeat (link energy) | IK / repeat (angle energy) | "
                  "const. velocity / repeat (link) | const. velocity / repeat (angle) | "
                  "per chain IK / repeat (link) |",
                  "|---|---|---|---|---|---|"]
        for k, r in res["prediction"].items():
            lines.append(f"| {k} | {r['ik_link']:.3f} | {r['ik_angle']:.3f} | "
                         f"{r['velocity_link']:.3f} | {r['velocity_angle']:.3f} | "
                         + ", ".join(f"{v:.2f}" for v in r["per_chain_ik_link"]) + " |")
        lines += ["", "| link-angle step (deg) | predictor | residual bytes | effector bytes | total |",
                  "|---|---|---|---|---|"]
        for r in res["closed_loop"]:
            name = "repeat last frame" if r["k"] is None else f"IK, k = {r['k']}"
            lines.append(f"| {r['step_deg']} | {name} | {r['angle_bytes']} | "
                         f"{r['effector_bytes']} | {r['angle_bytes'] + r['effector_bytes']} |")
        lines.append("")
    return "\n".join(lines)


def main() -> None:
    results = {}
    for clip, path in CLIPS.items():
        if not path.exists():
            print(f"skipping {clip}: {path} not present", file=sys.stderr)
            continue
        motion = read_bvh(path)
        results[clip] = {
            "frames": motion.frame_count,
            "channels": int(motion.source_channels.shape[1]),
            "baselines": study_baselines(motion),
            "prediction": study_prediction(motion),
            "closed_loop": study_closed_loop(motion),
        }
    out = REPO / "bench/results/ikfk_baselines.json"
    out.write_text(json.dumps(results, indent=1))
    print(markdown(results))


if __name__ == "__main__":
    main()
