"""Codec ``ik-predict``: seed 000 §3.2 and §5 (IKBP) — closed-loop inverse-kinematics
prediction of the converted joint angles, written as docs/FORMAT.md's ``IKPR`` payload.

State per frame: for every joint that turns, the world direction of its bone ``d`` as two
spherical angles (φ polar, ϕ azimuth, eq. 5) about a per-joint polar axis, and the twist ψ about
the bone (eq. 6–7, ``W = A(ψ, d)·R_cross(u → d)``), plus the coded local translations (the
root's). Why world angles about a chosen axis:

* the chain Jacobian of eq. 17–20 is closed form only for world link directions;
* the runtime turns (φ, ϕ, ψ) into a quaternion with a few sines and one normalisation, exactly
  the same way in the encoder's closed loop and in the decoder (it is the same C function);
* the polar axis of each joint is the world axis its bone stays farthest from over the clip,
  so ϕ does not spin at the poles (docs/IKFK_STUDY.md, point 4);
* a joint's angle error moves only the points rigidly attached to it (its children through
  non-coded nodes): errors along a chain add up but are not amplified, and the step of each
  joint follows from that lever arm (hierarchical steps).

The prediction step lives in the runtime (``runtime_c/src/codec_ikpredict.c``);
:func:`closed_loop` calls it through the cffi binding, so the encoder's reconstruction is the
decoder's, bit for bit. The encoder searches a global step scale for the smallest payload
whose world error, measured through the runtime's ``check``, is within the tolerance on every
frame of every node.
"""
from __future__ import annotations

import struct
import time
from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..entropy import entropy_encode
from ..ikfk.angles import bone_axes, shortest_arc
from ..ikfk.chains import motion_chains
from ..kinematics import forward_kinematics
from ..motion import Motion, Skeleton
from ..rotations import quat_conjugate, quat_multiply, quat_rotate
from ..runtime import Result, RuntimeResultError
from ..tolerance import Tolerance
from ..units import skeleton_height

ROT_IDENTITY, ROT_CONSTANT, ROT_CODED = 0, 1, 2
TRANS_REST, TRANS_CODED = 0, 1
HEADER = 48
NODE_RECORD = 32
BLOCK_ENTRY = 12
NO_CHILD = 0xFFFF
MAX_CHAINS = 16
MAX_BLOCK_FRAMES = 4096
MAX_K = 4.0
MIN_STEP, MAX_STEP = 1e-12, 1e3
MAX_ANGLE_STEP = 0.5  # radians: coarser steps make the prediction meaningless
FLAG_ROOT_VELOCITY = 1
_ZERO = 1e-12


class ToleranceNotMet(RuntimeError):
    """The encoder could not reach the requested tolerance."""


@dataclass
class IkPredictSettings:
    """Settings of the ``ik-predict`` codec.

    Parameters
    ----------
    tolerance : Tolerance
        Max world-space position error per node, every frame (cm).
    k : float, default 0.0
        Acceleration-constraint parameter of eq. 15 (0 … 4): the predicted angle change is the
        one closest to k × the last change that moves the effectors by their decoded deltas.
    block_frames : int, default 16
        Frames per block; the first frame of each block is intra (random access cost).
    effector_step_cm : float or None
        Quantization step of the effector deltas (cm); default ``effector_fraction`` × the
        smallest node tolerance.
    effector_fraction : float, default 0.25
        See ``effector_step_cm``.
    ik : bool, default True
        False sends no effector deltas and uses no Jacobian: plain closed-loop DPCM of the
        same angles (the comparison that tells what the IK step buys).
    root_velocity : bool, default True
        Predict coded translations at constant velocity (else repeat the last frame).
    search_steps : int, default 14
        Most encode-and-check rounds of the step-scale search.
    """

    tolerance: Tolerance
    k: float = 0.0
    block_frames: int = 16
    effector_step_cm: float | None = None
    effector_fraction: float = 0.25
    ik: bool = True
    root_velocity: bool = True
    search_steps: int = 14

    def validate(self) -> None:
        """Raise ValueError for a setting out of range."""
        if not (np.isfinite(self.k) and 0.0 <= self.k <= MAX_K):
            raise ValueError(f"ik-predict: k must be in [0, {MAX_K}], got {self.k!r}")
        if not (isinstance(self.block_frames, (int, np.integer)) and 1 <= self.block_frames <= MAX_BLOCK_FRAMES):
            raise ValueError(f"ik-predict: block_frames must be an integer in [1, {MAX_BLOCK_FRAMES}], "
                             f"got {self.block_frames!r}")
        if self.effector_step_cm is not None and not (np.isfinite(self.effector_step_cm) and self.effector_step_cm > 0):
            raise ValueError(f"ik-predict: effector_step_cm must be a positive number, got {self.effector_step_cm!r}")
        if not (np.isfinite(self.effector_fraction) and self.effector_fraction > 0):
            raise ValueError(f"ik-predict: effector_fraction must be positive, got {self.effector_fraction!r}")
        if not (isinstance(self.search_steps, (int, np.integer)) and self.search_steps >= 1):
            raise ValueError(f"ik-predict: search_steps must be a positive integer, got {self.search_steps!r}")


