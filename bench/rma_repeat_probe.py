"""Probe: what would coding repeated clips against their reconstructed primary save in `rma`?

    python bench/rma_repeat_probe.py                 # the rma_study subset, 1 cm
    python bench/rma_repeat_probe.py --tolerance 3

The repetition analysis of seed 003 §4 (``mocodec.rma``: segmentation, grouping, group PCA at
95 % variance, self-distance paths, eq. 5 selection) runs on the clips as one library. Each
*repeated* clip (frames of a source clip, a primary clip and a frame map ``ref``) is then coded
two ways by the real ``rma`` codec at the same tolerance, through the C runtime:

* direct: the repeated frames as a motion of their own;
* against the primary: every joint's local rotation as a residual ``q_P(ref)^-1 q``, where
  ``q_P`` is the primary as the runtime *reconstructs* it (the whole library encoded with
  ``rma`` at the same tolerance and decoded in C), slerped at the fractional ``ref``. The root
  keeps its own channels (a repeat walks elsewhere). The frame map is a 1-D curve fitted
  within 0.25 frames; its bits are added.

The composite pose ``q_P(ref) * residual`` is rebuilt in Python from the decoded residual and
its world error against the original is reported (the residual meets the tolerance on its own
skeleton; the composite error is what an engine would see if the runtime nested the two).
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import rma_study as st  # noqa: E402
from mocodec import rotations as R  # noqa: E402
from mocodec.container import read_summary  # noqa: E402
from mocodec.encode import encode_motions  # noqa: E402
from mocodec.kinematics import forward_kinematics  # noqa: E402
from mocodec.motion import Motion  # noqa: E402
from mocodec.rma import pca as C  # noqa: E402
from mocodec.rma import repeats as Rp  # noqa: E402
from mocodec.rma import segment as S  # noqa: E402
from mocodec.runtime import Asset, decode_local  # noqa: E402
from mocodec.tolerance import Tolerance  # noqa: E402
from mocodec.units import resolve_units  # noqa: E402


def slerp_rows(q: np.ndarray, at: np.ndarray) -> np.ndarray:
    """Quaternions ``q`` (F, N, 4) at fractional frames ``at`` (M,), per joint nlerp with sign
    continuity (the frames are 1/120 s apart, where nlerp and slerp agree to 1e-6)."""
    lo = np.clip(np.floor(at).astype(np.int64), 0, len(q) - 1)
    hi = np.minimum(lo + 1, len(q) - 1)
    w = (at - lo)[:, None, None]
    a, b = q[lo], q[hi]
    b = np.where(np.sum(a * b, axis=-1, keepdims=True) < 0, -b, b)
    return R.quat_normalize((1 - w) * a + w * b)


def rmal_bytes(asset: bytes) -> int:
    """Bytes of the asset's RMAL section: the motion itself, without skeletons and META."""
    return sum(size for kind, _v, _o, size in read_summary(asset).sections if kind == "RMAL")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--clips", nargs="*", default=st.SUBSET)
    ap.add_argument("--tolerance", type=float, default=1.0, help="cm, max on every frame")
    ap.add_argument("--threshold-cm", type=float, default=5.0)
    ap.add_argument("--out", type=Path, default=st.REPO / "bench" / "results" / "rma_repeat_probe.json")
    args = ap.parse_args()
    t0 = time.perf_counter()
    clips = st.load_library(args.clips, 0.1)
    motions = [c.motion for c in clips]
    units = [resolve_units(m.skeleton, cm_per_unit=st.CM) for m in motions]
    tol = Tolerance(args.tolerance)
    whole = encode_motions(motions, units, "rma", tol)
    asset = Asset(whole.asset)
    recon = [decode_local(asset, i)[0] for i in range(len(motions))]
    print(f"library: {len(whole.asset):,} B at {args.tolerance} cm", flush=True)

    # The analysis, as rma_study runs it (frame 0 of every clip is left out there: xs = flat[1:]).
    xs = [c.prep.flat[1:] for c in clips]
    segs = S.segment_library(xs)
    blocks = [xs[s.clip][s.start:s.stop] for s in segs]
    labels = S.group_segments([S.segment_feature(b) for b in blocks], cost=S.pca_group_cost(blocks))
    repeats: list[tuple[int, int, int, int, np.ndarray]] = []   # clip, start, stop, primary clip, ref
    for gi in range(int(labels.max()) + 1):
        members = [s for s, lab in zip(segs, labels) if lab == gi]
        x = np.concatenate([xs[s.clip][s.start:s.stop] for s in members])
        offsets = np.concatenate([[0], np.cumsum([s.frames for s in members])])
        dec = C.decompose(x)
        basis = dec.basis(dec.components_for_variance(0.95))
        thr = args.threshold_cm / st.CM * np.sqrt(x.shape[1] / 3)
        ra = Rp.analyse(basis.project(x), offsets[1:-1], clips[0].motion.frame_time,
                        Rp.RepeatSettings(threshold=thr))

        def source(row: float) -> tuple[int, float]:
            k = int(np.searchsorted(offsets, row, side="right") - 1)
            s = members[k]
            return s.clip, s.start + 1 + (row - offsets[k])   # +1: back to the clip's own frames

        for c in ra.clips:
            if c.kind != Rp.REPEATED:
                continue
            ci, start = source(c.start)
            ci2, last = source(c.stop - 1)
            pi, _ = source(float(ra.clips[c.primary].start))
            pi2, _ = source(float(ra.clips[c.primary].stop - 1))
            if ci != ci2 or pi != pi2:
                continue   # spans two source clips; the probe skips it
            ref = np.array([source(float(r))[1] for r in c.ref])
            repeats.append((ci, int(start), int(last) + 1, pi, ref))
    rep_frames = sum(b - a for _, a, b, _, _ in repeats)
    total_frames = sum(m.frame_count for m in motions)
    print(f"{len(repeats)} repeated clips, {rep_frames} of {total_frames} frames", flush=True)

    direct, residual, composite_err, fitted, ref_bits = [], [], [], [], 0
    for k, (ci, a, b, pi, ref) in enumerate(repeats):
        m = motions[ci].slice(a, b)
        m.name = f"rep{k}_{clips[ci].name}"
        direct.append(m)
        # The decoder would only have the fitted map, so the residual is taken against it.
        ref_fit, bits = st.fit_curve(ref, 0.25)
        ref_bits += bits + 32    # + primary index and start frame
        fitted.append(ref_fit)
        qp = slerp_rows(recon[pi], ref_fit)
        rot = m.rotations.copy()
        rot[:, 1:] = R.quat_multiply(R.quat_conjugate(qp[:, 1:]), rot[:, 1:])
        residual.append(Motion(m.skeleton, R.quat_normalize(rot), m.translations.copy(),
                               m.frame_time, m.name + "_res"))
    rep_units = [units[r[0]] for r in repeats]
    enc_direct = encode_motions(direct, rep_units, "rma", tol)
    enc_res = encode_motions(residual, rep_units, "rma", tol)
    res_asset = Asset(enc_res.asset)
    for k, (ci, a, b, pi, ref) in enumerate(repeats):
        loc_rot, loc_tr = decode_local(res_asset, k)
        qp = slerp_rows(recon[pi], fitted[k])
        rot = loc_rot.astype(np.float64)
        rot[:, 1:] = R.quat_multiply(qp[:, 1:], rot[:, 1:])
        _, world = forward_kinematics(direct[k].skeleton, R.quat_normalize(rot), loc_tr.astype(np.float64))
        _, orig = forward_kinematics(direct[k].skeleton, direct[k].rotations, direct[k].translations)
        composite_err.append(np.linalg.norm(world - orig, axis=-1) * st.CM)
    e = np.concatenate([x.ravel() for x in composite_err]) if composite_err else np.zeros(1)
    report = {
        "clips": args.clips, "tolerance_cm": args.tolerance, "library_bytes": len(whole.asset),
        "frames": total_frames, "repeated_clips": len(repeats), "repeated_frames": rep_frames,
        "direct_rmal_bytes": rmal_bytes(enc_direct.asset),
        "residual_rmal_bytes": rmal_bytes(enc_res.asset),
        "direct_bytes": len(enc_direct.asset), "residual_bytes": len(enc_res.asset),
        "ref_map_bytes": ref_bits / 8,
        "saving_bytes": len(enc_direct.asset) - len(enc_res.asset) - ref_bits / 8,
        "composite_max_cm": float(e.max()), "composite_mean_cm": float(e.mean()),
        "seconds": time.perf_counter() - t0,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(report, indent=1))
    print(json.dumps(report, indent=1))


if __name__ == "__main__":
    main()
