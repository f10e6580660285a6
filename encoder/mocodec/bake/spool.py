"""Finished clip payloads on disk until the asset is assembled, so that a bake holds none of
them in memory while its workers run.

The spool is an unnamed temporary file (:func:`tempfile.TemporaryFile`): nothing of it is left
in the folder whatever stops the bake (Ctrl-C, a kill, a crash). When every clip is in, it is
mapped read-only and each payload is a :class:`memoryview` of the map, which the asset builder
copies into its section.
"""
from __future__ import annotations

import mmap
import tempfile


class PayloadSpool:
    """Payloads appended one by one (:meth:`add`), read back by :meth:`views` in the order given."""

    def __init__(self) -> None:
        self._file = tempfile.TemporaryFile(prefix="mocodec-spool-")
        self._spans: dict[int, tuple[int, int]] = {}
        self._size = 0

    def add(self, key: int, payload: bytes) -> None:
        """Append the payload of clip ``key`` (bytes-like)."""
        self._file.write(payload)
        self._spans[key] = (self._size, len(payload))
        self._size += len(payload)

    def __len__(self) -> int:
        return len(self._spans)

    def views(self, keys: list[int]) -> list[memoryview]:
        """The payloads of ``keys``, read-only views of the spool (valid while one is held);
        the file is closed (its map lives on until the last view goes)."""
        self._file.flush()
        if self._size == 0:
            self.close()
            return [memoryview(b"") for _ in keys]
        mapped = memoryview(mmap.mmap(self._file.fileno(), self._size, access=mmap.ACCESS_READ))
        self.close()
        return [mapped[off:off + n] for off, n in (self._spans[k] for k in keys)]

    def close(self) -> None:
        self._file.close()

    def __enter__(self) -> "PayloadSpool":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
