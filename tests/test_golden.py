"""Golden assets of every released format version stay readable and sample to the poses
recorded beside them (tests/golden/make_golden.py); the C tests and every binding replay
the same files."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from mocodec.runtime import Asset, Result, validate

GOLDEN = Path(__file__).resolve().parent / "golden"


def _cases():
    return sorted(GOLDEN.glob("v*/*.mcd"))


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
    assert len(_cases()) >= 2


@pytest.mark.parametrize("path", _cases(), ids=lambda p: f"{p.parent.name}/{p.name}")
def test_golden_asset_samples_to_recorded_poses(path):
    data = path.read_bytes()
    assert validate(data) == Result.OK
    asset = Asset(data)
    samples = _read_poses(path.with_suffix(".poses.txt"))
    assert samples
    for clip, t, flags, expect in samples:
        got = asset.sample(clip, np.float32(t), flags).astype(np.float64)
        assert got.shape == expect.shape
        assert np.abs(got - expect).max() <= 1e-5 + 1e-6 * np.abs(expect).max()
