"""BVH reading and writing: bundled samples, synthetic layouts, round trips, bad input."""
from __future__ import annotations

import pickle
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from mocodec.io import BVHError, format_bvh, parse_bvh, read_bvh, write_bvh
from mocodec.kinematics import forward_kinematics
from mocodec.motion import Motion, Skeleton
from mocodec.rotations import EULER_ORDERS, quat_conjugate, quat_multiply

SAMPLE_FRAMES = {"09_11": 166, "07_01": 317, "02_01": 344}  # from samples/ATTRIBUTION.md


def header_frames(text: str) -> int:
    """The ``Frames:`` value, read independently of the parser under test."""
    return int(re.search(r"^Frames:\s*(\d+)", text, re.M).group(1))


def assert_same_rotations(a: np.ndarray, b: np.ndarray, tol: float) -> None:
    """Quaternion arrays equal up to sign: the largest rotation between them (radians) is
    below tol. Measured from the vector part of a^-1 b (sin of half the angle), which stays
    accurate for tiny angles where arccos of the dot product does not."""
    half_sin = np.linalg.norm(quat_multiply(quat_conjugate(a), b)[..., :3], axis=-1)
    assert float(np.max(2.0 * np.arcsin(np.minimum(half_sin, 1.0)))) <= tol


# ------------------------------------------------------------------- bundled samples
def test_bundled_samples_parse(sample_paths: list[Path]) -> None:
    for path in sample_paths:
        motion = read_bvh(path)
        motion.validate()
        sk = motion.skeleton
        text = path.read_text()
        assert motion.name == path.stem
        assert motion.frame_count == SAMPLE_FRAMES[path.stem] == header_frames(text)
        assert sk.node_count == 38
        assert int(np.sum(~sk.is_end_site)) == 31 and int(np.sum(sk.is_end_site)) == 7
        assert sk.channel_count == 96
        assert motion.frame_time == pytest.approx(1 / 120, rel=1e-4)
        assert sk.names[0] == "Hips" and sk.parents[0] == -1
        assert sk.rotation_order(0) == "ZYX" and sk.position_axes(0) == (0, 1, 2)
        assert "LeftToeBase_End" in sk.names
        # Frame 1 (the first captured frame) against the file's own text.
        first = np.array(text.split("Frame Time:")[1].splitlines()[2].split(), dtype=float)
        np.testing.assert_array_equal(motion.source_channels[1], first)
        np.testing.assert_array_equal(motion.translations[1, 0], first[:3])


@pytest.mark.parametrize("precision", [0, 2, 4, 6, 9])
def test_samples_round_trip(sample_paths: list[Path], precision: int) -> None:
    for path in sample_paths:
        motion = read_bvh(path)
        text = format_bvh(motion, precision)
        again = parse_bvh(text)
        assert again.skeleton == motion.skeleton
        assert again.frame_time == motion.frame_time
        step = 0.5 * 10.0 ** -precision + 1e-9
        assert np.max(np.abs(again.source_channels - motion.source_channels)) <= step
        assert np.max(np.abs(again.translations - motion.translations)) <= step
        assert_same_rotations(again.rotations, motion.rotations, 3 * np.radians(step) + 1e-9)
        # Writing what was read gives the same text: the format is a fixed point.
        assert format_bvh(again, precision) == text


def test_write_and_read_files(sample_paths: list[Path], tmp_path: Path) -> None:
    motion = read_bvh(sample_paths[0])
    out = tmp_path / "copy.bvh"
    write_bvh(motion, out, precision=4)
    again = read_bvh(out)
    assert again.name == "copy"
    np.testing.assert_array_equal(again.source_channels, motion.source_channels)
    assert b"\r" not in out.read_bytes()


def test_format_uses_reference_branches(sample_paths: list[Path]) -> None:
    motion = read_bvh(sample_paths[0])
    reference = motion.source_channels.copy()
    reference[:, 3] += 360.0  # root Zrotation one turn up
    shifted = parse_bvh(format_bvh(motion, 4, reference=reference))
    np.testing.assert_allclose(shifted.source_channels, reference, atol=1e-9)
    with pytest.raises(ValueError, match="shape"):
        format_bvh(motion, 4, reference=reference[1:])


def test_format_without_source_channels(sample_paths: list[Path]) -> None:
    motion = read_bvh(sample_paths[1])
    bare = Motion(motion.skeleton, motion.rotations, motion.translations, motion.frame_time)
    again = parse_bvh(format_bvh(bare, 6))
    assert_same_rotations(again.rotations, motion.rotations, 1e-6)
    np.testing.assert_allclose(again.translations, motion.translations, atol=1e-6)


@pytest.mark.parametrize("precision", [-1, 2.5, True, 18])
def test_format_rejects_bad_precision(sample_paths: list[Path], precision) -> None:
    motion = read_bvh(sample_paths[0])
    with pytest.raises(ValueError, match="precision"):
        format_bvh(motion, precision)


