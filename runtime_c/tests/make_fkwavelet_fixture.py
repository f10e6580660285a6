"""Write runtime_c/tests/fkwavelet_fixture.h: a small fk-wavelet asset (the first 56 frames
of sample 09_11, 3 cm, blocks of 16 frames: three full blocks and a last one of 8 frames with
one level fewer) as a C array, with the poses the Python reference decoder computes at every
frame, for test_fkwavelet.c. Rerun after a change of the FKWV layout:

    .venv/bin/python runtime_c/tests/make_fkwavelet_fixture.py
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
from fixture_util import CM, c_bytes, c_floats, c_header, sample_head, write_header

from mocodec.codecs import fk_wavelet as W
from mocodec.encode import _single_clip_asset, make_check
from mocodec.tolerance import Tolerance

FRAMES = 56
BLOCK = 16


def main() -> None:
    m = sample_head("09_11", FRAMES)
    check = make_check([m], [CM], "fk-wavelet")
    r = W.encode_clip(m, CM, W.FkWaveletSettings(Tolerance(3.0), block_frames=BLOCK), lambda p: check(0, p))
    asset = _single_clip_asset(m, CM, "fk-wavelet", r.payload)
    rot, trans = W.decode_payload(r.payload, m.skeleton)
    p = W.parse(r.payload)
    assert p.block == BLOCK
    lines = c_header("make_fkwavelet_fixture.py", "MCD_FKWAVELET_FIXTURE_H",
                     {"FKW_FIXTURE_FRAMES": f"{m.frame_count}u", "FKW_FIXTURE_NODES": f"{m.skeleton.node_count}u",
                      "FKW_FIXTURE_CHANNELS": f"{p.channels}u", "FKW_FIXTURE_BLOCK": f"{p.block}u"})
    lines += c_bytes("k_fkw_fixture", asset)
    lines.append("/* Local pose of every node on every frame: qx qy qz qw tx ty tz. */")
    lines += c_floats("k_fkw_fixture_poses", np.concatenate((rot, trans), axis=-1), 8)
    write_header(Path(__file__).parent / "fkwavelet_fixture.h", lines)
    print(f"{len(asset)} bytes, payload {len(r.payload)}, block {p.block}, levels {p.levels}, channels {p.channels}")


if __name__ == "__main__":
    main()
