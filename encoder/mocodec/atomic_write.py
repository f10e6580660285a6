"""Writing an asset whole or not at all: the bytes go to a temporary file beside the target,
which is renamed over it only when complete, so a bake that is killed, interrupted or out of
disk leaves either the previous file or none, never a partial ``.mcd``.

(Branch ``parallel``'s small helper; branch ``harden`` brings ``mocodec.output`` with the same
``write_atomic`` and more: the lead keeps one.)
"""
from __future__ import annotations

import os
import secrets
from pathlib import Path


def write_atomic(path: str | os.PathLike, data: bytes) -> None:
    """Write ``data`` to ``path`` through a temporary file in the same folder and a rename."""
    target = Path(path)
    tmp = target.with_name(f".{target.name}.{secrets.token_hex(4)}.tmp")
    try:
        with open(tmp, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, target)
    finally:
        tmp.unlink(missing_ok=True)