def test_shared_cmu_files(shared_cmu_dir: Path | None) -> None:
    if shared_cmu_dir is None:
        pytest.skip("../shared/data/cmu not present: the development data set is not on this "
                    "machine")
    paths = sorted(shared_cmu_dir.glob("*.bvh"))
    assert paths, f"no .bvh files in {shared_cmu_dir}"
    for path in paths:
        motion = read_bvh(path)
        motion.validate()
        assert motion.frame_count == header_frames(path.read_text()), path.name
        assert motion.skeleton.channel_count == 96, path.name
        # The files hold 4 decimals, so writing 4 decimals must give the same values back,
        # including Euler triples outside [-90, 90] in the middle angle.
        again = parse_bvh(format_bvh(motion, 4))
        assert np.max(np.abs(again.source_channels - motion.source_channels)) < 1e-9, path.name


# ------------------------------------------------------------------- synthetic files
@dataclass
class J:
    """A joint of a synthetic hierarchy."""

    name: str
    offset: tuple[float, float, float]
    channels: tuple[str, ...] = ()
    children: list["J"] = field(default_factory=list)
    end_site: tuple[float, float, float] | None = None
    write_channels_line: bool = True


def _walk(roots: list[J]):
    for root in roots:
        stack = [(root, None)]
        while stack:
            joint, parent = stack.pop()
            yield joint, parent
            stack.extend((c, joint) for c in reversed(joint.children))


def make_bvh(roots: list[J], values: np.ndarray, frame_time: float = 1 / 30,
             newline: str = "\n", indent: str = "\t", end_word: str = "End Site",
             blank_lines: bool = False) -> str:
    """BVH text for ``roots`` and ``values`` (frames x channels in file order)."""
    out = ["HIERARCHY"]

    def emit(joint: J, depth: int, keyword: str) -> None:
        pad = indent * depth
        out.extend([f"{pad}{keyword} {joint.name}", f"{pad}{{"])
        out.append(f"{pad}{indent}OFFSET " + " ".join(repr(v) for v in joint.offset))
        if joint.write_channels_line:
            out.append(f"{pad}{indent}CHANNELS {len(joint.channels)} {' '.join(joint.channels)}")
        if blank_lines:
            out.append("")
        for child in joint.children:
            emit(child, depth + 1, "JOINT")
        if joint.end_site is not None:
            out.extend([f"{pad}{indent}{end_word}", f"{pad}{indent}{{",
                        f"{pad}{indent * 2}OFFSET " + " ".join(map(repr, joint.end_site)),
                        f"{pad}{indent}}}"])
        out.append(f"{pad}}}")

    for root in roots:
        emit(root, 0, "ROOT")
    out += ["MOTION", f"Frames: {len(values)}", f"Frame Time: {frame_time!r}"]
    if blank_lines:
        out.append("")
    out += [" ".join(repr(float(v)) for v in row) for row in values]
    if blank_lines:
        out += ["", ""]
    return newline.join(out) + newline


def random_values(roots: list[J], frames: int, rng: np.random.Generator) -> np.ndarray:
    """Positions in +-30 units, angles anywhere in +-200 degrees (middle angles beyond
    +-90 included, so the writer must find the source's Euler triple)."""
    cols = [ch for joint, _ in _walk(roots) for ch in joint.channels]
    values = np.empty((frames, len(cols)))
    for c, ch in enumerate(cols):
        span = 30.0 if ch.endswith("position") else 200.0
        values[:, c] = rng.uniform(-span, span, frames)
    return values


def expected_model(roots: list[J], values: np.ndarray):
    """Per joint name: (quaternions, translations) computed with scipy, independently of
    the reader."""
    out = {}
    col = 0
    for joint, _ in _walk(roots):
        cols = values[:, col:col + len(joint.channels)]
        col += len(joint.channels)
        trans = np.tile(np.array(joint.offset, dtype=float), (len(values), 1))
        axes, angles = "", []
        for k, ch in enumerate(joint.channels):
            if ch.endswith("position"):
                trans[:, "XYZ".index(ch[0])] = cols[:, k]  # replaces the OFFSET axis
            else:
                axes += ch[0]
                angles.append(cols[:, k])
        if axes:
            quat = Rotation.from_euler(axes, np.stack(angles, -1), degrees=True).as_quat()
        else:
            quat = np.tile([0.0, 0.0, 0.0, 1.0], (len(values), 1))
        out[joint.name] = (quat, trans)
    return out


def assert_matches(motion: Motion, roots: list[J], values: np.ndarray) -> None:
    sk = motion.skeleton
    joints = list(_walk(roots))
    assert [sk.names[i] for i in np.flatnonzero(~sk.is_end_site)] == [j.name for j, _ in joints]
    for joint, parent in joints:
        i = sk.index(joint.name)
        assert sk.parents[i] == (-1 if parent is None else sk.index(parent.name))
    for name, (quat, trans) in expected_model(roots, values).items():
        i = sk.index(name)
        assert_same_rotations(motion.rotations[:, i], quat, 1e-9)
        np.testing.assert_allclose(motion.translations[:, i], trans, atol=1e-12)
    np.testing.assert_array_equal(motion.source_channels, values)


