"""What a person watching a bake sees: one bar with clips done / total, the time left, and the
clip each worker is on; a line per clip where stderr is not a terminal (logs stay readable).

A :class:`Progress` is the ``progress`` of :meth:`~.runners.Runner.run`: called with a clip's
name when it is done, told by ``started(name)`` when a worker takes one and by ``hit(name)``
when one comes from the cache.

Within a clip: a codec's long work calls :func:`report_within` (the windows of a long capture),
and the clip shows where it has got to, on the bar beside its worker or as a line, at most every
``within_every`` seconds, so a two-hour capture is not silent for minutes. A clip encoded in
this process reports straight to the :class:`Progress`; one in a worker process or on a Dask
worker sends its reports to the parent (:mod:`.runners`), which passes them on.
"""
from __future__ import annotations

import contextlib
import contextvars
import sys
import time
from typing import IO, Any, Callable, Iterator

from ..limits import printable

_WITHIN: contextvars.ContextVar[Callable[[str], None] | None] = contextvars.ContextVar("mocodec_within",
                                                                                      default=None)


def report_within(status: str) -> None:
    """Where the clip being encoded in this process has got to (``status``, e.g. "window 12 of
    211"); shown by the :class:`Progress` watching it, if any, else nothing."""
    show = _WITHIN.get()
    if show is not None:
        show(status)


@contextlib.contextmanager
def reporting(name: str, send: Callable[[str, str], None] | None) -> Iterator[None]:
    """Around the encoding of clip ``name``: its :func:`report_within` calls go to
    ``send(name, status)`` (None: nowhere)."""
    token = _WITHIN.set(None if send is None else (lambda status: send(name, status)))
    try:
        yield
    finally:
        _WITHIN.reset(token)


def within_clip(progress: Any, name: str) -> contextlib.AbstractContextManager[None]:
    """Around the encoding of clip ``name`` in this process: its :func:`report_within` calls go
    to ``progress.within(name, status)`` when ``progress`` has that method (a :class:`Progress`
    shows them while the clip is running: between ``started(name)`` and ``progress(name)``)."""
    return reporting(name, getattr(progress, "within", None))


class Progress:
    """Progress of ``total`` steps on ``stream`` (stderr); ``enabled=False`` (``--quiet``,
    ``--json``) shows nothing. Fewer than two steps show no count, but still where a long clip
    has got to (:meth:`within`): shown at least ``within_every`` seconds after the last time
    (or the start)."""

    def __init__(self, total: int, enabled: bool = True, stream: IO[str] | None = None,
                 bar: bool | None = None, within_every: float = 10.0) -> None:
        self.total, self.done, self.hits = total, 0, 0
        self.stream = stream if stream is not None else sys.stderr
        self.watching = enabled
        self.enabled = enabled and total >= 2
        self.started_at = time.perf_counter()
        self.within_every = within_every
        self._within_at = self.started_at
        self.slots: dict[int, str] = {}  # worker slot -> the clip it is on
        self.status: dict[str, str] = {}  # a running clip -> where it has got to (within)
        self._shown: dict[str, str] = {}  # what the lines have shown of it
        self._bar = None
        if self.enabled and (bar if bar is not None else self.stream.isatty()):
            from tqdm import tqdm

            self._bar = tqdm(total=total, unit="clip", file=self.stream, dynamic_ncols=True)

    def started(self, name: str) -> None:
        """A worker took clip ``name``: it gets the lowest free slot."""
        slot = next(k for k in range(len(self.slots) + 1) if k not in self.slots)
        self.slots[slot] = name
        self._show()

    def hit(self, name: str) -> None:
        """Clip ``name`` came from the cache."""
        self.hits += 1
        self(name)

    def __call__(self, name: str) -> None:
        """Clip (or step) ``name`` is done."""
        self.done += 1
        for slot, running in list(self.slots.items()):
            if running == name:
                del self.slots[slot]
                break
        self.status.pop(name, None)
        self._shown.pop(name, None)
        if self._bar is not None:
            self._bar.set_postfix_str(self.postfix(), refresh=False)
            self._bar.update(1)
            if self.done >= self.total:
                self.close()
        elif self.enabled:
            print(f"  [{self.done}/{self.total}] {printable(name)} ({time.perf_counter() - self.started_at:.1f}s)",
                  file=self.stream, flush=True)

    def within(self, name: str, status: str) -> None:
        """Running clip ``name`` has got to ``status``. Shown, with every other running clip's
        news, when ``within_every`` seconds have passed since the last time (or the start): on
        the bar beside the clip's worker, or a line a clip. A report of a clip not running (one
        from a worker that arrives after its clip ended) is dropped."""
        if not self.watching or name not in self.slots.values():
            return
        self.status[name] = status
        now = time.perf_counter()
        if now - self._within_at < self.within_every:
            return
        self._within_at = now
        if self._bar is not None:
            self._bar.set_postfix_str(self.postfix(), refresh=True)
            return
        for running in self.slots.values():
            news = self.status.get(running)
            if news is not None and self._shown.get(running) != news:
                self._shown[running] = news
                print(f"  {printable(running)}: {news} ({now - self.started_at:.1f}s)", file=self.stream, flush=True)

    def postfix(self) -> str:
        """The bar's tail: each worker's clip (and where it has got to), the cache hits so far."""
        running = "  ".join(f"w{slot + 1} {printable(name)}" + (f": {self.status[name]}" if name in self.status else "")
                            for slot, name in sorted(self.slots.items()))
        hits = f"  ({self.hits} cached)" if self.hits else ""
        return running + hits

    def _show(self) -> None:
        if self._bar is not None:
            self._bar.set_postfix_str(self.postfix(), refresh=True)

    def close(self) -> None:
        """End the bar (a Ctrl-C ends it where it was)."""
        bar, self._bar = self._bar, None
        if bar is not None:
            bar.close()
