"""Catmull-Rom curves through keys at integer frames, and adaptive key placement.

The curve is the one docs/FORMAT.md specifies (cubic Hermite segments with finite-difference
tangents, end keys repeated), evaluated here in float64 for fitting; the runtime evaluates the
same formula in float32 and is the judge of the error.

:func:`fit_keys` places keys. For a curve whose error is a :class:`CurveTarget` (the key-frame
engine's tracks) it runs compiled (:mod:`mocodec.native`); for any other error function it runs
:func:`fit_keys_reference`, the numpy statement of the same algorithm.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from . import native
from . import rotations as R

KIND_MRP, KIND_TWIST = native.KIND_MRP, native.KIND_TWIST
KIND_TRANSLATION, KIND_SCALE = native.KIND_TRANSLATION, native.KIND_SCALE
"""What a curve's values are: modified Rodrigues parameters of a rotation relative to a
reference, a twist angle about an axis followed by such parameters, a translation or a
scale."""
VECTOR_KINDS = (KIND_TRANSLATION, KIND_SCALE)
"""Kinds whose values are the decoded vectors themselves, their error a distance."""


def catmull_rom(key_frames: np.ndarray, key_values: np.ndarray, x: np.ndarray, split: bool = False) -> np.ndarray:
    """Evaluate the curve through ``(key_frames[k], key_values[k])`` at positions ``x``.

    ``key_frames`` is strictly increasing (K,), ``key_values`` is (K, d); returns (len(x), d).
    ``split``: the first segment is detached (the straight line from key 0 to key 1, and key
    0 is no neighbour of key 1), for captures that jump after frame 0.
    """
    key_frames = np.asarray(key_frames, dtype=np.float64)
    key_values = np.asarray(key_values, dtype=np.float64)
    x = np.asarray(x, dtype=np.float64)
    k = len(key_frames)
    if k == 1:
        return np.broadcast_to(key_values[0], (len(x), key_values.shape[1])).copy()
    if len(x) <= CURVE_CHUNK:
        return _catmull_rom(key_frames, key_values, x, split)
    # A run of positions at a time: a long clip's temporaries (a dozen arrays the size of the
    # result) stay small, and each position's numbers are its own.
    out = np.empty((len(x), key_values.shape[1]))
    for start in range(0, len(x), CURVE_CHUNK):
        rows = slice(start, start + CURVE_CHUNK)
        out[rows] = _catmull_rom(key_frames, key_values, x[rows], split)
    return out


CURVE_CHUNK = 8192
"""Positions :func:`catmull_rom` evaluates at a time."""


def _catmull_rom(key_frames: np.ndarray, key_values: np.ndarray, x: np.ndarray, split: bool) -> np.ndarray:
    """:func:`catmull_rom` of float64 arrays with at least two keys."""
    k = len(key_frames)
    i1 = np.clip(np.searchsorted(key_frames, x, side="right") - 1, 0, k - 2)
    i0 = np.maximum(i1 - 1, 0)
    i2 = i1 + 1
    i3 = np.minimum(i1 + 2, k - 1)
    if split:
        i0 = np.where(i1 <= 1, i1, i0)
        i3 = np.where(i1 == 0, i2, i3)
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


@dataclass
class CurveTarget:
    """What a curve's error is measured against, in a form the compiled fitter evaluates.

    Calling it maps a reconstruction (F, d) to the error per frame (F,): the angle (rad) from
    ``target`` rotations (F, 4) of the rotations an MRP curve (``KIND_MRP``: ``ref * q(p)``) or
    a twist curve (``KIND_TWIST``: ``twist(axis, a) * ref * q(p)``) decodes to, or the distance
    from ``target`` translations or scales (F, 3) (``VECTOR_KINDS``). :meth:`half` does the same for
    the curve half-way between frames against ``half_target`` (F - 1, 4 | 3).
    """

    kind: int
    target: np.ndarray
    ref: np.ndarray
    axis: np.ndarray
    half_target: np.ndarray | None = None

    def decoded(self, recon: np.ndarray) -> np.ndarray:
        """Rotations (F, 4), or translations or scales (F, 3), that curve values ``recon``
        decode to."""
        if self.kind in VECTOR_KINDS:
            return recon
        if self.kind == KIND_MRP:
            return R.quat_multiply(self.ref, R.quat_from_mrp(recon))
        tw = R.quat_from_axis_angle(self.axis, recon[:, 0])
        return R.quat_multiply(tw, R.quat_multiply(self.ref, R.quat_from_mrp(recon[:, 1:])))

    def _error(self, recon: np.ndarray, target: np.ndarray) -> np.ndarray:
        if self.kind in VECTOR_KINDS:
            return np.linalg.norm(recon - target, axis=1)
        return R.quat_angle(target, self.decoded(recon))

    def __call__(self, recon: np.ndarray) -> np.ndarray:
        return self._error(recon, self.target)

    def at(self, recon: np.ndarray, rows: np.ndarray) -> np.ndarray:
        """The error of ``recon`` on frames ``rows`` only (``recon`` holds those rows)."""
        return self._error(recon, self.target[rows])

    def half(self, recon_half: np.ndarray) -> np.ndarray:
        """Error of the curve at frames + 1/2 (F - 1, d) against :attr:`half_target`."""
        return self._error(recon_half, self.half_target)


def fit_keys(
    values: np.ndarray,
    budget: np.ndarray,
    error: Callable[[np.ndarray], np.ndarray],
    mandatory: np.ndarray,
    dequantize: Callable[[np.ndarray], np.ndarray],
    start: np.ndarray | None = None,
    grid: int = 1,
    split: bool = False,
    half_budget: np.ndarray | None = None,
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
    error : maps a reconstruction (F, d) to the error per frame (F,). A :class:`CurveTarget`
        runs the compiled fitter; any other function the numpy reference.
    mandatory : sorted frames that are always keys (must include 0 and F - 1).
    dequantize : maps original key values (K, d) to what the decoder will see, row by row.
    split : the curve's first segment is detached (:func:`catmull_rom`).
    grid : key cells of ``grid`` frames (frames 1 ... F - 2 in cells from frame 1; frame 0
        and frame F - 1 are cells of their own): the ``RMAL`` key times cost a bit per cell
        and per key, plus each key's place in its cell unless every key is on its cell's
        first frame. A new key goes on the first frame of a free cell where a failing
        interval has one (the cell start with the worst error/budget ratio), else on its worst
        failing frame in a free cell, and only where an interval has no free cell left on its
        worst failing frame. With ``grid == 1`` every frame is a cell.
    half_budget : (F - 1,) allowed error half-way between frames (``error`` must be a
        :class:`CurveTarget` with a ``half_target``; ``inf`` where not held), or None. A
        frame next to a half-way sample over budget counts as failing, with that sample's
        ratio, and so do the frames beyond a failing sample between two keys.

    Returns
    -------
    keys : sorted key frames.
    key_values : (K, d) their values before quantization.
    ok : False when frames that already are keys still exceed the budget (quantization is
        too coarse for the budget there). Half-way samples that no key can be added next to
        do not make it False: the curve there is the one its keys on every frame make.
    """
    if isinstance(error, CurveTarget):
        keys = np.asarray(mandatory, dtype=np.int64)
        if start is not None:
            keys = np.union1d(keys, start)
        mand = np.zeros(len(values), dtype=bool)
        mand[mandatory] = True
        half = half_budget is not None and error.half_target is not None
        keys, status = native.fit_keys(error.kind, dequantize(values), error.target, error.ref, error.axis,
                                       budget, keys, mand, grid, split,
                                       error.half_target if half else None, half_budget if half else None)
        return keys, values[keys], status != 0
    return fit_keys_reference(values, budget, error, mandatory, dequantize, start, grid, split, half_budget)


