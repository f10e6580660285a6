"""Copies the native runtime of every platform the Unity package ships into Plugins/ and
records what they were built from in Plugins/BUILD.json (the package check compares it with
runtime_c/ and the libraries). Takes the installs of `make -C runtime_c platforms` (built,
tested, stripped); `make unity-plugins` runs both.

    python3 unity_package/Tools~/update_plugins.py [--platforms runtime_c/build/platforms]
                                                   [--runtime runtime_c]
"""
from __future__ import annotations

import argparse
import hashlib
import json
import shutil
import sys
from pathlib import Path

from layout import BUILD_INFO, PACKAGE, PLATFORMS, RUNTIME, source_digests, write_missing_metas


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--platforms", type=Path, default=RUNTIME / "build" / "platforms",
                    help="the install root of `make -C runtime_c platforms`")
    ap.add_argument("--runtime", type=Path, default=RUNTIME,
                    help="the runtime_c tree those were built from (its sources are recorded)")
    args = ap.parse_args()
    missing = [f"{preset} ({args.platforms / preset / installed})"
               for preset, (_, _, installed, _) in PLATFORMS.items()
               if not (args.platforms / preset / installed).is_file()]
    if missing:
        print(f"update_plugins: not built (or its tests failed): {', '.join(missing)}", file=sys.stderr)
        return 1
    plugins = {}
    for preset, (folder, file, installed, _) in PLATFORMS.items():
        dest = PACKAGE / "Plugins" / folder / file
        dest.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(args.platforms / preset / installed, dest)
        data = dest.read_bytes()
        plugins[f"Plugins/{folder}/{file}"] = {"preset": preset, "bytes": len(data),
                                               "sha256": hashlib.sha256(data).hexdigest()}
        print(f"update_plugins: Plugins/{folder}/{file} from {preset}, {len(data)} bytes")
    info = {"about": "written by unity_package/Tools~/update_plugins.py; the package check compares it "
                     "with the libraries and runtime_c/",
            "plugins": plugins, "sources": source_digests(args.runtime)}
    (PACKAGE / BUILD_INFO).write_text(json.dumps(info, indent=1, sort_keys=True) + "\n")
    for rel in write_missing_metas(PACKAGE):
        print(f"update_plugins: wrote unity_package/{rel}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
