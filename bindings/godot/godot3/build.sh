#!/usr/bin/env bash
# Builds the Godot 3 GDNative library (runtime compiled in) into project/bin against the
# gdnative-sys 0.11.3 headers fetched by ../fetch_headers.sh, and prints its path.
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
echo "$out"
