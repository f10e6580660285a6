"""The entropy coder (docs/FORMAT.md, "Entropy coder") through the binding the encoder uses:
round trips, hostile streams, compression against the data's order-0 entropy, and a second,
pure-Python implementation written from the spec that must produce the same bytes."""
from __future__ import annotations

import numpy as np
import pytest

from mocodec.entropy import MAX_ABS, MAX_CHANNELS, entropy_decode, entropy_encode
from mocodec.runtime import Result, RuntimeResultError

# Also pinned in runtime_c/tests/test_entropy.c: the bitstream may not change.
GOLDEN_VALUES = [0, 1, -1, 2, -3, 7, -100, 1000, 123456, -1073741823, 1073741823, 0, 5, 0, 0, -2]
GOLDEN_CHANNELS = 3
GOLDEN_STREAM = bytes.fromhex(
    "4da7ba37fbc8dc71e2cb7e2830317fffffffffff6f103ffffffffdacaf2f81c800"
)


# ---------------------------------------------------------------- reference implementation
# Written from docs/FORMAT.md alone, deliberately plain: if the C code and the page disagree,
# the byte comparison below fails.
class _Contexts:
    PER_CHANNEL = 118

    def __init__(self, channels: int) -> None:
        self.p = [2048] * (self.PER_CHANNEL * channels)
        self.n = [0] * (self.PER_CHANNEL * channels)

    def update(self, i: int, bit: int) -> None:
        s = (self.n[i] + 1).bit_length()
        self.p[i] = self.p[i] - (self.p[i] >> s) if bit else self.p[i] + ((4096 - self.p[i]) >> s)
        self.n[i] = min(self.n[i] + 1, 15)


def _binarize(v: int, base: int) -> list[tuple[int | None, int]]:
    """(context index or None for raw, bit) decisions of one value."""
    if v == 0:
        return [(base, 0)]
    m = abs(v)
    e = m.bit_length() - 1
    out = [(base, 1), (base + 1, int(v < 0))]
    out += [(base + 2 + j, 1) for j in range(e)]
    if e < 29:
        out.append((base + 2 + e, 0))
    if e >= 1:
        b1 = (m >> (e - 1)) & 1
        out.append((base + 31 + 3 * (e - 1), b1))
        if e >= 2:
            out.append((base + 31 + 3 * (e - 1) + 1 + b1, (m >> (e - 2)) & 1))
            out += [(None, (m >> k) & 1) for k in range(e - 3, -1, -1)]
    return out


def reference_encode(values: list[int], channels: int) -> bytes:
    if not values:
        return b""
    ctx = _Contexts(channels)
    out = bytearray()
    low, rng, cache, pending = 0, 0xFFFFFFFF, 0, 0

    def shift_low() -> None:
        nonlocal low, cache, pending
        if pending == 0 or low % 2**32 < 0xFF000000 or low >= 2**32:
            carry = low >> 32
            if pending > 0:
                out.append((cache + carry) % 256)
                out.extend([(0xFF + carry) % 256] * (pending - 1))
            cache, pending = (low >> 24) % 256, 1
        else:
            pending += 1
        low = (low % 2**24) << 8

    for i, v in enumerate(values):
        for c, bit in _binarize(v, (i % channels) * _Contexts.PER_CHANNEL):
            if c is None:
                rng >>= 1
                if bit:
                    low += rng
                if rng < 2**24:
                    rng = (rng << 8) % 2**32
                    shift_low()
                continue
            bound = (rng >> 12) * ctx.p[c]
            if bit:
                low, rng = low + bound, rng - bound
            else:
                rng = bound
            ctx.update(c, bit)
            while rng < 2**24:
                rng = (rng << 8) % 2**32
                shift_low()
    for _ in range(5):
        shift_low()
    return bytes(out)


# ---------------------------------------------------------------- helpers
def laplace(rng: np.random.Generator, scale: float, n: int) -> np.ndarray:
    return np.clip(np.round(rng.laplace(0.0, scale, n)), -MAX_ABS, MAX_ABS).astype(np.int32)


def order0_bytes(values: np.ndarray) -> float:
    """Empirical order-0 entropy of the values, in bytes for all of them."""
    _, counts = np.unique(values, return_counts=True)
    return float(-(counts * np.log2(counts / counts.sum())).sum() / 8.0)


def round_trip(values: np.ndarray, channels: int = 1) -> bytes:
    data = entropy_encode(values, channels)
    back = entropy_decode(data, len(values), channels)
    assert back.dtype == np.int32
    np.testing.assert_array_equal(back, values)
    assert entropy_encode(values, channels) == data  # deterministic
    return data


def malformed(data: bytes, count: int, channels: int) -> bool:
    with pytest.raises(RuntimeResultError) as err:
        entropy_decode(data, count, channels)
    return err.value.code == Result.MALFORMED


# ---------------------------------------------------------------- tests
def test_golden_stream() -> None:
    assert entropy_encode(np.array(GOLDEN_VALUES), GOLDEN_CHANNELS) == GOLDEN_STREAM
    assert entropy_decode(GOLDEN_STREAM, len(GOLDEN_VALUES), GOLDEN_CHANNELS).tolist() == GOLDEN_VALUES
    assert reference_encode(GOLDEN_VALUES, GOLDEN_CHANNELS) == GOLDEN_STREAM


