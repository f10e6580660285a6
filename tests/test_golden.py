"""Golden assets of the format this runtime reads (tests/golden/v2) stay readable and sample to
the poses recorded beside them (tests/golden/make_golden.py); the C tests and every binding
replay the same files. Format-1 assets (tests/golden/v1, mocodec 0.1) are refused as too old."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from mocodec.runtime import TRANSFORM_FLOATS, Asset, Result, RuntimeResultError, validate

GOLDEN = Path(__file__).resolve().parent / "golden"
CURRENT = GOLDEN / "v2"
FORMAT_1 = GOLDEN / "v1"


def _read_poses(path: Path):
    samples = []
    lines = path.read_text().splitlines()
    i = 0
    while i < len(lines):
        _, clip, t, flags = lines[i].split()
        i += 1
        rows = []
        while i < len(lines) and not lines[i].startswith("sample"):
            rows.append([float(v) for v in lines[i].split()])
            i += 1
        samples.append((int(clip), float(t), int(flags), np.array(rows)))
    return samples


def test_there_are_golden_assets():
    assert len(sorted(CURRENT.glob("*.mcd"))) >= 6
    assert len(sorted(FORMAT_1.glob("*.mcd"))) >= 2


@pytest.mark.parametrize("path", sorted(CURRENT.glob("*.mcd")), ids=lambda p: p.name)
def test_golden_asset_samples_to_recorded_poses(path):
    data = path.read_bytes()
    assert validate(data) == Result.OK
    asset = Asset(data)
    samples = _read_poses(path.with_suffix(".poses.txt"))
    assert samples
    for clip, t, flags, expect in samples:
        got = asset.sample(clip, np.float32(t), flags).astype(np.float64)
        assert got.shape == expect.shape == (asset.clips[clip].node_count, TRANSFORM_FLOATS)
        assert np.abs(got - expect).max() <= 1e-5 + 1e-6 * np.abs(expect).max()


@pytest.mark.parametrize("path", sorted(FORMAT_1.glob("*.mcd")), ids=lambda p: p.name)
def test_format_1_is_refused_as_too_old(path):
    data = path.read_bytes()
    assert data[8:10] == b"\x01\x00"
    assert validate(data) == Result.VERSION_TOO_OLD
    assert validate(data, skip_checksum=True) == Result.VERSION_TOO_OLD
    with pytest.raises(RuntimeResultError) as info:
        Asset(data)
    assert info.value.code == Result.VERSION_TOO_OLD
    assert "older than this runtime" in str(info.value)

