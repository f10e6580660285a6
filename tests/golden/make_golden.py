"""Write the golden assets of the current format version and the poses they must sample to.

    python tests/golden/make_golden.py v2                  (every golden file still missing)
    python tests/golden/make_golden.py v2 --rewrite rma_library   (until the version is frozen)

Run once per released format version; never rewrite the files of a released version: the
script only writes the goldens that do not exist yet (so a codec added within a version, or
one whose runtime lands later, gets its golden beside the others), and ``--rewrite`` is refused
for a version whose files other runtimes already replay (:data:`FROZEN`). Every later runtime
must read the files and reproduce the poses (tests/test_golden.py,
runtime_c/tests/test_golden.c, the C# and Godot tests).

A golden the runtime cannot decode yet (its codec is not built into this runtime) is reported
as missing, one line each, and the exit status is 1.

Poses file format (text, one record per sample):
    sample <clip index> <time seconds, %.9g> <flags>
    then node_count lines: qx qy qz qw tx ty tz sx sy sz (%.9g)
"""
from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO / "encoder"))

from mocodec.encode import encode_motions  # noqa: E402
from mocodec.io import read_bvh  # noqa: E402
from mocodec.motion import Motion, Skeleton  # noqa: E402
from mocodec.runtime import Asset  # noqa: E402
from mocodec.tolerance import Tolerance  # noqa: E402
from mocodec.units import resolve_units  # noqa: E402

SAMPLES = REPO / "encoder" / "mocodec" / "samples"
FROZEN = {"v1"}  # versions released: their goldens are never rewritten
DEFAULT_FLAGS = (0, 1, 2, 4)  # local, world, loop, nearest


def default_times(duration: float, rate: float) -> list[float]:
    """Six times, the fourth the duration (the layout the golden readers check): the start,
    inside, between two frames, the end, past the end and before the start."""
    return [0.0, duration * 0.37, duration * 0.5 + 0.5 / rate, duration, duration * 1.3, -0.25]


def write_poses(asset_bytes: bytes, path: Path, flag_sets: tuple[int, ...] = DEFAULT_FLAGS,
                times: Callable[[float, float], list[float]] = default_times) -> None:
    """Sample every clip of the asset at ``times(duration, rate)`` with each flag set."""
    asset = Asset(asset_bytes)
    lines = []
    for clip in asset.clips:
        for t in times(clip.duration, clip.frame_rate):
            for flags in flag_sets:
                pose = asset.sample(clip.index, np.float32(t), flags)
                lines.append(f"sample {clip.index} {float(np.float32(t)):.9g} {flags}")
                lines.extend(" ".join(f"{v:.9g}" for v in row) for row in pose)
    path.write_text("\n".join(lines) + "\n")


@dataclass
class Case:
    """One golden asset: its clips, tolerance (cm), codec and codec options."""

    motions: Callable[[], list[Motion]]
    tolerance: float
    codec: str
    options: dict[str, Any] = field(default_factory=dict)
    contacts: bool = False
    flag_sets: tuple[int, ...] = DEFAULT_FLAGS
    times: Callable[[float, float], list[float]] = default_times


def _bvh(name: str, frames: int | None = None, rename: str | None = None) -> Motion:
    m = read_bvh(SAMPLES / f"{name}.bvh")
    if frames is not None:
        m = m.slice(0, frames)
    if rename:
        m.name = rename
    return m


def _mixed() -> Motion:
    """A walk, a run and the walk again on one skeleton: PPCA cuts it into pieces of two
    groups, so the rma-pca golden poses cover the cross-fade between pieces."""
    full, run = _bvh("02_01"), _bvh("09_11")
    # The run on the walk's bones: only nodes with position channels (the root) take its translations.
    run_t = full.skeleton.offsets[None].repeat(run.frame_count, axis=0)
    moved = [i for i in range(full.skeleton.node_count) if full.skeleton.position_axes(i)]
    run_t[:, moved] = run.translations[:, moved]
    return Motion(full.skeleton, np.concatenate([full.rotations[1:], run.rotations[1:], full.rotations[1:]]),
                  np.concatenate([full.translations[1:], run_t[1:], full.translations[1:]]),
                  full.frame_time, "mixed")


def _axis_angle(axis: list[float], angle: float) -> np.ndarray:
    a = np.asarray(axis) / np.linalg.norm(axis)
    return np.concatenate([a * np.sin(angle / 2), [np.cos(angle / 2)]])


