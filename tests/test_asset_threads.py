"""One Python ``Asset`` shared by threads: every thread samples with its own scratch, so the
poses are the ones a lone thread gets, bit for bit (with one shared scratch, threads that
interleave clips and times read each other's half-written decoder state: hundreds of wrong
poses, no error)."""
from __future__ import annotations

import threading

import numpy as np
import pytest

from mocodec.encode import encode_motions
from mocodec.io import read_bvh
from mocodec.runtime import Asset
from mocodec.units import resolve_units

THREADS = 8
QUERIES = 400


@pytest.mark.parametrize("codec", ["rma", "spline"])
def test_threads_sharing_an_asset_get_the_serial_poses(sample_paths, codec):
    motions = [read_bvh(p) for p in sample_paths]
    asset = Asset(encode_motions(motions, [resolve_units(m.skeleton, "cmu") for m in motions], codec).asset)
    rng = np.random.default_rng(16)
    # Each thread its own order of clips and times, off frames and on them, so that the
    # decoder state one query leaves behind is never the one the next query of another needs.
    plans = []
    for _ in range(THREADS):
        clips = rng.integers(0, len(asset.clips), QUERIES)
        times = [float(rng.uniform(0, asset.clips[c].duration)) for c in clips]
        plans.append(list(zip(clips.tolist(), times)))
    expected = [[Asset.sample(asset, c, t) for c, t in plan] for plan in plans]
    got: list[list[np.ndarray] | None] = [None] * THREADS
    start = threading.Barrier(THREADS)

    def work(k: int) -> None:
        start.wait()
        got[k] = [asset.sample(c, t) for c, t in plans[k]]
        got[k] += [asset.sample_times(c, np.array([t, t * 0.5])) for c, t in plans[k][:50]]

    threads = [threading.Thread(target=work, args=(k,)) for k in range(THREADS)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for k in range(THREADS):
        assert got[k] is not None
        wrong = sum(not np.array_equal(a, b) for a, b in zip(got[k][:QUERIES], expected[k]))
        assert wrong == 0, f"thread {k}: {wrong} of {QUERIES} poses differ from serial sampling"
        for (c, t), poses in zip(plans[k][:50], got[k][QUERIES:]):
            assert np.array_equal(poses[0], asset.sample(c, t))
            assert np.array_equal(poses[1], asset.sample(c, t * 0.5))
