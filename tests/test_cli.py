"""The command line: the main paths work, and every user error is one clear line with a
non-zero exit, never a traceback."""
from __future__ import annotations

import json
import re
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


def test_asset_errors_name_the_file(tmp_path, sample_paths):
    """`info`/`decode` of bytes the runtime refuses said "mcd_open: asset is truncated", naming
    neither the file nor anything a user knows; an unknown --clip gave no list to pick from."""
    good = tmp_path / "good.mcd"
    assert main(["encode", str(sample_paths[2]), "-o", str(good), "-q"]) == 0
    trunc = tmp_path / "trunc.mcd"
    trunc.write_bytes(good.read_bytes()[:1000])
    cases = [
        (["info", str(trunc)], f"{trunc}: asset is truncated"),
        (["decode", str(trunc), "-o", str(tmp_path / "t.bvh")], f"{trunc}: asset is truncated"),
        (["decode", str(sample_paths[0]), "-o", str(tmp_path / "t.bvh")], f"{sample_paths[0]}: not a mocodec asset"),
        (["decode", str(good), "-o", str(tmp_path / "d") + "/", "--clip", "nope"],
         f"{good}: no clip named 'nope' (it holds {sample_paths[2].stem})"),
    ]
    for args, phrase in cases:
        r = run(*args)
        assert r.returncode == 1, (args, r.stderr)
        lines = _error_lines(r.stderr)
        assert len(lines) == 1 and lines[0].startswith(f"mocodec: error: {phrase}"), r.stderr
        assert "mcd_open" not in r.stderr
    assert not (tmp_path / "t.bvh").exists() and not (tmp_path / "d").exists()


def test_an_output_folder_that_is_not_there_is_refused_before_the_work(tmp_path, sample_paths):
    """`encode x.bvh -o missing/x.mcd` encoded every clip and then failed naming a temporary
    file; now it ends at once naming the folder, and `decode -o new/` still makes its folder."""
    r = run("encode", str(sample_paths[0]), "-o", str(tmp_path / "missing" / "x.mcd"))
    assert r.returncode == 1
    assert _error_lines(r.stderr) == [f"mocodec: error: {tmp_path / 'missing' / 'x.mcd'}: "
                                      f"the folder {tmp_path / 'missing'} does not exist"]
    assert "encoding" not in r.stdout + r.stderr and ".tmp" not in r.stderr
    afile = tmp_path / "a.mcd"
    assert main(["encode", str(sample_paths[0]), "-o", str(afile), "-q"]) == 0
    r = run("decode", str(afile), "-o", str(afile / "x.bvh"))
    assert _error_lines(r.stderr) == [f"mocodec: error: {afile / 'x.bvh'}: {afile} is not a folder"]
    r = run("decode", str(afile), "-o", str(tmp_path / "new" / "sub") + "/", "-q")
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "new" / "sub" / f"{sample_paths[0].stem}.bvh").is_file()


def test_a_file_named_twice_is_one_clip(tmp_path, sample_paths):
    """The same file by a folder and by name (or twice) was encoded as two clips, the second
    renamed; it is read once, with a warning naming it."""
    folder = tmp_path / "clips"
    folder.mkdir()
    for p in sample_paths[:2]:
        (folder / p.name).write_bytes(p.read_bytes())
    out = tmp_path / "x.mcd"
    again = folder / ".." / "clips" / sample_paths[0].name
    r = run("encode", str(folder), str(again), "-o", str(out), "--json")
    assert r.returncode == 0, r.stderr
    assert f"mocodec: warning: {again}: given more than once; read once" in r.stderr
    assert sorted(c["name"] for c in json.loads(r.stdout)["clips"]) == sorted(p.stem for p in sample_paths[:2])


def test_bad_tolerances_end_before_reading_and_a_loose_effector_bound_warns(tmp_path, sample_paths):
    """A bad --tolerance was refused only after every input had been read (a long wait on a
    library); an --effector-tolerance looser than --tolerance changed nothing, silently."""
    r = run("encode", str(sample_paths[0]), "-o", str(tmp_path / "x.mcd"), "-t", "nan")
    assert _error_lines(r.stderr) == ["mocodec: error: tolerance must be a positive number of cm, got nan"]
    assert "units:" not in r.stderr  # said before the clip was read (reading it guesses its units)
    r = run("encode", str(sample_paths[0]), "-o", str(tmp_path / "x.mcd"), "-t", "1", "--effector-tolerance", "2")
    assert r.returncode == 0, r.stderr
    assert ("mocodec: warning: --effector-tolerance 2 cm is not tighter than --tolerance 1 cm: "
            "every node is held to 1 cm") in r.stderr


