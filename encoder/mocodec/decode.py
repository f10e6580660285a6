"""Decoding assets back into motions through the C runtime (for `mocodec decode`, BVH export
and tests). The runtime samples every frame; nothing here re-implements a codec."""
from __future__ import annotations

import numpy as np

from .motion import Motion, Skeleton
from .rotations import quat_make_continuous, quat_normalize
from .runtime import NODE_VIRTUAL, Asset


def skeleton_from_asset(asset: Asset, index: int) -> tuple[Skeleton, float]:
    """The skeleton stored in an asset (the whole rest pose, end sites and virtual points) and
    its centimetres per unit."""
    nodes = asset.nodes(index)
    _, cm_per_unit = asset.skeleton_info(index)
    sk = Skeleton(
        names=[n.name for n in nodes],
        parents=[n.parent for n in nodes],
        offsets=[n.rest_offset for n in nodes],
        channels=[n.channels for n in nodes],
        is_end_site=[n.is_end_site for n in nodes],
        rest_rotations=[n.rest_rotation for n in nodes],
        rest_scales=[n.rest_scale for n in nodes],
        is_virtual=[n.kind == NODE_VIRTUAL for n in nodes],
    )
    return sk, cm_per_unit


def decode_clip(asset: Asset, clip: int | str) -> Motion:
    """Every frame of a clip as a :class:`Motion` (local transforms from the runtime)."""
    info = asset.clips[asset.clip_index(clip)]
    skeleton, _ = skeleton_from_asset(asset, info.skeleton)
    rot, trans = asset.sample_frames(info.index, world=False)
    rot = quat_make_continuous(quat_normalize(rot), axis=0)
    return Motion(skeleton, rot, trans, 1.0 / float(np.float32(info.frame_rate)), info.name)


def decode_asset(data: bytes) -> list[Motion]:
    """Every clip of an asset."""
    asset = Asset(data)
    return [decode_clip(asset, c.index) for c in asset.clips]