ROT = {order: tuple(f"{a}rotation" for a in order) for order in EULER_ORDERS}
POS = ("Xposition", "Yposition", "Zposition")


def every_order_chain() -> list[J]:
    """A root with shuffled position and rotation channels, then one joint per Euler order."""
    root = J("Root", (1.0, 2.0, 3.0),
             ("Zrotation", "Xposition", "Yrotation", "Zposition", "Xrotation", "Yposition"))
    parent = root
    for order in EULER_ORDERS:
        child = J(f"J_{order}", (0.0, 4.0, 1.0), ROT[order])
        parent.children.append(child)
        parent = child
    parent.end_site = (0.0, 2.0, 0.0)
    return [root]


def test_every_euler_order_and_channel_order() -> None:
    rng = np.random.default_rng(1)
    roots = every_order_chain()
    values = random_values(roots, 25, rng)
    motion = parse_bvh(make_bvh(roots, values))
    motion.validate()
    assert_matches(motion, roots, values)
    assert [motion.skeleton.rotation_order(motion.skeleton.index(f"J_{o}"))
            for o in EULER_ORDERS] == list(EULER_ORDERS)


@pytest.mark.parametrize("root_channels", [POS, ROT["ZXY"], POS + ROT["YXZ"]],
                         ids=["3-pos", "3-rot", "6"])
def test_root_with_three_or_six_channels(root_channels: tuple[str, ...]) -> None:
    roots = [J("Hips", (5.0, 90.0, -2.0), root_channels,
               [J("Spine", (0.0, 10.0, 0.0), ROT["ZYX"], end_site=(0.0, 8.0, 0.0))])]
    values = random_values(roots, 12, np.random.default_rng(2))
    assert_matches(parse_bvh(make_bvh(roots, values)), roots, values)


def test_position_channels_replace_the_offset() -> None:
    # Six channels on every joint, OFFSETs that disagree with the channels: the bone length
    # must come from the channel values alone.
    chain = [J("Hips", (0.0, 0.0, 0.0), POS + ROT["ZYX"])]
    parent = chain[0]
    for k in range(4):
        child = J(f"Bone{k}", (7.0, 7.0, 7.0), POS + ROT["ZYX"])
        parent.children.append(child)
        parent = child
    partial = J("OnlyY", (3.0, 4.0, 5.0), ("Yposition",) + ROT["XYZ"])
    parent.children.append(partial)
    values = random_values(chain, 10, np.random.default_rng(3))
    motion = parse_bvh(make_bvh(chain, values))
    assert_matches(motion, chain, values)
    _, pos = forward_kinematics(motion.skeleton, motion.rotations, motion.translations)
    sk = motion.skeleton
    for k in range(4):
        i = sk.index(f"Bone{k}")
        bone = np.linalg.norm(pos[:, i] - pos[:, sk.parents[i]], axis=-1)
        col = 6 * (k + 1)
        np.testing.assert_allclose(bone, np.linalg.norm(values[:, col:col + 3], axis=-1))
    i = sk.index("OnlyY")
    np.testing.assert_allclose(motion.translations[:, i, [0, 2]], np.tile([3.0, 5.0], (10, 1)))
    np.testing.assert_array_equal(motion.translations[:, i, 1], values[:, -4])


def test_one_and_two_rotation_channel_joints() -> None:
    joints = [J(f"One{a}", (0.0, 1.0, 0.0), (f"{a}rotation",)) for a in "XYZ"]
    joints += [J(f"Two{o[:2]}", (1.0, 0.0, 0.0), ROT[o][:2]) for o in EULER_ORDERS]
    root = J("Root", (0.0, 0.0, 0.0), POS, joints)
    values = random_values([root], 30, np.random.default_rng(4))
    motion = parse_bvh(make_bvh([root], values))
    assert_matches(motion, [root], values)
    # Written back without a reference, the angles must still describe the same rotations
    # (the second of two angles goes beyond +-90 here).
    bare = Motion(motion.skeleton, motion.rotations, motion.translations, motion.frame_time)
    again = parse_bvh(format_bvh(bare, 9))
    assert_same_rotations(again.rotations, motion.rotations, 1e-8)


def several_roots() -> list[J]:
    return [
        J("Actor", (0.0, 0.0, 0.0), POS + ROT["ZYX"],
          [J("Head", (0.0, 20.0, 0.0), ROT["XYZ"], end_site=(0.0, 3.0, 0.0))]),
        J("Prop", (10.0, 0.0, 0.0), ROT["YZX"] + POS, end_site=(1.0, 0.0, 0.0)),
        J("Camera", (0.0, 5.0, -30.0), (), write_channels_line=False),
    ]


def test_several_roots() -> None:
    roots = several_roots()
    values = random_values(roots, 8, np.random.default_rng(5))
    motion = parse_bvh(make_bvh(roots, values))
    assert_matches(motion, roots, values)
    assert int(np.sum(motion.skeleton.parents == -1)) == 3


