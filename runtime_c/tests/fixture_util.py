"""Shared by the fixture generators of runtime_c/tests (make_*_fixture.py): the sample clip
they cut and the C array writers."""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "encoder"))

from mocodec.io import read_bvh  # noqa: E402
from mocodec.motion import Motion  # noqa: E402

CM = 5.6444


def sample_head(name: str, frames: int) -> Motion:
    """The first ``frames`` frames of a bundled sample clip."""
    full = read_bvh(REPO / "encoder" / "mocodec" / "samples" / f"{name}.bvh")
    return Motion(full.skeleton, full.rotations[:frames].copy(), full.translations[:frames].copy(),
                  full.frame_time, full.name)


def c_bytes(name: str, data: bytes) -> list[str]:
    """``static const unsigned char name[] = {...};``, 16 bytes a line."""
    lines = [f"static const unsigned char {name}[{len(data)}] = {{"]
    for i in range(0, len(data), 16):
        lines.append("    " + ", ".join(f"0x{b:02x}" for b in data[i:i + 16]) + ",")
    return lines + ["};"]


def c_floats(name: str, values: np.ndarray, digits: int) -> list[str]:
    """``static const float name[] = {...};``, one pose row (the last axis of ``values``) a line."""
    arr = np.asarray(values, dtype=np.float32)
    row = arr.shape[-1] if arr.ndim else 1
    vals = arr.reshape(-1)
    lines = [f"static const float {name}[{len(vals)}] = {{"]
    for i in range(0, len(vals), row):
        lines.append("    " + ", ".join(f"{float(v):.{digits}e}f" for v in vals[i:i + row]) + ",")
    return lines + ["};"]
