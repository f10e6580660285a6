"""The bridge to the C runtime (the cffi binding `mocodec_runtime`): the one place where the
encoder decodes, so every error it reports is what an engine will see."""
from __future__ import annotations

from typing import Iterable, Iterator

import numpy as np

try:
    import mocodec_runtime as _rt
except ImportError as exc:  # pragma: no cover - a broken install, reported plainly
    raise ImportError(
        "the C runtime binding 'mocodec_runtime' is not installed; "
        "install bindings/python (pip install ./bindings/python) or run `make demo`"
    ) from exc

Asset = _rt.Asset
RuntimeResultError = _rt.RuntimeResultError
Result = _rt.Result
validate = _rt.validate
version = _rt.version
clip_scratch_size = _rt.clip_scratch_size
TRANSFORM_FLOATS = _rt.TRANSFORM_FLOATS  # floats per mcd_transform: rotation, translation, scale
SAMPLE_WORLD, SAMPLE_LOOP, SAMPLE_NEAREST = _rt.SAMPLE_WORLD, _rt.SAMPLE_LOOP, _rt.SAMPLE_NEAREST
NODE_VIRTUAL = _rt.NODE_VIRTUAL  # a point the reader added at a leaf joint (mcd_node_info.kind)


def decode_world(asset: "Asset", clip: int | str) -> tuple[np.ndarray, np.ndarray]:
    """World rotations (F, N, 4) and positions (F, N, 3) of every frame of a clip."""
    return asset.sample_frames(clip, world=True)


def decode_local(asset: "Asset", clip: int | str) -> tuple[np.ndarray, np.ndarray]:
    """Local rotations (F, N, 4) and translations (F, N, 3) of every frame of a clip."""
    return asset.sample_frames(clip, world=False)


CHUNK_FRAMES = 1024
"""Frames the encoder samples at a time: a long clip's decoded poses (float64, 80 bytes a node
a frame, and the runtime's float32 40) are never held whole; a run of 1,024 frames of a 38-node
clip is 5 MB, and more per run saves no time that counts."""


def sample_chunks(asset: "Asset", clip: int | str, frames: np.ndarray, world: bool = True,
                  contacts: bool = False) -> Iterator[tuple[slice, np.ndarray, np.ndarray]]:
    """``(rows, rotations, positions)`` at ``frames`` (frame numbers, fractions allowed),
    :data:`CHUNK_FRAMES` at a time: ``rows`` the slice of ``frames`` each chunk covers."""
    frames = np.asarray(frames, dtype=np.float64)
    for start in range(0, len(frames), CHUNK_FRAMES):
        rows = slice(start, min(start + CHUNK_FRAMES, len(frames)))
        rot, pos = asset.sample_frames(clip, frames[rows], world=world, contacts=contacts)
        yield rows, rot, pos


def world_error_runs(asset: "Asset", clip: int | str, reference: np.ndarray,
                     offset: float = 0.0) -> Iterator[tuple[slice, np.ndarray]]:
    """Distances (F, N) from each node's world position at frame ``k + offset`` to
    ``reference[k]`` (F, N, 3), decoded a run of :data:`CHUNK_FRAMES` frames at a time
    (``(rows, distances)``; the same numbers as whole)."""
    frames = np.arange(len(reference), dtype=np.float64) + offset
    for rows, _, pos in sample_chunks(asset, clip, frames):
        yield rows, np.linalg.norm(pos - reference[rows], axis=-1)


def world_error_chunk_runs(asset: "Asset", clip: int | str, reference: Iterable[tuple[slice, np.ndarray]],
                           offset: float = 0.0) -> Iterator[tuple[slice, np.ndarray]]:
    """:func:`world_error_runs` against a reference given a run of frames at a time, ``(rows,
    positions)`` in order: the same numbers, without the reference held whole."""
    for rows, ref in reference:
        frames = np.arange(rows.start, rows.stop, dtype=np.float64) + offset
        _, pos = asset.sample_frames(clip, frames, world=True)
        yield rows, np.linalg.norm(pos - ref, axis=-1)
