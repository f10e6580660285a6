"""Codec ``neural``: a clip as a small network from time to pose (seed 001), stored as
docs/FORMAT.md's ``NEUR`` payload.

Pose parameters (seed 001 §3): each translated node's local translation, the root rotation as
a sign-continuous quaternion, every other animated joint as an axis-angle vector (relative to
the clip's mean rotation of that joint, so that it stays far from the angle-pi wrap). Each
parameter has a weight in length units (1 for translations, the farthest descendant distance
for rotations), which makes the L2 loss a position-like error.

The network is eq. 2: Fourier features x(t) = {t, sin w_k t, cos w_k t} (eq. 1), two hidden ELU
layers of h = 2(2K+1) units, a linear output layer. Frequencies are DCT bins (w_k = pi k for
t in [0, 1]) chosen by Algorithm 1: after each fit the residual's weighted first principal
component is DCT'd and its peak bin joins the set, the network grows and is warm-started.
Training is numpy with analytic gradients and scipy's L-BFGS. The loop stops when the
quantized network meets the tolerance on every frame through the C runtime.
"""
from __future__ import annotations

import contextlib
import struct
import time
from dataclasses import dataclass, field
from typing import Callable, Iterator

import numpy as np
from scipy.fft import dct
from scipy.optimize import minimize

from .. import rotations as R
from ..bitpack import BitWriter
from ..kinematics import forward_kinematics, halfway_world, lever_arms
from ..motion import Motion
from ..tolerance import ClipCheck, Tolerance, ToleranceNotMet, meet_tolerance
from . import ClipResult

try:
    from threadpoolctl import threadpool_limits
except ImportError:  # pragma: no cover - optional: only makes training faster
    threadpool_limits = None

ROT_IDENTITY, ROT_CONSTANT, ROT_QUATERNION, ROT_AXIS_ANGLE = 0, 1, 2, 3
TRANS_REST, TRANS_OUTPUT = 0, 2
HEADER_SIZE = 16
NODE_ENTRY = 8
WINDOW_ENTRY = 16
WINDOW_HEADER = 32
MAX_K = 32            # format limit on frequencies (docs/FORMAT.md)
MAX_WEIGHT = 1.0e4    # format bound on |dequantized weight|
MAX_ABS_VALUE = 1.0e7
TENSORS = ("W0", "b0", "W1", "b1", "W2", "b2")


@dataclass
class NeuralSettings:
    """Settings of the ``neural`` codec.

    Parameters
    ----------
    tolerance : Tolerance
        Max world-space position error per node, every frame (cm).
    max_frequencies : int, default 3
        Cap on K per window; a window that misses the tolerance with K frequencies is halved
        (a two-frame window that misses raises :class:`~mocodec.tolerance.ToleranceNotMet`).
    window_frames : int, default 240
        Longest first window (frames); windows are only ever split further.
    jump_cm : float, default 20
        A step larger than this between two frames (any point) gets its own two-frame window.
    iterations : int, default 500
        L-BFGS iterations per stage of Algorithm 1.
    seed : int, default 1
        Seed of the weight initialisation: the same seed gives the same asset.
    restart : bool, default True
        Each stage also trains a freshly initialised network beside the warm-started one and
        keeps the lower loss (``False``: Algorithm 1's warm start only).
    frequencies : str, default "adaptive"
        ``"adaptive"`` (Algorithm 1) or ``"naive"`` (the seed's baseline, Omega = {1..K}).
    min_bits, max_bits : int
        Weight quantization bits tried, the fewest that meets the tolerance wins.
    max_frequency_hz : float, default 12
        Highest Fourier feature frequency Algorithm 1 may pick (and never above a quarter of
        the frame rate). Training only sees whole frames: a feature near the frame rate's
        Nyquist limit fits them and swings between them, where engines also sample (measured
        before this cap: 93 cm half-way between two frames of a 1 cm asset). Human motion
        keeps its energy well below 12 Hz.
    halfway_factor : float, default 2
        The window's network must also stay within this many tolerances of the original's
        half-way pose (slerp) between every two of its frames; 0 turns the guard off. Fitting
        frames only, a network could still bend sharply between two of them to follow a fast
        wrist (measured: 43 cm at 3 cm, 05_12 frame 1315.5, with every frequency in band).
        Intervals where the capture itself jumps (``jump_cm``, or a joint turning more than
        45 degrees in one frame) are not held to it; nor are two-frame windows.
    """

    tolerance: Tolerance
    max_frequencies: int = 3
    window_frames: int = 240
    jump_cm: float = 20.0
    iterations: int = 500
    seed: int = 1
    restart: bool = True
    frequencies: str = "adaptive"
    min_bits: int = 6
    max_bits: int = 16
    max_frequency_hz: float = 12.0
    halfway_factor: float = 2.0

    def __post_init__(self) -> None:
        if not 0 <= self.max_frequencies <= MAX_K:
            raise ValueError(f"max_frequencies must be 0 ... {MAX_K} (the NEUR format's limit)")
        if not 2 <= self.min_bits <= self.max_bits <= 16:
            raise ValueError("weight bits must satisfy 2 <= min_bits <= max_bits <= 16")
        if self.frequencies not in ("adaptive", "naive"):
            raise ValueError(f"frequencies must be 'adaptive' or 'naive', got {self.frequencies!r}")
        if self.window_frames < 2:
            raise ValueError("window_frames must be at least 2")
        if self.iterations < 1:
            raise ValueError("iterations must be at least 1")
        if not self.max_frequency_hz > 0.0:
            raise ValueError("max_frequency_hz must be positive")
        if not self.halfway_factor >= 0.0:
            raise ValueError("halfway_factor must be 0 (off) or positive")