@pytest.mark.parametrize("channels", [1, 2, 5, 16])
def test_spec_reimplementation_matches(channels: int) -> None:
    rng = np.random.default_rng(channels)
    exps = rng.integers(0, 30, 400)
    wide = (rng.integers(0, 2**30, 400) >> (29 - exps)) * rng.choice([-1, 1], 400)
    values = np.concatenate([laplace(rng, 3.0, 600), wide, np.zeros(50, np.int32), [MAX_ABS, -MAX_ABS]])
    assert entropy_encode(values, channels) == reference_encode(values.tolist(), channels)


def test_empty_and_zeros() -> None:
    assert round_trip(np.zeros(0, np.int32)) == b""
    assert entropy_decode(b"", 0).shape == (0,)
    assert len(round_trip(np.zeros(100_000, np.int32))) < 200  # ~0.011 bit per zero at the floor
    for n in range(1, 40):
        round_trip(np.zeros(n, np.int32), 1 + n % MAX_CHANNELS)


@pytest.mark.parametrize("scale", [0.3, 2.0, 20.0, 300.0, 5000.0, 1e7])
@pytest.mark.parametrize("channels", [1, 3, 16])
def test_laplacian_round_trips(scale: float, channels: int) -> None:
    round_trip(laplace(np.random.default_rng(int(scale * 10)), scale, 20_000), channels)


def test_extremes_and_dtypes() -> None:
    ends = np.array([MAX_ABS, -MAX_ABS, 0, MAX_ABS, 1, -MAX_ABS] * 500, dtype=np.int64)
    round_trip(ends)
    round_trip(ends, 2)
    # Any integer dtype and shape: the values are flattened in C order.
    grid = np.arange(-60, 60, dtype=np.int16).reshape(8, 15)
    assert entropy_decode(entropy_encode(grid, 3), grid.size, 3).tolist() == grid.ravel().tolist()
    assert entropy_encode(np.arange(10, dtype=np.uint8)) == entropy_encode(np.arange(10, dtype=np.int32))


@pytest.mark.parametrize(
    "values",
    [[MAX_ABS + 1], [-MAX_ABS - 1], [0, 5, 2**31 - 1], [-(2**31)], [2**40]],
)
def test_value_out_of_range_rejected(values: list[int]) -> None:
    with pytest.raises(RuntimeResultError) as err:
        entropy_encode(np.array(values, dtype=np.int64))
    assert err.value.code == Result.INVALID_ARGUMENT


def test_bad_arguments_rejected() -> None:
    data = entropy_encode(np.array([1, 2, 3]))
    for channels in (0, MAX_CHANNELS + 1, -1):
        for call in (lambda: entropy_encode(np.array([1, 2, 3]), channels), lambda: entropy_decode(data, 3, channels)):
            with pytest.raises(RuntimeResultError) as err:
                call()
            assert err.value.code == Result.INVALID_ARGUMENT
    with pytest.raises(RuntimeResultError):
        entropy_decode(data, -1)
    with pytest.raises(TypeError):
        entropy_encode(np.array([1.0, 2.0]))


@pytest.mark.parametrize("scale", [0.5, 40.0, 1e5])
def test_every_truncation_and_a_trailing_byte_rejected(scale: float) -> None:
    values = laplace(np.random.default_rng(7), scale, 300)
    data = round_trip(values, 2)
    for length in range(len(data)):
        assert malformed(data[:length], len(values), 2), f"prefix of {length} of {len(data)} bytes"
    for extra in (0, 1, 0x80, 0xFF):
        assert malformed(data + bytes([extra]), len(values), 2)
    assert malformed(b"", 1, 1)
    assert malformed(b"\x00", 0, 1)


@pytest.mark.parametrize("scale", [0.5, 30.0, 3e4])
def test_bit_flips_rejected_or_change_values(scale: float) -> None:
    values = laplace(np.random.default_rng(11), scale, 200)
    data = bytearray(round_trip(values, 3))
    rejected = 0
    for bit in range(len(data) * 8):
        data[bit // 8] ^= 1 << (bit % 8)
        try:
            back = entropy_decode(bytes(data), len(values), 3)
        except RuntimeResultError as err:
            assert err.code == Result.MALFORMED
            rejected += 1
        else:
            assert not np.array_equal(back, values), f"bit {bit} flipped, same values accepted"
            assert np.abs(back.astype(np.int64)).max() <= MAX_ABS
        data[bit // 8] ^= 1 << (bit % 8)
    assert rejected > 0.9 * len(data) * 8


@pytest.mark.parametrize("scale", [1.0, 8.0, 60.0])
def test_size_near_order0_entropy(scale: float) -> None:
    values = laplace(np.random.default_rng(2024), scale, 100_000)
    size, h = len(round_trip(values)), order0_bytes(values)
    assert 0.98 * h <= size <= 1.05 * h, (size, h)


def test_channels_separate_statistics() -> None:
    rng = np.random.default_rng(5)
    values = np.empty(100_000, np.int32)
    values[0::2] = laplace(rng, 1.0, 50_000)
    values[1::2] = laplace(rng, 200.0, 50_000)
    mixed = order0_bytes(values)
    apart = order0_bytes(values[0::2]) + order0_bytes(values[1::2])
    two = len(round_trip(values, 2))
    assert two <= 0.92 * mixed and two <= 1.05 * apart, (two, mixed, apart)
    assert len(round_trip(values, 1)) >= 0.95 * mixed  # one channel cannot tell them apart
