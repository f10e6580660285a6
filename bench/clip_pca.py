"""Clip-PCA baseline: Arikan 2006, "Compression of motion capture databases", as seed 003
describes it (§2 related work, §6.1, §6.3.1), rebuilt here to put it on our RD plot.

    python bench/clip_pca.py --clips 02_01 07_01 --targets 1 2 4 8       # a subset
    python bench/clip_pca.py --targets 0.5 1 2 3 4 6 --clusters 1        # dev set -> results/clip_pca.json
    python bench/clip_pca.py --targets 1 2 3 4 --clusters 1 --fix-cm 2.5 # -> results/clip_pca_sparse.json

The method, per library of clips (all files coded together, as Arikan codes a database):

1. Frame 0 of every CMU file is the converter's T-pose, not motion: it is stored on its own
   (16 bits per Euler channel, float32 root translation), as ``bench/rma_study.py`` does.
2. Root alignment and virtual markers (``mocodec.rma.preprocess``): heading + root translation
   (or the whole root rotation for tumbling clips) come out; each joint becomes marker positions
   in the aligned frame. We use the project's compact set (2 markers per joint plus a bone point
   where a bone is too short, seed 003 Fig. 2b) rather than Arikan's 3 per joint: 1/3 fewer
   dimensions, which can only help this baseline.
3. Clips of ``clip_frames`` frames (24 at 120 fps = 200 ms, the length seed 003 §6.1 used for
   Arikan's method). Consecutive clips share their boundary frame (stride ``clip_frames - 1``);
   the last clip is padded with the last posture (seed 003 §6.1), padded frames are not output.
4. Every marker coordinate in a clip gets one cubic Bézier curve, least squares over the clip's
   frames (4 control points); a clip becomes a vector of 4 x 3M control values.
5. k-means (k-means++ seeding, fixed seed) over the clip vectors; PCA per cluster; a cluster
   keeps the fewest components whose truncation error (marker distances over its clips'
   frames, taken through the Bézier curves) is within ``target_cm``: RMS by default (the
   seed's reproduction keeps PCs by variance), or the max (``--criterion max``: then a few
   outlier clips buy whole basis vectors: on the dev set at 2 cm with 8 clusters it kept
   35-248 PCs per cluster against 25-52 with RMS).
   On our 50k-frame set fewer clusters are smaller (the axes dominate, seed 003 §6.3.1):
   ``--clusters`` is a knob, see bench/results/clip_pca.md.
6. Storage: means at 16 bits and axes at 12 bits per element (per-column range, float32 min and
   step), coefficients projected on the *quantized* axes and quantized with one uniform step
   (``coef_step_frac x target``; PCA axes are orthonormal, so every coefficient moves the
   control points by the same amount per unit); coefficients, cluster ids and root control
   points are written with ``mocodec.entropy.entropy_encode`` (the runtime's range coder).
7. Root channels (yaw + translation, or quaternion + translation) are fitted per clip with the
   same Bézier curves and quantized on a fixed grid (step ``root_step_frac x target``, yaw with
   a 100 cm lever), control points delta-coded along the file.
8. Decoding: control points -> curves -> per-boundary continuity fix (the two clips' values at a
   shared frame differ after lossy coding; each clip gets half the gap as a linear ramp over its
   length, so the curves meet at the mean, no bytes spent) -> markers -> joint rotations by
   Gram-Schmidt of (bone marker, side marker) -> forward kinematics with the file's skeleton
   -> root re-applied. Errors are measured on world positions of every joint and end site on
   every frame against the original, with ``mocodec.metrics`` (the figures every codec uses).

Arikan decodes marker positions, not rotations. A game runtime needs a pose (rotations on fixed
bones), so the primary figures are those of the rotation fit above (bone lengths kept exact;
marker noise turns into angle error). The marker-position error of the joints themselves (what
Arikan's method reconstructs before any skeleton fit) is also reported (``pos_*`` fields).
Not reproduced: Arikan's separate coding of foot contacts (an IK clean-up), and any optimised
bit allocation; coefficients use one step for all components.

Our extension, off by default (``--fix-cm`` / ``--sparse-frac``, codec ``clip_pca+sparse``):
one cubic per 200 ms cannot follow one-frame flips and root jumps in the source data (measured
on the dev set: Bézier-only marker errors up to 65 cm, a 112 cm root jump in 07_12), so the
plain method's max error stays above 1 m whatever the target. The extension stores a
quantized correction for every (frame, marker) still off by more than the threshold and for
every root frame off by more than a quarter of it, so its max error can be compared with the
codecs that promise one.
"""
from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
REPO = HERE.parent
sys.path.insert(0, str(REPO / "encoder"))

