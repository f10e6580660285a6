"""Bit packing, least significant bit first (docs/FORMAT.md: bit i is bit i % 8 of byte i // 8)."""
from __future__ import annotations

import numpy as np


class BitWriter:
    """Collects (value, width) fields, then packs them all at once (:func:`pack_fields`)."""

    def __init__(self) -> None:
        self._values: list[np.ndarray] = []
        self._widths: list[np.ndarray] = []
        self.bit_length = 0

    def write(self, values: np.ndarray | int, widths: np.ndarray | int) -> None:
        """Append fields; ``values`` and ``widths`` broadcast together (widths 0 ... 32)."""
        v, w = np.broadcast_arrays(np.atleast_1d(np.asarray(values, dtype=np.uint64)),
                                   np.atleast_1d(np.asarray(widths, dtype=np.int64)))
        if v.size == 0:
            return
        if np.any(w < 0) or np.any(w > 32):
            raise ValueError("field widths must be 0 ... 32")
        if np.any(v >> w.astype(np.uint64) != 0):
            raise ValueError("a value does not fit its field width")
        self._values.append(v.ravel().copy())
        self._widths.append(w.ravel().copy())
        self.bit_length += int(w.sum())

    def getvalue(self, tail_bytes: int = 0) -> bytes:
        """The packed bytes, then ``tail_bytes`` zero bytes."""
        nbytes = (self.bit_length + 7) // 8 + tail_bytes
        if not self._values:
            return bytes(nbytes)
        words, total = pack_fields(np.concatenate(self._values), np.concatenate(self._widths))
        data = words.astype("<u8").tobytes()[: (total + 7) // 8]
        return data + bytes(nbytes - len(data))


def read_bits(data: bytes, bit: int, width: int) -> int:
    """The ``width``-bit field at bit position ``bit`` (least significant bit first)."""
    if width == 0:
        return 0
    first = bit >> 3
    last = (bit + width + 7) >> 3
    word = int.from_bytes(data[first:last], "little")
    return (word >> (bit & 7)) & ((1 << width) - 1)


def pack_fields(values: np.ndarray, widths: np.ndarray) -> tuple[np.ndarray, int]:
    """Pack fields (each 0 ... 32 bits, ``values`` already within their widths) back to back,
    least significant bit first, into little-endian 64-bit words; returns (words, bit length).

    Compiled (``mcf_pack_fields``): the writers pack every track of every repair round, and a
    loop over the fields is what packing is."""
    from . import native  # the compiled helpers; bitpack itself stays importable without them

    v, w = np.broadcast_arrays(np.asarray(values, dtype=np.uint64), np.asarray(widths, dtype=np.int64))
    v, w = np.ascontiguousarray(v.ravel()), np.ascontiguousarray(w.ravel())
    words, total = native.pack_fields(v, w)
    return words[: (total + 63) // 64], total


def fields_bytes(values: np.ndarray, widths: np.ndarray, align: int = 4) -> bytes:
    """:func:`pack_fields` as bytes, zero-padded to a multiple of ``align``."""
    words, total = pack_fields(values, widths)
    data = words.astype("<u8").tobytes()[: (total + 7) // 8]
    return data + bytes((-len(data)) % align)


def fields_length(total_bits: int, align: int = 4) -> int:
    """The length of :func:`fields_bytes` for fields of ``total_bits`` bits in all, without packing them."""
    used = (int(total_bits) + 7) // 8
    return used + (-used) % align
