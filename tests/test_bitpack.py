"""Bit packing (mocodec.bitpack): the compiled pack_fields and BitWriter against a Python big
integer built field by field, and read_bits, fields of every width 0 ... 32 across word
boundaries."""
from __future__ import annotations

import numpy as np
import pytest

from mocodec.bitpack import BitWriter, fields_bytes, pack_fields, read_bits


@pytest.mark.parametrize("seed", range(5))
def test_pack_fields_is_bitwriters_packing(seed):
    rng = np.random.default_rng(seed)
    widths = rng.integers(0, 33, size=2000)
    widths[rng.integers(0, 2000, size=200)] = 0
    values = rng.integers(0, 2**32, size=2000, dtype=np.uint64) & ((np.uint64(1) << widths.astype(np.uint64)) - np.uint64(1))
    acc, bit = 0, 0
    for v, n in zip(values.tolist(), widths.tolist()):
        acc |= int(v) << bit
        bit += int(n)
    want = acc.to_bytes((bit + 7) // 8, "little")
    w = BitWriter()
    w.write(values[:1000], widths[:1000])
    w.write(values[1000:], widths[1000:])
    assert w.bit_length == bit and w.getvalue(3) == want + bytes(3)
    words, total = pack_fields(values, widths)
    assert total == int(widths.sum())
    got = words.astype("<u8").tobytes()[: (total + 7) // 8]
    assert got == want
    data = fields_bytes(values, widths)
    assert len(data) % 4 == 0 and data[: len(want)] == want
    bit = 0
    for v, n in zip(values[:300], widths[:300]):
        assert read_bits(data, bit, int(n)) == int(v)
        bit += int(n)


def test_pack_fields_edges():
    words, total = pack_fields(np.zeros(0, dtype=np.uint64), np.zeros(0, dtype=np.int64))
    assert total == 0 and len(words) == 0
    words, total = pack_fields(np.array([5, 0, 7]), np.array([0, 0, 0]))
    assert total == 0 and len(words) == 0
    words, total = pack_fields(np.array([2**32 - 1, 1]), np.array([32, 32]))
    assert total == 64 and words.tolist() == [(1 << 32) | (2**32 - 1)]
    with pytest.raises(ValueError, match="0 ... 32"):
        pack_fields(np.array([1]), np.array([33]))
    with pytest.raises(ValueError, match="0 ... 32"):
        pack_fields(np.array([1]), np.array([-1]))