from mocodec import rotations as R  # noqa: E402
from mocodec.entropy import MAX_ABS, entropy_decode, entropy_encode  # noqa: E402
from mocodec.io import read_bvh  # noqa: E402
from mocodec.kinematics import forward_kinematics  # noqa: E402
from mocodec.metrics import ErrorMetric, ErrorReport, combine, size_report  # noqa: E402
from mocodec.motion import Motion, Skeleton  # noqa: E402
from mocodec.rma import pca as C  # noqa: E402
from mocodec.rma import preprocess as P  # noqa: E402
from mocodec.units import resolve_units  # noqa: E402

DEV_SET = REPO.parent / "shared" / "data" / "cmu"
YAW_LEVER_CM = 100.0  # a heading error of e rad moves a point this far from the root by e * lever


@dataclass
class Config:
    """Knobs of the baseline. ``target_cm`` is the swept error target (step 5 of the module doc)."""

    target_cm: float = 2.0
    criterion: str = "rms"
    """How a cluster's truncation error is compared with the target: ``rms`` over its clips'
    frames and markers (the seed's reproduction keeps PCs by variance, an RMS criterion), or
    ``max`` over them (every marker on every frame; outliers then buy whole basis vectors)."""
    clip_frames: int = 24
    clusters: int = 8
    coef_step_frac: float = 0.5
    root_step_frac: float = 0.05
    mean_bits: int = 16
    axis_bits: int = 12
    frame0_bits: int = 16
    kmeans_iters: int = 40
    seed: int = 0
    sparse_frac: float = 0.0
    """0: Arikan's method as published. > 0: our extension (not Arikan's): after clip PCA,
    every (frame, marker) still off by more than ``sparse_frac x target`` and every root frame
    whose channels are (lever-weighted) off by more than that gets a quantized correction,
    stored sparsely. It catches what one cubic per 200 ms cannot follow: one-frame flips and
    teleports in the source data, fast hands, impacts."""
    fix_cm: float = 0.0
    """> 0: the correction threshold in cm for every target (overrides ``sparse_frac``), to
    sweep the mean error under one max-error cap (the seed's regime: mean <= 2, max <= 6 cm)."""
    sparse_step_frac: float = 0.4
    """Correction grid as a fraction of the correction threshold."""


# ------------------------------------------------------------------------ Bézier clips
def bezier_matrix(length: int) -> np.ndarray:
    """(length, 4) Bernstein weights of a cubic Bézier at ``length`` uniform parameters in [0, 1]."""
    t = np.linspace(0.0, 1.0, length)[:, None]
    s = 1.0 - t
    return np.hstack([s ** 3, 3 * s * s * t, 3 * s * t * t, t ** 3])


def clip_starts(frames: int, length: int) -> np.ndarray:
    """Start frames of the clips covering ``frames`` frames, sharing one frame per boundary."""
    stride = length - 1
    count = max(1, int(np.ceil((frames - 1) / stride)))
    return np.arange(count) * stride


def cut_clips(x: np.ndarray, length: int) -> np.ndarray:
    """(n, length, D) clips of rows ``x`` (F, D); the last clip is padded with the last row."""
    starts = clip_starts(len(x), length)
    idx = np.minimum(starts[:, None] + np.arange(length)[None, :], len(x) - 1)
    return x[idx]


def fit_bezier(clips: np.ndarray) -> np.ndarray:
    """Least-squares cubic Bézier control points (n, 4, D) of clips (n, L, D)."""
    pinv = np.linalg.pinv(bezier_matrix(clips.shape[1]))  # (4, L)
    return np.einsum("cl,nld->ncd", pinv, clips)


def join_clips(curves: np.ndarray, frames: int) -> np.ndarray:
    """Rows (frames, D) from decoded clip curves (n, L, D) that share boundary frames.

    Lossy coding leaves the two clips' values at a shared frame apart; each side takes half of
    the gap as a linear ramp over its own length, so they meet at the mean (C0, no extra data).
    """
    n, length, d = curves.shape
    ramp = np.linspace(0.0, 1.0, length)[None, :, None]
    gap = curves[1:, 0] - curves[:-1, -1]                       # (n-1, D)
    fixed = curves.copy()
    fixed[:-1] += 0.5 * gap[:, None] * ramp                     # end of clip i rises to the mean
    fixed[1:] -= 0.5 * gap[:, None] * (1.0 - ramp)              # start of clip i+1 falls to it
    rows = np.concatenate([fixed[:, :-1].reshape(-1, d), fixed[-1:, -1]], axis=0)
    return rows[:frames]


