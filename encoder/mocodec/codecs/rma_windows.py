"""``rma``'s fit of a long clip a window of frames at a time (docs/LONG_CLIP_PLAN.md, stage 2).

The whole-clip fit holds its targets and decoded poses for every frame of the clip, about
nine times the raw float32 channels; a window's are a few thousand frames. What must be the
same in every window is decided once for the whole clip: the clip plan (tracks stored, aim
points, reach, so the budgets and quantization steps), each rotation track's
parameterisation (kind, reference, twist axis, and per frame which side of the reference
and which turn of the twist), and whether the first segment is detached.

Windows meet at seams. At a seam frame ``c`` every track keys ``c - 1``, ``c`` and ``c + 1``.
A Catmull-Rom segment reads the keys on either side of it and the next one out, so every
frame up to ``c + 1`` depends only on keys up to ``c + 1``, and every frame from ``c - 1`` on only
on keys from ``c - 1`` on: the window before the seam ends at ``c + 1``, the next one starts at
``c - 1`` with those three keys as they were fitted (frozen), and the asset decodes every frame
of a window as the window's own one-clip asset does, except the window's last frame: the
runtime evaluates a clip's last frame at the end of its last segment in binary32, about 1e-8
rad from the key, which the window after checks as the key it is. Half-way between frames, the interval ``(c, c + 1)`` is checked in
the window after the seam and ``(c - 1, c)`` in the one before (the other window lacks a key its
segment reads). Windows run in order, each taking its frozen keys from the one before.

A window whose fit halves a track's quantization step (:func:`mocodec.keyframes.fit_track`)
cannot keep it to itself, since the format stores one step a track. A halved step is exactly
half in binary32, so the frozen keys (q x step) are 2q on the finer lattice and decode as
before, and the keys of the windows before are doubled onto it when they are joined: the same
values, nothing fitted again. (A step that were not a power of two finer would have the clip
fitted again from the first window with it, at most :data:`MAX_ROUNDS` times.) A track whose
original stays near its rest on every frame is left at rest for the whole clip
(:func:`rest_tracks`): windows fold no track, so that each stores the same ones.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from .. import rotations as R
from ..bake.progress import report_within
from ..clip_plan import ROT, ClipPlan, plan_clip
from ..encode import OneClipCheck, RuntimeCheck
from ..keyframes import KIND_TWIST, Track, _retarget_kept, _rotation_track_from, smallest_fit
from ..kinematics import forward_kinematics
from ..motion import Motion, frame_runs
from ..quantize import StepQuantizer, f32_exact
from ..tolerance import ClipCheck, OverRows, ToleranceNotMet, initial_budgets, within
from . import ClipResult
from .rma import MIN_WINDOW_FRAMES, RMAFitter, RMASettings, frame0_jumps, section_prefix, serialize
from .rma_bitstream import CurveTrack

SEAM = 3
"""Keys every track keeps at a seam: the frame before it, the seam frame and the one after."""

MAX_ROUNDS = 4
"""Fits of the whole clip, window by window, before a step that keeps halving is an error."""

@dataclass
class RotationParameters:
    """A rotation track's parameterisation over the whole clip, chosen from the node's original
    local rotations by the rules of the whole-clip fit (:func:`mocodec.keyframes._rotation_track_from`).

    ``negated`` (packed bits, a frame each): the frames whose original local rotation the
    parameters read negated (the side of the reference, for MRPs); for a twist, ``turn`` (F,)
    float32: its angle on every frame (which turn), and ``side`` (packed bits): the frames whose
    MRPs are of the swing negated. A window maps its compensated targets into these
    (:func:`_retarget_kept`): the same reference, axis, side and turn on every frame, whatever
    window it is in. (Bits and a float a frame: a long clip's parameters are not held.)"""

    kind: int
    ref: np.ndarray
    ref_codes: np.ndarray
    axis: np.ndarray
    axis_codes: np.ndarray | None
    negated: np.ndarray
    turn: np.ndarray | None = None
    side: np.ndarray | None = None

    def target(self, raw: np.ndarray, start: int) -> np.ndarray:
        """The original local rotations ``raw`` (n, 4) of frames ``start ...`` as the parameters read them."""
        return raw * _signs(self.negated, start, len(raw))[:, None]

    def values(self, target: np.ndarray, start: int) -> np.ndarray | None:
        """A twist track's values (n, 4) on frames ``start ...`` of its :meth:`target` there
        (None: an MRP track's are derived from its target)."""
        if self.turn is None:
            return None
        theta = self.turn[start:start + len(target)].astype(np.float64)
        rel = _swing(target, theta, self.axis, self.ref) * _signs(self.side, start, len(target))[:, None]
        with np.errstate(invalid="ignore", divide="ignore"):  # at the antipode: NaN, as the whole fit's
            return np.concatenate((theta[:, None], R.mrp_from_quat(rel)), axis=1)


def _signs(packed: np.ndarray, start: int, count: int) -> np.ndarray:
    """-1 where bits ``start ... start + count - 1`` of ``packed`` are set, else 1."""
    first, skip = divmod(start, 8)
    bits = np.unpackbits(packed[first:first + (skip + count + 7) // 8])[skip:skip + count]
    return np.where(bits.astype(bool), -1.0, 1.0)


def _swing(q: np.ndarray, theta: np.ndarray, axis: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """Rotations ``q`` less their twist ``theta`` about ``axis``, relative to ``ref`` (n, 4)."""
    rest = R.quat_multiply(R.quat_conjugate(R.quat_from_axis_angle(axis, theta)), q)
    return R.quat_multiply(R.quat_conjugate(ref), rest)


def rotation_parameters(motion: Motion, plan: ClipPlan) -> dict[int, RotationParameters]:
    """Per node with a stored rotation track, its :class:`RotationParameters`, one node's
    rotations at a time (a node's (F, 4) and its fit's temporaries, not the clip's)."""
    out = {}
    for i, part, stored in zip(plan.track_nodes, plan.track_parts, plan.stored):
        if part != ROT or not stored:
            continue
        raw = np.asarray(motion.rotations[:, i], dtype=np.float64)
        t = _rotation_track_from(raw, motion, i)
        negated = np.sum(t.target * raw, axis=1) < 0.0
        if t.derived:  # MRPs of the target relative to the reference, on the other side where flipped
            out[i] = RotationParameters(t.kind, t.ref, t.ref_codes, t.axis, t.axis_codes, np.packbits(negated ^ t.flips))
            continue
        turn = t.values[:, 0].astype(np.float32)
        rel = _swing(t.target, turn.astype(np.float64), t.axis, t.ref)
        side = np.sum(rel * R.quat_from_mrp(t.values[:, 1:]), axis=1) < 0.0
        out[i] = RotationParameters(t.kind, t.ref, t.ref_codes, t.axis, t.axis_codes, np.packbits(negated), turn,
                                    np.packbits(side))
    return out


def window_bounds(frames: int, window: int, grid: int = 1) -> list[tuple[int, int]]:
    """The windows ``[start, stop)`` of a clip of ``frames`` frames in windows of at most about
    ``window`` frames: consecutive ones share the three frames around a seam. A seam is the
    first frame of a key cell of ``grid`` frames (a window starts on a cell boundary, so its
    cells are the clip's)."""
    count = -(-frames // window)
    seams: list[int] = []
    for k in range(1, count):
        c = int(round(k * frames / count))
        c = grid * ((c - 1) // grid) + 1
        # Frames between the seams' triples (and frames 0 and 1 before the first: a detached
        # first segment is window 0's): a seam a cell rounds too near is left out.
        if c >= (seams[-1] + SEAM + 1 if seams else SEAM) and c + SEAM < frames:
            seams.append(c)
    starts = [0] + [c - 1 for c in seams]
    stops = [c + 2 for c in seams] + [frames]
    return list(zip(starts, stops))


def window_plan(plan: ClipPlan, start: int, stop: int, first: bool, last: bool) -> ClipPlan:
    """The clip's plan for frames ``[start, stop)``: its whole-clip decisions, and its held
    intervals there, less the one next to each seam that the window cannot check exactly."""
    held = None
    if plan.held is not None:
        held = plan.held[start:stop - 1].copy()
        if not first:
            held[0] = False
        if not last:
            held[-1] = False
    return ClipPlan(stop - start, plan.track_nodes, plan.track_parts, plan.stored, plan.spans, plan.aim,
                    plan.reach, held)


class WindowFitter(RMAFitter):
    """:class:`RMAFitter` on one window of a long clip: every stored track keyed (none folds,
    so every window stores the same tracks), rotations in the clip's parameterisation, the
    first :data:`SEAM` keys frozen to the window before's and, before a seam, the last
    :data:`SEAM` frames keys."""

    folds = False

    def __init__(self, motion: Motion, cm_per_unit: float, settings: RMASettings, plan: ClipPlan, *,
                 start: int, params: dict[int, RotationParameters], frozen: dict[tuple[int, int], np.ndarray],
                 seam_after: bool, split: bool, quant_scales: dict[tuple[int, int], float]) -> None:
        self.start, self.params, self.frozen = start, params, frozen
        self.seam_after, self.quant_scales = seam_after, quant_scales
        super().__init__(motion, cm_per_unit, settings, plan)
        self.split = split  # the clip's (RMAFitter looked at the window's own first frames)
        self.mandatory = self.mandatory_keys()

    def mandatory_keys(self) -> np.ndarray:
        f = self.frames
        keys = [0, f - 1] + ([1] if self.split else [])
        if self.frozen:
            keys += list(range(SEAM))
        if self.seam_after:
            keys += list(range(f - SEAM, f))
        return np.unique(keys)

    def _prepare(self, tracks: dict[tuple[int, int], Track]) -> None:
        for key, t in tracks.items():
            t.rest = None
            t.quant_scale = self.quant_scales.get(key, 1.0)
            frozen = self.frozen.get(key)
            if frozen is not None:  # the error there is the window before's, already checked
                budget = np.array(t.budget, dtype=np.float64)
                budget[:SEAM] = np.inf
                t.budget = budget
            if key[1] != ROT:
                if frozen is not None:
                    t.values[:SEAM] = frozen  # (its own copy of the clip's values)
                continue
            p = self.params[key[0]]
            t.kind, t.ref, t.ref_codes, t.axis, t.axis_codes = p.kind, p.ref, p.ref_codes, p.axis, p.axis_codes
            t.mrp_limit = np.inf  # the clip's parameterisation, whatever the window's targets
            t.target = p.target(np.asarray(self.motion.rotations[:, key[0]], dtype=np.float64), self.start)
            twist = p.values(t.target, self.start)
            t.__dict__["_values"] = twist
            t.flips = None if twist is not None else np.zeros(self.frames, dtype=bool)

    def _retarget_rows(self, track: Track, target: np.ndarray, rows: np.ndarray) -> bool:
        kept = _retarget_kept(track, target, rows)
        if kept:
            self._freeze(track)
        return kept

    def _retarget_all(self, track: Track, node: int, parent_rot: np.ndarray | None, pos: np.ndarray) -> None:
        if not _retarget_kept(track, self.compensation.rotation_target(node, parent_rot, pos)):
            raise ToleranceNotMet(f"node {node}: its targets in frames {self.start}-{self.start + self.frames - 1} "
                                  "do not fit the clip's rotation parameters")
        self._freeze(track)

    def _freeze(self, track: Track) -> None:
        """Hold a rotation track's frozen keys' values (held values from then on)."""
        frozen = self.frozen.get((track.node, ROT))
        if frozen is None:
            return
        values = track.values
        if track.derived or not np.array_equal(values[:SEAM], frozen):
            values = np.array(values, dtype=np.float64)
            values[:SEAM] = frozen
            track.values = values


@dataclass
class _Joined:
    """A track's keys so far, window after window: clip frames and lattice integers (int32:
    |q| < 2**30), and what the payload stores of it besides (kind, reference, axis, step)."""

    node: int
    kind: int
    ref_codes: np.ndarray
    axis_codes: np.ndarray | None
    step: np.ndarray
    frames: list[np.ndarray]
    q: list[np.ndarray]

    @classmethod
    def of(cls, t: Track) -> "_Joined":
        return cls(t.node, t.kind, t.ref_codes, t.axis_codes, np.array(t.quantizer.step), [], [])

    def refine(self, step: np.ndarray) -> bool:
        """Put the keys so far on the lattice of a finer ``step`` a power of two times finer
        (a step halved, :func:`mocodec.keyframes.fit_track`: exactly half in binary32): the
        integers doubled, the values the same. False, nothing changed, when it is not that."""
        ratio = self.step / step
        factor = int(ratio[0]) if np.all(ratio == ratio[0]) and ratio[0] >= 1 else 0
        if factor < 1 or factor & (factor - 1) or np.any(self.step != step * factor):
            return False
        if factor > 1:
            if any(len(q) and int(np.abs(q).max()) * factor > StepQuantizer.MAX_Q for q in self.q):
                raise ToleranceNotMet(f"node {self.node}: a finer step puts its keys past 2**30 steps")
            self.q = [q * np.int32(factor) for q in self.q]
            self.step = np.array(step)
        return True

    def curve(self, split: bool) -> CurveTrack:
        """The keys as the payload stores them (the lists let go)."""
        frames = np.concatenate(self.frames).astype(np.int64)
        self.frames = []
        q = np.concatenate(self.q).astype(np.int64)
        self.q = []
        return CurveTrack(kind=self.kind, frames=frames, q=q, step=float(self.step[-1]),
                          angle_step=float(self.step[0]) if self.kind == KIND_TWIST else 0.0,
                          ref_codes=self.ref_codes, axis_codes=self.axis_codes, split=split)


def fit_windowed(motion: Motion, cm_per_unit: float, settings: RMASettings, check: ClipCheck,
                 window: int | None = None) -> ClipResult:
    """Encode one clip within the tolerance on every frame, fitted a window of about
    ``window`` frames at a time (``settings.window_frames`` when None); the smallest payload
    over ``settings.budget_scales``. The joined payload is checked once more on every frame
    by ``check``."""
    started = time.perf_counter()
    window = settings.window_frames if window is None else int(window)
    if window < MIN_WINDOW_FRAMES:
        raise ValueError(f"window_frames must be at least {MIN_WINDOW_FRAMES}, got {window}")
    plan = plan_clip(motion, cm_per_unit, settings.shell_cm, None, settings.halfway_factor > 0.0)
    params = rotation_parameters(motion, plan)
    bounds = window_bounds(motion.frame_count, window, settings.key_grid)
    split = frame0_jumps(motion, cm_per_unit)
    scales = settings.budget_scales
    tried = iter(range(1, len(scales) + 1))  # smallest_fit fits the scales in order, once each
    best = smallest_fit(motion.name, scales, lambda scale: _fit_at_scale(
        motion, cm_per_unit, settings, check, plan, params, bounds, split, scale,
        f", budget {next(tried)} of {len(scales)}" if len(scales) > 1 else ""))
    best.seconds = time.perf_counter() - started
    return best


REST_SHARE = 0.5
"""A track whose original stays within this share of its budget of its rest value on every
frame may be left at rest for the whole clip (:func:`rest_tracks`)."""

REST_TOLERANCE_SHARE = 0.25
"""... when the tracks left at rest move no point further than this share of its tolerance."""


def near_rest(motion: Motion, plan: ClipPlan, budgets: np.ndarray, share: float = REST_SHARE) -> np.ndarray:
    """Per track of ``plan`` (T,) bool: stored, yet its original rotation, translation or
    scale stays within ``share`` of its budget (``budgets`` (T,), radians or file units) of the
    node's rest on every frame, a run of frames at a time."""
    sk = motion.skeleton
    near = np.zeros(len(plan.track_nodes), dtype=bool)
    for k, (i, part, stored) in enumerate(zip(plan.track_nodes, plan.track_parts, plan.stored)):
        if not stored:
            continue
        values = (motion.rotations, motion.translations, motion.scales)[part]
        rest = f32_exact((sk.rest_rotations, sk.offsets, sk.rest_scales)[part][i])
        worst = 0.0
        for rows in frame_runs(motion.frame_count):
            v = np.asarray(values[rows, i], dtype=np.float64)
            off = (R.quat_angle(v, np.broadcast_to(rest, v.shape)) if part == ROT
                   else np.linalg.norm(v - rest, axis=1))
            worst = max(worst, float(off.max()))
            if not worst <= share * budgets[k]:
                break
        near[k] = worst <= share * budgets[k]
    return near


def rest_tracks(motion: Motion, plan: ClipPlan, tol_units: np.ndarray, budgets: np.ndarray) -> np.ndarray:
    """The tracks of ``plan`` (T,) bool left at rest for the whole clip: those
    :func:`near_rest`, less any on the chain of a point that, with them all at rest and every
    other track as captured, moves further than :data:`REST_TOLERANCE_SHARE` of its tolerance
    ``tol_units`` (N,) on some frame (forward kinematics a run of frames at a time; a point
    below several such tracks, or far below one, adds up what compensation would not undo).
    The whole fit folds a track to its rest value when its target stays within its budget; a
    window cannot, since every window must store the same tracks, so the clip decides it once."""
    rest = near_rest(motion, plan, budgets)
    sk = motion.skeleton
    parts = np.asarray(plan.track_parts)
    nodes = np.asarray(plan.track_nodes)
    while rest.any():
        worst = np.zeros(sk.node_count)
        for rows in frame_runs(motion.frame_count):
            local = [np.array(a[rows], dtype=np.float64) for a in (motion.rotations, motion.translations, motion.scales)]
            _, original = forward_kinematics(sk, *local)
            for part, values, at_rest in zip((ROT, 1, 2), local, (sk.rest_rotations, sk.offsets, sk.rest_scales)):
                for i in nodes[rest & (parts == part)]:
                    values[:, i] = f32_exact(at_rest[i])
            _, moved = forward_kinematics(sk, *local)
            worst = np.maximum(worst, np.linalg.norm(moved - original, axis=-1).max(axis=0))
        over = ~(worst <= REST_TOLERANCE_SHARE * tol_units)
        if not over.any():
            break
        rest &= ~plan.reach.affects[:, over].any(axis=1)
    return rest


def _fit_at_scale(motion: Motion, cm_per_unit: float, settings: RMASettings, check: ClipCheck, plan: ClipPlan,
                  params: dict[int, RotationParameters], bounds: list[tuple[int, int]], split: bool,
                  scale: float, stage: str = "") -> ClipResult:
    """The clip in windows at budget ``scale``, tracks near rest left there; should a window
    not meet the tolerance so, the clip again with every track fitted (the whole fit would
    have given them keys back). ``stage`` ends each window's progress report."""
    tol = settings.tolerance.per_node_cm(motion.skeleton) / cm_per_unit
    at_rest = rest_tracks(motion, plan, tol, initial_budgets(plan.reach, tol, scale))
    if at_rest.any():
        try:
            return _fit_rounds(motion, cm_per_unit, settings, check, plan, params, bounds, split, scale, tol, at_rest,
                               stage)
        except ToleranceNotMet:
            at_rest = np.zeros_like(at_rest)
            stage += ", every track keyed"
    return _fit_rounds(motion, cm_per_unit, settings, check, plan, params, bounds, split, scale, tol, at_rest, stage)


def _fit_rounds(motion: Motion, cm_per_unit: float, settings: RMASettings, check: ClipCheck, plan: ClipPlan,
                params: dict[int, RotationParameters], bounds: list[tuple[int, int]], split: bool,
                scale: float, tol: np.ndarray, at_rest: np.ndarray, stage: str = "") -> ClipResult:
    plan = replace(plan, stored=plan.stored & ~at_rest)
    quant_scales: dict[tuple[int, int], float] = {}
    halvings = 0
    for rounds in range(1, MAX_ROUNDS + 1):
        again = False
        joined: dict[tuple[int, int], _Joined] = {}
        frozen: dict[tuple[int, int], np.ndarray] = {}
        stats: dict[str, Any] = {"keys": 0, "tracks": 0, "repairs": 0, "budget_scale": scale,
                                 "windows": len(bounds), "window_rounds": rounds, "at_rest": int(at_rest.sum())}
        for k, (start, stop) in enumerate(bounds):
            part = motion.slice(start, stop)
            first, last = k == 0, k == len(bounds) - 1
            fitter = WindowFitter(part, cm_per_unit, settings, window_plan(plan, start, stop, first, last),
                                  start=start, params=params, frozen=frozen, seam_after=not last,
                                  split=split and first, quant_scales=quant_scales)
            own = OneClipCheck(RuntimeCheck([part], [cm_per_unit], "rma"), section_prefix(1))
            result = fitter.run(scale, own)
            stats["repairs"] += result.stats["repairs"]
            for name in ("halfway_released", "halfway_repaired"):
                if name in result.stats:
                    stats[name] = stats.get(name, 0) + result.stats[name]
            frozen = {}
            for key, t in fitter.tracks.items():
                step = t.quantizer.step
                if t.quant_scale < quant_scales.get(key, 1.0):
                    quant_scales[key] = t.quant_scale  # finer from here on
                    halvings += 1
                keys = np.asarray(t.keys, dtype=np.int64) + start
                q = t.quantizer.encode(t.key_values)
                j = joined.get(key)
                if j is None:
                    j = joined[key] = _Joined.of(t)
                elif not j.refine(step):  # (not a power of two finer: the clip is fitted again with it)
                    again = True
                elif not again:
                    _same_keys(j, keys, q)
                drop = 0 if first else SEAM  # the frozen keys, the window before's
                j.frames.append(keys[drop:].astype(np.int32))
                j.q.append(q[drop:].astype(np.int32))
                if not last:  # the values the keys decode from, exactly (q x step, on any finer lattice too)
                    frozen[key] = q[-SEAM:].astype(np.float64) * step
            del fitter, part, own
            report_within(f"window {k + 1} of {len(bounds)}{stage}" + (f", fit {rounds}" if rounds > 1 else ""))
        if not again:
            break
    else:
        raise ToleranceNotMet(f"quantization steps still changing after {MAX_ROUNDS} fits of the clip in windows")
    tracks = [Track(j.node, j.kind, np.zeros((0, 3)), np.zeros((0, 4)), np.zeros(4), np.zeros(3), keys=np.zeros(0))
              for j in joined.values()]
    stats["steps_halved"] = halvings
    stats["keys"] = sum(sum(len(f) for f in j.frames) for j in joined.values())
    stats["tracks"] = len(tracks)
    curves = {id(t): j for t, j in zip(tracks, joined.values())}
    payload = serialize(motion, tracks, settings.block_keys, curve=lambda t: curves[id(t)].curve(split))
    del tracks, curves, joined
    # The windows' checks covered every frame; the joined payload is checked once more whole.
    # A miss here is a seam that did not join, a bug, not a miss a repair or another budget
    # scale should hide.
    errors = check(payload, over=tol) if getattr(check, "over_rows", False) else OverRows.of(check(payload), tol)
    if not within(errors, tol):
        raise AssertionError(f"clip {motion.name!r} joined from {len(bounds)} windows is over the tolerance on "
                             f"{len(errors.rows)} frames (a bug in the windowed fit)")
    return ClipResult(payload, errors, stats)


def _same_keys(joined: _Joined, keys: np.ndarray, q: np.ndarray) -> None:
    """A window's frozen keys (clip frames ``keys``, integers ``q``) are the window before's
    last ones, on the same lattice."""
    if not (np.array_equal(keys[:SEAM], joined.frames[-1][-SEAM:]) and np.array_equal(q[:SEAM], joined.q[-1][-SEAM:])):
        raise AssertionError(f"node {joined.node}: the keys at the seam at frame {keys[1]} do not join")
