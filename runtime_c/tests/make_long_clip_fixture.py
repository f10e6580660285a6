"""Write runtime_c/tests/long_clip_fixture.h: the two-hour clip of tests/long_clip.py (864,000
frames at 120 fps, two joints) as an rma asset at 1 cm, with the Python reference decoder's local
poses at late frames and a quarter frame after each, for test_long_clip.c. Rerun after a change
of the RMAL layout or of the clip:

    .venv/bin/python runtime_c/tests/make_long_clip_fixture.py
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from fixture_util import REPO, c_bytes, c_floats, c_header, c_unsigned, write_header

sys.path.insert(0, str(REPO / "tests"))

from long_clip import FRAMES, encode_rma, late_frames, long_clip  # noqa: E402

from mocodec.codecs.rma_reference import decode_payload  # noqa: E402

QUARTER = 0.25  # exact in binary32 at every frame number below 2^22


def main() -> None:
    m = long_clip()
    asset, payload = encode_rma(m)
    frames = late_frames()
    x = np.concatenate((frames, frames[:-1] + QUARTER))
    rot, trans, scale = decode_payload(payload, m.skeleton, x)
    poses = np.concatenate((rot, trans, scale), axis=-1)  # (len(x), N, 10)
    lines = c_header("make_long_clip_fixture.py", "MCD_LONG_CLIP_FIXTURE_H",
                     {"LONG_FIXTURE_FRAMES": f"{FRAMES}u", "LONG_FIXTURE_NODES": f"{m.skeleton.node_count}u",
                      "LONG_FIXTURE_LATE": f"{len(frames)}u", "LONG_FIXTURE_QUARTER": QUARTER})
    lines += c_unsigned("k_long_fixture_frames", "LONG_FIXTURE_LATE", frames)
    lines += c_bytes("k_long_fixture", asset)
    lines.append("/* The reference decoder's local pose of every node at each late frame, then a quarter "
                 "frame after each but the last: qx qy qz qw tx ty tz sx sy sz. */")
    lines += c_floats("k_long_fixture_poses", poses, 9)
    write_header(Path(__file__).parent / "long_clip_fixture.h", lines)


if __name__ == "__main__":
    main()
