"""Round trips through the C runtime: glTF -> mcd -> glTF within the tolerance (our own
measurement, on the re-read file), and BVH -> mcd -> glTF."""
from __future__ import annotations

import json
import struct
import subprocess
import sys

import numpy as np
import pytest

from mocodec import SAMPLES
from mocodec.io import read_bvh, read_gltf
from mocodec.kinematics import world_positions

TOL = 1.0


def run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "mocodec", *args], capture_output=True, text=True)


def _glb_json(path) -> dict:
    data = path.read_bytes()
    return json.loads(data[20:20 + struct.unpack_from("<I", data, 12)[0]])


@pytest.fixture(scope="module")
def encoded(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("rt")
    sources = [SAMPLES / "gltf" / n for n in ("SimpleSkin.gltf", "RiggedFigure.glb", "Luanti_spider_animated.gltf")]
    out = tmp / "samples.mcd"
    r = run("encode", *map(str, sources), "-o", str(out), "-t", str(TOL))
    assert r.returncode == 0, r.stderr
    assert "errors are measured against the source's own interpolation" in r.stdout
    return tmp, sources, out


@pytest.mark.parametrize("suffix", [".glb", ".gltf"])
def test_gltf_mcd_gltf_is_within_the_tolerance(encoded, suffix):
    tmp, sources, asset = encoded
    target = tmp / f"back{suffix}"
    r = run("decode", str(asset), "-o", str(target))
    assert r.returncode == 0, r.stderr
    back = {m.name: m for m in read_gltf(target)}
    originals = [m for p in sources for m in read_gltf(p)]
    assert sorted(back) == sorted(m.name for m in originals)
    for m in originals:
        b = back[m.name]
        assert b.frame_count == m.frame_count and b.frame_rate == pytest.approx(m.frame_rate)
        assert b.source["start_s"] == pytest.approx(m.source["start_s"], abs=1e-6)
        names = [n for n, v in zip(m.skeleton.names, m.skeleton.is_virtual) if not v]
        assert [n for n in b.skeleton.names if n in names] == names
        # The same nodes, virtual end points included (rebuilt from the same rest pose).
        idx = [b.skeleton.index(n) for n in m.skeleton.names]
        err = np.linalg.norm(world_positions(b)[:, idx] - world_positions(m), axis=-1) * 100.0
        assert err.max() <= TOL + 1e-4, (m.name, err.max())
        np.testing.assert_allclose(b.scales[:, idx], m.scales, atol=0.05)


def test_exported_glb_has_a_skin_and_no_virtual_nodes(encoded):
    tmp, _, asset = encoded
    target = tmp / "skin.glb"
    assert run("decode", str(asset), "-o", str(target), "--clip", "ArmatureAction").returncode == 0
    doc = _glb_json(target)
    names = [n["name"] for n in doc["nodes"]]
    assert not any(n.endswith("_end") for n in names)
    assert len(doc["animations"]) == 1 and doc["skins"] and len(doc["skins"][0]["joints"]) == 57
    full = tmp / "all.glb"
    assert run("decode", str(asset), "-o", str(full)).returncode == 0
    everything = _glb_json(full)
    # Per skeleton, every clip has a channel wherever any clip of that skeleton moves a node
    # (an engine keeps the last clip's pose where the next has none).
    roots = {}
    for a in everything["animations"]:
        targets = {(c["target"]["node"], c["target"]["path"]) for c in a["channels"]}
        roots.setdefault(min(n for n, _ in targets), []).append(targets)
    assert all(all(t == group[0] for t in group) for group in roots.values())
    assert {c["target"]["path"] for c in doc["animations"][0]["channels"]} == {"translation", "rotation", "scale"}


def test_gltf_asset_to_bvh_is_one_clear_error(encoded):
    tmp, _, asset = encoded
    r = run("decode", str(asset), "-o", str(tmp / "x"), "--clip", "SimpleSkin")
    assert r.returncode == 1 and "decode it to a .glb or .gltf file" in r.stderr and "Traceback" not in r.stderr


def test_bvh_mcd_gltf_keeps_the_motion_in_metres(sample_paths, tmp_path):
    asset = tmp_path / "walk.mcd"
    assert run("encode", str(sample_paths[0]), "-o", str(asset), "--units", "cmu", "-t", "0.5").returncode == 0
    target = tmp_path / "walk.glb"
    assert run("decode", str(asset), "-o", str(target)).returncode == 0
    back, = read_gltf(target)
    orig = read_bvh(sample_paths[0])
    idx = [back.skeleton.index(n) for n in orig.skeleton.names]
    assert back.frame_count == orig.frame_count
    err = np.linalg.norm(world_positions(back)[:, idx] * 100.0 - world_positions(orig) * 5.6444, axis=-1)
    assert err.max() <= 0.5 + 1e-3


def test_rate_option_and_the_sampling_note(tmp_path):
    r = run("eval", str(SAMPLES / "gltf" / "SimpleSkin.gltf"), "--rate", "30", "--json")
    assert r.returncode == 0, r.stderr
    notes = json.loads(r.stdout)["notes"]
    assert notes == ["SimpleSkin: resampled at 30 Hz (given); errors are measured against the source's own "
                     "interpolation (LINEAR) at those times"]
    bad = run("eval", str(SAMPLES / "gltf" / "SimpleSkin.gltf"), "--rate", "0")
    assert bad.returncode == 1 and "rate must be a positive number" in bad.stderr


def test_rma_pca_refuses_gltf_clips():
    from mocodec import codecs
    from mocodec.codecs import UnsupportedMotion
    from mocodec.tolerance import Tolerance

    motions = read_gltf(SAMPLES / "gltf" / "RiggedFigure.glb")
    with pytest.raises(UnsupportedMotion, match="codec 'rma-pca' reads BVH channel layouts"):
        codecs.get("rma-pca").encode(motions, [100.0], Tolerance(1.0), check=None)


def test_skin_joint_ranges_round_trip():
    from mocodec.encode import index_ranges, parse_index_ranges

    for joints in ([0, 1, 2, 5], [3], [1, 3, 4, 5, 9, 10]):
        assert parse_index_ranges(index_ranges(joints)) == joints
    assert index_ranges([5, 0, 1, 2]) == "0-2,5"
