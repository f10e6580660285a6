"""Reading clips from any supported file: BVH (one clip a file) and glTF 2.0 (every animation
of the file), by the file's extension; folders hold such files."""
from __future__ import annotations

import os
from pathlib import Path
from typing import Iterable, Iterator, Sequence

from .io import read_bvh, read_gltf
from .motion import Motion

BVH_SUFFIXES = (".bvh",)
GLTF_SUFFIXES = (".gltf", ".glb")
SUFFIXES = BVH_SUFFIXES + GLTF_SUFFIXES


class InputError(ValueError):
    """A path that names no readable animation file."""


def expand(inputs: Iterable[str | os.PathLike]) -> list[Path]:
    """Files named by ``inputs``: files as given, folders replaced by their BVH and glTF files
    (sorted, not recursive)."""
    paths: list[Path] = []
    for item in inputs:
        p = Path(item)
        if p.is_dir():
            found = sorted(q for q in p.iterdir() if q.is_file() and q.suffix.lower() in SUFFIXES)
            if not found:
                raise InputError(f"{p}: folder holds no .bvh, .gltf or .glb files")
            paths.extend(found)
        elif p.exists():
            paths.append(p)
        else:
            raise InputError(f"{p}: no such file or folder")
    if not paths:
        raise InputError("no input files")
    return paths


def load(path: str | os.PathLike, rate: float | None = None) -> list[Motion]:
    """The clips of one file (a BVH's one clip, a glTF's animations) or of every BVH and glTF
    file of a folder.

    Parameters
    ----------
    path : str or path-like
        A ``.bvh``, ``.gltf`` or ``.glb`` file, or a folder of them.
    rate : float, optional
        Frames per second glTF clips are resampled at (default: their key spacing when
        regular, else 60; :func:`mocodec.io.read_gltf`). BVH clips keep their frames.

    Raises
    ------
    InputError, mocodec.io.BVHError, mocodec.io.GLTFError
        One clear line naming the file and the fault.
    """
    return load_all([path], rate)


def read_clips(path: Path, rate: float | None = None) -> list[Motion]:
    """The clips of one file: a BVH's one clip, a glTF's animations (names as in the file)."""
    return read_gltf(path, rate) if path.suffix.lower() in GLTF_SUFFIXES else [read_bvh(path)]


def iter_clips(paths: Sequence[str | os.PathLike], rate: float | None = None) -> Iterator[tuple[Path, int, Motion]]:
    """(file, index in the file, clip) of every clip of ``paths`` in order, names made unique
    (``walk``, ``walk_2``): a library read one file at a time."""
    names: set[str] = set()
    for p in expand(paths):
        for index, m in enumerate(read_clips(p, rate)):
            base, k = m.name, 2
            while m.name in names:  # two files with one stem: keep both, distinctly named
                m.name = f"{base}_{k}"
                k += 1
            names.add(m.name)
            yield p, index, m


def load_all(paths: Sequence[str | os.PathLike], rate: float | None = None) -> list[Motion]:
    """The clips of several files or folders (see :func:`load`), names made unique
    (``walk``, ``walk_2``)."""
    return [m for _, _, m in iter_clips(paths, rate)]


def sampling_notes(motions: Sequence[Motion]) -> list[str]:
    """How resampled clips were measured, one line per kind of sampling (empty for BVH)."""
    groups: dict[tuple, list[str]] = {}
    for m in motions:
        src = m.source or {}
        if src.get("format") != "gltf":
            continue
        key = (src["rate"], src["rate_from"], tuple(src["interpolation"]))
        groups.setdefault(key, []).append(m.name)
    lines = []
    for (rate, origin, interp), names in groups.items():
        which = names[0] if len(names) == 1 else f"{len(names)} glTF clips"
        lines.append(f"{which}: resampled at {rate:g} Hz ({origin}); errors are measured against the "
                     f"source's own interpolation ({', '.join(interp)}) at those times")
    return lines
