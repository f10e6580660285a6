"""The whole-clip plan the key-frame fitter starts from (mocodec.clip_plan): the same plan
whether the clip's poses are held or measured a run of frames at a time, zero-length bones
skipped when aiming, tracks at rest not stored, and a fitter given a plan makes the asset it
makes when it measures the plan itself."""
from __future__ import annotations

import numpy as np
import pytest

import mocodec.clip_plan
import mocodec.keyframes
import mocodec.motion
from mocodec import rotations as R
from mocodec.clip_plan import ROT, TRANS, ClipPlan, plan_clip
from mocodec.codecs.rma import RMAFitter, RMASettings, section_prefix
from mocodec.encode import make_check
from mocodec.io import read_bvh
from mocodec.keyframes import fit_clip
from mocodec.kinematics import world_positions
from mocodec.motion import Motion, Skeleton
from mocodec.tolerance import Tolerance


def _same(a: ClipPlan, b: ClipPlan) -> None:
    assert (a.frames, a.track_nodes, a.track_parts, a.aim) == (b.frames, b.track_nodes, b.track_parts, b.aim)
    assert a.spans == b.spans
    assert np.array_equal(a.stored, b.stored)
    for name in ("affects", "lever", "is_rotation"):
        assert np.array_equal(getattr(a.reach, name), getattr(b.reach, name))
    assert (a.held is None) == (b.held is None)
    if a.held is not None:
        assert np.array_equal(a.held, b.held)


def _chain(frames: int) -> Motion:
    """Hips -> Spine -> Knot (a zero-length bone) -> Arm -> end site; the Knot has rotation
    channels but stays at rest, Arm swings, Hips moves."""
    sk = Skeleton(["Hips", "Spine", "Knot", "Arm", "Arm_End"], [-1, 0, 1, 2, 3],
                  [[0, 90, 0], [0, 10, 0], [0, 0, 0], [0, 8, 0], [0, 20, 0]],
                  [(0, 1, 2, 5, 3, 4), (5, 3, 4), (5, 3, 4), (5, 3, 4), ()], [False] * 4 + [True])
    f = np.arange(frames, dtype=np.float64)
    rot = np.tile([0.0, 0.0, 0.0, 1.0], (frames, 5, 1))
    rot[:, 1] = R.quat_from_axis_angle(np.array([1.0, 0.0, 0.0]), 0.3 * np.sin(f / 9.0))
    rot[:, 3] = R.quat_from_axis_angle(np.array([0.0, 0.0, 1.0]), 0.8 * np.sin(f / 5.0))
    rot[:, 2] *= -1.0  # the rest rotation's negation on every frame: still at rest
    trans = np.broadcast_to(sk.offsets, (frames, 5, 3)).copy()
    trans[:, 0, 0] = 0.5 * f
    return Motion(sk, rot, trans, 1.0 / 120.0, "chain")


def test_runs_give_the_held_plan(monkeypatch: pytest.MonkeyPatch, sample_paths: list) -> None:
    m = read_bvh(sample_paths[0])
    held = plan_clip(m, 2.54, 1.0, world_positions(m), halfway=True)
    monkeypatch.setattr(mocodec.clip_plan, "SPAN_CHUNK", 97)
    monkeypatch.setattr(mocodec.motion, "FRAME_RUN", 89)
    assert m.frame_count > 3 * 97
    _same(plan_clip(m, 2.54, 1.0, None, halfway=True), held)


def test_zero_length_bone_is_aimed_through() -> None:
    m = _chain(600)
    plan = plan_clip(m, 1.0, 1.0, halfway=False)
    spine, knot, arm = 1, 2, 3
    assert plan.spans[(spine, knot)] == 0.0
    assert plan.aim[spine] == [arm]  # the knot sits on the spine: the spine aims the arm
    assert plan.spans[(spine, arm)] == pytest.approx(8.0)
    assert plan.held is None
    row = plan.track_nodes.index(spine)
    assert plan.reach.lever[row, arm] == pytest.approx(8.0)
    assert plan.reach.lever[row, 4] == pytest.approx(8.0)  # the arm's subtree moves with it


def test_tracks_at_rest_are_not_stored(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(mocodec.motion, "FRAME_RUN", 64)
    m = _chain(600)
    m.rotations[590, 0] = R.quat_from_axis_angle(np.array([0.0, 1.0, 0.0]), 0.2)  # one late frame
    plan = plan_clip(m, 1.0, 1.0)
    stored = {(n, p): bool(s) for n, p, s in zip(plan.track_nodes, plan.track_parts, plan.stored)}
    assert stored[(2, ROT)] is False  # the rest's negation on every frame
    assert stored[(0, ROT)] is True  # leaves rest on frame 590 alone (a later run)
    assert stored[(0, TRANS)] is True and stored[(1, ROT)] is True and stored[(3, ROT)] is True


def test_a_given_plan_makes_the_same_asset(sample_paths: list, monkeypatch: pytest.MonkeyPatch) -> None:
    m = read_bvh(sample_paths[1])
    settings = RMASettings(tolerance=Tolerance(1.0))
    cm = 2.54
    plan = plan_clip(m, cm, settings.shell_cm, world_positions(m), halfway=settings.halfway_factor > 0)
    runtime, prefix = make_check([m], [cm], "rma"), section_prefix(1)

    def check(payload: bytes, **how: object) -> object:
        return runtime(0, payload, prefix, **how)
    measured = fit_clip(m, cm, settings, check, RMAFitter)

    def no_plan(*args: object, **kwargs: object) -> None:
        raise AssertionError("the fitter measured a plan it was given")
    monkeypatch.setattr(mocodec.keyframes, "plan_clip", no_plan)
    given = fit_clip(m, cm, settings, check, RMAFitter, plan)
    assert given.payload == measured.payload
    other = plan_clip(m.slice(0, m.frame_count - 1), cm, settings.shell_cm, halfway=True)
    with pytest.raises(ValueError, match="plan given is of a clip of"):
        fit_clip(m, cm, settings, check, RMAFitter, other)
    unheld = plan_clip(m, cm, settings.shell_cm, halfway=False)
    with pytest.raises(ValueError, match="without held intervals"):
        fit_clip(m, cm, settings, check, RMAFitter, unheld)
