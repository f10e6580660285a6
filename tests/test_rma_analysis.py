"""RMA analysis groundwork (seed 003 §3-4): marker round trips, PPCA cuts and grouping, group
PCA by max error, repeated-motion analysis (paths, clips, memory bound, determinism)."""
from __future__ import annotations

import tracemalloc

import numpy as np
import pytest

from mocodec import rotations as R
from mocodec.io import read_bvh
from mocodec.kinematics import forward_kinematics
from mocodec.motion import Motion
from mocodec.rma import pca as C
from mocodec.rma import preprocess as P
from mocodec.rma import repeats as Rp
from mocodec.rma import segment as S

CM = 5.6444


def _sample(sample_paths, stem: str) -> Motion:
    return read_bvh(next(p for p in sample_paths if p.stem == stem))


def _dance(shared_cmu_dir):
    if shared_cmu_dir is None or not (shared_cmu_dir / "05_02.bvh").exists():
        pytest.skip("needs ../shared/data/cmu/05_02.bvh (a dance)")
    return read_bvh(shared_cmu_dir / "05_02.bvh")


def _world(m: Motion) -> np.ndarray:
    return forward_kinematics(m.skeleton, m.rotations, m.translations)[1]


# ------------------------------------------------------------------------ preprocess
@pytest.mark.parametrize("stem", ["02_01", "07_01", "09_11"])
def test_markers_round_trip_rotations_and_positions(sample_paths, stem):
    m = _sample(sample_paths, stem)
    pr = P.to_markers(m, CM)
    assert not pr.root.full
    # Fig. 2b: at most two markers per joint beyond the shared position markers.
    assert pr.layout.marker_count <= len(pr.layout.position_nodes) + 2 * len(pr.layout.joints)
    back = P.from_markers(pr.markers, pr.root, pr.layout, m)
    ang = R.quat_angle(m.rotations, back.rotations)
    assert ang.max() < 1e-9
    assert np.abs(_world(m) - _world(back)).max() < 1e-9
    # Alignment is rigid: the aligned positions keep every distance of the world ones.
    w = _world(m)
    d_world = np.linalg.norm(w[:, 4] - w[:, 30], axis=-1)
    d_al = np.linalg.norm(pr.aligned_positions[:, 4] - pr.aligned_positions[:, 30], axis=-1)
    assert np.allclose(d_world, d_al, atol=1e-9)


def test_heading_and_translation_are_taken_out(sample_paths):
    m = _sample(sample_paths, "07_01")
    turned = Motion(m.skeleton, m.rotations.copy(), m.translations.copy(), m.frame_time, "turned")
    yaw = R.quat_from_axis_angle(np.array([0.0, 1.0, 0.0]), np.full(m.frame_count, 1.1))
    turned.rotations[:, 0] = R.quat_multiply(yaw, m.rotations[:, 0])
    turned.translations[:, 0] = R.quat_rotate(yaw, m.translations[:, 0]) + [30.0, 0.0, -12.0]
    a, b = P.to_markers(m, CM), P.to_markers(turned, CM)
    assert np.abs(a.markers - b.markers).max() < 1e-9


def test_large_tilt_takes_all_six_root_dofs(sample_paths):
    m = _sample(sample_paths, "02_01")
    rolled = Motion(m.skeleton, m.rotations.copy(), m.translations.copy(), m.frame_time, "roll")
    angle = np.linspace(0.0, 2.5, m.frame_count)  # a cartwheel-like roll past 140 degrees
    roll = R.quat_from_axis_angle(np.array([0.0, 0.0, 1.0]), angle)
    rolled.rotations[:, 0] = R.quat_make_continuous(R.quat_multiply(roll, m.rotations[:, 0]))
    pr = P.to_markers(rolled, CM)
    assert pr.root.full
    assert np.allclose(P.align_root(rolled)[0], [0, 0, 0, 1])
    back = P.from_markers(pr.markers, pr.root, pr.layout, rolled)
    assert np.abs(_world(rolled) - _world(back)).max() < 1e-9
    assert not P.to_markers(m, CM).root.full


def test_noisy_markers_still_give_rigid_poses(sample_paths):
    m = _sample(sample_paths, "09_11")
    pr = P.to_markers(m, CM)
    rng = np.random.default_rng(3)
    noisy = pr.markers + rng.normal(scale=0.5 / CM, size=pr.markers.shape)
    back = P.from_markers(noisy, pr.root, pr.layout, m)
    assert np.allclose(np.linalg.norm(back.rotations, axis=-1), 1.0)
    w = _world(back)
    # Bones keep their lengths whatever the markers do.
    for i in range(1, m.skeleton.node_count):
        p = m.skeleton.parents[i]
        assert np.allclose(np.linalg.norm(w[:, i] - w[:, p], axis=-1),
                           np.linalg.norm(m.skeleton.offsets[i]), atol=1e-9)
    err = np.linalg.norm(w - _world(m), axis=-1) * CM
    assert 0.05 < err.mean() < 5.0


