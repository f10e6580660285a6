"""Pack the Unity package as it stands in the repository into a UPM tarball, refusing one that
would not install: a missing .meta, a missing or stale native plugin, a broken asmdef
reference (layout.check lists them all, one line each).

    python3 unity_package/Tools~/pack.py OUT_DIR [--test-data DIR]

--test-data copies the .mcd and reference-pose files of DIR into Tests/Data~ for the Test
Runner. Writes OUT_DIR/com.mocodec.runtime-VERSION.tgz with the npm layout (root "package/").
"""
from __future__ import annotations

import argparse
import json
import shutil
import sys
import tarfile
from pathlib import Path

from layout import NAME, PACKAGE, RUNTIME, check


def stage_package(stage: Path, test_data: Path | None) -> None:
    shutil.copytree(PACKAGE, stage, ignore=shutil.ignore_patterns("Tools~", ".*"))
    if test_data is not None:
        data = stage / "Tests" / "Data~"
        data.mkdir()
        for f in sorted(test_data.iterdir()):
            if f.suffix in (".mcd", ".txt"):
                shutil.copyfile(f, data / f.name)


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("out", type=Path)
    ap.add_argument("--test-data", type=Path)
    args = ap.parse_args()
    root = args.out / "unity_stage"
    shutil.rmtree(root, ignore_errors=True)
    stage = root / "package"
    root.mkdir(parents=True)
    stage_package(stage, args.test_data)
    problems = check(stage, RUNTIME)
    for p in problems:
        print(f"unity package: {p}", file=sys.stderr)
    if problems:
        print(f"unity package: refused ({len(problems)} problems)", file=sys.stderr)
        return 1
    version = json.loads((stage / "package.json").read_text())["version"]
    tgz = args.out / f"{NAME}-{version}.tgz"
    with tarfile.open(tgz, "w:gz") as tar:
        tar.add(stage, arcname="package")
    files = sum(1 for p in stage.rglob("*") if p.is_file() and p.suffix != ".meta")
    print(f"unity package: {tgz.name}, {files} files with .meta, {tgz.stat().st_size} bytes")
    return 0


if __name__ == "__main__":
    sys.exit(main())
