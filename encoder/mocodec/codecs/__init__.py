"""The codecs. Each turns motions into clip payloads for its section of the asset.

A codec module provides ``encode(motions, cm_per_unit, tolerance, check, options, progress)``
returning a :class:`CodecOutput`. ``check`` (from :mod:`mocodec.encode`) decodes a payload
through the C runtime and returns the world-space error, so every codec measures what an
engine will see.
"""
from __future__ import annotations

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


def available() -> list[str]:
    return list(_REGISTRY)


def get(name: str) -> Callable[..., CodecOutput]:
    try:
        return _REGISTRY[name]
    except KeyError:
        raise ValueError(f"unknown codec {name!r}; available: {', '.join(available())}") from None


def _encode_spline(
    motions: list[Motion],
    cm_per_unit: list[float],
    tolerance: Tolerance,
    check: CheckFn,
    options: dict[str, Any],
    progress: ProgressFn | None = None,
) -> CodecOutput:
    from .spline import SplineSettings, encode_clip

    settings = SplineSettings(tolerance=tolerance, **options)
    out = CodecOutput(payloads=[])
    for i, (m, cm) in enumerate(zip(motions, cm_per_unit)):
        r = encode_clip(m, cm, settings, lambda payload, i=i: check(i, payload))
        out.payloads.append(r.payload)
        out.stats.append({"keys": r.keys, "tracks": r.tracks, "repairs": r.repairs,
                          "budget_scale": r.scale, "encode_seconds": r.seconds})
        if progress:
            progress(m.name)
    return out


def _encode_neural(
    motions: list[Motion],
    cm_per_unit: list[float],
    tolerance: Tolerance,
    check: CheckFn,
    options: dict[str, Any],
    progress: ProgressFn | None = None,
) -> CodecOutput:
    from .neural import NeuralSettings, encode_clip

    settings = NeuralSettings(tolerance=tolerance, **options)
    out = CodecOutput(payloads=[])
    for i, (m, cm) in enumerate(zip(motions, cm_per_unit)):
        r = encode_clip(m, cm, settings, lambda payload, i=i: check(i, payload))
        out.payloads.append(r.payload)
        out.stats.append({"frequencies": r.freqs, "weight_bits": r.bits, "parameters": r.parameters,
                          "stages": r.stages, "encode_seconds": r.seconds})
        if progress:
            progress(m.name)
    return out


_REGISTRY: dict[str, Callable[..., CodecOutput]] = {
    "spline": _encode_spline,
    "neural": _encode_neural,
}
