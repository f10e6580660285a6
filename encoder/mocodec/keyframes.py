"""The key-frame engine the key-frame codecs (``spline``, ``rma``) share, and the top-down
compensation ``fk-wavelet`` uses too.

A track is one node's rotation (modified Rodrigues parameters relative to the clip's mean
rotation; or an unwrapped twist angle plus MRPs for a node that keeps turning round), its
translation or its scale (only where the clip moves them away from the rest pose,
:meth:`mocodec.motion.Motion.animated`). Its keys are Catmull-Rom control points with
adaptive placement (seed 003 §5.1) and range-aware quantization (§5.2). A
:class:`KeyframeFitter` meets a world-space tolerance on every frame: it splits the tolerance
into per-track budgets (:mod:`mocodec.tolerance`), fits each track until its own error is within
budget, then checks the whole clip through the C runtime and tightens the budgets where a point
still misses, until nothing does. A codec subclasses it with its storage: the frames every
track keys, the key quantizer, and the payload writer.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from . import native
from . import rotations as R
from .codecs import ClipResult
from .curves import (KIND_MRP, KIND_SCALE, KIND_TRANSLATION, KIND_TWIST, VECTOR_KINDS, CurveTarget,
                     catmull_rom, fit_keys)
from .clip_plan import ROT, SCALE, TRANS, ClipPlan, plan_clip
from .kinematics import shared_world_positions, short_clip, world_rotations
from .motion import Motion
from .quantize import Quantizer, f32_exact
from .swing_hemisphere import swing_on_reference_hemisphere
from .tolerance import (ClipCheck, OverRows, RowTolerance, Tolerance, ToleranceNotMet, TrackReach,
                        budget_multipliers, failing_ratios, initial_budgets, meet_tolerance, tighten)

DIMS = {KIND_MRP: 3, KIND_TWIST: 4, KIND_TRANSLATION: 3, KIND_SCALE: 3}
TWIST_MRP_LIMIT = 1.0  # |p| > 1 means more than 180 degrees from the reference: use a twist
# A rotation that roams everywhere (CMU's thumbs) makes a twist track's parameters jump where its
# swing passes 180 degrees, many times a clip; MRPs that change hemisphere only past this |p|
# (288 degrees) jump far less often (swinging_mrp_track).
SWING_MRP_SWITCH = 3.0


@dataclass
class KeyframeSettings:
    """What every key-frame codec's settings hold (every length in cm).

    Parameters
    ----------
    tolerance : Tolerance
        The promise: max world-space position error per node, every frame.
    quant_fraction : float, default 0.6
        Share of a track's error budget given to quantization (the rest to the curve fit).
        Measured on dev clips: 0.4 and 0.6 tie at 1 cm; 0.6 is 2-4 % smaller at 0.1-0.02 cm.
    budget_scales : tuple of float, default (6.0,)
        Global scales tried on the per-track budgets (1 = worst-case additive errors); the
        smallest payload that meets the tolerance wins. Errors along a chain rarely add up
        worst-case, and compensation keeps them from compounding: on the CMU dev clips 6
        needs few repair rounds, 8 many for no gain.
    max_repairs : int, default 60
        Rounds of check-through-the-runtime and budget tightening before giving up.
    shell_cm : float, default 3.0
        Every rotation is also held to a virtual vertex this far from its joint.
    halfway_factor : float, default 1.5
        Hold the error half-way between frames too, to this multiple of the tolerance (0:
        off, frames only): the runtime's samples at x + 1/2 are checked against the
        original's half-way pose with the frames, and where one is over, the tracks on its
        chain are held to their targets' own half-way path (slerp, lerp) on that interval
        and refitted there (:class:`HalfwayHold`). Intervals where the capture jumps, and
        their neighbours (:func:`mocodec.kinematics.held_intervals`), are not held.
    """

    tolerance: Tolerance
    quant_fraction: float = 0.6
    budget_scales: tuple[float, ...] = (6.0,)
    max_repairs: int = 60
    shell_cm: float = 3.0
    halfway_factor: float = 1.5

    def __post_init__(self) -> None:
        self.quant_fraction = float(self.quant_fraction)
        if not 0.0 < self.quant_fraction < 1.0:
            raise ValueError(f"quant_fraction must be in (0, 1), got {self.quant_fraction}")
        if isinstance(self.budget_scales, (int, float, str)):
            self.budget_scales = (float(self.budget_scales),)
        self.budget_scales = tuple(float(x) for x in self.budget_scales)
        self.max_repairs = int(self.max_repairs)
        self.halfway_factor = float(self.halfway_factor)
        if not self.halfway_factor >= 0.0:
            raise ValueError(f"halfway_factor must be 0 (off) or positive, got {self.halfway_factor}")


@dataclass
class Track:
    """One node's rotation, translation or scale curve, as fitted: parameter values on every frame,
    the target they reproduce, the error budget per frame, and (once fitted) the keys and
    their quantizer, or the constant the track folds to."""

    node: int
    kind: int
    values: np.ndarray        # (F, d) parameters on every frame (an MRP track's derived from ``flips``)
    target: np.ndarray        # (F, 4) original local rotation or (F, 3) translation / scale
    ref: np.ndarray           # (4,) reference quaternion (float32-exact), rotations only
    axis: np.ndarray          # (3,) twist axis (float32-exact), kind 2 only
    budget: np.ndarray = field(default_factory=lambda: np.zeros(0))
    base_budget: float = 0.0
    quant_scale: float = 1.0
    keys: np.ndarray | None = None  # None: folded to a constant
    key_values: np.ndarray | None = None  # (K, d) before quantization
    recon: np.ndarray | None = None  # what the runtime decodes on every frame, once asked (_track_recon; translations and scales)
    ref_codes: np.ndarray | None = None   # int16 MRPs of ``ref`` as stored
    axis_codes: np.ndarray | None = None  # int16 axis as stored
    quantizer: Quantizer | None = None
    constant: np.ndarray | None = None
    split: bool = False  # first segment detached (curves.catmull_rom): the capture jumps after frame 0
    rest: np.ndarray | None = None  # the node's f32 rest value (what mode 0 stores for free)
    half_budget: np.ndarray | None = None  # (F-1,) allowed error half-way between frames (None, inf: not held)
    fitted: "Fitted | None" = None  # what its keys were last fitted to (local refits)
    mrp_limit: float = TWIST_MRP_LIMIT  # largest |p| a retarget keeps (SWING_MRP_SWITCH for swinging_mrp_track)
    # An MRP track built here holds no values (F x 3 numbers): they are its target relative to
    # the reference, each frame on the side ``flips`` (F,) bool says, as MRPs (mrp_values).
    flips: np.ndarray | None = None

    @property
    def derived(self) -> bool:
        """Whether the values are derived from the target (:attr:`flips`), not held."""
        return self.__dict__.get("_values") is None and self.flips is not None

    @property
    def frames(self) -> int:
        return len(self.target) if self.derived else len(self.__dict__["_values"])

    @property
    def value_shape(self) -> tuple[int, ...]:
        return (len(self.target), 3) if self.derived else self.__dict__["_values"].shape

    def values_at(self, rows: np.ndarray | slice) -> np.ndarray:
        """The values on frames ``rows`` (derived there alone when not held)."""
        if self.derived:
            return mrp_values(self.ref, self.target[rows], self.flips[rows])
        return self.__dict__["_values"][rows]

    def take_values(self, other: "Track") -> None:
        """Hold ``other``'s values as it does (held, or derived from its target and flips)."""
        self.__dict__["_values"], self.flips = other.__dict__["_values"], other.flips

    @property
    def is_rotation(self) -> bool:
        return self.kind not in VECTOR_KINDS

    @property
    def part(self) -> int:
        """ROT, TRANS or SCALE."""
        return SCALE if self.kind == KIND_SCALE else TRANS if self.kind == KIND_TRANSLATION else ROT


