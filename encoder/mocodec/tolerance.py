"""The tolerance promise: per-node position tolerances, their split into per-track error
budgets, the repair step that tightens budgets where the runtime's check fails, the loop every
codec meets its tolerance with, and the one error a codec raises when it cannot.

The user promises a world-space position error (cm) for every joint and end site on every
frame, optionally tighter for end effectors. A track (a node's rotation or translation curve)
moves every point below it. Each point's tolerance is shared equally among the tracks on its
chain, scaled by the distance the track's error is carried over (the lever arm), and a global
scale ``k`` lets errors that do not add up worst-case use more of it; where the check through
the runtime still fails, :func:`tighten` lowers the budgets of the tracks on the failing
chains around the failing frames.
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from typing import Callable, Iterable

import numpy as np

from .motion import Skeleton

DEFAULT_TOLERANCE_CM = 1.0
"""The tolerance of the command line and the Python API when none is given."""

EFFECTOR_PATTERN = re.compile(r"hand|foot|toe|head|wrist|ankle|finger|thumb", re.IGNORECASE)

ClipCheck = Callable[..., np.ndarray]
"""``check(payload) -> (F, N)``: the world position error of a clip payload, in file units,
decoded by the C runtime (:func:`mocodec.encode.make_check`); ``check(payload,
halfway=True) -> (F-1, N)`` the error half-way between frames."""


class ToleranceNotMet(RuntimeError):
    """A codec could not reach the requested tolerance (every codec raises this one type)."""


def effector_nodes(skeleton: Skeleton) -> np.ndarray:
    """Boolean (N,): end sites and joints named like hands, feet, toes and heads."""
    named = np.array([bool(EFFECTOR_PATTERN.search(n)) for n in skeleton.names])
    return named | skeleton.is_end_site


@dataclass
class Tolerance:
    """What the encoder promises, in centimetres.

    Parameters
    ----------
    tolerance_cm : float
        Max world-space position error of any joint or end site on any frame.
    effector_tolerance_cm : float or None
        A tighter bound for end effectors (hands, feet, head, end sites).
    """

    tolerance_cm: float
    effector_tolerance_cm: float | None = None

    def __post_init__(self) -> None:
        if not (np.isfinite(self.tolerance_cm) and self.tolerance_cm > 0):
            raise ValueError(f"tolerance must be a positive number of cm, got {self.tolerance_cm}")
        e = self.effector_tolerance_cm
        if e is not None and not (np.isfinite(e) and e > 0):
            raise ValueError(f"effector tolerance must be a positive number of cm, got {e}")

    def per_node_cm(self, skeleton: Skeleton) -> np.ndarray:
        """Tolerance of every node (N,), cm."""
        tol = np.full(skeleton.node_count, float(self.tolerance_cm))
        if self.effector_tolerance_cm is not None:
            eff = effector_nodes(skeleton)
            tol[eff] = np.minimum(tol[eff], self.effector_tolerance_cm)
        return tol


def ancestors_matrix(skeleton: Skeleton) -> np.ndarray:
    """``A[a, p]`` is True when ``a`` is ``p`` or one of its ancestors."""
    n = skeleton.node_count
    a = np.eye(n, dtype=bool)
    for p in range(n):
        q = skeleton.parents[p]
        if q >= 0:
            a[:, p] |= a[:, q]
    return a


@dataclass
class TrackReach:
    """Which points a track moves and how far its error is carried.

    ``affects`` (T, N) bool, ``lever`` (T, N) distance in file units (0 where not affected),
    ``is_rotation`` (T,) bool.
    """

    affects: np.ndarray
    lever: np.ndarray
    is_rotation: np.ndarray


def initial_budgets(reach: TrackReach, tolerance_units: np.ndarray, scale: float) -> np.ndarray:
    """Budget per track (T,): angle in radians for rotations, length for translations.

    Point ``p`` gives each of the ``D_p`` tracks on its chain an equal share
    ``tolerance_p / D_p``, divided by the lever; a track takes the smallest share any of its
    points gives it, times ``scale``.
    """
    chain_len = np.maximum(reach.affects.sum(axis=0), 1)  # D_p
    share = tolerance_units / chain_len                   # (N,)
    with np.errstate(divide="ignore"):
        per_point = np.where(reach.affects, share[None, :] / np.where(reach.lever > 0, reach.lever, 1.0), np.inf)
    return scale * per_point.min(axis=1)


def tighten(
    budgets: list[np.ndarray],
    reach: TrackReach,
    errors_units: np.ndarray,
    tolerance_units: np.ndarray,
    radius: int = 1,
    factor: float = 0.7,
    moved: Callable[[int, np.ndarray], None] | None = None,
) -> list[int]:
    """Lower the per-frame budgets of every track on a failing chain, around failing frames.

    ``errors_units`` (F, N) is the error measured through the runtime. Where it exceeds the
    tolerance, the budget of each track that moves the failing point is multiplied by
    ``min(factor, 0.95 * tolerance / error)`` on the failing frames and ``radius`` frames
    around them. Returns the indices of the tracks whose budgets changed; ``moved(t, rows)``,
    when given, is told which frames of track t's budget changed value (F,) bool. A budget that
    is not writeable (one number broadcast over the frames) is replaced in ``budgets`` by the
    tightened array.
    """
    changed: list[int] = []
    rows, ratio = failing_ratios(errors_units, tolerance_units)
    if not len(rows):
        return changed
    failing = ratio < 1.0
    frames = errors_units.shape[0]
    for t, budget in enumerate(budgets):
        spread = budget_multipliers(ratio, failing, reach.affects[t], factor, radius, rows, frames)
        if spread is None:
            continue
        new = budget * spread[:frames]
        if moved is not None:
            moved(t, new != budget)
        if budget.flags.writeable:
            budget[...] = new
        else:
            budgets[t] = new
        changed.append(t)
    return changed


RATIO_CHUNK = 8192
"""Rows :func:`failing_ratios` looks through at a time."""


def failing_ratios(errors_units: "np.ndarray | OverRows", tolerance_units: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The rows of ``errors_units`` (R, N) where some point is over its tolerance (N,) (its
    ratio tolerance / error under 1), and those rows' ratios: a run of rows at a time, so a long
    clip's R x N ratios are never whole (few rows fail; each ratio is the same number)."""
    if isinstance(errors_units, OverRows):  # the rows it leaves out have every ratio >= 1
        ratio = tolerance_units[None, :] / np.maximum(errors_units.values, 1e-30)
        failing = (ratio < 1.0).any(axis=1)
        return errors_units.rows[failing], ratio[failing]
    rows = []
    for start in range(0, len(errors_units), RATIO_CHUNK):
        part = tolerance_units[None, :] / np.maximum(errors_units[start:start + RATIO_CHUNK], 1e-30)
        rows.append(start + np.flatnonzero((part < 1.0).any(axis=1)))
    at = np.concatenate(rows) if rows else np.zeros(0, dtype=np.int64)
    return at, tolerance_units[None, :] / np.maximum(errors_units[at], 1e-30)


