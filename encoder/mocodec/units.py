"""Length units of a skeleton: BVH files do not say theirs, so they are given or guessed; glTF
is in metres.

Tolerances are in centimetres; a file unit is converted with ``cm_per_unit``. The guess picks
the unit that makes the figure closest to a human height of 170 cm. :func:`resolve_library_units`
(what the command line uses) measures the figure on its animated poses, whatever way the rest
pose lies: the median over frames of the pose's span (the largest distance between two of its
points, within a few per cent). Clips that share one skeleton layout are one figure and get one
unit, and a height outside :data:`PLAUSIBLE_CM` after the guess or after a given unit is a
warning naming the file and the height (:class:`UnitsError` with ``strict``).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Callable, Sequence

import numpy as np

from .kinematics import forward_kinematics, world_positions
from .motion import Motion, Skeleton

UNITS: dict[str, float] = {"cm": 1.0, "m": 100.0, "mm": 0.1, "in": 2.54, "cmu": 5.6444}
"""Centimetres per file unit (``cmu``: the CMU ASF unit, 0.056444 m)."""

HUMAN_HEIGHT_CM = 170.0
PLAUSIBLE_CM = (50.0, 300.0)
"""Figure heights that pass without a warning."""
POSE_FRAMES = 64  # frames of a clip the pose height looks at (evenly spread)


class UnitsError(ValueError):
    """A unit that cannot be right (a figure of implausible height, with ``strict``)."""


@dataclass(frozen=True)
class UnitsChoice:
    """The unit a skeleton is read in, and how it was chosen.

    Attributes
    ----------
    cm_per_unit : float
    label : str
        A key of :data:`UNITS`, or ``"custom"`` for an explicit ``cm_per_unit``.
    guessed : bool
        True when neither a unit nor a scale was given.
    height_units, height_cm : float
        Height of the figure in file units and in centimetres (of the rest pose, or of the
        animated poses for :func:`resolve_library_units`).
    known : str, optional
        Why the unit is certain without being given (``"glTF is in metres"``).
    """

    cm_per_unit: float
    label: str
    guessed: bool
    height_units: float
    height_cm: float
    known: str | None = None

    def describe(self) -> str:
        """One line for logs and reports."""
        scale = f"{self.cm_per_unit:g} cm per unit"
        if self.height_units <= 0:
            return f"units: assumed {self.label} ({scale}); the skeleton has no extent to guess from"
        size = f"a skeleton {_short(self.height_units)} units tall ({self.height_cm:.0f} cm)"
        if self.known:
            return f"units: {self.label} ({scale}; {self.known}); {size}"
        if self.guessed:
            return f"units: guessed {self.label} ({scale}) from {size}"
        if self.label == "custom":
            return f"units: {scale} (given); {size}"
        return f"units: {self.label} ({scale}, given); {size}"


def skeleton_height(skeleton: Skeleton) -> float:
    """Height of the rest pose (identity rotations, translations = offsets) in file units.

    The extent along Y (BVH is Y-up); when that is under half the largest extent (a skeleton
    lying down or built Z-up), the largest extent.
    """
    n = skeleton.node_count
    rest_rot = np.zeros((1, n, 4))
    rest_rot[..., 3] = 1.0
    _, pos = forward_kinematics(skeleton, rest_rot, skeleton.offsets[None])
    extent = np.ptp(pos[0], axis=0)
    largest = float(extent.max())
    return float(extent[1]) if extent[1] >= 0.5 * largest else largest


def guess_cm_per_unit(skeleton: Skeleton) -> tuple[float, str]:
    """``(cm_per_unit, label)`` of the unit in :data:`UNITS` that makes the skeleton closest
    (in log ratio) to 170 cm tall; ``cm`` for a skeleton without extent."""
    return _nearest_unit(skeleton_height(skeleton))


def resolve_units(skeleton: Skeleton, units: str | None = None,
                  cm_per_unit: float | None = None) -> UnitsChoice:
    """The unit to read ``skeleton`` in: ``units`` (a key of :data:`UNITS`), or an explicit
    ``cm_per_unit``, or a guess from the skeleton's height when neither is given.

    Raises
    ------
    ValueError
        Unknown unit name, both arguments given, or a non-positive / non-finite scale.
    """
    if units is not None and cm_per_unit is not None:
        raise ValueError(f"give units ({units!r}) or cm_per_unit ({cm_per_unit!r}), not both")
    height = skeleton_height(skeleton)
    if units is not None:
        label = str(units).strip().lower()
        if label not in UNITS:
            raise ValueError(f"unknown unit {units!r}; known units: {', '.join(UNITS)}")
        scale, guessed = UNITS[label], False
    elif cm_per_unit is not None:
        try:
            scale = float(cm_per_unit)
        except (TypeError, ValueError):
            raise ValueError(f"cm_per_unit must be a number, got {cm_per_unit!r}") from None
        if not (math.isfinite(scale) and scale > 0):
            raise ValueError(f"cm_per_unit must be a positive finite number, got {cm_per_unit!r}")
        label, guessed = "custom", False
    else:
        scale, label = guess_cm_per_unit(skeleton)
        guessed = True
    return UnitsChoice(scale, label, guessed, height, height * scale)


_DIRECTIONS = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 0], [1, -1, 0], [1, 0, 1], [1, 0, -1],
                        [0, 1, 1], [0, 1, -1], [1, 1, 1], [1, 1, -1], [1, -1, 1], [-1, 1, 1]], dtype=np.float64)
_DIRECTIONS /= np.linalg.norm(_DIRECTIONS, axis=1, keepdims=True)


def pose_height(motion: Motion) -> float:
    """The figure's height in file units from its animated poses: the median, over up to
    POSE_FRAMES frames, of the pose's span (its largest extent over 13 directions, which is
    within 13 % of the largest distance between two of its points and does not depend on
    which way the figure lies or stands)."""
    frames = np.unique(np.linspace(0, motion.frame_count - 1, min(POSE_FRAMES, motion.frame_count)).astype(int))
    pos = world_positions(_frames_of(motion, frames))
    proj = pos @ _DIRECTIONS.T                      # (S, N, 13)
    span = (proj.max(axis=1) - proj.min(axis=1)).max(axis=1)
    return float(np.median(span))


def _frames_of(motion: Motion, frames: np.ndarray) -> Motion:
    return Motion(motion.skeleton, motion.rotations[frames], motion.translations[frames],
                  motion.frame_time, motion.name, scales=motion.scales[frames])


def _layout_key(sk: Skeleton) -> tuple:
    return (tuple(sk.names), sk.parents.tobytes(), tuple(sk.channels), sk.is_end_site.tobytes())


def source_file(motion: Motion) -> str:
    """The file a motion was read from (its name when unknown)."""
    return str((motion.source or {}).get("file") or motion.name)


@dataclass(frozen=True)
class FigureFacts:
    """What the units of a clip depend on (:func:`figure_facts`): gathered as a library is
    read, so that its units are found without holding or reading its clips again."""

    gltf: bool
    layout: tuple
    height: float
    file: str
    skeleton: Skeleton


def figure_facts(motion: Motion) -> FigureFacts:
    """The facts of ``motion`` that :func:`resolve_library_units` looks at."""
    return FigureFacts((motion.source or {}).get("format") == "gltf", _layout_key(motion.skeleton),
                       pose_height(motion), source_file(motion), motion.skeleton)


def resolve_library_units(motions: Sequence[Motion], units: str | None = None,
                          cm_per_unit: float | None = None, strict: bool = False,
                          warn: Callable[[str], None] | None = None,
                          facts: Sequence[FigureFacts] | None = None) -> list[UnitsChoice]:
    """The unit of every clip of a library, one per skeleton layout.

    glTF clips are in metres (``units`` and ``cm_per_unit`` apply to BVH clips only). BVH
    clips that share one layout (names, parents, channels) are one figure: their height is
    the median of their :func:`pose_height`, and the unit is the one given, or the one that
    makes that height closest to 170 cm. A height outside :data:`PLAUSIBLE_CM` is reported
    through ``warn(message)`` (one line naming the files and the height) or, with ``strict``,
    raised as :class:`UnitsError`. ``facts``: the clips' :func:`figure_facts`, when gathered
    already (then ``motions`` is not read).
    """
    facts = list(facts) if facts is not None else [figure_facts(m) for m in motions]
    out: list[UnitsChoice | None] = [None] * len(facts)
    groups: dict[tuple, list[int]] = {}
    for k, f in enumerate(facts):
        if f.gltf:
            h = f.height
            out[k] = UnitsChoice(UNITS["m"], "m", False, h, h * UNITS["m"], known="glTF is in metres")
        else:
            groups.setdefault(f.layout, []).append(k)
    for members in groups.values():
        heights = [facts[k].height for k in members]
        height = float(np.median(heights))
        base = resolve_units(facts[members[0]].skeleton, units, cm_per_unit)
        if units is None and cm_per_unit is None:
            scale, label = _nearest_unit(height)
            base = replace(base, cm_per_unit=scale, label=label)
        choice = replace(base, height_units=height, height_cm=height * base.cm_per_unit)
        lo, hi = PLAUSIBLE_CM
        if choice.height_units > 0 and not lo <= choice.height_cm <= hi:
            files = [facts[k].file for k in members]
            where = files[0] if len(files) == 1 else f"{files[0]} and {len(files) - 1} more with its skeleton"
            how = "guessed" if choice.guessed else "given"
            message = (f"{where}: a figure {choice.height_cm:.0f} cm tall in the {how} unit "
                       f"{choice.label} ({choice.cm_per_unit:g} cm per unit), outside "
                       f"{lo:.0f}-{hi:.0f} cm; give --units or --cm-per-unit if that is wrong")
            if strict:
                raise UnitsError(message)
            if warn is not None:
                warn(message)
        for k in members:
            out[k] = choice
    return [c for c in out if c is not None]


def _nearest_unit(height: float) -> tuple[float, str]:
    if not (height > 0 and math.isfinite(height)):
        return UNITS["cm"], "cm"
    label = min(UNITS, key=lambda u: abs(math.log(height * UNITS[u] / HUMAN_HEIGHT_CM)))
    return UNITS[label], label


def _short(x: float) -> str:
    """A height for a sentence: 30.1, 1.7, 1702."""
    return f"{x:.3g}" if x < 100 else f"{x:.0f}"
