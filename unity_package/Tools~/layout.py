"""What makes unity_package/ installable from a git URL as it stands, and the check of it.

Unity ignores a file or folder of an immutable (git or registry) package that has no .meta, so
every one of them has a committed .meta whose GUID never changes (new ones are made from the
path, once, by ``write_missing_metas``). The native runtime is committed too, one library per
platform below, each with the importer settings that tell Unity which editor and player load
it, and Plugins/BUILD.json saying which runtime sources they were built from, so a stale
library is caught. Unity skips folders ending in '~', which is why this lives in one.
"""
from __future__ import annotations

import hashlib
import json
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1]
REPO = PACKAGE.parent
RUNTIME = REPO / "runtime_c"
NAME = "com.mocodec.runtime"
BUILD_INFO = Path("Plugins") / "BUILD.json"

# preset of runtime_c/CMakePresets.json -> (folder inside Plugins, file, installed file,
# PluginImporter entries: (platform group, target, settings)). Every entry is required.
PLATFORMS = {
    "linux-x86_64": ("Linux/x86_64", "libmocodec.so", "lib/libmocodec.so",
                     [("Editor", "Editor", {"CPU": "x86_64", "OS": "Linux"}),
                      ("Standalone", "Linux64", {"CPU": "x86_64"})]),
    "linux-aarch64": ("Linux/arm64", "libmocodec.so", "lib/libmocodec.so",
                      [("Editor", "Editor", {"CPU": "ARM64", "OS": "Linux"}),
                       ("Standalone", "Linux64", {"CPU": "ARM64"})]),
    "windows-x86_64": ("Windows/x86_64", "mocodec.dll", "bin/mocodec.dll",
                       [("Editor", "Editor", {"CPU": "x86_64", "OS": "Windows"}),
                        ("Standalone", "Win64", {"CPU": "x86_64"})]),
}

UNITY_ASSEMBLIES = {"UnityEngine.TestRunner", "UnityEditor.TestRunner"}
URL_KEYS = ("documentationUrl", "changelogUrl", "licensesUrl")
# Unity's offline fallbacks for those links, and what the package promises to carry.
REQUIRED_FILES = ("package.json", "LICENSE.md", "CHANGELOG.md", "README.md", "Documentation~/index.md")


def guid(rel: str) -> str:
    """A GUID for a path inside the package: stable, and unique as long as paths are."""
    return hashlib.md5(f"{NAME}/{rel}".encode()).hexdigest()


def skipped(rel: Path) -> bool:
    """Paths Unity does not import: hidden ('.') and '~' folders, except a sample's contents,
    which Unity copies into Assets/ with their .meta."""
    parts = rel.parts
    if any(p.startswith(".") for p in parts):
        return True
    if parts and parts[0] == "Samples~":
        return len(parts) < 3 or any(p.endswith("~") for p in parts[1:])
    return any(p.endswith("~") for p in parts)


def assets(root: Path) -> list[Path]:
    """Every file and folder of the package that needs a .meta, relative to root."""
    return [p.relative_to(root) for p in sorted(root.rglob("*"))
            if p.suffix != ".meta" and not skipped(p.relative_to(root))]


def plugin_meta(g: str, entries) -> str:
    lines = ["fileFormatVersion: 2", f"guid: {g}", "PluginImporter:", "  externalObjects: {}",
             "  serializedVersion: 2", "  iconMap: {}", "  executionOrder: {}",
             "  defineConstraints: []", "  isPreloaded: 0", "  isOverridable: 0",
             "  isExplicitlyReferenced: 0", "  validateReferences: 1", "  platformData:",
             "  - first:", "      Any: ", "    second:", "      enabled: 0", "      settings: {}"]
    for group, target, settings in entries:
        lines += ["  - first:", f"      {group}: {target}", "    second:", "      enabled: 1",
                  "      settings:"] + [f"        {k}: {v}" for k, v in settings.items()]
    lines += ["  userData: ", "  assetBundleName: ", "  assetBundleVariant: ", ""]
    return "\n".join(lines)


