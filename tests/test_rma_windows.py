"""rma's fit of a long clip a window of frames at a time (encoder/mocodec/codecs/rma_windows.py,
issue 16 §2): windows that cover the clip and meet at seams on key cells, sample clips forced
through small windows within the tolerance on every frame and close to the whole fit's bytes,
keys that join at every seam, a twist that goes round in one parameterisation, a halved step
that refits the clip, and the setting's bad values."""
from __future__ import annotations

import numpy as np
import pytest

from mocodec import rotations as R
from mocodec.codecs import rma_windows
from mocodec.codecs.rma import RMAFitter, RMASettings, section_prefix
from mocodec.codecs.rma_reference import decode_keys, decode_payload
from mocodec.codecs.rma_windows import SEAM, fit_windowed, window_bounds
from mocodec.encode import _single_clip_asset, encode_motions, evaluate, make_check
from mocodec.io import read_bvh
from mocodec.keyframes import KIND_TWIST, fit_clip
from mocodec.motion import Motion, Skeleton
from mocodec.runtime import Asset
from mocodec.tolerance import Tolerance, ToleranceNotMet
from mocodec.units import resolve_units


@pytest.mark.parametrize("frames, window, grid", [(1000, 100, 1), (1000, 100, 4), (4097, 4096, 8), (50, 16, 2),
                                                  (864_000, 4096, 4), (100, 100, 1), (17, 16, 8), (20, 16, 8)])
def test_windows_cover_the_clip_and_meet_at_seams_on_key_cells(frames, window, grid):
    bounds = window_bounds(frames, window, grid)
    assert bounds[0][0] == 0 and bounds[-1][1] == frames
    if frames <= window:
        assert bounds == [(0, frames)]
    for (a, b), (c, d) in zip(bounds, bounds[1:]):
        assert b - c == SEAM and d > b  # the three frames around the seam c + 1, in both
        assert c > a + 1  # frames 0 and 1 (a detached first segment) in window 0 alone
        assert c % grid == 0  # the window after starts on a cell boundary (cells start at 1 mod grid)
    assert max(b - a for a, b in bounds) <= window + SEAM + grid


def test_a_seam_rounded_onto_the_clip_start_is_left_out():
    # 17 frames in windows of 16 on 8-frame cells: the only seam would round to frame 1, and a
    # window starting at frame 0 again (without the detached first segment) would check a
    # curve the asset does not have.
    assert window_bounds(17, 16, 8) == [(0, 17)]


def _fit(m: Motion, tolerance: float, window: int | None):
    cm = resolve_units(m.skeleton, "cmu").cm_per_unit
    settings = RMASettings(Tolerance(tolerance))
    check = make_check([m], [cm], "rma").one_clip(0, section_prefix(1))
    if window is None:
        return fit_clip(m, cm, settings, check, RMAFitter), cm
    return fit_windowed(m, cm, settings, check, window), cm


def _errors(m: Motion, cm: float, payload: bytes):
    asset = _single_clip_asset(m, cm, "rma", payload, section_prefix(1))
    (report,) = evaluate(asset, [m], [resolve_units(m.skeleton, "cmu")])
    return asset, report


@pytest.mark.parametrize("tolerance", [1.0, 0.1])
def test_sample_clips_fitted_in_windows_keep_the_tolerance_and_join_at_every_seam(sample_paths, tolerance):
    for path in sample_paths:
        m = read_bvh(path)
        window = 128
        whole, cm = _fit(m, tolerance, None)
        result, _ = _fit(m, tolerance, window)
        bounds = window_bounds(m.frame_count, window, RMASettings(Tolerance(tolerance)).key_grid)
        assert result.stats["windows"] == len(bounds) > 1
        asset, report = _errors(m, cm, result.payload)
        assert report.max_cm <= tolerance + 1e-9, (path.name, report.max_cm)
        # A seam costs about two keys a track: a few % at windows this small.
        assert len(result.payload) <= 1.15 * len(whole.payload), (path.name, len(result.payload), len(whole.payload))
        _, tracks = decode_keys(result.payload)
        assert len(tracks) == result.stats["tracks"]
        for start, _ in bounds[1:]:
            seam = np.arange(start, start + SEAM)
            for t in tracks:
                assert np.isin(seam, t["frames"]).all(), (path.name, start)
        # The Python reference reads the joined payload as the runtime does.
        frames = np.arange(m.frame_count)
        rot, trans, _ = decode_payload(result.payload, m.skeleton, frames)
        c_rot, c_trans = Asset(asset).sample_frames(0, frames)
        sign = np.sign(np.sum(c_rot * rot, axis=-1, keepdims=True))
        assert np.abs(c_rot - sign * rot).max() <= 1e-5
        assert np.abs(c_trans - trans).max() <= 1e-3


