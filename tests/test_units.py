"""Unit guessing and explicit units."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from mocodec.io import read_bvh
from mocodec.motion import Skeleton
from mocodec.units import UNITS, guess_cm_per_unit, resolve_units, skeleton_height


def humanoid(height_cm: float, scale: float = 1.0, z_up: bool = False) -> Skeleton:
    """A T-posed humanoid ``height_cm`` tall (feet at 0), offsets multiplied by ``scale``."""
    k = height_cm / 170.0
    rows = [  # name, parent, offset in cm for a 170 cm figure
        ("Hips", -1, (0, 95, 0)),
        ("Spine", 0, (0, 15, 0)), ("Chest", 1, (0, 20, 0)), ("Neck", 2, (0, 15, 0)),
        ("Head", 3, (0, 10, 0)), ("Head_End", 4, (0, 15, 0)),
    ]
    for side in (-1, 1):
        base = len(rows)
        rows += [(f"UpLeg{side}", 0, (10 * side, 0, 0)), (f"Leg{side}", base, (0, -45, 0)),
                 (f"Foot{side}", base + 1, (0, -42, 0)), (f"Toe{side}", base + 2, (0, -8, 10))]
        base = len(rows)
        rows += [(f"Arm{side}", 2, (18 * side, 0, 0)), (f"Elbow{side}", base, (28 * side, 0, 0)),
                 (f"Hand{side}", base + 1, (25 * side, 0, 0))]
    offsets = np.array([r[2] for r in rows], dtype=float) * k * scale
    if z_up:
        offsets = offsets[:, [0, 2, 1]]
    ends = [r[0] in ("Head_End", "Toe-1", "Toe1") for r in rows]
    return Skeleton(names=[r[0] for r in rows], parents=[r[1] for r in rows], offsets=offsets,
                    channels=[() if e else (5, 3, 4) for e in ends], is_end_site=ends)


def test_height_of_rest_pose() -> None:
    sk = Skeleton(names=["R", "A", "B", "Down"], parents=[-1, 0, 1, 0],
                  offsets=[[0, 0, 0], [0, 10, 0], [0, 20, 0], [0, -50, 0]],
                  channels=[(3, 4, 5)] * 3 + [()], is_end_site=[False] * 3 + [True])
    assert skeleton_height(sk) == pytest.approx(80.0)
    assert skeleton_height(humanoid(170.0)) == pytest.approx(170.0)


def test_height_of_a_lying_skeleton_uses_the_largest_extent() -> None:
    assert skeleton_height(humanoid(170.0, z_up=True)) == pytest.approx(170.0)


@pytest.mark.parametrize("height_cm", [150.0, 170.0, 190.0])
@pytest.mark.parametrize("unit", ["cm", "m", "mm", "in", "cmu"])
def test_guess_for_scaled_humanoids(height_cm: float, unit: str) -> None:
    sk = humanoid(height_cm, scale=1.0 / UNITS[unit])
    assert guess_cm_per_unit(sk) == (UNITS[unit], unit)
    choice = resolve_units(sk)
    assert choice.guessed and choice.label == unit
    assert choice.height_cm == pytest.approx(height_cm)
    assert choice.describe().startswith(f"units: guessed {unit} (")


def test_guess_for_cmu_samples(sample_paths: list[Path]) -> None:
    for path in sample_paths:
        sk = read_bvh(path).skeleton
        assert 20.0 < skeleton_height(sk) < 35.0, path.name
        assert guess_cm_per_unit(sk) == (5.6444, "cmu")
        choice = resolve_units(sk)
        assert 120.0 < choice.height_cm < 200.0
        assert "cmu (5.6444 cm per unit)" in choice.describe()


def test_explicit_units() -> None:
    sk = humanoid(170.0)  # looks like cm, but the caller knows better
    choice = resolve_units(sk, units="in")
    assert (choice.cm_per_unit, choice.label, choice.guessed) == (2.54, "in", False)
    assert choice.height_units == pytest.approx(170.0)
    assert choice.height_cm == pytest.approx(170.0 * 2.54)
    assert "given" in choice.describe() and "guessed" not in choice.describe()
    assert resolve_units(sk, units=" CMU ").cm_per_unit == 5.6444
    custom = resolve_units(sk, cm_per_unit=0.5)
    assert (custom.cm_per_unit, custom.label, custom.guessed) == (0.5, "custom", False)
    assert custom.height_cm == pytest.approx(85.0)
    assert custom.describe().startswith("units: 0.5 cm per unit (given)")


def test_skeleton_without_extent_falls_back_to_cm() -> None:
    sk = Skeleton(names=["Only"], parents=[-1], offsets=[[0, 0, 0]], channels=[(0, 1, 2)],
                  is_end_site=[False])
    assert guess_cm_per_unit(sk) == (1.0, "cm")
    assert "no extent" in resolve_units(sk).describe()


@pytest.mark.parametrize("kwargs, phrase", [
    ({"units": "furlong"}, "unknown unit 'furlong'"),
    ({"units": "cm", "cm_per_unit": 1.0}, "not both"),
    ({"cm_per_unit": 0.0}, "positive finite"),
    ({"cm_per_unit": -2.0}, "positive finite"),
    ({"cm_per_unit": math.nan}, "positive finite"),
    ({"cm_per_unit": math.inf}, "positive finite"),
    ({"cm_per_unit": "big"}, "must be a number"),
])
def test_unit_errors(kwargs: dict, phrase: str) -> None:
    with pytest.raises(ValueError) as info:
        resolve_units(humanoid(170.0), **kwargs)
    assert phrase in str(info.value)