# ------------------------------------------------------------------------ k-means
def kmeans(x: np.ndarray, k: int, iters: int = 40, seed: int = 0) -> np.ndarray:
    """Cluster labels (n,) of rows ``x`` by Lloyd iterations from k-means++ seeds."""
    n = len(x)
    k = max(1, min(k, n))
    rng = np.random.default_rng(seed)
    sq = np.einsum("nd,nd->n", x, x)
    centers = [x[rng.integers(n)]]
    dist = np.maximum(sq - 2 * x @ centers[0] + centers[0] @ centers[0], 0.0)
    for _ in range(1, k):
        # k-means++: next seed drawn in proportion to the squared distance to the nearest seed.
        p = dist / dist.sum() if dist.sum() > 0 else np.full(n, 1.0 / n)
        c = x[rng.choice(n, p=p)]
        centers.append(c)
        dist = np.minimum(dist, np.maximum(sq - 2 * x @ c + c @ c, 0.0))
    cent = np.array(centers)
    labels = np.full(n, -1)
    for _ in range(iters):
        d2 = sq[:, None] - 2 * x @ cent.T + np.einsum("kd,kd->k", cent, cent)[None]
        new = np.argmin(d2, axis=1)
        if np.array_equal(new, labels):
            break
        labels = new
        counts = np.bincount(labels, minlength=k)
        sums = np.zeros_like(cent)
        np.add.at(sums, labels, x)
        # An emptied cluster keeps its old centre (it may win clips back next round).
        cent = np.where(counts[:, None] > 0, sums / np.maximum(counts, 1)[:, None], cent)
    # Renumber so cluster ids are dense (an empty cluster would cost a header for nothing).
    _, labels = np.unique(labels, return_inverse=True)
    return labels


# ------------------------------------------------------------------------ inputs
@dataclass
class Source:
    """One file ready to code: the motion, its aligned markers (frames 1..F-1) and truth."""

    motion: Motion
    cm_per_unit: float
    prepared: P.Prepared
    world_rot: np.ndarray  # (F, N, 4) original world rotations, every frame
    world_pos: np.ndarray  # (F, N, 3)
    height_units: float


def prepare(motions: list[Motion], cm_per_unit: float) -> list[Source]:
    """Markers of every motion on one shared marker layout (one PCA space for the library)."""
    shared = P.library_layout([m.skeleton for m in motions], cm_per_unit)
    out = []
    for m in motions:
        layout = P.layout_for(m.skeleton, shared)
        prep = P.to_markers(m.slice(1, m.frame_count), cm_per_unit, layout=layout)
        wr, wp = forward_kinematics(m.skeleton, m.rotations, m.translations)
        height = resolve_units(m.skeleton, cm_per_unit=cm_per_unit).height_units
        out.append(Source(m, cm_per_unit, prep, wr, wp, height))
    return out


# ------------------------------------------------------------------------ encoded form
@dataclass
class FileCode:
    """What the decoder holds for one file (besides its skeleton)."""

    frames: int
    frame0: np.ndarray          # (C,) dequantized channel values of frame 0
    root_full: bool
    root_ctrl: np.ndarray       # (n, 4, R) dequantized root control points
    clip_ids: np.ndarray        # (n,) cluster of each clip
    clip_rows: np.ndarray       # (n,) row of each clip in its cluster's coefficient matrix
    fix_index: np.ndarray = field(default_factory=lambda: np.empty((0, 2), int))  # (frame, marker)
    fix_value: np.ndarray = field(default_factory=lambda: np.empty((0, 3)))       # dequantized
    root_fix_frame: np.ndarray = field(default_factory=lambda: np.empty(0, int))
    root_fix_value: np.ndarray = field(default_factory=lambda: np.empty((0, 0)))


@dataclass
class ClusterCode:
    mean: np.ndarray            # (Dc,) dequantized
    axes: np.ndarray            # (Dc, k) dequantized
    coef: np.ndarray            # (m, k) dequantized coefficients


@dataclass
class Encoded:
    config: Config
    files: list[FileCode]
    clusters: list[ClusterCode]
    byte_parts: dict[str, int] = field(default_factory=dict)

    @property
    def total_bytes(self) -> int:
        return int(sum(self.byte_parts.values()))


