"""Local refits of the key-frame engine (``KeyframeFitter.local_refits``, codec ``rma``): a
repair changes a track only where its target or budgets changed, so that a long clip's repairs
settle in a few rounds (issue 16, long captures) and a clip joined from copies of itself costs
no more repairs than one copy."""
from __future__ import annotations

import numpy as np
import pytest

from mocodec import rotations as R
from mocodec.curves import KIND_MRP, KIND_TWIST
from mocodec.encode import encode_motions
from mocodec.io import read_bvh
from mocodec.keyframes import (Fitted, Track, _retarget, _retarget_kept, _track_recon, fit_track,
                               untouched_keys)
from mocodec.motion import Motion
from mocodec.quantize import StepQuantizer
from mocodec.tolerance import Tolerance
from mocodec.units import resolve_units

def _turning(frames: int, turns: float, seed: int = 0) -> np.ndarray:
    """Local rotations (F, 4) that turn ``turns`` times about a tilted axis, with a wobble."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 1.0, frames)
    spin = R.quat_from_axis_angle(np.array([0.1, 1.0, 0.2]) / np.linalg.norm([0.1, 1.0, 0.2]),
                                  2 * np.pi * turns * t)
    wobble = R.quat_from_axis_angle(np.array([1.0, 0.0, 0.0]), 0.3 * np.sin(9 * t + rng.uniform()))
    return R.quat_multiply(spin, wobble)


@pytest.fixture(scope="module")
def motion(sample_paths) -> Motion:
    return read_bvh(sample_paths[0])


@pytest.mark.parametrize("turns", [0.2, 3.0])  # an MRP track, then a twist
def test_a_target_changed_on_some_frames_changes_the_values_only_there(motion, turns):
    q = _turning(400, turns)
    track = Track(0, KIND_MRP, np.zeros((400, 3)), None, np.zeros(4), np.zeros(3))
    _retarget(track, q, motion, 1)
    assert track.kind == (KIND_TWIST if turns > 1 else KIND_MRP)
    before = track.values.copy()
    rows = np.arange(150, 170)
    nudged = R.quat_multiply(q[rows], R.quat_from_axis_angle(np.array([0.0, 0.0, 1.0]), 0.02))
    assert _retarget_kept(track, -nudged, rows)  # either hemisphere
    other = np.setdiff1d(np.arange(400), rows)
    assert np.array_equal(track.values[other], before[other])
    assert not np.array_equal(track.values[rows], before[rows])
    # The changed frames decode to the new target (values are in the track's own parameterisation).
    track.keys, track.constant = None, None
    decoded = R.quat_multiply(track.ref, R.quat_from_mrp(track.values[rows, -3:]))
    if track.kind == KIND_TWIST:
        decoded = R.quat_multiply(R.quat_from_axis_angle(track.axis, track.values[rows, 0]), decoded)
    assert np.max(R.quat_angle(decoded, nudged)) < 1e-6  # the stored reference is binary32


def test_an_mrp_track_derives_the_values_it_was_built_and_retargeted_with(motion):
    # An MRP track holds no values (a long clip's F x 3 numbers a track): they are derived from
    # its target where read, and must be bit for bit those its builders computed.
    q = _turning(400, 0.2)
    track = Track(0, KIND_MRP, np.zeros((400, 3)), None, np.zeros(4), np.zeros(3))
    _retarget(track, q, motion, 1)
    assert track.kind == KIND_MRP and track.derived
    rel = R.quat_make_continuous(R.quat_multiply(R.quat_conjugate(track.ref), R.quat_make_continuous(q)))
    if np.mean(rel[:, 3]) < 0:
        rel = -rel
    assert np.array_equal(track.values, R.mrp_from_quat(rel))
    before = track.values
    rows = np.arange(150, 170)
    nudged = -R.quat_multiply(q[rows], R.quat_from_axis_angle(np.array([0.0, 0.0, 1.0]), 0.02))
    assert _retarget_kept(track, nudged, rows) and track.derived
    side = nudged * np.where(np.sum(nudged * q[rows], axis=1) < 0.0, -1.0, 1.0)[:, None]
    moved = R.quat_multiply(R.quat_conjugate(track.ref), side)
    moved[np.sum(moved * R.quat_from_mrp(before[rows]), axis=1) < 0.0] *= -1.0
    expected = before.copy()
    expected[rows] = R.mrp_from_quat(moved)
    assert np.array_equal(track.values, expected)
    assert np.array_equal(track.values_at(rows), expected[rows])


def test_a_refit_after_a_local_change_keeps_the_curve_elsewhere(motion):
    frames = 600
    x = np.linspace(0, 6, frames)
    values = np.stack((np.sin(x), np.cos(1.3 * x), 0.2 * x), axis=1)
    track = Track(0, 3, values, values, np.zeros(4), np.zeros(3))
    track.base_budget = 0.01
    track.budget = np.full(frames, 0.01)
    mandatory = np.array([0, frames - 1])
    fit_track(track, mandatory, 0.6, StepQuantizer.for_range)
    track.fitted = Fitted.of(track)
    curve = _track_recon(track).copy()
    assert np.array_equal(untouched_keys(track), track.keys)  # nothing changed: every key stays
    bumped = values.copy()
    bumped[295:310, 0] += 0.05 * np.hanning(15)  # the target moves on a few frames
    track.values = track.target = bumped
    keep = untouched_keys(track)
    assert 0 < len(keep) < len(track.keys)
    fit_track(track, mandatory, 0.6, StepQuantizer.for_range, keep=keep)
    after = _track_recon(track)
    assert np.all(np.linalg.norm(after - bumped, axis=1) <= track.budget)
    changed = np.flatnonzero(np.any(after != curve, axis=1))
    # A key dropped next to the change moves the curve up to two keys on: the second kept key.
    assert changed.size and changed.min() >= keep[keep < 295][-2] and changed.max() <= keep[keep > 309][1]
    assert changed.max() - changed.min() < 300


def _joined(m: Motion, copies: int) -> Motion:
    """``copies`` of ``m`` end to end (its frame 0, a T-pose, dropped after the first)."""
    body = m.slice(1, m.frame_count)
    parts = [m] + [body] * (copies - 1)
    return Motion(m.skeleton, np.concatenate([p.rotations for p in parts]),
                  np.concatenate([p.translations for p in parts]), m.frame_time, f"{m.name}_x{copies}",
                  scales=np.concatenate([p.scales for p in parts]))


def test_a_clip_joined_from_copies_needs_no_more_repairs_than_one(sample_paths):
    # 07_01 at 1 cm: one copy takes 1 repair; ten, 2 with local refits, 6 without (and a
    # 20-minute capture 60 and more, each over every frame).
    m = read_bvh(sample_paths[1])
    units = [resolve_units(m.skeleton, "cmu", None)]
    one = encode_motions([m], units, "rma", Tolerance(1.0)).clips[0].stats["repairs"]
    result = encode_motions([_joined(m, 10)], units, "rma", Tolerance(1.0))  # checked by the C runtime
    assert result.clips[0].stats["repairs"] <= one + 1, (one, result.clips[0].stats)
    assert result.clips[0].frames == 10 * m.frame_count - 9
    assert result.clips[0].error.max_cm <= 1.0
