"""The codecs. Each turns motions into clip payloads for its section of the asset.

A codec module provides ``encode(motions, cm_per_unit, tolerance, check, options, progress)``
returning a :class:`CodecOutput`. ``check`` (from :mod:`mocodec.encode`) decodes a payload
through the C runtime and returns the world-space error, so every codec measures what an
engine will see.
"""
from __future__ import annotations

import importlib
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

from ..motion import Motion
from ..tolerance import Tolerance

CheckFn = Callable[[int, bytes], np.ndarray]
"""check(clip_index, payload) -> (F, N) world position error in file units."""

ProgressFn = Callable[[str], None]


@dataclass
class CodecOutput:
    payloads: list[bytes]
    section_prefix: bytes = b""
    stats: list[dict[str, Any]] = field(default_factory=list)
    # False when the codec is driven by a setting that bounds no error (rma-pca's variance):
    # the error reached is reported, not checked against the tolerance.
    promise: bool = True
    settings: dict[str, Any] = field(default_factory=dict)  # recorded in the asset's META


def available() -> list[str]:
    return list(_REGISTRY)


def get(name: str) -> Callable[..., CodecOutput]:
    try:
        return _REGISTRY[name]
    except KeyError:
        raise ValueError(f"unknown codec {name!r}; available: {', '.join(available())}") from None


def _per_clip(module: str, settings_class: str, stats: Callable[[Any], dict[str, Any]]):
    """A codec entry point for codecs that encode each clip on its own: build the codec's
    settings object from the options, encode clip by clip, collect payloads and stats."""

    def encode(
        motions: list[Motion],
        cm_per_unit: list[float],
        tolerance: Tolerance,
        check: CheckFn,
        options: dict[str, Any],
        progress: ProgressFn | None = None,
    ) -> CodecOutput:
        codec = importlib.import_module(f"{__name__}.{module}")
        settings = getattr(codec, settings_class)(tolerance=tolerance, **options)
        out = CodecOutput(payloads=[])
        for i, (m, cm) in enumerate(zip(motions, cm_per_unit)):
            r = codec.encode_clip(m, cm, settings, lambda payload, i=i: check(i, payload))
            out.payloads.append(r.payload)
            out.stats.append(stats(r))
            if progress:
                progress(m.name)
        return out

    return encode


def _library(module: str):
    """A codec entry point for codecs that encode the whole library at once (one section
    with shared data): the module's own ``encode``."""

    def encode(*args: Any, **kwargs: Any) -> CodecOutput:
        return importlib.import_module(f"{__name__}.{module}").encode(*args, **kwargs)

    return encode


_REGISTRY: dict[str, Callable[..., CodecOutput]] = {
    "spline": _per_clip("spline", "SplineSettings", lambda r: {
        "keys": r.keys, "tracks": r.tracks, "repairs": r.repairs, "budget_scale": r.scale,
        "encode_seconds": r.seconds}),
    "rma": _library("rma"),
    "rma-pca": _library("rma_pca"),
    "neural": _per_clip("neural", "NeuralSettings", lambda r: {
        "windows": [[w["start"], w["frames"], w["K"], w["bits"]] for w in r.windows],
        "frequencies": r.frequency_counts, "parameters": r.parameters, "splits": r.splits,
        "encode_seconds": r.seconds}),
    "fk-wavelet": _per_clip("fk_wavelet", "FkWaveletSettings", lambda r: {
        "levels": r.levels, "tracks": r.tracks, "repairs": r.repairs, "encode_seconds": r.seconds}),
    "ik-predict": _per_clip("ik_predict", "IkPredictSettings", lambda r: {
        "step_scale": r.scale, "checks": r.checks, "chains": r.chains, "encode_seconds": r.seconds}),
}