def _entropy_bytes(values: np.ndarray, channels: int = 1) -> int:
    """Bytes of ``values`` through the runtime's coder, checked to decode back exactly."""
    v = np.asarray(values, dtype=np.int64).ravel()
    if v.size == 0:
        return 0
    if np.abs(v).max() > MAX_ABS:
        raise ValueError("value out of the entropy coder's range")
    data = entropy_encode(v.astype(np.int32), channels)
    back = entropy_decode(data, v.size, channels)
    if not np.array_equal(back, v):
        raise AssertionError("entropy coder round trip failed")
    return len(data) + 4  # + a 32-bit length so the decoder can find the next stream


def _skeleton_bytes(sk: Skeleton) -> int:
    """Hierarchy a decoder needs: per node a name (length byte + UTF-8), parent (2 bytes),
    channel layout (1 byte) and float32 offset."""
    return sum(1 + len(name.encode()) + 2 + 1 + 12 for name in sk.names)


def _frame0(m: Motion, bits: int) -> tuple[np.ndarray, int]:
    """Frame 0 channels as a decoder gets them, and their bits: rotation channels uniform on
    [-180, 180) at ``bits``, translation channels float32."""
    ch = m.to_channels()[0] if m.source_channels is None else m.source_channels[0].copy()
    codes = np.concatenate([np.asarray(c, dtype=np.int64) for c in m.skeleton.channels])
    rot = codes >= 3
    step = 360.0 / (1 << bits)
    wrapped = (ch + 180.0) % 360.0 - 180.0
    out = ch.astype(np.float32).astype(np.float64)
    out[rot] = np.round(wrapped[rot] / step) * step
    return out, int(rot.sum()) * bits + int((~rot).sum()) * 32


def _root_channels(track: P.RootTrack) -> np.ndarray:
    """(F, R) root curves: yaw + translation, or quaternion + translation for tumbling clips."""
    if track.full:
        return np.hstack([track.rotation, track.translation])
    return np.hstack([track.yaw[:, None], track.translation])


def _root_track(rows: np.ndarray, full: bool) -> P.RootTrack:
    if full:
        q = R.quat_normalize(rows[:, :4])
        return P.RootTrack(np.zeros(len(rows)), rows[:, 4:], True, q)
    return P.RootTrack(rows[:, 0], rows[:, 1:], False, np.zeros((len(rows), 4)))


def _quantize_uniform(x: np.ndarray, step: float) -> tuple[np.ndarray, np.ndarray]:
    """Integers on a grid of ``step`` and the float32-step values they decode to."""
    s = float(np.float32(step))
    q = np.rint(x / s).astype(np.int64)
    return q, q * s


