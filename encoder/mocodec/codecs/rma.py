"""Codec ``rma``: a motion library as per-track Catmull-Rom keys placed freely in time (seed 003
§5.1), quantized on a step lattice chosen by the tolerance (§5.2) and entropy coded with the
runtime's coder (the lossless back-end the seed delegated to RAR), in one ``RMAL`` section
(docs/FORMAT.md).

It fits with the key-frame engine, like ``spline`` (:mod:`mocodec.keyframes`: compensated
top-down fitting, per-track budgets, repair through the C runtime), and differs in storage: no
block grid forces keys every 32 frames, key times are coded as entropy-coded gaps, key values
as entropy-coded differences of lattice integers, and the per-clip tables are compact. The runtime decodes the section once
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

import numpy as np

from ..entropy import entropy_encode
from ..keyframes import (DIMS, KIND_TRANSLATION, KIND_TWIST, KeyframeFitter, KeyframeSettings, Track,
                         fit_clip, node_modes)
from ..motion import Motion
from ..quantize import StepQuantizer
from ..tolerance import ClipCheck
from . import CheckFn, ClipResult, CodecOutput, ProgressFn, encode_each_clip

SECTION_HEADER = 16
PAYLOAD_HEADER = 32
SEEK_SHIFT = 5
DESC_SIZE = {1: 20, 2: 32, 3: 16}


@dataclass
class RMASettings(KeyframeSettings):
    """Settings of the ``rma`` codec: those of :class:`~mocodec.keyframes.KeyframeSettings`
    (tolerance, quant_fraction, budget_scales, max_repairs, shell_cm) and

    Parameters
    ----------
    key_grid : int or None, default None
        Keys prefer multiples of this many frames, so key times cost fewer bits (a key time is
        coded as its grid cell and its offset in the cell, almost always 0); 1 ... 8. None:
        4 when every node's tolerance is at least 0.25 cm, else 1 (measured: the grid saves
        8 % at 1 cm and 4 % at 0.3 cm, and costs 8-13 % at 0.1-0.02 cm, where keys are dense).
    """

    key_grid: int | None = None

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.key_grid is None:
            tightest = self.tolerance.tolerance_cm
            if self.tolerance.effector_tolerance_cm is not None:
                tightest = min(tightest, self.tolerance.effector_tolerance_cm)
            self.key_grid = 4 if tightest >= 0.25 else 1
        self.key_grid = int(self.key_grid)
        if not 1 <= self.key_grid <= 8:
            raise ValueError(f"key_grid must be 1 ... 8, got {self.key_grid}")


def _align(n: int, a: int) -> int:
    return (n + a - 1) // a * a


def section_prefix(clip_count: int) -> bytes:
    """The 16-byte ``RMAL`` section header."""
    return struct.pack("<IIII", clip_count, 0, 0, 0)


# Key value predictors (descriptor byte 1, bits 4-5): the previous key, or the previous key
# plus half / all of the slope of the two keys before, carried over the gap to this key. Dense
# keys (tight tolerances) follow the slope; sparse ones do not, so each track picks its own.
PREDICT_PREVIOUS, PREDICT_HALF_SLOPE, PREDICT_SLOPE = 0, 1, 2


def key_residuals(q: np.ndarray, frames: np.ndarray, predictor: int) -> np.ndarray:
    """Lattice integers ``q`` (K, d) of keys at ``frames`` (K,) minus their prediction, in
    integers only (docs/FORMAT.md gives the rounding the runtime repeats)."""
    q = np.asarray(q, dtype=np.int64)
    out = np.diff(q, axis=0, prepend=np.zeros((1, q.shape[1]), dtype=np.int64))
    if predictor == PREDICT_PREVIOUS or len(q) < 3:
        return out
    f = np.asarray(frames, dtype=np.int64)
    num = (q[1:-1] - q[:-2]) * ((f[2:] - f[1:-1]) * predictor)[:, None]
    den = (2 * (f[1:-1] - f[:-2]))[:, None]
    out[2:] = q[2:] - (q[1:-1] + (2 * num + den) // (2 * den))
    return out


def serialize(motion: Motion, tracks: list[Track], grid_of: int = 1) -> bytes:
    """The ``RMAL`` payload of one clip (resident offset 0; :func:`place` sets it); ``grid_of``
    is the key grid the tracks were fitted on."""
    sk = motion.skeleton
    rows, constants, animated = node_modes(motion, tracks)
    modes = bytes(rm | (tm << 2) for rm, tm, _, _ in rows).ljust(_align(sk.node_count, 4), b"\0")
    descs, streams, gaps = [], [], []
    keys = 0
    for t in animated:
        d = DIMS[t.kind]
        q = t.quantizer.encode(t.key_values)
        options = [entropy_encode(key_residuals(q, t.keys, p).ravel(), channels=d)
                   for p in (PREDICT_PREVIOUS, PREDICT_HALF_SLOPE, PREDICT_SLOPE)]
        predictor = int(np.argmin([len(o) for o in options]))
        stream = options[predictor]
        step = t.quantizer.step
        # One step for the three MRP or translation components (and a twist's own angle step).
        assert np.all(step[-3:] == step[-1]), "the format stores one step per track"
        grid = grid_of
        byte1 = grid | predictor << 4
        if t.is_rotation:
            desc = struct.pack("<BB3hIIf", t.kind, byte1, *t.ref_codes.tolist(), len(t.keys), len(stream), step[-1])
        else:
            desc = struct.pack("<BBHIIf", t.kind, byte1, 0, len(t.keys), len(stream), step[-1])
        if t.kind == KIND_TWIST:
            desc += struct.pack("<3hHf", *t.axis_codes.tolist(), 0, step[0])
        descs.append(desc)
        streams.append(stream)
        # Interior keys as (grid cells since the previous key's cell, offset in the cell); the
        # first (0) and last (F - 1) keys are implied.
        inner = t.keys[1:-1]
        gaps.append(np.stack((np.diff(inner // grid, prepend=0), inner % grid), axis=1).ravel())
        keys += len(t.keys)
    gap_stream = entropy_encode(np.concatenate(gaps).astype(np.int64), channels=2) if gaps else b""
    body = b"".join([modes, np.asarray(constants, dtype="<f4").tobytes(), *descs, gap_stream, *streams])
    size = _align(PAYLOAD_HEADER + len(body), 4)
    header = struct.pack("<IIIIIIII", size, motion.frame_count, sk.node_count, len(animated),
                         len(constants), keys, 0, len(gap_stream))
    return (header + body).ljust(size, b"\0")


def resident_bytes(payload: bytes) -> int:
    """Bytes the runtime decodes one payload into (docs/FORMAT.md, RMAL resident block)."""
    _, frames, nodes, tracks, consts, keys = struct.unpack_from("<IIIIII", payload)
    pos = PAYLOAD_HEADER + _align(nodes, 4) + 4 * consts
    values = 0
    for _ in range(tracks):
        kind = payload[pos]
        count = struct.unpack_from("<I", payload, pos + (4 if kind == KIND_TRANSLATION else 8))[0]
        values += count * DIMS[kind]
        pos += DESC_SIZE[kind]
    seek = ((frames - 1) >> SEEK_SHIFT) + 1
    return 16 + 16 * tracks + _align(4 * keys, 16) + _align(4 * values, 16) + _align(4 * tracks * seek, 16)


def place(payloads: list[bytes]) -> list[bytes]:
    """Set each payload's resident offset for a section holding them in this order."""
    out, offset = [], 0
    for p in payloads:
        out.append(p[:24] + struct.pack("<I", offset) + p[28:])
        offset += resident_bytes(p)
    return out


