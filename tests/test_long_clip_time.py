"""Sampling time on a two-hour clip (tests/long_clip.py, 864,000 frames at 120 fps) through the
Python binding: mcd_sample takes seconds as a double, so a late frame's time frame / fps shows
that frame's pose exactly and a time between late frames the curve's pose there. With 0.2's float
time, the times two hours in resolved 0.06 frames and were snapped onto a frame from 0.35 frames
away. (runtime_c/tests/test_long_clip.c checks the same in C.)"""
from __future__ import annotations

import numpy as np
import pytest
from long_clip import FPS, encode_rma, late_frames, long_clip

from mocodec.codecs.rma_reference import decode_payload
from mocodec.runtime import Asset
from mocodec_runtime import SAMPLE_NEAREST


@pytest.fixture(scope="module")
def clip():
    m = long_clip()
    asset, payload = encode_rma(m)
    return m, Asset(asset), payload


def _gap(c: np.ndarray, rot: np.ndarray, trans: np.ndarray) -> float:
    """Largest difference of runtime poses (K, N, 10) from reference rotations and translations,
    rotations whichever sign their quaternion has."""
    sign = np.sign(np.sum(c[..., :4] * rot, axis=-1, keepdims=True))
    return float(max(np.abs(c[..., :4] - sign * rot).max(), np.abs(c[..., 4:7] - trans).max()))


def test_late_frames_show_their_own_pose(clip):
    m, asset, payload = clip
    frames = late_frames()
    poses = asset.sample_times(0, frames / FPS)
    assert np.array_equal(poses, asset.sample_times(0, frames / FPS, SAMPLE_NEAREST))
    rot, trans, _ = decode_payload(payload, m.skeleton, frames)
    assert _gap(poses, rot, trans) <= 1e-5


# The runtime holds the position in the clip as a float frame number: 1/16 frame is its
# resolution 864,000 frames in (docs/FORMAT.md), and the snap onto frames is at most 1/128 frame.
@pytest.mark.parametrize("fraction", [0.25, 0.5, 1 / 16])
def test_times_between_late_frames_reach_the_curve_between_them(clip, fraction):
    m, asset, payload = clip
    frames = late_frames()[:-1]
    poses = asset.sample_times(0, (frames + fraction) / FPS)
    rot, trans, _ = decode_payload(payload, m.skeleton, frames + fraction)
    assert _gap(poses, rot, trans) <= 1e-5
    on_frames = asset.sample_times(0, frames / FPS)
    moved = np.abs(poses[..., :4] - on_frames[..., :4]).max(axis=(1, 2))
    assert np.all(moved > 1e-4 * fraction / 0.25), moved  # the joint turns ~1 degree a quarter frame
