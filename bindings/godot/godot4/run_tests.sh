#!/usr/bin/env bash
# Builds the Godot 4 GDExtension (runtime compiled in) against gdextension_interface.h from the
# crates.io crate gdextension-api 0.4.0 (interface 4.3: SkeletonModifier3D), with gcc and clang warning-free, and
# runs host_test: a stand-in engine that loads it like Godot, checks what it registers and
# calls it. Godot 4 itself is not installable here; see bindings/ENGINES.md.
set -euo pipefail
HERE="$(cd "$(dirname "$0")" && pwd)"
source "$HERE/../../common.sh"
OUT="$MCD_BUILD/godot4"
API_VERSION="${GDEXTENSION_API:-4.3}"
BIN="$HERE/project/addons/mocodec/bin"
mkdir -p "$OUT" "$BIN"

versions="$("$HERE/../fetch_headers.sh" | awk '$1 == "gdextension" { print $2 }')"
api="$versions/$API_VERSION/res"
[ -f "$api/gdextension_interface.h" ] || { echo "godot4: $api/gdextension_interface.h not found" >&2; exit 2; }
python3 "$HERE/gen_api_constants.py" "$api/extension_api.json" "$OUT/mcd_godot_api_constants.h"

FLAGS=(-std=c99 -O2 -fPIC -shared -fvisibility=hidden -Wall -Wextra -pedantic -Werror
       -I"$api" -I"$OUT" -I"$HERE/../common" -I"$MCD_RUNTIME/include" -I"$MCD_RUNTIME/src")
for cc in gcc clang; do
    if command -v "$cc" >/dev/null; then
        "$cc" "${FLAGS[@]}" "$HERE/mocodec_gdextension.c" "$HERE/../common/mcd_engine_asset.c" "$MCD_RUNTIME"/src/*.c \
            -o "$OUT/libmocodec_gdextension.$cc.so" -lm
        echo "godot4: built with $cc (-Wall -Wextra -pedantic -Werror)"
    fi
done
lib="$OUT/libmocodec_gdextension.gcc.so"
cp "$lib" "$BIN/libmocodec_gdextension.linux.x86_64.so"
exported="$(nm -D --defined-only "$lib" | awk '$2 == "T" { print $3 }')"
[ "$exported" = "mocodec_gdextension_init" ] || { echo "godot4: exports are '$exported', want only the entry point"; exit 1; }

# The addon's other platforms this machine can build (no engine loads them here): the same
# sources cross-compiled; each must export the entry point (and, for Linux, only it).
cross() { # NAME COMPILER OUTPUT EXTRA-FLAGS...
    local name="$1" compiler="$2" out="$3"
    shift 3
    if ! command -v "$compiler" >/dev/null; then
        echo "!!! godot4: SKIPPED the $name library: $compiler not installed"
        return
    fi
    "$compiler" "${FLAGS[@]}" "$@" "$HERE/mocodec_gdextension.c" "$HERE/../common/mcd_engine_asset.c" "$MCD_RUNTIME"/src/*.c \
        -o "$BIN/$out" -lm
    echo "godot4: built the $name library addons/mocodec/bin/$out"
}
cross "Linux arm64" aarch64-linux-gnu-gcc libmocodec_gdextension.linux.arm64.so
cross "Windows x86-64" x86_64-w64-mingw32-gcc-posix mocodec_gdextension.windows.x86_64.dll -static-libgcc
if [ -f "$BIN/libmocodec_gdextension.linux.arm64.so" ]; then
    exported="$(aarch64-linux-gnu-nm -D --defined-only "$BIN/libmocodec_gdextension.linux.arm64.so" 2>/dev/null | awk '$2 == "T" { print $3 }')"
    [ "$exported" = "mocodec_gdextension_init" ] || { echo "godot4: arm64 exports are '$exported'"; exit 1; }
fi
if [ -f "$BIN/mocodec_gdextension.windows.x86_64.dll" ]; then
    table="$(x86_64-w64-mingw32-objdump -p "$BIN/mocodec_gdextension.windows.x86_64.dll")"
    grep -q "\] mocodec_gdextension_init$" <<< "$table" ||
        { echo "godot4: the DLL does not export mocodec_gdextension_init"; exit 1; }
fi

# The addon's .gdextension names the entry point and the libraries built above.
ext="$HERE/project/addons/mocodec/mocodec.gdextension"
grep -q '^entry_symbol = "mocodec_gdextension_init"$' "$ext" || { echo "godot4: $ext: wrong entry_symbol"; exit 1; }
for f in "$BIN"/*; do
    grep -q "\"res://addons/mocodec/bin/$(basename "$f")\"" "$ext" || { echo "godot4: $ext does not list bin/$(basename "$f")"; exit 1; }
done
echo "godot4: addons/mocodec/mocodec.gdextension lists the $(ls "$BIN" | wc -l) libraries of bin/"

# The header of every newer interface version still compiles the extension (Godot keeps the
# 4.3 functions), so a project may build it against the engine it ships with. 4.2 has no
# SkeletonModifier3D.
for v in "$versions"/*/; do
    v="$(basename "$v")"
    [ "$v" = "$API_VERSION" ] && continue
    [ "$v" = "4.2" ] && continue
    python3 "$HERE/gen_api_constants.py" "$versions/$v/res/extension_api.json" "$OUT/check_$v.h"
    mkdir -p "$OUT/check_$v" && cp "$OUT/check_$v.h" "$OUT/check_$v/mcd_godot_api_constants.h"
    ${CC:-cc} -std=c99 -Wall -Wextra -Werror -Wno-deprecated-declarations -fsyntax-only \
        -I"$versions/$v/res" -I"$OUT/check_$v" -I"$HERE/../common" -I"$MCD_RUNTIME/include" "$HERE/mocodec_gdextension.c"
    echo "godot4: also compiles against the $v interface header"
done

mcd_test_data "$OUT/data" >&2
${CC:-cc} -std=c99 -O1 -g -Wall -Wextra -Werror -I"$api" "$HERE/host_test.c" -o "$OUT/host_test" -ldl -lm
total_passed=0
total_failed=0
for asset in "$OUT"/data/*.mcd; do
    for built in "$OUT"/libmocodec_gdextension.*.so; do
        log="$OUT/host_test.$(basename "$built" .so).$(basename "$asset" .mcd).log"
        "$OUT/host_test" "$built" "$asset" "${asset%.mcd}.poses.txt" > "$log" 2>&1 || true
        line="$(grep -E '^gdextension: [0-9]+ passed, [0-9]+ failed$' "$log" || echo 'gdextension: 0 passed, 1 failed')"
        p="$(echo "$line" | awk '{ print $2 }')"
        f="$(echo "$line" | awk '{ print $4 }')"
        total_passed=$((total_passed + p))
        total_failed=$((total_failed + f))
        echo "  $(basename "$built") on $(basename "$asset"): $p passed, $f failed"
        [ "$f" = 0 ] || grep -E "^FAIL|no method|cannot|usage" "$log" | sed 's/^/    /'
    done
done
echo "godot4 GDExtension checked in a stand-in host (host_test.c), not in Godot 4"
echo "godot4: $total_passed passed, $total_failed failed"
[ "$total_failed" = 0 ]
