"""Assemble the installable Unity package (a UPM tarball) and check its layout.

    python3 unity_package/Tools~/pack.py OUT_DIR [--plugin PLATFORM=PATH ...] [--test-data DIR]

The repository keeps the package's own sources here and the C# core once, in bindings/csharp;
this copies the core into Runtime/Core, the native libraries into Plugins/<platform>, the test
assets into Tests/Data~, writes a .meta (stable GUID from the path) for every file and folder,
since Unity ignores files without one in an immutable package, and writes
OUT_DIR/com.mocodec.runtime-VERSION.tgz with the npm layout (root folder "package/").
Unity skips folders ending in '~', which is why this script lives in one.
"""
from __future__ import annotations

import argparse
import hashlib
import json
import shutil
import sys
import tarfile
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1]
REPO = PACKAGE.parent
CORE = REPO / "bindings" / "csharp" / "Mocodec"

# platform -> (folder inside Plugins, file name, Unity importer platform entries)
PLATFORMS = {
    "linux-x86_64": ("Linux/x86_64", "libmocodec.so",
                     [("Editor", "Editor", {"CPU": "x86_64", "OS": "Linux"}),
                      ("Standalone", "Linux64", {"CPU": "x86_64"})]),
    "windows-x86_64": ("Windows/x86_64", "mocodec.dll",
                       [("Editor", "Editor", {"CPU": "x86_64", "OS": "Windows"}),
                        ("Standalone", "Win64", {"CPU": "x86_64"})]),
    "macos-universal": ("macOS", "libmocodec.dylib",
                        [("Editor", "Editor", {"CPU": "AnyCPU", "OS": "OSX"}),
                         ("Standalone", "OSXUniversal", {"CPU": "AnyCPU"})]),
    "android-arm64": ("Android/arm64-v8a", "libmocodec.so",
                      [("Android", "Android", {"CPU": "ARM64"})]),
    "ios": ("iOS", "libmocodec.a",
            [("iPhone", "iOS", {"CPU": "AnyCPU"})]),
}

UNITY_ASSEMBLIES = {"UnityEngine.TestRunner", "UnityEditor.TestRunner"}


def guid(rel: str) -> str:
    return hashlib.md5(f"com.mocodec.runtime/{rel}".encode()).hexdigest()


def plugin_meta(g: str, entries) -> str:
    lines = ["fileFormatVersion: 2", f"guid: {g}", "PluginImporter:", "  externalObjects: {}",
             "  serializedVersion: 2", "  iconMap: {}", "  executionOrder: {}",
             "  defineConstraints: []", "  isPreloaded: 0", "  isOverridable: 0",
             "  isExplicitlyReferenced: 0", "  validateReferences: 1", "  platformData:",
             "  - first:", "      Any: ", "    second:", "      enabled: 0", "      settings: {}"]
    editor_listed = any(group == "Editor" for group, _, _ in entries)
    for group, target, settings in entries:
        lines += ["  - first:", f"      {group}: {target}", "    second:", "      enabled: 1",
                  "      settings:"] + [f"        {k}: {v}" for k, v in settings.items()]
    if not editor_listed:  # mobile libraries must stay out of the editor
        lines += ["  - first:", "      Editor: Editor", "    second:", "      enabled: 0",
                  "      settings:", "        DefaultValueInitialized: true"]
    lines += ["  userData: ", "  assetBundleName: ", "  assetBundleVariant: ", ""]
    return "\n".join(lines)


def plain_meta(g: str, path: Path) -> str:
    if path.is_dir():
        body = ["folderAsset: yes", "DefaultImporter:", "  externalObjects: {}"]
    elif path.suffix == ".cs":
        body = ["MonoImporter:", "  externalObjects: {}", "  serializedVersion: 2",
                "  defaultReferences: []", "  executionOrder: 0", "  icon: {instanceID: 0}"]
    elif path.suffix == ".asmdef":
        body = ["AssemblyDefinitionImporter:", "  externalObjects: {}"]
    elif path.suffix in (".json", ".md", ".txt"):
        body = ["TextScriptImporter:", "  externalObjects: {}"]
    else:
        body = ["DefaultImporter:", "  externalObjects: {}"]
    return "\n".join(["fileFormatVersion: 2", f"guid: {g}", *body,
                      "  userData: ", "  assetBundleName: ", "  assetBundleVariant: ", ""])


def hidden(rel: Path) -> bool:
    return any(part.endswith("~") or part.startswith(".") for part in rel.parts)