IMPORTER = Path("Editor") / "MocodecImporter.cs"


def mcd_meta(g: str, importer_guid: str) -> str:
    """A .mcd sample: imported by the package's ScriptedImporter (MocodecImporter.cs)."""
    return "\n".join(["fileFormatVersion: 2", f"guid: {g}", "ScriptedImporter:", "  internalIDToNameTable: []",
                      "  externalObjects: {}", "  serializedVersion: 2", "  userData: ", "  assetBundleName: ",
                      "  assetBundleVariant: ", f"  script: {{fileID: 11500000, guid: {importer_guid}, type: 3}}", ""])


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


def meta_path(path: Path) -> Path:
    return path.with_name(path.name + ".meta")


def plugin_files() -> dict[Path, tuple]:
    """Plugins/<folder>/<file> (relative) -> (preset, importer entries)."""
    return {Path("Plugins") / folder / file: (preset, entries)
            for preset, (folder, file, _, entries) in PLATFORMS.items()}


def write_missing_metas(root: Path = PACKAGE) -> list[Path]:
    """Writes a .meta for every asset that has none (never touches an existing GUID)."""
    plugins = plugin_files()
    written = []
    for rel in assets(root):
        meta = meta_path(root / rel)
        if meta.exists():
            continue
        g = guid(rel.as_posix())
        if rel in plugins:
            text = plugin_meta(g, plugins[rel][1])
        elif rel.suffix == ".mcd":
            text = mcd_meta(g, _meta_guid(meta_path(root / IMPORTER)) or guid(IMPORTER.as_posix()))
        else:
            text = plain_meta(g, root / rel)
        meta.write_text(text)
        written.append(meta.relative_to(root))
    return written


def source_digests(runtime: Path = RUNTIME) -> dict[str, str]:
    """sha256 of each runtime source a plugin is built from (line endings normalised, so a
    Windows checkout compares equal)."""
    files = sorted([*runtime.glob("include/*.h"), *runtime.glob("src/*.c"), *runtime.glob("src/*.h")])
    return {f.relative_to(runtime).as_posix(): hashlib.sha256(f.read_bytes().replace(b"\r\n", b"\n")).hexdigest()
            for f in files}


def _meta_guid(meta: Path) -> str | None:
    for line in meta.read_text().splitlines():
        if line.startswith("guid: "):
            return line[6:].strip()
    return None