def test_library_layout_spans_two_subjects(sample_paths, shared_cmu_dir):
    walk = _sample(sample_paths, "07_01")
    dance = _dance(shared_cmu_dir)
    shared = P.library_layout([walk.skeleton, dance.skeleton], CM)
    for m in (walk, dance):
        lay = P.layout_for(m.skeleton, shared)
        pr = P.to_markers(m, CM, layout=lay)
        assert pr.markers.shape[1] == shared.marker_count
        back = P.from_markers(pr.markers, pr.root, lay, m)
        assert np.abs(_world(m) - _world(back)).max() < 1e-9


# ------------------------------------------------------------------------ segmentation
def _walk_then_dance(sample_paths, shared_cmu_dir):
    walk = _sample(sample_paths, "07_01")
    dance = _dance(shared_cmu_dir)
    shared = P.library_layout([walk.skeleton, dance.skeleton], CM)
    xw = P.to_markers(walk, CM, layout=P.layout_for(walk.skeleton, shared)).flat[1:]
    xd = P.to_markers(dance, CM, layout=P.layout_for(dance.skeleton, shared)).flat[1:601]
    return xw, xd


def test_ppca_cut_between_walk_and_dance(sample_paths, shared_cmu_dir):
    xw, xd = _walk_then_dance(sample_paths, shared_cmu_dir)
    for first, second in ((xw, xd), (xd, xw)):
        x = np.concatenate((first, second))
        cuts = S.ppca_cuts(x)
        assert min(abs(c - len(first)) for c in cuts) <= 15, (len(first), cuts)


def test_unify_cuts_merges_near_duplicates():
    assert S.unify_cuts([100, 400], [104, 700], 60) == [102, 400, 700]
    assert S.unify_cuts([], [], 60) == []


def test_grouping_separates_walk_from_dance(sample_paths, shared_cmu_dir):
    xw, xd = _walk_then_dance(sample_paths, shared_cmu_dir)
    # Four walk pieces and four dance pieces: eq. 1 must put each kind in its own group.
    blocks = [xw[i:i + 75] for i in range(0, 300, 75)] + [xd[i:i + 150] for i in range(0, 600, 150)]
    feats = [S.segment_feature(b) for b in blocks]
    labels = S.group_segments(feats, n_groups=2)
    assert len(set(labels[:4])) == 1 and len(set(labels[4:])) == 1 and labels[0] != labels[4]
    d = S.seg_distance(feats)
    assert np.allclose(d, d.T) and np.allclose(np.diag(d), 0.0, atol=1e-6)
    assert d[:4, :4].mean() < d[:4, 4:].mean()


# ------------------------------------------------------------------------ PCA
def test_components_for_max_error_is_the_fewest(sample_paths):
    m = _sample(sample_paths, "09_11")
    pr = P.to_markers(m, CM)
    x = pr.flat[1:]
    ref = pr.aligned_positions[1:]
    lay, sk = pr.layout, m.skeleton

    def err(rows: np.ndarray) -> float:
        pos = P.aligned_positions_from_markers(rows.reshape(len(rows), -1, 3), lay, sk)
        return float(np.linalg.norm(pos - ref, axis=-1).max() * CM)

    dec = C.decompose(x)
    k, e = C.components_for_max_error(x, dec, err, 2.0)
    assert e <= 2.0
    b = dec.basis(k - 1)
    assert err(b.reconstruct(b.project(x))) > 2.0
    k95 = dec.components_for_variance(0.95)
    assert 1 <= k95 < k <= x.shape[1]
    # 12-bit axes and 16-bit means change a full-rank reconstruction by well under 1 mm.
    full = dec.basis(x.shape[1])
    assert err(full.reconstruct(full.project(x))) < 0.1


# ------------------------------------------------------------------------ repeats
def _walk_twice(sample_paths):
    """07_01 followed by a time-warped copy of itself (slower, with a wobble in speed): the
    true source frame of every frame of the copy is known."""
    m = _sample(sample_paths, "07_01")
    x = P.to_markers(m, CM).flat[1:]
    n = len(x)
    t = np.linspace(0, n - 1, int(n * 1.15))
    t = np.clip(t + 8.0 * np.sin(np.linspace(0, 3 * np.pi, len(t))), 0, n - 1)
    lo = np.floor(t).astype(np.int64)
    hi = np.minimum(lo + 1, n - 1)
    w = (t - lo)[:, None]
    xs = np.concatenate((x, x[lo] * (1 - w) + x[hi] * w))
    dec = C.decompose(xs)
    b = dec.basis(dec.components_for_variance(0.95))
    settings = Rp.RepeatSettings(threshold=5.0 / CM * np.sqrt(xs.shape[1] / 3))
    return b.project(xs), n, t, settings


