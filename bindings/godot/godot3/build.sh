#!/usr/bin/env bash
# Builds the Godot 3 GDNative library (runtime compiled in) into project/addons/mocodec/bin
# against the gdnative-sys 0.11.3 headers fetched by ../fetch_headers.sh, and prints its path;
# also the Linux arm64 and Windows x86-64 ones (cross compilers, when installed; no engine loads
# them here), each checked for its machine and the three GDNative entry points.
set -euo pipefail
HERE="$(cd "$(dirname "$0")" && pwd)"
source "$HERE/../../common.sh"
headers="$("$HERE/../fetch_headers.sh" | awk '$1 == "gdnative" { print $2 }')"
[ -f "$headers/gdnative_api_struct.gen.h" ] || { echo "godot3: gdnative headers not found" >&2; exit 2; }
BIN="$HERE/project/addons/mocodec/bin"
rm -rf "$BIN" && mkdir -p "$BIN"  # no library of an earlier run survives a missing compiler
ENTRY_POINTS=(godot_gdnative_init godot_gdnative_terminate godot_nativescript_init)

# The Godot headers are third-party, so -isystem keeps their warnings out of -Werror: they mark
# every call sysv_abi, an x86 attribute that arm64 compilers ignore with a warning (Godot on
# arm64 uses the platform's own calling convention, which is what the library gets).
build() { # COMPILER OUTPUT EXTRA-FLAGS...
    local compiler="$1" out="$2"
    shift 2
    "$compiler" -std=c99 -O2 -shared -Wall -Wextra -Werror "$@" \
        -isystem "$headers" -I"$HERE/../common" -I"$MCD_RUNTIME/include" -I"$MCD_RUNTIME/src" \
        "$HERE/mocodec_gdnative.c" "$HERE/../common/mcd_engine_asset.c" "$MCD_RUNTIME"/src/*.c -o "$out" -lm
}

out="$BIN/libmocodec_gdnative.so"
build "${CC:-cc}" "$out" -fPIC -fvisibility=hidden

arm="$BIN/libmocodec_gdnative.linux.arm64.so"
if command -v aarch64-linux-gnu-gcc >/dev/null; then
    build aarch64-linux-gnu-gcc "$arm" -fPIC -fvisibility=hidden
    machine="$(aarch64-linux-gnu-readelf -h "$arm" | awk -F: '$1 ~ /Machine/ { gsub(/^ +/, "", $2); print $2 }')"
    [ "$machine" = "AArch64" ] || { echo "godot3: $arm is for '$machine', not AArch64" >&2; exit 1; }
    exported="$(aarch64-linux-gnu-nm -D --defined-only "$arm" | awk '$2 == "T" { print $3 }' | sort | tr '\n' ' ')"
    [ "$exported" = "$(printf '%s\n' "${ENTRY_POINTS[@]}" | sort | tr '\n' ' ')" ] ||
        { echo "godot3: $arm exports '$exported', want only the GDNative entry points" >&2; exit 1; }
    echo "godot3: built the Linux arm64 library (AArch64, exports only the GDNative entry points)" >&2
else
    echo "!!! godot3: SKIPPED the Linux arm64 library: aarch64-linux-gnu-gcc not installed" >&2
fi

win="$BIN/mocodec_gdnative.windows.x86_64.dll"
if command -v x86_64-w64-mingw32-gcc-posix >/dev/null; then
    build x86_64-w64-mingw32-gcc-posix "$win" -static-libgcc
    table="$(x86_64-w64-mingw32-objdump -p "$win")"
    for sym in "${ENTRY_POINTS[@]}"; do
        grep -q "\] $sym$" <<< "$table" || { echo "godot3: $win does not export $sym" >&2; exit 1; }
    done
    ! grep -q "DLL Name: libgcc" <<< "$table" || { echo "godot3: $win needs libgcc's DLL" >&2; exit 1; }
    echo "godot3: built the Windows x86-64 library (exports the GDNative entry points)" >&2
else
    echo "!!! godot3: SKIPPED the Windows x86-64 library: x86_64-w64-mingw32-gcc-posix not installed" >&2
fi
echo "$out"