def test_channels_zero_joints() -> None:
    roots = [J("Root", (0.0, 0.0, 0.0), POS,
               [J("Fixed", (0.0, 3.0, 0.0), (),
                  [J("Moving", (0.0, 3.0, 0.0), ROT["ZXY"], end_site=(0.0, 1.0, 0.0))]),
                J("NoLine", (1.0, 0.0, 0.0), (), write_channels_line=False)])]
    values = random_values(roots, 6, np.random.default_rng(6))
    motion = parse_bvh(make_bvh(roots, values))
    assert_matches(motion, roots, values)
    assert motion.skeleton.channels[motion.skeleton.index("Fixed")] == ()


def test_crlf_tabs_blank_lines_and_end_site_spelling() -> None:
    roots = every_order_chain() + several_roots()
    values = random_values(roots, 9, np.random.default_rng(7))
    plain = parse_bvh(make_bvh(roots, values))
    messy = parse_bvh(make_bvh(roots, values, newline="\r\n", indent="\t  ",
                               end_word="End site", blank_lines=True))
    assert messy.skeleton == plain.skeleton
    np.testing.assert_array_equal(messy.source_channels, plain.source_channels)
    assert_matches(messy, roots, values)


def test_end_site_names_stay_unique() -> None:
    roots = [J("Root", (0.0, 0.0, 0.0), POS,
               [J("Hand", (1.0, 0.0, 0.0), ROT["ZYX"], end_site=(1.0, 0.0, 0.0)),
                J("Hand_End", (0.0, 1.0, 0.0), ROT["ZYX"], end_site=(0.0, 1.0, 0.0))])]
    motion = parse_bvh(make_bvh(roots, random_values(roots, 2, np.random.default_rng(8))))
    names = motion.skeleton.names
    assert len(set(names)) == len(names)
    assert "Hand_End_End" in names and "Hand_End2" in names
    assert motion.skeleton.parents[names.index("Hand_End2")] == names.index("Hand")


@pytest.mark.parametrize("frame_time", [1 / 24, 1 / 30, 0.04, 1 / 60, 1 / 120, 0.001])
def test_any_frame_rate(frame_time: float) -> None:
    roots = every_order_chain()
    values = random_values(roots, 3, np.random.default_rng(9))
    motion = parse_bvh(make_bvh(roots, values, frame_time=frame_time))
    assert motion.frame_time == frame_time
    assert parse_bvh(format_bvh(motion)).frame_time == frame_time


@pytest.mark.parametrize("precision", [1, 3, 6, 8])
def test_synthetic_round_trip(precision: int) -> None:
    roots = every_order_chain() + several_roots()
    roots[0].children.append(J("Side", (2.0, 0.0, 0.0), ROT["XZY"][:2] + ("Xposition",)))
    values = random_values(roots, 40, np.random.default_rng(10 + precision))
    # Gimbal lock on some frames: middle angle exactly +-90 with the other two non-zero.
    col = len(roots[0].channels) + 1  # middle angle of J_XYZ
    values[::5, col] = 90.0
    values[1::5, col] = -90.0
    motion = parse_bvh(make_bvh(roots, values))
    again = parse_bvh(format_bvh(motion, precision))
    step = 0.5 * 10.0 ** -precision + 1e-9
    assert again.skeleton == motion.skeleton
    assert np.max(np.abs(again.source_channels - values)) <= step
    assert_same_rotations(again.rotations, motion.rotations, 3 * np.radians(step) + 1e-9)
    np.testing.assert_allclose(again.translations, motion.translations, atol=step)


def test_writer_follows_depth_first_order() -> None:
    # A skeleton listed breadth-first: the file is written depth-first, so the columns must
    # be reordered with the nodes.
    sk = Skeleton(names=["R", "A", "B", "A1", "B1"], parents=[-1, 0, 0, 1, 2],
                  offsets=[[0, 0, 0], [1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0]],
                  channels=[(0, 1, 2, 5, 4, 3), (3, 4, 5), (5, 3), (4,), (3, 5, 4)],
                  is_end_site=[False] * 5)
    values = np.random.default_rng(11).uniform(-80, 80, (7, sk.channel_count))
    motion = Motion.from_channels(sk, values, 0.01, "bfs")
    again = parse_bvh(format_bvh(motion, 9))
    assert again.skeleton.names == ["R", "A", "A1", "B", "B1"]
    for name in sk.names:
        i, k = sk.index(name), again.skeleton.index(name)
        assert_same_rotations(again.rotations[:, k], motion.rotations[:, i], 1e-8)
        np.testing.assert_allclose(again.translations[:, k], motion.translations[:, i],
                                   atol=1e-8)


def test_clip_names() -> None:
    roots = several_roots()
    text = make_bvh(roots, random_values(roots, 1, np.random.default_rng(13)))
    assert parse_bvh(text).name == "clip"
    assert parse_bvh(text, path="/x/walk_03.bvh").name == "walk_03"
    assert parse_bvh(text, path="/x/walk_03.bvh", name="w").name == "w"


