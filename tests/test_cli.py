"""The command line: the main paths work, and every user error is one clear line with a
non-zero exit, never a traceback."""
from __future__ import annotations

import json
import subprocess
import sys

import pytest

from mocodec.cli import main
from mocodec.io import read_bvh


def run(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "mocodec", *args], capture_output=True, text=True)


def test_help_explains_every_command():
    r = run("--help")
    assert r.returncode == 0
    for word in ("encode", "decode", "info", "eval", "demo", "tolerance", "units"):
        assert word in r.stdout
    for cmd in ("encode", "decode", "info", "eval", "demo"):
        sub = run(cmd, "--help")
        assert sub.returncode == 0 and "usage: mocodec " + cmd in sub.stdout


def test_encode_info_decode_round_trip(sample_paths, tmp_path):
    out = tmp_path / "s.mcd"
    r = run("encode", *map(str, sample_paths), "-o", str(out), "-t", "0.5", "--units", "cmu")
    assert r.returncode == 0, r.stderr
    assert "ratio" in r.stdout and "max" in r.stdout
    info = run("info", str(out), "--json")
    assert info.returncode == 0
    data = json.loads(info.stdout)
    assert data["valid"] == "OK" and len(data["clips"]) == 3
    assert all(c["max_error_cm"] <= 0.5 for c in data["clips"])
    dec = run("decode", str(out), "-o", str(tmp_path / "dec"))
    assert dec.returncode == 0, dec.stderr
    for p in sample_paths:
        back = read_bvh(tmp_path / "dec" / p.name)
        orig = read_bvh(p)
        assert back.skeleton.names == orig.skeleton.names
        assert back.skeleton.channels == orig.skeleton.channels
        assert back.frame_count == orig.frame_count
    one = run("decode", str(out), "-o", str(tmp_path / "one.bvh"), "--clip", sample_paths[0].stem)
    assert one.returncode == 0 and (tmp_path / "one.bvh").exists()


def test_decoded_bvh_is_within_tolerance(sample_paths, tmp_path):
    """Write back to BVH (6 decimals) and read again: still within the promise."""
    import numpy as np

    from mocodec.kinematics import world_positions

    out = tmp_path / "a.mcd"
    assert main(["encode", str(sample_paths[2]), "-o", str(out), "-t", "0.3", "-q"]) == 0
    assert main(["decode", str(out), "-o", str(tmp_path / "b.bvh"), "-q"]) == 0
    err = np.linalg.norm(world_positions(read_bvh(sample_paths[2])) -
                         world_positions(read_bvh(tmp_path / "b.bvh")), axis=-1) * 5.6444
    assert err.max() <= 0.3 + 1e-3


def test_eval_json_reports_both_conventions(sample_paths):
    r = run("eval", str(sample_paths[0]), "--tolerance", "1", "--json")
    assert r.returncode == 0, r.stderr
    data = json.loads(r.stdout)
    size = data["size"]
    assert size["ratio_bvh"] == pytest.approx(size["raw_bvh_bytes"] / size["asset_bytes"])
    assert size["ratio_acl"] == pytest.approx(size["raw_acl_bytes"] / size["asset_bytes"])
    assert data["error"]["max_cm"] <= 1.0
    assert "LeftHand" in data["per_joint"]


def test_folder_input_and_units_guess(tmp_path, sample_paths):
    for p in sample_paths[:2]:
        (tmp_path / p.name).write_bytes(p.read_bytes())
    r = run("encode", str(tmp_path), "-o", str(tmp_path / "f.mcd"))
    assert r.returncode == 0, r.stderr
    assert "guessed cmu" in r.stderr


@pytest.mark.parametrize("args, phrase", [
    (["encode", "missing.bvh", "-o", "x.mcd"], "no such file"),
    (["info", "missing.mcd"], "no such file"),
    (["encode", "{bad}", "-o", "{tmp}/x.mcd"], "bad.bvh:"),
    (["info", "{bad}"], "not a mocodec asset"),
    (["encode", "{sample}", "-o", "{tmp}/x.mcd", "-t", "-1"], "tolerance must be a positive"),
    (["encode", "{sample}", "-o", "{tmp}/x.mcd", "-t", "1e-8", "-O", "max_repairs=2"], "cannot meet"),
    (["encode", "{sample}", "-o", "{tmp}/x.mcd", "--cm-per-unit", "0"], "cm_per_unit"),
    (["decode", "{corrupt}", "-o", "{tmp}/y.bvh"], "checksum"),
    (["encode", "{sample}", "-o", "{tmp}/x.mcd", "-O", "nonsense"], "KEY=VALUE"),
])
def test_user_errors_are_one_line(args, phrase, tmp_path, sample_paths):
    bad = tmp_path / "bad.bvh"
    bad.write_text("HIERARCHY\nROOT a\n{\n OFFSET 0 0 0\n CHANNELS 3 Xposition Yposition Zposition\n}\n"
                   "MOTION\nFrames: 2\nFrame Time: 0.1\n1 2 3\n4 5\n")
    good = tmp_path / "good.mcd"
    assert main(["encode", str(sample_paths[2]), "-o", str(good), "-q"]) == 0
    corrupt = tmp_path / "corrupt.mcd"
    data = bytearray(good.read_bytes())
    data[100] ^= 0x55
    corrupt.write_bytes(bytes(data))
    fill = dict(bad=str(bad), tmp=str(tmp_path), sample=str(sample_paths[2]), corrupt=str(corrupt))
    r = run(*[a.format(**fill) for a in args])
    assert r.returncode != 0
    assert "Traceback" not in r.stderr
    lines = [line for line in r.stderr.splitlines() if line.startswith("mocodec: error:")]
    assert len(lines) == 1, r.stderr
    assert phrase.lower() in lines[0].lower()


def test_demo_runs(tmp_path):
    r = run("demo", "-o", str(tmp_path / "demo"))
    assert r.returncode == 0, r.stderr
    assert "met on every frame" in r.stdout
    assert (tmp_path / "demo" / "samples.mcd").exists()
    assert len(list((tmp_path / "demo" / "decoded").glob("*.bvh"))) == 3
