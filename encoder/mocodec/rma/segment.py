"""Behaviour segmentation and grouping (seed 003 §4.1).

Cuts: probabilistic PCA in the manner of Barbic et al. (2004), as the seed describes it. A model
fitted to the frames since the last cut predicts the next window; while the motion keeps its
behaviour the window's mean Mahalanobis distance ``H`` changes slowly as the model grows, and a
new behaviour makes it jump. A cut is placed where the growth of ``H`` exceeds its running mean
by ``k_sigma`` standard deviations. The scan runs forward and backward (a chaotic start can
over-fit the first model) and the two cut sets are unified.

Grouping: segments are compared by eq. 1 (their first ``K`` principal axes, weighted, and their
normalised mean postures, ``alpha`` between them) and grouped by normalized cut (spectral
clustering on a precomputed affinity); clip boundaries are always cuts.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Callable

import numpy as np
from sklearn.cluster import SpectralClustering


@dataclass(frozen=True)
class PPCASettings:
    """Scan settings, in frames (defaults are Barbic's values for 120 Hz).

    ``init``: frames of the first model after a cut; ``window``: frames predicted; ``step``:
    frames the model grows per test; ``variance``: fraction the PPCA latent space keeps;
    ``k_sigma``: jump threshold; ``min_gap``: cuts closer than this are unified into one;
    ``reduce_variance``: the scan runs on the clip's PCA subspace keeping this fraction, which
    changes nothing the test can see but makes each eigen-decomposition small.
    """

    init: int = 150
    window: int = 150
    step: int = 10
    variance: float = 0.9
    k_sigma: float = 3.0
    min_gap: int = 60
    reduce_variance: float = 0.9999


@dataclass
class Segment:
    clip: int   # index of the clip in the library
    start: int  # first frame
    stop: int   # one past the last frame

    @property
    def frames(self) -> int:
        return self.stop - self.start


def _reduce(x: np.ndarray, keep: float) -> np.ndarray:
    """Coordinates of ``x`` (F, D) in its own PCA subspace keeping ``keep`` of the variance."""
    xc = x - x.mean(axis=0)
    lam, vec = np.linalg.eigh(xc.T @ xc)
    lam, vec = lam[::-1], vec[:, ::-1]
    total = max(lam.sum(), 1e-300)
    r = int(np.searchsorted(np.cumsum(lam) / total, keep) + 1)
    return xc @ vec[:, :min(r, x.shape[1])]


def _scan(x: np.ndarray, s: PPCASettings) -> list[int]:
    """Forward PPCA cuts of ``x`` (F, d)."""
    frames, d = x.shape
    cuts: list[int] = []
    start = 0
    while start + s.init + s.window <= frames:
        k = s.init
        block = x[start:start + k]
        total = block.sum(axis=0)
        outer = block.T @ block
        hs: list[float] = []
        cut = -1
        while start + k + s.window <= frames:
            mean = total / k
            cov = outer / k - np.outer(mean, mean)
            lam, vec = np.linalg.eigh(cov)
            lam, vec = np.maximum(lam[::-1], 0.0), vec[:, ::-1]
            tot = max(lam.sum(), 1e-300)
            r = min(int(np.searchsorted(np.cumsum(lam) / tot, s.variance) + 1), d - 1)
            # PPCA noise = mean discarded variance (floored: a frozen pose has none).
            sigma2 = max(float(lam[r:].mean()), 1e-9 * tot / d, 1e-12)
            y = x[start + k:start + k + s.window] - mean
            proj = y @ vec[:, :r]
            resid = np.sum(y * y, axis=1) - np.sum(proj * proj, axis=1)
            maha = np.sum(proj * proj / np.maximum(lam[:r], sigma2), axis=1) + np.maximum(resid, 0) / sigma2
            hs.append(float(maha.mean()))
            if len(hs) >= 4:
                dh = np.diff(hs)
                prev = dh[:-1]
                if dh[-1] > prev.mean() + s.k_sigma * max(prev.std(), 1e-12) and dh[-1] > 0:
                    # H averages the whole window, so it starts rising as soon as the new
                    # behaviour enters the window's far end: the boundary lies inside the
                    # window. Place the cut at the first run of ``step`` frames that all lie
                    # farther from the model than any of its own last ``window`` frames.
                    own = x[start + max(k - s.window, 0):start + k] - mean
                    op = own @ vec[:, :r]
                    ores = np.sum(own * own, axis=1) - np.sum(op * op, axis=1)
                    tau = float(np.max(np.sum(op * op / np.maximum(lam[:r], sigma2), axis=1)
                                       + np.maximum(ores, 0) / sigma2))
                    cut = start + k + _first_run(maha > tau, s.step)
                    break
            new = x[start + k:start + k + s.step]
            total += new.sum(axis=0)
            outer += new.T @ new
            k += s.step
        if cut < 0:
            break
        cuts.append(cut)
        start = cut
    return cuts


def _first_run(flags: np.ndarray, run: int) -> int:
    """Index of the first run of ``run`` True values (the middle of ``flags`` if none)."""
    if len(flags) >= run:
        counts = np.convolve(flags.astype(np.int64), np.ones(run, dtype=np.int64), "valid")
        hit = np.flatnonzero(counts == run)
        if hit.size:
            return int(hit[0])
    return len(flags) // 2


def unify_cuts(forward: list[int], backward: list[int], min_gap: int) -> list[int]:
    """Union of the two cut sets; cuts closer than ``min_gap`` become their mean (the two scans
    see the same boundary a few frames apart)."""
    allc = np.sort(np.asarray(forward + backward, dtype=np.int64))
    if allc.size == 0:
        return []
    groups = np.concatenate(([0], np.cumsum(np.diff(allc) >= min_gap)))
    return [int(round(allc[groups == g].mean())) for g in range(int(groups[-1]) + 1)]


def ppca_cuts(x: np.ndarray, settings: PPCASettings = PPCASettings()) -> list[int]:
    """Unified forward and backward cuts (frame indices, sorted, inside (0, F))."""
    frames = len(x)
    if frames < settings.init + settings.window:
        return []
    z = _reduce(np.asarray(x, dtype=np.float64), settings.reduce_variance)
    fwd = _scan(z, settings)
    bwd = [frames - c for c in _scan(z[::-1].copy(), settings)]
    cuts = unify_cuts(fwd, bwd, settings.min_gap)
    return [c for c in cuts if settings.min_gap // 2 <= c <= frames - settings.min_gap // 2]


def segment_library(clips: list[np.ndarray], settings: PPCASettings = PPCASettings(),
                    map_clips: Callable[[Callable[[np.ndarray], list[int]], list[np.ndarray]], list[list[int]]] | None = None
                    ) -> list[Segment]:
    """Segments of every clip (clip boundaries are cuts). ``map_clips(fn, clips)`` runs the
    per-clip cut search (a runner's ``map``: the clips' cuts are independent); None: in turn."""
    cut = functools.partial(ppca_cuts, settings=settings)
    cuts = map_clips(cut, clips) if map_clips else [cut(x) for x in clips]
    out = []
    for ci, (x, inner) in enumerate(zip(clips, cuts)):
        bounds = [0] + inner + [len(x)]
        out.extend(Segment(ci, a, b) for a, b in zip(bounds[:-1], bounds[1:]) if b > a)
    return out


# ------------------------------------------------------------------------ grouping (eq. 1)
@dataclass
class SegmentFeature:
    axes: np.ndarray  # (K, D) unit principal axes, largest first
    mean: np.ndarray  # (D,) mean posture normalised to unit length


def segment_feature(x: np.ndarray, k: int = 5) -> SegmentFeature:
    mean = x.mean(axis=0)
    xc = x - mean
    # SVD of the (frames, D) block: only the first K right singular vectors are needed.
    _, _, vt = np.linalg.svd(xc, full_matrices=False)
    axes = np.zeros((k, x.shape[1]))
    axes[:min(k, len(vt))] = vt[:k]
    return SegmentFeature(axes, mean / max(np.linalg.norm(mean), 1e-300))


def seg_distance(features: list[SegmentFeature], alpha: float = 0.6, k: int = 5) -> np.ndarray:
    """Eq. 1 for every pair (S, S). Axes are sign-free, so each axis term takes the nearer of
    ``a - b`` and ``a + b``; ``w(p)`` falls linearly so the leading axes weigh most."""
    axes = np.stack([f.axes[:k] for f in features])    # (S, K, D)
    means = np.stack([f.mean for f in features])        # (S, D)
    w = np.arange(k, 0, -1, dtype=np.float64)
    w /= w.sum()
    dots = np.einsum("ipd,jpd->ijp", axes, axes)        # (S, S, K)
    norms2 = np.sum(axes * axes, axis=2)                # (S, K) 1 (or 0 for missing axes)
    ax_d = np.sqrt(np.maximum(norms2[:, None] + norms2[None] - 2.0 * np.abs(dots), 0.0))
    mp = np.linalg.norm(means[:, None] - means[None], axis=2)
    return alpha * np.einsum("p,ijp->ij", w, ax_d) + (1.0 - alpha) * mp


def affinity(d: np.ndarray, neighbours: int = 3) -> np.ndarray:
    """Gaussian affinity with local scaling (each segment's width is its distance to its
    ``neighbours``-th nearest segment): with one global width, eq. 1 distances on CMU clips
    (0.3-0.9) leave every affinity alike and the cut cannot separate anything."""
    s = len(d)
    kn = min(neighbours, s - 1)
    sig = np.maximum(np.sort(d, axis=1)[:, kn], 1e-12)
    return np.exp(-(d * d) / np.outer(sig, sig))


def ncut_labels(aff: np.ndarray, n_groups: int) -> np.ndarray:
    """Normalized cut into ``n_groups`` (spectral clustering, deterministic discretisation),
    labels numbered by first appearance."""
    if n_groups <= 1:
        return np.zeros(len(aff), dtype=np.int64)
    sc = SpectralClustering(n_clusters=n_groups, affinity="precomputed",
                            assign_labels="discretize", random_state=0)
    labels = sc.fit_predict(aff)
    _, first = np.unique(labels, return_index=True)
    rank = np.empty(labels.max() + 1, dtype=np.int64)
    rank[labels[np.sort(first)]] = np.arange(len(first))
    return rank[labels]


def group_segments(features: list[SegmentFeature], alpha: float = 0.6, k: int = 5,
                   max_groups: int = 12, n_groups: int | None = None,
                   cost: Callable[[np.ndarray], float] | None = None) -> np.ndarray:
    """Group label per segment by normalized cut on the eq. 1 distance.

    The seed does not say how many groups. With ``n_groups`` given, that many; else with a
    ``cost`` (labels -> estimated bits, e.g. :func:`pca_group_cost`) the count from 1 to
    ``max_groups`` whose grouping costs least, which is what grouping is for here; else the
    largest eigengap of the normalised affinity.
    """
    s = len(features)
    if s <= 1:
        return np.zeros(s, dtype=np.int64)
    aff = affinity(seg_distance(features, alpha, k))
    top = min(max_groups, s)
    if n_groups is not None:
        return ncut_labels(aff, min(n_groups, s))
    if cost is not None:
        best, best_cost = None, np.inf
        for n in range(1, top + 1):
            labels = ncut_labels(aff, n)
            c = cost(labels)
            if c < best_cost:
                best, best_cost = labels, c
        return best
    deg = aff.sum(axis=1)
    ev = np.sort(np.linalg.eigvalsh(aff / np.sqrt(np.outer(deg, deg))))[::-1]
    gaps = ev[:top - 1] - ev[1:top]
    return ncut_labels(aff, int(np.argmax(gaps) + 1) if len(gaps) else 1)


def pca_group_cost(blocks: list[np.ndarray], variance: float = 0.95,
                   coef_bits_per_frame: float = 1.5, axis_bits: int = 12) -> Callable[[np.ndarray], float]:
    """Cost model for choosing the group count: per group, ``k`` components (for ``variance``)
    cost ``k * frames * coef_bits_per_frame`` for the coefficient curves (about one 8-bit key
    per 5 frames, what the spline codec places on CMU at 1 cm) plus ``k * D * axis_bits`` for
    the axes and ``D * 16`` for the mean (§5.4). ``blocks`` are the segments' frames (F_s, D)."""
    d = blocks[0].shape[1]
    # Per segment sufficient statistics, so any grouping's covariance costs O(S D^2).
    counts = np.array([len(b) for b in blocks], dtype=np.float64)
    sums = np.stack([b.sum(axis=0) for b in blocks])
    outers = np.stack([b.T @ b for b in blocks])

    def cost(labels: np.ndarray) -> float:
        total = 0.0
        for g in np.unique(labels):
            sel = labels == g
            n = counts[sel].sum()
            mean = sums[sel].sum(axis=0) / n
            cov = outers[sel].sum(axis=0) / n - np.outer(mean, mean)
            lam = np.sort(np.maximum(np.linalg.eigvalsh(cov), 0.0))[::-1]
            kk = int(np.searchsorted(np.cumsum(lam) / max(lam.sum(), 1e-300), variance) + 1)
            total += kk * (n * coef_bits_per_frame + d * axis_bits) + d * 16
        return total

    return cost
