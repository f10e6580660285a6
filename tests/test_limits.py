"""The format's limits on a motion built in code (not read from a file): the encoder refuses
what the runtime would refuse, naming the item, instead of writing an asset that fails to open
('mcd_resident_size: asset is malformed' was all a user saw)."""
from __future__ import annotations

import dataclasses
import re

import numpy as np
import pytest

from mocodec.encode import encode_motions
from mocodec.io import read_bvh
from mocodec.limits import LimitError, printable, safe_clip_name
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


def test_printable_and_safe_clip_names():
    assert printable("a\x1b[2J\u202e\x07 b") == "a\\x1b[2J\\u202e\\x07 b"
    assert safe_clip_name("walk:1/2\\3\x00") == "walk_1_2_3_"
    assert safe_clip_name("..") == "clip" and safe_clip_name("") == "clip"
    assert len(safe_clip_name("é" * 200).encode()) == 254
