"""How much entropy-coding the spline key stream would save: a measurement for the next format
minor version, not a codec.

    python bench/spline_entropy_probe.py --tolerance 1 --clips 02_01 05_02 09_12

Encodes each clip with the `spline` codec as it is, then codes the same quantized key values
and key times with the runtime's entropy coder (`mocodec.entropy`, the code the C runtime
would decode at open): key values as differences from the previous key of the same track
component (one coder channel per component), extra-key offsets and per-block counts as they
are. Prints the bit-packed stream bytes against the entropy-coded bytes.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "encoder"))

import mocodec.codecs.spline as spline  # noqa: E402
from mocodec.encode import make_check  # noqa: E402
from mocodec.entropy import entropy_encode  # noqa: E402
from mocodec.io import read_bvh  # noqa: E402
from mocodec.tolerance import Tolerance  # noqa: E402

DEV = HERE.parents[1] / "shared" / "data" / "cmu"


def probe(path: Path, tolerance: float) -> dict[str, int]:
    motion = read_bvh(path)
    captured: dict[str, object] = {}
    pack = spline._pack_blocks

    def spy(tracks, qvals, starts, shift):  # keep the last (final) packing's inputs
        captured.update(tracks=tracks, qvals=qvals, starts=starts, shift=shift)
        return pack(tracks, qvals, starts, shift)

    spline._pack_blocks = spy
    try:
        check = make_check([motion], [5.6444], "spline")
        result = spline.encode_clip(motion, 5.6444, spline.SplineSettings(Tolerance(tolerance)),
                                    lambda p: check(0, p))
    finally:
        spline._pack_blocks = pack
    tracks, qvals, starts = captured["tracks"], captured["qvals"], captured["starts"]
    stream_bits = 0
    coded = 0
    for t, q in zip(tracks, qvals):
        q = q.astype(np.int64)
        stream_bits += int(q.shape[0] * t.quantizer.bits.sum())
        deltas = np.diff(np.vstack([np.zeros((1, q.shape[1]), dtype=np.int64), q]), axis=0)
        coded += len(entropy_encode(deltas.ravel(), channels=q.shape[1]))
        block = np.minimum(np.searchsorted(starts, t.keys, side="right") - 1, len(starts) - 1)
        offsets = t.keys - starts[block]
        counts = np.bincount(block, minlength=len(starts))[:-1] - 1
        coded += len(entropy_encode(offsets[offsets > 0])) + len(entropy_encode(counts))
    return {"frames": motion.frame_count, "payload": len(result.payload),
            "value_bytes_packed": stream_bits // 8, "entropy_coded_stream": coded}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--tolerance", type=float, default=1.0)
    ap.add_argument("--clips", nargs="+", default=["02_01", "05_02", "09_12"])
    args = ap.parse_args()
    total_payload = total_coded = total_values = 0
    print(f"tolerance {args.tolerance} cm")
    print(f"{'clip':<8} {'frames':>7} {'payload B':>10} {'key values packed B':>20} {'whole stream entropy-coded B':>29}")
    for name in args.clips:
        r = probe(DEV / f"{name}.bvh", args.tolerance)
        total_payload += r["payload"]
        total_coded += r["entropy_coded_stream"]
        total_values += r["value_bytes_packed"]
        print(f"{name:<8} {r['frames']:>7} {r['payload']:>10,} {r['value_bytes_packed']:>20,} {r['entropy_coded_stream']:>29,}")
    print(f"payloads {total_payload:,} B; entropy-coded key stream (values + times + counts) "
          f"{total_coded:,} B vs packed values alone {total_values:,} B")
    return 0


if __name__ == "__main__":
    sys.exit(main())
