"""What the key-frame fitter decides about a clip as a whole before it fits anything: which
tracks it stores, the points each rotation aims, how far each track's error is carried, and
which intervals between frames it holds to the tolerance half-way.

These are whole-clip facts (a bone's longest span over every frame, whether a track ever leaves
its rest value), measured a run of frames at a time on a long clip. Held apart from the fit in
a :class:`ClipPlan`, they can be measured once and given to a fit of any part of the clip
(docs/LONG_CLIP_PLAN.md, stage 1: the windowed fitter of a long clip takes them from the plan
of the whole clip instead of measuring its window).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Iterable

import numpy as np

from . import kinematics
from .kinematics import held_intervals, interval_motion
from .motion import Motion, frame_runs
from .quantize import f32_exact
from .tolerance import TrackReach, ancestors_matrix

ROT, TRANS, SCALE = 0, 1, 2  # the part of a node a track animates

SPAN_CHUNK = 4096
"""Frames a long clip is posed at a time to measure its bones' spans."""

ZERO_SPAN = 1e-6
"""A bone no longer than this (file units) on every frame aims nothing: its child sits on its
node, so the rotation aims the points below it instead."""


@dataclass(frozen=True)
class ClipPlan:
    """A clip's whole-clip decisions (:func:`plan_clip`).

    ``track_nodes`` / ``track_parts`` list the tracks the clip may animate
    (:meth:`Motion.animated`, ``ROT``, ``TRANS`` or ``SCALE``), node by node; ``stored`` (T,)
    says which of them leave their rest value on some frame (the others cost nothing);
    ``spans`` the longest distance over the clip from a node to each child it measured;
    ``aim`` per node the points its rotation aims; ``reach`` which points each track moves and
    how far; ``held`` (F-1,) the intervals held half-way (None when not asked for).
    """

    frames: int
    track_nodes: list[int]
    track_parts: list[int]
    stored: np.ndarray
    spans: dict[tuple[int, int], float]
    aim: list[list[int]]
    reach: TrackReach
    held: np.ndarray | None

    @property
    def track_is_rot(self) -> list[bool]:
        return [p == ROT for p in self.track_parts]


def plan_clip(motion: Motion, cm_per_unit: float, shell_cm: float, world: np.ndarray | None = None,
              halfway: bool = False) -> ClipPlan:
    """The :class:`ClipPlan` of ``motion``: from its world positions ``world`` (F, N, 3) when
    held, else posed a run of :data:`SPAN_CHUNK` frames at a time (the same numbers: each
    frame's are its own, and the largest of the runs' largest is the largest). ``shell_cm`` is
    the distance of the virtual vertices that hold a joint's twist; ``halfway`` asks for the
    held intervals (a clip of more than one frame)."""
    sk = motion.skeleton
    animated = motion.animated()
    nodes = [i for i in range(sk.node_count) for part in (ROT, TRANS, SCALE) if animated[i, part]]
    parts = [part for i in range(sk.node_count) for part in (ROT, TRANS, SCALE) if animated[i, part]]
    over = _over_frames(motion, world)
    spans = _spans(motion, over)
    aim = _aim_points(motion, spans)
    reach = _reach(motion, nodes, parts, aim, spans, shell_cm / cm_per_unit, over)
    held = None
    if halfway and motion.frame_count > 1:
        held = held_intervals(*interval_motion(motion, world), cm_per_unit)
    return ClipPlan(motion.frame_count, nodes, parts, _stored(motion, nodes, parts), spans, aim, reach, held)


Measure = Callable[[np.ndarray, "slice"], np.ndarray]


def _over_frames(motion: Motion, world: np.ndarray | None) -> Callable[[Measure], np.ndarray]:
    """A function that gives the largest of ``measure(positions, rows)`` (an array) over the
    clip's world positions, whole when held, else a run of frames at a time."""
    def over(measure: Measure) -> np.ndarray:
        if world is not None:
            return measure(world, slice(None))
        out = None
        for rows, pos in kinematics.world_position_chunks(motion, SPAN_CHUNK):
            m = measure(pos, rows)
            out = m if out is None else np.maximum(out, m)
        return out
    return over


