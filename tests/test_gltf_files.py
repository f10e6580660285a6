"""Every edge case the development glTF set's MANIFEST lists, each on the real file
(``../shared/data/gltf``; skipped loudly without it), plus the bundled samples."""
from __future__ import annotations

import json
import struct
from functools import lru_cache
from pathlib import Path

import numpy as np
import pytest

from mocodec import SAMPLES
from mocodec.io import read_gltf
from mocodec.kinematics import world_positions
from mocodec.rotations import quat_to_matrix


@lru_cache(maxsize=None)
def _read(path: str):
    return read_gltf(path)


def _json(path: Path) -> dict:
    """The file's glTF JSON (GLB JSON chunk or the text)."""
    data = path.read_bytes()
    if data[:4] == b"glTF":
        length = struct.unpack_from("<I", data, 12)[0]
        return json.loads(data[20:20 + length])
    return json.loads(data)


def _clips(d: Path, name: str):
    return _read(str(d / name))


def _matrix_world(m) -> np.ndarray:
    """World positions by glTF's own matrix products (to check the runtime composition)."""
    sk = m.skeleton
    local = np.zeros((m.frame_count, sk.node_count, 4, 4))
    local[..., :3, :3] = quat_to_matrix(m.rotations) * m.scales[..., None, :]
    local[..., :3, 3] = m.translations
    local[..., 3, 3] = 1.0
    world = np.empty_like(local)
    for i, p in enumerate(sk.parents):
        world[:, i] = local[:, i] if p < 0 else world[:, p] @ local[:, i]
    return world[..., :3, 3]


ALL = ["CesiumMan.glb", "Fox.glb", "GDQuest_mannequiny.glb", "KayKit_Med_General.glb",
       "Luanti_spider_animated.gltf", "Quaternius_Cyberpunk_Character.glb", "Quaternius_Horse.glb",
       "Quaternius_Wizard.glb", "RiggedFigure.glb", "RobotExpressive.glb", "SimpleSkin.gltf",
       "SimpleSkin_step.gltf"]
CLIPS = {"CesiumMan.glb": 1, "Fox.glb": 3, "GDQuest_mannequiny.glb": 10, "KayKit_Med_General.glb": 15,
         "Luanti_spider_animated.gltf": 1, "Quaternius_Cyberpunk_Character.glb": 22,
         "Quaternius_Horse.glb": 13, "Quaternius_Wizard.glb": 11, "RiggedFigure.glb": 1,
         "RobotExpressive.glb": 14, "SimpleSkin.gltf": 1, "SimpleSkin_step.gltf": 1}
JOINTS = {"CesiumMan.glb": 19, "Fox.glb": 24, "GDQuest_mannequiny.glb": 45, "KayKit_Med_General.glb": 23,
          "Luanti_spider_animated.gltf": 57, "Quaternius_Cyberpunk_Character.glb": 25,
          "Quaternius_Horse.glb": 50, "Quaternius_Wizard.glb": 32, "RiggedFigure.glb": 19,
          "RobotExpressive.glb": 43, "SimpleSkin.gltf": 2, "SimpleSkin_step.gltf": 2}


def test_the_set_has_the_manifest_files(shared_gltf_dir):
    assert sorted(p.name for p in shared_gltf_dir.glob("*.gl*")) == ALL
    assert (shared_gltf_dir / "MANIFEST.md").exists()


@pytest.mark.parametrize("name", ALL)
def test_every_file_reads_every_animation(shared_gltf_dir, name):
    clips = _clips(shared_gltf_dir, name)
    assert len(clips) == CLIPS[name]
    assert len({m.name for m in clips}) == len(clips)
    sk = clips[0].skeleton
    assert len(clips[0].source["joints"]) == JOINTS[name]
    for m in clips:
        m.validate()
        assert m.skeleton is sk
    # Every leaf has its virtual end point, and only leaves do.
    real = np.flatnonzero(~sk.is_virtual)
    leaves = [i for i in real if not np.any(sk.parents[real] == i)]
    assert sorted(sk.parents[sk.is_virtual].tolist()) == sorted(leaves)