def encode(sources: list[Source], cfg: Config) -> Encoded:
    """Code a library of files with clip PCA at ``cfg.target_cm``."""
    length = cfg.clip_frames
    cm = sources[0].cm_per_unit
    if any(abs(s.cm_per_unit - cm) > 1e-12 for s in sources):
        raise ValueError("one unit for the whole library (one PCA space)")
    parts = {"skeletons": 0, "headers": 0, "frame0": 0, "root": 0, "cluster_ids": 0,
             "pca_means": 0, "pca_axes": 0, "coefficients": 0}
    files: list[FileCode] = []
    ctrl_all, owner = [], []
    root_q_all = []
    for i, s in enumerate(sources):
        m = s.motion
        parts["skeletons"] += _skeleton_bytes(m.skeleton)
        f0, bits0 = _frame0(m, cfg.frame0_bits)
        parts["frame0"] += (bits0 + 7) // 8
        parts["headers"] += 4 + 1  # frame count, root mode
        ctrl = fit_bezier(cut_clips(s.prepared.flat, length))       # (n, 4, 3M)
        ctrl_all.append(ctrl.reshape(len(ctrl), -1))
        owner.append(np.full(len(ctrl), i))
        track = s.prepared.root
        rc = fit_bezier(cut_clips(_root_channels(track), length))    # (n, 4, R)
        # Root grid: translation in file units; angles (yaw, quaternion parts) via a lever.
        step_cm = cfg.root_step_frac * cfg.target_cm
        steps = np.full(rc.shape[2], step_cm / cm)
        steps[: 4 if track.full else 1] = step_cm / YAW_LEVER_CM
        steps = steps.astype(np.float32).astype(np.float64)
        q = np.rint(rc / steps).astype(np.int64)
        parts["headers"] += 4 * rc.shape[2]  # float32 step per root channel
        # Deltas along the file (clip-major, control points in order) are small: code those.
        flat = q.reshape(-1, rc.shape[2])
        root_q_all.append(np.diff(flat, axis=0, prepend=0))
        files.append(FileCode(m.frame_count, f0, track.full, q * steps, np.empty(0, int), np.empty(0, int)))
    # Root streams: one per mode so channel counts line up.
    for full in (False, True):
        chunks = [d for d, fc in zip(root_q_all, files) if fc.root_full == full]
        if chunks:
            arr = np.concatenate(chunks)
            parts["root"] += _entropy_bytes(arr, arr.shape[1])

    x = np.concatenate(ctrl_all)
    owner = np.concatenate(owner)
    labels = kmeans(x, cfg.clusters, cfg.kmeans_iters, cfg.seed)
    parts["cluster_ids"] += _entropy_bytes(labels)
    parts["headers"] += 2 + 2 + 1  # clip length, cluster count, bit depths
    bez = bezier_matrix(length)
    m3 = x.shape[1] // 12
    coef_step = cfg.coef_step_frac * cfg.target_cm / cm
    parts["headers"] += 4  # float32 coefficient step
    clusters: list[ClusterCode] = []
    coef_ints = []
    rows = np.zeros(len(x), dtype=np.int64)
    for c in range(int(labels.max()) + 1):
        members = np.flatnonzero(labels == c)
        rows[members] = np.arange(len(members))
        xc = x[members]
        dec = C.decompose(xc)
        k = components_for_target(xc, dec, bez, m3, cfg.target_cm / cm, cfg.criterion)
        basis = dec.basis(k, cfg.mean_bits, cfg.axis_bits)
        coef = basis.project(xc) if k else np.zeros((len(xc), 0))
        q, deq = _quantize_uniform(coef, coef_step)
        coef_ints.append(q.T.ravel())  # component-major: one component's values sit together
        clusters.append(ClusterCode(basis.mean, basis.axes, deq))
        d = xc.shape[1]
        parts["pca_means"] += (d * cfg.mean_bits + 7) // 8 + 8
        parts["pca_axes"] += (d * k * cfg.axis_bits + 7) // 8 + 8 * k + 2
    parts["coefficients"] += _entropy_bytes(np.concatenate(coef_ints))
    for i, fc in enumerate(files):
        mine = owner == i
        fc.clip_ids = labels[mine]
        fc.clip_rows = rows[mine]
    enc = Encoded(cfg, files, clusters, parts)
    if cfg.sparse_frac > 0 or cfg.fix_cm > 0:
        add_sparse_fixes(enc, sources)
    return enc


def add_sparse_fixes(enc: Encoded, sources: list[Source]) -> None:
    """The extension of :attr:`Config.sparse_frac`: residual corrections where clip PCA misses.

    Marker fixes: positions (frame delta, marker index) and the three quantized components,
    three entropy-coded streams for the whole library. Root fixes: frame deltas and the
    quantized channel residuals (one stream per root mode)."""
    cfg = enc.config
    cm = sources[0].cm_per_unit
    thr = (cfg.fix_cm if cfg.fix_cm > 0 else cfg.sparse_frac * cfg.target_cm) / cm
    step = float(np.float32(cfg.sparse_step_frac * thr))
    pos, vals, root_pos, root_vals = [], [], {False: [], True: []}, {False: [], True: []}
    for i, s in enumerate(sources):
        fc = enc.files[i]
        mk = s.prepared.layout.marker_count
        dec_m, dec_r = decode_markers(enc, i, mk)
        # Root first: a root error moves every marker, so it is fixed where it happens.
        truth_r = _root_channels(s.prepared.root)
        lever = np.full(truth_r.shape[1], 1.0)
        lever[: 4 if fc.root_full else 1] = YAW_LEVER_CM / cm  # angle -> file units at the lever
        rres = (truth_r - dec_r) * lever
        # A root error moves every joint, on top of the marker's own error: fix it at a
        # quarter of the threshold (cheap: the root curves miss only at jumps).
        bad_r = np.flatnonzero(np.abs(rres).max(axis=1) > 0.25 * thr)
        rq = np.rint(rres[bad_r] / (0.25 * step)).astype(np.int64)
        fc.root_fix_frame = bad_r
        fc.root_fix_value = rq * (0.25 * step) / lever
        root_pos[fc.root_full].append(np.diff(bad_r, prepend=-1))
        root_vals[fc.root_full].append(rq)
        res = s.prepared.markers - dec_m
        bad = np.argwhere(np.linalg.norm(res, axis=-1) > thr)      # (K, 2) frame-major order
        q = np.rint(res[bad[:, 0], bad[:, 1]] / step).astype(np.int64)
        fc.fix_index = bad
        fc.fix_value = q * step
        # Frame deltas (0 = same frame as the previous fix) and marker indices: both small.
        fd = np.diff(bad[:, 0], prepend=-1) if len(bad) else np.empty(0, int)
        pos.append(np.stack([fd, bad[:, 1]], axis=1) if len(bad) else np.empty((0, 2), int))
        vals.append(q)
        enc.byte_parts["headers"] += 4 + 2  # fix count per file, root fix count
    enc.byte_parts["fix_positions"] = _entropy_bytes(np.concatenate(pos), 2)
    enc.byte_parts["fix_values"] = _entropy_bytes(np.concatenate(vals), 3)
    enc.byte_parts["root_fixes"] = 4  # float32 step
    for full in (False, True):
        if root_pos[full]:
            enc.byte_parts["root_fixes"] += _entropy_bytes(np.concatenate(root_pos[full]))
            v = np.concatenate(root_vals[full])
            enc.byte_parts["root_fixes"] += _entropy_bytes(v, v.shape[1])


