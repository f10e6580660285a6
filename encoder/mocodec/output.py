"""Writing output files so that a failure never costs the user a file: each file is written to
a temporary file in the same folder, flushed to disk and renamed over the target only when it is
complete (a full disk, Ctrl-C or SIGTERM leave the previous file as it was), and an output that
is one of the command's own inputs is refused before any work is done.
"""
from __future__ import annotations

import contextlib
import os
import secrets
from pathlib import Path
from typing import IO, Iterable, Iterator

from .limits import printable


class OutputError(ValueError):
    """An output path that cannot be used; the message names it."""


def _same_file(a: Path, b: Path) -> bool:
    try:
        return os.path.samefile(a, b)
    except OSError:  # one of them does not exist (yet)
        return os.path.realpath(a) == os.path.realpath(b)


def check_output(output: str | os.PathLike, inputs: Iterable[str | os.PathLike],
                 folder_made: bool = False) -> Path:
    """``output`` as a path, after refusing it when it is one of ``inputs`` (the same file by
    any name: a link, ``./x``, another spelling), an existing folder where a file is meant, or
    in a folder that is not there (checked before the work, not when the file is written at its
    end; ``folder_made``: the caller makes the folder)."""
    out = Path(output)
    for item in inputs:
        if _same_file(out, Path(item)):
            raise OutputError(f"{printable(str(out))}: the output is the input {printable(str(item))}; "
                              "give another output path")
    if out.is_dir():
        raise OutputError(f"{printable(str(out))}: is a folder; give a file name")
    folder = out.parent
    if not folder_made and not folder.is_dir():
        where = printable(str(folder))
        raise OutputError(f"{printable(str(out))}: " + (f"{where} is not a folder" if folder.exists()
                                                        else f"the folder {where} does not exist"))
    return out


@contextlib.contextmanager
def atomic_open(path: str | os.PathLike, mode: str = "wb", **kwargs) -> Iterator[IO]:
    """A file object whose contents replace ``path`` when the ``with`` block ends without an
    exception, and that is removed otherwise (``KeyboardInterrupt`` and ``SystemExit`` too).

    The temporary file lies beside the target (a rename within one file system is atomic),
    gets the permissions a new file would get (``0o666`` less the umask), and is synced before
    the rename. A symbolic link at ``path`` stays and its target is replaced."""
    if "w" not in mode or "+" in mode or "a" in mode:
        raise ValueError(f"atomic_open writes a whole file: mode 'w' or 'wb', not {mode!r}")
    target = Path(os.path.realpath(path))
    tmp = target.with_name(f".{target.name}.{secrets.token_hex(4)}.tmp")
    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
    try:
        with os.fdopen(fd, mode, **kwargs) as f:
            yield f
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, target)
    except BaseException as exc:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        if isinstance(exc, OSError) and exc.filename is None:  # a full disk: say which file
            raise OSError(exc.errno, f"{exc.strerror} (not written; a file that was there is unchanged)",
                          str(path)) from exc
        raise


def write_atomic(path: str | os.PathLike, data: bytes | str, encoding: str = "utf-8") -> None:
    """Write ``data`` (bytes, or text in ``encoding``) to ``path`` with :func:`atomic_open`."""
    if isinstance(data, str):
        with atomic_open(path, "w", encoding=encoding, newline="") as f:
            f.write(data)
    else:
        with atomic_open(path, "wb") as f:
            f.write(data)
