#!/usr/bin/env bash
# Builds the Godot 3 GDNative library (runtime compiled in) against the gdnative-sys 0.11.3
# headers into the addon (project/addons/mocodec), lets the real editor import the test assets
# with the addon's import plugin (godot3-server --editor --quit: the headless build has the
# editor), then runs project/test.gd in the real headless engine. Prints the test's
# "godot3: N passed, N failed" line and fails when it fails, times out or prints none.
set -euo pipefail
HERE="$(cd "$(dirname "$0")" && pwd)"
source "$HERE/../../common.sh"
PROJECT="$HERE/project"
GODOT="${GODOT3:-godot3-server}"
command -v "$GODOT" >/dev/null || { echo "godot3: $GODOT not found (apt-get install godot3-server)" >&2; exit 2; }

"$HERE/build.sh" > /dev/null
# The addon's .gdnlib lists every library build.sh made, and each platform's arm64 entry comes
# before its "64" one: Godot 3 takes the first entry whose tags the engine has, and an arm64
# engine has "64" as well.
lib="$PROJECT/addons/mocodec/mocodec.gdnlib"
for f in "$PROJECT"/addons/mocodec/bin/*; do
    grep -q "=\"res://addons/mocodec/bin/$(basename "$f")\"$" "$lib" || { echo "godot3: $lib does not list bin/$(basename "$f")"; exit 1; }
done
for platform in X11 Server; do
    order="$(awk -F= -v p="$platform" '/^\[/ { s = $0 } s == "[entry]" && ($1 == p ".arm64" || $1 == p ".64") { printf "%s ", $1 }' "$lib")"
    [ "$order" = "$platform.arm64 $platform.64 " ] || { echo "godot3: $lib: [entry] has '$order', want $platform.arm64 before $platform.64"; exit 1; }
done
echo "godot3: addons/mocodec/mocodec.gdnlib lists the $(ls "$PROJECT/addons/mocodec/bin" | wc -l) libraries of bin/, arm64 ahead of x86-64"
rm -rf "$PROJECT/data" "$PROJECT/.import"
mcd_test_data "$PROJECT/data" >&2
# A corrupt asset the importer must refuse (one byte of the payload flipped: checksum).
python3 - "$PROJECT/data" <<'PY'
import sys, pathlib
d = pathlib.Path(sys.argv[1])
b = bytearray(sorted(d.glob("golden_*.mcd"))[0].read_bytes())
b[len(b) // 2] ^= 0x10
(d / "broken.mcd").write_bytes(bytes(b))
PY

# A script error makes Godot 3 wait forever instead of exiting: always bound the run. HOME is
# redirected so the engine's settings folder lands in the build tree, not the user's home.
log="$MCD_BUILD/godot3_test.log"
mkdir -p "$MCD_BUILD/godot3_home"
set +e
# The editor scans res:// once and imports every .mcd through addons/mocodec/import_plugin.gd.
HOME="$MCD_BUILD/godot3_home" timeout "${GODOT_TIMEOUT:-300}" "$GODOT" --no-window --editor --quit --path "$PROJECT" \
    > "$MCD_BUILD/godot3_import.log" 2>&1
imported="$(ls "$PROJECT"/.import/*.res 2>/dev/null | wc -l)"
echo "godot3: the editor imported $imported .mcd files (log: $MCD_BUILD/godot3_import.log)"
grep -E "not an asset this runtime reads" "$MCD_BUILD/godot3_import.log" | head -n 3
HOME="$MCD_BUILD/godot3_home" timeout "${GODOT_TIMEOUT:-300}" "$GODOT" --no-window --path "$PROJECT" -s test.gd > "$log" 2>&1
rc=$?
set -e
grep -E "^(FAIL|godot3)|SCRIPT ERROR|Parse Error" "$log" || true
if [ $rc -eq 124 ]; then
    echo "godot3: timed out (a script error hangs Godot 3); log: $log"
    echo "godot3: 0 passed, 1 failed"
    exit 1
fi
if ! grep -qE "^godot3: [0-9]+ passed, [0-9]+ failed" "$log"; then
    tail -n 40 "$log"
    echo "godot3: the test printed no result (exit $rc)"
    echo "godot3: 0 passed, 1 failed"
    exit 1
fi
exit $rc