def test_a_windowed_fit_is_deterministic_and_each_window_starts_from_the_keys_before(sample_paths, monkeypatch):
    m = read_bvh(sample_paths[0])
    seen = []
    run = rma_windows.WindowFitter.run

    def spy(self, scale, check):
        out = run(self, scale, check)
        seen.append((self.start, {k: (np.asarray(t.keys) + self.start, t.quantizer.encode(t.key_values))
                                  for k, t in self.tracks.items()}))
        return out
    monkeypatch.setattr(rma_windows.WindowFitter, "run", spy)
    first, _ = _fit(m, 1.0, 80)
    again, _ = _fit(m, 1.0, 80)
    assert first.payload == again.payload
    windows = seen[:len(seen) // 2]
    for (_, before), (start, after) in zip(windows, windows[1:]):
        for key, (frames, q) in after.items():
            assert np.array_equal(frames[:SEAM], np.arange(start, start + SEAM))
            assert np.array_equal(before[key][0][-SEAM:], frames[:SEAM])
            assert np.array_equal(before[key][1][-SEAM:], q[:SEAM]), key


def _turning_clip(frames: int = 1500) -> Motion:
    """A root turning round six times about up while it bobs, and an arm swinging below it: a
    twist track whose angle passes many turns, across many windows."""
    sk = Skeleton(["Hips", "Arm", "Arm_End"], [-1, 0, 1], [[0, 90, 0], [0, 10, 0], [0, 30, 0]],
                  [(0, 1, 2, 5, 3, 4), (5, 3, 4), ()], [False, False, True])
    f = np.arange(frames, dtype=np.float64)
    yaw = 12.0 * np.pi * f / frames
    tilt = np.radians(10.0) * np.sin(2.0 * np.pi * f / 90.0)
    rot = np.tile([0.0, 0.0, 0.0, 1.0], (frames, 3, 1))
    rot[:, 0] = R.quat_multiply(R.quat_from_axis_angle(np.array([0.0, 1.0, 0.0]), yaw),
                                R.quat_from_axis_angle(np.array([1.0, 0.0, 0.0]), tilt))
    rot[:, 1] = R.quat_from_axis_angle(np.array([0.0, 0.0, 1.0]), np.radians(40.0) * np.sin(2.0 * np.pi * f / 70.0))
    trans = np.broadcast_to(sk.offsets, (frames, 3, 3)).copy()
    trans[:, 0, 0] = 50.0 * np.sin(2.0 * np.pi * f / 400.0)
    return Motion(sk, rot, trans, 1.0 / 120.0, "turning")


def test_a_root_turning_round_keeps_one_twist_across_windows():
    m = _turning_clip()
    whole, cm = _fit(m, 0.5, None)
    result, _ = _fit(m, 0.5, 100)
    assert result.stats["windows"] == 15
    _, report = _errors(m, cm, result.payload)
    assert report.max_cm <= 0.5 + 1e-9
    _, tracks = decode_keys(result.payload)
    assert tracks[0]["kind"] == KIND_TWIST
    assert len(result.payload) <= 1.2 * len(whole.payload)


def test_a_step_halved_in_a_later_window_puts_the_keys_before_on_the_finer_lattice(sample_paths, monkeypatch):
    """The format keeps one step a track: a window that needs a finer one (half, exactly, in
    binary32) has the keys of the windows before doubled onto it (the same values), and its
    frozen keys decode as they did, so the window's own fit stands."""
    import mocodec.keyframes

    m = read_bvh(sample_paths[0])
    fit_keys = mocodec.keyframes.fit_keys
    calls = {"n": 0}

    def fails_once(*args, **kw):  # the 40th fit (in window 1, which has frozen keys) reports a key frame over budget
        keys, values, ok = fit_keys(*args, **kw)
        calls["n"] += 1
        return keys, values, ok and calls["n"] != 40
    monkeypatch.setattr(mocodec.keyframes, "fit_keys", fails_once)
    result, cm = _fit(m, 1.0, 64)
    assert result.stats["steps_halved"] == 1 and result.stats["window_rounds"] == 1
    _, report = _errors(m, cm, result.payload)
    assert report.max_cm <= 1.0 + 1e-9
    _, tracks = decode_keys(result.payload)
    monkeypatch.setattr(mocodec.keyframes, "fit_keys", fit_keys)
    plain, _ = _fit(m, 1.0, 64)
    assert plain.stats["steps_halved"] == 0
    _, plain_tracks = decode_keys(plain.payload)
    halved = [(a, b) for a, b in zip(tracks, plain_tracks) if not np.array_equal(a["steps"], b["steps"])]
    assert len(halved) == 1
    finer, coarse = halved[0]
    assert np.array_equal(finer["steps"] * 2, coarse["steps"])
    # Window 0's keys are the same keys on the finer lattice: twice the integers.
    first = window_bounds(m.frame_count, 64, RMASettings(Tolerance(1.0)).key_grid)[1][0]
    before = finer["frames"] < first
    assert np.array_equal(finer["frames"][before], coarse["frames"][coarse["frames"] < first])
    assert np.array_equal(finer["q"][before], 2 * coarse["q"][coarse["frames"] < first])


@pytest.mark.parametrize("tolerance, window", [(1.0, 16), (1.0, 32), (0.1, 24), (0.1, 48)])
def test_a_gltf_rig_with_rest_rotations_and_scales_halving_steps_in_windows_keeps_the_tolerance(
        repo_root, tolerance, window):
    """A glTF rig (rest rotations that are not the identity, scale tracks, 77 nodes) whose
    windows halve steps where keys are frozen: each such window keeps the frozen keys' values,
    and the clip meets the tolerance in one round."""
    from mocodec.io.gltf import read_gltf

    (m,) = read_gltf(repo_root / "encoder" / "mocodec" / "samples" / "gltf" / "Luanti_spider_animated.gltf")
    units = resolve_units(m.skeleton)
    settings = RMASettings(Tolerance(tolerance))
    check = make_check([m], [units.cm_per_unit], "rma").one_clip(0, section_prefix(1))
    result = fit_windowed(m, units.cm_per_unit, settings, check, window)
    assert result.stats["steps_halved"] > 0 and result.stats["window_rounds"] == 1
    asset = _single_clip_asset(m, units.cm_per_unit, "rma", result.payload, section_prefix(1))
    (report,) = evaluate(asset, [m], [units])
    assert report.max_cm <= tolerance + 1e-9


def test_a_long_clip_is_fitted_in_windows_through_encode_and_a_short_one_whole(sample_paths, monkeypatch):
    import mocodec.kinematics

    m = read_bvh(sample_paths[1])
    units = [resolve_units(m.skeleton, "cmu")]
    whole = encode_motions([m], units, "rma", Tolerance(1.0), {"window_frames": 100})
    assert "windows" not in whole.clips[0].stats  # short: fitted whole, whatever the setting
    monkeypatch.setattr(mocodec.kinematics, "SHORT_CLIP_BYTES", -1)
    long = encode_motions([m], units, "rma", Tolerance(1.0), {"window_frames": 100})
    assert long.clips[0].stats["windows"] == len(window_bounds(m.frame_count, 100, 4)) > 1
    assert long.max_error_cm <= 1.0


def test_a_long_clip_encoded_in_this_process_shows_its_windows_as_it_goes(sample_paths, monkeypatch):
    import io

    import mocodec.kinematics
    from mocodec.bake import make_runner
    from mocodec.bake.progress import Progress, report_within

    m = read_bvh(sample_paths[1])
    units = [resolve_units(m.skeleton, "cmu")]
    monkeypatch.setattr(mocodec.kinematics, "SHORT_CLIP_BYTES", -1)
    stream = io.StringIO()
    progress = Progress(1, stream=stream, bar=False, within_every=0.0)  # one clip: no count, but its windows
    with make_runner(1) as runner:
        out = encode_motions([m], units, "rma", Tolerance(1.0), {"window_frames": 100, "budget_scales": (1.0, 0.75)},
                             progress=progress, runner=runner)
    n = out.clips[0].stats["windows"]
    lines = stream.getvalue().splitlines()
    assert lines[0].startswith(f"  {m.name}: window 1 of {n}, budget 1 of 2")  # (", fit 2" if a step halved)
    assert any(f"window {n} of {n}, budget 2 of 2" in line for line in lines)
    assert len(lines) >= 2 * n  # every window of both budgets (nothing throttled at 0 s)
    quiet = io.StringIO()
    progress = Progress(1, enabled=False, stream=quiet, bar=False, within_every=0.0)
    with make_runner(1) as runner:
        encode_motions([m], units, "rma", Tolerance(1.0), {"window_frames": 100}, progress=progress, runner=runner)
    assert quiet.getvalue() == ""
    report_within("nobody watching")  # outside a clip: nothing, no error


def test_progress_within_a_clip_waits_its_interval():
    import io

    from mocodec.bake.progress import Progress

    stream = io.StringIO()
    p = Progress(1, stream=stream, bar=False, within_every=3600.0)
    p.started("walk")
    p.within("walk", "window 1 of 9")
    assert stream.getvalue() == ""  # not an hour since the start
    p.within_every = 0.0
    p.within("walk", "window 2 of 9")
    assert stream.getvalue().startswith("  walk: window 2 of 9 (")


def test_the_bar_shows_a_clips_windows_beside_its_worker():
    import io

    from mocodec.bake.progress import Progress

    stream = io.StringIO()
    p = Progress(2, stream=stream, bar=True, within_every=0.0)
    p.started("walk")
    p.hit("idle")
    p.within("walk", "window 3 of 9")
    assert p._bar is not None and "w1 walk: window 3 of 9  (1 cached)" in stream.getvalue()
    p("walk")
    assert p._bar is None


@pytest.mark.parametrize("value", [15, 0, -4])
def test_window_frames_below_sixteen_is_refused(value):
    with pytest.raises(ValueError, match="window_frames must be at least 16"):
        RMASettings(Tolerance(1.0), window_frames=value)


def test_tracks_that_barely_leave_rest_stay_at_rest_in_every_window(repo_root):
    """A glTF rig whose tracks mostly leave their rest by float noise (RiggedFigure: 57 tracks
    stored, 3 keyed by the whole fit): the windows leave those at rest for the whole clip, as
    the whole fit folds them, rather than key each in every window."""
    from mocodec.io.gltf import read_gltf

    (m,) = read_gltf(repo_root / "encoder" / "mocodec" / "samples" / "gltf" / "RiggedFigure.glb")
    units = resolve_units(m.skeleton)
    settings = RMASettings(Tolerance(1.0))
    check = make_check([m], [units.cm_per_unit], "rma").one_clip(0, section_prefix(1))
    whole = fit_clip(m, units.cm_per_unit, settings, check, RMAFitter)
    result = fit_windowed(m, units.cm_per_unit, settings, check, 16)
    assert result.stats["windows"] == 2 and result.stats["at_rest"] >= 50
    assert len(result.payload) <= 1.3 * len(whole.payload)
    asset = _single_clip_asset(m, units.cm_per_unit, "rma", result.payload, section_prefix(1))
    (report,) = evaluate(asset, [m], [units])
    assert report.max_cm <= 1.0 + 1e-9


def _curled_finger(curl_share: float) -> Motion:
    """A root that moves and turns, and a chain of five short joints each curled by
    ``curl_share`` of its rotation budget (and a wiggle far smaller): every joint is near its
    rest alone, but the curls add up along the chain, and a joint left at rest compensates
    nothing below it."""
    from mocodec.clip_plan import plan_clip
    from mocodec.tolerance import initial_budgets

    n = 6
    sk = Skeleton(["Hips"] + [f"J{i}" for i in range(1, n)] + ["End"], [-1] + list(range(n)),
                  [[0, 90, 0]] + [[0, 3, 0]] * n, [(0, 1, 2, 5, 3, 4)] + [(5, 3, 4)] * (n - 1) + [()],
                  [False] * n + [True])
    frames = 400
    f = np.arange(frames, dtype=np.float64)
    rot = np.tile([0.0, 0.0, 0.0, 1.0], (frames, n + 1, 1))
    trans = np.broadcast_to(sk.offsets, (frames, n + 1, 3)).copy()
    trans[:, 0, 0] = 50.0 * np.sin(2 * np.pi * f / 200)
    rot[:, 0] = R.quat_from_axis_angle(np.array([0.0, 1.0, 0.0]), 0.5 * np.sin(2 * np.pi * f / 150))
    units = resolve_units(sk, "cmu")
    settings = RMASettings(Tolerance(1.0))
    plan = plan_clip(Motion(sk, rot, trans, 1 / 120, "finger"), units.cm_per_unit, settings.shell_cm)
    budgets = initial_budgets(plan.reach, settings.tolerance.per_node_cm(sk) / units.cm_per_unit,
                              settings.budget_scales[0])
    for k, i in enumerate(plan.track_nodes):
        if i >= 1:
            angle = curl_share * budgets[k] * (1.0 + 0.001 * np.sin(f / 7))
            rot[:, i] = R.quat_from_axis_angle(np.array([0.0, 0.0, 1.0]), angle)
    return Motion(sk, rot, trans, 1 / 120, "finger")


@pytest.mark.parametrize("curl_share", [0.1, 0.3, 0.45])
def test_joints_near_rest_that_add_up_along_a_chain_are_keyed(curl_share):
    """Each curl is within half its budget of rest, yet left at rest together they move the end
    past the tolerance: the clip checks that in world space before leaving any at rest (the
    first rule, per track alone, left the windows unable to meet the tolerance)."""
    from mocodec.codecs.rma_windows import near_rest, rest_tracks
    from mocodec.clip_plan import plan_clip
    from mocodec.tolerance import initial_budgets

    m = _curled_finger(curl_share)
    units = resolve_units(m.skeleton, "cmu")
    settings = RMASettings(Tolerance(1.0))
    plan = plan_clip(m, units.cm_per_unit, settings.shell_cm)
    tol = settings.tolerance.per_node_cm(m.skeleton) / units.cm_per_unit
    budgets = initial_budgets(plan.reach, tol, settings.budget_scales[0])
    assert near_rest(m, plan, budgets).sum() == 5
    assert rest_tracks(m, plan, tol, budgets).sum() < 5
    result, cm = _fit(m, 1.0, 64)
    _, report = _errors(m, cm, result.payload)
    assert report.max_cm <= 1.0 + 1e-9


def test_a_window_that_cannot_meet_the_tolerance_with_tracks_at_rest_has_them_fitted(sample_paths, monkeypatch):
    """Should tracks left at rest keep a window from the tolerance, the clip is fitted again
    with every track keyed."""
    from mocodec.clip_plan import ROT

    m = read_bvh(sample_paths[0])
    rest = rma_windows.rest_tracks

    def root_at_rest(motion, plan, tol, budgets):  # the root's rotation: far from rest
        out = rest(motion, plan, tol, budgets)
        out[[k for k, (i, p) in enumerate(zip(plan.track_nodes, plan.track_parts)) if i == 0 and p == ROT]] = True
        return out
    monkeypatch.setattr(rma_windows, "rest_tracks", root_at_rest)
    result, cm = _fit(m, 1.0, 128)
    assert result.stats["at_rest"] == 0
    _, report = _errors(m, cm, result.payload)
    assert report.max_cm <= 1.0 + 1e-9


def test_keys_put_on_a_finer_lattice_past_two_to_the_thirty_steps_are_refused():
    j = rma_windows._Joined(0, 3, np.zeros(3, np.int16), None, np.full(3, 4.0),
                            [np.array([0, 5], np.int32)], [np.array([[1, 2, 3], [(1 << 29) + 1, 0, 0]], np.int32)])
    with pytest.raises(ToleranceNotMet, match="past 2\\*\\*30"):
        j.refine(np.full(3, 1.0))  # four times finer: 2**31 + 4 would wrap in int32
    assert j.refine(np.full(3, 4.0)) and j.q[0][1, 0] == (1 << 29) + 1  # the same step: nothing changes
    assert not j.refine(np.full(3, 3.0))  # not a power of two finer
