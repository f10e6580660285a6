# Sourced by the engine build/test scripts: where things are, and the two inputs they share
# (the runtime as a shared library, the encoder-made test assets).
# shellcheck shell=bash

MCD_REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
# MCD_RUNTIME_DIR builds the bindings against another copy of runtime_c (e.g. one without a codec
# that does not compile yet); the default is the repository's.
MCD_RUNTIME="${MCD_RUNTIME_DIR:-$MCD_REPO/runtime_c}"
MCD_BUILD="$MCD_REPO/bindings/build"

# The encoder's Python: the dev venv when there is one, else whatever python3 has it installed.
mcd_python() {
    if [ -x "$MCD_REPO/.venv/bin/python" ]; then
        echo "$MCD_REPO/.venv/bin/python"
    else
        command -v python3
    fi
}

# Builds runtime_c as a shared library and prints its path. Uses the runtime's own Makefile
# target when it has one, so there is one set of flags.
mcd_shared_lib() {
    if grep -q '^shared:' "$MCD_RUNTIME/Makefile" 2>/dev/null; then
        make -s -C "$MCD_RUNTIME" shared >&2 || return 1
        echo "$MCD_RUNTIME/build/libmocodec.so"
    else
        mkdir -p "$MCD_BUILD/native"
        ${CC:-cc} -std=c99 -O2 -fPIC -shared -DMCD_BUILD_SHARED -fvisibility=hidden \
            -I"$MCD_RUNTIME/include" "$MCD_RUNTIME"/src/*.c -o "$MCD_BUILD/native/libmocodec.so" -lm || return 1
        echo "$MCD_BUILD/native/libmocodec.so"
    fi
}

# Writes the golden vectors and fresh encoder output with reference poses into $1. When
# MCD_ENGINE_TEST_DATA names a folder already made this way (run_engine_tests.sh makes it
# once for all parts), copies that instead of encoding again.
mcd_test_data() {
    local out="$1" py
    if [ -n "${MCD_ENGINE_TEST_DATA:-}" ] && [ -d "$MCD_ENGINE_TEST_DATA" ]; then
        mkdir -p "$out" && cp "$MCD_ENGINE_TEST_DATA"/* "$out"/
        return
    fi
    py="$(mcd_python)"
    PYTHONPATH="$MCD_REPO/encoder${PYTHONPATH:+:$PYTHONPATH}" "$py" "$MCD_REPO/bindings/make_engine_test_data.py" "$out"
}
