"""Lossless back-end for the codecs: the runtime's adaptive binary range coder.

Codecs that quantize their data to small signed integers (RMA, IK-prediction residuals) write
them with :func:`entropy_encode`; the runtime decodes the stream once at ``mcd_open``. Both
calls run the same C code (``runtime_c/src/entropy.c`` through the cffi binding), so what the
encoder measures is what an engine decodes. The bitstream is specified in docs/FORMAT.md,
"Entropy coder"; the stream stores neither the value count nor the channel count, so the
codec's payload must.

>>> import numpy as np
>>> residuals = np.array([0, 3, -1, 0, 0, 2, -7, 1], dtype=np.int32)
>>> data = entropy_encode(residuals, channels=2)
>>> entropy_decode(data, count=len(residuals), channels=2).tolist()
[0, 3, -1, 0, 0, 2, -7, 1]
"""
from __future__ import annotations

import numpy as np

from .runtime import _rt

__all__ = ["MAX_ABS", "MAX_CHANNELS", "entropy_decode", "entropy_encode"]

MAX_ABS: int = int(_rt.ENTROPY_MAX_ABS)
"""Largest magnitude a value may have: 2**30 - 1."""

MAX_CHANNELS: int = int(_rt.ENTROPY_MAX_CHANNELS)
"""Most context sets a stream may use: 16."""


def entropy_encode(values: np.ndarray, channels: int = 1) -> bytes:
    """Entropy-code signed integers.

    Parameters
    ----------
    values : np.ndarray
        Integers with ``|v| <= MAX_ABS``, any integer dtype; flattened in C order.
    channels : int
        Context sets, 1 ... ``MAX_CHANNELS``. Value ``i`` is coded with the statistics of
        channel ``i % channels``: interleave components with different distributions
        (``x y z x y z ...`` with ``channels=3``) so each adapts on its own.

    Returns
    -------
    bytes
        The stream; empty for no values.

    Raises
    ------
    mocodec.runtime.RuntimeResultError
        ``INVALID_ARGUMENT`` for a value out of range or a bad channel count.
    TypeError
        For values that are not integers.
    """
    return _rt.entropy_encode(values, channels)


def entropy_decode(data: bytes, count: int, channels: int = 1) -> np.ndarray:
    """Decode exactly ``count`` values written by :func:`entropy_encode`.

    Parameters
    ----------
    data : bytes
        The whole stream: it must end exactly where the ``count``-th value does.
    count : int
        Number of values, as given to the encoder.
    channels : int
        The channel count the stream was written with.

    Returns
    -------
    np.ndarray
        ``int32`` array of ``count`` values.

    Raises
    ------
    mocodec.runtime.RuntimeResultError
        ``MALFORMED`` when the stream is truncated, has bytes left over or is corrupt;
        ``INVALID_ARGUMENT`` for a bad channel count.
    """
    return _rt.entropy_decode(data, count, channels)
