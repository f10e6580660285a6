"""glTF 2.0 reading on files built here: samplers, interpolation, skeleton layout, resampling,
and malformed input (one clear error naming the file and the item, never a traceback)."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from gltf_build import Doc, arm, quat_z
from mocodec import rotations as R
from mocodec.io import GLTFError, read_gltf
from mocodec.io.gltf import DEFAULT_RATE, VIRTUAL_MIN_M
from mocodec.kinematics import world_positions


def _same_rotation(a, b, atol=1e-6):
    return np.allclose(np.abs(np.sum(np.asarray(a) * np.asarray(b), axis=-1)), 1.0, atol=atol)


def test_linear_rotation_is_slerp_and_translation_is_lerp(tmp_path):
    doc = arm()
    times = np.array([0.0, 1.0])
    doc.animation("bend", [(2, "rotation", times, quat_z([0, 90]), "LINEAR"),
                           (1, "translation", times, [[0, 1, 0], [2, 1, 0]], "LINEAR")])
    m, = read_gltf(doc.write(tmp_path / "a.gltf"), rate=4)
    assert m.frame_count == 5 and m.frame_rate == 4
    assert _same_rotation(m.rotations[2, 2], quat_z(45)[0])         # slerp at t = 0.5
    np.testing.assert_allclose(m.translations[2, 1], [1, 1, 0], atol=1e-6)
    assert m.source["interpolation"] == ["LINEAR"]


def test_sampler_without_interpolation_is_linear(tmp_path):
    doc = arm()
    doc.animation("a", [(2, "rotation", np.array([0.0, 1.0]), quat_z([0, 60]), None)])
    m, = read_gltf(doc.write(tmp_path / "a.gltf"), rate=2)
    assert _same_rotation(m.rotations[1, 2], quat_z(30)[0])


def test_step_holds_the_previous_key(tmp_path):
    doc = arm()
    doc.animation("a", [(2, "rotation", np.array([0.0, 1.0, 2.0]), quat_z([0, 40, 80]), "STEP")])
    m, = read_gltf(doc.write(tmp_path / "a.gltf"), rate=4)
    expect = [0, 0, 0, 0, 40, 40, 40, 40, 80]
    for f, deg in enumerate(expect):
        assert _same_rotation(m.rotations[f, 2], quat_z(deg)[0]), f


def test_cubicspline_follows_the_hermite_curve(tmp_path):
    """No real skinned file uses CUBICSPLINE: in-tangent, value, out-tangent per key."""
    doc = arm()
    times = np.array([0.0, 2.0])
    p0, p1 = np.array([0.0, 1.0, 0.0]), np.array([4.0, 1.0, 0.0])
    out0, in1 = np.array([1.0, 0.0, 0.0]), np.array([-3.0, 2.0, 0.0])
    trans = np.array([[0, 0, 0], p0, out0, in1, p1, [0, 0, 0]], dtype=float)
    q0, q1 = quat_z([0, 90])
    rot = np.array([[0, 0, 0, 0], q0, [0, 0, 0, 0], [0, 0, 0, 0], q1, [0, 0, 0, 0]], dtype=float)
    doc.animation("c", [(1, "translation", times, trans, "CUBICSPLINE"),
                        (2, "rotation", times, rot, "CUBICSPLINE")])
    m, = read_gltf(doc.write(tmp_path / "c.gltf"), rate=4)
    dt = 2.0
    for f in range(m.frame_count):
        s = f / 4 / dt
        h = [2 * s**3 - 3 * s**2 + 1, s**3 - 2 * s**2 + s, -2 * s**3 + 3 * s**2, s**3 - s**2]
        expect = h[0] * p0 + dt * h[1] * out0 + h[2] * p1 + dt * h[3] * in1
        np.testing.assert_allclose(m.translations[f, 1], expect, atol=1e-5)
        q = h[0] * q0 + h[2] * q1  # zero tangents
        assert _same_rotation(m.rotations[f, 2], q / np.linalg.norm(q)), f
    assert m.source["interpolation"] == ["CUBICSPLINE"]


def test_scale_channel_and_unanimated_joints_hold_their_rest(tmp_path):
    doc = arm()
    doc.json["nodes"][2]["rotation"] = list(quat_z(30)[0])
    doc.json["nodes"][3]["scale"] = [2.0, 2.0, 2.0]
    doc.animation("grow", [(1, "scale", np.array([0.0, 1.0]), [[1, 1, 1], [0.5, 2, 1]], "LINEAR")])
    m, = read_gltf(doc.write(tmp_path / "g.gltf"), rate=2)
    np.testing.assert_allclose(m.scales[:, 1], [[1, 1, 1], [0.75, 1.5, 1], [0.5, 2, 1]])
    assert np.all(m.rotations[:, 2] == m.skeleton.rest_rotations[2])   # not animated: its rest
    assert np.all(m.scales[:, 3] == 2.0)
    animated = m.animated()
    assert animated[1].tolist() == [False, False, True] and not animated[2].any()
    # The world transform composes scale the runtime's way: p.t + p.r (p.s * c.t).
    pos = world_positions(m)
    np.testing.assert_allclose(pos[2, 2], [0, 1 + 2.0, 0], atol=1e-9)


def test_clip_starting_late_begins_at_its_first_key(tmp_path):
    doc = arm()
    doc.animation("late", [(2, "rotation", np.array([0.5, 0.75, 1.0]), quat_z([10, 20, 30]), "LINEAR")])
    m, = read_gltf(doc.write(tmp_path / "l.gltf"))
    assert m.source["start_s"] == pytest.approx(0.5)
    assert m.frame_rate == 4 * 6 and m.frame_count == 13  # 4 Hz keys subdivided to 24 Hz
    assert _same_rotation(m.rotations[0, 2], quat_z(10)[0]) and _same_rotation(m.rotations[-1, 2], quat_z(30)[0])


def test_irregular_keys_resample_at_the_default_rate(tmp_path):
    doc = arm()
    doc.animation("irr", [(2, "rotation", np.array([0.0, 0.11, 0.353, 1.0]), quat_z([0, 5, 10, 20]), "LINEAR")])
    m, = read_gltf(doc.write(tmp_path / "i.gltf"))
    assert m.frame_rate == DEFAULT_RATE and m.source["rate_from"] == "default"
    assert m.source["keys_between_frames"] >= 1


def test_external_buffer_and_skeleton_layout(tmp_path):
    doc = Doc()
    top = doc.node("Armature", scale=[0.01, 0.01, 0.01])       # a static armature scale
    hips = doc.node("hips", top, translation=[0, 100, 0])
    doc.node("mesh", top)                                     # neither joint nor animated
    left = doc.node("left", hips, translation=[10, 0, 0])
    right = doc.node("right", hips, translation=[-10, 0, 0])
    doc.skin([hips, left, right])
    doc.skin([hips, left, right])                            # two skins share the joints
    doc.animation("walk", [(hips, "rotation", np.array([0.0, 1.0]), quat_z([0, 10]), "LINEAR")])
    path = doc.write(tmp_path / "ext.gltf", external=True)
    m, = read_gltf(path)
    sk = m.skeleton
    assert sk.names[:4] == ["Armature", "hips", "left", "right"]
    assert "mesh" not in sk.names
    assert sk.parents[:4].tolist() == [-1, 0, 1, 1]
    assert [sk.names[i] for i in m.source["joints"]] == ["hips", "left", "right"]
    # Every leaf has a virtual end point along its parent bone, its length at least 3 cm.
    virtual = [sk.names[i] for i in np.flatnonzero(sk.is_virtual)]
    assert virtual == ["left_end", "right_end"]
    pos = world_positions(m)[0]
    np.testing.assert_allclose(pos[sk.index("hips")], [0, 1, 0], atol=1e-12)
    np.testing.assert_allclose(pos[sk.index("left_end")], [0.2, 1, 0], atol=1e-12)
    assert np.linalg.norm(pos[sk.index("left_end")] - pos[sk.index("left")]) >= VIRTUAL_MIN_M
    assert np.all(sk.is_end_site == sk.is_virtual)


def test_matrix_is_decomposed(tmp_path):
    doc = arm()
    rot = R.quat_to_matrix(quat_z([90]))[0]
    m4 = np.eye(4)
    m4[:3, :3] = rot * 2.0
    m4[:3, 3] = [5, 0, 0]
    doc.json["nodes"][0]["matrix"] = list(m4.T.ravel())       # column-major
    doc.animation("a", [(2, "rotation", np.array([0.0, 1.0]), quat_z([0, 10]), "LINEAR")])
    m, = read_gltf(doc.write(tmp_path / "m.gltf"))
    sk = m.skeleton
    np.testing.assert_allclose(sk.offsets[0], [5, 0, 0])
    np.testing.assert_allclose(sk.rest_scales[0], [2, 2, 2])
    assert _same_rotation(sk.rest_rotations[0], quat_z(90)[0])
    np.testing.assert_allclose(world_positions(m)[0, 1], [5 - 2, 0, 0], atol=1e-9)


# ----------------------------------------------------------------------------- malformed
def _animated_arm():
    doc = arm()
    doc.animation("a", [(2, "rotation", np.array([0.0, 1.0]), quat_z([0, 10]), "LINEAR")])
    return doc


MALFORMED = {
    "bad accessor bounds": (lambda d: d.json["accessors"][1].__setitem__("count", 1000), "accessor 1", "bounds"),
    "accessor out of range": (lambda d: d.json["animations"][0]["samplers"][0].__setitem__("output", 99),
                              "accessor 99", "does not exist"),
    "cycle": (lambda d: d.json["nodes"][3].__setitem__("children", [1]), "node", "two parents"),
    "self cycle": (lambda d: d.json["nodes"][2].__setitem__("children", [2]), "node 2", "cycle"),
    "unknown interpolation": (lambda d: d.json["animations"][0]["samplers"][0].__setitem__("interpolation", "BEZIER"),
                              "channel 0", "unknown interpolation"),
    "version": (lambda d: d.json["asset"].__setitem__("version", "1.0"), "asset.version", "2.x"),
    "no animation": (lambda d: d.json.__setitem__("animations", []), "", "no animation"),
    "bad child": (lambda d: d.json["nodes"][3].__setitem__("children", [42]), "node 3", "child 42"),
    "compressed buffers": (lambda d: d.json.__setitem__("extensionsRequired", ["EXT_meshopt_compression"]),
                           "extensionsRequired", "does not decode"),
}


@pytest.mark.parametrize("case", sorted(MALFORMED))
def test_malformed_structure_is_one_clear_error(tmp_path, case):
    damage, item, phrase = MALFORMED[case]
    doc = _animated_arm()
    damage(doc)
    path = doc.write(tmp_path / "bad.gltf")
    with pytest.raises(GLTFError) as info:
        read_gltf(path)
    text = str(info.value)
    assert text.startswith(str(path)) and item in text and phrase in text, text


def test_cycle_without_a_root_is_reported(tmp_path):
    doc = _animated_arm()
    doc.json["nodes"][0]["children"] = [1]
    doc.json["nodes"][3]["children"] = [0]  # 0 -> 1 -> 2 -> 3 -> 0
    with pytest.raises(GLTFError, match="cycle in the node graph"):
        read_gltf(doc.write(tmp_path / "c.gltf"))


@pytest.mark.parametrize("values, phrase", [
    (np.array([[0, 0, 0, 2.0], [0, 0, 0, 1.0]]), "not a unit quaternion (length 2"),
    (np.array([[0, 0, 0, 1.0], [np.nan, 0, 0, 1.0]]), "key 1 value [nan, 0.0, 0.0, 1.0] is not finite"),
])
def test_bad_key_values(tmp_path, values, phrase):
    doc = arm()
    doc.animation("bad", [(2, "rotation", np.array([0.0, 1.0]), values, "LINEAR")])
    path = doc.write(tmp_path / "k.gltf")
    with pytest.raises(GLTFError) as info:
        read_gltf(path)
    assert str(path) in str(info.value) and "animation 0 ('bad') channel 0" in str(info.value)
    assert phrase in str(info.value)


@pytest.mark.parametrize("times, phrase", [
    (np.array([0.0, np.nan]), "NaN key"), (np.array([1.0, 0.5]), "do not increase")])
def test_bad_key_times(tmp_path, times, phrase):
    doc = arm()
    doc.animation("bad", [(2, "rotation", times, quat_z([0, 1]), "LINEAR")])
    with pytest.raises(GLTFError, match=phrase):
        read_gltf(doc.write(tmp_path / "t.gltf"))


def test_missing_external_buffer(tmp_path):
    path = _animated_arm().write(tmp_path / "ext.gltf", external=True)
    path.with_suffix(".bin").unlink()
    with pytest.raises(GLTFError) as info:
        read_gltf(path)
    assert "buffer 0 (ext.bin)" in str(info.value) and "missing buffer" in str(info.value)


def test_short_buffer_and_output_count(tmp_path):
    doc = _animated_arm()
    doc.json["animations"][0]["samplers"][0]["interpolation"] = "CUBICSPLINE"
    with pytest.raises(GLTFError, match="CUBICSPLINE needs 6"):
        read_gltf(doc.write(tmp_path / "n.gltf"))
    doc = _animated_arm()
    path = doc.write(tmp_path / "s.gltf")
    text = json.loads(path.read_text())
    text["buffers"][0]["byteLength"] += 100
    path.write_text(json.dumps(text))
    with pytest.raises(GLTFError, match="buffer 0: holds .* byteLength says"):
        read_gltf(path)


def test_not_gltf_and_binary_without_chunk(tmp_path):
    junk = tmp_path / "junk.glb"
    junk.write_bytes(b"glTF" + bytes(40))
    with pytest.raises(GLTFError, match="junk.glb"):
        read_gltf(junk)
    text = tmp_path / "text.gltf"
    text.write_text("{ not json")
    with pytest.raises(GLTFError, match="not a readable glTF 2.0 file"):
        read_gltf(text)


def test_cli_reports_a_bad_gltf_in_one_line(tmp_path):
    doc = arm()
    doc.animation("bad", [(2, "rotation", np.array([0.0, 1.0]), np.array([[0, 0, 0, 3.0], [0, 0, 0, 1.0]]), "LINEAR")])
    path = doc.write(tmp_path / "q.gltf")
    run = subprocess.run([sys.executable, "-m", "mocodec", "encode", str(path), "-o", str(tmp_path / "x.mcd")],
                         capture_output=True, text=True)
    assert run.returncode == 1
    lines = run.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("mocodec: error: ") and str(path) in lines[0], run.stderr
    assert "Traceback" not in run.stderr