def _get_values(track: Track) -> np.ndarray:
    if track.derived:
        return mrp_values(track.ref, track.target, track.flips)
    return track.__dict__["_values"]


def _set_values(track: Track, values: np.ndarray) -> None:
    fitted = track.__dict__.get("fitted")
    if fitted is not None:  # what the fit saw changes where these differ (untouched_keys)
        old = track.values
        if old is not None and old.shape == np.shape(values):
            fitted.mark_values(np.any(old != values, axis=1))
        else:
            fitted.shape = ()  # another shape: no key stays
    track.__dict__["_values"] = values


# A property over the dataclass field, so that every reader of ``values`` gets an MRP track's
# derived ones (set: held ones, which take precedence over flips).
Track.values = property(_get_values, _set_values)  # type: ignore[assignment]


def mrp_values(ref: np.ndarray, target: np.ndarray, flips: np.ndarray) -> np.ndarray:
    """MRPs (n, 3) of rotations ``target`` (n, 4) relative to ``ref``, on the other side where
    ``flips``: the products and signs the track's builders make (:func:`_rotation_track_from`,
    :func:`_retarget_kept`), so the same numbers."""
    rel = R.quat_multiply(R.quat_conjugate(ref), target)
    rel *= np.where(flips, -1.0, 1.0)[:, None]
    return R.mrp_from_quat(rel)


def _flips(rel: np.ndarray, ref: np.ndarray, target: np.ndarray) -> np.ndarray:
    """Which rows of ``rel`` (n, 4), each exactly one of +-(conj(ref) target), are the minus one."""
    return np.sum(rel * R.quat_multiply(R.quat_conjugate(ref), target), axis=1) < 0.0


@dataclass
class Fitted:
    """What a track's keys were last fitted to (:func:`untouched_keys`): its values, and which
    frames' budgets and half-way budgets have changed since (None: none). Budgets only ever go
    down (tightened by a factor in [0, 1], or to the minimum with a wanted value), so a frame
    whose budget changed once differs from the fitted one for good: marks of each change, not a
    copy of every budget (F numbers a track)."""

    shape: tuple[int, ...]
    budget_moved: np.ndarray | None = None   # (F,) bool
    half_moved: np.ndarray | None = None     # (F-1,) bool
    values_moved: np.ndarray | None = None   # (F,) bool

    @classmethod
    def of(cls, track: "Track", values: np.ndarray | None = None) -> "Fitted":
        """The state of ``track`` now (``values``: its values, when at hand); a NaN budget or
        value counts as changed, as ``NaN != NaN`` says."""
        values = track.values if values is None else values
        budget = np.isnan(track.budget)
        half = None if track.half_budget is None else np.isnan(track.half_budget)
        moved = np.isnan(values).any(axis=1)
        return cls(values.shape, budget if budget.any() else None,
                   half if half is not None and half.any() else None, moved if moved.any() else None)

    def mark_values(self, moved: np.ndarray, rows: np.ndarray | slice = slice(None)) -> None:
        """Frames ``rows`` of the values changed where ``moved`` is True (a track is refitted
        after every retarget, so a mark is a difference from the fitted values)."""
        if self.values_moved is None:
            if not moved.any():
                return
            self.values_moved = np.zeros(self.shape[0], dtype=bool)
        self.values_moved[rows] |= moved

    def mark_budget(self, moved: np.ndarray, rows: np.ndarray | slice = slice(None)) -> None:
        """Frames ``rows`` of the budget changed where ``moved`` is True."""
        if self.budget_moved is None:
            if not moved.any():
                return
            self.budget_moved = np.zeros(self.shape[0], dtype=bool)
        self.budget_moved[rows] |= moved

    def mark_half(self, moved: np.ndarray, rows: np.ndarray | slice = slice(None)) -> None:
        """Intervals ``rows`` of the half-way budget changed where ``moved`` is True."""
        if self.half_moved is None:
            if not moved.any():
                return
            self.half_moved = np.zeros(max(self.shape[0] - 1, 0), dtype=bool)
        self.half_moved[rows] |= moved


