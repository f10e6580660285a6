#!/usr/bin/env bash
# Builds the Godot 3 GDNative library (runtime compiled in) into project/addons/mocodec/bin
# against the gdnative-sys 0.11.3 headers fetched by ../fetch_headers.sh, and prints its path;
# also the Windows x86-64 one (MinGW-w64, when installed; no engine loads it here), which must
# export the three GDNative entry points.
set -euo pipefail
HERE="$(cd "$(dirname "$0")" && pwd)"
source "$HERE/../../common.sh"
headers="$("$HERE/../fetch_headers.sh" | awk '$1 == "gdnative" { print $2 }')"
[ -f "$headers/gdnative_api_struct.gen.h" ] || { echo "godot3: gdnative headers not found" >&2; exit 2; }
mkdir -p "$HERE/project/addons/mocodec/bin"
out="$HERE/project/addons/mocodec/bin/libmocodec_gdnative.so"
${CC:-cc} -std=c99 -O2 -fPIC -shared -fvisibility=hidden -Wall -Wextra -Werror \
    -I"$headers" -I"$HERE/../common" -I"$MCD_RUNTIME/include" -I"$MCD_RUNTIME/src" \
    "$HERE/mocodec_gdnative.c" "$HERE/../common/mcd_engine_asset.c" "$MCD_RUNTIME"/src/*.c -o "$out" -lm
win="$HERE/project/addons/mocodec/bin/mocodec_gdnative.windows.x86_64.dll"
if command -v x86_64-w64-mingw32-gcc-posix >/dev/null; then
    x86_64-w64-mingw32-gcc-posix -std=c99 -O2 -shared -static-libgcc -Wall -Wextra -Werror \
        -I"$headers" -I"$HERE/../common" -I"$MCD_RUNTIME/include" -I"$MCD_RUNTIME/src" \
        "$HERE/mocodec_gdnative.c" "$HERE/../common/mcd_engine_asset.c" "$MCD_RUNTIME"/src/*.c -o "$win" -lm
    table="$(x86_64-w64-mingw32-objdump -p "$win")"
    for sym in godot_gdnative_init godot_gdnative_terminate godot_nativescript_init; do
        grep -q "\] $sym$" <<< "$table" || { echo "godot3: $win does not export $sym" >&2; exit 1; }
    done
    ! grep -q "DLL Name: libgcc" <<< "$table" || { echo "godot3: $win needs libgcc's DLL" >&2; exit 1; }
    echo "godot3: built the Windows x86-64 library (exports the GDNative entry points)" >&2
else
    echo "!!! godot3: SKIPPED the Windows x86-64 library: x86_64-w64-mingw32-gcc-posix not installed" >&2
fi
echo "$out"
