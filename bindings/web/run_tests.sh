#!/usr/bin/env bash
# The web binding's tests: builds the runtime for wasm32 (make -C runtime_c wasm), makes fixtures
# with the encoder and the native runtime, and runs the node tests and the type check.
# Installs the wasm toolchain from apt when it is missing and it can (root).
#   FIXTURES=DIR reuses (or keeps) the fixtures there; by default a temporary folder.
set -euo pipefail
cd "$(dirname "$0")"
ROOT=$(cd ../.. && pwd)
PY=${PYTHON:-$ROOT/.venv/bin/python}

need=()
[ -d /usr/lib/wasm32-wasi ] || need+=(wasi-libc)
command -v wasm-ld >/dev/null || [ -x /usr/lib/llvm-14/bin/wasm-ld ] || need+=(lld-14)
ls /usr/lib/llvm-14/lib/clang/*/lib/wasi/libclang_rt.builtins-wasm32.a >/dev/null 2>&1 || need+=(libclang-rt-14-dev-wasm32)
source "$ROOT/tests/apt_need.sh"
apt_need "${need[@]}" || exit 1

make -s -C "$ROOT/runtime_c" wasm
cp "$ROOT/runtime_c/build/wasm/mocodec.wasm" mocodec.wasm
[ -d node_modules ] || npm ci --no-audit --no-fund --silent

FIXTURES=${FIXTURES:-$(mktemp -d)}
[ -f "$FIXTURES/skipped.json" ] || "$PY" test/make_fixtures.py "$FIXTURES"
npx tsc -p test/tsconfig.json
MOCODEC_WEB_FIXTURES="$FIXTURES" node --test test/
