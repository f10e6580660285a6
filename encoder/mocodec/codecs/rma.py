"""Codec ``rma``: a motion library as per-track Catmull-Rom keys placed freely in time (seed 003
§5.1), quantized on a step lattice chosen by the tolerance (§5.2) and entropy coded with the
runtime's coder (the lossless back-end the seed delegated to RAR), in one ``RMAL`` section
(docs/FORMAT.md).

It shares the spline codec's tolerance machinery (compensated top-down fitting, per-track
budgets, repair through the C runtime) and differs in storage: no block grid forces keys every
32 frames, key times are coded as entropy-coded gaps, key values as entropy-coded differences
of lattice integers, and the per-clip tables are compact. The runtime decodes the section once
at ``mcd_open`` into resident memory (dequantized keys and a seek table) and samples floats.

The seed's own representation (PCA of virtual markers per behaviour group, coefficient curves)
is codec ``rma-pca`` (``--pca-variance``, :mod:`.rma_pca`); this one does not use it because
``docs/RMA_STUDY.md`` measured that a max-1 cm promise needs 43-140 principal components per
behaviour group and the PCA-coefficient streams come out about 4x larger than per-joint
splines. Repeated-motion references are not coded (measured not to pay, docs/CODECS.md).
"""
from __future__ import annotations

import struct
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from ..kinematics import forward_kinematics
from ..motion import Motion
from ..quantize import StepQuantizer
from ..tolerance import Tolerance
from . import CodecOutput, ProgressFn
from . import spline
from .rma_bitstream import DEFAULT_GROUP_SHIFT, CurveTrack, payload
from .spline import KIND_TWIST, SplineClipResult, _ClipFitter, _Track, node_modes

SECTION_HEADER = 16


@dataclass
class RMASettings:
    """Settings of the ``rma`` codec (every length in cm).

    Parameters
    ----------
    tolerance : Tolerance
        The promise: max world-space position error per node, every frame.
    quant_fraction : float, default 0.6
        Share of a track's error budget given to quantization (the rest to the curve fit).
    budget_scales : tuple of float, default (6.0,)
        Global scales tried on the per-track budgets; the smallest payload that meets the
        tolerance wins (see ``SplineSettings``).
    max_repairs : int, default 60
        Rounds of check-through-the-runtime and budget tightening before giving up.
    shell_cm : float, default 3.0
        Every rotation is also held to a virtual vertex this far from its joint.
    group_shift : int, default 4
        Key values come in groups of ``2**group_shift`` keys (docs/FORMAT.md, RMAL): a random
        access decodes at most one group's records per track, and each group costs an entry
        (offset, widths, its first key whole). Larger groups: fewer bytes, slower random access.
    key_grid : int or None, default None
        Keys prefer multiples of this many frames, so key times cost fewer bits (a key time is
        coded as its grid cell and its offset in the cell, almost always 0); 1 ... 8. None:
        4 when every node's tolerance is at least 0.25 cm, else 1 (measured: the grid saves
        8 % at 1 cm and 4 % at 0.3 cm, and costs 8-13 % at 0.1-0.02 cm, where keys are dense).
    """

    tolerance: Tolerance
    quant_fraction: float = 0.6
    budget_scales: tuple[float, ...] = (6.0,)
    max_repairs: int = 60
    shell_cm: float = 3.0
    key_grid: int | None = None
    group_shift: int = DEFAULT_GROUP_SHIFT

    def __post_init__(self) -> None:
        self.quant_fraction = float(self.quant_fraction)
        if not 0.0 < self.quant_fraction < 1.0:
            raise ValueError(f"quant_fraction must be in (0, 1), got {self.quant_fraction}")
        if isinstance(self.budget_scales, (int, float, str)):
            self.budget_scales = (float(self.budget_scales),)
        self.budget_scales = tuple(float(x) for x in self.budget_scales)
        self.max_repairs = int(self.max_repairs)
        if self.key_grid is None:
            tightest = self.tolerance.tolerance_cm
            if self.tolerance.effector_tolerance_cm is not None:
                tightest = min(tightest, self.tolerance.effector_tolerance_cm)
            self.key_grid = 4 if tightest >= 0.25 else 1
        self.key_grid = int(self.key_grid)
        if not 1 <= self.key_grid <= 8:
            raise ValueError(f"key_grid must be 1 ... 8, got {self.key_grid}")
        self.group_shift = int(self.group_shift)
        if not 1 <= self.group_shift <= 6:
            raise ValueError(f"group_shift must be 1 ... 6 (groups of 2 ... 64 keys), got {self.group_shift}")