class RMAFitter(KeyframeFitter):
    """The key-frame engine with free key times and lattice quantization."""

    quantizer_for = staticmethod(StepQuantizer.for_range)

    def __init__(self, motion: Motion, cm_per_unit: float, settings: RMASettings) -> None:
        super().__init__(motion, cm_per_unit, settings)
        self.key_grid = settings.key_grid

    def mandatory_keys(self) -> np.ndarray:
        return np.unique([0, self.frames - 1])

    def payload(self, tracks: list[Track]) -> bytes:
        return serialize(self.motion, tracks, self.key_grid)


def encode_clip(motion: Motion, cm_per_unit: float, settings: RMASettings,
                check: ClipCheck) -> ClipResult:
    """Encode one clip within the tolerance on every frame (``check``: payload -> error)."""
    return fit_clip(motion, cm_per_unit, settings, check, RMAFitter)


def encode(motions: list[Motion], cm_per_unit: list[float], settings: RMASettings,
           check: CheckFn, progress: ProgressFn | None = None) -> CodecOutput:
    """Encode a library: every clip into one ``RMAL`` section."""
    out = encode_each_clip(encode_clip, motions, cm_per_unit, settings, check, progress,
                           prefix=section_prefix(1))
    for st, payload in zip(out.stats, out.payloads):
        st["resident_bytes"] = resident_bytes(payload)
    out.payloads = place(out.payloads)
    out.section_prefix = section_prefix(len(out.payloads))
    return out
