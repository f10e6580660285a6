"""Baking on several cores, on a Dask cluster and from a cache gives the serial bake's bytes;
a worker that dies is survived or ends the bake with one clear error and no asset; bad
scheduler addresses and flags end in one line."""
from __future__ import annotations

import dataclasses
import os
import signal
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from mocodec.bake import (BakeError, ClipCache, ClipJob, ClipOutcome, ProcessRunner, SerialRunner, job_key,
                          make_runner)
from mocodec.cli import main
from mocodec.codecs.rma import RMASettings, encode_clip
from mocodec.encode import encode_motions
from mocodec.load import load_all
from mocodec.tolerance import Tolerance
from mocodec.units import resolve_library_units

TOL = 2.0  # loose: the tests check where clips run, not how well they fit


@pytest.fixture(scope="module")
def library(sample_paths):
    """The three sample clips and a renamed, time-reversed copy of the first (four jobs)."""
    motions = load_all(sample_paths)
    copies = [dataclasses.replace(m, name=f"{m.name}_rev", rotations=m.rotations[::-1].copy(),
                                  translations=m.translations[::-1].copy(), scales=m.scales[::-1].copy())
              for m in motions[:1]]
    motions = motions + copies
    return motions, resolve_library_units(motions, "cmu", None)


@pytest.fixture(scope="module")
def serial_asset(library) -> bytes:
    motions, units = library
    return encode_motions(motions, units, "rma", Tolerance(TOL)).asset


def _bake(library, runner) -> bytes:
    motions, units = library
    with runner:
        return encode_motions(motions, units, "rma", Tolerance(TOL), runner=runner).asset


# ----------------------------------------------------------------------------- local processes
def test_jobs_give_the_serial_bytes(library, serial_asset):
    assert _bake(library, ProcessRunner(2)) == serial_asset


def test_cli_jobs_flag_gives_the_same_file(sample_paths, tmp_path):
    files = []
    for jobs in ("1", "2"):
        out = tmp_path / f"j{jobs}.mcd"
        assert main(["encode", *map(str, sample_paths), "-o", str(out), "-t", str(TOL), "--units", "cmu",
                     "-q", "--jobs", jobs]) == 0
        files.append(out.read_bytes())
    assert files[0] == files[1]
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".")] == []  # no temporary file left


def _fails(motion, cm_per_unit, settings, check):
    from mocodec.tolerance import ToleranceNotMet

    raise ToleranceNotMet(f"clip {motion.name!r}: not this time")


def test_a_codec_error_in_a_worker_is_raised_as_in_serial(library):
    from mocodec.codecs.rma import section_prefix
    from mocodec.encode import RuntimeCheck
    from mocodec.tolerance import ToleranceNotMet

    motions, _ = library
    settings = RMASettings(Tolerance(TOL))
    jobs = [ClipJob(m.name, fn, m, 5.6444, settings, RuntimeCheck([m], [5.6444], "rma").one_clip(0, section_prefix(1)))
            for m, fn in zip(motions[:2], (encode_clip, _fails))]
    with pytest.raises(ToleranceNotMet, match=f"clip {motions[1].name!r}: not this time"), ProcessRunner(2) as r:
        r.run(jobs)