def test_demo_runs(tmp_path):
    r = run("demo", "-o", str(tmp_path / "demo"))
    assert r.returncode == 0, r.stderr
    assert "met on every frame" in r.stdout
    assert (tmp_path / "demo" / "samples.mcd").exists()
    assert len(list((tmp_path / "demo" / "decoded").glob("*.bvh"))) == 3


# --------------------------------------------------------------- output safety (issue 16)
def _error_lines(stderr: str) -> list[str]:
    assert "Traceback" not in stderr, stderr
    return [line for line in stderr.splitlines() if line.startswith("mocodec: error:")]


def test_an_output_that_is_an_input_is_refused(tmp_path, sample_paths):
    """`encode in.bvh -o in.bvh` overwrote the source with the asset and exited 0; by any
    spelling of the same file (a link, ./x) it is refused before any work, the file unchanged."""
    import os
    src = tmp_path / "in.bvh"
    src.write_bytes(sample_paths[2].read_bytes())
    before = src.read_bytes()
    (tmp_path / "link.bvh").symlink_to(src)
    for out in (str(src), str(tmp_path / "link.bvh"), os.path.join(str(tmp_path), ".", "in.bvh")):
        r = run("encode", str(src), "-o", out, "-q")
        assert r.returncode == 1 and len(_error_lines(r.stderr)) == 1, r.stderr
        assert "the output is the input" in r.stderr
    assert src.read_bytes() == before
    asset = tmp_path / "a.mcd"
    assert main(["encode", str(src), "-o", str(asset), "-q"]) == 0
    r = run("decode", str(asset), "-o", str(asset))
    assert r.returncode == 1 and "the output is the input" in r.stderr
    assert asset.read_bytes()[:4] == b"MCD\0" or asset.stat().st_size > 0
    assert main(["info", str(asset)]) == 0


def test_a_failed_write_leaves_the_previous_file(tmp_path, sample_paths, monkeypatch, capsys):
    """A full disk replaced the previous good asset with a truncated one; now the new asset
    goes to a temporary file beside it that is renamed only when complete, and removed when not."""
    import errno
    import os
    out = tmp_path / "a.mcd"
    out.write_bytes(b"previous asset")

    def full(fd):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(os, "fsync", full)
    assert main(["encode", str(sample_paths[2]), "-o", str(out), "-q"]) == 1
    err = capsys.readouterr().err
    assert len(_error_lines(err)) == 1 and "No space left" in err and str(out) in err, err
    assert out.read_bytes() == b"previous asset"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.mcd"]
    monkeypatch.undo()
    assert main(["encode", str(sample_paths[2]), "-o", str(out), "-q"]) == 0
    assert out.read_bytes()[:4] != b"prev" and sorted(p.name for p in tmp_path.iterdir()) == ["a.mcd"]


@pytest.mark.parametrize("signame, code, word", [("SIGTERM", 143, "terminated"), ("SIGINT", 130, "interrupted")])
def test_a_signal_while_encoding_leaves_the_previous_file(tmp_path, sample_paths, signame, code, word):
    """SIGTERM (a build farm's timeout) exits 143, Ctrl-C 130, with the previous output intact."""
    import signal
    # A clip of 80 times a sample's frames: its encode takes many seconds, so it cannot end
    # before the signal arrives, however late a loaded machine lets the test run. One job: the
    # encode runs in this process (a Ctrl-C while workers start is tests/test_bake.py's).
    head, frames = sample_paths[2].read_text().split("Frame Time:", 1)
    time_line, body = frames.split("\n", 1)
    lines = body.strip().splitlines()
    long_clip = tmp_path / "long.bvh"
    long_clip.write_text(re.sub(r"Frames:\s*\d+", f"Frames: {80 * len(lines)}", head)
                         + "Frame Time:" + time_line + "\n" + "\n".join(lines * 80) + "\n")
    out = tmp_path / "a.mcd"
    out.write_bytes(b"previous asset")
    # Ctrl-C's default handling in the child, as a terminal gives it: a test run in a shell's
    # background job (CI's workers) inherits SIGINT ignored, and an ignored signal stays ignored.
    default_sigint = ("import os, signal, sys; signal.signal(signal.SIGINT, signal.SIG_DFL); "
                      "os.execv(sys.argv[1], sys.argv[1:])")
    p = subprocess.Popen([sys.executable, "-c", default_sigint, sys.executable, "-m", "mocodec", "encode",
                          str(long_clip), "-o", str(out), "-t", "0.05", "-j", "1"],
                         stderr=subprocess.PIPE, text=True)
    seen = []
    for line in p.stderr:  # wait until encoding has started (imports done, handler set)
        seen.append(line)
        if line.startswith("encoding "):
            break
    p.send_signal(getattr(signal, signame))
    rest = p.stderr.read()
    assert p.wait(timeout=60) == code, "".join(seen) + rest
    assert word in rest and "Traceback" not in rest
    assert out.read_bytes() == b"previous asset"
    assert sorted(q.name for q in tmp_path.iterdir()) == ["a.mcd", "long.bvh"]