GLITCH_TURN_DEG = 45.0
"""A joint turning further than this between two frames (5,400 degrees/s at 120 fps) is a
capture glitch, not motion: the half-way guard does not hold the network to it."""


# ------------------------------------------------------------------------ pose parameters
@dataclass
class PoseLayout:
    """How a pose maps to the network's outputs (one row of the node table per node)."""

    entries: np.ndarray      # (N, 4) int: rotation mode, translation mode, rot out, trans out
    ref_index: np.ndarray    # (N,) int: reference quaternion of the node (modes 1, 3)
    refs: np.ndarray         # (R, 4) float32-exact unit quaternions
    weights: np.ndarray      # (M,) length units per parameter unit
    targets: np.ndarray      # (F, M) parameters on every frame

    @property
    def outputs(self) -> int:
        return self.targets.shape[1]


def _f32(a: np.ndarray) -> np.ndarray:
    return np.asarray(a, dtype=np.float32).astype(np.float64)


def _unit_f32(q: np.ndarray) -> np.ndarray:
    """A float32-exact quaternion whose norm is within 1e-6 of one (the format asks 1e-5)."""
    q = np.asarray(q, dtype=np.float64)
    return _f32(q / np.linalg.norm(q))


def continuous_rotation_vectors(q: np.ndarray, reset_deg: float = GLITCH_TURN_DEG) -> np.ndarray:
    """Rotation vectors (F, 3) of a path of unit quaternions (F, 4) that step little where the
    rotation steps little.

    Angles are folded to [0, pi] (the well-conditioned range: near 2 pi every axis gives almost
    the identity, so a small turn there can flip the vector, seen on 06_13's left hand). Then
    the axis keeps its direction from frame to frame (a flip negates axis and angle together)
    and the angle is unwrapped by 2 pi, so a path crossing pi stays continuous. The unwrapping
    starts afresh after a glitch (a turn past ``reset_deg`` in one frame), where there is
    nothing to be continuous with and a carried 2 pi would only push later frames towards the
    ill-conditioned range."""
    q = np.where(q[:, 3:4] < 0.0, -q, q)
    s = np.linalg.norm(q[:, :3], axis=1)
    angle = 2.0 * np.arctan2(s, q[:, 3])
    axis = np.where(s[:, None] > 1e-12, q[:, :3] / np.maximum(s, 1e-300)[:, None], 0.0)
    flip = np.concatenate(([False], np.sum(axis[1:] * axis[:-1], axis=1) < 0.0))
    sign = np.where(np.cumsum(flip) % 2 == 1, -1.0, 1.0)
    signed = sign * angle
    offset = np.unwrap(signed) - signed
    turn = np.degrees(R.quat_angle(q[:-1], q[1:]))
    start = np.concatenate(([True], turn > reset_deg))
    offset -= offset[np.maximum.accumulate(np.where(start, np.arange(len(q)), 0))]
    return axis * sign[:, None] * (signed + offset)[:, None]


def quat_from_axis_angle_vec(v: np.ndarray) -> np.ndarray:
    """Unit quaternions of rotation vectors (..., 3): the runtime's formula."""
    a = np.linalg.norm(v, axis=-1, keepdims=True)
    half = 0.5 * a
    k = np.where(a > 1e-12, np.sin(half) / np.maximum(a, 1e-300), 0.5)
    return np.concatenate((v * k, np.cos(half)), axis=-1)


