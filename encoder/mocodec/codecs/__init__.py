"""The codecs, in one registry: the only Python table of codec names, ids, section kinds and
section versions (the C runtime keeps its own, ``runtime_c/src/codecs.c``; a test holds the two
together). :mod:`mocodec.container` and the command line read it.

A codec is a :class:`Codec`: its module provides a settings type (a dataclass whose first field
is the :class:`~mocodec.tolerance.Tolerance`; every other setting has a default) and either

* ``encode_clip(motion, cm_per_unit, settings, check) -> ClipResult`` for a codec that codes
  each clip on its own (``check(payload)``: the clip's world error through the runtime), or
* ``encode(motions, cm_per_unit, settings, check, progress) -> CodecOutput`` for a codec whose
  section holds data the clips share (``check(i, payload, prefix)``: clip ``i`` in a one-clip
  section that starts with ``prefix``); one whose clips are still fitted one by one (``rma``)
  also takes ``runner`` and passes it to :func:`encode_each_clip`.

:func:`encode_each_clip` hands the clips to a :class:`~mocodec.bake.Runner` (this process, local
worker processes, a Dask cluster, a cache) and collects the payloads in clip order.

A codec that cannot meet the tolerance raises :class:`~mocodec.tolerance.ToleranceNotMet`.
Only codecs whose row says ``scale`` store scale tracks; :meth:`Codec.encode` refuses a clip
that animates scale for the others (:class:`UnsupportedMotion`, naming the codec, the clip and
the node), and hands them clips whose scales are the rest scales where the source's scale
only differs from its rest by float noise (at most :data:`SCALE_NOISE`; the error is still
measured against the source). Adding a codec is one row in :data:`CODECS` (and one in the
runtime's table).

>>> get("rma").section_kind, get("neural").section_version
(b'RMAL', 2)
"""
from __future__ import annotations

import dataclasses
import importlib
import inspect
from dataclasses import dataclass, field
from types import ModuleType
from typing import TYPE_CHECKING, Any, Callable

import numpy as np

from ..motion import Motion, frame_runs
from ..tolerance import OverRows, Tolerance, ToleranceNotMet  # noqa: F401  (the codecs' one error type)

if TYPE_CHECKING:
    from ..bake import Runner

CheckFn = Callable[..., np.ndarray]
"""``check(clip_index, payload, prefix=b"") -> (F, N)`` world position error in file units,
decoded by the C runtime (:func:`mocodec.encode.make_check`)."""

ProgressFn = Callable[[str], None]

DEFAULT_CODEC = "rma"
"""The codec of ``mocodec encode``, :func:`mocodec.encode.encode_motions` and
:func:`mocodec.encode` alike: the smallest that meets the tolerance, and the one that stores
animated scale."""

RESEARCH_PACKAGES = ("sklearn", "pywt")
"""Imports of the research extra (``mocodec[research]``), needed by rma-pca and bench/ only."""

SCALE_NOISE = 1e-4
"""Relative difference from the rest scale below which a scale is not animated."""


class UnsupportedMotion(ValueError):
    """A clip holds something the chosen codec cannot store (animated scale)."""


def scale_deviation(motion: Motion) -> tuple[float, int]:
    """(largest relative difference of any scale from its node's rest scale, that node)."""
    rest = motion.skeleton.rest_scales[None]
    per_node = np.zeros(motion.skeleton.node_count)
    for rows in frame_runs(motion.frame_count):  # a run of frames at a time: no whole-clip temporaries
        dev = np.abs(motion.scales[rows] - rest) / np.maximum(np.abs(rest), 1e-12)
        np.maximum(per_node, dev.max(axis=(0, 2)), out=per_node)
    node = int(np.argmax(per_node))
    return float(per_node[node]), node


def without_scale(motion: Motion) -> Motion:
    """``motion`` with every scale at its rest value (for codecs without scale tracks)."""
    rest = np.broadcast_to(motion.skeleton.rest_scales, motion.scales.shape)  # read-only, no frames held
    return dataclasses.replace(motion, scales=rest)


@dataclass
class ClipResult:
    """One clip encoded.

    Attributes
    ----------
    payload : bytes
        The clip's bytes in its codec's section.
    errors_units : ndarray (F, N) or OverRows
        World position error through the runtime, file units (the key-frame codecs, which
        check half-way between frames too: an :class:`~mocodec.tolerance.OverRows` of the
        rows over the tolerance, none when met).
    stats : dict
        What the encoder did, reported per clip (numbers and lists, JSON-ready).
    seconds : float
        Encoding time.
    """

    payload: bytes
    errors_units: "np.ndarray | OverRows"
    stats: dict[str, Any] = field(default_factory=dict)
    seconds: float = 0.0


