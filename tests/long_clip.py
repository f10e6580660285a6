"""A two-hour clip built in code for the tests of sampling time on long clips (tests/test_long_clip_time.py
and runtime_c/tests/make_long_clip_fixture.py): a root and one joint with an end site, 864,000
frames at 120 fps. The joint rests for almost two hours, then swings fast (30 degrees, a period
of 24 frames) over the last LIVELY_FRAMES frames, so the asset stays small while late frames and
the poses between them differ clearly (a float time there resolves 0.06 frames, and a float-time
runtime snapped any time within 0.35 frames onto a frame)."""
from __future__ import annotations

import numpy as np

from mocodec import rotations as R
from mocodec.codecs.rma import RMASettings, encode_clip, section_prefix
from mocodec.encode import _single_clip_asset, make_check
from mocodec.motion import Motion, Skeleton
from mocodec.tolerance import Tolerance

FPS = 120
FRAMES = 2 * 3600 * FPS
LIVELY_FRAMES = 480
CM_PER_UNIT = 1.0


def long_clip(frames: int = FRAMES) -> Motion:
    """The clip (file units: cm)."""
    sk = Skeleton(["Hips", "Arm", "Arm_End"], [-1, 0, 1], [[0, 90, 0], [0, 10, 0], [0, 30, 0]],
                  [(0, 1, 2, 5, 3, 4), (5, 3, 4), ()], [False, False, True])
    f = np.arange(frames, dtype=np.float64)
    start = frames - LIVELY_FRAMES
    ramp = np.clip((f - start) / 48.0, 0.0, 1.0)  # in over 48 frames, so the swing starts smoothly
    angle = np.radians(30.0) * ramp * np.sin(2.0 * np.pi * np.maximum(f - start, 0.0) / 24.0)
    rot = np.tile([0.0, 0.0, 0.0, 1.0], (frames, 3, 1))
    rot[:, 1] = R.quat_from_axis_angle(np.array([0.0, 0.0, 1.0]), angle)
    trans = np.broadcast_to(sk.offsets, (frames, 3, 3)).copy()  # no root track: RMAL's cells
    # cost a track about 15 KB over two hours, keys or not
    return Motion(sk, rot, trans, 1.0 / FPS, "two_hours")


def late_frames(frames: int = FRAMES) -> np.ndarray:
    """Frames of the lively end the tests sample at (the last one included)."""
    return np.array([frames - 200, frames - 101, frames - 37, frames - 2, frames - 1])


def encode_rma(m: Motion, tolerance_cm: float = 1.0) -> tuple[bytes, bytes]:
    """(asset, RMAL payload) of ``m`` alone, rma at ``tolerance_cm``: the payload for the Python
    reference decoder (mocodec.codecs.rma_reference), the asset for the runtime."""
    prefix = section_prefix(1)
    check = make_check([m], [CM_PER_UNIT], "rma")
    r = encode_clip(m, CM_PER_UNIT, RMASettings(Tolerance(tolerance_cm)), lambda p, **how: check(0, p, prefix, **how))
    return _single_clip_asset(m, CM_PER_UNIT, "rma", r.payload, prefix), r.payload
