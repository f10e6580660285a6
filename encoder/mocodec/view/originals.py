"""The original motions a page compares an asset with: read by any of mocodec's readers, matched
to the asset's clips by name, and reduced to world positions in the asset's node order."""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from .. import io
from ..kinematics import world_positions
from ..motion import Motion


class OriginalError(ValueError):
    """An original that cannot be read or does not fit the asset (one line: file, item, problem)."""


def _readers() -> dict[str, Callable[[Path], Motion | list[Motion]]]:
    """Readers by file suffix: every reader the io package has (glTF where it is there)."""
    readers: dict[str, Callable] = {".bvh": io.read_bvh}
    gltf = getattr(io, "read_gltf", None)
    if gltf is not None:
        readers[".gltf"] = readers[".glb"] = gltf
    return readers


def read_motions(path: str | Path) -> list[Motion]:
    """Every motion in a file (one for BVH, one per animation for glTF)."""
    p = Path(path)
    readers = _readers()
    reader = readers.get(p.suffix.lower())
    if reader is None:
        raise OriginalError(f"{p}: no reader for {p.suffix or 'files without a suffix'} "
                            f"(this mocodec reads {', '.join(sorted(readers))})")
    if not p.exists():
        raise OriginalError(f"{p}: no such file")
    found = reader(p)
    return list(found) if isinstance(found, (list, tuple)) else [found]


@dataclass
class Original:
    """One clip's original: world positions (frames, nodes, 3) in file units, asset node order."""

    clip: str
    source: str
    positions: np.ndarray


def match_originals(motions: list[tuple[str, Motion]], clips: list[tuple[str, int, list[str]]]) -> list[Original]:
    """Pair ``(source, motion)`` with the asset's clips ``(name, frame_count, node names)``.

    A motion goes with the clip of its name, or with the only clip of a one-clip asset. Its
    nodes are taken by name in the clip's order; a missing node or another frame count is an
    :class:`OriginalError`.
    """
    by_name = {c[0]: c for c in clips}
    out: list[Original] = []
    for source, m in motions:
        clip = by_name.get(m.name)
        if clip is None and len(clips) == 1 and len(motions) == 1:
            clip = clips[0]
        if clip is None:
            raise OriginalError(f"{source}: motion {m.name!r} matches no clip of the asset "
                                f"(clips: {', '.join(c[0] for c in clips)})")
        name, frames, nodes = clip
        if m.frame_count != frames:
            raise OriginalError(f"{source}: {m.frame_count} frames, clip {name!r} has {frames}")
        index = {n: i for i, n in enumerate(m.skeleton.names)}
        missing = [n for n in nodes if n not in index]
        if missing:
            raise OriginalError(f"{source}: no node {missing[0]!r} of clip {name!r} "
                                f"({len(missing)} of {len(nodes)} nodes missing)")
        positions = world_positions(m)[:, [index[n] for n in nodes]]
        out.append(Original(name, source, np.ascontiguousarray(positions, dtype=np.float32)))
    return out
