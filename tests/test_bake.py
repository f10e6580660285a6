"""Baking on several cores, on a Dask cluster and from a cache gives the serial bake's bytes;
a streamed library (clips read per task, payloads spooled to disk) gives the bytes of one held
in memory; a worker that dies is survived or ends the bake with one clear error and no asset;
Ctrl-C leaves no asset and no temporary file; bad scheduler addresses and flags end in one line."""
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
                          make_runner, run_job)
from mocodec.bake.fingerprint import motion_digest
from mocodec.bake.library import ClipRef, Library, open_library
from mocodec.bake.progress import Progress
from mocodec.bake.spool import PayloadSpool
from mocodec.cli import main
from mocodec.codecs.rma import RMASettings, encode_clip
from mocodec.encode import encode_motions
from mocodec.load import load_all
from mocodec.tolerance import Tolerance
from mocodec.units import figure_facts, resolve_library_units

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


# ----------------------------------------------------------------------------- streamed library
@pytest.fixture(scope="module")
def files_asset(sample_paths) -> bytes:
    """The sample files baked the way a library held in memory is: every motion read up front."""
    motions = load_all(sample_paths)
    return encode_motions(motions, resolve_library_units(motions, "cmu", None), "rma", Tolerance(TOL)).asset


def _streamed(sample_paths) -> tuple[Library, list]:
    """The sample files as a library that keeps no motion in memory (every read goes to the file)."""
    facts: list = []
    lib = open_library(sample_paths, resident_bytes=0, visit=lambda i, m: facts.append(figure_facts(m)))
    return lib, resolve_library_units(lib, "cmu", None, facts=facts)


@pytest.mark.parametrize("jobs", [1, 2])
def test_a_streamed_library_gives_the_bytes_of_one_held_whole(sample_paths, files_asset, jobs):
    lib, units = _streamed(sample_paths)
    assert lib._resident == {}
    with make_runner(jobs) as runner:
        assert encode_motions(lib, units, "rma", Tolerance(TOL), runner=runner).asset == files_asset
    assert lib._resident == {}  # nothing was kept: the clips were read where they were needed


def test_a_streamed_codec_without_scale_tracks_gives_the_same_bytes(sample_paths):
    motions = load_all(sample_paths)[:2]
    units = resolve_library_units(motions, "cmu", None)
    held = encode_motions(motions, units, "spline", Tolerance(TOL)).asset
    lib, _ = _streamed(sample_paths[:2])
    with ProcessRunner(2) as runner:
        assert encode_motions(lib, units, "spline", Tolerance(TOL), runner=runner).asset == held


def test_a_library_reads_its_clips_as_load_all_does(sample_paths, tmp_path):
    twin = tmp_path / sample_paths[0].name  # two files with one stem: the second is renamed
    twin.write_bytes(sample_paths[0].read_bytes())
    paths = [*sample_paths, twin]
    held = load_all(paths)
    lib = open_library(paths, resident_bytes=0)
    assert [r.name for r in lib.refs] == [m.name for m in held] and held[-1].name.endswith("_2")
    for k in range(len(held)):
        assert lib[k].name == held[k].name and motion_digest(lib[k]) == motion_digest(held[k])
    assert lib.refs[0].weight == held[0].frame_count * held[0].skeleton.node_count


def test_a_library_keeps_what_fits_and_pickles_without_motions(sample_paths):
    import pickle

    whole = open_library(sample_paths)
    assert sorted(whole._resident) == [0, 1, 2]
    one = open_library(sample_paths, resident_bytes=whole._held - 1)
    assert len(one._resident) < 3 and one._held <= one.resident_bytes  # least recently used dropped
    data = pickle.dumps(whole)
    assert len(data) < 4096  # refs only: a worker reads the clips itself
    back = pickle.loads(data)
    assert back._resident == {} and motion_digest(back[1]) == motion_digest(whole[1])
    assert isinstance(back.refs[0], ClipRef) and len(whole[0:2]) == 2


