"""What `pip install .` ships: both pyproject files (the repository's, which builds the encoder
with the runtime binding, and encoder/'s, the Makefile's development install) list every folder
of encoder/mocodec and cover every file in it. The root one once left out `mocodec.view`, so
`mocodec view` failed after a plain `pip install .`; data folders left out of the list make
setuptools warn that it may stop shipping them."""
from __future__ import annotations

import fnmatch
from pathlib import Path

import pytest

tomllib = pytest.importorskip("tomllib", reason="tomllib is in the standard library from Python 3.11")

REPO = Path(__file__).resolve().parent.parent
PACKAGE = REPO / "encoder" / "mocodec"
BUILT = ("*.so", "*.pyd", "*.pyc")  # compiled at install time (the _native module), not shipped from the tree


def _shipped_files() -> list[Path]:
    return [p for p in PACKAGE.rglob("*")
            if p.is_file() and "__pycache__" not in p.parts and not any(fnmatch.fnmatch(p.name, b) for b in BUILT)]


def _package_of(path: Path) -> str:
    return ".".join(("mocodec", *path.parent.relative_to(PACKAGE).parts))


@pytest.mark.parametrize("pyproject", ["pyproject.toml", "encoder/pyproject.toml"])
def test_every_folder_and_file_of_the_encoder_is_shipped(pyproject):
    config = tomllib.loads((REPO / pyproject).read_text())["tool"]["setuptools"]
    listed = {p for p in config["packages"] if p == "mocodec" or p.startswith("mocodec.")}
    files = _shipped_files()
    folders = {_package_of(f) for f in files}
    assert listed == folders, f"{pyproject}: not listed {sorted(folders - listed)}, listed but absent {sorted(listed - folders)}"
    data = config.get("package-data", {})
    missed = [str(f.relative_to(PACKAGE)) for f in files if f.suffix != ".py"
              and not any(fnmatch.fnmatch(f.name, pattern) for pattern in data.get(_package_of(f), []))]
    assert not missed, f"{pyproject}: no package-data pattern ships {missed}"
    assert {"mocodec.view", "mocodec.samples"} <= listed  # what `mocodec view` and the demo need
