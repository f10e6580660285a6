"""Repeated motion analysis (seed 003 §4.2): self-distance plots, similar-posture paths and the
greedy choice of primary, repeated and unique clips.

Memory stays sub-quadratic in frames. The plot is never held whole: it is scanned in square
tiles of the upper half (``tile`` pixels a side, one pixel of halo so minima at tile edges see
their neighbours), and only labelled pixels (below the threshold and a 1-D minimum along a row
or a column) are kept, as sparse arrays. Long groups are scanned at a lower resolution: one
pixel per ``step`` frames, with ``step`` chosen so a side never exceeds ``max_side`` pixels,
which bounds the kept pixels by a constant however long the group is.
"""
from __future__ import annotations

import heapq
from dataclasses import dataclass, field

import numpy as np

PRIMARY, REPEATED, UNIQUE = "primary", "repeated", "unique"


@dataclass(frozen=True)
class RepeatSettings:
    """Settings (times in seconds, distances in coefficient units unless noted).

    ``threshold``: pixels farther apart are suppressed (step 1 of §4.2.1); ``min_lag``: pixels
    nearer the diagonal than this are the motion matched with itself, not a repetition;
    ``bridge``: longest gap a path may jump to merge with the next (300 ms); ``min_path``:
    shorter paths (Manhattan length) are dropped (600 ms); ``min_clip``: shorter unique and
    repeated clips merge into a neighbour (200 ms); ``pri_overhead`` / ``rep_overhead``: the
    small per-clip constants added to eq. 2 / eq. 3; ``tile``: tile side in pixels;
    ``step`` / ``max_side``: plot resolution.
    """

    threshold: float
    min_lag: float = 0.25
    bridge: float = 0.3
    min_path: float = 0.6
    min_clip: float = 0.2
    pri_overhead: float = 0.0
    rep_overhead: float = 0.0
    tile: int = 256
    step: int = 2
    max_side: int = 4096


@dataclass
class PlotPixels:
    """Labelled pixels of the upper half of a self-distance plot (sparse)."""

    i: np.ndarray       # row pixel (int64)
    j: np.ndarray       # column pixel, j > i
    d: np.ndarray       # distance (float32)
    is_2d: np.ndarray   # minimum along both the row and the column
    step: int           # frames per pixel
    side: int           # pixels per side
    peak_tile_bytes: int = 0  # largest dense block the scan allocated

    def keys(self) -> np.ndarray:
        return self.i * self.side + self.j