@dataclass
class IkPredictClipResult:
    payload: bytes
    errors_units: np.ndarray
    scale: float
    checks: int
    chains: int
    seconds: float


# ------------------------------------------------------------------------ clip analysis
@dataclass
class _Plan:
    """What the payload's head says about a clip, and the signals the closed loop codes."""

    rot_mode: np.ndarray     # (N,)
    trans_mode: np.ndarray   # (N,)
    polar: np.ndarray        # (N,) polar axis of coded joints
    primary: np.ndarray      # (N,) primary child or NO_CHILD
    vec: np.ndarray          # (N, 4) float32: bone axis u or the constant quaternion
    chains: list[tuple[int, ...]]
    targets: np.ndarray      # (F, 3J + 3T)
    effectors: np.ndarray    # (F, 3C)
    base_dir: np.ndarray     # (J,) direction step at scale 1, radians
    base_twist: np.ndarray   # (J,)
    base_trans: float        # file units


def _polar_angles(d: np.ndarray, axis: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """φ, ϕ of world directions d (F, J, 3) in each joint's polar frame (the C side's cyclic
    permutation: s.z = d[a], s.x = d[a+1], s.y = d[a+2])."""
    j = np.arange(d.shape[1])
    sz = d[:, j, axis]
    sx = d[:, j, (axis + 1) % 3]
    sy = d[:, j, (axis + 2) % 3]
    return np.arctan2(np.hypot(sx, sy), sz), np.arctan2(sy, sx)


def _levers(sk: Skeleton, coded: np.ndarray, axes: np.ndarray) -> tuple[np.ndarray, np.ndarray, list[list[int]]]:
    """Per node: the largest rest distance to a point its world rotation moves (its children,
    and through non-coded children their children), that distance off the bone axis, and
    those points. A coded child carries its own rotation, so the walk stops there."""
    n = sk.node_count
    rest = np.zeros((n, 3))
    for i, p in enumerate(sk.parents):
        rest[i] = sk.offsets[i] + (rest[p] if p >= 0 else 0.0)
    lever = np.zeros(n)
    lever_twist = np.zeros(n)
    moved: list[list[int]] = [[] for _ in range(n)]
    for i in range(n):
        stack = list(sk.children(i))
        while stack:
            c = stack.pop()
            moved[i].append(c)
            if not coded[c]:
                stack.extend(sk.children(c))
        if moved[i]:
            v = rest[moved[i]] - rest[i]
            lever[i] = float(np.linalg.norm(v, axis=1).max())
            lever_twist[i] = float(np.linalg.norm(np.cross(v, axes[i]), axis=1).max())
    return lever, lever_twist, moved


def analyse(motion: Motion, cm_per_unit: float, settings: IkPredictSettings) -> _Plan:
    """Modes, axes, chains, target signals and unit steps of a clip."""
    sk = motion.skeleton
    f, n = motion.frame_count, sk.node_count
    rot, tr = motion.rotations, motion.translations
    rot_mode = np.zeros(n, dtype=np.int64)
    for i in range(n):
        if not sk.rotation_order(i):
            continue
        if np.all(rot[:, i] == rot[0, i]):
            rot_mode[i] = ROT_IDENTITY if np.array_equal(rot[0, i], [0.0, 0.0, 0.0, 1.0]) else ROT_CONSTANT
        else:
            rot_mode[i] = ROT_CODED
    trans_mode = np.where(np.all(tr == sk.offsets[None], axis=(0, 2)), TRANS_REST, TRANS_CODED)
    coded = rot_mode == ROT_CODED
    axes = bone_axes(sk)
    vec = np.zeros((n, 4), dtype=np.float32)
    vec[coded, :3] = axes[coded]
    vec[rot_mode == ROT_CONSTANT] = rot[0, rot_mode == ROT_CONSTANT]
    u = vec[:, :3].astype(np.float64)  # the float32 axes the runtime reads
    primary = np.full(n, NO_CHILD, dtype=np.int64)
    for i in np.flatnonzero(coded):
        direct = [c for c in sk.children(int(i)) if np.linalg.norm(sk.offsets[c]) > _ZERO]
        if direct:
            primary[i] = direct[0]

    world_rot, world_pos = forward_kinematics(sk, rot, tr)
    joints = np.flatnonzero(coded)
    w = world_rot[:, joints]
    d = quat_rotate(w, np.broadcast_to(u[joints], w.shape[:-1] + (3,)))
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    # The polar axis the bone stays farthest from (ϕ is ill-conditioned near the poles).
    polar = np.full(n, 0, dtype=np.int64)
    if len(joints):
        polar[joints] = np.argmin(np.abs(d).max(axis=0), axis=-1)
    phi, az = _polar_angles(d, polar[joints])
    a = quat_multiply(w, quat_conjugate(shortest_arc(u[joints], d)))
    psi = 2.0 * np.arctan2(np.sum(a[..., :3] * d, axis=-1), a[..., 3])
    ang = np.stack((phi, np.unwrap(az, axis=0), np.unwrap(psi, axis=0)), axis=-1)  # (F, J, 3)
    # Each block's intra frame is sent whole: bring ϕ and ψ into (−π, π] there, and shift the
    # rest of the block by the same turns so the block stays continuous.
    starts = (np.arange(f) // settings.block_frames) * settings.block_frames
    turns = np.round(ang[starts, :, 1:] / (2.0 * np.pi))
    ang[:, :, 1:] -= 2.0 * np.pi * turns
    coded_t = np.flatnonzero(trans_mode == TRANS_CODED)
    targets = np.concatenate((ang.reshape(f, -1), tr[:, coded_t].reshape(f, -1)), axis=1)

    chains: list[tuple[int, ...]] = []
    if settings.ik:
        chains = [c.nodes for c in motion_chains(sk)][:MAX_CHAINS]
    eff = [world_pos[:, c[-1]] - world_pos[:, c[0]] for c in chains]
    effectors = np.concatenate(eff, axis=1) if eff else np.zeros((f, 0))

    # Hierarchical steps: a point's tolerance is shared by the coded joints that move it,
    # each joint's share divided by its lever arm (floored so a joint that moves nothing
    # still gets a bounded step).
    tol = settings.tolerance.per_node_cm(sk) / cm_per_unit
    lever, lever_twist, moved = _levers(sk, coded, u)
    floor = 0.02 * skeleton_height(sk)
    movers = np.zeros(n)
    for i in joints:
        for c in moved[i]:
            for dsc in [c] + sk.descendants(c):
                movers[dsc] += 1
    share = tol / np.maximum(movers, 1)
    base_dir = np.empty(len(joints))
    base_twist = np.empty(len(joints))
    for s, i in enumerate(joints):
        pts = [p for c in moved[i] for p in [c] + sk.descendants(c)]
        budget = share[pts].min() if pts else tol.min()
        base_dir[s] = budget / max(lever[i], floor)
        base_twist[s] = budget / max(lever_twist[i], floor)
    return _Plan(rot_mode, trans_mode, polar, primary, vec, chains, targets, effectors,
                 base_dir, base_twist, 0.5 * float(tol.min()))


# ------------------------------------------------------------------------ payload
def skeleton_records(sk: Skeleton) -> bytes:
    """The SKEL section's node records as the runtime reads parents and rest offsets
    (16-byte section header, 32 bytes per node); names and channels are not needed here."""
    out = bytearray(16 + 32 * sk.node_count)
    struct.pack_into("<I", out, 0, sk.node_count)
    for i in range(sk.node_count):
        struct.pack_into("<i4x3f", out, 16 + 32 * i, int(sk.parents[i]), *sk.offsets[i].astype(np.float32))
    return bytes(out)


def head_bytes(plan: _Plan, frames: int, settings: IkPredictSettings, scale: float,
               eff_step: float, stream_bytes: int = 0) -> bytes:
    """Header, node table and chain tables (docs/FORMAT.md, IKPR)."""
    n = len(plan.rot_mode)
    joints = np.flatnonzero(plan.rot_mode == ROT_CODED)
    dir_step = np.clip(scale * plan.base_dir, MIN_STEP, MAX_ANGLE_STEP).astype(np.float32)
    twist_step = np.clip(scale * plan.base_twist, MIN_STEP, MAX_ANGLE_STEP).astype(np.float32)
    trans_step = float(np.clip(scale * plan.base_trans, MIN_STEP, MAX_STEP))
    total = sum(len(c) for c in plan.chains)
    flags = FLAG_ROOT_VELOCITY if settings.root_velocity else 0
    out = [struct.pack("<IIIIIHHfffB3xII", frames, n, settings.block_frames, len(joints),
                       int(np.sum(plan.trans_mode == TRANS_CODED)), len(plan.chains), total,
                       settings.k, eff_step, trans_step, flags, stream_bytes, 0)]
    slot = {int(j): s for s, j in enumerate(joints)}
    for i in range(n):
        s = slot.get(i)
        out.append(struct.pack("<BBBBHH4fff", int(plan.rot_mode[i]), int(plan.trans_mode[i]),
                               int(plan.polar[i]) if s is not None else 0, 0, int(plan.primary[i]), 0,
                               *plan.vec[i], dir_step[s] if s is not None else 0.0,
                               twist_step[s] if s is not None else 0.0))
    out.append(struct.pack(f"<{len(plan.chains)}H", *[len(c) for c in plan.chains]))
    out.append(struct.pack(f"<{total}H", *[x for c in plan.chains for x in c]))
    body = b"".join(out)
    return body + bytes((-len(body)) % 4)


def closed_loop(head: bytes, skeleton: bytes, targets: np.ndarray, effectors: np.ndarray,
                poses: bool = False) -> tuple[np.ndarray, np.ndarray | None]:
    """Run the runtime's closed loop (``mcd_ikp_closed_loop``): the codes (F, 3C + 3J + 3T)
    and, with ``poses``, the local pose (F, N, 7) float32 the runtime samples at each frame."""
    from mocodec_runtime._native import ffi, lib

    frames = targets.shape[0]
    nodes = struct.unpack_from("<I", head, 4)[0]
    size = int(lib.mcd_ikp_work_size(head, len(head), skeleton, len(skeleton)))
    if size == 0:
        raise ValueError("ik-predict: the payload head is not valid for this skeleton")
    mem = ffi.new("uint8_t[]", size + 16)
    addr = int(ffi.cast("uintptr_t", mem))
    work = ffi.cast("void*", addr + (-addr) % 16)
    t = np.ascontiguousarray(targets, dtype=np.float64)
    e = np.ascontiguousarray(effectors, dtype=np.float64)
    codes = np.zeros((frames, effectors.shape[1] + targets.shape[1]), dtype=np.int32)
    out = np.zeros((frames, nodes, 7), dtype=np.float32) if poses else None
    code = lib.mcd_ikp_closed_loop(
        head, len(head), skeleton, len(skeleton), frames, ffi.cast("double*", ffi.from_buffer(t)),
        ffi.cast("double*", ffi.from_buffer(e)), ffi.cast("int32_t*", ffi.from_buffer(codes)),
        ffi.cast("mcd_transform*", ffi.from_buffer(out)) if poses else ffi.NULL, work, size)
    if code != 0:
        raise RuntimeResultError(code, "mcd_ikp_closed_loop")
    return codes, out


def assemble(head: bytes, codes: np.ndarray, chains: int, block_frames: int) -> bytes:
    """The payload: head, block table and each block's three entropy streams."""
    frames = codes.shape[0]
    c3 = 3 * chains
    joints3 = (struct.unpack_from("<I", head, 12)[0]) * 3
    table, streams, at = [], [], 0
    for b0 in range(0, frames, block_frames):
        blk = codes[b0: b0 + block_frames]
        parts = [blk[1:, :c3], blk[:, c3: c3 + joints3], blk[:, c3 + joints3:]]
        data = [entropy_encode(p.ravel(), 3) if p.size else b"" for p in parts]
        table.append(struct.pack("<III", at, len(data[0]), len(data[1])))
        streams.extend(data)
        at += sum(len(x) for x in data)
    head = head[:40] + struct.pack("<I", at) + head[44:]
    body = head + b"".join(table) + b"".join(streams)
    return body + bytes((-len(body)) % 4)


# ------------------------------------------------------------------------ encoder
CheckFn = Callable[[bytes], np.ndarray]


def encode_clip(motion: Motion, cm_per_unit: float, settings: IkPredictSettings,
                check: CheckFn) -> IkPredictClipResult:
    """Encode one clip so that every node's error measured by ``check`` (through the C
    runtime) is within the tolerance on every frame: search the global step scale (doubling
    or halving until the pass/fail edge is found, then bisecting it) and keep the smallest
    payload that passes."""
    started = time.perf_counter()
    settings.validate()
    plan = analyse(motion, cm_per_unit, settings)
    sk = motion.skeleton
    skel = skeleton_records(sk)
    tol = settings.tolerance.per_node_cm(sk) / cm_per_unit
    eff_cm = settings.effector_step_cm if settings.effector_step_cm is not None \
        else settings.effector_fraction * float(tol.min()) * cm_per_unit
    eff_step = float(np.clip(eff_cm / cm_per_unit, MIN_STEP, MAX_STEP))
    frames = motion.frame_count
    checks = 0
    best: tuple[bytes, np.ndarray, float] | None = None

    def attempt(scale: float) -> bool:
        nonlocal checks, best
        head = head_bytes(plan, frames, settings, scale, eff_step)
        try:
            codes, _ = closed_loop(head, skel, plan.targets, plan.effectors)
        except RuntimeResultError as exc:
            if exc.code == Result.OUT_OF_RANGE:  # codes past the coder's range: too fine
                return False
            raise
        payload = assemble(head, codes, len(plan.chains), settings.block_frames)
        errors = check(payload)
        checks += 1
        ok = bool(np.all(errors <= tol[None, :]))
        if ok and (best is None or len(payload) < len(best[0])):
            best = (payload, errors, scale)
        return ok

    # Bracket the pass/fail edge by factors of 2, then bisect it geometrically.
    lo, hi = None, None
    scale = 1.0
    budget = settings.search_steps
    while budget > 0 and (lo is None or hi is None):
        budget -= 1
        if attempt(scale):
            lo = scale
            scale *= 2.0
        else:
            hi = scale
            scale /= 2.0
    while budget > 0 and lo is not None and hi is not None and hi / lo > 1.1:
        budget -= 1
        mid = float(np.sqrt(lo * hi))
        if attempt(mid):
            lo = mid
        else:
            hi = mid
    if best is None:
        raise ToleranceNotMet(f"{motion.name}: ik-predict found no step scale within "
                              f"{settings.search_steps} rounds that meets the tolerance")
    payload, errors, scale = best
    return IkPredictClipResult(payload, errors, scale, checks, len(plan.chains),
                               time.perf_counter() - started)
