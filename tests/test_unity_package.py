"""The Unity package installs from a git URL as it stands: every asset has a committed .meta, the
native plugins of every shipped platform are there with their importer settings and were built
from the runtime sources in the repository, and the pack step refuses a package that lacks any
of it. (Unity itself is not on the test machine: the C# core is tested under mono, see
bindings/csharp/run_tests.sh.)"""
from __future__ import annotations

import importlib.util
import json
import shutil
import subprocess
import sys
import tarfile
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
PACKAGE = REPO / "unity_package"
TOOLS = PACKAGE / "Tools~"


def _layout():
    spec = importlib.util.spec_from_file_location("unity_layout", TOOLS / "layout.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


layout = _layout()


@pytest.fixture
def copy(tmp_path: Path) -> Path:
    """A copy of the repository's package and runtime sources (the parts the tools read)."""
    shutil.copytree(PACKAGE, tmp_path / "unity_package")
    for part in ("include", "src"):
        shutil.copytree(REPO / "runtime_c" / part, tmp_path / "runtime_c" / part)
    return tmp_path


def _pack(root: Path, out: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(root / "unity_package" / "Tools~" / "pack.py"), str(out)],
                          capture_output=True, text=True, timeout=120)


def test_repository_package_is_installable() -> None:
    problems = layout.check(PACKAGE, REPO / "runtime_c")
    assert problems == [], "\n".join(problems)


def test_every_shipped_platform_has_its_plugin() -> None:
    info = json.loads((PACKAGE / layout.BUILD_INFO).read_text())
    shipped = {v["preset"] for v in info["plugins"].values()}
    assert shipped == {"linux-x86_64", "linux-aarch64", "windows-x86_64"}
    # ELF for Linux (x86-64 = 62, aarch64 = 183 in e_machine), PE for Windows
    elf = {"Linux/x86_64": 62, "Linux/arm64": 183}
    for folder, machine in elf.items():
        head = (PACKAGE / "Plugins" / folder / "libmocodec.so").read_bytes()[:20]
        assert head[:4] == b"\x7fELF" and int.from_bytes(head[18:20], "little") == machine, folder
    assert (PACKAGE / "Plugins" / "Windows" / "x86_64" / "mocodec.dll").read_bytes()[:2] == b"MZ"


def test_check_names_a_missing_or_orphaned_meta(copy: Path) -> None:
    pkg = copy / "unity_package"
    (pkg / "Runtime" / "Unity" / "MocodecPlayer.cs.meta").unlink()
    (pkg / "Runtime" / "Core.meta").unlink()
    (pkg / "Editor" / "Gone.cs.meta").write_text("fileFormatVersion: 2\nguid: 0123456789abcdef0123456789abcdef\n")
    problems = "\n".join(layout.check(pkg, copy / "runtime_c"))
    assert "Runtime/Unity/MocodecPlayer.cs: no .meta" in problems
    assert "Runtime/Core: no .meta" in problems
    assert "Editor/Gone.cs.meta: .meta of nothing" in problems


def test_check_names_a_repeated_guid(copy: Path) -> None:
    pkg = copy / "unity_package"
    shutil.copyfile(pkg / "Runtime" / "Unity" / "MocodecPlayer.cs.meta", pkg / "Runtime" / "Unity" / "MocodecClip.cs.meta")
    assert any("GUID also used by" in p for p in layout.check(pkg, copy / "runtime_c"))


def test_check_names_a_missing_plugin_or_wrong_import_settings(copy: Path) -> None:
    pkg = copy / "unity_package"
    (pkg / "Plugins" / "Windows" / "x86_64" / "mocodec.dll").unlink()
    meta = pkg / "Plugins" / "Linux" / "arm64" / "libmocodec.so.meta"
    meta.write_text(meta.read_text().replace("CPU: ARM64", "CPU: x86_64"))
    problems = "\n".join(layout.check(pkg, copy / "runtime_c"))
    assert "Plugins/Windows/x86_64/mocodec.dll: missing native plugin for windows-x86_64" in problems
    assert "Plugins/Linux/arm64/libmocodec.so.meta: not enabled for Editor" in problems


def test_check_names_plugins_built_from_other_sources(copy: Path) -> None:
    src = copy / "runtime_c" / "src" / "sample.c"
    src.write_text(src.read_text() + "\n/* changed */\n")
    problems = layout.check(copy / "unity_package", copy / "runtime_c")
    assert any("src/sample.c changed" in p for p in problems), problems
    lib = copy / "unity_package" / "Plugins" / "Linux" / "x86_64" / "libmocodec.so"
    lib.write_bytes(lib.read_bytes() + b"\0")
    assert any("not the library" in p for p in layout.check(copy / "unity_package", None))


def test_pack_writes_the_package_with_its_plugins(copy: Path, tmp_path: Path) -> None:
    result = _pack(copy, tmp_path / "out")
    assert result.returncode == 0, result.stderr
    version = json.loads((PACKAGE / "package.json").read_text())["version"]
    with tarfile.open(tmp_path / "out" / f"com.mocodec.runtime-{version}.tgz") as tar:
        names = set(tar.getnames())
    for rel in ("package/package.json", "package/Plugins/Linux/x86_64/libmocodec.so.meta",
                "package/Plugins/Linux/arm64/libmocodec.so", "package/Plugins/Windows/x86_64/mocodec.dll",
                "package/Samples~/Basic Playback/MocodecSampleFigure.cs.meta", "package/Documentation~/index.md"):
        assert rel in names, rel
    assert not any("Tools~" in n for n in names)


def test_pack_refuses_a_package_without_plugins_or_meta(copy: Path, tmp_path: Path) -> None:
    shutil.rmtree(copy / "unity_package" / "Plugins" / "Linux")
    (copy / "unity_package" / "Editor" / "MocodecImporter.cs.meta").unlink()
    result = _pack(copy, tmp_path / "out")
    assert result.returncode == 1
    assert "Plugins/Linux/x86_64/libmocodec.so: missing native plugin" in result.stderr
    assert "Editor/MocodecImporter.cs: no .meta" in result.stderr
    assert "Traceback" not in result.stderr
    assert not list((tmp_path / "out").glob("*.tgz"))


def test_sample_clip_is_accepted_by_the_runtime() -> None:
    runtime = pytest.importorskip("mocodec_runtime")
    manifest = json.loads((PACKAGE / "package.json").read_text())
    clips = [f for s in manifest["samples"] for f in (PACKAGE / s["path"]).glob("*.mcd")]
    scripts = [f for s in manifest["samples"] for f in (PACKAGE / s["path"]).glob("*.cs")]
    assert clips and scripts
    for clip in clips:
        asset = runtime.Asset(clip.read_bytes())
        assert len(asset.clips) >= 1 and clip.stat().st_size < 16 * 1024, clip.name