# ----------------------------------------------------------------------------- cache
def test_cache_reuses_clips_and_gives_the_clean_bytes(library, serial_asset, tmp_path):
    motions, units = library
    cache = tmp_path / "cache"
    first = encode_motions(motions, units, "rma", Tolerance(TOL), runner=make_runner(1, None, cache))
    assert first.asset == serial_asset and not any(c.stats.get("cached") for c in first.clips)
    again = encode_motions(motions, units, "rma", Tolerance(TOL), runner=make_runner(1, None, cache))
    assert again.asset == serial_asset and all(c.stats.get("cached") for c in again.clips)

    # One clip changes: only it is encoded, and the asset is a clean bake's.
    changed = list(motions)
    m = changed[1]
    rot = m.rotations.copy()
    rot[len(rot) // 2:, 0, 0] += 0.01  # the root turns a little in the second half
    rot[:, 0] /= np.linalg.norm(rot[:, 0], axis=-1, keepdims=True)
    changed[1] = dataclasses.replace(m, rotations=rot)
    incremental = encode_motions(changed, units, "rma", Tolerance(TOL), runner=make_runner(1, None, cache))
    assert [bool(c.stats.get("cached")) for c in incremental.clips] == [i != 1 for i in range(len(motions))]
    clean = encode_motions(changed, units, "rma", Tolerance(TOL)).asset
    assert incremental.asset == clean


def _job(motion, cm=5.6444, tol=TOL, **settings) -> ClipJob:
    return ClipJob(motion.name, encode_clip, motion, cm, RMASettings(Tolerance(tol), **settings), lambda p: None)


def test_cache_key_follows_content_settings_and_units(library):
    m = library[0][0]
    base = job_key(_job(m))
    assert job_key(_job(dataclasses.replace(m, name="renamed", source=None))) == base
    moved = m.translations.copy()
    moved[3, 0, 1] += 1e-9
    different = [
        _job(dataclasses.replace(m, translations=moved)),
        _job(m, tol=TOL * (1 + 1e-12)),
        _job(m, cm=5.6445),
        _job(m, key_grid=2),
        dataclasses.replace(_job(m), prefix=b"\x01"),
    ]
    keys = [job_key(j) for j in different]
    assert base not in keys and len(set(keys)) == len(keys)


def test_a_damaged_cache_entry_is_a_miss(tmp_path):
    cache = ClipCache(tmp_path)
    key = "ab" * 32
    cache.put(key, ClipOutcome(b"payload bytes", {"keys": 3}, 1.5))
    assert cache.get(key) == ClipOutcome(b"payload bytes", {"keys": 3}, 1.5, cached=True)
    path = tmp_path / key[:2] / f"{key}.clip"
    data = bytearray(path.read_bytes())
    data[-1] ^= 1
    path.write_bytes(bytes(data))
    assert cache.get(key) is None
    path.write_bytes(b"not an entry")
    assert cache.get(key) is None
    assert cache.get("cd" * 32) is None


def test_cache_must_be_a_folder(tmp_path, sample_paths, capsys):
    f = tmp_path / "file"
    f.write_text("x")
    assert main(["encode", str(sample_paths[0]), "-o", str(tmp_path / "a.mcd"), "--cache", str(f)]) == 1
    assert "must be a folder" in capsys.readouterr().err


# ----------------------------------------------------------------------------- flags
@pytest.mark.parametrize("flags, message", [
    (["--jobs", "0"], "--jobs must be at least 1"),
    (["--jobs", "2", "--scheduler", "tcp://127.0.0.1:1"], "exclude each other"),
])
def test_bad_flags_are_one_line(flags, message, sample_paths, tmp_path, capsys):
    assert main(["encode", str(sample_paths[0]), "-o", str(tmp_path / "a.mcd"), "-q", *flags]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("mocodec: error:") and message in err[0]
    assert not (tmp_path / "a.mcd").exists()


def test_serial_runner_is_the_default(library):
    assert isinstance(make_runner(1), SerialRunner)
    runner = make_runner(None)
    assert isinstance(runner, (SerialRunner, ProcessRunner)) and runner.workers == len(os.sched_getaffinity(0))


# ----------------------------------------------------------------------------- Dask
@pytest.fixture(scope="module")
def dask_installed() -> None:
    pytest.importorskip("distributed", reason="dask.distributed is not installed (pip install 'mocodec[cluster]')")


@pytest.fixture(scope="module")
def cluster(dask_installed):
    from distributed import LocalCluster

    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0") as c:
        yield c


def test_dask_gives_the_serial_bytes(library, serial_asset, cluster):
    assert _bake(library, make_runner(None, cluster.scheduler_address)) == serial_asset


def _kill_a_busy_worker(address: str, done: threading.Event, killed: list[int]) -> None:
    """Wait until a worker is encoding a clip, then SIGKILL its process."""
    from distributed import Client

    with Client(address, set_as_default=False) as client:
        pids = client.run(os.getpid)
        while not done.is_set():
            busy = [w for w, keys in client.processing().items() if any(str(k).startswith("mocodec-clip") for k in keys)]
            if busy:
                time.sleep(0.3)  # inside the clip, not at its start
                os.kill(pids[busy[0]], signal.SIGKILL)
                killed.append(pids[busy[0]])
                return
            time.sleep(0.05)


def test_dask_survives_a_killed_worker(library, serial_asset, cluster):
    done, killed = threading.Event(), []
    killer = threading.Thread(target=_kill_a_busy_worker, args=(cluster.scheduler_address, done, killed))
    killer.start()
    try:
        asset = _bake(library, make_runner(None, cluster.scheduler_address))
    finally:
        done.set()
        killer.join()
    assert killed, "no worker was busy: the test did not kill one"
    assert asset == serial_asset


def test_dask_worker_death_without_retries_fails_cleanly(sample_paths, tmp_path, capsys, dask_installed):
    import dask
    from distributed import LocalCluster

    out = tmp_path / "lib.mcd"
    out.write_bytes(b"the previous asset")
    with dask.config.set({"distributed.scheduler.allowed-failures": 0}), \
            LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0") as c:
        done, killed = threading.Event(), []
        killer = threading.Thread(target=_kill_a_busy_worker, args=(c.scheduler_address, done, killed))
        killer.start()
        try:
            rc = main(["encode", *map(str, sample_paths), "-o", str(out), "-t", str(TOL), "--units", "cmu", "-q",
                       "--scheduler", c.scheduler_address])
        finally:
            done.set()
            killer.join()
    assert killed, "no worker was busy: the test did not kill one"
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 1 and len(err) == 1 and "Dask workers died" in err[0], err
    assert out.read_bytes() == b"the previous asset"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["lib.mcd"]


def test_bad_scheduler_address_is_one_line(sample_paths, tmp_path, capsys, monkeypatch, dask_installed):
    from mocodec.bake import runners

    monkeypatch.setattr(runners, "CONNECT_TIMEOUT_S", 2.0)
    started = time.perf_counter()
    assert main(["encode", str(sample_paths[0]), "-o", str(tmp_path / "a.mcd"), "-q",
                 "--scheduler", "tcp://127.0.0.1:1"]) == 1
    assert time.perf_counter() - started < 30
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "cannot reach the Dask scheduler at 'tcp://127.0.0.1:1'" in err[0], err
    with pytest.raises(BakeError, match="cannot reach"):
        make_runner(None, "not an address")


def test_a_worker_with_other_encoder_code_refuses_the_clip(library):
    from mocodec.bake import EncoderMismatch, run_job

    m = library[0][0]
    with pytest.raises(EncoderMismatch, match="other mocodec code"):
        run_job(dataclasses.replace(_job(m), fingerprint="0" * 64))


def _children(pid: int) -> list[int]:
    try:
        with open(f"/proc/{pid}/task/{pid}/children") as f:
            return [int(p) for p in f.read().split()]
    except OSError:
        return []


@pytest.mark.skipif(not Path("/proc/self/task").is_dir(), reason="needs Linux /proc to find the workers")
def test_ctrl_c_stops_the_workers_and_writes_nothing(sample_paths, tmp_path):
    import subprocess
    import sys

    out = tmp_path / "lib.mcd"
    # A tight tolerance: the bake lasts long enough to be interrupted while the workers encode.
    p = subprocess.Popen([sys.executable, "-m", "mocodec", "encode", *map(str, sample_paths), "-o", str(out),
                          "-t", "0.05", "--units", "cmu", "-q", "--jobs", "2"], stderr=subprocess.PIPE, text=True,
                         start_new_session=True, preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    deadline = time.monotonic() + 60
    while len(_children(p.pid)) < 3 and p.poll() is None and time.monotonic() < deadline:
        time.sleep(0.1)  # the resource tracker and two workers
    workers = _children(p.pid)
    assert len(workers) >= 3, f"the workers did not start: {p.poll()}"
    time.sleep(0.5)
    os.killpg(p.pid, signal.SIGINT)
    try:
        err = p.communicate(timeout=30)[1]
    except subprocess.TimeoutExpired:
        os.killpg(p.pid, signal.SIGKILL)
        pytest.fail("the bake did not stop within 30 s of Ctrl-C")
    assert p.returncode == 130 and err.strip().startswith("mocodec: interrupted") and len(err.strip().splitlines()) == 1, err
    assert list(tmp_path.iterdir()) == []
    time.sleep(0.5)
    assert [w for w in workers if Path(f"/proc/{w}").exists() and "zombie" not in
            Path(f"/proc/{w}/status").read_text().lower()] == []
