"""The metrics every codec and benchmark uses."""
from __future__ import annotations

import numpy as np
import pytest

from mocodec.io import read_bvh
from mocodec.kinematics import forward_kinematics
from mocodec.metrics import ErrorMetric, combine, size_report
from mocodec.rotations import quat_from_axis_angle, quat_multiply


def _world(m):
    return forward_kinematics(m.skeleton, m.rotations, m.translations)


def test_identical_motion_has_no_error(sample_paths):
    m = read_bvh(sample_paths[0])
    w = _world(m)
    r = ErrorMetric(5.6444, 25.0).evaluate(m.skeleton, w, w, m.rotations, m.rotations)
    assert r.max_cm == 0 and r.mean_cm == 0 and r.shell_max_cm == 0
    assert r.angle_max_deg < 1e-9
    assert r.fraction_under(0.0) == 1.0


def test_known_offset_gives_known_errors(sample_paths):
    m = read_bvh(sample_paths[0])
    rot, pos = _world(m)
    shifted = pos.copy()
    shifted[:, 5] += [1.0, 0.0, 0.0]      # one node one unit off on every frame
    shifted[10, 7] += [0.0, 2.0, 0.0]     # another two units off on one frame
    metric = ErrorMetric(cm_per_unit=2.0, height_units=100.0)
    r = metric.evaluate(m.skeleton, (rot, pos), (rot, shifted))
    n, f = m.skeleton.node_count, m.frame_count
    assert r.max_cm == pytest.approx(4.0)
    assert (r.worst_frame, r.worst_node) == (10, 7)
    assert r.per_node_max_cm[5] == pytest.approx(2.0)
    # seed 000 eq. 25-26: mean over frames per joint, then over joints.
    assert r.mean_cm == pytest.approx((2.0 + 4.0 / f) / n)
    assert r.max_pct_height == pytest.approx(2.0)
    assert r.fraction_under(1.0) == pytest.approx(1 - (f + 1) / (f * n))


def test_shell_metric_sees_rotation_error(sample_paths):
    """A rotation error with no position error shows in the shell metric: a vertex 3 cm
    away moves by 2 * 3 cm * sin(angle / 2)."""
    m = read_bvh(sample_paths[0])
    rot, pos = _world(m)
    angle = np.radians(10)
    turned = rot.copy()
    turned[:, 3] = quat_multiply(rot[:, 3], quat_from_axis_angle(np.array([0.0, 0.0, 1.0]), angle))
    r = ErrorMetric(5.6444, 25.0, shell_cm=3.0).evaluate(m.skeleton, (rot, pos), (turned, pos))
    assert r.max_cm == 0
    assert r.shell_max_cm == pytest.approx(2 * 3.0 * np.sin(angle / 2), rel=1e-6)


def test_sizes_in_both_conventions(sample_paths):
    ms = [read_bvh(p) for p in sample_paths]
    s = size_report(ms, 10_000)
    frames = sum(m.frame_count for m in ms)
    assert s.raw_bvh_bytes == frames * 96 * 4
    assert s.raw_acl_bytes == frames * 38 * 40
    assert s.ratio_bvh == pytest.approx(frames * 96 * 4 / 10_000)
    assert s.bytes_per_second == pytest.approx(10_000 / sum(m.frame_count * m.frame_time for m in ms))


def test_combine_over_clips(sample_paths):
    ms = [read_bvh(p) for p in sample_paths[:2]]
    reports = []
    for k, m in enumerate(ms):
        rot, pos = _world(m)
        off = pos.copy()
        off[:, 0, 0] += k + 1.0
        reports.append(ErrorMetric(1.0, 25.0).evaluate(m.skeleton, (rot, pos), (rot, off)))
    c = combine(reports)
    assert c["max_cm"] == pytest.approx(2.0)


def _turned_and_moved(m):
    """World rotations and positions of ``m``, and a decoding of it: node 3 turned 3 degrees,
    every point moved further as the clip goes on (its local rotations too)."""
    rot, pos = _world(m)
    turned = rot.copy()
    turned[:, 3] = quat_multiply(rot[:, 3], quat_from_axis_angle(np.array([0.0, 0.0, 1.0]), np.radians(3)))
    off = pos + np.linspace(0.0, 0.5, m.frame_count)[:, None, None]
    local = m.rotations.copy()
    local[:, 3] = turned[:, 3]
    return rot, pos, turned, off, local


