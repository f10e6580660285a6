"""Where the clips of a bake are encoded: in this process, in local worker processes, or on a
running Dask cluster.

Encoding a clip (fitting its keys, checking it through the runtime) needs nothing from the other
clips, so a codec hands its clips to a :class:`Runner` as :class:`ClipJob` objects and gets the
:class:`ClipOutcome` objects back in clip order; the section and the asset are assembled here, so
the asset's bytes do not depend on where or in which order the clips ran. Jobs start longest
first, so that a long clip does not start last and leave the other workers idle. A runner with a
:class:`~.cache.ClipCache` encodes only the clips it does not hold.

Memory stays bounded however long the library: a job names its clip (a
:class:`~.library.ClipRef` the worker reads) rather than carrying it, only as many jobs as there
are workers are in flight at once, and each finished payload goes to a
:class:`~.spool.PayloadSpool` on disk until the asset is assembled.
"""
from __future__ import annotations

import concurrent.futures as cf
import contextlib
import dataclasses
import functools
import multiprocessing
import os
import queue
import signal
import sys
import threading
import time
import warnings
from dataclasses import dataclass, field
from typing import Any, Callable, Iterator, Sequence

from ..motion import Motion
from .cache import ClipCache, job_key
from .fingerprint import encoder_fingerprint
from .library import ClipRef
from .progress import reporting, within_clip
from .spool import PayloadSpool

ProgressFn = Callable[[str], None]
"""``progress(name)`` when a clip is done. A progress object may also have ``started(name)``
(a worker took the clip) and ``hit(name)`` (the clip came from the cache; else ``progress``)."""

WAIT_FOR_WORKERS_S = 60.0
"""How long a bake waits for a Dask scheduler to have a worker before it gives up."""

CONNECT_TIMEOUT_S = 10.0
"""How long connecting to a Dask scheduler may take."""

REPORTS_EVERY_S = 0.5
"""How often a parent waiting for its workers' clips passes on their reports from within a clip
(the :class:`~.progress.Progress` decides what it shows)."""

WITHIN_TOPIC = "mocodec-within"
"""The Dask event topic of a clip's reports from within (a worker's ``log_event``), followed by
the client's id: topics are the scheduler's, and two bakes on one cluster see only their own."""

DASK_POLL_S = 0.1
"""How often a parent waiting for a Dask cluster's clips looks for their reports (as often as
``distributed.as_completed`` itself looks for a finished task)."""


class BakeError(RuntimeError):
    """The clips could not be run: a worker process died, the cluster cannot be reached or has
    no workers, a worker runs other encoder code. The message says which and what to do."""


class EncoderMismatch(BakeError):
    """A Dask worker's mocodec differs from the client's (its asset would differ too)."""


@dataclass
class ClipJob:
    """One clip to encode: ``encode_clip(motion, cm_per_unit, settings, check)`` of its codec;
    ``motion`` is the clip or a :class:`~.library.ClipRef` to it (read where the job runs).

    ``check`` (payload -> world error, the clip alone through the runtime, in a section that
    starts with ``prefix``) and everything else here must pickle for a process or Dask runner.
    ``fingerprint``: the client's :func:`~.fingerprint.encoder_fingerprint` (without binaries),
    set by runners whose workers may run other code. ``report_to``: the Dask client the clip's
    reports from within go to (its id), set by the Dask runner."""

    name: str
    encode_clip: Callable[..., Any]
    motion: Motion | ClipRef
    cm_per_unit: float
    settings: Any
    check: Callable[[bytes], Any]
    prefix: bytes = b""
    fingerprint: str = ""
    report_to: str = ""

    @property
    def weight(self) -> int:
        """A guess of the work: frames times nodes."""
        if isinstance(self.motion, ClipRef):
            return self.motion.weight
        return self.motion.frame_count * self.motion.skeleton.node_count

    def load(self) -> Motion:
        """The clip (read from its file for a ref)."""
        return self.motion.load() if isinstance(self.motion, ClipRef) else self.motion

    def carried(self) -> "ClipJob":
        """This job with the clip's frames in it, and in its check, rather than a ref to its
        file (for workers on other machines)."""
        if not isinstance(self.motion, ClipRef):
            return self
        motion = self.load()
        carrying = getattr(self.check, "carrying", None)
        return dataclasses.replace(self, motion=motion, check=carrying(motion) if carrying else self.check)


