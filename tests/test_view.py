"""``mocodec view``: the page holds the wasm, the asset and the originals' world positions in the
asset's node order; originals that do not fit and damaged assets are one clear line. (The page
itself is tested in headless Chromium by viewer/run_tests.sh.)"""
from __future__ import annotations

import base64
import json
import re

import numpy as np
import pytest

from mocodec.cli import main
from mocodec.io import read_bvh, write_bvh
from mocodec.kinematics import world_positions
from mocodec.view.page import STATIC


@pytest.fixture(scope="module")
def encoded(tmp_path_factory, sample_paths):
    """An asset of two short clips and their originals as BVH files."""
    d = tmp_path_factory.mktemp("view")
    originals = []
    for p in sample_paths[:2]:
        m = read_bvh(p).slice(0, 60)
        m.name = p.stem
        write_bvh(m, d / f"{p.stem}.bvh")
        originals.append(d / f"{p.stem}.bvh")
    asset = d / "two.mcd"
    assert main(["encode", *map(str, originals), "-o", str(asset), "--codec", "spline", "--units", "cmu", "-q"]) == 0
    return asset, originals


def page_data(html: str) -> dict:
    block = re.search(r'<script id="mocodec-data" type="application/json">(.*?)</script>', html, re.S)
    assert block, "no data block"
    return json.loads(block.group(1))


def test_page_holds_wasm_asset_and_originals_in_node_order(encoded, tmp_path, capsys):
    asset, originals = encoded
    out = tmp_path / "v.html"
    assert main(["view", str(asset), "--original", *map(str, reversed(originals)), "-o", str(out)]) == 0
    assert "2 of 2 clips compared" in capsys.readouterr().out
    html = out.read_text()
    data = page_data(html)
    assert base64.b64decode(data["asset"]["bytes"]) == asset.read_bytes()
    assert base64.b64decode(data["wasm"]) == (STATIC / "mocodec.wasm").read_bytes()
    assert data["codecs"]["1"] == "spline" and data["meta"]["codec"] == "spline"
    assert (STATIC / "viewer.js").read_text()[:200] in html
    for path in originals:
        m = read_bvh(path)
        entry = data["originals"][path.stem]
        assert (entry["frames"], entry["nodes"]) == (m.frame_count, m.skeleton.node_count)
        got = np.frombuffer(base64.b64decode(entry["positions_b64"]), dtype="<f4").reshape(m.frame_count, -1, 3)
        np.testing.assert_allclose(got, world_positions(m), rtol=0, atol=1e-4)


def test_without_originals_and_one_clip_matched_by_position(encoded, tmp_path, sample_paths, capsys):
    asset, originals = encoded
    out = tmp_path / "plain.html"
    assert main(["view", str(asset), "-o", str(out)]) == 0
    assert page_data(out.read_text())["originals"] == {}
    one = tmp_path / "one.mcd"
    assert main(["encode", str(originals[0]), "-o", str(one), "--codec", "spline", "--units", "cmu", "-q"]) == 0
    renamed = tmp_path / "renamed.bvh"
    renamed.write_bytes(originals[0].read_bytes())
    assert main(["view", str(one), "--original", str(renamed), "-o", str(tmp_path / "one.html")]) == 0
    assert list(page_data((tmp_path / "one.html").read_text())["originals"]) == [originals[0].stem]


@pytest.mark.parametrize("problem, expected", [
    ("frames", "60 frames" ),
    ("name", "matches no clip"),
    ("suffix", "no reader for .txt"),
    ("missing", "no such file"),
])
def test_originals_that_do_not_fit_are_one_line(encoded, tmp_path, capsys, problem, expected):
    asset, originals = encoded
    if problem == "frames":
        m = read_bvh(originals[0]).slice(0, 30)
        bad = tmp_path / originals[0].name
        write_bvh(m, bad)
        expected = f"30 frames, clip {originals[0].stem!r} has 60"
    elif problem == "name":
        bad = tmp_path / "stranger.bvh"
        bad.write_bytes(originals[0].read_bytes())
    elif problem == "suffix":
        bad = tmp_path / "notes.txt"
        bad.write_text("hello")
    else:
        bad = tmp_path / "absent.bvh"
    assert main(["view", str(asset), "--original", str(bad), "-o", str(tmp_path / "x.html")]) == 1
    err = capsys.readouterr().err.strip()
    assert err.startswith("mocodec: error: ") and expected in err and "\n" not in err
    assert not (tmp_path / "x.html").exists()


def test_damaged_asset_still_makes_a_page_that_says_so(encoded, tmp_path, capsys):
    asset, originals = encoded
    data = bytearray(asset.read_bytes())
    data[len(data) // 2] ^= 0x5A
    bad = tmp_path / "bad.mcd"
    bad.write_bytes(bytes(data))
    assert main(["view", str(bad), "--original", str(originals[0]), "-o", str(tmp_path / "bad.html")]) == 0
    err = capsys.readouterr().err
    assert "warning" in err and "checksum" in err and "compares no original" in err
    assert page_data((tmp_path / "bad.html").read_text())["originals"] == {}


def test_originals_from_any_reader_are_taken_by_node_name(sample_paths):
    """A motion whose skeleton lists the nodes in another order, with one node more (as a reader
    of another format may give it), is reduced to the clip's nodes in the clip's order."""
    from mocodec.motion import Motion, Skeleton
    from mocodec.view import match_originals

    m = read_bvh(sample_paths[0]).slice(0, 5)
    sk = m.skeleton
    extra = Skeleton(names=sk.names + ["Extra"], parents=list(sk.parents) + [0],
                     offsets=np.vstack([sk.offsets, [[1.0, 2.0, 3.0]]]), channels=sk.channels + [()],
                     is_end_site=list(sk.is_end_site) + [True])
    rot = np.concatenate([m.rotations, np.tile([0.0, 0.0, 0.0, 1.0], (5, 1, 1))], axis=1)
    trans = np.concatenate([m.translations, np.tile([1.0, 2.0, 3.0], (5, 1, 1))], axis=1)
    other = Motion(extra, rot, trans, m.frame_time, "walk")
    clip_nodes = list(reversed(sk.names))
    (o,) = match_originals([("walk.any", other)], [("walk", 5, clip_nodes)])
    expected = world_positions(m)[:, ::-1]
    np.testing.assert_allclose(o.positions, expected, rtol=0, atol=1e-4)
    assert o.positions.dtype == np.float32 and o.source == "walk.any"


def test_help_names_view_and_sweep(capsys):
    with pytest.raises(SystemExit):
        main(["--help"])
    text = capsys.readouterr().out
    assert "view" in text and "--sweep" in text
    with pytest.raises(SystemExit):
        main(["view", "--help"])
    assert "--original" in capsys.readouterr().out