def fit_keys_reference(
    values: np.ndarray,
    budget: np.ndarray,
    error: Callable[[np.ndarray], np.ndarray],
    mandatory: np.ndarray,
    dequantize: Callable[[np.ndarray], np.ndarray],
    start: np.ndarray | None = None,
    grid: int = 1,
    split: bool = False,
    half_budget: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, bool]:
    """:func:`fit_keys` in numpy, for any ``error`` function (half-way samples need a
    :class:`CurveTarget`): the statement of the algorithm the compiled fitter follows."""
    frames = len(values)
    x = np.arange(frames, dtype=np.float64)
    keys = np.asarray(mandatory, dtype=np.int64)
    if start is not None:
        keys = np.union1d(keys, start)
    halfway = _Halfway(error, half_budget, frames) if half_budget is not None else None
    # Cell of every frame: frame 0 and the last frame have cells of their own.
    cell = np.zeros(frames, dtype=np.int64)
    cell[1:] = (np.arange(1, frames) - 1) // grid + 1
    if frames > 2:
        cell[-1] = cell[-2] + 1
    on_grid = np.zeros(frames, dtype=bool)
    on_grid[1:] = (np.arange(1, frames) - 1) % grid == 0
    taken = np.zeros(int(cell[-1]) + 1, dtype=bool)
    while True:
        kv = dequantize(values[keys])
        recon = catmull_rom(keys, kv, x, split)
        ratio = error(recon) / budget
        bad = ratio > 1.0
        frame_bad = bool(bad.any())
        is_key = np.zeros(frames, dtype=bool)
        is_key[keys] = True
        if halfway is not None:
            ratio, bad = halfway.flag(keys, kv, split, is_key, ratio, bad)
        if not bad.any():
            keys = _remove_keys(values, budget, error, keys, mandatory, dequantize, x, split, halfway)
            return keys, values[keys], True
        taken[:] = False
        taken[cell[keys]] = True
        free = ~taken[cell]
        candidates = bad & free
        if grid > 1:
            # Free cell starts of the failing intervals, failing or not; an interval with none
            # keeps its failing frames in free cells as candidates, and one with no free cell
            # at all its failing frames (a second key in a cell).
            span = np.searchsorted(keys, np.arange(frames), side="right") - 1
            gridded = on_grid & free & np.isin(span, span[bad])
            candidates = gridded | (candidates & ~np.isin(span, span[gridded]))
            stuck = bad & ~is_key & ~np.isin(span, span[candidates])
            candidates |= stuck
        if not candidates.any():
            if not frame_bad:  # only half-way samples between keys on every frame are over
                keys = _remove_keys(values, budget, error, keys, mandatory, dequantize, x, split, halfway)
                return keys, values[keys], True
            return keys, values[keys], False
        # Worst candidate of each failing interval: sort by (interval, -ratio), keep firsts.
        idx = np.flatnonzero(candidates)
        interval = np.searchsorted(keys, idx, side="right") - 1
        order = np.lexsort((-ratio[idx], interval))
        first = np.ones(len(order), dtype=bool)
        first[1:] = interval[order][1:] != interval[order][:-1]
        new = idx[order][first]
        # Two intervals may pick frames of one cell (a cell straddling a key): keep one.
        _, one = np.unique(cell[new], return_index=True)
        keys = np.union1d(keys, new[one])