def test_a_carried_job_needs_no_file(sample_paths, tmp_path):
    """A Dask worker may be on a machine without the input files: a job sent there carries its
    clip's frames, in itself and in its check."""
    import shutil

    from mocodec.codecs.rma import section_prefix
    from mocodec.encode import RuntimeCheck

    path = tmp_path / sample_paths[2].name
    shutil.copy(sample_paths[2], path)
    lib = open_library([path], resident_bytes=0)
    check = RuntimeCheck(lib, [5.6444], "rma").one_clip(0, section_prefix(1))
    job = ClipJob(lib.refs[0].name, encode_clip, lib.refs[0], 5.6444, RMASettings(Tolerance(TOL)), check)
    carried = job.carried()
    path.unlink()
    assert carried.carried() is carried and isinstance(carried.motion, type(load_all(sample_paths[2:])[0]))
    expected = encode_clip(load_all(sample_paths[2:])[0], 5.6444, RMASettings(Tolerance(TOL)),
                           RuntimeCheck(load_all(sample_paths[2:]), [5.6444], "rma").one_clip(0, section_prefix(1)))
    assert run_job(carried).payload == expected.payload
    from mocodec.io import BVHError

    with pytest.raises(BVHError, match="no such file|not found|No such"):
        run_job(job)  # the ref alone needs the file


def test_the_spool_gives_back_each_payload_and_leaves_no_file(tmp_path, monkeypatch):
    import tempfile

    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    payloads = {3: b"abc", 0: b"", 1: os.urandom(5000), 2: b"z"}
    with PayloadSpool() as spool:
        for k, p in payloads.items():
            spool.add(k, p)
        assert list(tmp_path.iterdir()) == []  # unnamed: nothing to leave behind
        views = spool.views([0, 1, 2, 3])
    assert [bytes(v) for v in views] == [payloads[k] for k in range(4)]
    empty = PayloadSpool()
    empty.add(0, b"")
    assert [bytes(v) for v in empty.views([0])] == [b""]


class _Recorder(Progress):
    """Progress that records how many clips were in flight at once."""

    def __init__(self, total: int) -> None:
        super().__init__(total, enabled=False)
        self.most = 0

    def started(self, name: str) -> None:
        super().started(name)
        self.most = max(self.most, len(self.slots))


def test_no_more_clips_in_flight_than_workers(library, serial_asset):
    motions, units = library
    progress = _Recorder(len(motions))
    with ProcessRunner(2) as runner:
        assert encode_motions(motions, units, "rma", Tolerance(TOL), progress=progress, runner=runner).asset \
            == serial_asset
    assert progress.most == 2 and progress.done == len(motions) and progress.slots == {}


def test_the_bar_shows_each_workers_clip_and_the_cache_hits():
    import io

    stream = io.StringIO()
    p = Progress(3, stream=stream, bar=True)
    p.started("walk")
    p.started("run")
    assert p.postfix() == "w1 walk  w2 run"
    p("walk")
    p.started("jump")
    assert p.postfix() == "w1 jump  w2 run"
    p.hit("idle")
    assert "(1 cached)" in p.postfix()
    p("run")
    p("jump")
    text = stream.getvalue()
    assert "3/3" in text and "w2 run" in text and p._bar is None


def test_progress_lines_without_a_terminal_and_nothing_when_off():
    import io

    stream = io.StringIO()
    p = Progress(2, stream=stream, bar=False)
    p.started("a")
    p("a")
    assert stream.getvalue().startswith("  [1/2] a (")
    quiet = io.StringIO()
    q = Progress(2, enabled=False, stream=quiet, bar=True)
    q.started("a")
    q("a")
    assert quiet.getvalue() == "" and q._bar is None


def _says_where_it_is(motion, cm_per_unit, settings, check):
    """rma's encode_clip, after reporting from within the clip as a long clip's windows do."""
    from mocodec.bake.progress import report_within

    for k in range(3):
        report_within(f"step {k + 1} of 3")
    return encode_clip(motion, cm_per_unit, settings, check)


def _within_lines(library, runner) -> tuple[list, list[str]]:
    import io

    from mocodec.codecs.rma import section_prefix
    from mocodec.encode import RuntimeCheck

    motions, units = library
    stream = io.StringIO()
    progress = Progress(len(motions), stream=stream, bar=False, within_every=0.0)
    jobs = [ClipJob(m.name, _says_where_it_is, m, 5.6444, RMASettings(Tolerance(TOL)),
                    RuntimeCheck([m], [5.6444], "rma").one_clip(0, section_prefix(1))) for m in motions]
    with runner:
        runner.run(jobs, progress)
    return motions, stream.getvalue().splitlines()


@pytest.mark.parametrize("runner", [SerialRunner, lambda: ProcessRunner(2)], ids=["serial", "processes"])
def test_each_clip_shows_where_it_has_got_to_wherever_it_runs(library, runner):
    motions, lines = _within_lines(library, runner())
    for m in motions:  # every report of every clip, before the clip's own line
        mine = [line for line in lines if line.startswith(f"  {m.name}: step ")]
        assert [line.split(" (")[0] for line in mine] == [f"  {m.name}: step {k} of 3" for k in (1, 2, 3)]
        done_at = next(i for i, line in enumerate(lines) if line.startswith("  [") and f"] {m.name} (" in line)
        assert lines.index(mine[-1]) < done_at


