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

import numpy as np

from ..entropy import entropy_encode
from ..ikfk.angles import bone_axes, shortest_arc
from ..ikfk.chains import motion_chains
from ..container import skeleton_section
from ..kinematics import forward_kinematics
from ..motion import Motion, Skeleton
from ..rotations import quat_conjugate, quat_multiply, quat_rotate
from ..runtime import TRANSFORM_FLOATS, Result, RuntimeResultError
from ..tolerance import ClipCheck, Tolerance, ToleranceNotMet, within
from ..units import skeleton_height
from . import ClipResult

ROT_IDENTITY, ROT_CONSTANT, ROT_CODED = 0, 1, 2
TRANS_REST, TRANS_CODED = 0, 1
HEADER = 48
NODE_RECORD = 32
BLOCK_ENTRY = 16
NO_CHILD = 0xFFFF
MAX_CHAINS = 16
MAX_BLOCK_FRAMES = 4096
MAX_GAP = 255
MAX_K = 4.0
MIN_STEP, MAX_STEP = 1e-12, 1e3
MAX_ANGLE_STEP = 0.5  # radians: coarser steps make the prediction meaningless
FLAG_ROOT_VELOCITY = 1
_ZERO = 1e-12


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
        Coded frames per block; the first of each block is intra (random access cost).
    max_gap : int, default 8
        Most frames from one coded frame to the next (1: every frame is coded, the seed's
        IKBP). With more, the encoder skips frames that interpolating their coded neighbours
        reproduces within ``gap_fraction`` of the tolerance (measured on the original
        motion), and the runtime interpolates them. The tolerance is checked on every frame
        either way.
    gap_fraction : float, default 0.7
        See ``max_gap``.
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
    relax_rounds : int, default 6
        Rounds of the per-joint relax pass after the search (0: global scale only).
    relax_target : float, default 0.9
        The relax pass aims each joint's worst point at this fraction of its tolerance.
    """

    tolerance: Tolerance
    k: float = 0.0
    block_frames: int = 16
    max_gap: int = 8
    gap_fraction: float = 0.7
    effector_step_cm: float | None = None
    effector_fraction: float = 0.25
    ik: bool = True
    root_velocity: bool = True
    search_steps: int = 14
    relax_rounds: int = 6
    relax_target: float = 0.9

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
        if not (isinstance(self.relax_rounds, (int, np.integer)) and self.relax_rounds >= 0):
            raise ValueError(f"ik-predict: relax_rounds must be a non-negative integer, got {self.relax_rounds!r}")
        if not (np.isfinite(self.relax_target) and 0.0 < self.relax_target <= 1.0):
            raise ValueError(f"ik-predict: relax_target must be in (0, 1], got {self.relax_target!r}")
        if not (isinstance(self.max_gap, (int, np.integer)) and 1 <= self.max_gap <= MAX_GAP):
            raise ValueError(f"ik-predict: max_gap must be an integer in [1, {MAX_GAP}], got {self.max_gap!r}")
        if not (np.isfinite(self.gap_fraction) and 0.0 < self.gap_fraction < 1.0):
            raise ValueError(f"ik-predict: gap_fraction must be in (0, 1), got {self.gap_fraction!r}")
        if not (isinstance(self.search_steps, (int, np.integer)) and self.search_steps >= 1):
            raise ValueError(f"ik-predict: search_steps must be a positive integer, got {self.search_steps!r}")


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
    frames: np.ndarray       # (G,) the coded frames
    targets: np.ndarray      # (G, 3J + 3T)
    effectors: np.ndarray    # (G, 3C)
    base_dir: np.ndarray     # (J,) direction step at scale 1, radians
    base_twist: np.ndarray   # (J,)
    base_trans: float        # file units
    affects: np.ndarray      # (J, N) bool: the points each coded joint's angles move
    multiplier: np.ndarray   # (J,) per-joint factor on the steps (the relax pass raises it)


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
    animated = motion.animated()
    for i in range(n):
        if not animated[i, 0]:
            continue  # mode 0: the rest rotation (identity for BVH) on every frame
        if np.all(rot[:, i] == rot[0, i]):
            rest = sk.rest_rotations[i]
            at_rest = np.array_equal(rot[0, i], rest) or np.array_equal(rot[0, i], -rest)
            rot_mode[i] = ROT_IDENTITY if at_rest else ROT_CONSTANT
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

    world_rot, world_pos = forward_kinematics(sk, rot, tr, motion.scales)
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
    # Only the coded frames are sent (unwrapped at the full rate first).
    tol_units = settings.tolerance.per_node_cm(sk) / cm_per_unit
    keep = select_frames(motion, world_pos, tol_units * settings.gap_fraction, settings.max_gap)
    g = len(keep)
    ang = ang[keep]
    # Each block's intra frame is sent whole: bring ϕ and ψ into (−π, π] there, and shift the
    # rest of the block by the same turns so the block stays continuous.
    starts = (np.arange(g) // settings.block_frames) * settings.block_frames
    turns = np.round(ang[starts, :, 1:] / (2.0 * np.pi))
    ang[:, :, 1:] -= 2.0 * np.pi * turns
    coded_t = np.flatnonzero(trans_mode == TRANS_CODED)
    targets = np.concatenate((ang.reshape(g, -1), tr[keep][:, coded_t].reshape(g, -1)), axis=1)

    chains: list[tuple[int, ...]] = []
    if settings.ik:
        chains = [c.nodes for c in motion_chains(sk)][:MAX_CHAINS]
    eff = [world_pos[keep, c[-1]] - world_pos[keep, c[0]] for c in chains]
    effectors = np.concatenate(eff, axis=1) if eff else np.zeros((g, 0))

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
    affects = np.zeros((len(joints), n), dtype=bool)
    for s, i in enumerate(joints):
        pts = [p for c in moved[i] for p in [c] + sk.descendants(c)]
        affects[s, pts] = True
        budget = share[pts].min() if pts else tol.min()
        base_dir[s] = budget / max(lever[i], floor)
        base_twist[s] = budget / max(lever_twist[i], floor)
    return _Plan(rot_mode, trans_mode, polar, primary, vec, chains, keep, targets, effectors,
                 base_dir, base_twist, 0.5 * float(tol.min()), affects, np.ones(len(joints)))


# ------------------------------------------------------------------------ payload
def _interpolation_ok(motion: Motion, world_pos: np.ndarray, tol_units: np.ndarray,
                      gap: int, starts: np.ndarray) -> np.ndarray:
    """For each start i of ``starts``: interpolating frames i and i + gap as the runtime does
    (normalised lerp of sign-aligned local rotations, lerp of translations) keeps every frame
    between within ``tol_units`` of the original at every node."""
    sk = motion.skeleton
    a_rot, b_rot = motion.rotations[starts], motion.rotations[starts + gap]
    b_rot = np.where(np.sum(a_rot * b_rot, axis=-1, keepdims=True) < 0, -b_rot, b_rot)
    a_tr, b_tr = motion.translations[starts], motion.translations[starts + gap]
    ok = np.ones(len(starts), dtype=bool)
    for r in range(1, gap):
        t = r / gap
        q = a_rot + (b_rot - a_rot) * t
        q /= np.linalg.norm(q, axis=-1, keepdims=True)
        _, pos = forward_kinematics(sk, q, a_tr + (b_tr - a_tr) * t, sk.rest_scales[None])
        err = np.linalg.norm(pos - world_pos[starts + r], axis=-1)
        ok &= np.all(err <= tol_units[None, :], axis=1)
    return ok


def select_frames(motion: Motion, world_pos: np.ndarray, tol_units: np.ndarray, max_gap: int) -> np.ndarray:
    """The coded frames (G,): from frame 0, greedily the farthest next frame (at most
    ``max_gap`` on) such that interpolating every shorter gap from there also holds the frames
    between within ``tol_units``; always the last frame. Each gap is tested only at the starts
    where the gap one shorter passed, so long gaps cost little."""
    f = motion.frame_count
    ok: dict[int, np.ndarray] = {}
    alive = np.arange(f)
    for g in range(2, min(max_gap, f - 1) + 1):
        alive = alive[alive + g <= f - 1]
        if not len(alive):
            break
        alive = alive[_interpolation_ok(motion, world_pos, tol_units, g, alive)]
        ok[g] = np.zeros(f, dtype=bool)
        ok[g][alive] = True
    keep, i = [0], 0
    while i < f - 1:
        step = 1
        for g in range(min(max_gap, f - 1 - i), 1, -1):
            if g in ok and ok[g][i]:
                step = g
                break
        i += step
        keep.append(i)
    return np.asarray(keep, dtype=np.int64)


def payload_frames(payload: bytes) -> np.ndarray:
    """The frames a payload codes (G,), from its gap table."""
    frames, nodes = struct.unpack_from("<II", payload, 0)
    chains, total = struct.unpack_from("<HH", payload, 20)
    coded = struct.unpack_from("<I", payload, 44)[0]
    if coded == frames:
        return np.arange(frames)
    at = HEADER + NODE_RECORD * nodes + 2 * (chains + total)
    gaps = np.frombuffer(payload, dtype=np.uint8, count=coded - 1, offset=at)
    return np.concatenate(([0], np.cumsum(gaps.astype(np.int64))))


def skeleton_records(sk: Skeleton) -> bytes:
    """The skeleton as the runtime reads it: a complete ``SKEL`` section (version 2: parents,
    rest translation, rotation and scale per node; the units are not read here)."""
    return skeleton_section(sk, 1.0)


def head_bytes(plan: _Plan, frames: int, settings: IkPredictSettings, scale: float,
               eff_step: float, stream_bytes: int = 0) -> bytes:
    """Header, node table and chain tables (docs/FORMAT.md, IKPR)."""
    n = len(plan.rot_mode)
    joints = np.flatnonzero(plan.rot_mode == ROT_CODED)
    dir_step = np.clip(scale * plan.multiplier * plan.base_dir, MIN_STEP, MAX_ANGLE_STEP).astype(np.float32)
    twist_step = np.clip(scale * plan.multiplier * plan.base_twist, MIN_STEP, MAX_ANGLE_STEP).astype(np.float32)
    trans_step = float(np.clip(scale * plan.base_trans, MIN_STEP, MAX_STEP))
    total = sum(len(c) for c in plan.chains)
    flags = FLAG_ROOT_VELOCITY if settings.root_velocity else 0
    coded = len(plan.frames)
    out = [struct.pack("<IIIIIHHfffB3xII", frames, n, settings.block_frames, len(joints),
                       int(np.sum(plan.trans_mode == TRANS_CODED)), len(plan.chains), total,
                       settings.k, eff_step, trans_step, flags, stream_bytes, coded)]
    slot = {int(j): s for s, j in enumerate(joints)}
    for i in range(n):
        s = slot.get(i)
        out.append(struct.pack("<BBBBHH4fff", int(plan.rot_mode[i]), int(plan.trans_mode[i]),
                               int(plan.polar[i]) if s is not None else 0, 0, int(plan.primary[i]), 0,
                               *plan.vec[i], dir_step[s] if s is not None else 0.0,
                               twist_step[s] if s is not None else 0.0))
    out.append(struct.pack(f"<{len(plan.chains)}H", *[len(c) for c in plan.chains]))
    out.append(struct.pack(f"<{total}H", *[x for c in plan.chains for x in c]))
    if coded < frames:
        out.append(np.diff(plan.frames).astype(np.uint8).tobytes())
    body = b"".join(out)
    return body + bytes((-len(body)) % 4)


def closed_loop(head: bytes, skeleton: bytes, targets: np.ndarray, effectors: np.ndarray,
                poses: bool = False) -> tuple[np.ndarray, np.ndarray | None]:
    """Run the runtime's closed loop (``mcd_ikp_closed_loop``): the codes (F, 3C + 3J + 3T)
    and, with ``poses``, the local pose (F, N, 10) float32 the runtime samples at each frame
    (``mcd_transform``: rotation, translation, scale)."""
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
    out = np.zeros((frames, nodes, TRANSFORM_FLOATS), dtype=np.float32) if poses else None
    code = lib.mcd_ikp_closed_loop(
        head, len(head), skeleton, len(skeleton), frames, ffi.cast("double*", ffi.from_buffer(t)),
        ffi.cast("double*", ffi.from_buffer(e)), ffi.cast("int32_t*", ffi.from_buffer(codes)),
        ffi.cast("mcd_transform*", ffi.from_buffer(out)) if poses else ffi.NULL, work, size)
    if code != 0:
        raise RuntimeResultError(code, "mcd_ikp_closed_loop")
    return codes, out


def assemble(head: bytes, codes: np.ndarray, chains: int, block_frames: int,
             frames: np.ndarray) -> bytes:
    """The payload: head, block table and each block's three entropy streams; ``frames``
    are the coded frames (each block's entry holds its first)."""
    coded = codes.shape[0]
    c3 = 3 * chains
    joints3 = (struct.unpack_from("<I", head, 12)[0]) * 3
    table, streams, at = [], [], 0
    for b0 in range(0, coded, block_frames):
        blk = codes[b0: b0 + block_frames]
        parts = [blk[1:, :c3], blk[:, c3: c3 + joints3], blk[:, c3 + joints3:]]
        data = [entropy_encode(p.ravel(), 3) if p.size else b"" for p in parts]
        table.append(struct.pack("<IIII", at, len(data[0]), len(data[1]), int(frames[b0])))
        streams.extend(data)
        at += sum(len(x) for x in data)
    head = head[:40] + struct.pack("<I", at) + head[44:]
    body = head + b"".join(table) + b"".join(streams)
    return body + bytes((-len(body)) % 4)


# ------------------------------------------------------------------------ encoder
def encode_clip(motion: Motion, cm_per_unit: float, settings: IkPredictSettings,
                check: ClipCheck) -> ClipResult:
    """Encode one clip so that every node's error measured by ``check`` (through the C
    runtime) is within the tolerance on every frame: search the global step scale (doubling
    or halving until the pass/fail edge is found, then bisecting it) and keep the smallest
    payload that passes (stats: step_scale, checks, chains).

    Not :func:`mocodec.tolerance.meet_tolerance`'s repair loop: this bisects one step scale
    for the pass/fail edge (steps hold for the whole clip, and in the closed loop a step moves
    every later frame's prediction), then relaxes joints with headroom."""
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
        payload = assemble(head, codes, len(plan.chains), settings.block_frames, plan.frames)
        errors = check(payload)
        checks += 1
        ok = within(errors, tol)
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
    # Relax: the global scale is set by the worst point; joints whose points all keep
    # headroom get coarser steps, round by round, while the clip still passes and shrinks.
    for _ in range(settings.relax_rounds):
        payload, errors, scale = best
        ratio = np.max(errors / tol[None, :], axis=0)                       # (N,)
        worst = np.max(np.where(plan.affects, ratio[None, :], 0.0), axis=1)  # (J,)
        grow = np.clip(np.sqrt(settings.relax_target / np.maximum(worst, 1e-9)), 1.0, 1.5)
        if not np.any(grow > 1.01):
            break
        previous = plan.multiplier.copy()
        plan.multiplier = previous * grow
        size = len(payload)
        if not attempt(scale) or len(best[0]) >= size:
            plan.multiplier = previous
            break
    payload, errors, scale = best
    return ClipResult(payload, errors, {"step_scale": scale, "checks": checks, "chains": len(plan.chains)},
                      time.perf_counter() - started)


# ------------------------------------------------------------------------ inspection
def head_size(payload: bytes) -> int:
    """Bytes of a payload's head (header, node table, chain and gap tables), as the runtime
    parses it."""
    frames, nodes = struct.unpack_from("<II", payload, 0)
    chains, total = struct.unpack_from("<HH", payload, 20)
    coded = struct.unpack_from("<I", payload, 44)[0]
    size = HEADER + NODE_RECORD * nodes + 2 * (chains + total) + (coded - 1 if coded < frames else 0)
    return size + (-size) % 4


def payload_codes(payload: bytes) -> np.ndarray:
    """Every code of a payload (G coded frames, 3C + 3J + 3T) read back from its entropy streams (the
    effector part of intra rows is 0), in the layout :func:`closed_loop` returns."""
    from ..entropy import entropy_decode

    frames, _, block, joints, tracks, chains = struct.unpack_from("<IIIIIH", payload, 0)
    frames = struct.unpack_from("<I", payload, 44)[0]
    c3, j3, t3 = 3 * chains, 3 * joints, 3 * tracks
    at = head_size(payload)
    blocks = -(-frames // block)
    table = np.frombuffer(payload, dtype="<u4", count=4 * blocks, offset=at).reshape(blocks, 4)
    streams = at + BLOCK_ENTRY * blocks
    total = struct.unpack_from("<I", payload, 40)[0]
    codes = np.zeros((frames, c3 + j3 + t3), dtype=np.int32)
    for b in range(blocks):
        n = min(block, frames - b * block)
        off, e_bytes, a_bytes = (int(x) for x in table[b, :3])
        end = int(table[b + 1, 0]) if b + 1 < blocks else total
        sizes = (e_bytes, a_bytes, end - off - e_bytes - a_bytes)
        widths = (c3, j3, t3)
        rows = (n - 1, n, n)
        cols = (slice(0, c3), slice(c3, c3 + j3), slice(c3 + j3, c3 + j3 + t3))
        first = (b * block + 1, b * block, b * block)
        pos = streams + off
        for k in range(3):
            if rows[k] * widths[k]:
                vals = entropy_decode(payload[pos: pos + sizes[k]], rows[k] * widths[k], 3)
                codes[first[k]: first[k] + rows[k], cols[k]] = vals.reshape(rows[k], widths[k])
            pos += sizes[k]
    return codes


def reconstruction(payload: bytes, motion: Motion, cm_per_unit: float,
                   settings: IkPredictSettings) -> np.ndarray:
    """The encoder's own reconstruction of ``payload``: the closed loop rerun with the
    payload's head on the clip's signals, as local poses (G, N, 10) float32 at every coded
    frame (:func:`payload_frames`).
    Raises ValueError when the rerun does not give the payload's codes back."""
    plan = analyse(motion, cm_per_unit, settings)
    head = payload[: head_size(payload)]
    head = head[:40] + bytes(4) + head[44:]  # the closed loop ran before the streams existed
    codes, poses = closed_loop(head, skeleton_records(motion.skeleton), plan.targets,
                               plan.effectors, poses=True)
    if not np.array_equal(codes, payload_codes(payload)):
        raise ValueError("ik-predict: the closed loop does not reproduce the payload's codes")
    return poses