def plot_step(frames: int, s: RepeatSettings) -> int:
    return max(s.step, -(-frames // s.max_side))


def scan_plot(z: np.ndarray, threshold: float, min_lag_px: int, step: int, tile: int) -> PlotPixels:
    """Scan the self-distance plot of coefficient rows ``z`` (F, k) at one pixel per ``step``
    frames, tile by tile, keeping labelled pixels only."""
    zs = np.asarray(z, dtype=np.float64)[::step]
    n = len(zs)
    sq = np.sum(zs * zs, axis=1)
    out_i, out_j, out_d, out_2 = [], [], [], []
    peak = 0
    for i0 in range(0, n, tile):
        i1 = min(i0 + tile, n)
        # Only tiles that reach past the diagonal band hold upper-half pixels.
        for j0 in range((i0 + min_lag_px) // tile * tile, n, tile):
            j1 = min(j0 + tile, n)
            if j1 - 1 < i0 + min_lag_px:
                continue
            ra, rb = max(i0 - 1, 0), min(i1 + 1, n)
            ca, cb = max(j0 - 1, 0), min(j1 + 1, n)
            # Halo of +inf outside the plot so edge pixels compare only with real neighbours.
            d = np.full((i1 - i0 + 2, j1 - j0 + 2), np.inf)
            blk = sq[ra:rb, None] + sq[None, ca:cb] - 2.0 * zs[ra:rb] @ zs[ca:cb].T
            d[ra - (i0 - 1):rb - (i0 - 1), ca - (j0 - 1):cb - (j0 - 1)] = np.sqrt(np.maximum(blk, 0.0))
            peak = max(peak, d.nbytes + blk.nbytes)
            c = d[1:-1, 1:-1]
            row_min = (c <= d[1:-1, :-2]) & (c <= d[1:-1, 2:])
            col_min = (c <= d[:-2, 1:-1]) & (c <= d[2:, 1:-1])
            ii, jj = np.meshgrid(np.arange(i0, i1), np.arange(j0, j1), indexing="ij")
            keep = (c < threshold) & (row_min | col_min) & (jj - ii >= min_lag_px)
            if keep.any():
                out_i.append(ii[keep])
                out_j.append(jj[keep])
                out_d.append(c[keep].astype(np.float32))
                out_2.append((row_min & col_min)[keep])
    cat = (lambda a, t: np.concatenate(a) if a else np.zeros(0, dtype=t))
    return PlotPixels(cat(out_i, np.int64), cat(out_j, np.int64), cat(out_d, np.float32),
                      cat(out_2, bool), step, n, peak)


# ------------------------------------------------------------------------ similar-posture paths
@dataclass
class Path:
    """A similar-posture path at full frame resolution: frames ``i[k]`` and ``j[k]`` match,
    both non-decreasing, ``j > i``."""

    i: np.ndarray
    j: np.ndarray

    @property
    def manhattan(self) -> int:
        return int(self.i[-1] - self.i[0] + self.j[-1] - self.j[0])


def _segment_of(frames: np.ndarray, breaks: np.ndarray) -> np.ndarray:
    return np.searchsorted(breaks, frames, side="right")


def grow_paths(px: PlotPixels, breaks_px: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    """Steps 3-5 of §4.2.1 at pixel resolution: from each unassigned 2-D minimum (most similar
    first), follow the cheapest labelled unassigned neighbour toward the lower right and toward
    the upper left; the explored pixels form a path. A path never crosses a segment break."""
    keys = px.keys()
    order = np.argsort(keys, kind="stable")
    skeys = keys[order]
    taken = np.zeros(len(keys), dtype=bool)
    seg = _segment_of(np.arange(px.side), breaks_px)

    def lookup(cands: np.ndarray) -> np.ndarray:
        pos = np.searchsorted(skeys, cands)
        pos = np.minimum(pos, len(skeys) - 1)
        hit = skeys[pos] == cands
        return np.where(hit, order[pos], -1)

    paths = []
    seeds = np.flatnonzero(px.is_2d)
    seeds = seeds[np.lexsort((keys[seeds], px.d[seeds]))]
    moves = {+1: np.array([[1, 1], [1, 0], [0, 1]]), -1: np.array([[-1, -1], [-1, 0], [0, -1]])}
    for s in seeds:
        if taken[s]:
            continue
        taken[s] = True
        halves = {}
        for direction, mv in moves.items():
            ci, cj = int(px.i[s]), int(px.j[s])
            trail = []
            while True:
                ni, nj = ci + mv[:, 0], cj + mv[:, 1]
                ok = (ni >= 0) & (nj < px.side) & (nj > ni)
                ok &= (seg[np.clip(ni, 0, px.side - 1)] == seg[ci]) & (seg[np.clip(nj, 0, px.side - 1)] == seg[cj])
                idx = np.where(ok, lookup(ni * px.side + nj), -1)
                valid = idx >= 0
                if valid.any():
                    valid &= ~taken[np.maximum(idx, 0)]
                if not valid.any():
                    break
                best = idx[valid][np.argmin(px.d[idx[valid]])]
                taken[best] = True
                ci, cj = int(px.i[best]), int(px.j[best])
                trail.append((ci, cj))
            halves[direction] = trail
        pts = halves[-1][::-1] + [(int(px.i[s]), int(px.j[s]))] + halves[+1]
        arr = np.asarray(pts, dtype=np.int64)
        paths.append((arr[:, 0], arr[:, 1]))
    return paths


def bridge_paths(paths: list[tuple[np.ndarray, np.ndarray]], max_gap: int,
                 breaks_px: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
    """Step 6: join a path to the nearest path starting at most ``max_gap`` (Manhattan,
    pixels) below and right of its end, in the same segments; repeat until nothing joins."""
    paths = list(paths)
    changed = True
    while changed and len(paths) > 1:
        changed = False
        starts = np.array([[p[0][0], p[1][0]] for p in paths])
        ends = np.array([[p[0][-1], p[1][-1]] for p in paths])
        seg_s = _segment_of(starts, breaks_px)
        seg_e = _segment_of(ends, breaks_px)
        used = np.zeros(len(paths), dtype=bool)
        merged = []
        for a in np.argsort(starts[:, 0] * 1_000_000 + starts[:, 1], kind="stable"):
            if used[a]:
                continue
            di = starts[:, 0] - ends[a, 0]
            dj = starts[:, 1] - ends[a, 1]
            gap = di + dj
            ok = (di >= 0) & (dj >= 0) & (gap > 0) & (gap <= max_gap) & ~used
            ok &= np.all(seg_s == seg_e[a], axis=1)
            ok[a] = False
            if ok.any():
                b = int(np.flatnonzero(ok)[np.argmin(gap[ok])])
                used[a] = used[b] = True
                merged.append((np.concatenate((paths[a][0], paths[b][0])),
                               np.concatenate((paths[a][1], paths[b][1]))))
                changed = True
            else:
                used[a] = True
                merged.append(paths[a])
        paths = merged
    return paths


def similar_posture_paths(z: np.ndarray, breaks: np.ndarray, frame_time: float,
                          s: RepeatSettings) -> tuple[list[Path], PlotPixels]:
    """§4.2.1 on coefficient rows ``z`` (F, k); ``breaks`` are the frames where a new segment
    starts (paths never cross them). Paths come back at full frame resolution."""
    step = plot_step(len(z), s)
    fps = 1.0 / frame_time
    min_lag_px = max(1, int(round(s.min_lag * fps / step)))
    px = scan_plot(z, s.threshold, min_lag_px, step, s.tile)
    breaks_px = np.unique(-(-np.asarray(breaks, dtype=np.int64) // step))
    raw = grow_paths(px, breaks_px)
    joined = bridge_paths(raw, max(1, int(s.bridge * fps / step)), breaks_px)
    min_len = s.min_path * fps
    out = []
    for pi, pj in joined:
        p = Path(np.minimum(pi * step, len(z) - 1), np.minimum(pj * step, len(z) - 1))
        if p.manhattan >= min_len:
            out.append(p)
    out.sort(key=lambda p: (int(p.i[0]), int(p.j[0])))
    return out, px


# ------------------------------------------------------------------------ clip selection
@dataclass
class Clip:
    kind: str
    start: int
    stop: int
    primary: int = -1                    # index of the referred primary clip (repeated clips)
    ref: np.ndarray | None = None        # (stop - start,) referred frame (float), repeated only

    @property
    def frames(self) -> int:
        return self.stop - self.start


@dataclass
class RepeatAnalysis:
    clips: list[Clip]
    paths: list[Path]
    pixels: int
    step: int
    peak_tile_bytes: int
    stats: dict[str, float] = field(default_factory=dict)

    def frames_of(self, kind: str) -> int:
        return sum(c.frames for c in self.clips if c.kind == kind)


def _dist(z: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.linalg.norm(z[a] - z[b], axis=-1)


def _interp_rows(z: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """Coefficients at fractional frames ``ref`` (linear between frames)."""
    lo = np.clip(np.floor(ref).astype(np.int64), 0, len(z) - 1)
    hi = np.minimum(lo + 1, len(z) - 1)
    t = (ref - lo)[:, None]
    return z[lo] * (1.0 - t) + z[hi] * t


def pri_cost(z: np.ndarray, s: int, e: int, init: int, overhead: float) -> float:
    """Eq. 2 for frames [s, e): spread of the frames around the middle one, times the length,
    plus the middle frame's distance from the initial posture."""
    f = np.arange(s, e)
    m = (s + e - 1) // 2
    dm = _dist(z, np.full(len(f), m), f)
    return float(dm.std() * len(f) + np.linalg.norm(z[m] - z[init]) + overhead)


def rep_cost(z: np.ndarray, s: int, e: int, ref: np.ndarray, overhead: float) -> float:
    """Eq. 3 for frames [s, e) referring to ``ref`` (fractional frames)."""
    d = np.linalg.norm(z[s:e] - _interp_rows(z, ref), axis=1)
    return float(d.std() * (e - s) + overhead)


def _monotone_map(src: np.ndarray, dst: np.ndarray, frames: np.ndarray) -> np.ndarray:
    """Interpolate the path's map ``src -> dst`` at ``frames`` (duplicates of src averaged)."""
    u, inv = np.unique(src, return_inverse=True)
    mean = np.bincount(inv, weights=dst) / np.bincount(inv)
    return np.interp(frames, u, mean)


def _images(paths: list[Path], s: int, e: int) -> list[tuple[int, int, np.ndarray]]:
    """Every image of [s, e) through a path, either way: (start, stop, ref per frame)."""
    out = []
    for p in paths:
        for src, dst in ((p.i, p.j), (p.j, p.i)):
            sel = (src >= s) & (src < e)
            if not sel.any():
                continue
            a, b = int(dst[sel].min()), int(dst[sel].max()) + 1
            frames = np.arange(a, b, dtype=np.float64)
            ref = np.clip(_monotone_map(dst, src.astype(np.float64), frames), s, e - 1)
            out.append((a, b, ref))
    return out


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """Maximal runs [a, b) of True."""
    m = np.concatenate(([False], mask, [False])).astype(np.int8)
    d = np.diff(m)
    return list(zip(np.flatnonzero(d == 1).tolist(), np.flatnonzero(d == -1).tolist()))


def select_clips(z: np.ndarray, paths: list[Path], breaks: np.ndarray, frame_time: float,
                 s: RepeatSettings) -> list[Clip]:
    """§4.2.2: candidate intervals from projected path ends; greedily the interval of largest
    eq. 5 gain becomes a primary clip and its unlabelled images repeated clips; what is left
    are unique clips; unique and repeated clips under ``min_clip`` merge into a neighbour."""
    n = len(z)
    fps = 1.0 / frame_time
    min_rep = max(2, int(round(s.min_clip * fps)))
    cuts = {0, n, *[int(b) for b in breaks]}
    for p in paths:
        cuts.update((int(p.i[0]), int(p.i[-1]) + 1, int(p.j[0]), int(p.j[-1]) + 1))
    cuts = sorted(c for c in cuts if 0 <= c <= n)
    label = np.zeros(n, dtype=bool)
    clips: list[Clip] = []

    def evaluate(a: int, b: int) -> tuple[float, list[tuple[int, int, np.ndarray]]]:
        pc = pri_cost(z, a, b, 0, s.pri_overhead)
        reps = []
        free = ~label.copy()
        free[a:b] = False
        for ia, ib, ref in _images(paths, a, b):
            for ra, rb in _runs(free[ia:ib]):
                if rb - ra < min_rep:
                    continue
                r = ref[ra:rb]
                lo, hi = ia + ra, ia + rb
                rc = rep_cost(z, lo, hi, r, s.rep_overhead)
                pr = pri_cost(z, lo, hi, 0, s.pri_overhead)
                if rc < pr:
                    reps.append((lo, hi, r, pr, rc))
                    free[lo:hi] = False  # images of other paths may not claim these frames
        if not reps:
            return 1.0, []
        gain = (pc + sum(r[3] for r in reps)) / max(pc + sum(r[4] for r in reps), 1e-12)
        return gain, [(r[0], r[1], r[2]) for r in reps]

    # Lazy greedy: gains only get re-evaluated when a candidate reaches the top of the heap.
    heap = []
    for a, b in zip(cuts[:-1], cuts[1:]):
        if b - a >= 2:
            g, _ = evaluate(a, b)
            if g > 1.0:
                heapq.heappush(heap, (-g, a, b))
    while heap:
        neg, a, b = heapq.heappop(heap)
        if label[a:b].any():
            # Part of it was taken: put the free residuals back as candidates.
            for ra, rb in _runs(~label[a:b]):
                if rb - ra >= 2:
                    g, _ = evaluate(a + ra, a + rb)
                    if g > 1.0:
                        heapq.heappush(heap, (-g, a + ra, a + rb))
            continue
        g, reps = evaluate(a, b)
        if not reps or g <= 1.0:
            continue
        if heap and g < -heap[0][0] - 1e-12:
            heapq.heappush(heap, (-g, a, b))  # stale: someone else is better now
            continue
        label[a:b] = True
        clips.append(Clip(PRIMARY, a, b))
        pid = len(clips) - 1
        for lo, hi, ref in reps:
            label[lo:hi] = True
            clips.append(Clip(REPEATED, lo, hi, pid, ref))
    # Unique clips: free runs, split at segment breaks.
    free = ~label
    brk = np.zeros(n + 1, dtype=bool)
    brk[np.asarray(list(breaks), dtype=np.int64)] = True
    for a, b in _runs(free):
        edges = [a] + [int(x) for x in np.flatnonzero(brk[a + 1:b]) + a + 1] + [b]
        clips.extend(Clip(UNIQUE, x, y) for x, y in zip(edges[:-1], edges[1:]))
    order = sorted(range(len(clips)), key=lambda k: clips[k].start)
    new_index = np.empty(len(clips), dtype=np.int64)
    new_index[order] = np.arange(len(clips))
    clips = [clips[k] for k in order]
    for c in clips:
        if c.kind == REPEATED:
            c.primary = int(new_index[c.primary])
    return _merge_short(clips, min_rep, breaks)


def _merge_short(clips: list[Clip], min_len: int, breaks: np.ndarray) -> list[Clip]:
    """Unique and repeated clips shorter than ``min_len`` join a neighbour in the same segment:
    a unique neighbour absorbs them as directly coded frames (preferred: no reference to
    extend); else a repeated neighbour extends its reference with slope 1 inside its
    primary. Primary clips are kept whole (others refer to them)."""
    seg = lambda f: int(np.searchsorted(np.asarray(breaks), f, side="right"))  # noqa: E731
    changed = True
    while changed:
        changed = False
        for k, c in enumerate(clips):
            if c.kind == PRIMARY or c.frames >= min_len:
                continue
            nbrs = [x for x in (k - 1, k + 1) if 0 <= x < len(clips)
                    and seg(clips[x].start) == seg(c.start)
                    and seg(clips[x].stop - 1) == seg(c.stop - 1)]
            if not nbrs:
                continue
            uniq = [x for x in nbrs if clips[x].kind == UNIQUE]
            reps = [x for x in nbrs if clips[x].kind == REPEATED]
            prim = [x for x in nbrs if clips[x].kind == PRIMARY]
            if uniq:
                t = uniq[0]
                clips[t] = Clip(UNIQUE, min(clips[t].start, c.start), max(clips[t].stop, c.stop))
            elif reps:
                t = reps[0]
                clips[t] = _extend_repeated(clips[t], c, clips[clips[t].primary])
            elif prim:
                # A short clip between primaries (or next to one) is coded directly: as a
                # unique clip it would stay short, so it becomes part of the primary.
                t = prim[0]
                clips[t] = Clip(PRIMARY, min(clips[t].start, c.start), max(clips[t].stop, c.stop))
            else:
                continue
            del clips[k]
            # Primary indices after k shift down by one.
            for x in clips:
                if x.kind == REPEATED and x.primary > k:
                    x.primary -= 1
            changed = True
            break
    return clips


def _extend_repeated(r: Clip, extra: Clip, primary: Clip) -> Clip:
    """Repeated clip ``r`` grown over the adjacent frames of ``extra`` (slope-1 reference)."""
    if extra.start >= r.stop:
        add = r.ref[-1] + np.arange(1, extra.frames + 1, dtype=np.float64)
        ref = np.concatenate((r.ref, add))
        start, stop = r.start, extra.stop
    else:
        add = r.ref[0] - np.arange(extra.frames, 0, -1, dtype=np.float64)
        ref = np.concatenate((add, r.ref))
        start, stop = extra.start, r.stop
    return Clip(REPEATED, start, stop, r.primary, np.clip(ref, primary.start, primary.stop - 1))


def analyse(z: np.ndarray, breaks: np.ndarray, frame_time: float, s: RepeatSettings) -> RepeatAnalysis:
    """Paths and clips of one group's coefficient rows ``z`` (F, k)."""
    paths, px = similar_posture_paths(z, breaks, frame_time, s)
    clips = select_clips(z, paths, breaks, frame_time, s)
    a = RepeatAnalysis(clips, paths, len(px.i), px.step, px.peak_tile_bytes)
    a.stats = {
        "frames": float(len(z)),
        "repeated_fraction": a.frames_of(REPEATED) / max(len(z), 1),
        "primary_fraction": a.frames_of(PRIMARY) / max(len(z), 1),
        "unique_fraction": a.frames_of(UNIQUE) / max(len(z), 1),
        "clips": float(len(clips)),
        "paths": float(len(paths)),
    }
    return a
