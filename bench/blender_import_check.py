"""Import a glTF file and its decoded export into Blender and compare the animated skeletons.

    python bench/blender_import_check.py original.glb decoded.glb     # needs `blender` on PATH

Runs Blender in the background twice (this file is also the script Blender runs): each time
imports one file with Blender's own glTF importer and records, for every action, the world
position of every pose bone's head at the action's first, middle and last frame (pose reset to
rest before each action). Prints, per action, the largest distance between the two files (cm),
and the worst of all. A manual end-to-end check that Blender imports what `mocodec decode -o
x.glb` writes as the same motion; it is not part of the test suite (Blender is not installed by
the project).
"""
from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import tempfile
from pathlib import Path


def _in_blender(path: str, out: str) -> None:
    import bpy  # only inside Blender

    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.import_scene.gltf(filepath=path)
    arm = next(o for o in bpy.data.objects if o.type == "ARMATURE")
    poses = {}
    for act in bpy.data.actions:
        for pb in arm.pose.bones:
            pb.location, pb.rotation_quaternion, pb.scale = (0, 0, 0), (1, 0, 0, 0), (1, 1, 1)
        arm.animation_data.action = act
        for track in arm.animation_data.nla_tracks:
            track.mute = True
        lo, hi = act.frame_range
        for frame in (lo, (lo + hi) / 2, hi):
            bpy.context.scene.frame_set(int(frame), subframe=frame - int(frame))
            bpy.context.view_layer.update()
            poses[f"{act.name}@{frame:.2f}"] = {pb.name: list(arm.matrix_world @ pb.head) for pb in arm.pose.bones}
    Path(out).write_text(json.dumps(poses))


def _poses(path: Path, tmp: Path) -> dict:
    out = tmp / f"{path.stem}_{len(list(tmp.iterdir()))}.json"
    # Blender's Python finds its own modules (numpy for the importer) only without ours.
    env = {"PATH": "/usr/local/bin:/usr/bin:/bin", "HOME": os.environ.get("HOME", "/tmp")}
    subprocess.run(["blender", "-b", "--factory-startup", "--python", __file__, "--", str(path), str(out)],
                   check=True, capture_output=True, text=True, env=env)
    return json.loads(out.read_text())


def main(argv: list[str]) -> int:
    if len(argv) != 2:
        print(__doc__, file=sys.stderr)
        return 2
    with tempfile.TemporaryDirectory() as tmp:
        a, b = (_poses(Path(p), Path(tmp)) for p in argv)
    worst: dict[str, float] = {}
    for key, bones in a.items():
        if key not in b:
            print(f"{key}: missing in {argv[1]}")
            continue
        action = key.rsplit("@", 1)[0]
        d = max(math.dist(p, b[key][n]) for n, p in bones.items() if n in b[key]) * 100.0
        worst[action] = max(worst.get(action, 0.0), d)
    for action, d in worst.items():
        print(f"{action}: {d:.3f} cm")
    print(f"{len(worst)} actions; largest bone-head distance {max(worst.values()):.3f} cm")
    return 0


if __name__ == "__main__":
    if "--" in sys.argv:  # running inside Blender
        _in_blender(*sys.argv[sys.argv.index("--") + 1:])
    else:
        sys.exit(main(sys.argv[1:]))
