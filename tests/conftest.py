"""Shared fixtures; makes ``mocodec`` importable from a plain checkout."""
from __future__ import annotations

import sys
from pathlib import Path

import pytest

REPO_ROOT = Path(__file__).resolve().parents[1]

try:
    import mocodec  # noqa: F401
except ImportError:
    sys.path.insert(0, str(REPO_ROOT / "encoder"))


@pytest.fixture(scope="session")
def repo_root() -> Path:
    return REPO_ROOT


@pytest.fixture(scope="session")
def sample_paths(repo_root: Path) -> list[Path]:
    """The BVH clips bundled with the encoder."""
    paths = sorted((repo_root / "encoder" / "mocodec" / "samples").glob("*.bvh"))
    assert len(paths) == 3, f"expected 3 bundled samples, found {[p.name for p in paths]}"
    return paths


@pytest.fixture(scope="session")
def shared_cmu_dir(repo_root: Path) -> Path | None:
    """``../shared/data/cmu`` (the development data set) when it is present, else None."""
    path = (repo_root / ".." / "shared" / "data" / "cmu").resolve()
    return path if path.is_dir() else None