def _spans(motion: Motion, over: Callable[[Measure], np.ndarray]) -> dict[tuple[int, int], float]:
    """The longest distance from each node to each child, and through a zero-length bone
    (:data:`ZERO_SPAN`) to the child's children, and so on: one pass over a long clip's poses
    per level of zero-length bones."""
    sk = motion.skeleton
    spans: dict[tuple[int, int], float] = {}
    frontier = [(i, c) for i in range(sk.node_count) for c in sk.children(i)]
    while frontier:
        found = over(lambda pos, _rows: np.array(
            [np.linalg.norm(pos[:, c] - pos[:, i], axis=-1).max() for i, c in frontier]))
        spans.update(zip(frontier, (float(d) for d in found)))
        frontier = [(i, g) for (i, c), d in zip(frontier, found) if not d > ZERO_SPAN for g in sk.children(c)]
    return spans


def _aim_points(motion: Motion, spans: dict[tuple[int, int], float]) -> list[list[int]]:
    """Per node, the nearest descendants in each branch that sit away from it (skipping
    zero-length bones): the points its rotation aims."""
    sk = motion.skeleton
    aims = []
    for i in range(sk.node_count):
        out: list[int] = []
        stack = sk.children(i)
        while stack:
            c = stack.pop(0)
            if spans[(i, c)] > ZERO_SPAN:
                out.append(c)
            else:
                stack.extend(sk.children(c))
        aims.append(out)
    return aims


def _reach(motion: Motion, nodes: list[int], parts: list[int], aim: list[list[int]],
           spans: dict[tuple[int, int], float], shell: float,
           over: Callable[[Measure], np.ndarray]) -> TrackReach:
    """Which points each track moves, and by how much per unit of its error. A rotation moves
    its aim points and their subtrees by the bone length (compensation keeps it from growing
    further), and a shell vertex of its own."""
    sk = motion.skeleton
    anc = ancestors_matrix(sk)
    t = len(nodes)
    affects = np.zeros((t, sk.node_count), dtype=bool)
    lever = np.zeros((t, sk.node_count))
    for k, (i, part) in enumerate(zip(nodes, parts)):
        if part == TRANS:
            affects[k, anc[i]] = True
            lever[k, anc[i]] = 1.0
            continue
        if part == SCALE:
            below = anc[i].copy()
            below[i] = False
            # A scale error ds moves a point w away by about |ds| |w| / |s| (s the node's local
            # scale); where s is near 0 the subtree has shrunk onto the node too.
            s = np.maximum(np.abs(motion.scales[:, i]).min(axis=-1), 1e-2)
            affects[k, below] = True
            if below.any():
                far = over(lambda pos, rows: (
                    np.linalg.norm(pos[:, below] - pos[:, i:i + 1], axis=-1) / s[rows, None]).max(axis=0))
                lever[k, below] = np.maximum(far, 1e-9)
            else:
                lever[k, below] = 1e-9
            continue
        affects[k, i] = True
        lever[k, i] = shell
        for c in aim[i]:
            bone = spans[(i, c)]
            below = anc[c]
            affects[k, below] = True
            lever[k, below] = np.maximum(lever[k, below], max(bone, shell))
    return TrackReach(affects, lever, np.asarray([p == ROT for p in parts], dtype=bool))


def _stored(motion: Motion, nodes: Iterable[int], parts: Iterable[int]) -> np.ndarray:
    """Per track, whether its value leaves the node's rest on some frame (a rotation: neither
    the rest nor its negation; a translation or scale: the float32 rest, what a node mode
    stores for free), a run of frames at a time."""
    sk = motion.skeleton
    nodes, parts = list(nodes), list(parts)
    rest = [(sk.rest_rotations[i] if part == ROT else f32_exact(sk.offsets[i]) if part == TRANS
             else f32_exact(sk.rest_scales[i])) for i, part in zip(nodes, parts)]
    same = np.ones(len(nodes), dtype=bool)
    negated = np.array([part == ROT for part in parts])
    arrays = (motion.rotations, motion.translations, motion.scales)
    for rows in frame_runs(motion.frame_count):
        for k, (i, part) in enumerate(zip(nodes, parts)):
            if not (same[k] or negated[k]):
                continue
            v = arrays[part][rows, i]
            same[k] &= bool(np.all(v == rest[k]))
            if part == ROT:
                negated[k] &= bool(np.all(v == -rest[k]))
    return ~(same | negated)

