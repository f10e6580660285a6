"""Hashes that say when two encodings of a clip must come out the same: the encoder's own code,
a clip's content, a codec's settings.

A cached clip is reused only when all three match (:mod:`.cache`), and a Dask worker refuses a
clip when its encoder's code differs from the client's (:mod:`.runners`), since either would
otherwise give an asset other than the one a serial bake gives.
"""
from __future__ import annotations

import dataclasses
import functools
import hashlib
import importlib.util
import json
from pathlib import Path
from typing import Any

import numpy as np

from .. import __version__
from ..channel_frames import ChannelFrames
from ..motion import Motion, frame_runs

EXTENSION_SUFFIXES = (".so", ".pyd", ".dylib")


def _package_files(package: str, binaries: bool) -> list[tuple[str, Path]]:
    """(path inside the package, path) of its sources and, with ``binaries``, its extensions."""
    spec = importlib.util.find_spec(package)
    if spec is None or not spec.submodule_search_locations:
        return []
    root = Path(next(iter(spec.submodule_search_locations)))
    files = [p for p in root.rglob("*") if p.is_file() and "__pycache__" not in p.parts
             and (p.suffix == ".py" or (binaries and p.suffix in EXTENSION_SUFFIXES))]
    return sorted((p.relative_to(root).as_posix(), p) for p in files)


@functools.lru_cache(maxsize=2)
def encoder_fingerprint(binaries: bool = True) -> str:
    """A hash of the encoder's version and code: every ``.py`` file of :mod:`mocodec` and of the
    runtime binding ``mocodec_runtime`` and (``binaries``) their compiled extensions, with
    numpy's version. ``binaries=False`` is what two machines with the same release share even
    when their compilers differ."""
    h = hashlib.sha256(f"mocodec {__version__} numpy {np.__version__}\n".encode())
    for package in ("mocodec", "mocodec_runtime"):
        for name, path in _package_files(package, binaries):
            data = path.read_bytes()
            h.update(f"{package}/{name}:{len(data)}\n".encode())
            h.update(data)
    return h.hexdigest()


def _update_array(h: "hashlib._Hash", a: np.ndarray | None) -> None:
    if a is None:
        h.update(b"none;")
        return
    if not isinstance(a, ChannelFrames):
        a = np.atleast_1d(np.asarray(a))  # (a number hashes as one of shape (1,), as it did)
    h.update(f"{a.dtype.str}{tuple(a.shape)};".encode())
    # The C-order bytes a run of frames at a time (the same digest as whole): a long clip's
    # rotations computed from its channels, or a broadcast array, are never made whole.
    for rows in frame_runs(len(a)):
        h.update(np.ascontiguousarray(a[rows]).tobytes())


def motion_digest(motion: Motion) -> str:
    """A hash of everything of ``motion`` a codec reads: skeleton, frames and frame time (not
    its name or where it was read from, so a renamed or moved file is still the same clip)."""
    sk = motion.skeleton
    h = hashlib.sha256()
    h.update(json.dumps([sk.names, sk.channels, repr(float(motion.frame_time))]).encode())
    for a in (sk.parents, sk.offsets, sk.is_end_site, sk.rest_rotations, sk.rest_scales, sk.is_virtual,
              motion.rotations, motion.translations, motion.scales, motion.source_channels):
        _update_array(h, a)
    return h.hexdigest()


def _canonical(value: Any) -> Any:
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {"<type>": type(value).__qualname__,
                **{f.name: _canonical(getattr(value, f.name)) for f in dataclasses.fields(value)}}
    if isinstance(value, dict):
        return {str(k): _canonical(v) for k, v in sorted(value.items(), key=lambda kv: str(kv[0]))}
    if isinstance(value, (list, tuple)):
        return [_canonical(v) for v in value]
    if isinstance(value, np.ndarray):
        h = hashlib.sha256()
        _update_array(h, value)
        return {"<array>": h.hexdigest()}
    if isinstance(value, (np.generic,)):
        return _canonical(value.item())
    if isinstance(value, float):
        return repr(value)  # exact: 0.1 and 0.1000000001 are different settings
    if value is None or isinstance(value, (bool, int, str)):
        return value
    return repr(value)


def settings_digest(settings: Any) -> str:
    """A hash of a codec's settings (a dataclass, the tolerance its first field), exact to the bit."""
    return hashlib.sha256(json.dumps(_canonical(settings), sort_keys=True).encode()).hexdigest()
