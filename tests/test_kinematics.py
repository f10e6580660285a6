"""Forward kinematics against an independent, slow implementation (4x4 matrices per frame
and node, rotations from scipy), and lever arms."""
from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from mocodec.io import read_bvh
from mocodec.kinematics import forward_kinematics, lever_arms, world_positions


def _slow_fk(motion, frames):
    """World positions the textbook way: per frame, per node, compose homogeneous matrices
    from the BVH channels (Euler via scipy, position channels replacing the offset)."""
    sk = motion.skeleton
    channels = motion.source_channels
    out = np.zeros((len(frames), sk.node_count, 3))
    for fi, f in enumerate(frames):
        mats = [None] * sk.node_count
        col = 0
        for i in range(sk.node_count):
            ch = sk.channels[i]
            vals = channels[f, col:col + len(ch)]
            col += len(ch)
            t = np.array(sk.offsets[i], dtype=float)
            angles, axes = [], ""
            for code, v in zip(ch, vals):
                if code < 3:
                    t[code] = v
                else:
                    axes += "XYZ"[code - 3]
                    angles.append(v)
            local = np.eye(4)
            if axes:
                local[:3, :3] = Rotation.from_euler(axes, angles, degrees=True).as_matrix()
            local[:3, 3] = t
            p = sk.parents[i]
            mats[i] = local if p < 0 else mats[p] @ local
            out[fi, i] = mats[i][:3, 3]
    return out


def test_fk_matches_slow_matrix_implementation(sample_paths):
    for path in sample_paths:
        m = read_bvh(path)
        frames = [0, 1, m.frame_count // 2, m.frame_count - 1]
        fast = world_positions(m)[frames]
        assert np.allclose(fast, _slow_fk(m, frames), atol=1e-9)


def test_world_rotations_place_children(sample_paths):
    m = read_bvh(sample_paths[0])
    rot, pos = forward_kinematics(m.skeleton, m.rotations, m.translations)
    sk = m.skeleton
    for i in range(sk.node_count):
        p = sk.parents[i]
        if p < 0:
            continue
        # Child position = parent position + parent world rotation applied to the offset.
        expect = pos[:, p] + Rotation.from_quat(rot[:, p]).apply(m.translations[:, i])
        assert np.allclose(pos[:, i], expect, atol=1e-9)


def test_lever_arms(sample_paths):
    m = read_bvh(sample_paths[0])
    pos = world_positions(m)
    lev = lever_arms(m.skeleton, pos)
    sk = m.skeleton
    leaves = [i for i in range(sk.node_count) if not sk.children(i)]
    assert np.all(lev[leaves] == 0)
    root = int(np.flatnonzero(sk.parents < 0)[0])
    # The root reaches every point; an arm joint reaches less than the root.
    assert lev[root] == max(lev)
    assert 0 < lev[sk.index("LeftForeArm")] < lev[sk.index("LeftArm")] < lev[root]
