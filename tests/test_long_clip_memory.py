"""Memory of a long clip's encode (issue 16: hours-long captures). The encoder's runtime check
(the originals and the half-way reference posed a run of frames at a time, only the rows over
the tolerance kept) and final evaluation sample a run of frames at a time and the key-frame
fitter keeps one decoded pose of the clip and its tracks (an MRP track's targets alone), so
encoding allocates a bounded multiple of the clip's raw float32 channels.
Counted by tracemalloc (numpy reports its buffers to it), which is exact and does not depend on
the allocator or the load, unlike the resident size."""
from __future__ import annotations

import tracemalloc

import pytest
from long_clip import CM_PER_UNIT, long_clip

from mocodec.encode import encode_motions
from mocodec.tolerance import Tolerance
from mocodec.units import resolve_units

FRAMES = 200_000  # 28 minutes at 120 fps, about 3 s to encode

# Allocated at the peak over the raw float32 channels. 3.84x since 2026-12-07, the clip fitted a
# window of 4,096 frames at a time (codecs/rma_windows.py): for this three-node clip (36 raw bytes
# a frame) the peak is the one whole-clip array left, a node's rotations (F, 4) float64 and
# their parameterisation's temporaries (about 128 bytes a frame); on a 38-node CMU skeleton the
# same arrays are a third of the raw channels. Before (2026-12-04, branch mem3): 5.76x with the
# half-way hold (on by default): no world positions held (posed along a target's chain, and a
# run at a time for the check), the check's errors only where over, budgets broadcast until
# tightened, a fit's state as marks, MRP values derived from the targets. Before: 8.1x (7.8x
# without the hold: half-way reference streamed per check, no world rotations held, curves,
# targets, roundtrips and poses built a run of frames at a time); 23.7x (2026-12-02); 32.0x
# before the check and evaluation were chunked and the fitter's pass held two poses.
MAX_PEAK_OVER_RAW = 4.5


def test_rma_encode_of_a_long_clip_allocates_a_bounded_multiple_of_its_raw_data():
    m = long_clip(FRAMES)
    raw = m.frame_count * m.skeleton.channel_count * 4
    units = resolve_units(m.skeleton, cm_per_unit=CM_PER_UNIT)
    tracemalloc.start()
    try:
        result = encode_motions([m], [units], "rma", Tolerance(1.0))
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert result.clips[0].error.max_cm <= 1.0
    assert peak / raw <= MAX_PEAK_OVER_RAW, f"peak {peak / 1e6:.0f} MB = {peak / raw:.1f}x the raw float32 channels"


# The whole-clip checks before the codec runs, and the final evaluation, over the same raw
# channels (2026-12-07): before, each held temporaries of the clip's size (validate's norms,
# the scale deviation, the translation limits: 2.7-4.8x at 24,000 CMU frames; the evaluation's
# shell and angle errors 4.4x); now the checks read runs of mocodec.motion.FRAME_RUN frames and
# the evaluation summarises the position errors as they come (1.59x here when it kept them whole,
# with np.percentile's copy; 0.97x since, mostly the frame numbers the runtime is asked for,
# 8 bytes a frame against this three-node clip's 36 raw).
MAX_CHECK_PEAK_OVER_RAW = 0.1
MAX_EVALUATE_PEAK_OVER_RAW = 1.2


def _peak(f):
    tracemalloc.start()
    try:
        base = tracemalloc.get_traced_memory()[0]
        out = f()
        return out, tracemalloc.get_traced_memory()[1] - base
    finally:
        tracemalloc.stop()


def test_the_whole_clip_checks_and_the_evaluation_of_a_long_clip_hold_little_beside_it():
    from mocodec import limits
    from mocodec.codecs import scale_deviation
    from mocodec.encode import evaluate

    m = long_clip(FRAMES)
    raw = m.frame_count * m.skeleton.channel_count * 4
    units = resolve_units(m.skeleton, cm_per_unit=CM_PER_UNIT)
    for name, check in [("validate", m.validate), ("check_motion", lambda: limits.check_motion(m)),
                        ("position_reach", lambda: limits.position_reach(m)),
                        ("scale_deviation", lambda: scale_deviation(m)), ("animated", m.animated)]:
        _, peak = _peak(check)
        assert peak / raw <= MAX_CHECK_PEAK_OVER_RAW, f"{name}: {peak / raw:.2f}x the raw float32 channels"
    asset = encode_motions([m], [units], "rma", Tolerance(1.0)).asset
    (report,), peak = _peak(lambda: evaluate(asset, [m], [units]))
    assert 0 < report.max_cm <= 1.0 and report.errors_cm is None and report.samples == FRAMES * m.skeleton.node_count
    assert peak / raw <= MAX_EVALUATE_PEAK_OVER_RAW, f"evaluate: {peak / raw:.2f}x the raw float32 channels"


@pytest.mark.parametrize("codec", ["rma", "spline"])
def test_the_streamed_long_clip_path_writes_the_short_paths_bytes(sample_paths, monkeypatch, codec):
    """A long clip's encode streams what a short one holds whole (world rotations, the half-way
    reference) and works a run of frames at a time; forced onto that path with runs of 97
    frames, a sample clip's asset is the same bytes."""
    import mocodec.clip_plan
    import mocodec.curves
    import mocodec.keyframes
    import mocodec.kinematics
    import mocodec.motion
    import mocodec.quantize
    import mocodec.runtime
    import mocodec.tolerance
    from mocodec.io import read_bvh

    m = read_bvh(sample_paths[0])
    units = [resolve_units(m.skeleton, "cmu")]
    short = encode_motions([m], units, codec, Tolerance(1.0)).asset
    monkeypatch.setattr(mocodec.kinematics, "SHORT_CLIP_BYTES", -1)
    for module, name in [(mocodec.curves, "CURVE_CHUNK"), (mocodec.keyframes, "TARGET_CHUNK"),
                         (mocodec.clip_plan, "SPAN_CHUNK"),
                         (mocodec.kinematics, "HALFWAY_CHUNK"), (mocodec.kinematics, "POSE_CHUNK"),
                         (mocodec.motion, "FRAME_RUN"),
                         (mocodec.runtime, "CHUNK_FRAMES"), (mocodec.quantize, "ROUNDTRIP_CHUNK"),
                         (mocodec.tolerance, "RATIO_CHUNK")]:
        monkeypatch.setattr(module, name, 97)
    assert not mocodec.kinematics.short_clip(m) and m.frame_count > 3 * 97
    assert encode_motions([m], units, codec, Tolerance(1.0)).asset == short