def test_a_workers_report_fits_one_pipe_write_and_a_serial_clip_sends_none(monkeypatch):
    import pickle

    from mocodec.bake import runners

    sent: list = []
    monkeypatch.setattr(runners, "_REPORTS", type("Q", (), {"put": lambda self, x: sent.append(x)})())
    runners._to_queue("walk", "window 1 of 9, " + "é" * 400)
    runners._to_queue("w" * (runners.NAME_BYTES + 1), "window 1 of 9")  # too long a name: not sent
    assert len(sent) == 1 and sent[0][1].startswith("window 1 of 9, é")
    assert 4 + len(pickle.dumps(("x" * runners.NAME_BYTES, sent[0][1]))) < 512  # with the pipe's length header
    monkeypatch.setattr(runners, "_REPORTS", None)
    job = ClipJob("walk", encode_clip, None, 1.0, None, lambda p: None)
    assert runners._report_sender(job) is None  # this process: reports go straight to its progress
    assert runners._report_sender(dataclasses.replace(job, report_to="a-client")) is None  # not a Dask worker


def test_a_report_of_a_clip_not_running_is_dropped_and_news_shown_once():
    import io

    stream = io.StringIO()
    p = Progress(2, stream=stream, bar=False, within_every=0.0)
    p.within("walk", "window 1 of 9")  # not started (or already ended): nothing
    assert stream.getvalue() == ""
    p.started("walk")
    p.started("run")
    p.within("walk", "window 2 of 9")
    p.within("run", "window 1 of 4")  # walk's news is shown already: only run's
    p("walk")
    p.within("walk", "window 3 of 9")  # after walk ended (a late report from its worker)
    lines = stream.getvalue().splitlines()
    assert [line.split(" (")[0] for line in lines] == ["  walk: window 2 of 9", "  run: window 1 of 4",
                                                       "  [1/2] walk"]
    assert p.status == {"run": "window 1 of 4"}


def _pid(_: object) -> int:
    return os.getpid()


def _env(name: str) -> str | None:
    return os.environ.get(name)


def _fails_on_two(x: int) -> int:
    if x == 2:
        raise ValueError("item 2")
    return x


@pytest.mark.parametrize("runner", [SerialRunner, lambda: ProcessRunner(2)], ids=["serial", "processes"])
def test_map_keeps_the_order_and_raises_an_items_error(runner):
    with runner() as r:
        assert r.map(abs, [-3, 1, -2, 0]) == [3, 1, 2, 0]
        assert r.map(abs, []) == []
        with pytest.raises(ValueError, match="item 2"):
            r.map(_fails_on_two, [0, 1, 2, 3])


def test_process_map_runs_in_the_workers_with_one_blas_thread(monkeypatch):
    monkeypatch.setenv("OPENBLAS_NUM_THREADS", "7")
    with ProcessRunner(2) as r:
        pids = r.map(_pid, range(8))
        threads = r.map(_env, ["OPENBLAS_NUM_THREADS"] * 4)
    assert os.getpid() not in pids
    assert threads == ["1"] * 4
    assert os.environ["OPENBLAS_NUM_THREADS"] == "7"  # this process's setting is given back


@pytest.fixture
def default_sigint():
    """Ctrl-C handled as a terminal's foreground process does (a shell's background job, as CI
    runs pytest, inherits it ignored)."""
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, previous)


@pytest.mark.skipif(not hasattr(signal, "pthread_sigmask"), reason="no signal masks on this platform")
def test_a_ctrl_c_while_workers_start_is_not_lost(default_sigint):
    """Workers start with Ctrl-C held off; a Ctrl-C meanwhile used to be ignored by the parent
    too, so the encode went on. It now arrives when the workers have started."""
    from mocodec.bake.runners import _starting_workers
    reached = []
    with pytest.raises(KeyboardInterrupt):
        with _starting_workers():
            # To this thread: a signal sent to the process may go to another thread, whose
            # handler would raise here at once (not lost either).
            signal.pthread_kill(threading.main_thread().ident, signal.SIGINT)
            time.sleep(0.05)
            reached.append("end of the start-up")
        time.sleep(1.0)  # a Python handler runs between bytecodes: long before this ends
        reached.append("after")
    assert reached == ["end of the start-up"]
    assert signal.SIGINT not in signal.pthread_sigmask(signal.SIG_BLOCK, set())


