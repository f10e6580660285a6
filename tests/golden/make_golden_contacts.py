"""Write the golden asset with a contacts (``CNTC``) section and the poses it must sample to,
with and without ``MCD_SAMPLE_CONTACTS``. Same poses format as make_golden.py; it only adds
this file, it never rewrites the other goldens.

    python tests/golden/make_golden_contacts.py v1
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "encoder"))

from mocodec.encode import encode_motions  # noqa: E402
from mocodec.io import read_bvh  # noqa: E402
from mocodec.runtime import Asset  # noqa: E402
from mocodec.tolerance import Tolerance  # noqa: E402
from mocodec.units import resolve_units  # noqa: E402

SAMPLES = REPO / "encoder" / "mocodec" / "samples"
FLAGS = (0, 1, 8, 9)  # local, world, and both with contacts (four sets, like make_golden.py)


def write_poses(asset_bytes: bytes, path: Path) -> None:
    asset = Asset(asset_bytes)
    lines = []
    for clip in asset.clips:
        rate = clip.frame_rate
        # Six times, the fourth the duration (the layout tests/golden readers expect): inside
        # contacts, between frames and near the ends of contacts of the 02_01 walk.
        times = [0.0, 20.3 / rate, 131.7 / rate, clip.duration, 232.25 / rate, clip.duration * 0.5 + 0.5 / rate]
        for t in times:
            for flags in FLAGS:
                pose = asset.sample(clip.index, np.float32(t), flags)
                lines.append(f"sample {clip.index} {float(np.float32(t)):.9g} {flags}")
                lines.extend(" ".join(f"{v:.9g}" for v in row) for row in pose)
    path.write_text("\n".join(lines) + "\n")


def main(version: str) -> None:
    out = REPO / "tests" / "golden" / version
    walk = read_bvh(SAMPLES / "02_01.bvh")
    units = [resolve_units(walk.skeleton, "cmu", None)]
    result = encode_motions([walk], units, "spline", Tolerance(1.0), contacts=True)
    name = "spline_contacts_02_01"
    (out / f"{name}.mcd").write_bytes(result.asset)
    write_poses(result.asset, out / f"{name}.poses.txt")
    print(f"{name}: {len(result.asset)} bytes, max error {result.max_error_cm:.4f} cm, "
          f"{result.clips[0].stats.get('contact_segments')} contact segments")


if __name__ == "__main__":
    main(sys.argv[1] if len(sys.argv) > 1 else "v1")
