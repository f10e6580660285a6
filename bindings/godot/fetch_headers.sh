#!/usr/bin/env bash
# Fetches the engine headers from crates.io into cargo's registry cache and prints where they
# are, one "NAME PATH" line each:
#   gdextension  .../gdextension-api-0.4.0/versions      (Godot 4: <4.x>/res/gdextension_interface.h)
#   gdnative     .../gdnative-sys-0.11.3/godot_headers   (Godot 3)
# The headers are never copied into the repository: a throwaway Cargo project under
# bindings/build names the two crates and `cargo metadata` resolves where cargo unpacked them.
set -euo pipefail
HERE="$(cd "$(dirname "$0")" && pwd)"
WORK="$HERE/../build/header_fetch"
mkdir -p "$WORK/src"
[ -f "$WORK/src/lib.rs" ] || : > "$WORK/src/lib.rs"
cat > "$WORK/Cargo.toml.new" <<'TOML'
[package]
name = "mocodec-engine-headers"
version = "0.0.0"
edition = "2021"
publish = false

[lib]
path = "src/lib.rs"

[dependencies]
gdextension-api = "=0.4.0"
gdnative-sys = "=0.11.3"
TOML
cmp -s "$WORK/Cargo.toml.new" "$WORK/Cargo.toml" 2>/dev/null || mv "$WORK/Cargo.toml.new" "$WORK/Cargo.toml"
rm -f "$WORK/Cargo.toml.new"
command -v cargo >/dev/null || { echo "fetch_headers: cargo not found" >&2; exit 2; }
cargo fetch --quiet --manifest-path "$WORK/Cargo.toml" >&2
cargo metadata --quiet --format-version 1 --manifest-path "$WORK/Cargo.toml" | python3 -c '
import json, os, sys
wanted = {"gdextension-api": ("gdextension", "versions"), "gdnative-sys": ("gdnative", "godot_headers")}
for p in json.load(sys.stdin)["packages"]:
    if p["name"] in wanted:
        label, sub = wanted[p["name"]]
        print(label, os.path.join(os.path.dirname(p["manifest_path"]), sub))
'