def test_repeats_found_in_a_walk_and_its_warped_copy(sample_paths):
    z, n, truth, settings = _walk_twice(sample_paths)
    a = Rp.analyse(z, np.array([n]), 1.0 / 120.0, settings)
    # A path links the whole first walk to the copy and follows the warp.
    long = [p for p in a.paths if p.i[0] < 20 and p.i[-1] > n - 20 and p.j[0] >= n - 5]
    assert long, [(p.i[0], p.i[-1], p.j[0], p.j[-1]) for p in a.paths]
    p = long[0]
    mapped = np.interp(np.arange(n, len(z)), p.j, p.i)
    assert np.median(np.abs(mapped - truth)) < 4.0
    assert a.stats["repeated_fraction"] > 0.5
    kinds = {c.kind for c in a.clips}
    assert Rp.PRIMARY in kinds and Rp.REPEATED in kinds
    # Clips tile the group exactly, repeated clips point at primaries and stay inside them.
    edges = sorted((c.start, c.stop) for c in a.clips)
    assert edges[0][0] == 0 and edges[-1][1] == len(z)
    assert all(e0[1] == e1[0] for e0, e1 in zip(edges[:-1], edges[1:]))
    for c in a.clips:
        if c.kind == Rp.REPEATED:
            pri = a.clips[c.primary]
            assert pri.kind == Rp.PRIMARY
            assert len(c.ref) == c.frames
            assert pri.start <= c.ref.min() and c.ref.max() <= pri.stop - 1
            # The reference is a good predictor: the difference is far smaller than the motion.
            diff = np.linalg.norm(z[c.start:c.stop] - Rp._interp_rows(z, c.ref), axis=1)
            assert diff.mean() < settings.threshold
        if c.kind != Rp.PRIMARY:
            assert c.frames >= int(round(settings.min_clip * 120))


def test_no_repeats_without_repetition():
    rng = np.random.default_rng(7)
    # A random walk in coefficient space never comes back near a previous posture.
    z = np.cumsum(rng.normal(size=(900, 4)), axis=0) * 3.0
    a = Rp.analyse(z, np.array([], dtype=np.int64), 1.0 / 120.0, Rp.RepeatSettings(threshold=1.0))
    assert a.stats["repeated_fraction"] == 0.0
    assert [c.kind for c in a.clips] == [Rp.UNIQUE]


def test_paths_never_cross_a_segment_break(sample_paths):
    z, n, _, settings = _walk_twice(sample_paths)
    brk = np.array([n // 2, n, n + 150])
    paths, _ = Rp.similar_posture_paths(z, brk, 1.0 / 120.0, settings)
    for p in paths:
        for axis in (p.i, p.j):
            seg = np.searchsorted(brk, axis, side="right")
            assert seg.min() == seg.max()


def test_self_distance_scan_memory_is_bounded_by_the_tile():
    rng = np.random.default_rng(11)
    frames = 12000  # a dense plot would be 1.15 GB of float64
    t = np.arange(frames) / 120.0
    z = np.stack([np.sin(2 * np.pi * t * f) for f in (0.9, 1.8, 2.7)], axis=1) * 10.0
    z += rng.normal(scale=0.05, size=z.shape)
    tile = 128
    tracemalloc.start()
    px = Rp.scan_plot(z, threshold=1.0, min_lag_px=30, step=1, tile=tile)
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    assert px.peak_tile_bytes <= 2 * (tile + 2) ** 2 * 8
    assert peak < 64 * 2**20, peak
    assert len(px.i) > frames  # a periodic signal does produce many labelled pixels
    assert np.all(px.j > px.i)
    # The scan agrees with a direct computation on a small corner.
    d = np.linalg.norm(z[:300, None] - z[None, :300], axis=-1)
    sel = (px.i < 299) & (px.j < 299) & (px.i > 0)
    assert np.allclose(px.d[sel], d[px.i[sel], px.j[sel]], atol=1e-4)


def test_plot_resolution_caps_the_side():
    s = Rp.RepeatSettings(threshold=1.0, step=2, max_side=4096)
    assert Rp.plot_step(2000, s) == 2
    assert -(-72000 // Rp.plot_step(72000, s)) <= 4096  # a 10-minute group at 120 fps


def test_costs_follow_eq_2_and_3():
    z = np.cumsum(np.ones((200, 3)), axis=0)
    ref = np.arange(0, 50, dtype=np.float64)
    copy = np.concatenate((z[:100], z[:50] + 5.0))  # frames 100..149 repeat 0..49, shifted
    assert Rp.rep_cost(copy, 100, 150, ref, 0.0) == pytest.approx(0.0, abs=1e-9)
    assert Rp.pri_cost(copy, 100, 150, 0, 0.0) > 10.0


def test_analysis_is_deterministic(sample_paths):
    z, n, _, settings = _walk_twice(sample_paths)
    a = Rp.analyse(z, np.array([n]), 1.0 / 120.0, settings)
    b = Rp.analyse(z.copy(), np.array([n]), 1.0 / 120.0, settings)
    assert [(c.kind, c.start, c.stop, c.primary) for c in a.clips] == \
           [(c.kind, c.start, c.stop, c.primary) for c in b.clips]
    for c, d in zip(a.clips, b.clips):
        assert (c.ref is None and d.ref is None) or np.array_equal(c.ref, d.ref)
    x = np.concatenate([z, z[::-1]])
    assert S.ppca_cuts(x) == S.ppca_cuts(x.copy())
