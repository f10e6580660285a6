"""A folder of encoded clips (``--cache DIR``), so that re-baking a library after a few clips
changed encodes those clips only.

An entry is one clip's payload and stats under a key that hashes everything its bytes depend
on (:func:`job_key`): the clip's content, the codec's settings (the tolerance among them), the
section header it was checked in, the codec's function and the encoder's code
(:func:`~.fingerprint.encoder_fingerprint`). Changing any of them misses; a stale entry is never
read because nothing in its key can match. Entries are written whole (a temporary file renamed
into place), so bakes sharing a folder at the same time, or one killed while writing, leave no
torn entry; an entry whose bytes do not match its header's hash is treated as absent.
"""
from __future__ import annotations

import hashlib
import json
import os
import secrets
from pathlib import Path
from typing import TYPE_CHECKING

from .fingerprint import encoder_fingerprint, motion_digest, settings_digest

if TYPE_CHECKING:
    from .runners import ClipJob, ClipOutcome

FORMAT = 1
"""Layout of an entry: one JSON line (format, payload size and SHA-256, stats, seconds), then
the payload."""


def job_key(job: "ClipJob") -> str:
    """The cache key of ``job``: a SHA-256 over what its payload depends on."""
    fn = job.encode_clip
    parts = {
        "format": FORMAT,
        "encoder": encoder_fingerprint(binaries=True),
        "codec": f"{fn.__module__}.{fn.__qualname__}",
        "settings": settings_digest(job.settings),
        "cm_per_unit": repr(float(job.cm_per_unit)),
        "prefix": job.prefix.hex(),
        "motion": motion_digest(job.load()),
    }
    return hashlib.sha256(json.dumps(parts, sort_keys=True).encode()).hexdigest()


def _plain(value: object) -> object:
    """numpy numbers and arrays in a codec's stats, as JSON numbers and lists."""
    if hasattr(value, "tolist"):
        return value.tolist()
    raise TypeError(f"cannot store {type(value).__name__} in the clip cache")


class ClipCache:
    """Encoded clips in the folder ``root`` (created when needed), one file per key."""

    def __init__(self, root: str | os.PathLike) -> None:
        self.root = Path(root)
        if self.root.exists() and not self.root.is_dir():
            raise NotADirectoryError(f"{self.root}: the cache must be a folder")

    def _path(self, key: str) -> Path:
        return self.root / key[:2] / f"{key}.clip"

    def get(self, key: str) -> "ClipOutcome | None":
        """The entry under ``key``, or None when there is none or it is damaged."""
        from .runners import ClipOutcome

        try:
            data = self._path(key).read_bytes()
        except OSError:
            return None
        head, sep, payload = data.partition(b"\n")
        try:
            meta = json.loads(head)
            if (not sep or meta.get("format") != FORMAT or meta.get("payload_bytes") != len(payload)
                    or meta.get("payload_sha256") != hashlib.sha256(payload).hexdigest()):
                return None
            return ClipOutcome(payload, dict(meta["stats"]), float(meta["seconds"]), cached=True)
        except (ValueError, KeyError, TypeError):
            return None

    def put(self, key: str, outcome: "ClipOutcome") -> None:
        """Store ``outcome`` under ``key`` (whole or not at all)."""
        path = self._path(key)
        path.parent.mkdir(parents=True, exist_ok=True)
        head = json.dumps({"format": FORMAT, "payload_bytes": len(outcome.payload),
                           "payload_sha256": hashlib.sha256(outcome.payload).hexdigest(),
                           "stats": outcome.stats, "seconds": outcome.seconds}, sort_keys=True,
                          default=_plain)
        tmp = path.with_name(f".{path.name}.{secrets.token_hex(4)}.tmp")
        try:
            tmp.write_bytes(head.encode() + b"\n" + outcome.payload)
            os.replace(tmp, path)
        finally:
            tmp.unlink(missing_ok=True)
