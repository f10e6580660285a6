"""Codec ``rma``: a motion library as per-track Catmull-Rom keys placed freely in time (seed 003
§5.1), quantized on a step lattice chosen by the tolerance (§5.2), in one ``RMAL`` section
(docs/FORMAT.md, version 4) that the runtime samples in place.

It fits with the key-frame engine, like ``spline`` (:mod:`mocodec.keyframes`: compensated
top-down fitting, per-track budgets, repair through the C runtime), and differs in storage
(:mod:`.rma_bitstream`, :mod:`.rma_blocks`): no block grid forces keys every 32 frames; each
track's keys come in blocks whose first key is whole in a row and whose other keys are Rice-coded
frame gaps and differences, so playback decodes a key per key interval and a random access half
a block.

The seed's own representation (PCA of virtual markers per behaviour group, coefficient curves)
is codec ``rma-pca`` (``--pca-variance``, :mod:`.rma_pca`); this one does not use it because
``docs/RMA_STUDY.md`` measured that a max-1 cm promise needs 43-140 principal components per
behaviour group and the PCA-coefficient streams come out about 4x larger than per-joint
splines. Repeated-motion references are not coded (measured not to pay, docs/CODECS.md).
"""
from __future__ import annotations

import struct
from dataclasses import dataclass
from typing import TYPE_CHECKING, Callable

import numpy as np

from ..clip_plan import ClipPlan
from ..keyframes import KIND_TWIST, KeyframeFitter, KeyframeSettings, Track, fit_clip, node_modes
from ..kinematics import forward_kinematics, short_clip
from ..motion import Motion
from ..quantize import StepQuantizer
from ..tolerance import ClipCheck
from . import CheckFn, ClipResult, CodecOutput, ProgressFn, encode_each_clip
from .rma_bitstream import Blocks, CurveTrack, WrittenTracks, payload
from .rma_blocks import DEFAULT_BLOCK_KEYS, MAX_BLOCK_SHIFT

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
    block_keys : int, default 32
        Each track's keys come in blocks of this many keys (2, 4 ... 64; docs/FORMAT.md, RMAL
        version 4): a block costs a row (its first key whole, where its codes start, their Rice
        parameters), and a random access decodes half a block on average. Larger blocks take
        fewer bytes and make random access slower; playback in order costs the same.
    window_frames : int, default 4096
        A long clip (one whose whole-clip poses the encoder does not hold,
        :func:`mocodec.kinematics.short_clip`) is fitted this many frames at a time
        (:mod:`.rma_windows`), so that its memory is the clip's channels and a window's, not
        the whole fit's. Shorter clips are fitted whole.
    """

    key_grid: int | None = None
    block_keys: int = DEFAULT_BLOCK_KEYS
    window_frames: int = 4096

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
        self.block_keys = int(self.block_keys)
        if self.block_keys not in BLOCK_KEYS:
            raise ValueError(f"block_keys must be one of {', '.join(map(str, BLOCK_KEYS))}, got {self.block_keys}")
        self.window_frames = int(self.window_frames)
        if self.window_frames < MIN_WINDOW_FRAMES:
            raise ValueError(f"window_frames must be at least {MIN_WINDOW_FRAMES}, got {self.window_frames}")


BLOCK_KEYS = tuple(1 << s for s in range(1, MAX_BLOCK_SHIFT + 1))
MIN_WINDOW_FRAMES = 16  # a long clip's windows (rma_windows): seams three frames wide, some frames between


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


def serialize(motion: Motion, tracks: list[Track], block_keys: int = DEFAULT_BLOCK_KEYS,
              written: WrittenTracks | None = None, curve: Callable[[Track], CurveTrack] = curve_track) -> bytes:
    """The ``RMAL`` payload of one clip (docs/FORMAT.md, version 4), keys in blocks of
    ``block_keys``; ``written``: the tracks of this clip's previous payload, not packed again
    where unchanged; ``curve``: a fitted track's keys as stored (:func:`curve_track`)."""
    rows, constants, animated = node_modes(motion, tracks)
    modes = [(rm, tm, sm) for rm, tm, sm, _, _, _ in rows]
    return payload(motion.frame_count, modes, constants, [curve(t) for t in animated],
                   Blocks(block_keys.bit_length() - 1), written)


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

    def __init__(self, motion: Motion, cm_per_unit: float, settings: RMASettings,
                 plan: ClipPlan | None = None) -> None:
        self.split = frame0_jumps(motion, cm_per_unit)
        super().__init__(motion, cm_per_unit, settings, plan)
        self.key_grid = settings.key_grid
        self.written = WrittenTracks()

    def mandatory_keys(self) -> np.ndarray:
        return np.unique([0, 1, self.frames - 1] if self.split else [0, self.frames - 1])

    def payload(self, tracks: list[Track]) -> bytes:
        return serialize(self.motion, tracks, self.settings.block_keys, self.written)


def encode_clip(motion: Motion, cm_per_unit: float, settings: RMASettings,
                check: ClipCheck) -> ClipResult:
    """Encode one clip within the tolerance on every frame (``check``: payload -> error); a long
    clip a window of frames at a time (``settings.window_frames``)."""
    if not short_clip(motion) and motion.frame_count > settings.window_frames:
        from .rma_windows import fit_windowed  # (it builds on this module)

        return fit_windowed(motion, cm_per_unit, settings, check)
    return fit_clip(motion, cm_per_unit, settings, check, RMAFitter)


def encode(motions: list[Motion], cm_per_unit: list[float], settings: RMASettings,
           check: CheckFn, progress: ProgressFn | None = None, runner: "Runner | None" = None) -> CodecOutput:
    """Encode a library: every clip into one ``RMAL`` section (the clips fitted by ``runner``,
    :mod:`mocodec.bake`, the section assembled here)."""
    out = encode_each_clip(encode_clip, motions, cm_per_unit, settings, check, progress,
                           prefix=section_prefix(1), runner=runner)
    out.section_prefix = section_prefix(len(out.payloads))
    return out