# ------------------------------------------------------------------------ bad input
BASE = [
    "HIERARCHY",                                                                  # 1
    "ROOT Hips",                                                                  # 2
    "{",                                                                          # 3
    "\tOFFSET 0 0 0",                                                             # 4
    "\tCHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation",   # 5
    "\tJOINT Spine",                                                              # 6
    "\t{",                                                                        # 7
    "\t\tOFFSET 0 10 0",                                                          # 8
    "\t\tCHANNELS 3 Zrotation Yrotation Xrotation",                               # 9
    "\t\tEnd Site",                                                               # 10
    "\t\t{",                                                                      # 11
    "\t\t\tOFFSET 0 5 0",                                                         # 12
    "\t\t}",                                                                      # 13
    "\t}",                                                                        # 14
    "}",                                                                          # 15
    "MOTION",                                                                     # 16
    "Frames: 2",                                                                  # 17
    "Frame Time: 0.0333333",                                                      # 18
    "1 2 3 10 20 30 40 50 60",                                                    # 19
    "4 5 6 11 21 31 41 51 61",                                                    # 20
]


def replaced(line: int, text: str) -> list[str]:
    out = list(BASE)
    out[line - 1] = text
    return out


def inserted(after: int, *texts: str) -> list[str]:
    return BASE[:after] + list(texts) + BASE[after:]


def deleted(line: int) -> list[str]:
    return BASE[:line - 1] + BASE[line:]


BAD = [
    ("missing HIERARCHY", deleted(1), 1, "expected HIERARCHY"),
    ("missing MOTION", BASE[:15], 15, "missing MOTION"),
    ("truncated MOTION", BASE[:19], 20, "truncated MOTION: 'Frames: 2' but only 1"),
    ("truncated mid-line", BASE[:19] + ["4 5 6 11"], 20, "may be truncated"),
    ("extra frame line", BASE + ["7 8 9 1 2 3 4 5 6"], 21, "more frame lines than 'Frames: 2'"),
    ("extra line after blanks", BASE + ["", "7 8 9"], 22, "more frame lines"),
    ("too few values", replaced(19, "1 2 3 10 20 30 40 50"), 19, "expected 9 values, got 8"),
    ("too many values", replaced(20, "4 5 6 11 21 31 41 51 61 0"), 20,
     "expected 9 values, got 10"),
    ("non-numeric value", replaced(20, "4 5 6 11 abc 31 41 51 61"), 20,
     "value 5: 'abc' is not a number"),
    ("underscore number", replaced(19, "1 2 3 1_0 20 30 40 50 60"), 19, "'1_0' is not a number"),
    ("nan value", replaced(19, "1 2 nan 10 20 30 40 50 60"), 19, "'nan' is not finite"),
    ("inf value", replaced(20, "4 5 6 11 21 31 41 51 -inf"), 20, "'-inf' is not finite"),
    ("unknown channel", replaced(9, "\t\tCHANNELS 3 Zrotation Yrotation Wrotation"), 9,
     "unknown channel 'Wrotation'"),
    ("channel count mismatch", replaced(9, "\t\tCHANNELS 2 Zrotation Yrotation Xrotation"), 9,
     "count says 2 but 3 channel names"),
    ("channel count missing", replaced(9, "\t\tCHANNELS Zrotation Yrotation Xrotation"), 9,
     "needs a channel count"),
    ("duplicate channel", replaced(9, "\t\tCHANNELS 3 Zrotation Xrotation Zrotation"), 9,
     "duplicate channel 'Zrotation'"),
    ("keyword case", replaced(9, "\t\tchannels 3 Zrotation Yrotation Xrotation"), 9,
     "unexpected 'channels'"),
    ("unknown keyword", inserted(4, "\tSCALE 2"), 5, "unexpected 'SCALE'"),
    ("missing closing brace", deleted(14), 15, "unbalanced braces"),
    ("extra closing brace", inserted(15, "}"), 16, "unmatched '}'"),
    ("missing opening brace", deleted(7), 7, "expected '{' after JOINT 'Spine'"),
    ("end of file in hierarchy", BASE[:8], 8, "unexpected end of file inside JOINT 'Spine'"),
    ("Frames: 0", replaced(17, "Frames: 0"), 17, "at least one frame"),
    ("negative Frames", replaced(17, "Frames: -5"), 17, "at least one frame"),
    ("Frames not a number", replaced(17, "Frames: two"), 17, "whole number"),
    ("missing Frames", deleted(17), 17, "missing 'Frames:'"),
    ("missing Frame Time", deleted(18), 18, "missing 'Frame Time:'"),
    ("invalid Frame Time", replaced(18, "Frame Time: fast"), 18, "number of seconds"),
    ("zero Frame Time", replaced(18, "Frame Time: 0"), 18, "positive"),
    ("negative Frame Time", replaced(18, "Frame Time: -0.01"), 18, "positive"),
    ("nan Frame Time", replaced(18, "Frame Time: nan"), 18, "positive"),
    ("duplicate joint", replaced(6, "\tJOINT Hips"), 6,
     "duplicate joint name 'Hips' (first on line 2)"),
    ("OFFSET two values", replaced(8, "\t\tOFFSET 0 10"), 8, "OFFSET needs 3 numbers, got 2"),
    ("OFFSET four values", replaced(8, "\t\tOFFSET 0 10 0 1"), 8, "OFFSET needs 3 numbers, got 4"),
    ("OFFSET not a number", replaced(8, "\t\tOFFSET 0 ten 0"), 8, "'ten' is not a number"),
    ("OFFSET not finite", replaced(8, "\t\tOFFSET 0 inf 0"), 8, "'inf' is not finite"),
    ("missing OFFSET", deleted(8), 13, "JOINT 'Spine' (line 6) has no OFFSET"),
    ("End Site with channels", inserted(12, "\t\t\tCHANNELS 1 Xrotation"), 13,
     "End Site (line 10) cannot have channels"),
    ("End Site with children", inserted(12, "\t\t\tJOINT Tip"), 13, "cannot have children"),
    ("JOINT outside ROOT", inserted(15, "JOINT Loose", "{", "OFFSET 0 0 0", "}"), 16,
     "JOINT 'Loose' outside any ROOT"),
    ("empty file", [], 1, "empty file"),
    ("blank file", ["", "  ", "\t"], 1, "empty file"),
]