@dataclass
class ClipOutcome:
    """What a bake keeps of an encoded clip: its payload, the codec's stats, the seconds it took
    (when it was encoded, for a clip from the cache)."""

    payload: bytes
    stats: dict[str, Any] = field(default_factory=dict)
    seconds: float = 0.0
    cached: bool = False


def _same_encoder(fingerprint: str, fn: Callable[[Any], Any], item: Any) -> Any:
    """``fn(item)`` on a Dask worker that runs the client's mocodec code (else the asset could
    mix two encoders' output)."""
    if fingerprint != encoder_fingerprint(binaries=False):
        raise EncoderMismatch(f"a Dask worker runs other mocodec code than this client (fingerprint "
                              f"{encoder_fingerprint(binaries=False)[:12]} vs {fingerprint[:12]}); install the "
                              "same mocodec on the workers")
    return fn(item)


_REPORTS: Any = None
"""In a worker process of a :class:`ProcessRunner`: the queue its clips' reports from within go
to (the parent reads it)."""


NAME_BYTES, STATUS_BYTES = 300, 150
"""A worker sends a report only when the clip's name fits in NAME_BYTES (UTF-8), and cuts its
status to STATUS_BYTES: pickled and framed, a report is then under 512 bytes, one write to the
pipe on every system (POSIX: PIPE_BUF >= 512), so a worker killed in the middle of a put cannot
leave half a report for the parent to wait on."""


def _to_queue(name: str, status: str) -> None:
    if len(name.encode()) > NAME_BYTES:
        return
    try:
        _REPORTS.put((name, status.encode()[:STATUS_BYTES].decode(errors="ignore")))
    except (OSError, ValueError):  # the parent closed it (stopping): a report is not worth a failed clip
        pass


def _report_sender(job: ClipJob) -> Callable[[str, str], None] | None:
    """Where the reports from within ``job``'s clip go from this process: the parent's queue in
    a worker process, the client's event topic on a Dask worker, else None (a clip in the
    parent's own process reports straight to its progress: :meth:`Runner._dispatch`)."""
    if _REPORTS is not None:
        return _to_queue
    if not job.report_to or "distributed" not in sys.modules:  # a Dask worker has it imported
        return None
    from distributed import get_worker

    try:
        worker = get_worker()
    except ValueError:  # not on a worker
        return None
    topic = f"{WITHIN_TOPIC}-{job.report_to}"

    def to_dask(name: str, status: str) -> None:
        try:
            worker.log_event(topic, {"name": name, "status": status})
        except (OSError, ValueError, RuntimeError):  # a worker shutting down: as above
            pass

    return to_dask


def run_job(job: ClipJob) -> ClipOutcome:
    """Encode one clip (in whichever process runs it)."""
    if job.fingerprint and job.fingerprint != encoder_fingerprint(binaries=False):
        raise EncoderMismatch(
            f"clip {job.name!r}: a Dask worker runs other mocodec code than this client (fingerprint "
            f"{encoder_fingerprint(binaries=False)[:12]} vs {job.fingerprint[:12]}); install the same "
            "mocodec on the workers")
    send = _report_sender(job)
    with reporting(job.name, send) if send is not None else contextlib.nullcontext():
        r = job.encode_clip(job.load(), job.cm_per_unit, job.settings, job.check)
    return ClipOutcome(r.payload, dict(r.stats), float(r.seconds))