def assemble(stage: Path, plugins: dict[str, Path], test_data: Path | None) -> None:
    for name in ("package.json", "Runtime", "Editor", "Tests", "Plugins"):
        src = PACKAGE / name
        (shutil.copytree if src.is_dir() else shutil.copyfile)(src, stage / name)
    for cs in sorted(CORE.glob("*.cs")):
        shutil.copyfile(cs, stage / "Runtime" / "Core" / cs.name)
    shutil.copyfile(REPO / "bindings" / "ENGINES.md", stage / "README.md")
    plugin_files = {}
    for platform, lib in plugins.items():
        folder, filename, entries = PLATFORMS[platform]
        dest = stage / "Plugins" / folder / filename
        dest.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(lib, dest)
        plugin_files[dest] = entries
    if test_data is not None:
        data = stage / "Tests" / "Data~"
        data.mkdir()
        for f in sorted(test_data.iterdir()):
            if f.suffix in (".mcd", ".txt"):
                shutil.copyfile(f, data / f.name)
    for path in sorted(stage.rglob("*")):
        rel = path.relative_to(stage)
        if hidden(rel) or path.suffix == ".meta":
            continue
        g = guid(rel.as_posix())
        text = plugin_meta(g, plugin_files[path]) if path in plugin_files else plain_meta(g, path)
        path.with_name(path.name + ".meta").write_text(text)


def check(stage: Path) -> list[str]:
    """Problems Unity would report on import; empty when the layout is sound."""
    problems = []
    manifest = json.loads((stage / "package.json").read_text())
    if not manifest.get("name", "").startswith("com.") or manifest["name"] != manifest["name"].lower():
        problems.append("package.json: name must be lower-case reverse-DNS")
    if len(manifest.get("version", "").split(".")) != 3:
        problems.append("package.json: version must be MAJOR.MINOR.PATCH")
    seen = {}
    asmdefs = {}
    for path in sorted(stage.rglob("*")):
        rel = path.relative_to(stage)
        if hidden(rel) or path.suffix == ".meta":
            continue
        meta = path.with_name(path.name + ".meta")
        if not meta.exists():
            problems.append(f"{rel}: no .meta")
            continue
        g = meta.read_text().split("guid: ")[1].split()[0]
        if g in seen:
            problems.append(f"{rel}: GUID also used by {seen[g]}")
        seen[g] = rel
        if path.suffix == ".asmdef":
            asmdefs[json.loads(path.read_text())["name"]] = path.parent
    for name, folder in asmdefs.items():
        refs = json.loads(next(folder.glob("*.asmdef")).read_text()).get("references", [])
        problems += [f"{name}: unknown reference {r}" for r in refs if r not in asmdefs and r not in UNITY_ASSEMBLIES]
    for cs in stage.rglob("*.cs"):
        rel = cs.relative_to(stage)
        if not hidden(rel) and not any(p in asmdefs.values() for p in cs.parents):
            problems.append(f"{rel}: outside every asmdef (would land in Assembly-CSharp)")
    if not list((stage / "Runtime" / "Core").glob("*.cs")):
        problems.append("Runtime/Core: the C# core was not copied")
    return problems


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("out", type=Path)
    ap.add_argument("--plugin", action="append", default=[], help="PLATFORM=PATH")
    ap.add_argument("--test-data", type=Path)
    args = ap.parse_args()
    plugins = {}
    for spec in args.plugin:
        platform, _, path = spec.partition("=")
        if platform not in PLATFORMS:
            ap.error(f"unknown platform {platform}; known: {', '.join(PLATFORMS)}")
        plugins[platform] = Path(path)
    version = json.loads((PACKAGE / "package.json").read_text())["version"]
    root = args.out / "unity_stage"
    shutil.rmtree(root, ignore_errors=True)
    stage = root / "package"
    stage.mkdir(parents=True)
    assemble(stage, plugins, args.test_data)
    problems = check(stage)
    for p in problems:
        print(f"unity package: {p}", file=sys.stderr)
    if problems:
        return 1
    tgz = args.out / f"com.mocodec.runtime-{version}.tgz"
    with tarfile.open(tgz, "w:gz") as tar:
        tar.add(stage, arcname="package")
    files = sum(1 for p in stage.rglob("*") if p.is_file() and p.suffix != ".meta")
    print(f"unity package: {tgz.name}, {files} files with .meta, plugins: {', '.join(plugins) or 'none'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