def pose_layout(motion: Motion) -> PoseLayout:
    """Seed 001 §3 parameters of ``motion`` with their weights."""
    sk = motion.skeleton
    frames = motion.frame_count
    pos = forward_kinematics(sk, motion.rotations, motion.translations, motion.scales)[1]
    lever = lever_arms(sk, pos)
    floor = max(1e-3 * float(lever.max()), 1e-6)  # a leaf joint still needs a nonzero weight
    entries = np.zeros((sk.node_count, 4), dtype=np.int64)
    entries[:, 0], entries[:, 1] = ROT_IDENTITY, TRANS_REST  # the rest pose, until the clip moves it
    animated = motion.animated()
    ref_index = np.zeros(sk.node_count, dtype=np.int64)
    refs: list[np.ndarray] = []
    cols: list[np.ndarray] = []
    weights: list[float] = []
    m = 0
    for i in range(sk.node_count):
        if animated[i, 0]:
            q = R.quat_make_continuous(motion.rotations[:, i])
            w = max(float(lever[i]), floor)
            if np.max(R.quat_angle(q[:1], q)) < 1e-9:
                entries[i, 0] = ROT_CONSTANT
                ref_index[i] = len(refs)
                refs.append(_unit_f32(q[0]))
            elif sk.parents[i] < 0:
                # The root may turn round: a quaternion has no wrap (seed 001 §3). A change
                # dq of a component turns it by about 2|dq|.
                entries[i, 0], entries[i, 2] = ROT_QUATERNION, m
                cols.append(q)
                weights += [2.0 * w] * 4
                m += 4
            else:
                ref = _unit_f32(R.quat_mean(q))
                # Continuous in time: a vector folded at pi flipped v -> -v between two frames
                # and the network's path between them ran through the identity (a hand 43 cm
                # off half-way between frames 1315 and 1316 of 05_12).
                rel = R.quat_multiply(R.quat_conjugate(ref), q)
                entries[i, 0], entries[i, 2] = ROT_AXIS_ANGLE, m
                ref_index[i] = len(refs)
                refs.append(ref)
                cols.append(continuous_rotation_vectors(rel))
                weights += [w] * 3
                m += 3
        if animated[i, 1]:
            entries[i, 1], entries[i, 3] = TRANS_OUTPUT, m
            cols.append(motion.translations[:, i])
            weights += [1.0] * 3
            m += 3
    targets = np.concatenate(cols, axis=1) if cols else np.zeros((frames, 0))
    return PoseLayout(entries, ref_index, np.array(refs).reshape(-1, 4), np.array(weights), targets)