def _pass_on(reports: Any, progress: ProgressFn | None) -> None:
    """Give the workers' reports from within a clip waiting in ``reports`` (a queue this thread
    alone reads, so ``get`` after ``empty`` does not wait; None: none) to ``progress.within``
    (if it has it)."""
    within = getattr(progress, "within", None)
    while reports is not None and not reports.empty():
        name, status = reports.get()
        if within is not None:
            within(name, status)


class Runner:
    """Runs clip jobs, each once, and returns their outcomes in job order (a context manager:
    leaving it stops what it started)."""

    workers = 1

    def __init__(self, cache: ClipCache | None = None) -> None:
        self.cache = cache

    def run(self, jobs: Sequence[ClipJob], progress: ProgressFn | None = None) -> list[ClipOutcome]:
        """The outcome of every job, in the order of ``jobs``; ``progress(name)`` after each.
        Payloads wait in a spool file until all are done; an outcome's payload is a read-only
        view of it. An error of one clip (its codec's, or :class:`BakeError`) stops the others
        and is raised."""
        outcomes: list[ClipOutcome | None] = [None] * len(jobs)
        keys: dict[int, str] = {}
        to_encode: list[tuple[int, ClipJob]] = []
        with PayloadSpool() as spool:
            for i, job in enumerate(jobs):
                if self.cache is not None:
                    keys[i] = job_key(job)
                    hit = self.cache.get(keys[i])
                    if hit is not None:
                        outcomes[i] = self._spooled(spool, i, hit)
                        _report(progress, "hit", job.name) or (progress and progress(job.name))
                        continue
                to_encode.append((i, job))
            to_encode.sort(key=lambda item: -item[1].weight)  # stable: equal weights keep clip order
            for i, outcome in self._dispatch(to_encode, progress):
                if self.cache is not None:
                    self.cache.put(keys[i], outcome)
                outcomes[i] = self._spooled(spool, i, outcome)
                if progress:
                    progress(jobs[i].name)
            views = spool.views(list(range(len(jobs))))
        for o, view in zip(outcomes, views):
            assert o is not None
            o.payload = view  # type: ignore[assignment]
        return outcomes  # type: ignore[return-value]

    def map(self, fn: Callable[[Any], Any], items: Sequence[Any]) -> list[Any]:
        """``[fn(x) for x in items]``, spread over this runner's workers: for a codec whose clips
        share a fit (rma-pca), the parts of its work that are per clip or per piece. ``fn`` is a
        module-level function (it is pickled); an error of one item stops the others and is
        raised."""
        return [fn(x) for x in items]

    @staticmethod
    def _spooled(spool: PayloadSpool, i: int, outcome: ClipOutcome) -> ClipOutcome:
        spool.add(i, outcome.payload)
        return dataclasses.replace(outcome, payload=b"")

    def _dispatch(self, to_encode: list[tuple[int, ClipJob]],
                  progress: ProgressFn | None = None) -> Iterator[tuple[int, ClipOutcome]]:
        """(position, outcome) of every job of ``to_encode`` as it finishes."""
        for i, job in to_encode:
            _report(progress, "started", job.name)
            with within_clip(progress, job.name):
                outcome = run_job(job)
            yield i, outcome

    def close(self) -> None:
        """Stop the workers this runner started."""

    def __enter__(self) -> "Runner":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _report(progress: ProgressFn | None, event: str, name: str) -> bool:
    """Call ``progress.event(name)`` when the progress object has it; whether it did."""
    method = getattr(progress, event, None)
    if method is None:
        return False
    method(name)
    return True


def _windowed(to_encode: list[tuple[int, ClipJob]], window: int, submit: Callable[[ClipJob], Any],
              wait_one: Callable[[set], Any], progress: ProgressFn | None) -> Iterator[tuple[Any, int, ClipJob]]:
    """Submit the jobs of ``to_encode`` in order, at most ``window`` in flight (the parent holds only
    those, not one future per clip of the library); yield (future, position, job) as each ends.
    ``wait_one(in_flight)`` returns a finished future of the set."""
    pending = iter(to_encode)
    in_flight: dict[Any, tuple[int, ClipJob]] = {}

    def top_up() -> None:
        while len(in_flight) < window:
            item = next(pending, None)
            if item is None:
                return
            in_flight[submit(item[1])] = item
            _report(progress, "started", item[1].name)

    top_up()
    while in_flight:
        f = wait_one(set(in_flight))
        i, job = in_flight.pop(f)
        yield f, i, job
        top_up()