def _align(n: int, a: int) -> int:
    return (n + a - 1) // a * a


def section_prefix(clip_count: int) -> bytes:
    """The 16-byte ``RMAL`` section header."""
    return struct.pack("<IIII", clip_count, 0, 0, 0)


def curve_track(t: _Track) -> CurveTrack:
    """A fitted track as the payload stores it: key frames and lattice integers."""
    step = t.quantizer.step
    # One step for the three MRP or translation components (and a twist's own angle step).
    assert np.all(step[-3:] == step[-1]), "the format stores one step per track"
    return CurveTrack(kind=t.kind, frames=np.asarray(t.keys, dtype=np.int64),
                      q=t.quantizer.encode(t.key_values), step=float(step[-1]),
                      angle_step=float(step[0]) if t.kind == KIND_TWIST else 0.0,
                      ref_codes=t.ref_codes, axis_codes=t.axis_codes, split=t.split)


def serialize(motion: Motion, tracks: list[_Track], group_shift: int = DEFAULT_GROUP_SHIFT) -> bytes:
    """The ``RMAL`` payload of one clip (docs/FORMAT.md, version 2)."""
    rows, constants, animated = node_modes(motion, tracks)
    modes = [(rm, tm, 0) for rm, tm, _, _ in rows]
    return payload(motion.frame_count, modes, constants, [curve_track(t) for t in animated], group_shift)


JUMP_CM = 20.0  # a point moving this far in one frame is the capture jumping, not motion


def frame0_jumps(motion: Motion, cm_per_unit: float) -> bool:
    """True when some point jumps more than :data:`JUMP_CM` from frame 0 to frame 1 (CMU's
    files start with a T-pose the converter added): the curves then detach frame 0."""
    if motion.frame_count < 3:
        return False
    _, pos = forward_kinematics(motion.skeleton, motion.rotations[:2], motion.translations[:2])
    return bool(np.max(np.linalg.norm(pos[1] - pos[0], axis=-1)) * cm_per_unit > JUMP_CM)


class _RMAFitter(_ClipFitter):
    """The spline fitter with free key times and lattice quantization."""

    quantizer_for = staticmethod(StepQuantizer.for_range)

    def __init__(self, motion: Motion, cm_per_unit: float, settings: RMASettings) -> None:
        self.split = frame0_jumps(motion, cm_per_unit)
        super().__init__(motion, cm_per_unit, settings)  # type: ignore[arg-type]
        self.key_grid = settings.key_grid

    def _mandatory_keys(self) -> np.ndarray:
        return np.unique([0, 1, self.frames - 1] if self.split else [0, self.frames - 1])

    def _payload(self, tracks: list[_Track]) -> bytes:
        return serialize(self.motion, tracks, self.settings.group_shift)


def encode_clip(motion: Motion, cm_per_unit: float, settings: RMASettings,
                check: Callable[[bytes], np.ndarray]) -> SplineClipResult:
    """Encode one clip within the tolerance on every frame (``check``: payload -> error)."""
    return spline.encode_clip(motion, cm_per_unit, settings, check, _RMAFitter)  # type: ignore[arg-type]


def encode(
    motions: list[Motion],
    cm_per_unit: list[float],
    tolerance: Tolerance,
    check: Callable[..., np.ndarray],
    options: dict[str, Any],
    progress: ProgressFn | None = None,
) -> CodecOutput:
    """Encode a library: every clip into one ``RMAL`` section."""
    settings = RMASettings(tolerance=tolerance, **options)
    one = section_prefix(1)
    payloads, stats = [], []
    for i, (m, cm) in enumerate(zip(motions, cm_per_unit)):
        r = encode_clip(m, cm, settings, lambda payload, i=i: check(i, payload, one))
        payloads.append(r.payload)
        stats.append({"keys": r.keys, "tracks": r.tracks, "repairs": r.repairs,
                      "budget_scale": r.scale, "encode_seconds": r.seconds})
        if progress:
            progress(m.name)
    return CodecOutput(payloads=payloads, section_prefix=section_prefix(len(payloads)), stats=stats)
