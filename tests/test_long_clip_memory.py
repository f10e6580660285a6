"""Memory of a long clip's encode (issue 16: hours-long captures). The encoder's runtime check
(the half-way reference too) and final evaluation sample a run of frames at a time and the
key-frame fitter keeps one decoded pose of the clip, its tracks and the original's world
positions, so encoding allocates a bounded multiple of the clip's raw float32 channels.
Counted by tracemalloc (numpy reports its buffers to it), which is exact and does not depend on
the allocator or the load, unlike the resident size."""
from __future__ import annotations

import tracemalloc

from long_clip import CM_PER_UNIT, long_clip

from mocodec.encode import encode_motions
from mocodec.tolerance import Tolerance
from mocodec.units import resolve_units

FRAMES = 200_000  # 28 minutes at 120 fps, about 3 s to encode

# Allocated at the peak over the raw float32 channels (2026-12-04): 8.1x with the half-way hold
# (on by default), 7.8x without: the half-way reference streamed per check, no world rotations
# held, curves, targets, roundtrips and poses built a run of frames at a time. Before
# (2026-12-02): 23.7x with the hold, 18.9x without; 32.0x before the check and evaluation were
# chunked and the fitter's pass held two poses.
MAX_PEAK_OVER_RAW = 8.5


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
