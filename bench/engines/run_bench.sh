#!/usr/bin/env bash
# Per-pose sampling cost of the 31-joint clip 09_11 (38 nodes with end sites; the golden spline
# asset) through C directly, the C# binding under mono, and the Godot 3 binding from GDScript
# in the headless engine. All three sample the same runtime build flags (-O2). Prints a table.
set -euo pipefail
HERE="$(cd "$(dirname "$0")" && pwd)"
source "$HERE/../../bindings/common.sh"
OUT="$MCD_REPO/bench/out/engines"
mkdir -p "$OUT"
N="${BENCH_SAMPLES:-200000}"
ASSET="${MCD_GOLDEN_DIR:-$MCD_REPO/tests/golden/v2}/spline_09_11.mcd"

lib="$(mcd_shared_lib)"
libdir="$(dirname "$lib")"
${CC:-cc} -std=c99 -O2 -I"$MCD_RUNTIME/include" "$HERE/bench_c.c" -L"$libdir" -lmocodec -Wl,-rpath,"$libdir" -o "$OUT/bench_c"

mcs -langversion:7.2 -unsafe -nologo -optimize+ -target:library -out:"$OUT/Mocodec.dll" "$MCD_REPO"/unity_package/Runtime/Core/*.cs
mcs -langversion:7.2 -nologo -optimize+ -out:"$OUT/Bench.exe" -r:"$OUT/Mocodec.dll" "$HERE/Bench.cs"

project="$MCD_REPO/bindings/godot/godot3/project"
"$MCD_REPO/bindings/godot/godot3/build.sh" > /dev/null
mkdir -p "$project/data"
cp "$ASSET" "$project/data/bench.mcd"
cp "$HERE/bench_godot3.gd" "$project/bench.gd"

# The three programs run in turn, REPEATS times, and each path keeps its best figure: on a shared
# machine the minimum is the figure least disturbed by other work.
mkdir -p "$MCD_BUILD/godot3_home"
: > "$OUT/raw.txt"
for _ in $(seq "${REPEATS:-3}"); do
    "$OUT/bench_c" "$ASSET" "$N" >> "$OUT/raw.txt"
    LD_LIBRARY_PATH="$libdir" mono "$OUT/Bench.exe" "$ASSET" "$N" >> "$OUT/raw.txt"
    HOME="$MCD_BUILD/godot3_home" timeout 600 godot3-server --no-window --path "$project" -s bench.gd 2>/dev/null |
        grep -E '^(godot3_|gdscript_)' >> "$OUT/raw.txt"
done
rm -f "$project/bench.gd" "$project/data/bench.mcd"

python3 -c '
import sys
rows = {}
for l in open(sys.argv[1]):
    key, nodes, us = l.split()[:3]
    if key not in rows or float(us) < rows[key][1]:
        rows[key] = (int(nodes), float(us))
c = rows["c"][1]
nodes = rows["c"][0]
print(f"per-pose sampling cost, clip 09_11 ({nodes} nodes = 31 joints + 7 end sites), best of all rounds")
names = [("c", "C, mcd_sample directly"),
         ("csharp", "C# (mono), MocodecContext.Sample"),
         ("godot3_sample", "Godot 3 GDScript -> MocodecAnimation.sample"),
         ("godot3_apply", "Godot 3 GDScript -> apply (sample + 38 set_bone_pose)"),
         ("gdscript_empty_call", "Godot 3 GDScript -> empty GDScript function")]
for key, label in names:
    us = rows[key][1]
    print(f"  {label:58s} {us:8.3f} us/pose  ({us - c:+.3f} us vs C, x{us / c:.2f})")
' "$OUT/raw.txt" | tee "$OUT/engines.txt"