@pytest.mark.parametrize("lines, line, phrase", [c[1:] for c in BAD], ids=[c[0] for c in BAD])
@pytest.mark.parametrize("newline", ["\n", "\r\n"], ids=["lf", "crlf"])
def test_bad_input(lines: list[str], line: int, phrase: str, newline: str) -> None:
    text = newline.join(lines) + (newline if lines else "")
    with pytest.raises(BVHError) as info:
        parse_bvh(text, path="bad.bvh")
    err = info.value
    assert (err.path, err.line) == ("bad.bvh", line), str(err)
    assert phrase in err.message
    assert str(err) == f"bad.bvh:{line}: {err.message}"


def test_base_of_bad_input_is_valid() -> None:
    motion = parse_bvh("\n".join(BASE) + "\n")
    assert motion.frame_count == 2 and motion.skeleton.names == ["Hips", "Spine", "Spine_End"]


def test_non_utf8_bytes() -> None:
    with pytest.raises(BVHError, match="not UTF-8") as info:
        parse_bvh(b"HIERARCHY\nROOT Hips\xff\xfe\n{\n", path="x.bvh")
    assert info.value.line == 2


def test_nul_characters() -> None:
    with pytest.raises(BVHError, match="binary data") as info:
        parse_bvh("HIERARCHY\nROOT Hips\n\x00\x00\x00")
    assert info.value.line == 3 and info.value.path is None


def test_binary_file_through_read_bvh(tmp_path: Path) -> None:
    path = tmp_path / "garbage.bvh"
    path.write_bytes(bytes(np.random.default_rng(12).integers(0, 256, 4096, dtype=np.uint8)))
    with pytest.raises(BVHError) as info:
        read_bvh(path)
    assert info.value.path == str(path)
    assert str(info.value).startswith(f"{path}:")


def test_file_error_names_path_and_line(tmp_path: Path) -> None:
    path = tmp_path / "broken.bvh"
    path.write_text("\n".join(replaced(20, "4 5 6 11 21 31 41 51")) + "\n")
    with pytest.raises(BVHError) as info:
        read_bvh(path)
    assert str(info.value).startswith(f"{path}:20: frame 2 of 2: expected 9 values, got 8")


def test_missing_file(tmp_path: Path) -> None:
    with pytest.raises(BVHError, match="cannot read"):
        read_bvh(tmp_path / "nope.bvh")


def test_error_text_and_type() -> None:
    assert str(BVHError("bad")) == "bad"
    assert str(BVHError("bad", path="a.bvh")) == "a.bvh: bad"
    assert str(BVHError("bad", line=3)) == "3: bad"
    assert str(BVHError("bad", path="a.bvh", line=3)) == "a.bvh:3: bad"
    assert isinstance(BVHError("bad"), ValueError)
    copy = pickle.loads(pickle.dumps(BVHError("bad", path="a.bvh", line=3)))
    assert (copy.message, copy.path, copy.line) == ("bad", "a.bvh", 3)


def test_braces_on_header_lines() -> None:
    text = "\n".join(BASE).replace("ROOT Hips\n{", "ROOT Hips {").replace(
        "JOINT Spine\n\t{", "JOINT Spine{").replace("End Site\n\t\t{", "End Site{")
    assert text.count("{") == 3 and text.count("\n") == len(BASE) - 4
    motion = parse_bvh(text)
    assert motion.skeleton.names == ["Hips", "Spine", "Spine_End"]