# ------------------------------------------------------- names that steer a path or a terminal
def _renamed_asset(tmp_path, sample, old: bytes, new: bytes):
    """An asset of ``sample`` whose clip ``old`` is renamed ``new`` (same length) with the
    checksum made right again: only the name rules can refuse it."""
    import zlib
    src = tmp_path / (old.decode() + ".bvh")
    src.write_bytes(sample.read_bytes())
    good = tmp_path / "good.mcd"
    assert main(["encode", str(src), "-o", str(good), "-q"]) == 0
    data = bytearray(good.read_bytes().replace(old, new))
    data[20:24] = (zlib.crc32(bytes(data[24:])) & 0xFFFFFFFF).to_bytes(4, "little")
    bad = tmp_path / "bad.mcd"
    bad.write_bytes(bytes(data))
    return bad


@pytest.mark.parametrize("name", [b"../pw", b"/tmp/", b"a\\b:c", b"..", b"x\x1b[2J"])
def test_clip_names_that_steer_a_path_are_refused(tmp_path, sample_paths, name):
    """An asset could name a clip `../pw` and `decode -o out/` wrote `out/../pw.bvh`; the runtime
    now refuses such an asset (validate, open) and decode writes nothing."""
    from mocodec.runtime import Result, validate
    old = b"abcdefghij"[:len(name)]
    bad = _renamed_asset(tmp_path, sample_paths[2], old, name)
    assert validate(bad.read_bytes()) == Result.MALFORMED
    before = set(tmp_path.rglob("*"))
    r = run("decode", str(bad), "-o", str(tmp_path / "out") + "/")
    assert r.returncode == 1 and len(_error_lines(r.stderr)) == 1, r.stderr
    assert set(tmp_path.rglob("*")) == before
    info = run("info", str(bad))
    assert info.returncode == 1 and "\x1b" not in info.stdout + info.stderr


def test_info_prints_the_asset_s_own_text_with_escapes(tmp_path, sample_paths, monkeypatch, capsys):
    """`info` printed META text raw: an escape sequence in it reached the terminal."""
    import importlib
    monkeypatch.setattr(importlib.import_module("mocodec.encode"), "__version__", "9\x1b[2J\x07")
    out = tmp_path / "a.mcd"
    assert main(["encode", str(sample_paths[2]), "-o", str(out), "-q"]) == 0
    assert main(["info", str(out)]) == 0
    text = capsys.readouterr().out
    assert "written by mocodec 9\\x1b[2J\\x07" in text and "\x1b" not in text and "\x07" not in text


# ---------------------------------------------------- the real reason, not an internal error
def test_zero_offsets_and_a_huge_tolerance_encode(tmp_path):
    """All-zero offsets ended in 'float division by zero', `--tolerance 1e8` in an asset the
    runtime refused ('asset is malformed'): both encode now, and the asset opens."""
    from mocodec.runtime import Result, validate
    bvh = tmp_path / "zero.bvh"
    bvh.write_text("HIERARCHY\nROOT a\n{\n OFFSET 0 0 0\n CHANNELS 6 Xposition Yposition Zposition "
                   "Zrotation Xrotation Yrotation\n JOINT b\n {\n  OFFSET 0 0 0\n  CHANNELS 3 Zrotation "
                   "Xrotation Yrotation\n  End Site\n  {\n   OFFSET 0 0 0\n  }\n }\n}\nMOTION\nFrames: 3\n"
                   "Frame Time: 0.1\n0 0 0 0 0 0 0 0 0\n0 0 0 0 10 0 5 0 0\n0 0 0 0 20 0 10 0 0\n")
    for codec in ("rma", "spline"):
        r = run("encode", str(bvh), "-o", str(tmp_path / "z.mcd"), "--codec", codec)
        assert r.returncode == 0, r.stderr
        assert "the skeleton has no height" in r.stdout
    for codec in ("rma", "spline"):
        out = tmp_path / f"{codec}.mcd"
        r = run("encode", str(bvh), "-o", str(out), "--codec", codec, "-t", "1e8", "-q")
        assert r.returncode == 0, r.stderr
        assert validate(out.read_bytes()) == Result.OK


