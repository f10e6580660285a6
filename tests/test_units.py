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


# ----------------------------------------------------------------------------- animated poses
from mocodec.motion import Motion  # noqa: E402
from mocodec.units import PLAUSIBLE_CM, UnitsError, pose_height, resolve_library_units  # noqa: E402


def _motion(sk: Skeleton, frames: int = 5, name: str = "clip", root_turn=None) -> Motion:
    """Rest pose on every frame, the root turned by ``root_turn`` (x y z w) if given."""
    rot = np.zeros((frames, sk.node_count, 4))
    rot[..., 3] = 1.0
    if root_turn is not None:
        rot[:, 0] = root_turn
    m = Motion(sk, rot, np.broadcast_to(sk.offsets, (frames, sk.node_count, 3)).copy(), 1 / 30, name)
    m.source = {"format": "bvh", "file": f"{name}.bvh"}
    return m


@pytest.mark.parametrize("axis", ["x", "z"])
@pytest.mark.parametrize("unit", ["cm", "m", "mm", "in", "cmu"])
def test_guess_for_skeletons_lying_along_x_or_z(axis: str, unit: str) -> None:
    """A rest pose lying along X or Z (Bandai-like) whose animation stands it up: the guess
    reads the poses, so the unit is right whichever way the rest pose lies."""
    sk = humanoid(175.0, scale=1.0 / UNITS[unit])
    order = [1, 0, 2] if axis == "x" else [0, 2, 1]
    sk = Skeleton(sk.names, sk.parents, sk.offsets[:, order], sk.channels, sk.is_end_site)
    half = np.sqrt(0.5)
    turn = [0, 0, half, half] if axis == "x" else [half, 0, 0, half]  # back to standing along Y
    m = _motion(sk, root_turn=turn)
    choice, = resolve_library_units([m])
    assert choice.label == unit and choice.guessed
    assert 150 < choice.height_cm < 200


def test_guess_for_cmu_samples_from_their_poses(sample_paths: list[Path]) -> None:
    motions = [read_bvh(p) for p in sample_paths]
    choices = resolve_library_units(motions)
    assert {c.label for c in choices} == {"cmu"}
    for m in motions:
        assert 20.0 < pose_height(m) < 35.0


def test_a_library_with_one_skeleton_gets_one_unit() -> None:
    """Alone, a crouching clip of a 180 cm figure in cm (a pose 90 units across) would be read as
    inches; with its library it is cm, like the standing clips."""
    sk = humanoid(180.0)
    standing = [_motion(sk, name=f"stand{k}") for k in range(3)]
    crouch = _motion(Skeleton(sk.names, sk.parents, sk.offsets * 0.5, sk.channels, sk.is_end_site), name="crouch")
    alone, = resolve_library_units([crouch])
    assert alone.label == "in"                      # the per-clip guess that went wrong
    # The same layout: names, parents and channels (the figure's offsets are not compared).
    together = resolve_library_units(standing + [crouch])
    assert {c.label for c in together} == {"cm"} and len({c.height_units for c in together}) == 1


def test_implausible_height_is_a_warning_naming_the_file_or_an_error_with_strict() -> None:
    tiny = _motion(humanoid(170.0, scale=0.2), name="doll")   # 34 cm in cm... guessed as in: 86 cm
    given = []
    resolve_library_units([tiny], units="cm", warn=given.append)
    assert len(given) == 1 and "doll.bvh" in given[0] and "34 cm" in given[0] and "given" in given[0]
    with pytest.raises(UnitsError, match="doll.bvh: a figure 34 cm tall"):
        resolve_library_units([tiny], units="cm", strict=True)
    fine = []
    resolve_library_units([_motion(humanoid(170.0))], units="cm", warn=fine.append)
    assert fine == [] and PLAUSIBLE_CM == (50.0, 300.0)


def test_cli_warns_and_strict_fails(tmp_path: Path, sample_paths: list[Path]) -> None:
    import subprocess
    import sys
    cmd = [sys.executable, "-m", "mocodec", "eval", str(sample_paths[0]), "--units", "mm", "--codec", "spline",
           "--json"]
    run = subprocess.run(cmd, capture_output=True, text=True)
    assert run.returncode == 0
    assert "mocodec: warning:" in run.stderr and sample_paths[0].name in run.stderr and "cm tall" in run.stderr
    run = subprocess.run(cmd + ["--strict"], capture_output=True, text=True)
    assert run.returncode == 1 and run.stderr.count("\n") == 1 and "mocodec: error:" in run.stderr


def test_gltf_is_metres_never_guessed(tmp_path: Path) -> None:
    from mocodec import SAMPLES
    from mocodec.io import read_gltf
    motions = read_gltf(SAMPLES / "gltf" / "RiggedFigure.glb")
    choice, = resolve_library_units(motions, units="in")   # --units is for BVH files
    assert (choice.cm_per_unit, choice.label, choice.guessed) == (100.0, "m", False)
    assert "glTF is in metres" in choice.describe()