def components_for_target(x: np.ndarray, dec: C.Decomposition, bez: np.ndarray, markers: int,
                          target_units: float, criterion: str = "rms") -> int:
    """Fewest leading components of ``dec`` whose truncation error on the clips ``x``
    (n, 4 * 3M), marker distances on every frame, is within ``target_units``: their RMS
    (``criterion="rms"``) or their max (``"max"``). Bisection: both fall as components are
    added (the max up to ties)."""
    if criterion not in ("rms", "max"):
        raise ValueError(f"criterion must be 'rms' or 'max', not {criterion!r}")
    xc = x - dec.mean
    coef = xc @ dec.vectors                                  # (n, Dc), full orthonormal basis

    def err(k: int) -> float:
        resid = xc - coef[:, :k] @ dec.vectors[:, :k].T     # (n, Dc) control-point residual
        frames = np.einsum("lc,ncd->nld", bez, resid.reshape(len(x), 4, -1))
        d2 = np.sum(frames.reshape(len(x), len(bez), markers, 3) ** 2, axis=-1)
        return float(np.sqrt(d2.max() if criterion == "max" else d2.mean()))

    d = x.shape[1]
    if err(0) <= target_units:
        return 0
    lo, hi = 0, min(d, max(len(x) - 1, 1))  # beyond n - 1 components the residual is zero
    if err(hi) > target_units:
        return hi
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if err(mid) <= target_units:
            hi = mid
        else:
            lo = mid
    return hi


# ------------------------------------------------------------------------ decoding
def decode_markers(enc: Encoded, i: int, markers: int) -> tuple[np.ndarray, np.ndarray]:
    """Aligned markers (F-1, M, 3) and root rows (F-1, R) of file ``i``, from the code only."""
    fc = enc.files[i]
    length = enc.config.clip_frames
    bez = bezier_matrix(length)
    n = len(fc.clip_ids)
    ctrl = np.empty((n, 4 * 3 * markers))
    for c in np.unique(fc.clip_ids):
        sel = fc.clip_ids == c
        cl = enc.clusters[c]
        ctrl[sel] = cl.mean + cl.coef[fc.clip_rows[sel]] @ cl.axes.T
    curves = np.einsum("lc,ncd->nld", bez, ctrl.reshape(n, 4, -1))
    rows = join_clips(curves, fc.frames - 1)
    root_curves = np.einsum("lc,ncd->nld", bez, fc.root_ctrl)
    root = join_clips(root_curves, fc.frames - 1)
    if len(fc.root_fix_frame):
        root[fc.root_fix_frame] += fc.root_fix_value
    out = rows.reshape(len(rows), markers, 3)
    out[fc.fix_index[:, 0], fc.fix_index[:, 1]] += fc.fix_value
    return out, root