# ------------------------------------------------------------------------ track construction
def _product(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``a * b`` of two (F, d) arrays, a broadcast view when both are one row broadcast over the
    frames (a scale at rest below a scale at rest): the same numbers without the F rows."""
    if a.strides[0] == 0 and b.strides[0] == 0:
        return np.broadcast_to(a[0] * b[0], np.broadcast_shapes(a.shape, b.shape))
    return a * b


def _reference(q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Store a reference rotation as int16 MRPs and return (codes, the quaternion the runtime
    expands them to, computed in binary32 exactly as the C code does)."""
    q = np.asarray(q, dtype=np.float64)
    if q[3] < 0:
        q = -q
    codes = np.clip(np.rint(R.mrp_from_quat(q) * 32767.0), -32767, 32767).astype(np.int16)
    p = codes.astype(np.float32) / np.float32(32767.0)
    s = p[0] * p[0] + p[1] * p[1] + p[2] * p[2]
    inv = np.float32(1.0) / (np.float32(1.0) + s)
    ref = np.array([np.float32(2.0) * p[0] * inv, np.float32(2.0) * p[1] * inv,
                    np.float32(2.0) * p[2] * inv, (np.float32(1.0) - s) * inv], dtype=np.float32)
    return codes, ref.astype(np.float64)


def _axis(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Store a unit axis as int16 and return (codes, the normalised axis the runtime uses)."""
    a = np.asarray(a, dtype=np.float64)
    codes = np.clip(np.rint(a / np.linalg.norm(a) * 32767.0), -32767, 32767).astype(np.int16)
    f = codes.astype(np.float32) / np.float32(32767.0)
    n2 = f[0] * f[0] + f[1] * f[1] + f[2] * f[2]
    inv = np.float32(1.0) / np.sqrt(n2, dtype=np.float32)
    return codes, (f * inv).astype(np.float32).astype(np.float64)


def _twist_axis(motion: Motion, node: int, rel: np.ndarray) -> np.ndarray:
    """Axis for a node that turns round: world up (Y, BVH's convention) for a root; otherwise
    the dominant direction of its rotation vectors."""
    if motion.skeleton.parents[node] < 0:
        return np.array([0.0, 1.0, 0.0])
    half = np.arctan2(np.linalg.norm(rel[:, :3], axis=1), rel[:, 3])
    vec = rel[:, :3] / np.maximum(np.linalg.norm(rel[:, :3], axis=1, keepdims=True), 1e-12) * (2 * half)[:, None]
    _, _, vt = np.linalg.svd(vec, full_matrices=False)
    return vt[0]


def _rotation_track_from(q: np.ndarray, motion: Motion, node: int) -> Track:
    """A rotation track for local rotations ``q`` (F, 4) of ``node``: MRPs when they stay
    within 180 degrees of the reference, else a twist track, unless the twist's parameters
    jump often (:func:`_parameter_flips`: a swing passing 180 degrees) and MRPs that change
    hemisphere late (:func:`swinging_mrp_track`) jump at most half as often."""
    q = R.quat_make_continuous(q)
    ref_codes, ref = _reference(R.quat_mean(q))
    rel = R.quat_make_continuous(R.quat_multiply(R.quat_conjugate(ref), q))
    if np.mean(rel[:, 3]) < 0:
        rel = -rel
    with np.errstate(invalid="ignore", divide="ignore"):  # a frame at the antipode: NaN, not <= 1
        p = R.mrp_from_quat(rel)
    if np.max(np.linalg.norm(p, axis=1)) <= TWIST_MRP_LIMIT:
        del p  # derived from q where read (mrp_values): not held
        return Track(node, KIND_MRP, None, q, ref, np.zeros(3), ref_codes=ref_codes, flips=_flips(rel, ref, q))
    twist = _twist_track_from(q, rel, motion, node)
    flips = _count_parameter_flips(twist)
    if flips:  # half-way, a jump is a miss (no curve follows slerp across it)
        swinging = swinging_mrp_track(q, node, ref_codes, ref, rel)
        if 2 * _count_parameter_flips(swinging) <= flips:
            return swinging
    return twist


FLIP_RUN = 65536
"""Intervals :func:`_count_parameter_flips` measures at a time."""


def _count_parameter_flips(track: Track) -> int:
    """How many intervals between frames a rotation track's parameters jump across
    (:func:`_parameter_flips`), a run at a time: each interval's answer is its own, and a
    long clip's (F - 1, 4) temporaries are not built whole."""
    intervals = track.frames - 1
    return sum(int(np.count_nonzero(_parameter_flips(track, np.arange(s, min(s + FLIP_RUN, intervals)))))
               for s in range(0, intervals, FLIP_RUN))


def _twist_track_from(q: np.ndarray, rel: np.ndarray, motion: Motion, node: int) -> Track:
    """A twist track (``KIND_TWIST``) for continuous local rotations ``q`` (F, 4), ``rel``
    the same relative to their mean (which picks the twist axis)."""
    axis_codes, axis = _axis(_twist_axis(motion, node, rel))
    # Swing-twist: q = twist(axis, theta) * rest, theta unwrapped so it may exceed a turn.
    half = np.unwrap(np.arctan2(q[:, :3] @ axis, q[:, 3]))
    theta = 2.0 * half
    rest = R.quat_multiply(R.quat_conjugate(R.quat_from_axis_angle(axis, theta)), q)
    rest = R.quat_make_continuous(rest)
    ref_codes, ref = _reference(R.quat_mean(rest))
    rel = R.quat_make_continuous(R.quat_multiply(R.quat_conjugate(ref), rest))
    if np.mean(rel[:, 3]) < 0:
        rel = -rel
    with np.errstate(invalid="ignore", divide="ignore"):  # a frame at the antipode: NaN, bounded below
        values = np.concatenate((theta[:, None], R.mrp_from_quat(rel)), axis=1)
    # A long clip's swing, followed continuously, can go round to the reference's antipode,
    # past any key width: keep it on the reference's hemisphere (mocodec.swing_hemisphere).
    bounded = swing_on_reference_hemisphere(KIND_TWIST, values, q, ref, axis)
    if bounded is not None:
        values = bounded
    return Track(node, KIND_TWIST, values, q, ref, axis, ref_codes=ref_codes, axis_codes=axis_codes)


def swinging_mrp_track(q: np.ndarray, node: int, ref_codes: np.ndarray, ref: np.ndarray,
                       rel: np.ndarray) -> Track:
    """A plain MRP track (``KIND_MRP``) for continuous local rotations ``q`` (F, 4) that go
    round: each frame's MRPs on the hemisphere of the frame before, until the rotation has gone
    past 180 degrees from the reference and on to where |p| would pass
    :data:`SWING_MRP_SWITCH`; the parameters then change hemisphere (a jump, not of the
    rotation) on the interval of that excursion where the rotation turns fastest, where a
    capture's glitch is, rather than where it moves smoothly. ``ref_codes``, ``ref`` and
    ``rel`` are :func:`_rotation_track_from`'s: the reference of ``q`` and ``q`` relative to it,
    continuous, on the reference's side on average."""
    w = rel[:, 3]
    turn = R.quat_angle(q[:-1], q[1:])
    # |p| = sqrt((1 - w) / (1 + w)) on a frame's side: |p| > 1 where w < 0, > the limit where w < edge.
    edge = (1.0 - SWING_MRP_SWITCH ** 2) / (1.0 + SWING_MRP_SWITCH ** 2)
    side = np.ones(len(w))
    s, f = 1.0, 0
    while True:  # one pass per change of hemisphere (a few a clip)
        far = np.flatnonzero(s * w[f:] < edge)
        if not len(far):
            side[f:] = s
            break
        g = f + int(far[0])
        near = np.flatnonzero(s * w[f:g] >= 0.0)  # the excursion past 180 degrees starts after the last
        h = f + int(near[-1]) if len(near) else max(f - 1, 0)
        k = h + int(np.argmax(turn[h:g])) if g > h else g - 1  # switch between frames k and k + 1
        k = max(k, f - 1)
        side[f:k + 1] = s
        s, f = -s, k + 1
    rel = rel * side[:, None]
    return Track(node, KIND_MRP, None, q, ref, np.zeros(3), ref_codes=ref_codes, mrp_limit=SWING_MRP_SWITCH,
                 flips=_flips(rel, ref, q))


def _track_rotations(track: Track, values: np.ndarray) -> np.ndarray:
    """Local rotations (F, 4) a track's parameter values decode to."""
    return _track_error(track).decoded(values)


def _track_error(track: Track) -> CurveTarget:
    """Per-frame error of a reconstruction: rotation angle (rad), translation distance or
    scale difference."""
    return CurveTarget(track.kind, track.target, track.ref, track.axis)


# ------------------------------------------------------------------------ fitting
def _quant_steps(track: Track, fraction: float) -> np.ndarray:
    """Largest quantization step per component whose worst case stays within ``fraction``
    of the track's base budget (angle for rotations: |dq| <= 4|dp| for MRPs)."""
    b = fraction * track.base_budget * track.quant_scale
    if track.kind in VECTOR_KINDS:
        return np.full(3, 2.0 * b / np.sqrt(3.0))
    if track.kind == KIND_MRP:
        return np.full(3, b / (2.0 * np.sqrt(3.0)))
    # Twist: half the share to the angle (error = step / 2), half to the MRPs.
    return np.array([b, *np.full(3, 0.5 * b / (2.0 * np.sqrt(3.0)))])


def _constant_value(track: Track) -> np.ndarray:
    if track.kind in VECTOR_KINDS:
        lo, hi = track.values.min(axis=0), track.values.max(axis=0)
        return f32_exact(0.5 * (lo + hi))
    return track.ref  # exactly what the runtime expands the stored codes to


def halfway_target(track: Track, at: np.ndarray | None = None) -> np.ndarray:
    """A track's target half-way between frames (F-1, 4 | 3): rotations by slerp at one half
    (the normalised sum on one hemisphere), translations and scales by their mean; between
    frames ``at`` and ``at + 1`` only (len(at), 4 | 3) when given (each interval's numbers are
    its own: a long clip's F-1 are not built for a few)."""
    if at is None:
        a, b = track.target[:-1], track.target[1:]
    else:
        a, b = track.target[at], track.target[at + 1]
    if track.kind in VECTOR_KINDS:
        return 0.5 * (a + b)
    mid = a + np.where((np.sum(a * b, axis=1) < 0.0)[:, None], -b, b)
    return mid / np.linalg.norm(mid, axis=1, keepdims=True)


def untouched_keys(track: Track) -> np.ndarray | None:
    """The keys of a fitted track whose curve segments (keys i - 2 ... i + 2) see no frame
    whose value or budget changed since the fit, nor a half-way sample next to one whose
    half-way budget did (None when it was not fitted): a local refit keeps them, so that the
    curve changes only where it has to."""
    if track.fitted is None or track.keys is None:
        return None
    fitted = track.fitted
    if fitted.shape != track.value_shape:
        return None
    dirty = np.zeros(fitted.shape[0], dtype=bool)
    if fitted.values_moved is not None:
        dirty |= fitted.values_moved
    if fitted.budget_moved is not None:
        dirty |= fitted.budget_moved
    if fitted.half_moved is not None:
        dirty[:-1] |= fitted.half_moved
        dirty[1:] |= fitted.half_moved
    keys = np.asarray(track.keys, dtype=np.int64)
    seen = np.concatenate(([0], np.cumsum(dirty)))
    idx = np.arange(len(keys))
    lo = keys[np.maximum(idx - 2, 0)]
    hi = keys[np.minimum(idx + 2, len(keys) - 1)]
    return keys[seen[hi + 1] == seen[lo]]


PROBE_STRIDE = 16  # a constant is first tried on every 16th frame: most tracks fail there


def _within_budget(deviation: Callable[[np.ndarray], np.ndarray], budget: np.ndarray) -> bool:
    """Whether ``deviation(rows)`` (per frame, on frames ``rows``) is within ``budget`` on every
    frame: tried on every :data:`PROBE_STRIDE`-th frame first, then, if none is over, on all.
    The same answer as the check on all frames (each frame's deviation is its own)."""
    probe = np.arange(0, len(budget), PROBE_STRIDE)
    if not np.all(deviation(probe) <= budget[probe]):
        return False
    return bool(np.all(deviation(np.arange(len(budget))) <= budget))


def fit_track(track: Track, mandatory: np.ndarray, fraction: float,
              quantizer_for: Callable[..., Quantizer] = Quantizer.for_range, grid: int = 1,
              keep: np.ndarray | None = None, values: np.ndarray | None = None, fold: bool = True) -> None:
    """Fold the track to a constant if that is within budget (and ``fold``), else place its keys.
    ``quantizer_for(lo, hi, step)`` builds the key quantizer (the codec's storage rule);
    ``grid`` the key cells new keys prefer to keep to one each (``fit_keys``). A track with a
    ``half_budget`` is held to its target's half-way path too (constants are judged on the
    frames: half-way, a constant is as far from the target as on one of the two frames at
    most). ``keep``: keys that stay whatever the fit finds (:func:`untouched_keys`); ``values``:
    the track's values, when at hand."""
    err = _track_error(track)
    frames = track.frames
    half_budget = track.half_budget if frames > 1 else None
    if half_budget is not None:
        err.half_target = halfway_target(track)
    if fold and track.rest is not None:  # the rest value costs nothing: take it when within budget
        rest = track.rest

        def rest_dev(rows: np.ndarray) -> np.ndarray:
            target = track.target[rows]
            return (np.linalg.norm(rest - target, axis=1) if track.kind in VECTOR_KINDS
                    else R.quat_angle(target, np.broadcast_to(rest, target.shape)))
        if _within_budget(rest_dev, track.budget):
            track.keys, track.quantizer, track.constant, track.recon = None, None, track.rest, None
            return
    if fold and track.kind != KIND_TWIST:
        const = _constant_value(track)
        flat = const if track.kind in VECTOR_KINDS else np.zeros(3)
        if _within_budget(lambda rows: err.at(np.broadcast_to(flat, (len(rows), 3)), rows), track.budget):
            track.keys, track.quantizer, track.constant, track.recon = None, None, const, None
            return
    track.constant = None
    if keep is not None and len(keep):
        mandatory = np.union1d(mandatory, keep)
    values = track.values if values is None else values  # derived once for the fit
    while True:
        step = _quant_steps(track, fraction)
        try:
            qz = quantizer_for(values.min(axis=0), values.max(axis=0), step)
        except ValueError as exc:
            raise ToleranceNotMet(f"node {track.node}: {exc}") from None
        keys, key_values, ok = fit_keys(values, track.budget, err, mandatory, qz.roundtrip,
                                        start=track.keys, grid=grid, split=track.split,
                                        half_budget=half_budget)
        track.keys, track.key_values, track.quantizer, track.recon = keys, key_values, qz, None
        if ok:
            return
        if track.quant_scale < 1e-4:
            raise ToleranceNotMet(f"node {track.node}: quantization cannot reach the budget")
        track.quant_scale *= 0.5  # keys on every failing frame and still over: finer steps


def node_modes(motion: Motion, tracks: list[Track]) -> tuple[list[tuple[int, int, int, int, int, int]], list[float], list[Track]]:
    """How each node is stored, shared by the key-frame codecs: per node (rotation_mode,
    translation_mode, scale_mode, rotation_index, translation_index, scale_index) as
    docs/FORMAT.md's node tables (0 the rest value, 1 constant, 2 animated; an index is the
    track's among the animated ones, or the first of its constants), the f32 constants, and
    the animated tracks in node order (rotation, translation, scale)."""
    sk = motion.skeleton
    by_node: dict[tuple[int, int], Track] = {(t.node, t.part): t for t in tracks}
    ordered = [by_node[(i, part)] for i in range(sk.node_count) for part in (ROT, TRANS, SCALE)
               if (i, part) in by_node]
    animated = [t for t in ordered if t.keys is not None]
    index = {id(t): i for i, t in enumerate(animated)}
    constants: list[float] = []
    rows = []
    for i in range(sk.node_count):
        rest_q = f32_exact(sk.rest_rotations[i])
        rest = {ROT: (rest_q, -rest_q), TRANS: (f32_exact(sk.offsets[i]),),
                SCALE: (f32_exact(sk.rest_scales[i]),)}
        modes, where = [0, 0, 0], [0, 0, 0]
        for part in (ROT, TRANS, SCALE):
            t = by_node.get((i, part))
            if t is None:
                continue
            if t.keys is not None:
                modes[part], where[part] = 2, index[id(t)]
            elif not any(np.array_equal(t.constant, r) for r in rest[part]):
                modes[part], where[part] = 1, len(constants)
                constants.extend(t.constant.tolist())
        rows.append((modes[0], modes[1], modes[2], where[0], where[1], where[2]))
    return rows, constants, animated


class Compensation:
    """Top-down error compensation (the idea of seed 000's FKBC), for codecs that code nodes
    parents first.

    A joint's rotation target is not its original local rotation but the one that, applied to
    its *decoded* parent, best re-aims its children at their original positions (a Wahba fit
    over its child points, plus virtual vertices at the shell distance that fix the twist). A
    parent's error then moves its children but is not carried on down the chain, so each
    rotation only answers for its own bones. Scales are not compensated: a scale track's
    error moves every point below its node. :attr:`reach` says which points each track (a
    node's rotation, translation or scale, in ``track_nodes`` / ``track_parts`` order) moves
    and how far its error is carried.
    """

    def __init__(self, motion: Motion, cm_per_unit: float, shell_cm: float, plan: ClipPlan | None = None,
                 halfway: bool = False) -> None:
        self.motion = motion
        sk = motion.skeleton
        self.frames = motion.frame_count
        # A long clip's world poses are not held (F x N x 7 float64): each target builds its
        # node's rotation and its points' positions along their chains (_world_pose), the
        # products forward kinematics makes; a short clip's are computed once (the positions
        # shared with the runtime check and the plan).
        self.chains = [self._chain(i) for i in range(sk.node_count)]
        short = short_clip(motion)
        self.pos_w = shared_world_positions(motion) if short else None
        self.rot_w = world_rotations(motion) if short else None
        scales = motion.scales
        self.scaled = not (scales.ndim == 3 and scales.strides[0] == 0 and np.all(scales[0] == 1.0))
        self.shell = shell_cm / cm_per_unit
        if plan is not None and (plan.frames != motion.frame_count or halfway and plan.held is None
                                 and motion.frame_count > 1):
            raise ValueError(f"the plan given is of a clip of {plan.frames} frames"
                             f"{'' if plan.held is not None else ' without held intervals'}; this one has "
                             f"{motion.frame_count}{' and holds half-way' if halfway else ''}")
        self.plan = plan or plan_clip(motion, cm_per_unit, shell_cm, self.pos_w, halfway)
        self.aim = self.plan.aim
        self.track_nodes, self.track_parts = self.plan.track_nodes, self.plan.track_parts
        self.reach = self.plan.reach

    @property
    def track_is_rot(self) -> list[bool]:
        return self.plan.track_is_rot

    def rotation_target(self, i: int, parent_rot: np.ndarray | None, pos_i: np.ndarray,
                        rows: np.ndarray | None = None) -> np.ndarray:
        """Local rotation (F, 4) that best places node i's aim points given the decoded
        parent rotation (None for a root) and the decoded position of i; on frames ``rows``
        only (parent_rot and pos_i given there) when not None."""
        count = self.frames if rows is None else len(rows)
        world = np.empty((count, 4))
        # A run of frames at a time (each frame's fit is its own): a long clip's point sets
        # (F x (aim points + 3) x 3, a few of them) are never whole.
        for start in range(0, count, TARGET_CHUNK):
            stop = min(start + TARGET_CHUNK, count)
            frames = slice(start, stop) if rows is None else rows[start:stop]
            world[start:stop] = self._aimed(i, frames, pos_i[start:stop])
        world = R.quat_make_continuous(world)
        if parent_rot is None:
            return world
        return R.quat_make_continuous(R.quat_multiply(R.quat_conjugate(parent_rot), world))

    def _aimed(self, i: int, frames: slice | np.ndarray, pos_i: np.ndarray) -> np.ndarray:
        """:meth:`rotation_target`'s world rotations of node i on ``frames`` (before they are
        made continuous), its decoded position ``pos_i`` there."""
        aim = self.aim[i]
        orig, here, points = self._world_pose(i, frames)
        # The aim points (their columns alone: on ``frames``, not every node's), then the shell
        # vertices; each set rotated in one call.
        there = np.stack(points, axis=1) if aim else np.empty((len(orig), 0, 3))
        shell = np.eye(3) * self.shell
        vs = np.concatenate((R.quat_rotate(R.quat_conjugate(orig)[:, None], there - here[:, None]),
                             np.broadcast_to(shell, (len(orig), 3, 3))), axis=1)
        us = np.concatenate((there - pos_i[:, None], R.quat_rotate(orig[:, None], shell)), axis=1)
        ws = np.array([1.0] * len(aim) + [0.25 if aim else 1.0] * 3)
        return native.wahba(vs, us, ws, orig)

    def _chain(self, i: int) -> list[int]:
        """Node i's ancestors from its root down, then i."""
        chain = [i]
        while self.motion.skeleton.parents[chain[-1]] >= 0:
            chain.append(int(self.motion.skeleton.parents[chain[-1]]))
        return chain[::-1]

    def _world_pose(self, i: int, frames: slice | np.ndarray) -> tuple[np.ndarray, np.ndarray, list[np.ndarray]]:
        """The original world rotation (n, 4) and position (n, 3) of node i on ``frames``, and
        the positions of its aim points: a long clip's posed along their chains from the root
        down, the products and sums forward kinematics makes (the same numbers)."""
        if self.pos_w is not None:
            return self.rot_w[frames, i], self.pos_w[frames, i], [self.pos_w[frames, c] for c in self.aim[i]]
        m = self.motion
        rot, pos, scale = m.rotations, m.translations, m.scales
        world: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray | None]] = {}

        def pose(a: int) -> None:
            p = int(m.skeleton.parents[a])
            r, t = np.array(rot[frames, a], dtype=np.float64), np.array(pos[frames, a], dtype=np.float64)
            s = np.array(scale[frames, a], dtype=np.float64) if self.scaled else None
            if p < 0:
                world[a] = (r, t, s)
                return
            pr, pp, ps = world[p]
            world[a] = (R.quat_multiply(pr, r), pp + R.quat_rotate(pr, t if ps is None else ps * t),
                        None if ps is None else ps * s)
        for a in self.chains[i]:
            pose(a)
        points = []
        for c in self.aim[i]:
            for a in self.chains[c][len(self.chains[i]):]:
                if a not in world:
                    pose(a)
            points.append(world[c][1])
        return world[i][0], world[i][1], points


TARGET_CHUNK = 8192
"""Frames :meth:`Compensation.rotation_target` fits at a time."""

class KeyframeFitter:
    """Fits a clip's tracks parents first with :class:`Compensation` and repairs them through
    the runtime until the clip meets the tolerance.

    A codec subclasses it with its storage: :meth:`mandatory_keys` (frames every track keys),
    :meth:`payload` (the clip's bytes), ``quantizer_for(lo, hi, step)`` (the key quantizer)
    and ``key_grid`` (the frames new keys prefer, ``curves.fit_keys``).
    """

    quantizer_for = staticmethod(Quantizer.for_range)
    key_grid = 1
    split = False  # whether the codec's curves detach their first segment (``Track.split``)
    # Refits that change a track only where its target or budgets did: the reference rotation
    # kept (_retarget_kept), the keys elsewhere kept (untouched_keys). Otherwise every refit
    # re-derives the track and may move keys anywhere, and a long clip's repairs never settle.
    local_refits = False
    folds = True  # tracks may fold to their rest value or a constant (fit_track)

    def mandatory_keys(self) -> np.ndarray:
        """Frames every track keys."""
        raise NotImplementedError

    def payload(self, tracks: list[Track]) -> bytes:
        """The clip's payload for fitted ``tracks``."""
        raise NotImplementedError

    def __init__(self, motion: Motion, cm_per_unit: float, settings: KeyframeSettings,
                 plan: ClipPlan | None = None) -> None:
        """``plan``: the clip's whole-clip decisions (:func:`mocodec.clip_plan.plan_clip`, with
        the held intervals when ``settings.halfway_factor`` > 0), measured here when None."""
        self.motion = motion
        self.settings = settings
        self.frames = motion.frame_count
        self.cm_per_unit = cm_per_unit
        self.tol_units = settings.tolerance.per_node_cm(motion.skeleton) / cm_per_unit
        self.compensation = Compensation(motion, cm_per_unit, settings.shell_cm, plan,
                                         halfway=settings.halfway_factor > 0.0)
        self.mandatory = self.mandatory_keys()
        self._fits = 0
        self._decoded: tuple[list[np.ndarray], list[np.ndarray], list[np.ndarray]] | None = None
        self.tracks: dict[tuple[int, int], Track] = {}

    # -------------------------------------------------------------- passes
    def _fit(self, track: Track) -> None:
        self._fits += 1  # a pass tells a node's refitted tracks by this count
        keep = untouched_keys(track) if self.local_refits else None
        values = track.values  # an MRP track's derived once for the fit and its state
        fit_track(track, self.mandatory, self.settings.quant_fraction, self.quantizer_for, self.key_grid, keep,
                  values, self.folds)
        if self.local_refits:
            track.fitted = Fitted.of(track, values)

    def _fit_pass(self, tracks: dict[tuple[int, int], Track], refit: set[tuple[int, int]]) -> None:
        """Walk the nodes parents first; refit a track when asked to or when its parent's
        decoded pose changed since the last pass."""
        sk = self.motion.skeleton
        comp = self.compensation
        n = sk.node_count
        # Per node (F, 4 | 3) arrays, not one (F, N, d) block: a node whose value is the same on
        # every frame (a scale at rest) stays a broadcast view, a node whose parent and own track
        # are as they were keeps its previous arrays (the same numbers, not computed again),
        # and the previous pass's arrays are let go node by node, so that a pass holds one
        # decoded pose of the clip, not two.
        rot_d: list[np.ndarray] = [np.empty(0)] * n
        pos_d: list[np.ndarray] = [np.empty(0)] * n
        scale_d: list[np.ndarray] = [np.empty(0)] * n
        moved = np.zeros(n, dtype=bool)
        prev = self._decoded
        self._decoded = None
        rot_moved = np.zeros((self.frames, n), dtype=bool)  # frames where a node's decoded rotation changed
        need_pos, need_rot = self._read_poses(tracks)
        for i in range(n):
            p = sk.parents[i]
            parent_moved = p >= 0 and moved[p]
            same_parent = prev is not None and not parent_moved
            fits = self._fits
            local_t = self._vector_part(tracks, refit, i, TRANS, sk.offsets[i])
            if not need_pos[i]:
                pos_d[i] = _UNREAD  # an end site's position: no node and no target reads it
            elif same_parent and self._fits == fits:
                pos_d[i] = prev[1][i]
            elif p < 0:
                pos_d[i] = local_t
            else:
                pos_d[i] = pos_d[p] + R.quat_rotate(rot_d[p], scale_d[p] * local_t)
            # Rotation.
            key = (i, ROT)
            fits = self._fits
            t = tracks.get(key)
            if t is not None:
                parent_rot = rot_d[p] if p >= 0 else None
                if self.local_refits and t.target is not None and prev is not None:
                    # Only the frames whose decoded parent or position moved get a new target.
                    rows = np.flatnonzero(np.any(prev[1][i] != pos_d[i], axis=1)
                                          | (rot_moved[:, p] if p >= 0 else False))
                    if len(rows):
                        target = comp.rotation_target(i, None if p < 0 else parent_rot[rows], pos_d[i][rows], rows)
                        if not self._retarget_rows(t, target, rows):
                            self._retarget_all(t, i, parent_rot, pos_d[i])
                    if len(rows) or key in refit:
                        self._fit(t)
                elif key in refit or parent_moved or t.target is None:
                    self._retarget_all(t, i, parent_rot, pos_d[i])
                    self._fit(t)
            if not need_rot[i]:  # no node reads it (a leaf's, or a node's above end sites alone)
                rot_d[i] = _UNREAD
            elif same_parent and self._fits == fits:
                rot_d[i] = prev[0][i]
            else:
                # A rotation track's decoded rotations are not kept on it (F x 4 numbers a track):
                # the next pass keeps this node's arrays, or refits the track.
                local_q = (_track_recon(t, keep=False) if t is not None  # the rest rotation (identity for BVH)
                           else np.broadcast_to(f32_exact(sk.rest_rotations[i]), (self.frames, 4)))
                rot_d[i] = np.asarray(local_q, dtype=np.float64) if p < 0 else R.quat_multiply(rot_d[p], local_q)
            # Scale (not compensated: its target is the original).
            fits = self._fits
            local_s = self._vector_part(tracks, refit, i, SCALE, sk.rest_scales[i])
            if same_parent and self._fits == fits:
                scale_d[i] = prev[2][i]
            else:
                scale_d[i] = local_s if p < 0 else _product(scale_d[p], local_s)
            moved[i] = prev is None or not (_same(prev[0][i], rot_d[i]) and _same(prev[1][i], pos_d[i])
                                            and _same(prev[2][i], scale_d[i]))
            if self.local_refits and prev is not None and moved[i] and need_rot[i]:
                rot_moved[:, i] = np.any(prev[0][i] != rot_d[i], axis=1)
            if prev is not None:  # nothing after this node reads its previous pose
                prev[0][i] = prev[1][i] = prev[2][i] = np.empty(0)
        self._decoded = (rot_d, pos_d, scale_d)

    def _retarget_rows(self, track: Track, target: np.ndarray, rows: np.ndarray) -> bool:
        """Give a rotation track new targets on frames ``rows`` in its own parameterisation
        (:func:`_retarget_kept`); False when they do not fit it."""
        return _retarget_kept(track, target, rows)

    def _retarget_all(self, track: Track, node: int, parent_rot: np.ndarray | None, pos: np.ndarray) -> None:
        """Give a rotation track its target on every frame from the decoded parent rotation and
        node position, its parameterisation derived anew (:func:`_retarget`)."""
        _retarget(track, self.compensation.rotation_target(node, parent_rot, pos), self.motion, node)

    def _prepare(self, tracks: dict[tuple[int, int], Track]) -> None:
        """Called with the new tracks before the first pass: what a subclass sets on them."""

    def _read_poses(self, tracks: dict[tuple[int, int], Track]) -> tuple[np.ndarray, np.ndarray]:
        """Which nodes' decoded positions and rotations a pass reads (N,) bool each: a node's
        position where its rotation track's target or a child's position needs it, its rotation
        where a child's position does (an end site's position, and the rotation of a joint
        above end sites alone, nothing reads: not held, F x 3 and F x 4 numbers a node)."""
        sk = self.motion.skeleton
        need_pos = np.zeros(sk.node_count, dtype=bool)
        need_rot = np.zeros(sk.node_count, dtype=bool)
        for i in range(sk.node_count - 1, -1, -1):  # children before parents
            need_pos[i] |= (i, ROT) in tracks
            p = sk.parents[i]
            if p >= 0 and need_pos[i]:
                need_rot[p] = need_pos[p] = True
        return need_pos, need_rot

    def _vector_part(self, tracks: dict[tuple[int, int], Track], refit: set[tuple[int, int]], node: int,
                     part: int, rest: np.ndarray) -> np.ndarray:
        """A node's decoded translation or scale (F, 3), its track (re)fitted when asked to."""
        t = tracks.get((node, part))
        if t is None:
            return np.broadcast_to(f32_exact(rest), (self.frames, 3))
        if (node, part) in refit or t.keys is None and t.constant is None:
            self._fit(t)
        return _track_recon(t)

    def run(self, scale: float, check: ClipCheck) -> ClipResult:
        """Fit every track with budgets at ``scale`` and repair until ``check`` passes (stats:
        keys, tracks, repairs, budget_scale); :class:`ToleranceNotMet` after
        ``settings.max_repairs`` repairs."""
        sk = self.motion.skeleton
        comp = self.compensation
        budgets0 = initial_budgets(comp.reach, self.tol_units, scale)
        plan = comp.plan
        half = (HalfwayHold(plan.held, self.settings.halfway_factor, self.tol_units)
                if self.settings.halfway_factor > 0.0 and self.frames > 1 else None)
        tracks: dict[tuple[int, int], Track] = {}
        order = []
        for i, part, b, stored in zip(plan.track_nodes, plan.track_parts, budgets0, plan.stored):
            if not stored:
                continue  # the rest value on every frame: nothing to store
            if part == ROT:
                # Values and target come with the first pass (_retarget): no F x 3 zeros till then.
                t = Track(i, KIND_MRP, np.broadcast_to(np.zeros(3), (self.frames, 3)), None, np.zeros(4),
                          np.zeros(3))
            else:
                v = (self.motion.translations if part == TRANS else self.motion.scales)[:, i]
                t = Track(i, KIND_TRANSLATION if part == TRANS else KIND_SCALE, v.copy(), v, np.zeros(4),
                          np.zeros(3))
            t.rest = f32_exact((sk.rest_rotations, sk.offsets, sk.rest_scales)[part][i])
            t.base_budget = float(b)
            # One number broadcast over the frames until a repair tightens it (read-only: tighten
            # gives the track its own array then), not F of them for every track.
            t.budget = np.broadcast_to(float(b), (self.frames,))
            t.split = self.split
            tracks[(i, part)] = t
            order.append((i, part))
        row_of = {key: k for k, key in enumerate(zip(comp.track_nodes, comp.track_parts))}
        reach_rows = [row_of[key] for key in order]
        reach = TrackReach(comp.reach.affects[reach_rows], comp.reach.lever[reach_rows],
                           comp.reach.is_rotation[reach_rows])
        self._prepare(tracks)
        self.tracks = tracks  # the last run's, as fitted (a caller that joins fits reads them)
        self._decoded = None
        self._fit_pass(tracks, set(order))
        frames = self.frames

        def repair(errors: np.ndarray) -> Callable[[], None]:
            def moved(k: int, rows: np.ndarray) -> None:
                fitted = tracks[order[k]].fitted
                if fitted is not None:
                    fitted.mark_budget(rows)
            budgets = [tracks[k].budget for k in order]
            changed = set(tighten(budgets, reach, errors[:frames], self.tol_units, moved=moved))
            for k, budget in zip(order, budgets):  # a broadcast budget tightened is a new array
                tracks[k].budget = budget
            if half is not None:
                changed |= set(half.tighten([tracks[k] for k in order], reach, errors[frames:]))
            refit = {order[c] for c in changed}
            return lambda: self._fit_pass(tracks, refit)  # run by meet_tolerance once the errors are gone

        tolerance = self.tol_units if half is None else half.stacked(self.tol_units)
        attempt = meet_tolerance(lambda: self.payload(list(tracks.values())),
                                 check if half is None else half.check(check), tolerance,
                                 repair, self.settings.max_repairs)
        if not attempt.met:
            raise ToleranceNotMet(f"scale {scale}: still {attempt.worst(tolerance):.3f}x over the "
                                  f"tolerance after {self.settings.max_repairs} repairs")
        keys = sum(len(t.keys) for t in tracks.values() if t.keys is not None)
        stats = {"keys": keys, "tracks": len(tracks), "repairs": attempt.adjustments, "budget_scale": scale}
        if half is not None:
            stats["halfway_released"] = int(half.released.sum())
            repaired = np.zeros(frames - 1, dtype=bool)
            for t in tracks.values():
                if t.half_budget is not None:
                    repaired |= np.isfinite(t.half_budget)
            stats["halfway_repaired"] = int(repaired.sum())
        return ClipResult(attempt.payload, attempt.errors_units[:frames], stats)


class HalfwayHold:
    """The tolerance half-way between frames (:attr:`KeyframeSettings.halfway_factor`): which
    intervals are held (the capture moves smoothly through them), the tolerance there per
    node, the clip check extended to the runtime's samples at x + 1/2, and the repair there.

    Tracks start with no half-way budgets, so the fit is the frames' own; only where the
    runtime's half-way sample of a point is over do the tracks on its chain get a half-way
    budget, on that interval and its neighbours (:meth:`tighten`), and are refitted there (a
    local refit keeps their other keys), so the hold costs little fitting where the frames'
    curves already keep to it half-way (stats ``halfway_repaired``: the intervals given a
    half-way budget).

    The frames are the promise; half-way is held as far as repairs reach. An interval a
    track's parameters jump across (:func:`_parameter_flips`) is released at once with its
    neighbours, and one still over after :attr:`RELEASE_AFTER` repairs too: no longer
    measured (counted in :attr:`released`) rather than failing the clip, since there no curve
    through the frames' targets follows the original's half-way path (keys on every frame
    already, or a track's parameters jumping where its rotation does not, as a thumb turning
    round in CMU 06_13).
    After :attr:`HOLD_ROUNDS` checks an interval over is released at once, so that the
    frames' repairs converge as they do without the hold (the tracks' half-way budgets stay)."""

    RELEASE_AFTER = 1
    HOLD_ROUNDS = 20

    def __init__(self, held: np.ndarray, factor: float, tol_units: np.ndarray) -> None:
        """``held`` (F-1,) bool: the intervals held (:attr:`ClipPlan.held`)."""
        self.smooth = held
        self.factor = factor
        self.frame_tolerance = tol_units
        self.tolerance = factor * tol_units
        # Repairs an interval has failed: only whether more than RELEASE_AFTER counts, and a
        # clip has at most max_repairs + 1 checks (int32, not F - 1 int64).
        self.fails = np.zeros(len(self.smooth), dtype=np.int32)
        self.released = np.zeros(len(self.smooth), dtype=bool)
        self.rounds = 0

    def held(self, half_errors: "np.ndarray | OverRows") -> "np.ndarray | OverRows":
        """Half-way errors (F-1, N) with the intervals not held zeroed, in place (the
        errors are the check's own array): no copy of a long clip's (F-1, N)."""
        if isinstance(half_errors, OverRows):
            half_errors.zero(~(self.smooth & ~self.released))
        else:
            half_errors[~(self.smooth & ~self.released)] = 0.0
        return half_errors

    def stacked(self, tol_units: np.ndarray) -> RowTolerance:
        """Per row of :meth:`check`'s errors (2F-1, N): the tolerance on frames, then half-way."""
        return RowTolerance(tol_units, len(self.smooth) + 1, self.tolerance)

    def check(self, check: ClipCheck) -> ClipCheck:
        """``check`` on the frames, then on the held half-way samples (``check(payload,
        halfway=True)``, zero where not held), as one (2F-1, N) :class:`OverRows` (the rows over
        the frames' tolerance, then those over the half-way one: all the repairs read); counts
        the repairs each interval has failed and releases those over :attr:`RELEASE_AFTER`."""
        def both(payload: bytes) -> OverRows:
            self.rounds += 1
            # Rows within the tolerance are never held (a long clip's (2F-1) x N numbers, most
            # of them within): the check keeps the others as it goes, or they are picked out.
            if sparse:
                half = check(payload, halfway=True, over=self.tolerance)
            else:
                half = OverRows.of(check(payload, halfway=True), self.tolerance)
            self.held(half)
            over = half.rows[np.any(half.over(self.tolerance), axis=1)]
            self.fails[over] += 1
            self.released |= self.fails > self.RELEASE_AFTER
            if self.rounds > self.HOLD_ROUNDS:
                self.released[over] = True
            if sparse:
                frames = check(payload, over=self.frame_tolerance)
            else:
                frames = OverRows.of(check(payload), self.frame_tolerance)
            self.held(half)
            return OverRows.stack(frames, half)
        sparse = getattr(check, "over_rows", False)
        return both

    def tighten(self, tracks: list[Track], reach: TrackReach, half_errors: np.ndarray,
                factor: float = 0.7) -> list[int]:
        """Hold the tracks on the chains of the held half-way samples over the tolerance
        (``half_errors`` (F-1, N), file units): on each failing interval and its held
        neighbours a track's half-way budget becomes at most its own curve's error there now
        times ``min(factor, 0.95 * tolerance / error)`` (what :func:`tolerance.tighten` does
        to frames), and at most :attr:`factor` times its frame budgets. A track without
        half-way budgets gets them (inf elsewhere). Returns the indices of the tracks changed."""
        changed: list[int] = []
        if isinstance(half_errors, OverRows):  # (zeroed in place)
            rows, over = half_errors.rows, self.held(half_errors).over(self.tolerance)
        else:
            over = self.held(half_errors) > self.tolerance[None, :]
            rows = np.arange(len(over))
        if not over.any():
            return changed
        for k, t in enumerate(tracks):  # first release what a track's parameters jump across
            at = rows[np.any(over[:, reach.affects[k]], axis=1)]
            if len(at):  # and their neighbours: a curve's tangent there spans the jump
                flips = at[_parameter_flips(t, at)]
                self.released[np.clip(np.concatenate((flips - 1, flips, flips + 1)), 0, len(self.released) - 1)] = True
        errors = self.held(half_errors)
        rows, ratio = failing_ratios(errors, self.tolerance)
        if not len(rows):
            return changed
        failing = ratio < 1.0
        for k, t in enumerate(tracks):
            spread = budget_multipliers(ratio, failing, reach.affects[k], factor, 1, rows, len(errors))
            if spread is None:
                continue
            at = np.flatnonzero((spread < 1.0) & self.smooth)
            cap = self.factor * np.minimum(t.budget[at], t.budget[at + 1])
            wanted = np.minimum(cap, _half_errors(t, at) * spread[at])
            if t.half_budget is None:
                t.half_budget = np.full(len(self.smooth), np.inf)
            if np.any(wanted < t.half_budget[at]):
                old = t.half_budget[at]
                new = np.minimum(old, wanted)
                if t.fitted is not None:
                    t.fitted.mark_half(new != old, at)
                t.half_budget[at] = new
                changed.append(k)
        return changed


def _parameter_flips(track: Track, at: np.ndarray) -> np.ndarray:
    """Which intervals ``at`` a rotation track's parameters jump across while its rotation
    turns little (F-1 bool over ``at``): the mean of the two frames' parameters decodes
    further from the slerp half-way than half the interval's own turn (a swing crossing 180
    degrees, where the twist angle is undefined; a thumb turning round in CMU 06_13). Keys on
    both frames do not help there, so the hold does not try."""
    if track.kind in VECTOR_KINDS or not len(at):
        return np.zeros(len(at), dtype=bool)
    mid = _track_error(track).decoded(0.5 * (track.values_at(at) + track.values_at(at + 1)))
    off = R.quat_angle(halfway_target(track, at), mid)
    return off > 0.5 * R.quat_angle(track.target[at], track.target[at + 1]) + 1e-9


def _half_errors(track: Track, at: np.ndarray) -> np.ndarray:
    """A fitted track's own error half-way between frames ``at`` and ``at + 1`` (against
    :func:`halfway_target`): angle for rotations, distance for translations and scales."""
    target = halfway_target(track, at)
    if track.keys is None:
        recon = np.broadcast_to(track.constant, target.shape)
    else:
        values = catmull_rom(track.keys, track.quantizer.roundtrip(track.key_values), at + 0.5, track.split)
        recon = values if track.kind in VECTOR_KINDS else _track_error(track).decoded(values)
    if track.kind in VECTOR_KINDS:
        return np.linalg.norm(recon - target, axis=1)
    return R.quat_angle(target, recon)


def fit_clip(motion: Motion, cm_per_unit: float, settings: KeyframeSettings, check: ClipCheck,
             fitter_class: type[KeyframeFitter], plan: ClipPlan | None = None) -> ClipResult:
    """Encode one clip so that every node's error, measured by ``check``, is within the
    tolerance on every frame; the smallest payload over ``settings.budget_scales`` wins.
    ``plan``: the clip's whole-clip decisions when already measured (:class:`KeyframeFitter`)."""
    started = time.perf_counter()
    fitter = fitter_class(motion, cm_per_unit, settings, plan)
    best = smallest_fit(motion.name, settings.budget_scales, lambda scale: fitter.run(scale, check))
    best.seconds = time.perf_counter() - started
    return best


def smallest_fit(name: str, scales: tuple[float, ...], fit: Callable[[float], ClipResult]) -> ClipResult:
    """The smallest payload of ``fit(scale)`` over the budget ``scales``; a
    :class:`ToleranceNotMet` naming clip ``name`` and every scale's failure when none met it."""
    best: ClipResult | None = None
    failures = []
    for scale in scales:
        try:
            result = fit(scale)
        except ToleranceNotMet as exc:
            failures.append(str(exc))
            continue
        if best is None or len(result.payload) < len(best.payload):
            best = result
    if best is None:
        raise ToleranceNotMet(f"clip {name!r}: " + "; ".join(failures))
    return best


def _retarget_kept(track: Track, target: np.ndarray, rows: np.ndarray | None = None) -> bool:
    """Give a rotation track a new local target (F, 4), or new targets on frames ``rows``
    only (then ``target`` is (len(rows), 4)), in its own parameterisation: the same reference
    and twist axis, each frame on the hemisphere (and a twist on the turn) it had, so that its
    values change only where the target did. False, the track untouched, when it has no
    parameterisation yet or a new value strays past its ``mrp_limit`` from the
    reference."""
    if track.target is None or track.kind not in (KIND_MRP, KIND_TWIST):
        return False
    at = slice(None) if rows is None else rows
    old_q, old_v = track.target[at], track.values_at(at)
    if old_q.shape != np.shape(target):
        return False
    q = np.array(target, dtype=np.float64)
    q[np.sum(q * old_q, axis=1) < 0.0] *= -1.0
    rest, old_p = q, old_v
    if track.kind == KIND_TWIST:
        half = np.arctan2(q[:, :3] @ track.axis, q[:, 3])
        half += 2.0 * np.pi * np.rint((0.5 * old_v[:, 0] - half) / (2.0 * np.pi))
        theta = 2.0 * half
        rest = R.quat_multiply(R.quat_conjugate(R.quat_from_axis_angle(track.axis, theta)), q)
        old_p = old_v[:, 1:]
    rel = R.quat_multiply(R.quat_conjugate(track.ref), rest)
    other = np.sum(rel * R.quat_from_mrp(old_p), axis=1) < 0.0
    rel[other] *= -1.0
    p = R.mrp_from_quat(rel)
    if len(p) and np.max(np.linalg.norm(p, axis=1)) > track.mrp_limit:
        return False
    new_v = p if track.kind == KIND_MRP else np.concatenate((theta[:, None], p), axis=1)
    full = track.target.copy()
    full[at] = q
    if track.derived:  # (MRP) its values are mrp_values of the new target with these flips
        if track.fitted is not None:  # (held values mark it as they are set)
            track.fitted.mark_values(np.any(new_v != old_v, axis=1), at)
        flips = track.flips.copy()
        flips[at] = other
        track.target, track.flips, track.recon = full, flips, None
        return True
    values = track.values.copy()
    values[at] = new_v
    track.values, track.target, track.recon = values, full, None
    return True


def _retarget(track: Track, target: np.ndarray, motion: Motion, node: int) -> None:
    """Rebuild a rotation track's parameter values for a new local target."""
    fresh = _rotation_track_from(target, motion, node)
    track.recon = None
    if fresh.kind != track.kind:
        track.keys = None  # the old keys belong to another parameterisation
    elif track.fitted is not None and track.target is not None and fresh.value_shape == track.value_shape:
        track.fitted.mark_values(np.any(fresh.values != track.values, axis=1))
    track.take_values(fresh)
    track.kind, track.target, track.ref, track.axis = fresh.kind, fresh.target, fresh.ref, fresh.axis
    track.ref_codes, track.axis_codes, track.mrp_limit = fresh.ref_codes, fresh.axis_codes, fresh.mrp_limit


def _track_values(track: Track) -> np.ndarray:
    """The parameter curve the runtime decodes, on every frame (keys must be set)."""
    return catmull_rom(track.keys, track.quantizer.roundtrip(track.key_values),
                       np.arange(track.frames, dtype=np.float64), track.split)


def _track_recon(track: Track, keep: bool = True) -> np.ndarray:
    """What the runtime decodes for a track on every frame: local rotation, translation or
    scale (with ``keep``, kept on the track until it is fitted again)."""
    if track.recon is not None:
        return track.recon
    frames = track.frames
    if track.keys is None:
        recon = np.broadcast_to(track.constant, (frames, 3 if track.kind in VECTOR_KINDS else 4))
    else:
        values = _track_values(track)
        recon = values if track.kind in VECTOR_KINDS else _track_rotations(track, values)
    if keep:
        track.recon = recon
    return recon


_UNREAD = np.empty((0, 4))  # the decoded rotation or position of a leaf, which no pass reads


def _same(a: np.ndarray, b: np.ndarray) -> bool:
    """``np.array_equal``, at once for the same array (a node's arrays kept from the last pass)."""
    return a is b or np.array_equal(a, b)
