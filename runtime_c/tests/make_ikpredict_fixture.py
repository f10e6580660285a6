"""Write runtime_c/tests/ikpredict_fixture.h: a small ik-predict asset (the first 60 frames of
sample 09_11, 1 cm, blocks of 8 coded frames, at most 4 frames between coded frames) as a C
array, with the coded frames and the poses the encoder's closed loop reconstructs on them, for
test_ikpredict.c. Rerun after a change of the IKPR layout:

    .venv/bin/python runtime_c/tests/make_ikpredict_fixture.py
"""
from __future__ import annotations

from pathlib import Path

from fixture_util import CM, c_bytes, c_floats, c_header, c_unsigned, sample_head, write_header

from mocodec.codecs import ik_predict as I
from mocodec.encode import _single_clip_asset, make_check
from mocodec.tolerance import Tolerance

FRAMES = 60


def main() -> None:
    m = sample_head("09_11", FRAMES)
    check = make_check([m], [CM], "ik-predict")
    settings = I.IkPredictSettings(Tolerance(1.0), block_frames=8, max_gap=4)
    r = I.encode_clip(m, CM, settings, lambda p: check(0, p))
    asset = _single_clip_asset(m, CM, "ik-predict", r.payload)
    poses = I.reconstruction(r.payload, m, CM, settings)
    frames = I.payload_frames(r.payload)
    assert len(frames) < m.frame_count  # the fixture exercises the gap table
    lines = c_header("make_ikpredict_fixture.py", "MCD_IKPREDICT_FIXTURE_H",
                     {"IKP_FIXTURE_FRAMES": f"{m.frame_count}u", "IKP_FIXTURE_NODES": f"{m.skeleton.node_count}u",
                      "IKP_FIXTURE_CODED": f"{len(frames)}u"})
    lines += c_unsigned("k_ikp_fixture_frames", "IKP_FIXTURE_CODED", frames)
    lines += c_bytes("k_ikp_fixture", asset)
    lines.append("/* The encoder's reconstruction: local pose of every node on every coded frame, "
                 "qx qy qz qw tx ty tz sx sy sz. */")
    lines += c_floats("k_ikp_fixture_poses", poses, 9)
    write_header(Path(__file__).parent / "ikpredict_fixture.h", lines)
    print(f"{len(asset)} bytes, payload {len(r.payload)}, {len(frames)} coded frames")


if __name__ == "__main__":
    main()