def _leg() -> Motion:
    """The left leg of 09_11 (Hips down to the toe: the first seven nodes, in parent-first
    order) as a glTF-like skeleton: every joint's rest rotation is its pose half-way through
    the clip, LHipJoint (still in the capture) holds a rest rotation of its own (0.4 rad about
    (1, 2, -0.5)) on every frame, and the end site is a virtual point that keeps its rest
    rotation (0.7 rad about (0.3, -0.5, 0.81)). Its clip needs less scratch than a 38-node one."""
    m = _bvh("09_11")
    n = 7
    sk = m.skeleton
    rotations = m.rotations[:, :n].copy()
    rotations[:, 1] = _axis_angle([1.0, 2.0, -0.5], 0.4)
    rotations[:, n - 1] = _axis_angle([0.3, -0.5, 0.81], 0.7)
    rest = rotations[len(rotations) // 2].copy()
    skeleton = Skeleton(sk.names[:n], sk.parents[:n], sk.offsets[:n], list(sk.channels[:n]), np.zeros(n, bool),
                        rest_rotations=rest, is_virtual=np.arange(n) == n - 1)
    return Motion(skeleton, rotations, m.translations[:, :n].copy(), m.frame_time, "09_11_leg")


def contact_times(duration: float, rate: float) -> list[float]:
    """Six times, the fourth the duration: inside contacts, between frames and near the ends
    of contacts of the 02_01 walk."""
    return [0.0, 20.3 / rate, 131.7 / rate, duration, 232.25 / rate, duration * 0.5 + 0.5 / rate]


CASES: dict[str, Case] = {
    "spline_09_11": Case(lambda: [_bvh("09_11")], 1.0, "spline"),
    # two clips, two skeletons (subjects 07, 02)
    "spline_library": Case(lambda: [_bvh("07_01"), _bvh("02_01", 61, "02_01_head")], 0.5, "spline"),
    "rma_library": Case(lambda: [_bvh("07_01"), _bvh("09_11")], 1.0, "rma"),  # subjects 07, 09
    "rma_pca_library": Case(lambda: [_bvh("07_01"), _mixed()], 1.0, "rma-pca", {"groups": 2, "variance": 0.98}),
    # repeated pieces (seed 003 eq. 6)
    "rma_pca_repeats": Case(lambda: [_mixed()], 1.0, "rma-pca", {"groups": 2, "variance": 0.98, "repeats": True}),
    # SKEL version 2: rest rotations and a virtual point; two clips that need different scratch
    "spline_rest_pose": Case(lambda: [_bvh("07_01"), _leg()], 1.0, "spline"),
    "rma_rest_pose": Case(lambda: [_bvh("07_01"), _leg()], 1.0, "rma"),
    # RMAL's dense end: keys one frame apart, wide differences, blocks of 8 keys (version 4: slope
    # predictors and streams of zeros)
    "rma_09_11_dense": Case(lambda: [_bvh("09_11", 120, "09_11_head")], 0.05, "rma", {"block_keys": 8}),
    # rma_rmal2_library and rma_rmal2_rest_pose: rma_library and rma_rest_pose as rma wrote them in
    # RMAL version 2 (before version 3); rma_rmal3_library, rma_rmal3_rest_pose and
    # rma_rmal3_09_11_dense: the three above in RMAL version 3 (before version 4). No case writes
    # them again; every runtime still reads them.
    # windows of frames: a short first window so the clip has several
    "neural_09_11": Case(lambda: [_bvh("09_11", 90, "09_11_head")], 2.0, "neural", {"window_frames": 40}),
    "fk_wavelet_09_11": Case(lambda: [_bvh("09_11")], 2.0, "fk-wavelet"),
    # short blocks and gaps, so the clip has several intra frames and interpolated frames
    "ik_predict_09_11": Case(lambda: [_bvh("09_11", 100, "09_11_head")], 1.0, "ik-predict",
                             {"block_frames": 8, "max_gap": 4}),
    # contact trajectories (CNTC), sampled with and without MCD_SAMPLE_CONTACTS
    "spline_contacts_02_01": Case(lambda: [_bvh("02_01")], 1.0, "spline", contacts=True,
                                  flag_sets=(0, 1, 8, 9), times=contact_times),
}


def write_case(name: str, case: Case, out: Path) -> None:
    motions = case.motions()
    units = [resolve_units(m.skeleton, "cmu", None) for m in motions]
    result = encode_motions(motions, units, case.codec, Tolerance(case.tolerance), case.options or None,
                            contacts=case.contacts)
    (out / f"{name}.mcd").write_bytes(result.asset)
    write_poses(result.asset, out / f"{name}.poses.txt", case.flag_sets, case.times)
    print(f"{name}: {len(result.asset)} bytes, max error {result.max_error_cm:.4f} cm")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("version", nargs="?", default="v2", help="folder under tests/golden (default v2)")
    parser.add_argument("--rewrite", nargs="+", default=[], metavar="NAME",
                        help="write these goldens again (a format version not yet released only)")
    parser.add_argument("--only", nargs="+", default=None, metavar="NAME", help="consider only these goldens")
    args = parser.parse_args(argv)
    unknown = sorted((set(args.rewrite) | set(args.only or ())) - set(CASES))
    if unknown:
        print(f"make_golden: no golden named {', '.join(unknown)}; known: {', '.join(CASES)}", file=sys.stderr)
        return 2
    if args.rewrite and args.version in FROZEN:
        print(f"make_golden: {args.version} is released; its goldens are never rewritten", file=sys.stderr)
        return 2
    out = REPO / "tests" / "golden" / args.version
    out.mkdir(parents=True, exist_ok=True)
    missing = []
    for name, case in CASES.items():
        if args.only is not None and name not in args.only:
            continue
        if (out / f"{name}.mcd").exists() and name not in args.rewrite:
            print(f"{name}: kept (golden files are never rewritten)")
            continue
        try:
            write_case(name, case, out)
        except Exception as exc:  # one line per golden that cannot be written; the rest go on
            missing.append(name)
            print(f"{name}: NOT WRITTEN ({case.codec}): {type(exc).__name__}: {exc}", file=sys.stderr)
    if missing:
        print(f"make_golden: missing in {args.version}: {', '.join(missing)}", file=sys.stderr)
    return 1 if missing else 0


if __name__ == "__main__":
    sys.exit(main())