# ------------------------------------------------------- the format's limits at read time
LIMITS = [
    ("OFFSET 1e308 (hung in an SVD)", replaced(8, "\t\tOFFSET 0 1e308 0"), 8, "outside the format's +-1e7"),
    ("OFFSET beyond 1e7", replaced(8, "\t\tOFFSET 0 -2e7 0"), 8, "outside the format's +-1e7"),
    ("frame value 1e308", replaced(19, "1e308 2 3 10 20 30 40 50 60"), 19, "value 1: '1e308' is outside"),
    ("rotation 1e300 degrees", replaced(20, "4 5 6 11 21 31 41 51 1e300"), 20, "value 9: '1e300' is outside"),
    ("Frame Time 1e-7", replaced(18, "Frame Time: 1e-7"), 18, "at most 100,000"),
    ("Frame Time 1e-300", replaced(18, "Frame Time: 1e-300"), 18, "at most 100,000"),
    ("Frame Time 1e40", replaced(18, "Frame Time: 1e40"), 18, "below what binary32 holds"),
    ("Frames above 2^24", replaced(17, "Frames: 16777217"), 17, "at most 16,777,216 per clip"),
    ("Frames of 40 digits", replaced(17, "Frames: " + "9" * 40), 17, "whole number"),
    ("joint name with an escape", replaced(6, "\tJOINT Sp\x1b[31mine"), 6, "control character U+001B"),
    ("joint name of 256 bytes", replaced(6, "\tJOINT " + "é" * 128), 6, "256 bytes; the format allows at most 255"),
    ("a megabyte of garbage", inserted(4, "x" * 1_000_000), 5, "unexpected 'xxxxxxxx"),
]


@pytest.mark.parametrize("lines, line, phrase", [c[1:] for c in LIMITS], ids=[c[0] for c in LIMITS])
def test_format_limits_are_checked_at_read_time(lines: list[str], line: int, phrase: str) -> None:
    """Every limit of docs/FORMAT.md is refused where the file states it (the encoder used to
    write assets the runtime refuses, or hang, on these), and a message stays short."""
    with pytest.raises(BVHError) as info:
        parse_bvh("\n".join(lines) + "\n", path="bad.bvh")
    assert (info.value.path, info.value.line) == ("bad.bvh", line), str(info.value)
    assert phrase in info.value.message
    assert len(str(info.value)) < 200 and "\x1b" not in str(info.value)


def test_a_thousand_and_twenty_five_nodes_are_refused_at_the_node(tmp_path: Path) -> None:
    """20,000 joints: refused at the 1,025th node, before the skeleton (and the encoder's
    node-by-node matrices) exist, so reading stays small and quick."""
    import tracemalloc
    lines = ["HIERARCHY", "ROOT Hips", "{", "\tOFFSET 0 0 0", "\tCHANNELS 3 Xposition Yposition Zposition"]
    for i in range(20_000):
        lines += [f"\tJOINT J{i}", "\t{", "\t\tOFFSET 1 0 0", "\t\tCHANNELS 0", "\t}"]
    lines += ["}", "MOTION", "Frames: 1", "Frame Time: 0.01", "0 0 0"]
    text = "\n".join(lines) + "\n"
    tracemalloc.start()
    try:
        with pytest.raises(BVHError) as info:
            parse_bvh(text, path="wide.bvh")
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert info.value.line == 5 + 5 * 1023 + 1 and "more than 1,024 nodes" in info.value.message
    assert peak < 40 * len(text)
    ok = lines[:5 + 5 * 1023] + ["}", "MOTION", "Frames: 1", "Frame Time: 0.01", "0 0 0"]
    assert parse_bvh("\n".join(ok) + "\n").skeleton.node_count == 1024


def test_a_hierarchy_without_channels_has_a_line_a_frame() -> None:
    """A still pose written by write_bvh (one empty line a frame) reads back with its frames;
    a 'Frames:' count the lines do not back is a truncated file, not millions of frames."""
    head = ["HIERARCHY", "ROOT Hips", "{", "\tOFFSET 0 0 0", "\tCHANNELS 0", "\tJOINT Leg", "\t{",
            "\t\tOFFSET 0 -1 0", "\t\tCHANNELS 0", "\t}", "}", "MOTION"]
    still = parse_bvh("\n".join(head + ["Frames: 5", "Frame Time: 0.01"]) + "\n" * 6)
    assert still.frame_count == 5
    again = parse_bvh(format_bvh(still))
    assert again.frame_count == 5 and again.skeleton.names == still.skeleton.names
    with pytest.raises(BVHError) as info:
        parse_bvh("\n".join(head + ["Frames: 3000000", "Frame Time: 0.01"]) + "\n", path="still.bvh")
    assert info.value.line == 15 and "'Frames: 3000000' but only 0 frame lines" in info.value.message


