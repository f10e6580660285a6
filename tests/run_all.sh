#!/usr/bin/env bash
# Every test of the project, as `make test` and CI run it. Installs the system tools it needs
# (clang for the second compiler, sanitizers and libFuzzer) when they are missing and it can.
set -euo pipefail
cd "$(dirname "$0")/.."

need_apt=()
command -v clang >/dev/null || need_apt+=(clang)
[ -n "$(ls /usr/lib/llvm-*/lib/clang/*/lib/linux/libclang_rt.fuzzer-x86_64.a 2>/dev/null)" ] || need_apt+=(libclang-rt-14-dev)
source tests/apt_need.sh
apt_need "${need_apt[@]}" || exit 1

failed=0
step() { echo; echo "== $*"; }

step "C runtime: gcc, clang, ASan+UBSan, header as C99 and C++, no allocation"
make -s -C runtime_c test || failed=1

step "C runtime: fuzz smoke (${FUZZ_SECONDS:-20} s each target)"
make -s -C runtime_c fuzz FUZZ_SECONDS="${FUZZ_SECONDS:-20}" || failed=1

step "C runtime on every platform here: Linux x86-64, aarch64 (qemu), s390x big-endian (qemu), Windows x86-64 (wine); CMake package and consumers"
make -s -C runtime_c platforms || failed=1

step "Python: encoder, binding, CLI, cross-checks with the C runtime"
.venv/bin/python -m pytest -q -ra tests || failed=1

step "Web: the runtime in wasm (node tests against the native runtime), the viewer in headless Chromium"
web_fixtures=$(mktemp -d)
FIXTURES="$web_fixtures" bindings/web/run_tests.sh || failed=1
FIXTURES="$web_fixtures" viewer/run_tests.sh || failed=1
rm -rf "$web_fixtures"

if [ -x bindings/run_engine_tests.sh ]; then
  step "Engine bindings: C# (mono NUnit), Godot 3 headless, GDExtension build"
  bindings/run_engine_tests.sh || failed=1
fi

echo
if [ "$failed" = 0 ]; then echo "all test suites passed"; else echo "SOME TEST SUITES FAILED"; fi
exit "$failed"