def test_the_help_text_s_option_examples_work(tmp_path, sample_paths):
    """`-O block_shift=6`, the help's own example, failed on the default codec: every example
    the help gives now names its codec and works, and an unknown setting names the list."""
    import re
    text = run("encode", "--help").stdout
    examples = re.findall(r"-O (\w+=\w+) \(codec ([\w-]+)\)", " ".join(text.split()))
    assert len(examples) >= 2, text
    for option, codec in examples:
        r = run("encode", str(sample_paths[2]), "-o", str(tmp_path / "x.mcd"), "--codec", codec,
                "-O", option, "-q")
        assert r.returncode == 0, (option, codec, r.stderr)
    r = run("encode", str(sample_paths[2]), "-o", str(tmp_path / "x.mcd"), "-O", "block_shift=6")
    assert r.returncode == 1 and "its settings:" in _error_lines(r.stderr)[0]


def test_library_warnings_are_one_line_and_silent_under_quiet(tmp_path, sample_paths, monkeypatch, capsys):
    """rma-pca printed scikit-learn's two-line warnings even under -q: a warning raised while a
    command runs is one 'mocodec: warning:' line, and nothing under -q or --json."""
    import importlib
    import warnings
    module = importlib.import_module("mocodec.encode")
    original = module.encode_motions

    def warning_encoder(*args, **kwargs):
        warnings.warn("n_components=96 must be between 1 and\nmin(n_samples, n_features)", UserWarning)
        return original(*args, **kwargs)

    monkeypatch.setattr(module, "encode_motions", warning_encoder)
    out = str(tmp_path / "x.mcd")
    assert main(["encode", str(sample_paths[2]), "-o", out, "-q"]) == 0
    assert capsys.readouterr().err == ""
    assert main(["encode", str(sample_paths[2]), "-o", out]) == 0
    err = capsys.readouterr().err
    assert "mocodec: warning: n_components=96 must be between 1 and\n" in err
    assert "UserWarning" not in err and "warnings.warn" not in err


def test_rma_pca_without_a_variance_states_its_promise(tmp_path, sample_paths, monkeypatch, capsys):
    """`--codec rma-pca` without `--pca-variance` failed formatting its own promise line
    ('unsupported format string passed to NoneType')."""
    import importlib
    from mocodec.encode import EncodeError

    def stop(*args, **kwargs):
        raise EncodeError("stopped after the promise line")

    monkeypatch.setattr(importlib.import_module("mocodec.encode"), "encode_motions", stop)
    assert main(["encode", str(sample_paths[2]), "-o", str(tmp_path / "x.mcd"), "--codec", "rma-pca"]) == 1
    err = capsys.readouterr().err
    assert "PCA keeping its default share of the variance" in err
    assert "mocodec: error: stopped after the promise line" in err


def test_encode_json_has_the_bake_summary(sample_paths, tmp_path):
    out, cache = tmp_path / "s.mcd", tmp_path / "cache"
    args = ["encode", *map(str, sample_paths[:2]), "-o", str(out), "-t", "2", "--units", "cmu", "--json",
            "--jobs", "2", "--cache", str(cache)]
    summaries = []
    for _ in range(2):  # a clean bake, then one from the cache
        r = run(*args)
        assert r.returncode == 0 and r.stderr == "", r.stderr
        data = json.loads(r.stdout)
        summaries.append(data["bake"])
    first, again = summaries
    assert set(first) == {"clips", "bytes", "seconds", "workers", "mb_per_s", "bvh_mb_per_s", "cache_hits",
                          "error", "peak_rss_mb"}
    assert first["clips"] == 2 and first["bytes"] == out.stat().st_size == data["size"]["asset_bytes"]
    assert first["workers"] == 2 and first["seconds"] > 0
    for key, raw in (("mb_per_s", "raw_acl_bytes"), ("bvh_mb_per_s", "raw_bvh_bytes")):
        assert first[key] == pytest.approx(data["size"][raw] / 1e6 / first["seconds"], rel=1e-2, abs=1e-3)
    assert list(first["error"]) == ["rma"] and 0 < first["error"]["rma"]["max_cm"] <= 2.0
    assert first["peak_rss_mb"]["main"] > 0 and first["peak_rss_mb"]["largest_worker"] > 0
    assert (first["cache_hits"], again["cache_hits"]) == (0, 2) and again["error"] == first["error"]


def test_progress_is_a_line_per_clip_off_a_terminal_and_off_under_quiet(sample_paths, tmp_path, capsys):
    out = str(tmp_path / "x.mcd")
    base = ["encode", *map(str, sample_paths), "-o", out, "-t", "2", "--units", "cmu", "--jobs", "1"]
    assert main(base) == 0
    err = capsys.readouterr().err
    assert [line.split("]")[0].strip() for line in err.splitlines() if line.startswith("  [")] == \
        ["[1/3", "[2/3", "[3/3"]
    assert main(base + ["--quiet"]) == 0
    assert capsys.readouterr().err == ""
    assert main(base + ["--json"]) == 0
    assert capsys.readouterr().err == ""