class SerialRunner(Runner):
    """Every clip in this process, one after the other (``--jobs 1``)."""


def _ignore_interrupt() -> None:
    # Ctrl-C goes to the whole process group: the parent stops the workers, each of which
    # would otherwise print its own KeyboardInterrupt traceback.
    signal.signal(signal.SIGINT, signal.SIG_IGN)


def _start_worker(reports: Any) -> None:
    """A worker process's start: Ctrl-C ignored, its clips' reports to ``reports``."""
    global _REPORTS
    _ignore_interrupt()
    _REPORTS = reports


BLAS_THREADS = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")
"""What a worker process's numpy may run beside it: one thread (the workers fill the cores;
a BLAS pool in each, spinning for a core, made rma-pca's bake 5x slower on two)."""


@contextlib.contextmanager
def _starting_workers() -> Iterator[None]:
    """Around the submits that start worker processes: each starts with one BLAS thread, and
    with Ctrl-C held off until its initializer ignores it (a Ctrl-C while a worker is still
    importing would print that worker's own traceback).

    The main thread blocks SIGINT here rather than ignoring it: a started process inherits the
    blocked mask (fork and exec keep it), and in this process a Ctrl-C that comes meanwhile
    stays pending and is delivered when the block ends, where an ignored one was lost."""
    saved = {name: os.environ.get(name) for name in BLAS_THREADS}
    os.environ.update({name: "1" for name in BLAS_THREADS})
    main = threading.current_thread() is threading.main_thread()
    block = main and hasattr(signal, "pthread_sigmask")
    # Windows has no signal masks: there the old way, Ctrl-C ignored for the moment.
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN) if main and not block else None
    mask = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT}) if block else None
    try:
        yield
    finally:
        for name, value in saved.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value
        if block:
            signal.pthread_sigmask(signal.SIG_SETMASK, mask)  # a pending Ctrl-C arrives here
        elif main:
            signal.signal(signal.SIGINT, previous)


