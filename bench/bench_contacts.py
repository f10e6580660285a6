"""What contact IK buys and costs: foot error on the original's contact frames before and after
IK, every node's error with IK applied, and the bytes of the CNTC section.

    python bench/bench_contacts.py --codec rma --tolerance 1 --clips 02_01 07_01 07_04 09_01 06_10

Each clip is encoded three times: without and with ``--contacts``, and (the other way to keep
feet within 0.5 cm) without contacts but with ``--effector-tolerance 0.5``, which holds hands,
feet and head to 0.5 cm on every frame. Contact frames are those the encoder's detector finds
on the original (mocodec.contacts.detect_contacts). Writes ``bench/results/contacts_<codec>.md``.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent / "encoder"))

from mocodec import contacts as C  # noqa: E402
from mocodec.encode import encode_motions  # noqa: E402
from mocodec.io import read_bvh  # noqa: E402
from mocodec.kinematics import forward_kinematics  # noqa: E402
from mocodec.runtime import Asset  # noqa: E402
from mocodec.tolerance import Tolerance  # noqa: E402
from mocodec.units import resolve_units  # noqa: E402

DEV = HERE.parents[1] / "shared" / "data" / "cmu"
SAMPLES = HERE.parent / "encoder" / "mocodec" / "samples"
EFFECTOR_CM = 0.5


def measure(path: Path, codec: str, tol: float) -> dict:
    m = read_bvh(path)
    units = [resolve_units(m.skeleton, "cmu", None)]
    cm = units[0].cm_per_unit
    _, pos = forward_kinematics(m.skeleton, m.rotations, m.translations)
    masks = C.detect_contacts(m.skeleton, pos, m.frame_rate, cm)
    plain = encode_motions([m], units, codec, Tolerance(tol))
    with_c = encode_motions([m], units, codec, Tolerance(tol), contacts=True)
    tight = encode_motions([m], units, codec, Tolerance(tol, EFFECTOR_CM))
    asset = Asset(with_c.asset)
    out = {"clip": m.name, "frames": m.frame_count, "plain_bytes": len(plain.asset),
           "contacts_bytes": len(with_c.asset), "effector_bytes": len(tight.asset),
           "contact_frames": int(sum(int(v.sum()) for v in masks.values()))}
    for key, a, flag in (("before", asset, False), ("after", asset, True),
                         ("effector", Asset(tight.asset), False)):
        _, got = a.sample_frames(m.name, world=True, contacts=flag)
        err = np.linalg.norm(got - pos, axis=-1) * cm
        feet = np.concatenate([err[mask, n] for n, mask in masks.items()]) if masks else np.zeros(1)
        out[f"foot_max_{key}"] = float(feet.max())
        out[f"foot_mean_{key}"] = float(feet.mean())
        out[f"foot_over_half_cm_{key}"] = float(np.mean(feet > 0.5))
        out[f"all_max_{key}"] = float(err.max())
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--codec", default="rma")
    ap.add_argument("--tolerance", type=float, default=1.0)
    ap.add_argument("--clips", nargs="+", default=["02_01", "07_01", "07_04", "09_01", "06_10"])
    ap.add_argument("--out", type=Path, default=HERE / "results")
    args = ap.parse_args()
    rows = []
    for name in args.clips:
        path = DEV / f"{name}.bvh" if (DEV / f"{name}.bvh").exists() else SAMPLES / f"{name}.bvh"
        rows.append(measure(path, args.codec, args.tolerance))
        print(rows[-1], file=sys.stderr)
    lines = [f"Contact IK, codec `{args.codec}`, tolerance {args.tolerance:g} cm "
             "(foot = foot/toe joints on the original's contact frames; errors in cm)", "",
             "| clip | frames | contact samples | bytes without | bytes with | foot max before → after | "
             "foot mean before → after | share > 0.5 cm after | every node max with IK | "
             f"bytes with --effector-tolerance {EFFECTOR_CM:g}, no contacts | its foot max / mean |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['clip']} | {r['frames']} | {r['contact_frames']} | {r['plain_bytes']:,} | "
                     f"{r['contacts_bytes']:,} (+{100 * (r['contacts_bytes'] / r['plain_bytes'] - 1):.1f} %) | "
                     f"{r['foot_max_before']:.3f} → {r['foot_max_after']:.3f} | "
                     f"{r['foot_mean_before']:.3f} → {r['foot_mean_after']:.3f} | "
                     f"{100 * r['foot_over_half_cm_after']:.1f} % | {r['all_max_after']:.4f} | "
                     f"{r['effector_bytes']:,} (+{100 * (r['effector_bytes'] / r['plain_bytes'] - 1):.1f} %) | "
                     f"{r['foot_max_effector']:.3f} / {r['foot_mean_effector']:.3f} |")
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / f"contacts_{args.codec}.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    sys.exit(main())