class _Halfway:
    """The half-way samples of :func:`fit_keys_reference`."""

    def __init__(self, error: CurveTarget, half_budget: np.ndarray, frames: int) -> None:
        if not isinstance(error, CurveTarget) or error.half_target is None:
            raise TypeError("half-way budgets need a CurveTarget error with a half_target")
        self.error, self.budget = error, np.asarray(half_budget, dtype=np.float64)
        self.x = np.arange(frames - 1, dtype=np.float64) + 0.5

    def errors(self, keys: np.ndarray, kv: np.ndarray, split: bool) -> np.ndarray:
        return self.error.half(catmull_rom(keys, kv, self.x, split))

    def flag(self, keys, kv, split, is_key, ratio, bad) -> tuple[np.ndarray, np.ndarray]:
        """Frames next to a failing half-way sample fail with its ratio; so do the frames
        beyond one between two keys (their keys shape its segment), where they are no keys."""
        hratio = self.errors(keys, kv, split) / self.budget
        hb = hratio > 1.0
        hr = np.where(hb, hratio, -np.inf)
        rank, bad = ratio.copy(), bad.copy()
        bad[:-1] |= hb
        bad[1:] |= hb
        rank[:-1] = np.maximum(rank[:-1], hr)
        rank[1:] = np.maximum(rank[1:], hr)
        blocked = np.where(hb & is_key[:-1] & is_key[1:], hr, -np.inf)
        before = np.full(len(ratio), -np.inf)
        before[:-2] = blocked[1:]   # frame f - 1 of a blocked sample f
        after = np.full(len(ratio), -np.inf)
        after[2:] = blocked[:-1]    # frame f + 2
        beyond = np.maximum(before, after)
        beyond = np.where(is_key, -np.inf, beyond)
        bad |= beyond > -np.inf
        rank = np.maximum(rank, beyond)
        return rank, bad


def _remove_keys(values, budget, error, keys, mandatory, dequantize, x, split=False, halfway=None) -> np.ndarray:
    """Drop keys the curve can do without (greedy insertion over-places some).

    Removing key i changes the curve only between keys i-2 and i+2, so keys whose indices
    differ by 4 or more can be tried together: each sweep tries one residue class mod 4 in
    one vectorised evaluation and keeps the removals whose own region stays within budget
    (frames, and half-way samples when ``halfway`` holds them).
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
            kv = dequantize(values[kept])
            recon = catmull_rom(kept, kv, x, split)
            bad = error(recon) > budget
            # A removal is fine when no frame between keys i-2 and i+2 (of the original set) fails.
            lo = keys[np.maximum(idx - 2, 0)]
            hi = keys[np.minimum(idx + 2, len(keys) - 1)]
            bad_count = np.concatenate(([0], np.cumsum(bad)))
            region_bad = bad_count[hi + 1] - bad_count[lo]
            if halfway is not None:  # and no half-way sample lo ... hi - 1
                hbad = halfway.errors(kept, kv, split) > halfway.budget
                hcount = np.concatenate(([0], np.cumsum(hbad)))
                region_bad = region_bad + hcount[hi] - hcount[lo]
            ok = trial & (region_bad == 0)
            # Regions of accepted removals are disjoint only if candidates are 4 apart: they are.
            if ok.any():
                keys = keys[~ok]
                changed = True
    return keys