def check(root: Path = PACKAGE, runtime: Path = RUNTIME) -> list[str]:
    """Everything that would stop a git-URL install from importing, compiling or loading the
    runtime; an empty list when the package is sound. ``runtime``: the sources the plugins must
    have been built from (None skips that comparison, for a packed copy)."""
    problems = []
    for rel in REQUIRED_FILES:
        if not (root / rel).is_file():
            problems.append(f"{rel}: missing")
    try:
        manifest = json.loads((root / "package.json").read_text())
    except (OSError, ValueError) as exc:
        return problems + [f"package.json: unreadable ({exc})"]
    if manifest.get("name") != NAME:
        problems.append(f"package.json: name is not {NAME}")
    if len(str(manifest.get("version", "")).split(".")) != 3:
        problems.append("package.json: version must be MAJOR.MINOR.PATCH")
    for key in URL_KEYS:
        if not str(manifest.get(key, "")).startswith("https://"):
            problems.append(f"package.json: no {key}")
    for sample in manifest.get("samples", []):
        if not (root / sample.get("path", "")).is_dir() or not sample.get("path", "").startswith("Samples~/"):
            problems.append(f"package.json: sample '{sample.get('displayName')}' has no folder {sample.get('path')}")
    if not manifest.get("samples"):
        problems.append("package.json: no samples")

    seen: dict[str, Path] = {}
    for rel in assets(root):
        meta = meta_path(root / rel)
        if not meta.exists():
            problems.append(f"{rel}: no .meta (Unity ignores it in a git package; run unity_package/Tools~/write_metas.py)")
            continue
        g = _meta_guid(meta)
        if g is None or len(g) != 32:
            problems.append(f"{rel}.meta: no GUID")
        elif g in seen:
            problems.append(f"{rel}: GUID also used by {seen[g]}")
        else:
            seen[g] = rel
    for meta in sorted(root.rglob("*.meta")):
        rel = meta.relative_to(root)
        target = meta.with_name(meta.name[:-5])
        if not skipped(rel) and not target.exists():
            problems.append(f"{rel}: .meta of nothing (left from a removed file)")

    importer = meta_path(root / IMPORTER)
    importer_guid = _meta_guid(importer) if importer.exists() else None
    for rel in assets(root):
        if rel.suffix == ".mcd" and meta_path(root / rel).exists() and \
                f"guid: {importer_guid}, type: 3" not in meta_path(root / rel).read_text():
            problems.append(f"{rel}.meta: not imported by {IMPORTER}")

    asmdefs = {}
    for path in sorted(root.rglob("*.asmdef")):
        rel = path.relative_to(root)
        if not skipped(rel):
            asmdefs[json.loads(path.read_text())["name"]] = (path.parent, json.loads(path.read_text()))
    for name, (_, data) in asmdefs.items():
        problems += [f"{name}: unknown reference {r}" for r in data.get("references", [])
                     if r not in asmdefs and r not in UNITY_ASSEMBLIES]
    folders = [folder for folder, _ in asmdefs.values()]
    for cs in sorted(root.rglob("*.cs")):
        rel = cs.relative_to(root)
        if not skipped(rel) and rel.parts[0] != "Samples~" and not any(f in cs.parents for f in folders):
            problems.append(f"{rel}: outside every asmdef (would land in Assembly-CSharp)")

    problems += check_plugins(root, runtime)
    return problems


def check_plugins(root: Path, runtime: Path | None) -> list[str]:
    problems = []
    for rel, (preset, entries) in plugin_files().items():
        lib = root / rel
        if not lib.is_file() or lib.stat().st_size == 0:
            problems.append(f"{rel}: missing native plugin for {preset} (make unity-plugins)")
            continue
        meta = meta_path(lib)
        if meta.exists():
            text = meta.read_text()
            if "PluginImporter:" not in text:
                problems.append(f"{rel}.meta: not a PluginImporter")
            for group, target, settings in entries:
                block = f"      {group}: {target}\n    second:\n      enabled: 1\n      settings:\n" + \
                        "".join(f"        {k}: {v}\n" for k, v in settings.items())
                if block not in text:
                    problems.append(f"{rel}.meta: not enabled for {group} {target} {settings}")
    info_path = root / BUILD_INFO
    if not info_path.is_file():
        return problems + [f"{BUILD_INFO}: missing (make unity-plugins writes it)"]
    info = json.loads(info_path.read_text())
    for rel in plugin_files():
        lib = root / rel
        want = info.get("plugins", {}).get(rel.as_posix(), {}).get("sha256")
        if lib.is_file() and want != hashlib.sha256(lib.read_bytes()).hexdigest():
            problems.append(f"{rel}: not the library {BUILD_INFO} describes (make unity-plugins)")
    if runtime is not None:
        built, now = info.get("sources", {}), source_digests(runtime)
        changed = sorted(k for k in now if built.get(k) != now[k])
        gone = sorted(k for k in built if k not in now)
        if changed or gone:
            what = ", ".join([*(f"{k} changed" if k in built else f"{k} not built in" for k in changed),
                              *(f"{k} removed" for k in gone)])
            problems.append(f"Plugins: built from other runtime sources than runtime_c/ ({what}); make unity-plugins")
    return problems
