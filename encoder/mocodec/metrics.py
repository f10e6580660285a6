"""Error and size metrics shared by every codec and benchmark.

Errors are world-space distances between the original and the decoded position of every joint
and end site on every frame, reported in centimetres and in % of skeleton height. The mean
follows seed 000 eq. 25-26 (per-joint mean over frames, then mean over joints). ACL's
virtual-vertex metric places three vertices at ``shell_cm`` along each node's local axes and
measures how far they move. Sizes follow DESIGN.md's two conventions.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Iterable

import numpy as np

from .motion import Motion, Skeleton
from .rotations import quat_angle, rotate_axis

Chunk = tuple[tuple[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray], np.ndarray | None, np.ndarray | None]
"""Frames of one clip for :meth:`ErrorMetric.evaluate_chunks`: original and decoded world
(rotations, positions), original and decoded local rotations (None: no angle error)."""

ACL_BYTES_PER_BONE_SAMPLE = 40  # float32 quaternion + translation + scale per bone per sample


@dataclass
class ErrorReport:
    """World-space position error of one decoded clip (or a whole set, see :func:`combine`).

    All lengths in centimetres. ``per_node_*`` are indexed like the skeleton's nodes.
    """

    max_cm: float
    p99_cm: float
    mean_cm: float
    height_cm: float
    per_node_max_cm: np.ndarray
    per_node_mean_cm: np.ndarray
    worst_frame: int
    worst_node: int
    shell_max_cm: float
    shell_mean_cm: float
    angle_mean_deg: float
    angle_max_deg: float
    samples: int
    errors_cm: np.ndarray | None = field(repr=False)
    """(F, N) error of every node on every frame; None where the evaluation summarised them
    as they came (a long clip's, :meth:`ErrorMetric.evaluate_chunks`)."""

    @property
    def max_pct_height(self) -> float | None:
        """None for a skeleton without height (every rest offset zero)."""
        return 100.0 * self.max_cm / self.height_cm if self.height_cm > 0 else None

    @property
    def mean_pct_height(self) -> float | None:
        return 100.0 * self.mean_cm / self.height_cm if self.height_cm > 0 else None

    def fraction_under(self, threshold_cm: float) -> float:
        """Fraction of (frame, node) samples with error <= threshold."""
        if self.errors_cm is None:
            raise ValueError("this report summarised its errors (a long clip's): no per-sample errors kept")
        return float(np.mean(self.errors_cm <= threshold_cm))

    def as_dict(self) -> dict[str, float | None]:
        return {
            "max_cm": self.max_cm,
            "p99_cm": self.p99_cm,
            "mean_cm": self.mean_cm,
            "max_pct_height": self.max_pct_height,
            "mean_pct_height": self.mean_pct_height,
            "shell_max_cm": self.shell_max_cm,
            "shell_mean_cm": self.shell_mean_cm,
            "angle_mean_deg": self.angle_mean_deg,
            "angle_max_deg": self.angle_max_deg,
            "height_cm": self.height_cm,
        }


@dataclass
class ErrorMetric:
    """How errors are measured: units, the shell distance of the virtual-vertex metric.

    Parameters
    ----------
    cm_per_unit : float
        Centimetres per file unit.
    height_units : float
        Skeleton height in file units, for the % of height figures.
    shell_cm : float, default 3.0
        Distance of ACL's virtual vertices from each node (ACL's default is 3 cm).
    """

    cm_per_unit: float
    height_units: float
    shell_cm: float = 3.0

    def evaluate(
        self,
        skeleton: Skeleton,
        original: tuple[np.ndarray, np.ndarray],
        decoded: tuple[np.ndarray, np.ndarray],
        original_local: np.ndarray | None = None,
        decoded_local: np.ndarray | None = None,
    ) -> ErrorReport:
        """Compare world transforms ``(rotations (F,N,4), positions (F,N,3))``.

        ``original_local`` / ``decoded_local`` (F, N, 4) local rotations give the angle error;
        without them it is reported as NaN.
        """
        return self.evaluate_chunks(skeleton, [(original, decoded, original_local, decoded_local)])

    def evaluate_chunks(self, skeleton: Skeleton, chunks: Iterable[Chunk], frames: int | None = None) -> ErrorReport:
        """:meth:`evaluate` given the clip a run of frames at a time, in frame order
        (``(original, decoded, original_local, decoded_local)`` each): the same figures, so
        that a long clip's transforms are never held whole. The shell and angle figures are
        running maxima and sums (their means may differ from a whole-clip mean in the last
        bits). The position errors are kept and joined (``errors_cm``), or, given the clip's
        ``frames``, summarised as they come (:class:`_RunningErrors`: the same bits, without
        the clip's (F, N) errors and their copy for the percentile; a skeleton of two nodes or
        more; the per-node means are the kept errors' bits when the runs are frame-major, as
        the runtime decodes them: kept node-major runs join node-major, and numpy sums each
        node's column pairwise)."""
        errs: list[np.ndarray] = []
        # One node's errors are one contiguous column, which numpy sums pairwise, not frame after
        # frame: kept (F numbers), so that its mean is the same bits too.
        summarise = frames is not None and skeleton.node_count > 1
        running = _RunningErrors(frames * skeleton.node_count) if summarise else None
        shell_max, shell_sum = -np.inf, 0.0
        angle_max, angle_sum = -np.inf, 0.0
        angles = True
        for (rot_o, pos_o), (rot_d, pos_d), original_local, decoded_local in chunks:
            err_part = np.linalg.norm(pos_o - pos_d, axis=-1) * self.cm_per_unit
            if running is None:
                errs.append(err_part)
            else:
                running.add(err_part)
            shell = self._shell_errors(rot_o, pos_o, rot_d, pos_d)
            if shell.size:
                shell_max = float(np.maximum(shell_max, shell.max()))  # NaN stays NaN
                shell_sum += float(shell.sum())
            if original_local is not None and decoded_local is not None and angles:
                ang = np.degrees(quat_angle(original_local, decoded_local))
                if ang.size:
                    angle_max = float(np.maximum(angle_max, ang.max()))
                    angle_sum += float(ang.sum())
            else:
                angles = False
        if running is None:
            # Joined, not written into one array: the join keeps the chunks' memory order, which
            # the per-node means below sum along (a different order changes their last bits).
            err = np.concatenate(errs)
            del errs
            per_node_mean = err.mean(axis=0)
            worst_frame, worst_node = divmod(int(np.argmax(err)), err.shape[1])
            max_cm, p99_cm, per_node_max, size = float(err.max()), float(np.percentile(err, 99)), err.max(axis=0), err.size
        else:
            err = None
            per_node_mean = running.sums / running.rows
            worst_frame, worst_node = running.worst
            max_cm, p99_cm, per_node_max, size = running.max(), running.p99(), running.maxima, running.seen
        return ErrorReport(
            max_cm=max_cm,
            p99_cm=p99_cm,
            mean_cm=float(per_node_mean.mean()),
            height_cm=self.height_units * self.cm_per_unit,
            per_node_max_cm=per_node_max,
            per_node_mean_cm=per_node_mean,
            worst_frame=worst_frame,
            worst_node=worst_node,
            shell_max_cm=shell_max,
            shell_mean_cm=shell_sum / size,
            angle_mean_deg=angle_sum / size if angles else float("nan"),
            angle_max_deg=angle_max if angles else float("nan"),
            samples=int(size),
            errors_cm=err,
        )

    def _shell_errors(self, rot_o, pos_o, rot_d, pos_d) -> np.ndarray:
        """Per (frame, node), the largest displacement of the three virtual vertices."""
        d = self.shell_cm / self.cm_per_unit
        worst = np.zeros(pos_o.shape[:2])
        for axis in range(3):
            a = pos_o + rotate_axis(rot_o, axis, d)
            b = pos_d + rotate_axis(rot_d, axis, d)
            worst = np.maximum(worst, np.linalg.norm(a - b, axis=-1))
        return worst * self.cm_per_unit


def combine(reports: list[ErrorReport]) -> dict[str, float | None]:
    """Set-level figures over several clips: max of maxima, p99 over all samples, mean of
    per-clip means weighted by samples (``max_pct_height`` None when no clip has a height).
    Where a clip's report summarised its errors (a long clip's) and there are several clips,
    the p99 is the largest clip p99, which the set's is close to (not above it but for the
    interpolation between its two nearest samples)."""
    if len(reports) == 1:
        p99 = reports[0].p99_cm
    elif any(r.errors_cm is None for r in reports):
        p99 = max(r.p99_cm for r in reports)
    else:
        p99 = float(np.percentile(np.concatenate([r.errors_cm.ravel() for r in reports]), 99))
    weights = np.array([r.samples for r in reports], dtype=np.float64)
    return {
        "max_cm": float(max(r.max_cm for r in reports)),
        "p99_cm": p99,
        "mean_cm": float(np.average([r.mean_cm for r in reports], weights=weights)),
        "shell_max_cm": float(max(r.shell_max_cm for r in reports)),
        "max_pct_height": max((r.max_pct_height for r in reports if r.max_pct_height is not None),
                              default=None),
    }


class _RunningErrors:
    """A clip's per-sample position errors summarised a run of frames at a time, to the bits
    the whole (F, N) array gives: per-node sums in the order numpy's ``mean(axis=0)`` adds
    (frame after frame), maxima, the first worst sample, and for the 99th percentile only the
    largest samples it can read (about 1 % of them) with numpy's linear rule."""

    def __init__(self, samples: int) -> None:
        self.samples = samples
        self.rows = self.seen = 0
        self.sums: np.ndarray | None = None
        self.maxima: np.ndarray | None = None
        self.worst = (0, 0)
        self._worst_value: float | None = None
        # numpy's linear percentile reads the sorted samples at floor((n-1) q) and the next one.
        self._at = int(np.floor((samples - 1) * 0.99)) if samples else 0
        self._keep = max(samples - self._at, 1)
        self._top: list[np.ndarray] = []  # runs' samples, cut to the largest now and then
        self._held = 0

    def add(self, err: np.ndarray) -> None:
        if not err.size:
            return
        err = np.ascontiguousarray(err)  # summed frame after frame whatever the runs' layout
        # The running sums go first in the reduction, so each frame is added to them in turn.
        self.sums = err.sum(axis=0) if self.sums is None else np.add.reduce(np.concatenate((self.sums[None], err)), axis=0)
        self.maxima = err.max(axis=0) if self.maxima is None else np.maximum(self.maxima, err.max(axis=0))
        flat = int(np.argmax(err))  # the first NaN, else the first largest
        value = float(err.flat[flat])
        best = self._worst_value
        if best is None or (not np.isnan(best) and (np.isnan(value) or value > best)):
            self._worst_value = value
            frame, node = divmod(flat, err.shape[1])
            self.worst = (self.rows + frame, node)
        self._top.append(err.ravel())
        self._held += err.size
        if self._held > 2 * self._keep + 65536:  # joined and partitioned now and then, not every run
            self._trim()
        self.rows += err.shape[0]
        self.seen += err.size

    def _trim(self) -> np.ndarray:
        """The samples held, cut to the largest :attr:`_keep`."""
        top = self._top[0] if len(self._top) == 1 else np.concatenate(self._top or [np.empty(0)])
        if len(top) > self._keep:
            cut = len(top) - self._keep
            top = np.partition(top, cut)[cut:]
        self._top, self._held = [top], len(top)
        return top

    def max(self) -> float:
        """The largest error (NaN if one is NaN, as ``max`` of the whole)."""
        if self._worst_value is not None and np.isnan(self._worst_value):
            return float("nan")
        return float(self.maxima.max())

    def p99(self) -> float:
        """``np.percentile(errors, 99)`` of every sample added (NaN if one is NaN)."""
        if self.seen != self.samples:
            raise ValueError(f"{self.seen} samples evaluated, {self.samples} expected")
        if self._worst_value is not None and np.isnan(self._worst_value):
            return float("nan")
        top = np.sort(self._trim())
        low, high = float(top[0]), float(top[1]) if len(top) > 1 else float(top[0])
        # numpy's _lerp, in float64 as it computes it.
        virtual = (self.samples - 1) * 0.99
        gamma = virtual - np.floor(virtual)
        diff = high - low
        return high - diff * (1 - gamma) if gamma >= 0.5 else low + diff * gamma


@dataclass
class SizeReport:
    """Asset size against the raw sizes of DESIGN.md's two conventions."""

    asset_bytes: int
    raw_bvh_bytes: int
    raw_acl_bytes: int
    seconds: float

    @property
    def ratio_bvh(self) -> float:
        """Raw BVH float32 channels / asset (seed 003's convention)."""
        return self.raw_bvh_bytes / self.asset_bytes

    @property
    def ratio_acl(self) -> float:
        """Raw 40 bytes per node per frame / asset (ACL's convention)."""
        return self.raw_acl_bytes / self.asset_bytes

    @property
    def bytes_per_second(self) -> float:
        return self.asset_bytes / self.seconds

    def as_dict(self) -> dict[str, float | None]:
        return {
            "asset_bytes": self.asset_bytes,
            "raw_bvh_bytes": self.raw_bvh_bytes,
            "raw_acl_bytes": self.raw_acl_bytes,
            "ratio_bvh": self.ratio_bvh,
            "ratio_acl": self.ratio_acl,
            "bytes_per_second": self.bytes_per_second,
            "seconds": self.seconds,
        }


def raw_bvh_bytes(motion: Motion) -> int:
    """Every source channel of every frame as float32: the BVH channels, or for a clip without
    them (glTF) the animated components (4 per rotation, 3 per translation and scale)."""
    if motion.skeleton.channel_count:
        return motion.skeleton.channel_count * motion.frame_count * 4
    per_node = motion.animated() @ np.array([4, 3, 3])
    return int(per_node.sum()) * motion.frame_count * 4


def raw_acl_bytes(motion: Motion) -> int:
    """ACL's convention: 40 bytes per node (joints and end sites; not the virtual end points
    added to glTF leaves) per frame."""
    nodes = motion.skeleton.node_count - int(motion.skeleton.is_virtual.sum())
    return nodes * motion.frame_count * ACL_BYTES_PER_BONE_SAMPLE


def size_report(motions: list[Motion], asset_bytes: int) -> SizeReport:
    """Sizes of an asset holding ``motions``; seconds = frames x frame time (ACL's count)."""
    return SizeReport(
        asset_bytes=asset_bytes,
        raw_bvh_bytes=sum(raw_bvh_bytes(m) for m in motions),
        raw_acl_bytes=sum(raw_acl_bytes(m) for m in motions),
        seconds=sum(m.frame_count * m.frame_time for m in motions),
    )