def budget_multipliers(ratio: np.ndarray, failing: np.ndarray, affects: np.ndarray, factor: float,
                       radius: int, rows: np.ndarray | None = None, count: int = 0) -> np.ndarray | None:
    """Per row of ``ratio`` (tolerance / error, (R, N)), the multiplier of one track's budget:
    ``min(factor, 0.95 * worst ratio)`` on the rows where a point it moves (``affects`` (N,))
    fails, spread ``radius`` rows each way (smallest wins), 1 elsewhere; None when it moves no
    failing point. With ``rows``, ``ratio`` and ``failing`` are those rows of ``count`` (every
    other row failing nowhere, :func:`failing_ratios`)."""
    mask = failing & affects[None, :]
    hit = mask.any(axis=1)
    if not hit.any():
        return None
    worst = np.where(mask, ratio, np.inf).min(axis=1)
    mult = np.where(hit, np.minimum(factor, 0.95 * worst), 1.0)
    if rows is not None:
        whole = np.ones(count)
        whole[rows] = mult
        mult = whole
    spread = mult.copy()
    for r in range(1, radius + 1):
        spread[r:] = np.minimum(spread[r:], mult[:-r])
        spread[:-r] = np.minimum(spread[:-r], mult[r:])
    return spread



# --------------------------------------------------------------------------- meeting it
class OverRows:
    """An (R, N) array of errors of which only the rows with some error over a tolerance are
    held (``rows``, sorted, and their ``values``): every other row is within it. What the
    repairs read of a check (:func:`within`, :func:`failing_ratios`, the rows over), without a
    long clip's R x N numbers, most of them within. Rows sliced (``errors[a:b]``) or zeroed
    (:meth:`zero`) stay within what they were measured against."""

    def __init__(self, count: int, rows: np.ndarray, values: np.ndarray) -> None:
        self.shape = (count, values.shape[1])
        self.rows, self.values = rows, values

    @classmethod
    def gather(cls, runs: "Iterable[tuple[slice, np.ndarray]]", shape: tuple[int, int],
               tolerance: np.ndarray) -> "OverRows":
        """The rows of errors given a run of rows at a time, ``(rows, errors)`` covering
        ``shape`` in order, where some error is not within ``tolerance`` (N,) (NaN too)."""
        rows, values = [], []
        for at, part in runs:
            over = np.flatnonzero(~np.all(part <= tolerance[None, :], axis=1))
            if len(over):
                rows.append(at.start + over)
                values.append(part[over])
        if not rows:
            return cls(shape[0], np.zeros(0, dtype=np.int64), np.zeros((0, shape[1])))
        return cls(shape[0], np.concatenate(rows), np.concatenate(values))

    @classmethod
    def of(cls, errors: np.ndarray, tolerance: np.ndarray) -> "OverRows":
        """The rows of a whole (R, N) array not within ``tolerance`` (N,)."""
        return cls.gather([(slice(0, len(errors)), errors)], errors.shape, tolerance)

    def __len__(self) -> int:
        return self.shape[0]

    def __getitem__(self, rows: slice) -> "OverRows":
        start, stop, step = rows.indices(self.shape[0])
        if step != 1:
            raise IndexError("OverRows takes a run of rows")
        keep = (self.rows >= start) & (self.rows < stop)
        return OverRows(max(stop - start, 0), self.rows[keep] - start, self.values[keep])

    @classmethod
    def stack(cls, head: "OverRows", tail: "OverRows") -> "OverRows":
        """``head``'s rows, then ``tail``'s."""
        return cls(len(head) + len(tail), np.concatenate((head.rows, tail.rows + len(head))),
                   np.concatenate((head.values, tail.values)))

    def zero(self, rows: np.ndarray) -> None:
        """Set the rows where ``rows`` (R,) bool is True to 0 (not over anything), in place."""
        self.values[rows[self.rows]] = 0.0

    def over(self, tolerance: np.ndarray) -> np.ndarray:
        """(len(rows), N) bool: which held errors exceed ``tolerance`` (N,)."""
        return self.values > tolerance[None, :]


