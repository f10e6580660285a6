"""Codec ``rma``: a motion library as per-track Catmull-Rom keys placed freely in time (seed 003
§5.1), quantized on a step lattice chosen by the tolerance (§5.2), in one ``RMAL`` section
(docs/FORMAT.md, version 2) that the runtime samples in place.

It fits with the key-frame engine, like ``spline`` (:mod:`mocodec.keyframes`: compensated
top-down fitting, per-track budgets, repair through the C runtime), and differs in storage
(:mod:`.rma_bitstream`): no block grid forces keys every 32 frames; key times are bits of a
cell bitmap; key values are residuals from a chord between group anchors at per-group widths,
with outliers whole, so any key is a few direct reads, at random as in sequence.

The seed's own representation (PCA of virtual markers per behaviour group, coefficient curves)
is codec ``rma-pca`` (``--pca-variance``, :mod:`.rma_pca`); this one does not use it because
``docs/RMA_STUDY.md`` measured that a max-1 cm promise needs 43-140 principal components per
behaviour group and the PCA-coefficient streams come out about 4x larger than per-joint
splines. Repeated-motion references are not coded (measured not to pay, docs/CODECS.md).
"""
from __future__ import annotations

import struct
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..keyframes import KIND_TWIST, KeyframeFitter, KeyframeSettings, Track, fit_clip, node_modes
from ..kinematics import forward_kinematics
from ..motion import Motion
from ..quantize import StepQuantizer
from ..tolerance import ClipCheck
from . import CheckFn, ClipResult, CodecOutput, ProgressFn, encode_each_clip
from .rma_bitstream import GROUP_SHIFTS, CurveTrack, WrittenTracks, payload

if TYPE_CHECKING:
    from ..bake import Runner

SECTION_HEADER = 16


@dataclass
class RMASettings(KeyframeSettings):
    """Settings of the ``rma`` codec: those of :class:`~mocodec.keyframes.KeyframeSettings`
    (tolerance, quant_fraction, budget_scales, max_repairs, shell_cm) and

    Parameters
    ----------
    key_grid : int or None, default None
        Keys only on the first frames of cells of this many frames (1, 2, 4 or 8), where a key
        time costs a bit of the track's cell bitmap; a track that needs a key elsewhere goes on
        in cells of half the size. None: 4 when every node's tolerance is at least 0.25 cm,
        else 1 (dense keys).
    group_shifts : tuple of int, default (3, 4, 5)
        Each track's keys come in groups of ``2**s`` keys, s the one of these that takes the
        fewest bytes (docs/FORMAT.md, RMAL): a group costs a row (offset, widths, its first
        key whole), and its other keys are residuals from the chord between two rows' keys.
    """

    key_grid: int | None = None
    group_shifts: tuple[int, ...] = GROUP_SHIFTS

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.key_grid is None:
            tightest = self.tolerance.tolerance_cm
            if self.tolerance.effector_tolerance_cm is not None:
                tightest = min(tightest, self.tolerance.effector_tolerance_cm)
            self.key_grid = 4 if tightest >= 0.25 else 1
        self.key_grid = int(self.key_grid)
        if self.key_grid not in (1, 2, 4, 8):
            raise ValueError(f"key_grid must be 1, 2, 4 or 8, got {self.key_grid}")
        if isinstance(self.group_shifts, (int, str)):
            self.group_shifts = (int(self.group_shifts),)
        self.group_shifts = tuple(int(g) for g in self.group_shifts)
        if not self.group_shifts or any(not 1 <= g <= 6 for g in self.group_shifts):
            raise ValueError(f"group_shifts must be 1 ... 6 (groups of 2 ... 64 keys), got {self.group_shifts}")


def section_prefix(clip_count: int) -> bytes:
    """The 16-byte ``RMAL`` section header."""
    return struct.pack("<IIII", clip_count, 0, 0, 0)


def curve_track(t: Track) -> CurveTrack:
    """A fitted track as the payload stores it: key frames and lattice integers."""
    step = t.quantizer.step
    # One step for the three MRP or translation components (and a twist's own angle step).
    assert np.all(step[-3:] == step[-1]), "the format stores one step per track"
    return CurveTrack(kind=t.kind, frames=np.asarray(t.keys, dtype=np.int64),
                      q=t.quantizer.encode(t.key_values), step=float(step[-1]),
                      angle_step=float(step[0]) if t.kind == KIND_TWIST else 0.0,
                      ref_codes=t.ref_codes, axis_codes=t.axis_codes, split=t.split)


def serialize(motion: Motion, tracks: list[Track], group_shifts: tuple[int, ...] = GROUP_SHIFTS,
              written: WrittenTracks | None = None) -> bytes:
    """The ``RMAL`` payload of one clip (docs/FORMAT.md, version 2); ``written``: the tracks
    of this clip's previous payload, not packed again where unchanged."""
    rows, constants, animated = node_modes(motion, tracks)
    modes = [(rm, tm, sm) for rm, tm, sm, _, _, _ in rows]
    return payload(motion.frame_count, modes, constants, [curve_track(t) for t in animated], group_shifts, written)


JUMP_CM = 20.0  # a point moving this far in one frame is the capture jumping, not motion


def frame0_jumps(motion: Motion, cm_per_unit: float) -> bool:
    """True when some point jumps more than :data:`JUMP_CM` from frame 0 to frame 1 (CMU's
    files start with a T-pose the converter added): the curves then detach frame 0."""
    if motion.frame_count < 3:
        return False
    _, pos = forward_kinematics(motion.skeleton, motion.rotations[:2], motion.translations[:2], motion.scales[:2])
    return bool(np.max(np.linalg.norm(pos[1] - pos[0], axis=-1)) * cm_per_unit > JUMP_CM)


class RMAFitter(KeyframeFitter):
    """The key-frame engine with free key times and lattice quantization."""

    quantizer_for = staticmethod(StepQuantizer.for_range)
    local_refits = True

    def __init__(self, motion: Motion, cm_per_unit: float, settings: RMASettings) -> None:
        self.split = frame0_jumps(motion, cm_per_unit)
        super().__init__(motion, cm_per_unit, settings)
        self.key_grid = settings.key_grid
        self.written = WrittenTracks()

    def mandatory_keys(self) -> np.ndarray:
        return np.unique([0, 1, self.frames - 1] if self.split else [0, self.frames - 1])

    def payload(self, tracks: list[Track]) -> bytes:
        return serialize(self.motion, tracks, self.settings.group_shifts, self.written)


def encode_clip(motion: Motion, cm_per_unit: float, settings: RMASettings,
                check: ClipCheck) -> ClipResult:
    """Encode one clip within the tolerance on every frame (``check``: payload -> error)."""
    return fit_clip(motion, cm_per_unit, settings, check, RMAFitter)


def encode(motions: list[Motion], cm_per_unit: list[float], settings: RMASettings,
           check: CheckFn, progress: ProgressFn | None = None, runner: "Runner | None" = None) -> CodecOutput:
    """Encode a library: every clip into one ``RMAL`` section (the clips fitted by ``runner``,
    :mod:`mocodec.bake`, the section assembled here)."""
    out = encode_each_clip(encode_clip, motions, cm_per_unit, settings, check, progress,
                           prefix=section_prefix(1), runner=runner)
    out.section_prefix = section_prefix(len(out.payloads))
    return out