def local_pose(layout: PoseLayout, motion: Motion, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Local rotations (F, N, 4) and translations (F, N, 3) of parameters ``y`` (F, M)."""
    sk = motion.skeleton
    f = y.shape[0]
    # Rotation mode 0 is the rest rotation (identity for BVH), as the runtime reads it.
    rot = np.broadcast_to(_f32(sk.rest_rotations), (f, sk.node_count, 4)).copy()
    trans = np.broadcast_to(_f32(sk.offsets), (f, sk.node_count, 3)).copy()
    for i, (rm, tm, ro, to) in enumerate(layout.entries):
        if rm == ROT_CONSTANT:
            rot[:, i] = layout.refs[layout.ref_index[i]]
        elif rm == ROT_QUATERNION:
            q = y[:, ro:ro + 4]
            n = np.linalg.norm(q, axis=1, keepdims=True)
            rot[:, i] = np.where(n > 1e-15, q / np.maximum(n, 1e-300), [0.0, 0.0, 0.0, 1.0])
        elif rm == ROT_AXIS_ANGLE:
            rot[:, i] = R.quat_multiply(layout.refs[layout.ref_index[i]],
                                        quat_from_axis_angle_vec(y[:, ro:ro + 3]))
        if tm == TRANS_OUTPUT:
            trans[:, i] = y[:, to:to + 3]
    return rot, trans


# ------------------------------------------------------------------------ the network
def fourier_features(x: np.ndarray, frames: int, freqs: list[int]) -> np.ndarray:
    """Eq. 1 at frame positions ``x``: (len(x), 2K + 1), t = x / (F - 1), w_k = pi k.
    Computed in float64 and rounded to float32, as the runtime does."""
    t = np.asarray(x, dtype=np.float64) / max(frames - 1, 1)
    cols = [t]
    for k in freqs:
        cols += [np.sin(np.pi * k * t), np.cos(np.pi * k * t)]
    return _f32(np.stack(cols, axis=1))


def _elu(z: np.ndarray) -> np.ndarray:
    return np.where(z > 0, z, np.expm1(np.minimum(z, 0.0)))


def forward(p: dict[str, np.ndarray], x: np.ndarray) -> np.ndarray:
    """Eq. 2: W2 ELU(W1 ELU(W0 x + b0) + b1) + b2 for rows x."""
    a0 = _elu(x @ p["W0"].T + p["b0"])
    a1 = _elu(a0 @ p["W1"].T + p["b1"])
    return a1 @ p["W2"].T + p["b2"]


def _shapes(d: int, h: int, m: int) -> list[tuple[int, ...]]:
    return [(h, d), (h,), (h, h), (h,), (m, h), (m,)]


def _pack(p: dict[str, np.ndarray]) -> np.ndarray:
    return np.concatenate([p[k].ravel() for k in TENSORS])


def _unpack(v: np.ndarray, d: int, h: int, m: int) -> dict[str, np.ndarray]:
    out, o = {}, 0
    for k, s in zip(TENSORS, _shapes(d, h, m)):
        n = int(np.prod(s))
        out[k] = v[o:o + n].reshape(s)
        o += n
    return out


def _loss_grad(v: np.ndarray, x: np.ndarray, z: np.ndarray, d: int, h: int) -> tuple[float, np.ndarray]:
    """Eq. 3 on normalised targets (the weights are folded into the normalisation) and its
    analytic gradient by back-propagation."""
    m = z.shape[1]
    p = _unpack(v, d, h, m)
    z0 = x @ p["W0"].T + p["b0"]
    a0 = _elu(z0)
    z1 = a0 @ p["W1"].T + p["b1"]
    a1 = _elu(z1)
    r = a1 @ p["W2"].T + p["b2"] - z
    n = x.shape[0]
    loss = 0.5 * float(np.sum(r * r)) / n
    g = r / n
    d1 = (g @ p["W2"]) * np.where(z1 > 0, 1.0, a1 + 1.0)   # ELU'(z) = ELU(z) + 1 below 0
    d0 = (d1 @ p["W1"]) * np.where(z0 > 0, 1.0, a0 + 1.0)
    grads = {"W2": g.T @ a1, "b2": g.sum(0), "W1": d1.T @ a0, "b1": d1.sum(0),
             "W0": d0.T @ x, "b0": d0.sum(0)}
    return loss, _pack(grads)


def init_network(d: int, m: int, rng: np.random.Generator) -> dict[str, np.ndarray]:
    h = 2 * d
    return {"W0": rng.normal(0, np.sqrt(1.0 / d), (h, d)), "b0": np.zeros(h),
            "W1": rng.normal(0, np.sqrt(1.0 / h), (h, h)), "b1": np.zeros(h),
            "W2": rng.normal(0, np.sqrt(1.0 / h), (m, h)) * 0.1, "b2": np.zeros(m)}


def grow_network(p: dict[str, np.ndarray], rng: np.random.Generator, small: float = 1e-2) -> dict[str, np.ndarray]:
    """Two more inputs (a new sin/cos pair) and four more hidden units per layer (h = 2d),
    old weights copied (Algorithm 1, line 11). The grown network computes exactly the old
    function at first: the new units' output weights are zero. The new units get weights at
    the initialisation scale, so they are live features from the start (with tiny weights
    they stayed near zero and the fit stalled: 3.9 cm instead of 1.1 cm on the first 40
    frames of sample 07_01 with 7 frequencies), and
    the old units see the new inputs through small weights."""
    h, d = p["W0"].shape
    m = p["W2"].shape[0]
    h2, d2 = h + 4, d + 2
    q = {"W0": rng.normal(0, np.sqrt(1.0 / d2), (h2, d2)), "b0": np.zeros(h2),
         "W1": rng.normal(0, np.sqrt(1.0 / h2), (h2, h2)), "b1": np.zeros(h2),
         "W2": np.zeros((m, h2)), "b2": p["b2"].copy()}
    q["W0"][:h, d:] = rng.normal(0, small, (h, 2))
    q["W1"][:h, h:] = rng.normal(0, small, (h, 4))
    q["W0"][:h, :d] = p["W0"]
    q["b0"][:h] = p["b0"]
    q["W1"][:h, :h] = p["W1"]
    q["b1"][:h] = p["b1"]
    q["W2"][:, :h] = p["W2"]
    return q


def _one_thread() -> contextlib.AbstractContextManager:
    """BLAS on one thread: these matrices are tiny, and on a shared machine thread hand-offs
    made each L-BFGS iteration about ten times slower."""
    return threadpool_limits(1) if threadpool_limits else contextlib.nullcontext()


def train(p: dict[str, np.ndarray], x: np.ndarray, z: np.ndarray, iterations: int) -> tuple[dict[str, np.ndarray], float]:
    """L-BFGS on eq. 3 from ``p``; returns the weights and the final loss."""
    h, d = p["W0"].shape
    with _one_thread():
            res = minimize(_loss_grad, _pack(p), args=(x, z, d, h), jac=True, method="L-BFGS-B",
                       options={"maxiter": iterations, "maxcor": 20, "gtol": 1e-12, "ftol": 1e-15})
    return _unpack(res.x, d, h, z.shape[1]), float(res.fun)


def fit_stage(p: dict[str, np.ndarray] | None, x: np.ndarray, z: np.ndarray, iterations: int,
              restart: bool, rng: np.random.Generator) -> dict[str, np.ndarray]:
    """One stage of Algorithm 1: train the warm-started (grown) network ``p``; with
    ``restart`` also a freshly initialised one of the same size, keeping the lower loss. The
    warm start alone often settles in a worse minimum than a fresh start (first 40 / 80 frames
    of samples 07_01 / 09_11, 8 frequencies: 0.7 / 1.6 cm against 0.1 / 1.0 cm)."""
    best, best_loss = None, np.inf
    starts = [] if p is None else [p]
    if restart or p is None:
        starts.append(init_network(x.shape[1], z.shape[1], rng))
    for start in starts:
        q, loss = train(start, x, z, iterations)
        if loss < best_loss:
            best, best_loss = q, loss
    return best


def highest_bin(frames: int, fps: float, max_hz: float) -> int:
    """The highest k whose feature sin(pi k t), t = x / (frames - 1), stays at or below
    ``max_hz`` and a quarter of ``fps``: k / (2 (frames - 1)) cycles per frame."""
    hz = min(max_hz, fps / 4.0)
    return int(np.floor(2.0 * (frames - 1) * hz / fps + 1e-9))


def next_frequency(residual: np.ndarray, used: list[int], max_bin: int | None = None) -> int | None:
    """Algorithm 1, lines 7-10: the residual's first principal component (the residual is
    already in weighted units), its DCT, and the peak bin not yet used (at most ``max_bin``);
    None when no bin is left."""
    r = residual - residual.mean(axis=0)
    _, _, vt = np.linalg.svd(r, full_matrices=False)
    spectrum = np.abs(dct(r @ vt[0], type=2, norm="ortho"))
    spectrum[0] = -1.0            # the constant is the biases' job
    spectrum[list(used)] = -1.0
    spectrum[1 << 16:] = -1.0     # frequencies are stored as u16
    if max_bin is not None:
        spectrum[max_bin + 1:] = -1.0
    best = int(np.argmax(spectrum))
    return best if spectrum[best] >= 0.0 else None


# ------------------------------------------------------------------------ quantization, payload
@dataclass
class QuantizedNetwork:
    bits: int
    steps: np.ndarray                 # (6,) float32-exact
    codes: dict[str, np.ndarray]      # signed integers per tensor

    def weights(self) -> dict[str, np.ndarray]:
        """Dequantized weights exactly as the runtime forms them (binary32 product)."""
        return {k: (self.codes[k].astype(np.float32) * np.float32(s)).astype(np.float64)
                for k, s in zip(TENSORS, self.steps)}


def quantize(p: dict[str, np.ndarray], bits: int) -> QuantizedNetwork:
    half = (1 << (bits - 1)) - 1
    steps, codes = [], {}
    for k in TENSORS:
        peak = float(np.max(np.abs(p[k]))) if p[k].size else 0.0
        # A tensor of zeros still needs a step the format accepts (any positive one).
        step = float(np.float32(peak / half)) if peak > 0 else 1.0 / (1 << (bits - 1))
        # The runtime's own check, in binary32: |code| <= 2^(bits-1) stays within MAX_WEIGHT.
        if np.float32(step) * np.float32(1 << (bits - 1)) > np.float32(MAX_WEIGHT):
            raise ToleranceNotMet(f"weight magnitude {peak:.3g} exceeds the format's bound")
        steps.append(step)
        codes[k] = np.clip(np.rint(p[k] / step), -half, half).astype(np.int64)
    return QuantizedNetwork(bits, np.array(steps), codes)


@dataclass
class WindowNetwork:
    """One window's network: frames ``start ... start + frames - 1`` on its own time axis."""

    start: int
    frames: int
    freqs: list[int]
    net: QuantizedNetwork