@dataclass
class RowTolerance:
    """A tolerance per node on the first ``rows`` rows of an error array and another on the
    rest (the frames, then half-way between them): what a stacked (R, N) array would say,
    without its R x N numbers."""

    head: np.ndarray
    rows: int
    tail: np.ndarray

    def ratio_max(self, errors_units: "np.ndarray | OverRows") -> float:
        """The largest error over its tolerance (of rows over it: an :class:`OverRows`' held
        rows, where that largest is when some row is over)."""
        if isinstance(errors_units, OverRows):
            head, tail = errors_units.rows < self.rows, errors_units.rows >= self.rows
            ratios = [float(np.max(errors_units.values[m] / t)) for m, t in ((head, self.head), (tail, self.tail))
                      if m.any()]
            return max(ratios, default=0.0)
        return max(float(np.max(errors_units[:self.rows] / self.head)),
                   float(np.max(errors_units[self.rows:] / self.tail)))


def within(errors_units: np.ndarray, tolerance_units: "np.ndarray | RowTolerance") -> bool:
    """True when every error is within its tolerance (``tolerance_units`` (N,) per node,
    (F, N) per frame and node, or a :class:`RowTolerance`)."""
    if isinstance(errors_units, OverRows):  # the rows it leaves out are within
        rows, values = errors_units.rows, errors_units.values
        if isinstance(tolerance_units, RowTolerance):
            t = tolerance_units
            head = rows < t.rows
            return bool(np.all(values[head] <= t.head)) and bool(np.all(values[~head] <= t.tail))
        return bool(np.all(values <= tolerance_units))
    if isinstance(tolerance_units, RowTolerance):
        t = tolerance_units
        return bool(np.all(errors_units[:t.rows] <= t.head)) and bool(np.all(errors_units[t.rows:] <= t.tail))
    return bool(np.all(errors_units <= tolerance_units))


@dataclass
class Attempt:
    """The end of :func:`meet_tolerance`: the last payload coded, its error through the
    runtime (F, N), the adjustments made before it, and whether it is within tolerance."""

    payload: bytes
    errors_units: "np.ndarray | OverRows"
    adjustments: int
    met: bool

    def worst(self, tolerance_units: "np.ndarray | RowTolerance") -> float:
        """The largest ratio of error to tolerance."""
        if isinstance(tolerance_units, RowTolerance):
            return tolerance_units.ratio_max(self.errors_units)
        if isinstance(self.errors_units, OverRows):
            values = self.errors_units.values
            return float(np.max(values / tolerance_units)) if len(values) else 0.0
        return float(np.max(self.errors_units / tolerance_units))


def meet_tolerance(code: Callable[[], bytes], check: ClipCheck, tolerance_units: "np.ndarray | RowTolerance",
                   adjust: Callable[[np.ndarray], object], rounds: int) -> Attempt:
    """Code, check through the runtime, adjust where the error is over, until it is not.

    The loop the codecs that refine a coding share: ``code()`` writes the payload from the
    codec's current parameters, ``check`` measures it, ``adjust(errors)`` changes the
    parameters where ``errors`` exceed ``tolerance_units`` (it may raise
    :class:`ToleranceNotMet` when it cannot); when it returns a callable, that is called once
    the errors are let go (so that a refit does not hold a long clip's errors). At most
    ``rounds`` adjustments; the returned attempt says whether the last payload met the
    tolerance. What each codec adjusts is its
    own: spline and rma tighten per-track budgets and refit keys, fk-wavelet lowers step codes
    (and raises the ROI gain), neural adds weight bits. ik-predict does not refine: it searches
    one step scale for the pass/fail edge, and only shares :func:`within`.
    """
    for n in range(rounds + 1):
        payload = code()
        errors = check(payload)
        if within(errors, tolerance_units):
            return Attempt(payload, errors, n, True)
        if n < rounds:
            then = adjust(errors)
            del errors  # not held while the next check measures (F x N numbers of a long clip)
            if callable(then):  # the adjustment's own work after the errors are let go (a refit)
                then()
    return Attempt(payload, errors, rounds, False)
