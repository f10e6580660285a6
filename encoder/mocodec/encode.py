"""Encoding motions into an asset and measuring it through the C runtime.

:func:`encode_motions` is the library entry point behind ``mocodec encode`` and ``mocodec eval``:
it runs a codec, packs the asset, decodes every clip of the finished asset through the runtime,
and reports sizes and errors. A tolerance that is not met is an error, never a silent miss.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any, Callable, Iterator, Sequence

import numpy as np

from . import __version__, codecs, limits
from .container import AssetBuilder, ClipEntry
from .kinematics import (halfway_chunks, halfway_positions, motion_world, shared_world_positions,
                         short_clip, world_position_chunks)
from .metrics import Chunk, ErrorMetric, ErrorReport, SizeReport, raw_acl_bytes, raw_bvh_bytes
from .motion import Motion
from .codecs import DEFAULT_CODEC
from .tolerance import DEFAULT_TOLERANCE_CM, OverRows, Tolerance, ToleranceNotMet
from typing import TYPE_CHECKING
if TYPE_CHECKING:
    from .bake import Runner
    from .runtime import Asset
    from .units import UnitsChoice


class EncodeError(RuntimeError):
    """Encoding failed (for example, the tolerance cannot be met)."""


@dataclass
class ClipReport:
    name: str
    frames: int
    error: ErrorReport
    units: "UnitsChoice"
    stats: dict[str, Any] = field(default_factory=dict)


@dataclass
class EncodeResult:
    asset: bytes
    codec: str
    tolerance: Tolerance
    clips: list[ClipReport]
    size: SizeReport
    encode_seconds: float
    # False when the codec's setting bounds no error (rma-pca's variance fraction): the
    # errors are what it reached, and the tolerance was not applied.
    promise: bool = True
    settings: dict[str, Any] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    """How resampled (glTF) clips were measured (:func:`mocodec.load.sampling_notes`)."""

    @property
    def max_error_cm(self) -> float:
        return max(c.error.max_cm for c in self.clips)


def _single_clip_asset(motion: Motion, cm_per_unit: float, codec: str, payload: bytes,
                       prefix: bytes = b"") -> bytes:
    b = AssetBuilder()
    b.add_skeleton(motion.skeleton, cm_per_unit)
    if prefix:
        b.codec_prefix[codec] = prefix
    b.add_clip(ClipEntry(motion.name, 0, codec, payload, motion.frame_count, motion.frame_rate))
    return b.build()


class RuntimeCheck:
    """``check(i, payload, prefix=b"", halfway=False)``: clip ``i``'s world error (F, N) in file
    units (half-way between frames (F - 1, N) with ``halfway``), decoded by the C runtime from a
    one-clip asset. It pickles without its cached world positions, and :meth:`one_clip` is the
    check of one clip alone, small enough to send to a worker process. ``out``: an (F, N) or
    (F - 1, N) array the errors are written into (a long clip's check allocates none);
    ``over``: a tolerance per node (N,), and the errors come as an
    :class:`~mocodec.tolerance.OverRows` of the rows not within it."""

    fills_out = True
    over_rows = True  # ``over=tolerance``: an OverRows of the rows not within it, not (F, N)

    def __init__(self, motions: list[Motion], cm_per_unit: list[float], codec: str) -> None:
        from . import runtime  # noqa: F401  (the binding: fail here, not in the first check)

        from .bake.library import Library  # a streamed library stays one: clips read as checked

        self.motions = motions if isinstance(motions, Library) else list(motions)
        self.cm_per_unit, self.codec = list(cm_per_unit), codec
        self._originals: dict[int, np.ndarray] = {}
        self._halfway: dict[int, np.ndarray] = {}  # a short clip's half-way reference, once asked

    def __call__(self, i: int, payload: bytes, prefix: bytes = b"", halfway: bool = False,
                 out: np.ndarray | None = None, over: np.ndarray | None = None) -> "np.ndarray | OverRows":
        from .runtime import CHUNK_FRAMES, Asset, world_error_chunk_runs, world_error_runs

        asset = Asset(_single_clip_asset(self.motions[i], self.cm_per_unit[i], self.codec, payload, prefix))
        m = self.motions[i]
        shape = (m.frame_count - 1 if halfway else m.frame_count, m.skeleton.node_count)
        if halfway:  # the runtime at x + 1/2 against the original's own half-way pose, a long
            # clip's built a run at a time on every call (never held whole, F x N x 3 float64)
            if short_clip(m):
                if i not in self._halfway:
                    self._halfway[i] = halfway_positions(m)
                runs = world_error_runs(asset, 0, self._halfway[i], 0.5)
            else:
                runs = world_error_chunk_runs(asset, 0, halfway_chunks(m, CHUNK_FRAMES), 0.5)
        elif short_clip(m):
            if i not in self._originals:
                self._originals[i] = shared_world_positions(m)  # the fitter's own, if it holds it
            runs = world_error_runs(asset, 0, self._originals[i])
        else:  # a long clip's originals posed a run at a time on every call, as half-way
            runs = world_error_chunk_runs(asset, 0, world_position_chunks(m, CHUNK_FRAMES))
        if over is not None:  # only the rows over ``over`` kept: the same numbers there
            return OverRows.gather(runs, shape, over)
        out = np.empty(shape) if out is None else out
        for rows, errors in runs:
            out[rows] = errors
        return out

    def one_clip(self, i: int, prefix: bytes = b"") -> "OneClipCheck":
        """``check(payload)`` of clip ``i`` alone (of a streamed library: its ref, not its frames)."""
        from .bake.library import Library

        one = self.motions.subset([i]) if isinstance(self.motions, Library) else [self.motions[i]]
        return OneClipCheck(RuntimeCheck(one, [self.cm_per_unit[i]], self.codec), prefix)

    def __getstate__(self) -> dict[str, Any]:
        return {**self.__dict__, "_originals": {}, "_halfway": {}}


@dataclass
class OneClipCheck:
    """``check(payload, halfway=False, out=None)``: the error of one clip alone (:meth:`RuntimeCheck.one_clip`)."""

    fills_out = True
    over_rows = True
    runtime: RuntimeCheck
    prefix: bytes = b""

    def __call__(self, payload: bytes, **how: Any) -> np.ndarray:
        return self.runtime(0, payload, prefix=self.prefix, **how)

    def carrying(self, motion: Motion) -> "OneClipCheck":
        """This check with the clip's frames in it (for a worker that cannot read its file)."""
        return OneClipCheck(RuntimeCheck([motion], self.runtime.cm_per_unit, self.runtime.codec), self.prefix)


def make_check(motions: list[Motion], cm_per_unit: list[float], codec: str) -> codecs.CheckFn:
    """A check function for codecs: payload of clip i -> world error (F, N) in file units,
    decoded by the C runtime from a one-clip asset (:class:`RuntimeCheck`); with ``halfway=True``
    the error half-way between frames (F - 1, N) instead, sampled by the runtime at x + 1/2
    against the original's own half-way pose (:func:`mocodec.kinematics.halfway_positions`, a
    run at a time)."""
    return RuntimeCheck(motions, cm_per_unit, codec)


def evaluate(asset: "bytes | Asset", motions: list[Motion], units: "list[UnitsChoice]",
             clip_names: list[str] | None = None, contacts: bool = False) -> list[ErrorReport]:
    """Decode each clip of ``asset`` through the runtime and compare with ``motions``
    (``contacts``: with the contact trajectories applied, as an engine samples them)."""
    from .runtime import Asset, sample_chunks

    a = asset if isinstance(asset, Asset) else Asset(asset)
    names = clip_names or [m.name for m in motions]
    reports = []
    for m, u, name in zip(motions, units, names):
        frames = np.arange(m.frame_count)

        def chunks(m: Motion = m, name: str = name, frames: np.ndarray = frames) -> Iterator[Chunk]:
            # A run of frames at a time (forward kinematics is frame by frame: the same numbers).
            world = sample_chunks(a, name, frames, world=True, contacts=contacts)
            local = sample_chunks(a, name, frames, world=False, contacts=contacts)
            for (rows, rot_d, pos_d), (_, local_d, _) in zip(world, local):
                part = m.slice(rows.start, rows.stop)
                yield motion_world(part), (rot_d, pos_d), part.rotations, local_d
        metric = ErrorMetric(cm_per_unit=u.cm_per_unit, height_units=u.height_units)
        # A long clip's errors are summarised as they come (the same figures), not kept whole.
        reports.append(metric.evaluate_chunks(m.skeleton, chunks(), None if short_clip(m) else m.frame_count))
    return reports


def encode_motions(
    motions: Sequence[Motion],
    units: "list[UnitsChoice]",
    codec: str = DEFAULT_CODEC,
    tolerance: Tolerance | None = None,
    options: dict[str, Any] | None = None,
    progress: Callable[[str], None] | None = None,
    contacts: bool = False,
    runner: "Runner | None" = None,
) -> EncodeResult:
    """Encode ``motions`` (one clip each: a list, or a streamed library that reads its clips
when needed, :func:`mocodec.bake.library.open_library`, same bytes) into one asset and measure
it through the runtime.

    ``contacts`` adds foot contact trajectories (a ``CNTC`` section, :mod:`mocodec.contacts`)
    and measures every error with them applied by the runtime's IK. ``runner`` encodes the
    clips (local processes, a Dask cluster, a cache: :func:`mocodec.bake.make_runner`; None:
    one after the other in this process); the asset is the same bytes either way.

    Raises :class:`EncodeError` when the tolerance is not met on every frame of every clip (at
    once when a clip is so far from the origin, or the tolerance so fine, that the runtime's
    binary32 positions cannot hold it: :func:`~mocodec.limits.position_precision_problem`),
    :class:`~mocodec.limits.LimitError` when a motion is outside the format's limits.
    """
    if not motions:
        raise EncodeError("nothing to encode")
    if len(motions) > limits.MAX_CLIPS:
        raise EncodeError(f"{len(motions):,} clips; an asset holds at most {limits.MAX_CLIPS:,}")
    tolerance = tolerance or Tolerance(DEFAULT_TOLERANCE_CM)
    entry = codecs.get(codec)
    from .load import sampling_notes
    # One pass over the clips before the codec and one after (evaluate): what the asset and the
    # report need of each clip is kept here, so a streamed library is not read again for it.
    builder = AssetBuilder()
    facts = []
    for m, u in zip(motions, units):
        m.validate()
        limits.check_motion(m)  # what a reader did not check yet: an asset the runtime reads
        problem = entry.spacing_share is not None and limits.position_precision_problem(
            m, u.cm_per_unit, float(tolerance.per_node_cm(m.skeleton).min()), entry.spacing_share)
        if problem:
            raise EncodeError(f"cannot meet the tolerance: clip '{limits.printable(m.name)}': {problem}")
        facts.append(_ClipFacts.of(m, builder.add_skeleton(m.skeleton, u.cm_per_unit), tolerance))
    cm = [u.cm_per_unit for u in units]
    started = time.perf_counter()
    check = make_check(motions, cm, codec)
    try:
        out = entry.encode(motions, cm, tolerance, check, options, progress, runner)
    except ToleranceNotMet as exc:
        raise EncodeError(f"cannot meet the tolerance: {exc}") from None
    if out.section_prefix:
        builder.codec_prefix[codec] = out.section_prefix
    skin_joints: dict[str, str] = {}
    for f, payload in zip(facts, out.payloads):
        builder.add_clip(ClipEntry(f.name, f.skeleton, codec, payload, f.frames, f.frame_rate))
        if f.joints is not None:
            skin_joints[str(f.skeleton)] = index_ranges(f.joints)
    # First pass measures the asset; the second writes the measured errors into META.
    asset = builder.build()
    contact_stats: list[dict[str, Any]] = [{} for _ in facts]
    if contacts:
        asset, contact_stats = add_contacts(builder, asset, motions, units, tolerance)
    reports = evaluate(asset, motions, units, contacts=contacts)
    elapsed = time.perf_counter() - started
    for f, r in zip(facts, reports):
        over = ~(r.per_node_max_cm <= f.tolerance_cm + 1e-9)  # a NaN error is over too
        if over.any() and out.promise:
            where = (f"{int(np.sum(~(r.errors_cm <= f.tolerance_cm[None, :] + 1e-9)))} samples" if r.errors_cm is not None
                     else f"{int(over.sum())} nodes")
            raise EncodeError(
                f"clip {f.name!r}: error {r.max_cm:.4f} cm exceeds the tolerance on "
                f"{where} (this is a bug in codec {codec!r})"
            )
    builder.meta = {
        "encoder": f"mocodec {__version__}",
        "codec": codec,
        "settings": {"tolerance_cm": tolerance.tolerance_cm,
                     "effector_tolerance_cm": tolerance.effector_tolerance_cm,
                     "contacts": contacts, **out.settings}
        if out.promise else {"tolerance_cm": None, "contacts": contacts, **out.settings},
        "clips": {
            f.name: {
                "max_error_cm": round(r.max_cm, 6),
                "p99_error_cm": round(r.p99_cm, 6),
                "mean_error_cm": round(r.mean_cm, 6),
                "height_cm": round(r.height_cm, 3),
                "cm_per_unit": u.cm_per_unit,
                "units": u.label,
                "raw_bvh_bytes": f.raw_bvh_bytes,
                **f.source_meta,
            }
            for f, r, u in zip(facts, reports, units)
        },
        # glTF export: which nodes of each skeleton were skin joints (the others moved them).
        **({"skin_joints": skin_joints} if skin_joints else {}),
    }
    asset = builder.build()
    stats = out.stats or [{} for _ in facts]
    for s, payload, cs in zip(stats, out.payloads, contact_stats):
        s["payload_bytes"] = len(payload)
        s.update(cs)
    clips = [ClipReport(f.name, f.frames, r, u, s) for f, r, u, s in zip(facts, reports, units, stats)]
    size = SizeReport(asset_bytes=len(asset), raw_bvh_bytes=sum(f.raw_bvh_bytes for f in facts),
                      raw_acl_bytes=sum(f.raw_acl_bytes for f in facts), seconds=sum(f.seconds for f in facts))
    return EncodeResult(asset, codec, tolerance, clips, size, elapsed, out.promise, dict(out.settings),
                        sampling_notes(facts))  # type: ignore[arg-type]


@dataclass
class _ClipFacts:
    """What an encode keeps of a clip besides its payload (a few numbers, not its frames)."""

    name: str
    skeleton: int
    frames: int
    frame_rate: float
    seconds: float
    raw_bvh_bytes: int
    raw_acl_bytes: int
    tolerance_cm: np.ndarray
    source: dict[str, Any]
    source_meta: dict[str, Any]
    joints: list[int] | None

    @classmethod
    def of(cls, m: Motion, skeleton: int, tolerance: Tolerance) -> "_ClipFacts":
        src = m.source or {}
        return cls(m.name, skeleton, m.frame_count, m.frame_rate, m.frame_count * m.frame_time,
                   raw_bvh_bytes(m), raw_acl_bytes(m), tolerance.per_node_cm(m.skeleton),
                   {k: v for k, v in src.items() if k != "joints"}, _source_meta(m), src.get("joints"))


def _source_meta(m: Motion) -> dict[str, Any]:
    """What META keeps of a clip's source: its format and, for glTF, the time of frame 0."""
    src = m.source or {}
    out: dict[str, Any] = {"source": src["format"]} if "format" in src else {}
    if src.get("start_s"):
        out["start_s"] = float(src["start_s"])
    return out


def index_ranges(indices: list[int]) -> str:
    """``[0, 1, 2, 5]`` -> ``"0-2,5"``."""
    values = sorted(indices)
    starts = [k for k, v in enumerate(values) if k == 0 or v != values[k - 1] + 1]
    runs = [values[a:b] for a, b in zip(starts, starts[1:] + [len(values)])]
    return ",".join(f"{r[0]}-{r[-1]}" if len(r) > 1 else str(r[0]) for r in runs)


def parse_index_ranges(text: str) -> list[int]:
    """The inverse of :func:`index_ranges`."""
    out: list[int] = []
    for part in filter(None, text.split(",")):
        lo, _, hi = part.partition("-")
        out.extend(range(int(lo), int(hi or lo) + 1))
    return out


def add_contacts(builder: AssetBuilder, asset: bytes, motions: list[Motion], units: "list[UnitsChoice]",
                 tolerance: Tolerance) -> tuple[bytes, list[dict[str, Any]]]:
    """Detect contacts on the originals, store them against the decoded pose of ``asset``
    (built by ``builder`` without contacts) and return the asset with its ``CNTC`` section.

    The IK moves knees and hips: a segment whose IK pushes any node of any frame it touches
    past the tolerance is shrunk (a smaller share of the correction is stored) and, if that
    is not enough, left out; the check is repeated until no node is over."""
    from . import contacts as C
    from .runtime import Asset, decode_world

    a = Asset(asset)
    clips: dict[int, C.ClipContacts] = {}
    stats: list[dict[str, Any]] = [{} for _ in motions]
    originals = []
    for i, (m, u) in enumerate(zip(motions, units)):
        _, orig = motion_world(m)
        originals.append(orig)
        _, dec = decode_world(a, m.name)
        masks = C.detect_contacts(m.skeleton, orig, m.frame_rate, u.cm_per_unit)
        cc = C.build_clip_contacts(m.skeleton, masks, orig, dec, m.frame_rate, u.cm_per_unit)
        stats[i] = {"contact_frames": int(sum(int(v.sum()) for v in masks.values())),
                    "contact_segments": cc.segment_count if cc else 0, "contact_segments_dropped": 0}
        if cc is not None:
            clips[i] = cc
    # Each round lowers the stored share of the correction by SHRINK on the frames (and the
    # frames around them, so targets stay smooth) where some node is over the tolerance.
    shrink, spread, rounds = 0.1, 1, 40
    for _ in range(rounds + 1):
        builder.contacts = C.contacts_section(clips) if clips else None
        asset = builder.build()
        if not clips:
            break
        a = Asset(asset)
        changed = False
        for i in list(clips):
            m, u, cc = motions[i], units[i], clips[i]
            _, pos = a.sample_frames(m.name, world=True, contacts=True)
            err = np.linalg.norm(pos - originals[i], axis=-1) * u.cm_per_unit
            over_nodes = err > tolerance.per_node_cm(m.skeleton)[None, :]
            if not over_nodes.any():
                continue
            # A frame is influenced by segments up to the blend length (+1 for interpolation) away.
            reach = int(np.ceil(cc.blend_frames)) + 1 + spread
            for e in cc.effectors:
                # Only the nodes this effector's IK can move: the subtree of its chain's root.
                root = e.node
                for _ in range(e.chain):
                    root = int(m.skeleton.parents[root])
                moved = [root] + m.skeleton.descendants(root)
                over = over_nodes[:, moved].any(axis=1)
                if not over.any():
                    continue
                grown = np.convolve(over, np.ones(2 * reach + 1), mode="same") > 0
                keep = []
                for s in e.segments:
                    hit = grown[s.start:s.end + 1]
                    if hit.any():
                        changed = True
                        sc = s.current_scale().copy()
                        if sc[hit].max() <= -1.0:
                            stats[i]["contact_segments_dropped"] += 1
                            continue
                        sc[hit] = np.maximum(sc[hit] - shrink, -1.0)
                        s.rescale(sc)
                    keep.append(s)
                e.segments = keep
            if not cc.prune().effectors:
                del clips[i]
        if not changed:
            break
    else:
        # Out of rounds: a clip still over the tolerance keeps no contacts at all.
        a = Asset(asset)
        for i in list(clips):
            m, u = motions[i], units[i]
            _, pos = a.sample_frames(m.name, world=True, contacts=True)
            err = np.linalg.norm(pos - originals[i], axis=-1) * u.cm_per_unit
            if (err > tolerance.per_node_cm(m.skeleton)[None, :]).any():
                stats[i]["contact_segments_dropped"] += clips.pop(i).segment_count
        builder.contacts = C.contacts_section(clips) if clips else None
        asset = builder.build()
    for i, cc in clips.items():
        stats[i]["contact_segments"] = cc.segment_count
        stats[i]["contact_bytes"] = len(C.clip_block(cc)) + 8
    return asset, stats