@dataclass
class CodecOutput:
    payloads: list[bytes]
    section_prefix: bytes = b""
    stats: list[dict[str, Any]] = field(default_factory=list)
    # False when the codec is driven by a setting that bounds no error (rma-pca's variance):
    # the error reached is reported, not checked against the tolerance.
    promise: bool = True
    settings: dict[str, Any] = field(default_factory=dict)  # recorded in the asset's META


@dataclass(frozen=True)
class Codec:
    """One codec.

    Parameters
    ----------
    name : str
        The name users give (``mocodec encode --codec NAME``).
    id : int
        Its id in the clip directory (``mcd_codec`` in ``mocodec.h``).
    section_kind : bytes
        The FourCC of the section that holds its payloads.
    section_version : int
        The layout version of that section (docs/FORMAT.md).
    module : str
        The module under :mod:`mocodec.codecs` that implements it (imported when used).
    settings_name : str
        Its settings type, a class of that module.
    per_clip : bool
        True: the module's ``encode_clip`` codes one clip at a time; False: its ``encode``
        codes the library.
    summary : str
        One line for ``--help``.
    scale : bool
        Whether its payload stores scale tracks (animated scale).
    spacing_share : float or None
        The largest binary32 spacing of a position, as a share of the tolerance, at which it
        still meets the tolerance (the runtime's arithmetic is binary32: a clip far from the
        origin is refused up front, :func:`mocodec.limits.position_precision_problem`); None
        when it makes no tolerance promise (rma-pca's variance bounds no error). Measured on
        CMU 02_01 and 09_11 moved from the origin, docs/FORMAT.md "Positions far from the origin".
    """

    name: str
    id: int
    section_kind: bytes
    section_version: int
    module: str
    settings_name: str
    per_clip: bool
    summary: str
    scale: bool = False
    spacing_share: float | None = 0.25

    @property
    def implementation(self) -> ModuleType:
        try:
            return importlib.import_module(f"{__name__}.{self.module}")
        except ModuleNotFoundError as exc:
            if exc.name in RESEARCH_PACKAGES:
                raise ImportError(f"codec {self.name!r} needs {exc.name}, an optional dependency: "
                                  "pip install 'mocodec[research]'") from None
            raise

    @property
    def settings_type(self) -> type:
        return getattr(self.implementation, self.settings_name)

    def settings(self, tolerance: Tolerance, **options: Any) -> Any:
        """The codec's settings object for ``tolerance`` and ``options`` (setting name ->
        value); an option the codec does not have is named in a :class:`TypeError`, a value
        out of range in a :class:`ValueError`."""
        kind = self.settings_type
        names = [f.name for f in dataclasses.fields(kind) if f.name != "tolerance"]
        unknown = sorted(set(options) - set(names))
        if unknown:
            raise TypeError(f"codec {self.name!r} has no setting {', '.join(map(repr, unknown))}; "
                            f"its settings: {', '.join(names)}")
        return kind(tolerance=tolerance, **options)

    def encode(self, motions: list[Motion], cm_per_unit: list[float], tolerance: Tolerance,
               check: CheckFn, options: dict[str, Any] | None = None,
               progress: ProgressFn | None = None, runner: "Runner | None" = None) -> CodecOutput:
        """Encode ``motions`` (one clip each) into this codec's payloads; a codec without
        scale tracks raises :class:`UnsupportedMotion` for a clip that animates scale.
        ``runner`` (:mod:`mocodec.bake`) runs the per-clip work (None: in this process); a
        library codec whose ``encode`` takes no runner (its clips share a fit) ignores it."""
        settings = self.settings(tolerance, **(options or {}))
        if not self.scale:
            from ..bake.library import Library  # a streamed library: the change made as clips are read

            motions = (motions.map(self._scale_free) if isinstance(motions, Library)
                       else [self._scale_free(m) for m in motions])
        if not self.per_clip:
            encode = self.implementation.encode
            extra = {"runner": runner} if "runner" in inspect.signature(encode).parameters else {}
            return encode(motions, cm_per_unit, settings, check, progress, **extra)
        return encode_each_clip(self.implementation.encode_clip, motions, cm_per_unit, settings,
                                check, progress, runner=runner)


    def _scale_free(self, motion: Motion) -> Motion:
        dev, node = scale_deviation(motion)
        if dev <= SCALE_NOISE:
            return without_scale(motion) if dev > 0 else motion
        frame = int(np.argmax(np.abs(motion.scales[:, node] - motion.skeleton.rest_scales[node]).max(axis=1)))
        raise UnsupportedMotion(
            f"codec {self.name!r} cannot store animated scale: clip {motion.name!r}, node "
            f"{motion.skeleton.names[node]!r} scales to {np.round(motion.scales[frame, node], 4).tolist()} "
            f"on frame {frame} (rest {np.round(motion.skeleton.rest_scales[node], 4).tolist()}); "
            f"codec 'rma' stores scale tracks")