@dataclass
class NeuralModel:
    """Everything a payload holds."""

    frames: int
    nodes: int
    layout: PoseLayout
    scale: np.ndarray    # (M,) float32-exact
    offset: np.ndarray   # (M,) float32-exact
    windows: list[WindowNetwork]

    def window_index(self, x: np.ndarray) -> np.ndarray:
        """The window sampling each frame position: the last one starting at or before it
        (a shared border frame belongs to the later window), as the runtime picks it."""
        starts = np.array([w.start for w in self.windows], dtype=np.float64)
        return np.maximum(np.searchsorted(starts, np.asarray(x, dtype=np.float64), side="right") - 1, 0)

    def parameters(self, x: np.ndarray) -> np.ndarray:
        """Pose parameters (len(x), M) at frame positions x (the reference evaluation)."""
        x = np.asarray(x, dtype=np.float64)
        y = np.zeros((x.size, self.layout.outputs))
        which = self.window_index(x)
        for i in np.unique(which):
            w, sel = self.windows[i], which == i
            y[sel] = forward(w.net.weights(), fourier_features(x[sel] - w.start, w.frames, w.freqs))
        return np.clip(self.offset + self.scale * y, -MAX_ABS_VALUE, MAX_ABS_VALUE)


def _window_block(w: WindowNetwork) -> bytes:
    net, k = w.net, len(w.freqs)
    out = bytearray(struct.pack("<HHB3x", k, net.codes["W0"].shape[0], net.bits))
    out += struct.pack("<6f", *net.steps)
    out += struct.pack(f"<{k}H", *w.freqs) + bytes(2 * (k % 2))
    bw = BitWriter()
    bias = 1 << (net.bits - 1)
    for name in TENSORS:
        bw.write(net.codes[name].ravel() + bias, net.bits)
    stream = bw.getvalue()
    return bytes(out + stream + bytes(-len(stream) % 4))


def write_payload(model: NeuralModel) -> bytes:
    """docs/FORMAT.md, NEUR version 2: clip-wide layout, window table, window blocks."""
    L = model.layout
    m = L.outputs
    out = bytearray(struct.pack("<IIHHHH", model.frames, model.nodes, m, len(L.refs), len(model.windows), 0))
    for (rm, tm, ro, to), ri in zip(L.entries, L.ref_index):
        out += struct.pack("<BBHHH", rm, tm, ro if rm in (ROT_QUATERNION, ROT_AXIS_ANGLE) else 0,
                           to if tm == TRANS_OUTPUT else 0, ri if rm in (ROT_CONSTANT, ROT_AXIS_ANGLE) else 0)
    out += np.asarray(L.refs, dtype="<f4").tobytes()
    out += np.asarray(model.scale, dtype="<f4").tobytes()
    out += np.asarray(model.offset, dtype="<f4").tobytes()
    blocks = [_window_block(w) for w in model.windows]
    at = len(out) + WINDOW_ENTRY * len(blocks)
    for w, blk in zip(model.windows, blocks):
        out += struct.pack("<IIII", w.start, w.frames, at, len(blk))
        at += len(blk)
    return bytes(out + b"".join(blocks))