def _sigint_ignored(_: object) -> bool:
    """Whether this worker ignores SIGINT, from /proc."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("SigIgn:"):
            return bool(int(line.split()[1], 16) >> (signal.SIGINT - 1) & 1)
    raise AssertionError("no SigIgn line in /proc/self/status")


@pytest.mark.skipif(not Path("/proc/self/status").exists(), reason="reads the signal state from Linux's /proc")
def test_workers_ignore_ctrl_c_and_the_parent_does_not(default_sigint):
    with ProcessRunner(2) as r:
        ignored = r.map(_sigint_ignored, range(4))
    assert all(ignored), ignored  # the parent stops the workers
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
    assert signal.SIGINT not in signal.pthread_sigmask(signal.SIG_BLOCK, set())


class CountingRunner(ProcessRunner):
    """A process runner that counts the items its ``map`` spread."""

    def __init__(self, workers: int) -> None:
        super().__init__(workers)
        self.items = 0

    def map(self, fn, items):
        self.items += len(items)
        return super().map(fn, items)


@pytest.fixture(scope="module")
def pca_serial(library) -> bytes:
    pytest.importorskip("sklearn", reason="rma-pca needs the research extra (pip install 'mocodec[research]')")
    motions, units = library
    return encode_motions(motions, units, "rma-pca", Tolerance(TOL), options={"variance": 0.95}).asset


def test_rma_pca_spreads_its_pieces_over_the_workers_with_the_serial_bytes(library, pca_serial):
    motions, units = library
    with CountingRunner(2) as runner:
        asset = encode_motions(motions, units, "rma-pca", Tolerance(TOL), options={"variance": 0.95},
                               runner=runner).asset
    # the cut search and the root curves per clip, the coefficient curves per piece
    assert runner.items >= 3 * len(motions)
    assert asset == pca_serial


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


def test_dask_runs_rma_pca_to_the_serial_bytes(library, pca_serial, cluster):
    motions, units = library
    with make_runner(None, cluster.scheduler_address) as runner:
        assert encode_motions(motions, units, "rma-pca", Tolerance(TOL), options={"variance": 0.95},
                              runner=runner).asset == pca_serial


def test_dask_workers_send_where_their_clips_have_got_to(library, cluster):
    motions, lines = _within_lines(library, make_runner(None, cluster.scheduler_address))
    for m in motions:  # events and results reach the client by different routes: some report, not each
        assert any(line.startswith(f"  {m.name}: step ") for line in lines)


def test_dask_bakes_a_streamed_library_to_the_same_bytes(sample_paths, files_asset, cluster):
    lib, units = _streamed(sample_paths)
    with make_runner(None, cluster.scheduler_address) as runner:
        assert encode_motions(lib, units, "rma", Tolerance(TOL), runner=runner).asset == files_asset


def _kill_a_busy_worker(address: str, done: threading.Event, killed: list[int]) -> None:
    """Wait until a worker is encoding a clip, then SIGKILL its process."""
    from distributed import Client

    with Client(address, set_as_default=False) as client:
        pids = client.run(os.getpid)
        while not done.is_set():
            busy = [w for w, keys in client.processing().items() if any(str(k).startswith("mocodec-clip") for k in keys)]
            if busy:
                # At once: a sample clip can end within a few tenths of a second on an idle
                # machine, and a kill after its tasks are done tests nothing.
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


def _looped_bvh(source: Path, times: int, dest: Path) -> Path:
    """``source``'s motion played ``times`` over in one BVH: a bake long enough to interrupt."""
    head, motion = source.read_text().split("MOTION", 1)
    lines = motion.strip().splitlines()
    frames = [line for line in lines[2:] if line.strip()]
    dest.write_text(f"{head}MOTION\nFrames: {len(frames) * times}\n{lines[1]}\n" + "\n".join(frames * times) + "\n")
    return dest