def test_samplers_without_interpolation(shared_gltf_dir):
    """Fox.glb: all 63 samplers omit `interpolation` (default LINEAR)."""
    doc = _json(shared_gltf_dir / "Fox.glb")
    samplers = [s for a in doc["animations"] for s in a["samplers"]]
    assert len(samplers) == 63 and not any("interpolation" in s for s in samplers)
    survey, walk, run = _clips(shared_gltf_dir, "Fox.glb")
    for m in (survey, walk, run):
        assert m.source["interpolation"] == ["LINEAR"]
    for m in (survey, walk):  # 24 Hz keys: every key is a frame
        assert (m.frame_rate, m.source["keys_between_frames"]) == (24.0, 0)
    # Run's keys jump from 16/24 s to 20.8/24 s: no one grid, so the default rate.
    assert run.frame_rate == 60.0 and run.source["rate_from"] == "default"


@pytest.mark.parametrize("name", ["SimpleSkin.gltf", "SimpleSkin_step.gltf", "Luanti_spider_animated.gltf"])
def test_buffers_embedded_as_data_uris(shared_gltf_dir, name):
    doc = _json(shared_gltf_dir / name)
    assert all(b["uri"].startswith("data:") for b in doc["buffers"])
    assert _clips(shared_gltf_dir, name)[0].frame_count > 1


def test_animation_only_file_and_channels_outside_the_skin(shared_gltf_dir):
    """KayKit: a skin and no mesh; 3 channels per clip on the `Rig_Medium` armature node."""
    doc = _json(shared_gltf_dir / "KayKit_Med_General.glb")
    assert not doc.get("meshes") and doc["skins"]
    clips = _clips(shared_gltf_dir, "KayKit_Med_General.glb")
    sk = clips[0].skeleton
    rig = sk.index("Rig_Medium")
    assert rig not in clips[0].source["joints"]
    targets = {c["target"]["node"] for c in doc["animations"][0]["channels"]}
    rig_gltf = next(i for i, n in enumerate(doc["nodes"]) if n.get("name") == "Rig_Medium")
    assert rig_gltf in targets
    assert sk.parents[rig] < 0 or not sk.is_virtual[rig]


def test_four_skins_share_one_joint_list(shared_gltf_dir):
    doc = _json(shared_gltf_dir / "Quaternius_Cyberpunk_Character.glb")
    assert len(doc["skins"]) == 4 and len({tuple(s["joints"]) for s in doc["skins"]}) == 1
    m = _clips(shared_gltf_dir, "Quaternius_Cyberpunk_Character.glb")[0]
    assert len(m.source["joints"]) == 25
    assert len(set(m.skeleton.names)) == m.skeleton.node_count


@pytest.mark.parametrize("name", ["Quaternius_Horse.glb", "Fox.glb", "Luanti_spider_animated.gltf"])
def test_clips_that_animate_only_some_joints_hold_the_others_at_rest(shared_gltf_dir, name):
    doc = _json(shared_gltf_dir / name)
    for a, m in zip(doc["animations"], _clips(shared_gltf_dir, name)):
        sk = m.skeleton
        rotated = {doc["nodes"][c["target"]["node"]].get("name") for c in a["channels"]
                   if c["target"]["path"] == "rotation"}
        still = [i for i in range(sk.node_count) if sk.names[i] not in rotated]
        assert still
        for i in still:
            assert np.all(m.rotations[:, i] == sk.rest_rotations[i]), (m.name, sk.names[i])


@pytest.mark.parametrize("name, start", [("CesiumMan.glb", 1 / 24), ("KayKit_Med_General.glb", 1 / 30)])
def test_clips_that_start_after_zero(shared_gltf_dir, name, start):
    for m in _clips(shared_gltf_dir, name):
        assert m.source["start_s"] == pytest.approx(start, abs=1e-5)
        assert m.frame_rate == round(1 / start)


def test_one_frame_pose_clips(shared_gltf_dir):
    """KayKit's *_Pose and T-Pose clips: two STEP keys 1/30 s apart."""
    poses = [m for m in _clips(shared_gltf_dir, "KayKit_Med_General.glb") if m.name.endswith(("_Pose", "T-Pose"))]
    assert len(poses) == 3
    for m in poses:
        assert m.frame_count == 2 and m.source["interpolation"] == ["STEP"]


def test_two_keys_per_channel_are_subdivided(shared_gltf_dir):
    """RiggedFigure: 2 keys 1.25 s apart; frames every 1/24 s measure the slerp between them."""
    m, = _clips(shared_gltf_dir, "RiggedFigure.glb")
    assert m.frame_rate == pytest.approx(0.8 * 30) and m.frame_count == 31
    assert m.source["rate_from"] == "key spacing"


