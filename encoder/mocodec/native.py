"""The encoder's compiled fitting helpers (the cffi module ``mocodec._native``, built from
``encoder/native/`` when the encoder is installed), wrapped for numpy arrays.

They are the hot loops of the key-frame engine: key placement for one curve
(:func:`mocodec.curves.fit_keys`, whose numpy version is the reference they are tested
against), the per-frame Wahba fits of the compensation (:mod:`mocodec.keyframes`), and the
bit packing of the payload writers (:func:`mocodec.bitpack.pack_fields`).
Compiled rather than vectorised because both are loops whose next step depends on the last
(keys placed, then only the changed segments measured again; Jacobi sweeps), which numpy can
only do by redoing whole arrays.
"""
from __future__ import annotations

import numpy as np

try:
    from ._native import ffi, lib
except ImportError as exc:  # pragma: no cover - a broken install, reported plainly
    raise ImportError(
        "mocodec's compiled fitting helpers (mocodec._native) are not built: install the "
        "encoder with its build step (pip install -e ./encoder, or make venv)"
    ) from exc

KIND_MRP, KIND_TWIST, KIND_TRANSLATION, KIND_SCALE = (lib.MCF_KIND_MRP, lib.MCF_KIND_TWIST,
                                                     lib.MCF_KIND_TRANSLATION, lib.MCF_KIND_SCALE)


def _f64(a: np.ndarray) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=np.float64)


def _ptr(a: np.ndarray | None, kind: str = "double *"):
    return ffi.NULL if a is None else ffi.cast(kind, a.ctypes.data)


class _Curve:
    """An ``mcf_curve`` and the arrays it points into (kept alive with it)."""

    def __init__(self, kind: int, deq: np.ndarray, target: np.ndarray, ref: np.ndarray, axis: np.ndarray,
                 budget: np.ndarray | None, grid: int, split: bool,
                 half_target: np.ndarray | None, half_budget: np.ndarray | None) -> None:
        self.arrays = [_f64(deq), _f64(target), _f64(ref), _f64(axis),
                       None if budget is None else _f64(budget),
                       None if half_target is None else _f64(half_target),
                       None if half_budget is None else _f64(half_budget)]
        deq, target, ref, axis, budget, half_target, half_budget = self.arrays
        frames, dims = deq.shape
        if len(target) != frames or (budget is not None and len(budget) != frames):
            raise ValueError("curve arrays disagree on the frame count")
        if half_target is not None and (len(half_target) != frames - 1 or half_budget is None
                                        or len(half_budget) != frames - 1):
            raise ValueError("half-way targets and budgets need frames - 1 rows")
        self.c = ffi.new("mcf_curve *")
        self.c.kind, self.c.dims, self.c.frames = int(kind), int(dims), int(frames)
        self.c.deq, self.c.target, self.c.ref, self.c.axis = _ptr(deq), _ptr(target), _ptr(ref), _ptr(axis)
        self.c.budget, self.c.half_target, self.c.half_budget = _ptr(budget), _ptr(half_target), _ptr(half_budget)
        self.c.grid, self.c.split = int(grid), int(bool(split))


def fit_keys(kind: int, deq: np.ndarray, target: np.ndarray, ref: np.ndarray, axis: np.ndarray,
             budget: np.ndarray, start: np.ndarray, mandatory: np.ndarray, grid: int, split: bool,
             half_target: np.ndarray | None = None, half_budget: np.ndarray | None = None) -> tuple[np.ndarray, int]:
    """Key frames for one curve (``mcf_fit_keys``): ``start`` the sorted keys to begin from
    (the mandatory ones among them), ``mandatory`` (F,) bool the keys that stay. Returns the
    keys and the status: 1 within budget everywhere, 2 within budget on every frame but not at
    some half-way samples no key can be added next to, 0 over budget at keys."""
    curve = _Curve(kind, deq, target, ref, axis, budget, grid, split, half_target, half_budget)
    frames = curve.c.frames
    keys = np.empty(frames, dtype=np.int64)
    start = np.asarray(start, dtype=np.int64)
    keys[:len(start)] = start
    n = ffi.new("int64_t *", len(start))
    mand = np.ascontiguousarray(mandatory, dtype=np.uint8)
    status = lib.mcf_fit_keys(curve.c, _ptr(keys, "int64_t *"), n, _ptr(mand, "uint8_t *"))
    if status < 0:
        raise MemoryError("mcf_fit_keys: bad arguments or out of memory")
    return keys[:n[0]].copy(), int(status)


def evaluate(kind: int, deq: np.ndarray, target: np.ndarray, ref: np.ndarray, axis: np.ndarray,
             keys: np.ndarray, split: bool, half_target: np.ndarray | None = None
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """The curve through ``keys`` on every frame (F, d), its error per frame (F,), and per
    half-way sample (F - 1,) when ``half_target`` is given (``mcf_evaluate``)."""
    frames = len(deq)
    curve = _Curve(kind, deq, target, ref, axis, None, 1, split, half_target,
                   None if half_target is None else np.zeros(frames - 1))
    keys = np.ascontiguousarray(keys, dtype=np.int64)
    values = np.empty((frames, curve.c.dims))
    error = np.empty(frames)
    half = np.empty(max(frames - 1, 0)) if half_target is not None else None
    if lib.mcf_evaluate(curve.c, _ptr(keys, "int64_t *"), len(keys), _ptr(values), _ptr(error), _ptr(half)) != 0:
        raise ValueError("mcf_evaluate: bad arguments")
    return values, error, half


def wahba(v: np.ndarray, u: np.ndarray, w: np.ndarray, hint: np.ndarray) -> np.ndarray:
    """Per frame the rotation (F, 4) minimising ``sum_k w_k |Q v_k - u_k|^2`` for point pairs
    ``v``, ``u`` (F, K, 3) and weights ``w`` (K,), on the hemisphere of ``hint`` (F, 4)."""
    v, u, w, hint = _f64(v), _f64(u), _f64(w), _f64(hint)
    frames, count = v.shape[:2]
    out = np.empty((frames, 4))
    if lib.mcf_wahba(frames, count, _ptr(v), _ptr(u), _ptr(w), _ptr(hint), _ptr(out)) != 0:
        raise ValueError("mcf_wahba: bad arguments")
    return out


def pack_fields(values: np.ndarray, widths: np.ndarray) -> tuple[np.ndarray, int]:
    """Fields ``values`` (uint64) of ``widths`` (int64, 0 ... 32) bits packed least significant
    bit first into 64-bit words (``mcf_pack_fields``): (words, bit length)."""
    values = np.ascontiguousarray(values, dtype=np.uint64)
    widths = np.ascontiguousarray(widths, dtype=np.int64)
    words = np.zeros(int(widths.sum()) // 64 + 2 if len(widths) else 2, dtype=np.uint64)
    total = lib.mcf_pack_fields(_ptr(values, "uint64_t *"), _ptr(widths, "int64_t *"), len(values),
                                _ptr(words, "uint64_t *"))
    if total < 0:
        raise ValueError("field widths must be 0 ... 32")
    return words, int(total)