@pytest.mark.skipif(not Path("/proc/self/task").is_dir(), reason="needs Linux /proc to find the workers")
@pytest.mark.parametrize("jobs", [2, 1])
def test_ctrl_c_stops_the_workers_and_writes_nothing(sample_paths, tmp_path, jobs):
    import subprocess
    import sys

    out_dir, tmp = tmp_path / "out", tmp_path / "tmp"
    out_dir.mkdir()
    tmp.mkdir()
    out = out_dir / "lib.mcd"
    # Each sample looped 40 times at a tight tolerance: the bake lasts long enough (tens of
    # seconds) to be interrupted while the workers encode, however fast the fitting gets.
    # The bar is on (no -q): the interrupted bar must not add lines to the one message.
    inputs = [_looped_bvh(path, 40, tmp_path / f"long_{path.name}") for path in sample_paths]
    p = subprocess.Popen([sys.executable, "-m", "mocodec", "encode", *map(str, inputs), "-o", str(out),
                          "-t", "0.05", "--units", "cmu", "--jobs", str(jobs)], stderr=subprocess.PIPE,
                         stdout=subprocess.PIPE, text=True, env={**os.environ, "TMPDIR": str(tmp)},
                         start_new_session=True, preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    deadline = time.monotonic() + 60
    if jobs > 1:
        while len(_children(p.pid)) < 3 and p.poll() is None and time.monotonic() < deadline:
            time.sleep(0.1)  # the resource tracker and two workers
        workers = _children(p.pid)
        assert len(workers) >= 3, f"the workers did not start: {p.poll()}"
    else:
        workers = []
        time.sleep(4.0)  # past the imports and the reading, into the first clip's fit
    time.sleep(0.5)
    assert p.poll() is None, "the bake ended before it was interrupted"
    os.killpg(p.pid, signal.SIGINT)
    try:
        err = p.communicate(timeout=30)[1]
    except subprocess.TimeoutExpired:
        os.killpg(p.pid, signal.SIGKILL)
        pytest.fail("the bake did not stop within 30 s of Ctrl-C")
    last = err.strip().splitlines()[-1]
    assert p.returncode == 130 and last == "mocodec: interrupted; no file was changed by the unfinished step", err
    assert [line for line in err.splitlines() if line.startswith("mocodec:")] == [last]
    assert "Traceback" not in err
    assert list(out_dir.iterdir()) == [] and list(tmp.iterdir()) == []  # no asset, no temporary file, no spool
    time.sleep(0.5)
    assert [w for w in workers if Path(f"/proc/{w}").exists() and "zombie" not in
            Path(f"/proc/{w}/status").read_text().lower()] == []


def test_a_clip_read_once_is_shared_while_held(tmp_path, monkeypatch, sample_paths) -> None:
    """A clip too large to stay resident is read again only when nothing holds it: its job and
    its check share the copy held (one read, one copy of a long clip), and a file changed since
    is read afresh."""
    import importlib
    import shutil

    loading = importlib.import_module("mocodec.load")  # (mocodec.load is also a function)
    path = tmp_path / "walk.bvh"
    shutil.copy(sample_paths[0], path)
    lib = open_library([path], resident_bytes=0)  # nothing kept: every clip read when asked for
    reads = []
    read_clips = loading.read_clips
    monkeypatch.setattr(loading, "read_clips", lambda *a: reads.append(a) or read_clips(*a))
    first = lib[0]
    assert lib.subset([0])[0] is first and lib.refs[0].load() is first and len(reads) == 1
    del first
    held = lib[0]  # dropped: read again
    assert len(reads) == 2 and lib[0] is held
    text = path.read_text()
    path.write_text(text.replace("Frame Time: .0083333", "Frame Time: 0.01"))
    os.utime(path, ns=(time.time_ns(), time.time_ns() + 10**9))
    fresh = lib[0]
    assert fresh is not held and fresh.frame_time == 0.01 and len(reads) == 3
    # A copy that keeps the modification time and size (cp -p, rsync -a) is read afresh too.
    stat = path.stat()
    other = tmp_path / "other.bvh"
    other.write_text(text.replace("Frame Time: .0083333", "Frame Time: 0.02"))
    os.utime(other, ns=(stat.st_atime_ns, stat.st_mtime_ns))
    os.replace(other, path)
    assert lib[0].frame_time == 0.02 and len(reads) == 4


@dataclasses.dataclass
class _Unhashable:
    """A transform that does not hash (a plain dataclass): its clips are read, not shared."""
    scale: float

    def __call__(self, motion):
        motion.frame_time *= self.scale
        return motion


def test_a_library_mapped_by_a_transform_that_does_not_hash_still_reads(tmp_path, sample_paths) -> None:
    lib = open_library([sample_paths[0]], resident_bytes=0).map(_Unhashable(2.0))
    a, b = lib[0], lib[0]
    assert a.frame_time == b.frame_time == pytest.approx(2 * 0.0083333)