def _read_codes(payload: bytes, o: int, shapes: list[tuple[int, ...]], bits: int) -> dict[str, np.ndarray]:
    counts = [int(np.prod(s)) for s in shapes]
    total = sum(counts)
    nbytes = (total * bits + 7) // 8
    bitsarr = np.unpackbits(np.frombuffer(payload, np.uint8, nbytes, o), bitorder="little")
    vals = bitsarr[: total * bits].reshape(total, bits).astype(np.int64) @ (1 << np.arange(bits))
    vals -= 1 << (bits - 1)
    codes, c = {}, 0
    for name, s, cnt in zip(TENSORS, shapes, counts):
        codes[name] = vals[c:c + cnt].reshape(s)
        c += cnt
    return codes


def read_payload(payload: bytes) -> NeuralModel:
    """Parse a payload the encoder wrote (trusted input: the reference decoder for tests)."""
    f, n, m, r, nw, _ = struct.unpack_from("<IIHHHH", payload, 0)
    o = HEADER_SIZE
    table = np.frombuffer(payload, "<u2", 4 * n, o).reshape(n, 4).astype(np.int64)
    raw = np.frombuffer(payload, np.uint8, 8 * n, o).reshape(n, 8)
    o += NODE_ENTRY * n
    refs = np.frombuffer(payload, "<f4", 4 * r, o).reshape(r, 4).astype(np.float64)
    o += 16 * r
    scale = np.frombuffer(payload, "<f4", m, o).astype(np.float64)
    offset = np.frombuffer(payload, "<f4", m, o + 4 * m).astype(np.float64)
    o += 8 * m
    windows = []
    for i in range(nw):
        start, count, at, _size = struct.unpack_from("<IIII", payload, o + WINDOW_ENTRY * i)
        k, h, bits = struct.unpack_from("<HHB", payload, at)
        steps = np.array(struct.unpack_from("<6f", payload, at + 8))
        freqs = [int(v) for v in np.frombuffer(payload, "<u2", k, at + WINDOW_HEADER)]
        codes = _read_codes(payload, at + WINDOW_HEADER + 2 * k + 2 * (k % 2), _shapes(2 * k + 1, h, m), bits)
        windows.append(WindowNetwork(start, count, freqs, QuantizedNetwork(bits, steps, codes)))
    entries = np.stack((raw[:, 0], raw[:, 1], table[:, 1], table[:, 2]), axis=1).astype(np.int64)
    layout = PoseLayout(entries, table[:, 3].copy(), refs, np.ones(m), np.zeros((f, m)))
    return NeuralModel(f, n, layout, scale, offset, windows)


