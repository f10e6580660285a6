"""Opening and reading input files, refusing early what would block, never end or fill memory: only
regular files are read (a FIFO would wait for a writer forever, ``/dev/zero`` never ends), and a
file larger than :data:`MAX_INPUT_BYTES` is refused from its size before a byte is read."""
from __future__ import annotations

import contextlib
import os
import stat
from typing import BinaryIO, Callable, Iterator

MAX_INPUT_BYTES = 4 << 30
"""4 GiB: far above a 2-hour capture as BVH text (about 1 GB at 120 Hz and 100 channels)."""


def _kind(mode: int) -> str:
    if stat.S_ISDIR(mode):
        return "a folder"
    if stat.S_ISFIFO(mode):
        return "a FIFO"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "a device"
    return "a socket" if stat.S_ISSOCK(mode) else "not a regular file"


@contextlib.contextmanager
def open_regular_file(path: str | os.PathLike, what: str, error: Callable[[str], Exception],
                      limit: int = MAX_INPUT_BYTES) -> Iterator[BinaryIO]:
    """``path`` opened for reading bytes, or ``error(message)`` raised: it cannot be opened, is
    not a regular file (``"a FIFO, not a {what} (only regular files are read)"``) or is larger
    than ``limit`` (from its size, before a byte is read)."""
    try:
        # O_NONBLOCK: opening a FIFO does not wait for a writer; fstat then refuses it.
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    except OSError as exc:
        raise error(f"cannot read: {exc.strerror or exc}") from None
    try:
        try:
            info = os.fstat(fd)
        except OSError as exc:
            raise error(f"cannot read: {exc.strerror or exc}") from None
        if not stat.S_ISREG(info.st_mode):
            raise error(f"{_kind(info.st_mode)}, not a {what} (only regular files are read)")
        if info.st_size > limit:
            raise error(f"{info.st_size:,} bytes; files over {limit:,} bytes are not read")
        try:
            f = os.fdopen(fd, "rb")
        except OSError as exc:
            raise error(f"cannot read: {exc.strerror or exc}") from None
    except BaseException:
        os.close(fd)
        raise
    with f:
        yield f


def too_large(limit: int = MAX_INPUT_BYTES) -> str:
    """The message for a file that grew past ``limit`` while it was read."""
    return f"more than {limit:,} bytes; files over {limit:,} bytes are not read"


def read_regular_file(path: str | os.PathLike, what: str, error: Callable[[str], Exception],
                      limit: int = MAX_INPUT_BYTES) -> bytes:
    """The bytes of ``path`` (:func:`open_regular_file`'s checks), or ``error(message)``
    raised, also for a file that grows past ``limit`` while it is read."""
    with open_regular_file(path, what, error, limit) as f:
        try:
            # read(n) reserves n bytes up front: ask for the stated size, then in small pieces
            # for a file that grows while it is read, up to the limit.
            parts = [f.read(min(os.fstat(f.fileno()).st_size, limit + 1))]
            total = len(parts[0])
            while total <= limit:
                more = f.read(1 << 16)
                if not more:
                    break
                parts.append(more)
                total += len(more)
            data = parts[0] if len(parts) == 1 else b"".join(parts)
        except OSError as exc:
            raise error(f"cannot read: {exc.strerror or exc}") from None
    if len(data) > limit:
        raise error(too_large(limit))
    return data
