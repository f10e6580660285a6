"""The clip-PCA baseline of bench/clip_pca.py (Arikan 2006 as seed 003 describes it)."""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

BENCH = Path(__file__).resolve().parents[1] / "bench"
sys.path.insert(0, str(BENCH))

import clip_pca as cp  # noqa: E402
from mocodec.io import read_bvh  # noqa: E402


@pytest.fixture(scope="module")
def sources(repo_root: Path) -> list[cp.Source]:
    motion = read_bvh(repo_root / "encoder" / "mocodec" / "samples" / "07_01.bvh")
    return cp.prepare([motion], 5.6444)


def test_bezier_fit_is_exact_on_a_cubic() -> None:
    # A cubic polynomial is a cubic Bézier: the least-squares fit must give it back exactly.
    t = np.linspace(0.0, 1.0, 24)
    x = np.stack([1 + 2 * t - 3 * t ** 2 + 0.5 * t ** 3, np.sin(0.3) * t], axis=1)
    ctrl = cp.fit_bezier(x[None])
    np.testing.assert_allclose(cp.bezier_matrix(24) @ ctrl[0], x, atol=1e-12)


def test_clips_cover_every_frame_and_join_meets_at_boundaries() -> None:
    x = np.random.default_rng(1).normal(size=(50, 3)).cumsum(axis=0)
    clips = cp.cut_clips(x, 8)
    assert clips.shape == (7, 8, 3)                      # 7 clips * 7 frames + 1 >= 50
    np.testing.assert_array_equal(clips[1, 0], clips[0, -1])  # shared boundary frame
    # Curves that disagree at a boundary are joined at the mean of the two values.
    curves = clips + np.random.default_rng(2).normal(scale=0.1, size=clips.shape)
    rows = cp.join_clips(curves, len(x))
    assert rows.shape == x.shape
    np.testing.assert_allclose(rows[7], 0.5 * (curves[0, -1] + curves[1, 0]))
    # Inside a clip both of its boundary ramps apply: 6/7 of the start gap, 1/7 of the end gap.
    gap0, gap1 = curves[1, 0] - curves[0, -1], curves[2, 0] - curves[1, -1]
    np.testing.assert_allclose(rows[8], curves[1, 1] - 0.5 * gap0 * 6 / 7 + 0.5 * gap1 / 7)


def test_kmeans_separates_two_blobs() -> None:
    rng = np.random.default_rng(0)
    x = np.vstack([rng.normal(size=(40, 5)), rng.normal(size=(30, 5)) + 50])
    labels = cp.kmeans(x, 2, seed=3)
    assert len(set(labels[:40])) == 1 and len(set(labels[40:])) == 1
    assert labels[0] != labels[-1]


def test_round_trip_error_falls_and_bytes_rise_as_the_target_tightens(sources) -> None:
    rows = [cp.run(sources, cp.Config(target_cm=t, clusters=2)) for t in (8.0, 2.0, 0.5)]
    sizes = [r["asset_bytes"] for r in rows]
    means = [r["mean_cm"] for r in rows]
    assert sizes[0] < sizes[1] < sizes[2], sizes
    assert means[0] > means[1] > means[2], means
    # Every part a decoder needs is counted, and the error covers every frame and node.
    parts = rows[-1]["bytes_by_part"]
    assert all(parts[k] > 0 for k in ("skeletons", "frame0", "root", "cluster_ids", "pca_means",
                                      "pca_axes", "coefficients"))
    assert rows[-1]["raw_bvh_bytes"] == sources[0].motion.skeleton.channel_count * 317 * 4


def test_sparse_fixes_bound_the_max_error(sources) -> None:
    plain = cp.run(sources, cp.Config(target_cm=1.0, clusters=2))
    fixed = cp.run(sources, cp.Config(target_cm=1.0, clusters=2, sparse_frac=1.0))
    assert fixed["asset_bytes"] > plain["asset_bytes"]
    assert fixed["max_cm"] < plain["max_cm"]
    # Markers within 1 cm (+ half the fix grid, root fixes) keep the joint markers under
    # 1.4 cm, and the rotation fit on top under 2 cm; plain clip PCA of this walk is at ~5 cm.
    assert fixed["pos_max_cm"] < 1.4
    assert fixed["max_cm"] < 2.0 < plain["max_cm"]
