"""Retargeting through the Python binding (the runtime's mcd_retarget_*): the asset's own
skeleton as the rig gives the sampled pose back; a rig with other rest orientations puts every
joint where the world-space sample has it (in metres, in a Z-up rig space); pairs and bad input
raise with the bone or pair named. The C suite (runtime_c/tests/test_retarget.c) checks the
same rules on the goldens; this runs on assets encoded now."""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from mocodec.encode import encode_motions
from mocodec.tolerance import Tolerance
from mocodec.units import resolve_units
from mocodec_runtime import SAMPLE_WORLD, Asset, Result, Retarget, RetargetError, RigBone

sys.path.insert(0, str(Path(__file__).resolve().parent / "golden"))
from make_golden import _bvh, _leg  # noqa: E402


@pytest.fixture(scope="module")
def assets() -> list[Asset]:
    """A BVH skeleton and a glTF-like one (rest rotations, a virtual point)."""
    out = []
    for motion in (_bvh("09_11", 60), _leg()):
        result = encode_motions([motion], [resolve_units(motion.skeleton, "cmu", None)], "spline", Tolerance(1.0))
        out.append(Asset(result.asset))
    return out


def _qmul(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return np.array([aw * bx + ax * bw + ay * bz - az * by, aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw, aw * bw - ax * bx - ay * by - az * bz])


def _conj(q: np.ndarray) -> np.ndarray:
    return np.array([-q[0], -q[1], -q[2], q[3]])


def _rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    return _qmul(_qmul(q, np.append(v, 0.0)), _conj(q))[:3]


def _world(local: np.ndarray, parents: list[int]) -> tuple[np.ndarray, np.ndarray]:
    rot = np.zeros((len(parents), 4))
    pos = np.zeros((len(parents), 3))
    for i, p in enumerate(parents):
        q, t = local[i, :4].astype(np.float64), local[i, 4:7].astype(np.float64)
        if p < 0:
            rot[i], pos[i] = q, t
        else:
            rot[i], pos[i] = _qmul(rot[p], q), pos[p] + _rotate(rot[p], t)
    return rot, pos


def _own_rig(asset: Asset) -> list[RigBone]:
    return [RigBone(n.name, n.parent, n.rest_rotation + n.rest_translation + n.rest_scale) for n in asset.nodes(0)]


def test_own_skeleton_gives_the_pose_back(assets):
    for asset in assets:
        nodes = asset.nodes(0)
        rt = Retarget(asset, 0, _own_rig(asset))
        assert rt.matched == sum(n.kind != 2 for n in nodes)  # virtual points match only by pair
        for t in np.linspace(0, asset.clips[0].duration, 7):
            pose = asset.sample(0, t)
            out = rt.pose(pose)
            a, b = out[:, :4].astype(np.float64), pose[:, :4].astype(np.float64)
            dots = np.abs(np.sum(a * b, axis=1)) / (np.linalg.norm(a, axis=1) * np.linalg.norm(b, axis=1))
            assert np.all(dots > 1 - 1e-12), f"rotations off by up to {np.degrees(2 * np.arccos(dots.min())):.2g} deg"
            np.testing.assert_allclose(out[:, 4:], pose[:, 4:], rtol=2e-6, atol=2e-6)


def test_other_rest_orientations_keep_the_world_pose(assets):
    rng = np.random.default_rng(7)
    space = np.array([np.sin(np.pi / 4), 0.0, 0.0, np.cos(np.pi / 4)])  # Y up -> Z up
    for asset in assets:
        nodes = asset.nodes(0)
        parents = [n.parent for n in nodes]
        _, cm = asset.skeleton_info(0)
        scale = cm / 100.0
        rest = np.array([n.rest_rotation + n.rest_translation + n.rest_scale for n in nodes])
        rest_rot, rest_pos = _world(rest, parents)
        # each rig bone: the node's world rest rotation turned at random, same rest position
        rig_rot = [_qmul(space, _qmul(rest_rot[i], _axis(rng.normal(size=3), rng.uniform(0.3, 2.8))))
                   for i in range(len(nodes))]
        rig_pos = [scale * _rotate(space, rest_pos[i]) for i in range(len(nodes))]
        bones = []
        for i, n in enumerate(nodes):
            if n.parent < 0:
                q, t = rig_rot[i], rig_pos[i]
            else:
                p = n.parent
                q, t = _qmul(_conj(rig_rot[p]), rig_rot[i]), _rotate(_conj(rig_rot[p]), rig_pos[i] - rig_pos[p])
            bones.append(RigBone(f"Armature|{n.name.lower()}", n.parent, tuple(q) + tuple(t) + (1.0, 1.0, 1.0)))
        rt = Retarget(asset, 0, bones, unit_scale=scale, space_rotation=tuple(space))
        for t in np.linspace(0, asset.clips[0].duration, 5):
            out = rt.pose(asset.sample(0, t))
            _, got = _world(out, parents)
            want = asset.sample(0, t, SAMPLE_WORLD)[:, 4:7].astype(np.float64)
            want = np.array([scale * _rotate(space, w) for w in want])
            size = np.abs(want).max()
            assert np.abs(got - want).max() <= 2e-6 * size, f"joints {np.abs(got - want).max() / size:.2g} of the size off"


def _axis(axis: np.ndarray, angle: float) -> np.ndarray:
    a = axis / np.linalg.norm(axis)
    return np.append(a * np.sin(angle / 2), np.cos(angle / 2))


def test_pairs_and_root_motion(assets):
    asset = assets[0]
    nodes = asset.nodes(0)
    bones = _own_rig(asset)
    rt = Retarget(asset, 0, bones, pairs={nodes[1].name: nodes[2].name, nodes[3].name: None})
    assert rt.node_of(1) == 2 and rt.node_of(3) == -1 and rt.node_of(4) == 4
    fixed = Retarget(asset, 0, bones, root_motion=False)
    pose = asset.sample(0, asset.clips[0].duration)
    out = fixed.pose(pose)
    np.testing.assert_allclose(out[0, [4, 6]], np.array(bones[0].rest)[[4, 6]], atol=1e-6)  # stays over its rest spot
    assert out[0, 5] == pytest.approx(pose[0, 5], rel=1e-6)  # the height still moves


def test_bad_input_names_the_bone_or_pair(assets):
    asset = assets[0]
    bones = _own_rig(asset)
    broken = list(bones)
    broken[5] = RigBone(bones[5].name, 9, bones[5].rest)  # parent after the bone
    with pytest.raises(RetargetError) as err:
        Retarget(asset, 0, broken)
    assert (err.value.code, err.value.where, err.value.index) == (Result.INVALID_ARGUMENT, "bone", 5)
    with pytest.raises(RetargetError) as err:
        Retarget(asset, 0, bones, pairs={bones[2].name: "no such node"})
    assert (err.value.code, err.value.where, err.value.index) == (Result.NOT_FOUND, "pair", 0)
    with pytest.raises(RetargetError) as err:
        Retarget(asset, 0, bones, unit_scale=0.0)
    assert err.value.where == "config"
    rt = Retarget(asset, 0, bones)
    with pytest.raises(Exception, match="invalid argument"):
        rt.pose(np.zeros((len(bones) - 1, 10), np.float32))  # not this skeleton's node count
