"""The format's limits on a motion built in code (not read from a file): the encoder refuses
what the runtime would refuse, naming the item, instead of writing an asset that fails to open
('mcd_resident_size: asset is malformed' was all a user saw)."""
from __future__ import annotations

import dataclasses
import re

import numpy as np
import pytest

from mocodec.encode import EncodeError, encode_motions
from mocodec.io import read_bvh
from mocodec.kinematics import forward_kinematics
from mocodec.limits import LimitError, position_reach, printable, safe_clip_name, samples_problem
from mocodec.tolerance import Tolerance
from mocodec.units import resolve_units


@pytest.fixture()
def motion(sample_paths):
    return read_bvh(sample_paths[2])


def _encode(m):
    return encode_motions([m], [resolve_units(m.skeleton, "cmu")], "spline")


@pytest.mark.parametrize("name, phrase", [
    ("../pw", "holds '/'"), ("C:", "holds '/'"), ("..", "is '.' or '..'"),
    ("a\x1b[2J", "control character U+001B"), ("", "an empty name"), ("x" * 256, "256 bytes"),
])
def test_clip_names_the_runtime_refuses_are_refused(motion, name, phrase):
    with pytest.raises(LimitError, match=re.escape(phrase)):
        _encode(dataclasses.replace(motion, name=name))


def test_values_outside_the_format_are_named(motion):
    trans = motion.translations.copy()
    trans[7, 0, 1] = 1e308
    with pytest.raises(LimitError) as info:
        _encode(dataclasses.replace(motion, translations=trans))
    assert "frame 8, translation of node 'Hips': 1e+308 is outside the format's +-1e7" in str(info.value)
    with pytest.raises(LimitError, match="frames per second; the format allows at most 100,000"):
        _encode(dataclasses.replace(motion, frame_time=1e-7))


def test_checks_read_a_long_clip_a_run_at_a_time_and_name_the_right_frame(motion, monkeypatch):
    """The whole-clip checks read runs of frames (mocodec.motion.FRAME_RUN): what is wrong in
    a later run is found and named with its frame in the clip, as when read whole."""
    import mocodec.motion
    from mocodec.codecs import scale_deviation
    from mocodec.limits import check_motion
    from mocodec.motion import MotionError

    monkeypatch.setattr(mocodec.motion, "FRAME_RUN", 7)
    assert motion.frame_count > 5 * 7
    late = 4 * 7 + 3
    trans = motion.translations.copy()
    trans[late, 0, 2] = -2e7
    with pytest.raises(LimitError, match=f"frame {late + 1}, translation of node 'Hips': -2e\\+07 is outside"):
        check_motion(dataclasses.replace(motion, translations=trans))
    offsets = motion.skeleton.offsets.copy()
    offsets[3, 0] = np.inf
    with pytest.raises(LimitError, match=f"rest offset of node '{motion.skeleton.names[3]}': inf is not finite"):
        check_motion(dataclasses.replace(motion, skeleton=dataclasses.replace(motion.skeleton, offsets=offsets)))
    rot = motion.rotations.copy()
    rot[late, 4] *= 1.001
    with pytest.raises(MotionError, match="not unit quaternions"):
        dataclasses.replace(motion, rotations=rot).validate()
    rot[late + 3, 2, 0] = np.nan
    with pytest.raises(MotionError, match="non-finite"):  # found before the norms, as read whole
        dataclasses.replace(motion, rotations=rot).validate()
    scales = np.ones_like(motion.translations)
    scales[late, 5] = [1.0, 1.5, 1.0]
    scales[2, 4] = [1.2, 1.0, 1.0]
    assert scale_deviation(dataclasses.replace(motion, scales=scales)) == pytest.approx((0.5, 5))
    end = int(np.flatnonzero(motion.skeleton.is_end_site)[0])  # no channels: animated only if it moves
    turned = motion.rotations.copy()
    turned[late, end] = [0.0, 0.6, 0.0, 0.8]
    assert not motion.animated()[end, 0] and dataclasses.replace(motion, rotations=turned).animated()[end, 0]
    moved = motion.translations.copy()
    moved[:] = motion.skeleton.offsets
    moved[late, 6, 1] += 1.0
    animated = dataclasses.replace(motion, translations=moved).animated()
    expected = [bool(motion.skeleton.position_axes(i)) for i in range(motion.skeleton.node_count)]
    expected[6] = True
    assert animated[:, 1].tolist() == expected


def test_printable_and_safe_clip_names():
    assert printable("a\x1b[2J\u202e\x07 b") == "a\\x1b[2J\\u202e\\x07 b"
    assert safe_clip_name("walk:1/2\\3\x00") == "walk_1_2_3_"
    assert safe_clip_name("..") == "clip" and safe_clip_name("") == "clip"
    assert len(safe_clip_name("é" * 200).encode()) == 254


def _moved(m, cm: float):
    """``m`` with its root ``cm`` centimetres further along X (the samples are in CMU units)."""
    trans = m.translations.copy()
    trans[:, 0, 0] += cm / resolve_units(m.skeleton, "cmu").cm_per_unit
    return dataclasses.replace(m, translations=trans)


@pytest.mark.parametrize("codec", ["rma", "spline"])
def test_a_clip_far_from_the_origin_is_refused_before_encoding(motion, codec):
    """50 km out, binary32 positions are 0.35 cm apart: no key lands within 1 cm once the
    runtime's own rounding is added. Refused up front with the limit named (rma failed late with
    "range ... needs more than 2**30 steps", spline with "quantization cannot reach the
    budget"); 20 km out still encodes within the tolerance."""
    units = [resolve_units(motion.skeleton, "cmu")]
    with pytest.raises(EncodeError, match=r"cannot meet the tolerance: clip '09_11': a position reaches 5e\+06 cm from the origin, "
                                         r"where the runtime's binary32 positions are 0\.353 cm apart.* "
                                         r"within 2\.959e\+06 cm of the origin, or loosen the tolerance to at least 1\.41 cm"):
        encode_motions([_moved(motion, 5e6)], units, codec, Tolerance(1.0))
    near = encode_motions([_moved(motion, 2e6)], units, codec, Tolerance(1.0))
    assert near.max_error_cm <= 1.0


def test_position_reach_bounds_every_world_coordinate(motion):
    m = _moved(motion, 3e4)
    _, pos = forward_kinematics(m.skeleton, m.rotations, m.translations, m.scales)
    reach = position_reach(m)
    # At most the root's reach plus every other node's longest translation (all in one chain).
    loose = np.abs(m.translations[:, 0]).max() + np.linalg.norm(m.translations[:, 1:], axis=-1).max(axis=0).sum()
    assert np.abs(pos).max() <= reach < loose


def test_the_sample_budget_keeps_long_captures_and_refuses_unbacked_frames() -> None:
    """A 2-hour capture at 120 fps on 100 nodes (BVH: 3 values a joint; glTF: a rotation key
    a node a frame, or resampled at 4 x its key rate) is backed; 12 keys or no value at all
    for millions of frames is not."""
    frames = 2 * 3600 * 120
    assert samples_problem(frames, 100, frames * 3 * 80) is None
    assert samples_problem(frames, 100, frames * 100) is None
    assert samples_problem(4 * frames, 100, frames * 100) is None
    assert samples_problem(4_194_304 // 4, 4, 0) is None
    assert "24,000,024 samples" in samples_problem(6_000_006, 4, 12, "keys")
    assert "backed by 0 frame values" in samples_problem(3_000_000, 2, 0, "frame values")