class ProcessRunner(Runner):
    """Clips in ``workers`` local processes at once (``--jobs N``), started when first needed
    and kept until :meth:`close`."""

    def __init__(self, workers: int, cache: ClipCache | None = None) -> None:
        super().__init__(cache)
        if workers < 1:
            raise ValueError(f"--jobs must be at least 1, got {workers}")
        self.workers = workers
        self._pool: cf.ProcessPoolExecutor | None = None
        self._reports: Any = None  # the workers' reports from within a clip

    def _executor(self) -> cf.ProcessPoolExecutor:
        if self._pool is None:
            # Spawned, not forked: the parent may hold threads (a progress bar) and their locks;
            # and the workers are this process's children, so `time` counts their CPU.
            context = multiprocessing.get_context("spawn")
            # A SimpleQueue writes in put() itself (a Queue leaves it to a thread): a clip's
            # reports are in the pipe before its outcome is sent, so none arrive after it ended.
            self._reports = context.SimpleQueue()
            self._pool = cf.ProcessPoolExecutor(self.workers, mp_context=context, initializer=_start_worker,
                                                initargs=(self._reports,))
        return self._pool

    def _dispatch(self, to_encode: list[tuple[int, ClipJob]],
                  progress: ProgressFn | None = None) -> Iterator[tuple[int, ClipOutcome]]:
        if len(to_encode) <= 1:  # starting a process would only add its start-up time
            yield from super()._dispatch(to_encode, progress)
            return
        pool = self._executor()
        submitted: list[cf.Future] = []

        def submit(job: ClipJob) -> cf.Future:
            if len(submitted) < self.workers:  # the pool starts a worker on each of these submits
                with _starting_workers():
                    f = pool.submit(run_job, job)
            else:
                f = pool.submit(run_job, job)
            submitted.append(f)
            return f

        def wait_one(futures: set) -> cf.Future:
            while True:  # woken now and then to pass on the reports from within the clips
                done = cf.wait(futures, timeout=REPORTS_EVERY_S, return_when=cf.FIRST_COMPLETED).done
                _pass_on(self._reports, progress)
                if done:
                    return next(iter(done))

        try:
            for f, i, job in _windowed(to_encode, self.workers, submit, wait_one, progress):
                try:
                    outcome = f.result()
                except cf.process.BrokenProcessPool:
                    raise BakeError(f"clip {job.name!r}: a worker process died while encoding (killed, or "
                                    "out of memory: try fewer --jobs); nothing was written") from None
                yield i, outcome
        except BaseException:
            for f in submitted:
                f.cancel()
            self.close(kill=True)
            raise

    def map(self, fn: Callable[[Any], Any], items: Sequence[Any]) -> list[Any]:
        if len(items) <= 1:
            return super().map(fn, items)
        pool = self._executor()
        futures: list[cf.Future] = []
        try:
            with _starting_workers():  # the first submits start the workers
                futures = [pool.submit(fn, x) for x in items]
            return [f.result() for f in futures]
        except cf.process.BrokenProcessPool:
            self.close(kill=True)
            raise BakeError("a worker process died (killed, or out of memory: try fewer --jobs); "
                            "nothing was written") from None
        except BaseException:
            for f in futures:
                f.cancel()
            self.close(kill=True)
            raise

    def close(self, kill: bool = False) -> None:
        pool, self._pool = self._pool, None
        reports, self._reports = self._reports, None
        if pool is None:
            return
        if kill:  # a clip failed or the user interrupted: the other clips' work is not wanted
            for p in list(getattr(pool, "_processes", {}).values()):
                p.terminate()
        pool.shutdown(wait=True, cancel_futures=True)
        if reports is not None:
            reports.close()


