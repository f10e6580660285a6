"""Decoding assets back into motions through the C runtime (for `mocodec decode`, BVH and glTF
export and tests). The runtime samples every frame; nothing here re-implements a codec."""
from __future__ import annotations

import numpy as np

from .motion import Motion, Skeleton
from .rotations import quat_make_continuous, quat_normalize
from .runtime import Asset

NODE_END_SITE, NODE_VIRTUAL = 1, 2


def skeleton_from_asset(asset: Asset, index: int) -> tuple[Skeleton, float]:
    """The skeleton stored in an asset (rest TRS, node kinds) and its centimetres per unit."""
    nodes = asset.nodes(index)
    _, cm_per_unit = asset.skeleton_info(index)
    sk = Skeleton(
        names=[n.name for n in nodes],
        parents=[n.parent for n in nodes],
        offsets=[n.rest_translation for n in nodes],
        channels=[n.channels for n in nodes],
        # A virtual end point is a leaf with a fixed offset, as an end site is.
        is_end_site=[n.kind in (NODE_END_SITE, NODE_VIRTUAL) for n in nodes],
        rest_rotations=[n.rest_rotation for n in nodes],
        rest_scales=[n.rest_scale for n in nodes],
        is_virtual=[n.kind == NODE_VIRTUAL for n in nodes],
    )
    return sk, cm_per_unit


def decode_clip(asset: Asset, clip: int | str) -> Motion:
    """Every frame of a clip as a :class:`Motion` (local transforms from the runtime)."""
    info = asset.clips[asset.clip_index(clip)]
    skeleton, _ = skeleton_from_asset(asset, info.skeleton)
    rot, trans, scale = asset.sample_frames(info.index, world=False, scales=True)
    rot = quat_make_continuous(quat_normalize(rot), axis=0)
    return Motion(skeleton, rot, trans, 1.0 / float(np.float32(info.frame_rate)), info.name, scales=scale)


def decode_asset(data: bytes) -> list[Motion]:
    """Every clip of an asset."""
    asset = Asset(data)
    return [decode_clip(asset, c.index) for c in asset.clips]


def write_asset_gltf(data: bytes, path, clips: list[int | str] | None = None) -> list[Motion]:
    """Decode clips (default: all) of an asset through the runtime and write them as one glTF
    file (:func:`mocodec.io.gltf_write.write_gltf`): every skeleton's node hierarchy, one
    animation per clip, timed from the clip's source start (META), lengths in metres (a BVH
    skeleton's through its cm per unit). Returns the motions as written."""
    from .container import read_summary
    from .encode import parse_index_ranges
    from .io.gltf_write import write_gltf

    asset = Asset(data)
    meta = read_summary(data).meta
    infos = [asset.clips[asset.clip_index(c)] for c in clips] if clips is not None else asset.clips
    used = sorted({c.skeleton for c in infos})
    skeletons, metres = [], []  # glTF lengths are metres: a BVH skeleton is converted
    for s in used:
        sk, cm_per_unit = skeleton_from_asset(asset, s)
        metres.append(cm_per_unit / 100.0)
        sk.offsets = sk.offsets * metres[-1]
        skeletons.append(sk)
    joints = {used.index(int(s)): parse_index_ranges(r)
              for s, r in meta.get("skin_joints", {}).items() if int(s) in used}
    motions, entries = [], []
    for c in infos:
        m = decode_clip(asset, c.index)
        m.translations = m.translations * metres[used.index(c.skeleton)]
        start = float(meta.get("clips", {}).get(c.name, {}).get("start_s", 0.0))
        motions.append(m)
        entries.append((used.index(c.skeleton), m, start))
    write_gltf(path, skeletons, entries, joints)
    return motions
