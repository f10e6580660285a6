"""Measure what the RMA analysis (seed 003) buys on CMU clips, before the codec exists.

    python bench/rma_study.py                          # the 10-clip subset of docs/RMA_STUDY.md
    python bench/rma_study.py --clips 02_01 07_01 --out /tmp/study.json

Per library (clips analysed together): PPCA segments, normalized-cut groups, and per group the
PCs at 95 % / 98 % variance and the fewest PCs whose reconstruction (quantized basis, markers
back to joint rotations, forward kinematics) stays within 1 cm / 2 cm / 5 cm max error; the
repeated-motion analysis on the 95 % coefficients (fraction of frames in repeated clips). Then
a byte estimate: every coefficient curve fitted with the project's Catmull-Rom key fitting
(``curves.fit_keys``: keys every 32 frames, then the worst frame of every failing interval)
and range-aware quantization (``quantize.Quantizer``), bits counted as the spline codec packs
them (value bits per key, 5 bits of time per inserted key, 72 bits of header per curve), basis
at 12/16 bits, root curves (yaw and translation, or the whole root rotation), and frame 0 (the
converter's T-pose) at 16 bits per joint angle. A per-group global coefficient budget is
bisected until the world-space max error over every frame (root re-applied) meets the target:
(a) PCA only, (b) PCA + repeated clips coded as differences to the reconstructed primary plus
a reference-index curve (eq. 6, §5.4 end). Bit counts are before any entropy coding.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
sys.path.insert(0, str(REPO / "encoder"))

from mocodec import rotations as R  # noqa: E402
from mocodec.curves import catmull_rom, fit_keys  # noqa: E402
from mocodec.io import read_bvh  # noqa: E402
from mocodec.kinematics import forward_kinematics  # noqa: E402
from mocodec.motion import Motion  # noqa: E402
from mocodec.quantize import Quantizer  # noqa: E402
from mocodec.rma import pca as C  # noqa: E402
from mocodec.rma import preprocess as P  # noqa: E402
from mocodec.rma import repeats as Rp  # noqa: E402
from mocodec.rma import segment as S  # noqa: E402

CM = 5.6444
DATA = REPO.parent / "shared" / "data" / "cmu"
SUBSET = ["02_01", "02_05", "05_02", "07_01", "07_04", "09_01", "09_12", "05_18", "06_01", "06_02"]
BLOCK = 32          # mandatory key spacing, as the spline codec's blocks
TIME_BITS = 5       # an inserted key's offset inside its block
CURVE_HEADER = 72   # float32 minimum + float32 step + 8-bit width
CLIP_HEADER = 64    # kind, start, length, primary index of a clip


# ------------------------------------------------------------------------ curve fitting
class Tally:
    """Bits of a set of curves quantized as §5.2 does: per (kind, axis) one step and one range
    for the whole group (eq. 8 bits from the group's range), per curve only its minimum as an
    offset (8 bits, §5.4). Kinds keep primary/unique coefficients and repeated differences apart
    (their ranges differ by 2-16x, §6.3.3)."""

    def __init__(self) -> None:
        self.keys: dict[tuple[str, int], int] = {}
        self.extra: dict[tuple[str, int], int] = {}
        self.curves: dict[tuple[str, int], int] = {}
        self.lo: dict[tuple[str, int], float] = {}
        self.hi: dict[tuple[str, int], float] = {}
        self.step: dict[tuple[str, int], float] = {}

    def add(self, slot: tuple[str, int], lo: float, hi: float, step: float, keys: int, extra: int) -> None:
        self.keys[slot] = self.keys.get(slot, 0) + keys
        self.extra[slot] = self.extra.get(slot, 0) + extra
        self.curves[slot] = self.curves.get(slot, 0) + 1
        self.lo[slot] = min(self.lo.get(slot, lo), lo)
        self.hi[slot] = max(self.hi.get(slot, hi), hi)
        self.step[slot] = step

    def bits(self) -> int:
        total = 0
        for slot, k in self.keys.items():
            levels = np.ceil((self.hi[slot] - self.lo[slot]) / self.step[slot])
            width = int(np.ceil(np.log2(levels + 1))) if levels > 0 else 0
            total += k * width + self.extra[slot] * TIME_BITS + self.curves[slot] * 8 + CURVE_HEADER
        return total


def fit_curve(values: np.ndarray, eps: float, tally: Tally | None = None,
              slot: tuple[str, int] = ("", 0)) -> tuple[np.ndarray, int]:
    """Fit one trajectory within ``eps`` on every frame; return (what a decoder rebuilds,
    bits). Quantization gets 40 % of the budget (step = 0.8 eps), the key fit the rest. With a
    ``tally`` the bits are counted there (group-level ranges) and 0 is returned."""
    v = np.asarray(values, dtype=np.float64)
    f = len(v)
    lo, hi = float(v.min()), float(v.max())
    if hi - lo <= eps or f == 1:
        mid = np.float32(0.5 * (lo + hi))
        if tally is not None:
            tally.add(slot, lo, hi, 0.8 * eps, 0, 0)
            return np.full(f, float(mid)), 0
        return np.full(f, float(mid)), 32
    qz = Quantizer.for_range(np.array([lo]), np.array([hi]), np.array([0.8 * eps]))
    mand = np.unique(np.concatenate((np.arange(0, f, BLOCK), [f - 1])))
    keys, kv, ok = fit_keys(v[:, None], np.full(f, eps), lambda r: np.abs(r[:, 0] - v), mand,
                            qz.roundtrip)
    recon = catmull_rom(keys, qz.roundtrip(kv), np.arange(f, dtype=np.float64))[:, 0]
    extra = len(keys) - len(mand)
    if tally is not None:
        tally.add(slot, lo, hi, 0.8 * eps, len(keys), extra)
        return recon, 0
    return recon, int(len(keys) * int(qz.bits[0]) + extra * TIME_BITS + CURVE_HEADER)


def fit_rows(z: np.ndarray, eps: float, tally: Tally | None = None, kind: str = "") -> tuple[np.ndarray, int]:
    out = np.empty_like(z)
    bits = 0
    for c in range(z.shape[1]):
        out[:, c], b = fit_curve(z[:, c], eps, tally, (kind, c))
        bits += b
    return out, bits


# ------------------------------------------------------------------------ library
@dataclass
class ClipData:
    name: str
    motion: Motion
    layout: P.MarkerLayout
    prep: P.Prepared
    world: np.ndarray      # (F-1, N, 3) original world positions without frame 0
    root_removed: np.ndarray  # (F-1, 4) reconstructed removed root rotation
    root_trans: np.ndarray    # (F-1, 3) reconstructed root translation
    root_bits: int


def code_root(cd: P.Prepared, eps_cm: float) -> tuple[np.ndarray, np.ndarray, int]:
    """Root curves at ``eps_cm`` each: translation in units; yaw in radians scaled by the
    largest horizontal reach of any joint (so its error also moves points <= eps_cm); the whole
    root rotation as 4 normalised quaternion curves for large-tilt clips."""
    root = cd.root
    eps_u = eps_cm / CM
    trans, bits = fit_rows(root.translation[1:], eps_u)
    reach = float(np.max(np.linalg.norm(cd.aligned_positions[1:, :, [0, 2]], axis=-1)))
    if root.full:
        q, b = fit_rows(root.rotation[1:], 0.5 * eps_u / max(reach, 1e-9))
        rot = R.quat_normalize(q)
    else:
        yaw, b = fit_curve(root.yaw[1:], eps_u / max(reach, 1e-9))
        rot = R.quat_from_axis_angle(P.UP, yaw)
    return rot, trans, bits + b


def load_library(names: list[str], root_eps_cm: float) -> list[ClipData]:
    motions = [read_bvh(DATA / f"{n}.bvh") for n in names]
    shared = P.library_layout([m.skeleton for m in motions], CM)
    out = []
    for n, m in zip(names, motions):
        lay = P.layout_for(m.skeleton, shared)
        pr = P.to_markers(m, CM, layout=lay)
        world = forward_kinematics(m.skeleton, m.rotations, m.translations)[1][1:]
        rot, trans, bits = code_root(pr, root_eps_cm)
        out.append(ClipData(n, m, lay, pr, world, rot, trans, bits))
    return out


@dataclass
class Group:
    segments: list[S.Segment]
    x: np.ndarray            # (F, D) concatenated marker rows
    breaks: np.ndarray       # group frames where a new segment starts
    dec: C.Decomposition


def world_error(clips: list[ClipData], g: Group, rows: np.ndarray) -> np.ndarray:
    """(F, N) world error (cm) of reconstructed marker rows of a group, root re-applied from
    its coded curves."""
    errs = []
    at = 0
    for s in g.segments:
        cd = clips[s.clip]
        n = s.frames
        mk = rows[at:at + n].reshape(n, -1, 3)
        al = P.aligned_positions_from_markers(mk, cd.layout, cd.motion.skeleton)
        rot = cd.root_removed[s.start:s.stop]
        pos = R.quat_rotate(rot[:, None], al) + cd.root_trans[s.start:s.stop, None]
        errs.append(np.linalg.norm(pos - cd.world[s.start:s.stop], axis=-1) * CM)
        at += n
    return np.concatenate(errs)


def aligned_errors(clips: list[ClipData], g: Group, rows: np.ndarray):
    """Per segment of the group, the (F, N) aligned-frame error (cm) of marker rows taken
    through markers -> rotations -> FK (the subspace's own error, root excluded)."""
    at = 0
    for s in g.segments:
        cd = clips[s.clip]
        n = s.frames
        al = P.aligned_positions_from_markers(rows[at:at + n].reshape(n, -1, 3), cd.layout,
                                              cd.motion.skeleton)
        yield np.linalg.norm(al - cd.prep.aligned_positions[1:][s.start:s.stop], axis=-1) * CM
        at += n


def residual_cells(clips: list[ClipData], g: Group, rows: np.ndarray, tol_cm: float) -> dict[str, float]:
    """How sparse a residual layer on top of a subspace could be: the fraction of (frame,
    joint) samples whose aligned-frame error exceeds ``tol_cm`` and of (joint, 32-frame block)
    cells holding any such sample (a residual coded per joint and block pays only there)."""
    over, cells, total_cells, samples = 0, 0, 0, 0
    for err in aligned_errors(clips, g, rows):
        e = err > tol_cm
        over += int(e.sum())
        samples += e.size
        nb = -(-len(e) // BLOCK)
        pad = np.zeros((nb * BLOCK, e.shape[1]), dtype=bool)
        pad[:len(e)] = e
        blk = pad.reshape(nb, BLOCK, -1).any(axis=1)
        cells += int(blk.sum())
        total_cells += blk.size
    return {"samples_over": over / samples, "cells_over": cells / total_cells}


def projection_error_fn(clips: list[ClipData], g: Group):
    """Max aligned-frame error (cm) of marker rows (see :func:`aligned_errors`)."""
    return lambda rows: max(float(e.max()) for e in aligned_errors(clips, g, rows))


# ------------------------------------------------------------------------ coding estimates
def code_pca_only(z: np.ndarray, g: Group, eps: float) -> tuple[np.ndarray, int]:
    """Coefficient curves per segment (curves break where the group jumps between clips)."""
    out = np.empty_like(z)
    tally = Tally()
    for a, b in zip(np.r_[0, g.breaks], np.r_[g.breaks, len(z)]):
        if b > a:
            out[a:b], _ = fit_rows(z[a:b], eps, tally, "coef")
    return out, tally.bits()


def code_with_repeats(z: np.ndarray, clips: list[Rp.Clip], eps: float,
                      ref_eps: float = 0.25) -> tuple[np.ndarray, int]:
    """Primary and unique clips as coefficient curves; repeated clips as a reference curve
    (frames, within ``ref_eps``) and difference curves against the *reconstructed* primary."""
    out = np.full_like(z, np.nan)
    tally = Tally()
    bits = 0
    for c in clips:
        if c.kind != Rp.REPEATED:
            out[c.start:c.stop], _ = fit_rows(z[c.start:c.stop], eps, tally, "coef")
            bits += CLIP_HEADER
    for c in clips:
        if c.kind != Rp.REPEATED:
            continue
        pri = clips[c.primary]
        ref, rb = fit_curve(c.ref, ref_eps)
        ref = np.clip(ref, pri.start, pri.stop - 1)
        # Interpolate inside the primary only, so the frame after it is never touched.
        pred = Rp._interp_rows(out[pri.start:pri.stop], ref - pri.start)
        diff, _ = fit_rows(z[c.start:c.stop] - pred, eps, tally, "diff")
        out[c.start:c.stop] = pred + diff
        bits += rb + CLIP_HEADER
    return out, bits + tally.bits()


def bisect_eps(code, basis: C.Basis, z: np.ndarray, clips: list[ClipData], g: Group,
               target_cm: float, lo: float, hi: float, steps: int = 7):
    """Largest coefficient budget in [lo, hi] (log bisection) whose world max error meets
    ``target_cm``; returns (eps, bits, max, mean) or None when even ``lo`` misses."""
    def run(eps):
        zr, bits = code(z, eps)
        e = world_error(clips, g, basis.reconstruct(zr))
        return bits, float(e.max()), float(e.mean())

    b_lo = run(lo)
    if b_lo[1] > target_cm:
        return None
    best = (lo, *b_lo)
    a, b = np.log(lo), np.log(hi)
    for _ in range(steps):
        mid = 0.5 * (a + b)
        r = run(float(np.exp(mid)))
        if r[1] <= target_cm:
            best = (float(np.exp(mid)), *r)
            a = mid
        else:
            b = mid
    return best


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--clips", nargs="*", default=SUBSET,
                    help="clip stems in ../shared/data/cmu, or 'all'")
    ap.add_argument("--out", type=Path, default=REPO / "bench" / "results" / "rma_study.json")
    ap.add_argument("--threshold-cm", type=float, default=5.0,
                    help="self-distance threshold, RMS distance per marker (cm)")
    ap.add_argument("--root-eps-cm", type=float, default=0.1)
    ap.add_argument("--groups", type=int, default=None,
                    help="force this many groups (default: the cost model of segment.pca_group_cost)")
    ap.add_argument("--skip-bytes", action="store_true",
                    help="groups, PCs and repeats only (no byte estimates): for the whole set")
    args = ap.parse_args()
    t0 = time.perf_counter()
    if args.clips == ["all"]:
        args.clips = sorted(p.stem for p in DATA.glob("*.bvh"))
    clips = load_library(args.clips, args.root_eps_cm)
    xs = [c.prep.flat[1:] for c in clips]
    frames = sum(len(x) for x in xs)
    raw_bvh = sum(c.motion.skeleton.channel_count * c.motion.frame_count * 4 for c in clips)
    t_seg = time.perf_counter()
    segs = S.segment_library(xs)
    blocks = [xs[s.clip][s.start:s.stop] for s in segs]
    feats = [S.segment_feature(b) for b in blocks]
    labels = S.group_segments(feats, n_groups=args.groups, cost=S.pca_group_cost(blocks))
    t_seg = time.perf_counter() - t_seg
    root_bits = sum(c.root_bits for c in clips)
    frame0_bits = sum(16 * 3 * len(c.layout.joints) + 6 * 32 for c in clips)
    report = {"clips": args.clips, "frames": frames, "raw_bvh_bytes": raw_bvh,
              "segments": len(segs), "groups": int(labels.max() + 1),
              "segment_seconds": t_seg, "root_bytes": root_bits / 8, "frame0_bytes": frame0_bits / 8,
              "group_rows": []}
    totals = {k: 0 for k in ("pca_1cm", "rma_1cm", "pca_6cm", "rma_6cm", "pca95", "rma95")}
    errs = {k: [] for k in totals}
    for gi in range(int(labels.max()) + 1):
        members = [s for s, lab in zip(segs, labels) if lab == gi]
        x = np.concatenate([xs[s.clip][s.start:s.stop] for s in members])
        breaks = np.cumsum([s.frames for s in members])[:-1]
        g = Group(members, x, breaks, C.decompose(x))
        perr = projection_error_fn(clips, g)
        row = {"group": gi, "frames": len(x), "segments": len(members),
               "clip_names": sorted({clips[s.clip].name for s in members}),
               "k95": g.dec.components_for_variance(0.95), "k98": g.dec.components_for_variance(0.98)}
        for tgt in (1.0, 2.0, 5.0, 0.8):
            row[f"k_max{tgt:g}cm"], row[f"err_max{tgt:g}cm"] = C.components_for_max_error(x, g.dec, perr, tgt)
        b95 = g.dec.basis(row["k95"])
        z95 = b95.project(x)
        row["proj95_max_cm"] = perr(b95.reconstruct(z95))
        row["residual_1cm_at_k95"] = residual_cells(clips, g, b95.reconstruct(z95), 1.0)
        b5 = g.dec.basis(row["k_max5cm"])
        row["residual_1cm_at_k5cm"] = residual_cells(clips, g, b5.reconstruct(b5.project(x)), 1.0)
        ta = time.perf_counter()
        thr = args.threshold_cm / CM * np.sqrt(x.shape[1] / 3)
        rma = Rp.analyse(z95, breaks, clips[0].motion.frame_time, Rp.RepeatSettings(threshold=thr))
        row["rma_seconds"] = time.perf_counter() - ta
        row.update({k: v for k, v in rma.stats.items()})
        row["plot_step"] = rma.step
        row["plot_pixels_kept"] = rma.pixels
        if args.skip_bytes:
            report["group_rows"].append(row)
            print(json.dumps(row), flush=True)
            continue
        # Byte estimates. Budgets are in coefficient units (marker-space length, file units).
        unit = 1.0 / CM
        for tag, k_key, target in (("1cm", "k_max0.8cm", 1.0), ("6cm", "k_max5cm", 6.0)):
            basis = g.dec.basis(row[k_key])
            z = basis.project(x)
            for kind, code in (("pca", lambda zz, e: code_pca_only(zz, g, e)),
                               ("rma", lambda zz, e: code_with_repeats(zz, rma.clips, e))):
                r = bisect_eps(code, basis, z, clips, g, target, 0.05 * unit, 20.0 * unit, steps=6)
                key = f"{kind}_{tag}"
                if r is None:
                    row[key] = None
                    continue
                eps, bits, emax, emean = r
                bits += basis.header_bits()
                row[key] = {"k": row[k_key], "eps_cm": eps / unit, "bytes": bits / 8,
                            "max_cm": emax, "mean_cm": emean}
                totals[key] += bits / 8
                errs[key].append((emax, emean, len(x)))
        # The paper's own setting: 95 % variance, quantization error ~0.5 cm (eq. 8, §5.2).
        for kind, code in (("pca95", lambda zz, e: code_pca_only(zz, g, e)),
                           ("rma95", lambda zz, e: code_with_repeats(zz, rma.clips, e))):
            zr, bits = code(z95, 1.25 * unit)
            e = world_error(clips, g, b95.reconstruct(zr))
            bits += b95.header_bits()
            row[kind] = {"k": row["k95"], "eps_cm": 1.25, "bytes": bits / 8,
                         "max_cm": float(e.max()), "mean_cm": float(e.mean())}
            totals[kind] += bits / 8
            errs[kind].append((float(e.max()), float(e.mean()), len(x)))
        report["group_rows"].append(row)
        print(json.dumps(row), flush=True)
    fixed = report["root_bytes"] + report["frame0_bytes"]
    report["totals"] = {}
    for k, v in totals.items():
        if not errs[k]:
            continue
        e = np.array(errs[k])
        complete = len(errs[k]) == report["groups"]
        report["totals"][k] = {
            "bytes": v + fixed, "complete": complete,
            "ratio_bvh": raw_bvh / (v + fixed),
            "max_cm": float(e[:, 0].max()), "mean_cm": float(np.average(e[:, 1], weights=e[:, 2])),
        }
    rep_frames = sum(r["repeated_fraction"] * r["frames"] for r in report["group_rows"])
    report["repeated_fraction"] = rep_frames / frames
    report["seconds"] = time.perf_counter() - t0
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(report, indent=1))
    print(json.dumps({k: report[k] for k in report if k != "group_rows"}, indent=1))


if __name__ == "__main__":
    main()