def decode(enc: Encoded, sources: list[Source]) -> list[Motion]:
    """Decoded motions (local rotations on each file's skeleton; frame 0 from its channels)."""
    out = []
    for i, s in enumerate(sources):
        fc = enc.files[i]
        layout = s.prepared.layout
        markers, root = decode_markers(enc, i, layout.marker_count)
        body = P.from_markers(markers, _root_track(root, fc.root_full), layout, s.motion)
        first = Motion.from_channels(s.motion.skeleton, fc.frame0[None], s.motion.frame_time)
        rot = np.concatenate([first.rotations, body.rotations])
        trans = np.concatenate([first.translations, body.translations])
        out.append(Motion(s.motion.skeleton, rot, trans, s.motion.frame_time, s.motion.name))
    return out


# ------------------------------------------------------------------------ measuring
def evaluate(enc: Encoded, sources: list[Source]) -> dict:
    """Set-level errors (cm) of the decoded poses on every frame, and the marker-position
    (no skeleton fit) error of the joints, against the originals."""
    reports: list[ErrorReport] = []
    pos_err = []
    for i, (s, dm) in enumerate(zip(sources, decode(enc, sources))):
        metric = ErrorMetric(s.cm_per_unit, s.height_units)
        drot, dpos = forward_kinematics(dm.skeleton, dm.rotations, dm.translations)
        reports.append(metric.evaluate(s.motion.skeleton, (s.world_rot, s.world_pos), (drot, dpos)))
        # Joint positions straight from the decoded markers (what Arikan's decoder outputs).
        markers, root = decode_markers(enc, i, s.prepared.layout.marker_count)
        track = _root_track(root, enc.files[i].root_full)
        src = s.prepared.layout.position_source
        aligned = np.where((src >= 0)[None, :, None], markers[:, np.maximum(src, 0)], 0.0)
        world = track.translation[:, None] + R.quat_rotate(track.removed_rotation()[:, None], aligned)
        pos_err.append(np.linalg.norm(world - s.world_pos[1:], axis=-1).ravel() * s.cm_per_unit)
    err = combine(reports)
    pe = np.concatenate(pos_err)
    err.update({"pos_max_cm": float(pe.max()), "pos_p99_cm": float(np.percentile(pe, 99)),
                "pos_mean_cm": float(pe.mean())})
    return err


def run(sources: list[Source], cfg: Config) -> dict:
    """Encode, decode, measure: one RD row."""
    t0 = time.perf_counter()
    enc = encode(sources, cfg)
    t1 = time.perf_counter()
    err = evaluate(enc, sources)
    size = size_report([s.motion for s in sources], enc.total_bytes)
    ks = [cl.axes.shape[1] for cl in enc.clusters]
    return {"tolerance_cm": cfg.target_cm, "asset_bytes": enc.total_bytes,
            **{k: size.as_dict()[k] for k in ("ratio_bvh", "ratio_acl", "bytes_per_second",
                                              "raw_bvh_bytes", "raw_acl_bytes", "seconds")},
            **err, "bytes_by_part": enc.byte_parts, "clusters": len(enc.clusters),
            "components_per_cluster": ks, "encode_seconds": t1 - t0,
            "eval_seconds": time.perf_counter() - t1}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--data", type=Path, default=DEV_SET)
    ap.add_argument("--clips", nargs="*", default=None, help="clip names (file stems); default all")
    ap.add_argument("--targets", type=float, nargs="+", default=[0.5, 1.0, 2.0, 4.0, 8.0], metavar="CM")
    ap.add_argument("--clusters", type=int, default=Config.clusters)
    ap.add_argument("--criterion", choices=("rms", "max"), default=Config.criterion)
    ap.add_argument("--clip-frames", type=int, default=Config.clip_frames)
    ap.add_argument("--coef-step-frac", type=float, default=Config.coef_step_frac)
    ap.add_argument("--sparse-frac", type=float, default=0.0,
                    help="> 0: add our sparse residual fixes (not Arikan's) above this x target")
    ap.add_argument("--fix-cm", type=float, default=0.0,
                    help="> 0: sparse fixes (our extension) above this many cm at every target")
    ap.add_argument("--units", default="cmu")
    ap.add_argument("--out", type=Path, default=None,
                    help="result JSON (a .md beside it); default bench/results/clip_pca.json, or "
                         "clip_pca_sparse.json with --sparse-frac; '-' to print only")
    args = ap.parse_args(argv)

    paths = sorted(args.data.glob("*.bvh"))
    if args.clips:
        paths = [p for p in paths if p.stem in set(args.clips)]
    if not paths:
        print("no clips", file=sys.stderr)
        return 1
    motions = [read_bvh(p) for p in paths]
    cm = resolve_units(motions[0].skeleton, args.units).cm_per_unit
    sources = prepare(motions, cm)
    frames = sum(m.frame_count for m in motions)
    print(f"{len(motions)} clips, {frames} frames", file=sys.stderr)
    rows = []
    for t in args.targets:
        cfg = Config(target_cm=t, clusters=args.clusters, clip_frames=args.clip_frames,
                     coef_step_frac=args.coef_step_frac, sparse_frac=args.sparse_frac,
                     criterion=args.criterion, fix_cm=args.fix_cm)
        row = run(sources, cfg)
        rows.append(row)
        print(json.dumps({k: v for k, v in row.items() if not isinstance(v, (list, dict))}), file=sys.stderr)
    sparse = args.sparse_frac > 0 or args.fix_cm > 0
    codec = "clip_pca+sparse" if sparse else "clip_pca"
    out = args.out or HERE / "results" / ("clip_pca_sparse.json" if sparse else "clip_pca.json")
    label = f"{codec}, {args.clusters} cluster{'s' if args.clusters != 1 else ''}"
    if args.fix_cm > 0:
        label += f", fixes > {args.fix_cm:g} cm"
    elif args.sparse_frac > 0:
        label += f", fixes > {args.sparse_frac:g} x target"
    report = {"codec": codec, "label": label, "data": str(args.data), "clips": len(motions),
              "clip_names": [m.name for m in motions], "frames": frames,
              "options": {"clusters": args.clusters, "criterion": args.criterion, "clip_frames": args.clip_frames,
                          "coef_step_frac": args.coef_step_frac, "sparse_frac": args.sparse_frac, "fix_cm": args.fix_cm,
                          "sparse_step_frac": Config.sparse_step_frac,
                          "root_step_frac": Config.root_step_frac, "mean_bits": Config.mean_bits,
                          "axis_bits": Config.axis_bits, "entropy": "mocodec.entropy (runtime range coder)"},
              "error_path": "markers -> joint rotations (Gram-Schmidt) -> FK on the file's skeleton; "
                            "pos_* = joint marker positions without the skeleton fit",
              "machine": platform.machine(), "python": platform.python_version(), "rows": rows}
    md = markdown(report)
    print(md)
    if str(out) != "-":
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(json.dumps(report, indent=2))
        out.with_suffix(".md").write_text(md)
    return 0


