"""Catmull-Rom curves through keys at integer frames, and adaptive key placement.

The curve is the one docs/FORMAT.md specifies (cubic Hermite segments with finite-difference
tangents, end keys repeated), evaluated here in float64 for fitting; the runtime evaluates the
same formula in float32 and is the judge of the error.
"""
from __future__ import annotations

from typing import Callable

import numpy as np


def catmull_rom(key_frames: np.ndarray, key_values: np.ndarray, x: np.ndarray) -> np.ndarray:
    """Evaluate the curve through ``(key_frames[k], key_values[k])`` at positions ``x``.

    ``key_frames`` is strictly increasing (K,), ``key_values`` is (K, d); returns (len(x), d).
    """
    key_frames = np.asarray(key_frames, dtype=np.float64)
    key_values = np.asarray(key_values, dtype=np.float64)
    x = np.asarray(x, dtype=np.float64)
    k = len(key_frames)
    if k == 1:
        return np.broadcast_to(key_values[0], (len(x), key_values.shape[1])).copy()
    i1 = np.clip(np.searchsorted(key_frames, x, side="right") - 1, 0, k - 2)
    i0 = np.maximum(i1 - 1, 0)
    i2 = i1 + 1
    i3 = np.minimum(i1 + 2, k - 1)
    t0, t1, t2, t3 = key_frames[i0], key_frames[i1], key_frames[i2], key_frames[i3]
    p0, p1, p2, p3 = key_values[i0], key_values[i1], key_values[i2], key_values[i3]
    h = t2 - t1
    s = (x - t1) / h
    s2 = s * s
    s3 = s2 * s
    h00 = 2 * s3 - 3 * s2 + 1
    h10 = s3 - 2 * s2 + s
    h01 = -2 * s3 + 3 * s2
    h11 = s3 - s2
    a = h10 * h / (t2 - t0)
    b = h11 * h / (t3 - t1)
    return h00[:, None] * p1 + h01[:, None] * p2 + a[:, None] * (p2 - p0) + b[:, None] * (p3 - p1)


def fit_keys(
    values: np.ndarray,
    budget: np.ndarray,
    error: Callable[[np.ndarray], np.ndarray],
    mandatory: np.ndarray,
    dequantize: Callable[[np.ndarray], np.ndarray],
    start: np.ndarray | None = None,
    grid: int = 1,
) -> tuple[np.ndarray, np.ndarray, bool]:
    """Place keys until the curve's error is within ``budget`` on every frame (seed 003 §5.1).

    Starts from the ``mandatory`` keys (plus ``start`` if given); while some frames exceed
    their budget, inserts into every failing interval the frame with the largest
    error/budget ratio. The curve goes through the *dequantized* key values, so quantization
    is inside the loop.

    Parameters
    ----------
    values : (F, d) the track's parameter values on every frame.
    budget : (F,) allowed error per frame (same units as ``error``'s output).
    error : maps a reconstruction (F, d) to the error per frame (F,).
    mandatory : sorted frames that are always keys (must include 0 and F - 1).
    dequantize : maps original key values (K, d) to what the decoder will see.
    grid : new keys go on multiples of ``grid`` where a failing interval has one (coarser key
        times cost fewer bits): the grid frame with the worst error/budget ratio; elsewhere on
        the worst failing frame.

    Returns
    -------
    keys : sorted key frames.
    key_values : (K, d) their values before quantization.
    ok : False when frames that already are keys still exceed the budget (quantization is
        too coarse for the budget there).
    """
    frames = len(values)
    x = np.arange(frames, dtype=np.float64)
    keys = np.asarray(mandatory, dtype=np.int64)
    if start is not None:
        keys = np.union1d(keys, start)
    is_key = np.zeros(frames, dtype=bool)
    on_grid = np.arange(frames) % grid == 0
    while True:
        recon = catmull_rom(keys, dequantize(values[keys]), x)
        ratio = error(recon) / budget
        bad = ratio > 1.0
        if not bad.any():
            keys = _remove_keys(values, budget, error, keys, mandatory, dequantize, x)
            return keys, values[keys], True
        is_key[:] = False
        is_key[keys] = True
        candidates = bad & ~is_key
        if grid > 1:
            # Grid frames of the failing intervals, failing or not; an interval with no grid
            # frame left keeps its failing frames as candidates.
            span = np.searchsorted(keys, np.arange(frames), side="right") - 1
            gridded = on_grid & ~is_key & np.isin(span, span[bad])
            candidates = gridded | (candidates & ~np.isin(span, span[gridded]))
        if not candidates.any():
            return keys, values[keys], False
        # Worst candidate of each failing interval: sort by (interval, -ratio), keep firsts.
        idx = np.flatnonzero(candidates)
        interval = np.searchsorted(keys, idx, side="right") - 1
        order = np.lexsort((-ratio[idx], interval))
        first = np.ones(len(order), dtype=bool)
        first[1:] = interval[order][1:] != interval[order][:-1]
        new = idx[order][first]
        keys = np.union1d(keys, new)



def _remove_keys(values, budget, error, keys, mandatory, dequantize, x) -> np.ndarray:
    """Drop keys the curve can do without (greedy insertion over-places some).

    Removing key i changes the curve only between keys i-2 and i+2, so keys whose indices
    differ by 4 or more can be tried together: each sweep tries one residue class mod 4 in
    one vectorised evaluation and keeps the removals whose own region stays within budget.
    """
    mandatory_set = np.zeros(len(values), dtype=bool)
    mandatory_set[mandatory] = True
    changed = True
    while changed:
        changed = False
        for r in range(4):
            idx = np.arange(len(keys))
            trial = (idx % 4 == r) & ~mandatory_set[keys]
            if not trial.any():
                continue
            kept = keys[~trial]
            recon = catmull_rom(kept, dequantize(values[kept]), x)
            bad = error(recon) > budget
            # A removal is fine when no frame between keys i-2 and i+2 (of the original set) fails.
            lo = keys[np.maximum(idx - 2, 0)]
            hi = keys[np.minimum(idx + 2, len(keys) - 1)]
            bad_count = np.concatenate(([0], np.cumsum(bad)))
            region_bad = bad_count[hi + 1] - bad_count[lo]
            ok = trial & (region_bad == 0)
            # Regions of accepted removals are disjoint only if candidates are 4 apart: they are.
            if ok.any():
                keys = keys[~ok]
                changed = True
    return keys
