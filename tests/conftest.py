"""Shared fixtures; makes ``mocodec`` importable from a plain checkout."""
from __future__ import annotations

import os
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


def shared_data(name: str) -> Path | None:
    """``shared/data/<name>`` of the development data (``$MOCODEC_SHARED`` or ``../shared``
    beside the repository) when it is present, else None."""
    root = Path(os.environ["MOCODEC_SHARED"]) if os.environ.get("MOCODEC_SHARED") else REPO_ROOT / ".." / "shared"
    path = (root / "data" / name).resolve()
    return path if path.is_dir() else None


@pytest.fixture(scope="session")
def shared_cmu_dir(repo_root: Path) -> Path | None:
    """``../shared/data/cmu`` (the development data set) when it is present, else None."""
    return shared_data("cmu")


@pytest.fixture(scope="session")
def shared_gltf_dir() -> Path:
    """``../shared/data/gltf`` (12 real glTF files, MANIFEST.md); skips loudly without it."""
    path = shared_data("gltf")
    if path is None:
        pytest.skip("SKIPPED LOUDLY: ../shared/data/gltf (the development glTF set) is not on this "
                    "machine; set MOCODEC_SHARED to the shared folder to run the real-file tests")
    return path
