"""``mocodec eval --sweep``: the size-against-error curve of one or more codecs, as a page or a PNG,
with the numbers each point stands for; bad requests are one line."""
from __future__ import annotations

import json
import re

import pytest

from mocodec.cli import main
from mocodec.io import read_bvh, write_bvh


@pytest.fixture(scope="module")
def clip(tmp_path_factory, sample_paths):
    path = tmp_path_factory.mktemp("sweep") / "short.bvh"
    write_bvh(read_bvh(sample_paths[0]).slice(0, 50), path)
    return path


def test_sweep_page_has_a_point_per_codec_and_tolerance(clip, tmp_path, capsys):
    page = tmp_path / "curve.html"
    assert main(["eval", str(clip), "--units", "cmu", "--sweep", "2", "0.5", "--codecs", "spline", "rma",
                 "--plot", str(page), "--json", "-q"]) == 0
    report = json.loads(capsys.readouterr().out)
    points = report["points"]
    assert [(p["codec"], p["tolerance_cm"]) for p in points] == [("spline", 0.5), ("spline", 2), ("rma", 0.5), ("rma", 2)]
    for p in points:
        assert p["failed"] is None and 0 < p["max_cm"] <= p["tolerance_cm"] and p["asset_bytes"] > 0
        assert p["mean_cm"] <= p["p99_cm"] <= p["max_cm"]
    text = page.read_text()
    assert text.count("<svg") == 2 and "<script" not in text and "http://" not in text.replace(
        'xmlns="http://www.w3.org/2000/svg"', "")
    # One dot per point in each chart, each with its figures as a tooltip, and every number in the table.
    assert len(re.findall(r"<circle ", text)) == 2 * len(points)
    for p in points:
        assert f"{p['asset_bytes']:,}" in text and f"{p['max_cm']:.4f}" in text


def test_sweep_png(clip, tmp_path):
    pytest.importorskip("matplotlib")
    png = tmp_path / "curve.png"
    assert main(["eval", str(clip), "--units", "cmu", "--sweep", "1", "--plot", str(png), "-q"]) == 0
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize("args, expected", [
    (["--sweep", "1", "--codecs", "nope"], "unknown codec 'nope'"),
    (["--sweep", "1", "--plot", "x.svg"], "writes .html or .png"),
    (["--sweep", "0"], "must be positive"),
    (["--codecs", "rma"], "go with --sweep"),
    (["--sweep", "1", "-o", "a.mcd"], "drop -o"),
])
def test_bad_sweep_requests_are_one_line(clip, tmp_path, capsys, args, expected):
    assert main(["eval", str(clip), "--units", "cmu", *args]) == 1
    err = capsys.readouterr().err.strip()
    assert err.startswith("mocodec: error: ") and expected in err and "\n" not in err