class DaskRunner(Runner):
    """Clips as tasks of a running Dask distributed scheduler (``--scheduler ADDRESS``). A worker
    that dies takes its clip to another worker (up to the scheduler's
    ``distributed.scheduler.allowed-failures``, then the bake fails)."""

    def __init__(self, address: str, cache: ClipCache | None = None) -> None:
        super().__init__(cache)
        try:
            from distributed import Client
        except ImportError:
            raise BakeError("--scheduler needs Dask's distributed scheduler: pip install 'mocodec[cluster]'") from None
        self.address = address
        try:
            self.client = Client(address, timeout=CONNECT_TIMEOUT_S, set_as_default=False)
        except (OSError, TimeoutError, ValueError, TypeError) as exc:
            reason = (str(exc) or type(exc).__name__).splitlines()[0]
            raise BakeError(f"cannot reach the Dask scheduler at {address!r}: {reason}") from None
        self.workers = max(1, len(self.client.scheduler_info().get("workers", {})))

    def _wait_for_workers(self) -> None:
        try:
            self.client.wait_for_workers(1, timeout=WAIT_FOR_WORKERS_S)
        except TimeoutError:
            raise BakeError(f"the Dask scheduler at {self.address} has no workers (waited {WAIT_FOR_WORKERS_S:g} s): "
                            f"start some with `dask worker {self.address}`") from None

    def _dispatch(self, to_encode: list[tuple[int, ClipJob]],
                  progress: ProgressFn | None = None) -> Iterator[tuple[int, ClipOutcome]]:
        if not to_encode:
            return
        from distributed import KilledWorker, as_completed

        self._wait_for_workers()
        fingerprint = encoder_fingerprint(binaries=False)
        workers = max(1, len(self.client.scheduler_info().get("workers", {})))
        in_flight: set = set()
        finished = as_completed(loop=self.client.loop)  # this client's futures, as they end
        # The workers' reports from within a clip arrive on the client's event loop thread.
        received: queue.SimpleQueue = queue.SimpleQueue()
        topic = f"{WITHIN_TOPIC}-{self.client.id}"
        self.client.subscribe_topic(topic, lambda event: received.put((event[1]["name"], event[1]["status"])))

        def submit(job: ClipJob) -> Any:
            with warnings.catch_warnings():
                # A clip's frames are its task's argument (a long clip is a large one, by design):
                # a worker needs no access to the input files.
                warnings.filterwarnings("ignore", message=".*[Ll]arge.*")
                f = self.client.submit(run_job, dataclasses.replace(job.carried(), fingerprint=fingerprint,
                                                                    report_to=self.client.id),
                                       pure=False, key=f"mocodec-clip-{os.urandom(8).hex()}")
            in_flight.add(f)
            finished.add(f)
            return f

        def wait_one(futures: set) -> Any:
            while not finished.has_ready() and not finished.is_empty():
                _pass_on(received, progress)
                time.sleep(DASK_POLL_S)
            _pass_on(received, progress)
            f = next(finished)
            in_flight.discard(f)
            return f

        try:
            # Two tasks a worker: the next clip is there when one ends (a network away).
            for f, i, job in _windowed(to_encode, 2 * workers, submit, wait_one, progress):
                try:
                    outcome = f.result()
                except KilledWorker:
                    raise BakeError(f"clip {job.name!r}: Dask workers died while encoding it, more often than "
                                    "the scheduler retries a task (distributed.scheduler.allowed-failures); "
                                    "nothing was written") from None
                except cf.CancelledError:
                    raise BakeError(f"clip {job.name!r}: the Dask scheduler at {self.address} dropped the task "
                                    "(restarted or lost?); nothing was written") from None
                yield i, outcome
        except BaseException:
            self.client.cancel(list(in_flight), force=True)
            raise
        finally:
            # A client that lost its scheduler cannot unsubscribe: the error that ended the bake matters.
            with contextlib.suppress(Exception):
                self.client.unsubscribe_topic(topic)

    def map(self, fn: Callable[[Any], Any], items: Sequence[Any]) -> list[Any]:
        if not items:
            return []
        from distributed import KilledWorker

        self._wait_for_workers()
        with warnings.catch_warnings():
            warnings.filterwarnings("ignore", message=".*[Ll]arge.*")  # the items are the work, by design
            futures = self.client.map(functools.partial(_same_encoder, encoder_fingerprint(binaries=False), fn),
                                      list(items), pure=False,
                                      key=[f"mocodec-part-{os.urandom(8).hex()}" for _ in items])
        try:
            return self.client.gather(futures)
        except KilledWorker:
            raise BakeError("Dask workers died more often than the scheduler retries a task "
                            "(distributed.scheduler.allowed-failures); nothing was written") from None
        except BaseException:
            self.client.cancel(futures, force=True)
            raise

    def close(self) -> None:
        client, self.client = getattr(self, "client", None), None
        if client is not None:
            client.close()


def default_jobs() -> int:
    """The cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return os.cpu_count() or 1


def make_runner(jobs: int | None = None, scheduler: str | None = None,
                cache: str | os.PathLike | None = None) -> Runner:
    """The runner of ``--jobs``/``--scheduler``/``--cache``: a Dask cluster when ``scheduler``
    is given, else ``jobs`` local processes (None: :func:`default_jobs`; 1: this process)."""
    store = ClipCache(cache) if cache is not None else None
    if scheduler:
        if jobs is not None:
            raise ValueError("--jobs and --scheduler exclude each other: a Dask cluster has its own workers")
        return DaskRunner(scheduler, store)
    n = default_jobs() if jobs is None else int(jobs)
    if n < 1:
        raise ValueError(f"--jobs must be at least 1, got {n}")
    return SerialRunner(store) if n == 1 else ProcessRunner(n, store)