def markdown(report: dict) -> str:
    head = ["target cm", "bytes", "ratio BVH f32", "ratio ACL 40B", "max cm", "p99 cm", "mean cm",
            "pos max cm", "pos mean cm", "PCs per cluster", "bytes: coef / axes / means / root / fixes"]
    o = report["options"]
    extra = ""
    if o.get("fix_cm", 0) > 0:
        extra = f" + sparse residual fixes of markers off by more than {o['fix_cm']} cm (our extension)"
    elif o.get("sparse_frac", 0) > 0:
        extra = f" + sparse residual fixes above {o['sparse_frac']} x target (our extension)"
    lines = [f"`{report['codec']}` (Arikan 2006 as seed 003 describes it{extra}) on {report['clips']} clips "
             f"({report['frames']:,} frames) from `{report['data']}`; {o['clusters']} cluster(s), "
             f"{o['clip_frames']}-frame clips, PCs per cluster by the {o.get('criterion', 'max')} "
             f"marker error of the truncation <= target, coefficient step {o['coef_step_frac']} x target", "",
             "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in report["rows"]:
        b = r["bytes_by_part"]
        lines.append("| " + " | ".join([
            f"{r['tolerance_cm']:g}", f"{r['asset_bytes']:,}", f"{r['ratio_bvh']:.1f}",
            f"{r['ratio_acl']:.1f}", f"{r['max_cm']:.3f}", f"{r['p99_cm']:.3f}", f"{r['mean_cm']:.3f}",
            f"{r['pos_max_cm']:.3f}", f"{r['pos_mean_cm']:.3f}",
            " ".join(str(k) for k in r["components_per_cluster"]),
            f"{b['coefficients']:,} / {b['pca_axes']:,} / {b['pca_means']:,} / {b['root']:,} / "
            f"{b.get('fix_positions', 0) + b.get('fix_values', 0) + b.get('root_fixes', 0):,}"]) + " |")
    lines += ["", "max / p99 / mean: world positions of every joint and end site on every frame, "
                  "after the markers are turned into joint rotations on the file's skeleton; "
                  "pos: the decoded joint markers themselves (no skeleton fit, frames 1..F-1)."]
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    sys.exit(main())
