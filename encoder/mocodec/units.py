"""Length units of a skeleton: BVH files do not say theirs, so they are given or guessed.

Tolerances are in centimetres; a file unit is converted with ``cm_per_unit``. The guess picks
the unit that makes the skeleton's rest pose closest to a human height of 170 cm.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .kinematics import forward_kinematics
from .motion import Skeleton

UNITS: dict[str, float] = {"cm": 1.0, "m": 100.0, "mm": 0.1, "in": 2.54, "cmu": 5.6444}
"""Centimetres per file unit (``cmu``: the CMU ASF unit, 0.056444 m)."""

HUMAN_HEIGHT_CM = 170.0


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
        Rest-pose height of the skeleton in file units and in centimetres.
    """

    cm_per_unit: float
    label: str
    guessed: bool
    height_units: float
    height_cm: float

    def describe(self) -> str:
        """One line for logs and reports."""
        scale = f"{self.cm_per_unit:g} cm per unit"
        if self.height_units <= 0:
            return f"units: assumed {self.label} ({scale}); the skeleton has no extent to guess from"
        size = f"a skeleton {_short(self.height_units)} units tall ({self.height_cm:.0f} cm)"
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
    height = skeleton_height(skeleton)
    if not (height > 0 and math.isfinite(height)):
        return UNITS["cm"], "cm"
    label = min(UNITS, key=lambda u: abs(math.log(height * UNITS[u] / HUMAN_HEIGHT_CM)))
    return UNITS[label], label


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


def _short(x: float) -> str:
    """A height for a sentence: 30.1, 1.7, 1702."""
    return f"{x:.3g}" if x < 100 else f"{x:.0f}"