def test_frames_a_file_does_not_back_are_refused_before_the_motion_exists() -> None:
    """One channel on 1,000 joints: 2 bytes a frame would become 80 bytes x 1,001 nodes; past
    the free budget it is refused on the 'Frames:' line, and a real skeleton's ratio is far
    inside it."""
    lines = ["HIERARCHY", "ROOT Hips", "{", "\tOFFSET 0 0 0", "\tCHANNELS 1 Xposition"]
    for i in range(1000):
        lines += [f"\tJOINT J{i}", "\t{", "\t\tOFFSET 1 0 0", "\t\tCHANNELS 0", "\t}"]
    lines += ["}", "MOTION"]
    with pytest.raises(BVHError) as info:
        parse_bvh("\n".join(lines + ["Frames: 5000", "Frame Time: 0.01"] + ["0"] * 5000) + "\n")
    assert info.value.line == len(lines) + 1 and "5,005,000 samples" in info.value.message
    assert parse_bvh("\n".join(lines + ["Frames: 4000", "Frame Time: 0.01"] + ["0"] * 4000) + "\n"
                     ).frame_count == 4000


def test_only_regular_files_are_read(tmp_path: Path) -> None:
    """A FIFO blocked forever and /dev/zero grew to gigabytes: both are refused unread."""
    import os
    import subprocess
    import sys
    fifo = tmp_path / "pipe.bvh"
    os.mkfifo(fifo)
    code = ("import sys; from mocodec.io import read_bvh, BVHError\n"
            "for p in sys.argv[1:]:\n"
            "    try: read_bvh(p)\n"
            "    except BVHError as e: print(e)\n")
    r = subprocess.run([sys.executable, "-c", code, str(fifo), "/dev/zero", str(tmp_path)],
                       capture_output=True, text=True, timeout=60)
    assert r.stdout.splitlines() == [
        f"{fifo}: a FIFO, not a BVH file (only regular files are read)",
        "/dev/zero: a device, not a BVH file (only regular files are read)",
        f"{tmp_path}: a folder, not a BVH file (only regular files are read)"], r.stderr


def test_clip_names_from_file_names_keep_to_the_format(tmp_path: Path) -> None:
    """A file name may hold what a clip name may not (':', a control character): the clip is
    named with '_' in their place and its asset opens (it was refused by the runtime)."""
    from mocodec.encode import encode_motions
    from mocodec.runtime import Asset
    from mocodec.units import resolve_units
    path = tmp_path / "take:2\x1b.bvh"
    path.write_text("\n".join(BASE) + "\n")
    motion = read_bvh(path)
    assert motion.name == "take_2_"
    result = encode_motions([motion], [resolve_units(motion.skeleton, "cm")], "spline")
    assert [c.name for c in Asset(result.asset).clips] == ["take_2_"]


def long_sample_text(path: Path, frames: int) -> str:
    """The BVH at ``path`` with its frames repeated to ``frames`` of them."""
    lines = path.read_text().splitlines()
    at = next(k for k, line in enumerate(lines) if line.startswith("Frames:"))
    rows = [line for line in lines[at + 2:] if line.strip()]
    return "\n".join(lines[:at] + [f"Frames: {frames}", lines[at + 1]] + (rows * (frames // len(rows) + 1))[:frames]) + "\n"


def test_reading_a_long_clip_keeps_memory_near_the_motion(sample_paths: list[Path]) -> None:
    """Reading held every token of the MOTION block as a Python string at once (11.6 times the
    text at the peak on a CMU clip); now lines are converted in chunks and a node's rotations
    made continuous one node at a time: the peak is what the motion keeps (its float64
    rotations and translations) plus at most 2.5 times the text."""
    data = long_sample_text(sample_paths[0], 6000).encode()
    motion, kept, peak = traced(lambda: parse_bvh(data))
    assert motion.frame_count == 6000
    assert peak < kept + 2.5 * len(data), (peak / len(data), kept / len(data))


def traced(read):
    """``read()``, and the memory it keeps and its peak (tracemalloc)."""
    import tracemalloc
    tracemalloc.start()
    try:
        out = read()
        kept, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    return out, kept, peak


def test_a_file_over_the_size_limit_is_refused_from_its_size(tmp_path: Path) -> None:
    """Reading took the whole file whatever its size; now a file over the limit is refused
    before a byte is read (the limit is 4 GiB: tried here with a small one)."""
    from mocodec.io.files import MAX_INPUT_BYTES, read_regular_file
    big = tmp_path / "big.bvh"
    big.write_bytes(b"x" * 200)
    with pytest.raises(BVHError) as info:
        read_regular_file(big, "BVH file", lambda m: BVHError(m, str(big)), limit=100)
    assert str(info.value) == f"{big}: 200 bytes; files over 100 bytes are not read"
    assert read_regular_file(big, "BVH file", lambda m: BVHError(m, str(big)), limit=200) == b"x" * 200
    assert MAX_INPUT_BYTES == 4 << 30


def test_reading_a_small_file_reserves_no_more_than_it_holds(tmp_path: Path) -> None:
    """The size limit must not become an allocation: read(limit + 1) reserved 4 GiB for any file."""
    import tracemalloc
    from mocodec.io.files import read_regular_file
    small = tmp_path / "small.bvh"
    small.write_bytes(b"y" * 1000)
    tracemalloc.start()
    try:
        assert read_regular_file(small, "BVH file", lambda m: BVHError(m, str(small))) == b"y" * 1000
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 1 << 20