def encode_each_clip(encode_clip: Callable[..., ClipResult], motions: list[Motion],
                     cm_per_unit: list[float], settings: Any, check: CheckFn,
                     progress: ProgressFn | None = None, prefix: bytes = b"",
                     runner: "Runner | None" = None) -> CodecOutput:
    """Run ``encode_clip`` on every clip (checked in a one-clip section starting with
    ``prefix``) through ``runner`` (None: one after the other in this process) and collect
    payloads and stats in clip order."""
    from ..bake import ClipJob, SerialRunner
    from ..bake.library import clip_ref

    # A streamed library's clips are named, not carried: each job reads its own clip.
    refs = [clip_ref(motions, i) for i in range(len(cm_per_unit))]
    jobs = [ClipJob(ref.name, encode_clip, ref, cm, settings, _clip_check(check, i, prefix), prefix)
            for i, (ref, cm) in enumerate(zip(refs, cm_per_unit))]
    out = CodecOutput(payloads=[])
    for o in (runner or SerialRunner()).run(jobs, progress):
        out.payloads.append(o.payload)
        out.stats.append({**o.stats, "encode_seconds": o.seconds, **({"cached": True} if o.cached else {})})
    return out


def _clip_check(check: CheckFn, i: int, prefix: bytes) -> Callable[[bytes], np.ndarray]:
    """Clip ``i``'s check alone; one that pickles (for worker processes) when ``check`` can
    make one (:meth:`mocodec.encode.RuntimeCheck.one_clip`)."""
    one_clip = getattr(check, "one_clip", None)
    return one_clip(i, prefix) if one_clip else (lambda payload, **how: check(i, payload, prefix, **how))


CODECS: tuple[Codec, ...] = (
    Codec("spline", 1, b"SPLN", 1, "spline", "SplineSettings", True,
          "per-joint Catmull-Rom keys on a block grid; samples in place, no resident memory"),
    Codec("rma", 2, b"RMAL", 4, "rma", "RMASettings", False,
          "seed 003: keys placed freely in time, lattice quantization, sampled in place, one section",
          scale=True),
    Codec("rma-pca", 6, b"RMAP", 2, "rma_pca", "RmaPcaSettings", False,
          "seed 003's PCA of virtual markers per behaviour group (--pca-variance; no error bound)",
          spacing_share=None),
    Codec("neural", 5, b"NEUR", 2, "neural", "NeuralSettings", True,
          "seed 001: a small network from time to pose per window of frames"),
    Codec("fk-wavelet", 4, b"FKWV", 2, "fk_wavelet", "FkWaveletSettings", True,
          "seed 000 FKBC: 9/7 wavelet per channel with forward-kinematics compensation",
          spacing_share=1 / 16),  # its binary32 synthesis rounds more often: failed at 0.098
    Codec("ik-predict", 3, b"IKPR", 1, "ik_predict", "IkPredictSettings", True,
          "seed 000 IKBP: closed-loop inverse-kinematics prediction of joint angles"),
)
"""Every codec (NEUR 2: windowed networks; NEUR 1 was never released)."""

_BY_NAME = {c.name: c for c in CODECS}
_BY_ID = {c.id: c for c in CODECS}


def available() -> list[str]:
    """The codec names, in the registry's order."""
    return [c.name for c in CODECS]


def get(name: str) -> Codec:
    """The codec called ``name``; a ValueError listing the codecs for any other name."""
    try:
        return _BY_NAME[name]
    except KeyError:
        raise ValueError(f"unknown codec {name!r}; available: {', '.join(available())}") from None


def by_id(codec_id: int) -> Codec | None:
    """The codec with clip-directory id ``codec_id``, or None."""
    return _BY_ID.get(codec_id)