@pytest.mark.parametrize("name", ["Quaternius_Horse.glb", "Quaternius_Cyberpunk_Character.glb"])
def test_armature_with_static_scale(shared_gltf_dir, name):
    """FBX2glTF: an armature node scales everything below it (100x or 1/100)."""
    m = _clips(shared_gltf_dir, name)[0]
    sk = m.skeleton
    scaled = [i for i in range(sk.node_count) if not np.allclose(sk.rest_scales[i], 1.0)]
    assert scaled and all(sk.names[i] not in [sk.names[j] for j in m.source["joints"]] for i in scaled[:1])
    assert any(np.isclose(sk.rest_scales[i][0], 100.0) or np.isclose(sk.rest_scales[i][0], 0.01) for i in scaled)
    # Uniform scales: the runtime's composition is glTF's own (1e-5 m of float noise).
    assert np.abs(_matrix_world(m) - world_positions(m)).max() < 1e-4


@pytest.mark.parametrize("name", ["CesiumMan.glb", "RiggedFigure.glb"])
def test_matrix_on_non_joint_nodes(shared_gltf_dir, name):
    doc = _json(shared_gltf_dir / name)
    with_matrix = [n["name"] for n in doc["nodes"] if "matrix" in n]
    assert with_matrix
    m = _clips(shared_gltf_dir, name)[0]
    for nm in with_matrix:
        if nm in m.skeleton.names:
            i = m.skeleton.index(nm)
            node = next(n for n in doc["nodes"] if n.get("name") == nm)
            mat = np.array(node["matrix"]).reshape(4, 4).T
            np.testing.assert_allclose(m.skeleton.offsets[i], mat[:3, 3], atol=1e-7)
    assert np.abs(_matrix_world(m) - world_positions(m)).max() < 1e-5


def test_many_clips_per_file(shared_gltf_dir):
    clips = _clips(shared_gltf_dir, "Quaternius_Cyberpunk_Character.glb")
    assert len(clips) == 22 and clips[0].name == "CharacterArmature|Death"


def test_step_interpolation(shared_gltf_dir):
    """SimpleSkin_step: the only sampler is STEP; KayKit mixes STEP and LINEAR in a clip."""
    m, = _clips(shared_gltf_dir, "SimpleSkin_step.gltf")
    doc = _json(shared_gltf_dir / "SimpleSkin_step.gltf")
    assert [s["interpolation"] for s in doc["animations"][0]["samplers"]] == ["STEP"]
    joint = np.flatnonzero(m.animated()[:, 0])[0]
    q = m.rotations[:, joint]
    # Held between keys (every 0.5 s, frames every 1/24 s): 12 distinct poses.
    changes = np.flatnonzero(np.abs(np.sum(q[1:] * q[:-1], axis=1)) < 1 - 1e-12)
    assert np.all((changes + 1) % 12 == 0)
    kay = _clips(shared_gltf_dir, "KayKit_Med_General.glb")
    assert any(m.source["interpolation"] == ["LINEAR", "STEP"] for m in kay)


@pytest.mark.parametrize("name, clips", [("KayKit_Med_General.glb", 2), ("GDQuest_mannequiny.glb", 10),
                                         ("Luanti_spider_animated.gltf", 1)])
def test_animated_scale(shared_gltf_dir, name, clips):
    scaled = [m for m in _clips(shared_gltf_dir, name)
              if np.abs(m.scales - m.skeleton.rest_scales[None]).max() > 1e-4]
    assert len(scaled) == clips


def test_non_uniform_scale_is_where_compositions_differ(shared_gltf_dir):
    """GDQuest animates non-uniform scale under rotated children: the runtime's composition
    (scale multiplied per axis) and glTF's matrix product differ there, and only there."""
    worst = max(np.abs(_matrix_world(m) - world_positions(m)).max() for m in _clips(shared_gltf_dir, "GDQuest_mannequiny.glb"))
    assert worst > 1e-3  # metres: measured 3.15 cm
    spider = _clips(shared_gltf_dir, "Luanti_spider_animated.gltf")[0]
    assert np.abs(_matrix_world(spider) - world_positions(spider)).max() < 1e-4


def test_bundled_samples_read():
    names = sorted(p.name for p in (SAMPLES / "gltf").glob("*.gl*"))
    assert names == ["Luanti_spider_animated.gltf", "RiggedFigure.glb", "SimpleSkin.gltf"]
    for n in names:
        for m in read_gltf(SAMPLES / "gltf" / n):
            m.validate()