def test_chunked_evaluation_gives_the_whole_clips_figures(sample_paths):
    """A clip given a run of frames at a time gives the same figures as given whole (the shell
    and angle means up to the last bits: running sums)."""
    m = read_bvh(sample_paths[0])
    rot, pos, turned, off, local = _turned_and_moved(m)
    metric = ErrorMetric(5.6444, 25.0)
    whole = metric.evaluate(m.skeleton, (rot, pos), (turned, off), m.rotations, local)
    runs = [slice(a, min(a + 97, m.frame_count)) for a in range(0, m.frame_count, 97)]
    assert len(runs) > 3
    r = metric.evaluate_chunks(m.skeleton, (((rot[s], pos[s]), (turned[s], off[s]), m.rotations[s], local[s])
                                            for s in runs))
    assert (r.max_cm, r.p99_cm, r.mean_cm, r.worst_frame, r.worst_node, r.samples) == \
        (whole.max_cm, whole.p99_cm, whole.mean_cm, whole.worst_frame, whole.worst_node, whole.samples)
    assert np.array_equal(r.errors_cm, whole.errors_cm)
    assert np.array_equal(r.per_node_mean_cm, whole.per_node_mean_cm)
    assert (r.shell_max_cm, r.angle_max_deg) == (whole.shell_max_cm, whole.angle_max_deg)
    assert r.shell_mean_cm == pytest.approx(whole.shell_mean_cm, rel=1e-12)
    assert r.angle_mean_deg == pytest.approx(whole.angle_mean_deg, rel=1e-12) and whole.angle_mean_deg > 0


@pytest.mark.parametrize("samples", [2, 3, 37, 100, 101, 1000, 4096, 99_991])
def test_summarised_errors_have_the_whole_figures(samples: int) -> None:
    """A long clip's errors summarised a run at a time (ErrorMetric.evaluate_chunks given the
    frame count) give the bits the whole array gives: p99 by numpy's linear rule from the
    largest samples alone, per-node means in numpy's order, the first worst sample."""
    from mocodec.metrics import _RunningErrors

    rng = np.random.default_rng(samples)
    nodes = 2 if samples % 4 else 4  # (one node's column numpy sums pairwise: kept, not summarised)
    frames = samples // nodes
    err = rng.gamma(2.0, 0.3, (frames, nodes))
    err[rng.integers(0, frames, 3), 0] = err.max()  # ties for the worst: the first one counts
    err[: frames // 3] = np.round(err[: frames // 3], 1)  # many equal values around the p99
    if samples == 1000:
        err[frames // 2, 1] = np.nan  # a NaN: numpy's figures are NaN, and it is the worst sample
    if samples == 4096:
        err = np.asfortranarray(err)  # runs given node-major: the same sums as frame-major
    running = _RunningErrors(err.size)
    for a in range(0, frames, 97):
        running.add(err[a:a + 97])
    same = (lambda a, b: a == b or np.isnan(a) and np.isnan(b))
    assert same(running.p99(), float(np.percentile(err, 99)))
    assert np.array_equal(running.sums / running.rows, np.ascontiguousarray(err).mean(axis=0), equal_nan=True)
    assert running.worst == divmod(int(np.argmax(np.ascontiguousarray(err))), nodes)
    assert same(running.max(), float(err.max()))
    assert np.array_equal(running.maxima, err.max(axis=0), equal_nan=True)


def test_summarised_report_is_the_kept_report(sample_paths) -> None:
    """evaluate_chunks with the frame count: every figure the same as with the errors kept,
    and no (F, N) errors held."""
    m = read_bvh(sample_paths[0])
    rot, pos, turned, off, local = _turned_and_moved(m)
    metric = ErrorMetric(5.6444, 25.0)
    runs = [slice(a, min(a + 97, m.frame_count)) for a in range(0, m.frame_count, 97)]

    c = np.ascontiguousarray  # frame-major, as the runtime decodes (the encoder's evaluation)

    def chunks():
        return (((rot[s], c(pos[s])), (turned[s], c(off[s])), m.rotations[s], local[s]) for s in runs)
    kept = metric.evaluate_chunks(m.skeleton, chunks())
    summed = metric.evaluate_chunks(m.skeleton, chunks(), m.frame_count)
    assert summed.errors_cm is None
    for name in ("max_cm", "p99_cm", "mean_cm", "worst_frame", "worst_node", "samples", "shell_max_cm",
                 "shell_mean_cm", "angle_mean_deg", "angle_max_deg"):
        assert getattr(summed, name) == getattr(kept, name), name
    assert np.array_equal(summed.per_node_mean_cm, kept.per_node_mean_cm)
    assert np.array_equal(summed.per_node_max_cm, kept.per_node_max_cm)
    with pytest.raises(ValueError, match="summarised"):
        summed.fraction_under(1.0)
    assert combine([summed])["p99_cm"] == kept.p99_cm
    louder = ErrorMetric(5.6444 * 2, 25.0).evaluate_chunks(m.skeleton, chunks())
    both = combine([summed, louder])
    assert both["p99_cm"] == louder.p99_cm > summed.p99_cm  # the largest clip p99
    assert both["max_cm"] == louder.max_cm
