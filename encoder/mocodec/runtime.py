"""The bridge to the C runtime (the cffi binding `mocodec_runtime`): the one place where the
encoder decodes, so every error it reports is what an engine will see."""
from __future__ import annotations

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
