"""Seed 000's baselines (§6), on BVH channel values, each quantized with a uniform step and
written with the runtime's entropy coder, so their sizes compare with our codecs' fairly.

* **SPBLF** — simple prediction by the last frame (eq. 21): each frame is sent as its
  difference from the last *decoded* frame, quantized.
* **DWT** — plain 9/7 wavelet (PyWavelets ``bior4.4``) per channel, every coefficient
  quantized with one uniform step.
* **IBKF** — key frames chosen by curve simplification, values quantized, piecewise cubic
  Hermite (PCHIP) between keys.

The signal is the (F, C) channel array: rotation channels in degrees, position channels in
file units. One step ``s`` applies to rotation channels and ``s · position_scale`` to position
channels (default 0.1 unit per degree: one degree at a 6-unit CMU thigh moves its end ~0.1).

Sizes count every byte a decoder needs beyond the skeleton and the frame count: the entropy
streams, and 4 bytes per stream for its value count where the count is not implied.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pywt
from scipy.interpolate import PchipInterpolator

from ..entropy import MAX_ABS, entropy_decode, entropy_encode
from ..motion import Skeleton

WAVELET = "bior4.4"      # PyWavelets' name for the CDF 9/7 biorthogonal pair
WAVELET_MODE = "periodization"  # keeps one coefficient per sample (no boundary padding growth)


def channel_steps(skeleton: Skeleton, step: float, position_scale: float = 0.1) -> np.ndarray:
    """Per BVH channel quantization step (C,): ``step`` degrees for rotation channels,
    ``step · position_scale`` file units for position channels."""
    codes = np.array([c for ch in skeleton.channels for c in ch])
    return np.where(codes < 3, step * position_scale, step).astype(np.float64)


def _check_range(q: np.ndarray) -> np.ndarray:
    if q.size and np.abs(q).max() > MAX_ABS:
        raise ValueError("step too small: quantized values exceed the entropy coder's range")
    return q.astype(np.int64)


# ------------------------------------------------------------------------------ SPBLF
@dataclass
class SPBLFStream:
    data: bytes
    frames: int
    steps: np.ndarray  # (C,)

    @property
    def size(self) -> int:
        return len(self.data)


def spblf_encode(channels: np.ndarray, steps: np.ndarray) -> SPBLFStream:
    """Closed-loop last-frame DPCM (eq. 21): frame i is coded as the rounded difference from
    the decoder's frame i-1, which is kept as an integer multiple of the step, exactly as the
    decoder accumulates it, so encoder and decoder never disagree and no float drift builds
    up. One numpy step per frame, vectorised over channels. (``round(xᵢ/step)`` differences
    would be the same in exact arithmetic but not on ties, which 2-decimal BVH data hits.)"""
    frames = channels.shape[0]
    state = np.zeros(channels.shape[1], dtype=np.int64)  # decoder's last frame, in steps
    codes = np.empty(channels.shape, dtype=np.int64)
    for i in range(frames):
        q = np.rint((channels[i] - state * steps) / steps).astype(np.int64)
        codes[i] = q
        state += q
    return SPBLFStream(entropy_encode(_check_range(codes)), frames, steps)


def spblf_decode(stream: SPBLFStream) -> np.ndarray:
    c = stream.steps.shape[0]
    codes = entropy_decode(stream.data, stream.frames * c).reshape(stream.frames, c)
    return np.cumsum(codes.astype(np.int64), axis=0) * stream.steps


# -------------------------------------------------------------------------------- DWT
@dataclass
class DWTStream:
    data: bytes
    frames: int
    level: int
    steps: np.ndarray  # (C,)

    @property
    def size(self) -> int:
        return len(self.data) + 1  # one byte for the level


def _coefficient_layout(frames: int, level: int) -> list[int]:
    """Lengths of the arrays ``pywt.wavedec`` returns for one channel (approximation first)."""
    return [len(a) for a in pywt.wavedec(np.zeros(frames), WAVELET, WAVELET_MODE, level)]


def dwt_level(frames: int) -> int:
    return pywt.dwt_max_level(frames, pywt.Wavelet(WAVELET).dec_len)


def dwt_encode(channels: np.ndarray, steps: np.ndarray) -> DWTStream:
    """Full-depth 9/7 analysis along frames for every channel at once, uniform quantization."""
    frames = channels.shape[0]
    level = dwt_level(frames)
    coeffs = np.concatenate(pywt.wavedec(channels, WAVELET, WAVELET_MODE, level, axis=0), axis=0)
    q = _check_range(np.rint(coeffs / steps))
    # Channel-major order so the coder sees each channel's coarse-to-fine run in sequence.
    return DWTStream(entropy_encode(q.T.copy()), frames, level, steps)


def dwt_decode(stream: DWTStream) -> np.ndarray:
    c = stream.steps.shape[0]
    lengths = _coefficient_layout(stream.frames, stream.level)
    q = entropy_decode(stream.data, sum(lengths) * c).reshape(c, -1).T
    parts = np.split(q * stream.steps, np.cumsum(lengths)[:-1], axis=0)
    return pywt.waverec(parts, WAVELET, WAVELET_MODE, axis=0)[: stream.frames]


def dwt_error_bound(frames: int, steps: np.ndarray) -> np.ndarray:
    """Largest per-channel reconstruction error (C,) that coefficient rounding can cause:
    ``step/2 · max_t Σ_c |M[t, c]|`` with M the synthesis matrix (9/7 is not orthonormal, so
    the bound is not step/2). M is built column by column: O(F²), for tests on short clips."""
    level = dwt_level(frames)
    lengths = _coefficient_layout(frames, level)
    eye = np.eye(sum(lengths))
    parts = np.split(eye, np.cumsum(lengths)[:-1], axis=0)
    synthesis = pywt.waverec(parts, WAVELET, WAVELET_MODE, axis=0)[:frames]  # (F, n_coeffs)
    return 0.5 * steps * np.abs(synthesis).sum(axis=1).max()


# ------------------------------------------------------------------------------- IBKF
@dataclass
class IBKFStream:
    keys: bytes    # gaps between key frame indices
    values: bytes  # key values, delta-coded key to key on the quantization grid
    key_count: int
    frames: int
    steps: np.ndarray

    @property
    def size(self) -> int:
        return len(self.keys) + len(self.values) + 4  # + the key count


def _pchip(keys: np.ndarray, values: np.ndarray, frames: int) -> np.ndarray:
    if len(keys) == 1:
        return np.repeat(values, frames, axis=0)
    return PchipInterpolator(keys, values, axis=0)(np.arange(frames))


def select_key_frames(channels: np.ndarray, steps: np.ndarray, tolerance: float) -> np.ndarray:
    """Curve simplification, top-down: start from the first and last frame and keep adding the
    frame where the PCHIP curve through the *quantized* keys is farthest from the data (in
    steps, worst channel), until every frame is within ``tolerance`` steps. Interpolating the
    decoded keys inside the loop makes the tolerance hold for what the decoder rebuilds."""
    frames = channels.shape[0]
    grid = np.rint(channels / steps) * steps
    keys = sorted({0, frames - 1})
    while True:
        approx = _pchip(np.array(keys), grid[keys], frames)
        err = (np.abs(approx - channels) / steps).max(axis=1)
        worst = int(np.argmax(err))
        if err[worst] <= tolerance or worst in keys:
            return np.array(keys)
        keys = sorted(keys + [worst])


def ibkf_encode(channels: np.ndarray, steps: np.ndarray, tolerance: float = 2.0) -> IBKFStream:
    keys = select_key_frames(channels, steps, tolerance)
    grid = _check_range(np.rint(channels[keys] / steps))
    gaps = np.diff(keys, prepend=0)
    values = np.diff(grid, axis=0, prepend=0)
    return IBKFStream(entropy_encode(gaps), entropy_encode(_check_range(values)),
                      len(keys), channels.shape[0], steps)


def ibkf_decode(stream: IBKFStream) -> np.ndarray:
    c = stream.steps.shape[0]
    keys = np.cumsum(entropy_decode(stream.keys, stream.key_count).astype(np.int64))
    codes = entropy_decode(stream.values, stream.key_count * c).reshape(stream.key_count, c)
    values = np.cumsum(codes.astype(np.int64), axis=0) * stream.steps
    return _pchip(keys, values, stream.frames)
