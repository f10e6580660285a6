"""Range-aware uniform quantization (seed 003 §5.2, eq. 7-8), per curve component.

Each component gets its own minimum and step; the number of bits follows from the range and
the step, so small-range components (minor axes, quiet joints) cost few bits. Minimum and
step are rounded to float32 first, because that is what the asset stores and the runtime uses.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

MAX_BITS = 24
MAX_STEP = 1e7  # the format's bound on every stored number (docs/FORMAT.md)


def f32_exact(a: np.ndarray) -> np.ndarray:
    """``a`` rounded to float32, as float64 (what the asset stores and the runtime holds)."""
    return np.asarray(a, dtype=np.float32).astype(np.float64)


ROUNDTRIP_CHUNK = 8192
"""Rows a quantizer's roundtrip takes at a time."""


def by_rows(f: Callable[[np.ndarray], np.ndarray], v: np.ndarray) -> np.ndarray:
    """``f(v)`` (float64, v's shape) for a row-by-row ``f``, a run of rows at a time when
    ``v`` is long: a clip's values roundtrip with temporaries of a run's size, not a clip's
    (each row's numbers are its own)."""
    v = np.asarray(v)
    if len(v) <= ROUNDTRIP_CHUNK:
        return f(v)
    out = np.empty(v.shape)
    for start in range(0, len(v), ROUNDTRIP_CHUNK):
        out[start:start + ROUNDTRIP_CHUNK] = f(v[start:start + ROUNDTRIP_CHUNK])
    return out


@dataclass
class Quantizer:
    """``v = minimum + q * step`` per component, ``0 <= q < 2**bits``."""

    minimum: np.ndarray  # (d,) float32-exact
    step: np.ndarray     # (d,) float32-exact, 0 where the component is constant
    bits: np.ndarray     # (d,) int

    @classmethod
    def for_range(cls, lo: np.ndarray, hi: np.ndarray, step: np.ndarray) -> "Quantizer":
        """Quantizer covering ``[lo, hi]`` with at most ``step`` per level (bits = eq. 8 with
        the maximum error = step / 2). Raises ValueError when more than 24 bits are needed."""
        lo = np.asarray(lo, dtype=np.float64)
        hi = np.asarray(hi, dtype=np.float64)
        step = np.asarray(step, dtype=np.float64)
        minimum = lo.astype(np.float32).astype(np.float64)
        span = hi - minimum
        levels = np.where(span > 0, np.ceil(span / step - 1e-9), 0).astype(np.int64)
        bits = np.where(levels > 0, np.ceil(np.log2(levels + 1)), 0).astype(np.int64)
        if np.any(bits > MAX_BITS):
            raise ValueError(
                f"range {span.max():.6g} needs {int(bits.max())} bits at step {step.min():.3g} "
                f"(the format allows {MAX_BITS})"
            )
        st = np.where(levels > 0, span / np.maximum(levels, 1), 0.0)
        st32 = st.astype(np.float32).astype(np.float64)
        # float32 rounding may shrink the step: make sure the top level still reaches hi.
        short = (levels > 0) & (minimum + levels * st32 < hi)
        st32 = np.where(short, np.nextafter(st32.astype(np.float32), np.float32(np.inf)).astype(np.float64), st32)
        return cls(minimum, st32, bits)

    def encode(self, v: np.ndarray) -> np.ndarray:
        """Integers ``q`` (K, d) for values ``v`` (K, d)."""
        safe = np.where(self.step > 0, self.step, 1.0)
        q = np.rint((np.asarray(v, dtype=np.float64) - self.minimum) / safe)
        q = np.where(self.step > 0, q, 0)
        return np.clip(q, 0, (1 << self.bits) - 1).astype(np.int64)

    def decode(self, q: np.ndarray) -> np.ndarray:
        """Values the runtime reconstructs (binary32 arithmetic, as the C code does)."""
        return (self.minimum.astype(np.float32) + np.asarray(q).astype(np.float32) * self.step.astype(np.float32)).astype(np.float64)

    def roundtrip(self, v: np.ndarray) -> np.ndarray:
        return by_rows(lambda rows: self.decode(self.encode(rows)), v)


@dataclass
class StepQuantizer:
    """``v = q * step`` per component, ``|q| < 2**30`` (codec ``rma``: values are stored as
    residuals or whole at the track's own width, so no minimum or bit count is kept, only the
    step). The runtime computes ``(float)((double)q * step)``: exact for long clips whose
    root travels far, where ``q`` passes 2**24."""

    step: np.ndarray  # (d,) float32-exact, > 0

    MAX_Q = (1 << 30) - 1

    @classmethod
    def for_range(cls, lo: np.ndarray, hi: np.ndarray, step: np.ndarray) -> "StepQuantizer":
        """Quantizer with the given step (rounded to float32) for values within ``[lo, hi]``.
        Raises ValueError when a value would need ``|q| > 2**30``. A step above the format's
        bound on stored numbers (1e7) is lowered to it: with every value within +-1e7, a
        smaller step only lowers the error (a huge tolerance asks for nothing finer)."""
        st = np.minimum(np.asarray(step, dtype=np.float64), MAX_STEP).astype(np.float32).astype(np.float64)
        reach = np.maximum(np.abs(np.asarray(lo, dtype=np.float64)), np.abs(np.asarray(hi, dtype=np.float64)))
        if np.any(st <= 0) or np.any(reach / st >= cls.MAX_Q) or np.any(reach >= 1e7):
            raise ValueError(f"range {reach.max():.6g} needs more than 2**30 steps of {st.min():.3g}")
        return cls(st)

    def encode(self, v: np.ndarray) -> np.ndarray:
        """Integers ``q`` (K, d) for values ``v`` (K, d)."""
        return np.rint(np.asarray(v, dtype=np.float64) / self.step).astype(np.int64)

    def decode(self, q: np.ndarray) -> np.ndarray:
        """Values the runtime reconstructs (the binary64 product rounded to binary32)."""
        return (np.asarray(q, dtype=np.float64) * self.step).astype(np.float32).astype(np.float64)

    def roundtrip(self, v: np.ndarray) -> np.ndarray:
        return by_rows(lambda rows: self.decode(self.encode(rows)), v)
