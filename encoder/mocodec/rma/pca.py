"""Per-group frame PCA (seed 003 §4.1 end, §5.4 bits).

A group's marker frames (F, D) are reduced to ``k`` coefficients per frame. ``k`` comes from a
variance fraction (the paper's 95 % / 98 %) or from a max-error target: the fewest components
whose reconstruction, taken back to joint positions by the caller's error function, stays
within the target on every frame. The basis is stored as the asset would store it: the mean
with 16 bits and the axes with 12 bits per element (per-axis range), and coefficients are the
least-squares projection on the *quantized* axes, so what is measured is what a decoder gets.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..quantize import Quantizer


@dataclass
class Basis:
    """Mean (D,), axes (D, k) as the decoder sees them, and all eigenvalues (largest first)."""

    mean: np.ndarray
    axes: np.ndarray
    eigenvalues: np.ndarray
    mean_bits: int
    axis_bits: int

    @property
    def components(self) -> int:
        return int(self.axes.shape[1])

    def header_bits(self) -> int:
        """Mean + axes + per-column float32 minimum and step (what §5.4 stores per group)."""
        d, k = self.axes.shape
        return d * self.mean_bits + 2 * 32 + k * (d * self.axis_bits + 2 * 32)

    def project(self, x: np.ndarray) -> np.ndarray:
        """Coefficients (F, k): least squares on the quantized axes (no longer exactly
        orthonormal, so a plain dot product would add error)."""
        a = self.axes
        gram = a.T @ a
        return np.linalg.solve(gram, a.T @ (np.asarray(x) - self.mean).T).T

    def reconstruct(self, coefficients: np.ndarray) -> np.ndarray:
        return self.mean + np.asarray(coefficients) @ self.axes.T


@dataclass
class Decomposition:
    mean: np.ndarray         # (D,) float64
    eigenvalues: np.ndarray  # (D,) largest first
    vectors: np.ndarray      # (D, D) columns, same order

    def components_for_variance(self, fraction: float) -> int:
        lam = np.maximum(self.eigenvalues, 0.0)
        cum = np.cumsum(lam) / max(lam.sum(), 1e-300)
        return int(min(np.searchsorted(cum, fraction - 1e-12) + 1, len(lam)))

    def basis(self, k: int, mean_bits: int = 16, axis_bits: int = 12) -> Basis:
        return Basis(_quantize_fixed(self.mean[:, None], mean_bits)[:, 0],
                     _quantize_fixed(self.vectors[:, :k], axis_bits),
                     self.eigenvalues, mean_bits, axis_bits)


def decompose(x: np.ndarray) -> Decomposition:
    """PCA of rows ``x`` (F, D) through the D x D covariance: O(F D^2) time, O(D^2) memory
    beyond the data, whatever F is."""
    x = np.asarray(x, dtype=np.float64)
    mean = x.mean(axis=0)
    xc = x - mean
    lam, vec = np.linalg.eigh(xc.T @ xc / max(len(x), 1))
    order = np.argsort(lam)[::-1]
    vec = vec[:, order]
    # Fix each axis' sign (largest element positive) so results do not depend on LAPACK's.
    flip = np.sign(vec[np.argmax(np.abs(vec), axis=0), np.arange(vec.shape[1])])
    return Decomposition(mean, lam[order], vec * np.where(flip == 0, 1.0, flip))


def _quantize_fixed(m: np.ndarray, bits: int) -> np.ndarray:
    """Uniform ``bits``-bit quantization of each column of ``m`` over its own range."""
    lo, hi = m.min(axis=0), m.max(axis=0)
    step = np.maximum(hi - lo, 1e-30) / ((1 << bits) - 1)
    q = Quantizer.for_range(lo, hi, step * (1.0 + 1e-6))
    return q.roundtrip(m)


ErrorFn = Callable[[np.ndarray], float]
"""Maps reconstructed marker rows (F, D) to the max joint-position error (cm)."""


def components_for_max_error(x: np.ndarray, dec: Decomposition, error: ErrorFn, target_cm: float,
                             k_max: int | None = None, mean_bits: int = 16,
                             axis_bits: int = 12) -> tuple[int, float]:
    """Fewest components whose quantized-basis reconstruction of ``x`` has max error <=
    ``target_cm`` (bisection: the error falls with k, up to quantization noise, and the
    returned k is checked). Returns (k, error at k); k = k_max with its error if even that
    misses."""
    d = x.shape[1]
    k_max = min(k_max or d, d)

    def err(k: int) -> float:
        b = dec.basis(k, mean_bits, axis_bits)
        return float(error(b.reconstruct(b.project(x))))

    hi_err = err(k_max)
    if hi_err > target_cm:
        return k_max, hi_err
    lo, hi = 0, k_max  # err(lo) > target (k = 0 is treated as failing), err(hi) <= target
    cache = {k_max: hi_err}
    while hi - lo > 1:
        mid = (lo + hi) // 2
        cache[mid] = err(mid)
        if cache[mid] <= target_cm:
            hi = mid
        else:
            lo = mid
    return hi, cache[hi]