def reference_pose(payload: bytes, motion: Motion, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Local rotations and translations a payload decodes to at frame positions ``x``,
    computed in float64 from the stored (float32) numbers: the Python model of the runtime."""
    model = read_payload(payload)
    return local_pose(model.layout, motion, model.parameters(x))


# ------------------------------------------------------------------------ Algorithm 1
@dataclass
class NeuralClipResult(ClipResult):
    """A clip encoded (stats: windows as [start, frames, K, bits], frequencies, parameters,
    splits), with the search's trace: every window in full (start, frames, K, freqs, bits,
    stages, seconds) and every stage of Algorithm 1 (``history``)."""

    windows: list[dict[str, object]] = field(default_factory=list)
    history: list[dict[str, float]] = field(default_factory=list)


def _normalisation(layout: PoseLayout) -> tuple[np.ndarray, np.ndarray]:
    """out = offset + scale * net: offset the mid-range, scale = L / w, so the plain MSE on
    the network's outputs is eq. 3's weighted loss divided by L^2 (L: the largest weighted
    half-range, which keeps the network's targets within [-1, 1])."""
    y, w = layout.targets, layout.weights
    lo, hi = y.min(axis=0), y.max(axis=0)
    offset = _f32(0.5 * (lo + hi))
    L = max(float(np.max(0.5 * (hi - lo) * w)) if y.size else 1.0, 1e-9)
    return _f32(L / w), offset


def algorithm1(z: np.ndarray, frames: int, mode: str, k_max: int, iterations: int, restart: bool,
               rng: np.random.Generator, max_bin: int | None = None
               ) -> Iterator[tuple[list[int], dict[str, np.ndarray]]]:
    """Algorithm 1's stages on normalised targets ``z`` (F, M): yields (frequencies, weights)
    after each fit, K = 0 ... k_max; the caller stops it when the error is good enough.
    ``mode`` "naive" takes Omega = {1, ..., K} (DCT bins) instead of the residual's peaks;
    no bin above ``max_bin`` is taken (the stages end when none is left)."""
    fx = np.arange(frames, dtype=np.float64)
    freqs: list[int] = []
    p: dict[str, np.ndarray] | None = None
    while True:
        x = fourier_features(fx, frames, freqs)
        p = fit_stage(p, x, z, iterations, restart, rng)
        yield list(freqs), p
        if len(freqs) >= k_max:
            return
        k = len(freqs) + 1 if mode == "naive" else next_frequency(z - forward(p, x), freqs, max_bin)
        if k is None or (max_bin is not None and k > max_bin):
            return
        freqs.append(k)
        p = grow_network(p, rng)


def initial_windows(world: np.ndarray, cm_per_unit: float, window_frames: int, jump_cm: float) -> list[tuple[int, int]]:
    """(start, frames) of the first windows: cut where any point jumps more than ``jump_cm``
    between two frames (CMU's synthetic T-pose frame 0: a network would spend frequencies on
    the step), each such pair its own two-frame window; the rest in even pieces of at most
    ``window_frames`` frames. Consecutive windows share their border frame."""
    frames = world.shape[0]
    if frames == 1:
        return [(0, 1)]
    step = np.max(np.linalg.norm(np.diff(world, axis=0), axis=-1), axis=1) * cm_per_unit
    cuts = sorted({0, frames - 1} | {int(i) for i in np.flatnonzero(step > jump_cm)}
                  | {int(i) + 1 for i in np.flatnonzero(step > jump_cm)})
    out: list[tuple[int, int]] = []
    for a, b in zip(cuts[:-1], cuts[1:]):
        pieces = -(-(b - a) // max(window_frames - 1, 1))
        edges = [a + round(i * (b - a) / pieces) for i in range(pieces + 1)]
        out += [(s, e - s + 1) for s, e in zip(edges[:-1], edges[1:])]
    return out


def encode_clip(motion: Motion, cm_per_unit: float, settings: NeuralSettings,
                check: ClipCheck,
                on_stage: Callable[[dict[str, float]], None] | None = None) -> NeuralClipResult:
    """The clip in windows, Algorithm 1 per window (adaptive split: a window that misses the
    tolerance within the K cap is halved), then the whole payload checked through the runtime
    (``check(payload)``: the (F, N) world error there, in file units); a window whose frames
    miss there gets more weight bits."""
    started = time.perf_counter()
    sk = motion.skeleton
    layout = pose_layout(motion)
    tol_units = settings.tolerance.per_node_cm(sk) / cm_per_unit
    frames = motion.frame_count
    scale, offset = _normalisation(layout)
    z = (layout.targets - offset) / scale
    world = forward_kinematics(sk, motion.rotations, motion.translations, motion.scales)[1]

    def window_error(s: int, y: np.ndarray) -> np.ndarray:
        rot, trans = local_pose(layout, motion, y)
        return np.linalg.norm(forward_kinematics(sk, rot, trans, sk.rest_scales[None])[1] - world[s:s + len(y)], axis=-1)

    half_world, half_step, half_turn = halfway_world(motion)
    held = (half_step * cm_per_unit <= settings.jump_cm) & (half_turn <= GLITCH_TURN_DEG)

    def halfway_error(s: int, y: np.ndarray) -> np.ndarray:
        """Error at s + 0.5 ... of parameters ``y`` there; 0 on intervals the guard skips."""
        rot, trans = local_pose(layout, motion, y)
        err = np.linalg.norm(forward_kinematics(sk, rot, trans, sk.rest_scales[None])[1] - half_world[s:s + len(y)], axis=-1)
        return np.where(held[s:s + len(y), None], err, 0.0)

    history: list[dict[str, float]] = []
    done: list[tuple[WindowNetwork, dict[str, np.ndarray], dict[str, object]]] = []
    queue = initial_windows(world, cm_per_unit, settings.window_frames, settings.jump_cm)
    splits = 0
    # One BLAS thread for the whole search, not only the L-BFGS: results then do not depend
    # on the machine's thread count.
    with _one_thread():
        while queue:
            s, n = queue.pop(0)
            t0 = time.perf_counter()
            found = _fit_window(s, n, z, layout, scale, offset, settings, motion.frame_rate, tol_units, window_error,
                                halfway_error, history, on_stage)
            if found is None:
                if n <= 2:
                    raise ToleranceNotMet(f"{motion.name}: frames {s}-{s + n - 1} miss the tolerance "
                                          f"with K = {settings.max_frequencies} frequencies (the cap)")
                half = (n - 1) // 2
                queue[:0] = [(s, half + 1), (s + half, n - half)]
                splits += 1
                continue
            w, p, stages = found
            done.append((w, p, {"start": s, "frames": n, "K": len(w.freqs), "freqs": list(w.freqs),
                                "bits": w.net.bits, "stages": stages, "seconds": time.perf_counter() - t0}))
        model = NeuralModel(frames, sk.node_count, layout, scale, offset, [d[0] for d in done])

        def more_bits(errors: np.ndarray) -> None:
            # The Python model met the tolerance with a margin: a miss here is a rounding
            # difference on a frame at the edge; one more bit for the windows holding it.
            over = np.any(errors > tol_units[None, :], axis=1)
            for i in np.unique(model.window_index(np.flatnonzero(over))):
                w, p, info = done[i]
                if w.net.bits >= settings.max_bits:
                    raise ToleranceNotMet(f"{motion.name}: window at frame {w.start} misses through the runtime")
                w.net = quantize(p, w.net.bits + 1)
                info["bits"] = w.net.bits

        # Each round adds a bit to some window until one is at max_bits: this bounds the rounds.
        rounds = len(done) * (settings.max_bits - settings.min_bits + 1)
        attempt = meet_tolerance(lambda: write_payload(model), check, tol_units, more_bits, rounds)
        if not attempt.met:
            raise ToleranceNotMet(f"{motion.name}: misses through the runtime after {rounds} rounds of weight bits")
    windows = [d[2] for d in done]
    stats = {"windows": [[w["start"], w["frames"], w["K"], w["bits"]] for w in windows],
             "frequencies": [int(w["K"]) for w in windows], "parameters": sum(_pack(d[1]).size for d in done),
             "splits": splits}
    return NeuralClipResult(attempt.payload, attempt.errors_units, stats, time.perf_counter() - started,
                            windows=windows, history=history)


def _fit_window(s: int, n: int, z: np.ndarray, layout: PoseLayout, scale: np.ndarray, offset: np.ndarray,
                settings: NeuralSettings, fps: float, tol_units: np.ndarray,
                window_error: Callable[[int, np.ndarray], np.ndarray],
                halfway_error: Callable[[int, np.ndarray], np.ndarray], history: list[dict[str, float]],
                on_stage: Callable[[dict[str, float]], None] | None
                ) -> tuple[WindowNetwork, dict[str, np.ndarray], int] | None:
    """Algorithm 1 on frames s ... s + n - 1 until the quantized network (fewest bits) meets
    the tolerance in the Python model of the runtime; None when K reaches the cap first."""
    started = time.perf_counter()
    x = np.arange(n, dtype=np.float64)
    # Seeded by the window too: the same seed gives the same asset, windows differ.
    rng = np.random.default_rng([settings.seed, s, n])
    if n <= 2:
        # Two frames (a jump's own window, or the end of halving): the exact straight line in
        # parameters, built rather than trained. A trained two-point fit is free between its
        # frames and was seen to bend 35 cm there; this network is linear on [0, 1], where
        # both hidden layers stay positive and ELU is the identity.
        z0, dz = z[s], z[s + n - 1] - z[s]
        stages = iter([([], {"W0": np.array([[1.0], [0.0]]), "b0": np.ones(2), "W1": np.eye(2),
                              "b1": np.zeros(2), "W2": np.stack([dz, z0 - dz], axis=1),
                              "b2": np.zeros(z.shape[1])})])
    else:
        stages = algorithm1(z[s:s + n], n, settings.frequencies, settings.max_frequencies, settings.iterations,
                            settings.restart, rng, highest_bin(n, fps, settings.max_frequency_hz))
    for stage, (freqs, p) in enumerate(stages, start=1):
        err = window_error(s, offset + scale * forward(p, fourier_features(x, n, freqs)))
        rec = {"start": s, "frames": n, "K": len(freqs), "max_error_cm": float(np.max(err / tol_units)),
               "seconds": time.perf_counter() - started}
        history.append(rec)
        if on_stage:
            on_stage(rec)
        # Leave a little of the tolerance to the weights' quantization.
        if np.max(err / tol_units) > 0.95:
            continue
        for bits in range(settings.min_bits, settings.max_bits + 1):
            w = WindowNetwork(s, n, list(freqs), quantize(p, bits))
            y = offset + scale * forward(w.net.weights(), fourier_features(x, n, freqs))
            y = np.clip(y, -MAX_ABS_VALUE, MAX_ABS_VALUE)
            # A small margin for the runtime's float32 arithmetic (agrees to ~1e-4 cm).
            if np.all(window_error(s, y) <= tol_units[None, :] * 0.999):
                if n <= 2 or settings.halfway_factor == 0.0:
                    return w, p, stage
                yh = offset + scale * forward(w.net.weights(), fourier_features(x[:-1] + 0.5, n, freqs))
                yh = np.clip(yh, -MAX_ABS_VALUE, MAX_ABS_VALUE)
                if np.all(halfway_error(s, yh) <= tol_units[None, :] * settings.halfway_factor):
                    return w, p, stage
                history[-1]["halfway_miss"] = 1.0
                break  # a bend between frames: more bits will not remove it; a later stage or a split may
    return None


def fit_stages(motion: Motion, mode: str, k_max: int, iterations: int, seed: int = 1,
               restart: bool = True) -> Iterator[NeuralModel]:
    """The one-window model (16-bit weights) after every stage of :func:`algorithm1`, K = 0 ...
    k_max, without the tolerance test: for the rate/error curves of bench/bench_neural.py."""
    layout = pose_layout(motion)
    scale, offset = _normalisation(layout)
    z = (layout.targets - offset) / scale
    frames = motion.frame_count
    for freqs, p in algorithm1(z, frames, mode, k_max, iterations, restart, np.random.default_rng(seed)):
        yield NeuralModel(frames, motion.skeleton.node_count, layout, scale, offset,
                          [WindowNetwork(0, frames, freqs, quantize(p, 16))])
