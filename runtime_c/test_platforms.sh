#!/usr/bin/env bash
# The runtime on every platform this Linux x86-64 machine can build and run: each CMake preset
# below is configured, built, tested with ctest (the C test suite, the consumer projects built
# against the installed tree, the shared library's exports) and, when it passed, installed into
# build/platforms/<preset>/, where the engine packaging picks the libraries up.
#
#   linux-x86_64     native gcc
#   linux-aarch64    gcc-aarch64-linux-gnu, run under qemu-aarch64
#   linux-s390x      gcc-s390x-linux-gnu, run under qemu-s390x: big-endian (and FLT_EVAL_METHOD 1)
#   windows-x86_64   MinGW-w64 (posix threads), run under wine
#
#   runtime_c/test_platforms.sh [preset ...]     (make -C runtime_c platforms)
#
# Missing tools are installed from apt when run as root; a platform whose tools cannot be had is
# reported SKIPPED, loudly, and does not count as passed. The suite runs with MCD_TEST_QUICK=1
# everywhere (damage sweeps shortened): under emulation the full sweeps would take an hour, and
# natively make test's gcc, clang and ASan runs already sweep every byte. Logs: build/platforms/logs/.
set -uo pipefail
cd "$(dirname "$0")"
ALL=(linux-x86_64 linux-aarch64 linux-s390x windows-x86_64)
if [ $# -gt 0 ]; then PRESETS=("$@"); else PRESETS=("${ALL[@]}"); fi
LOGS=build/platforms/logs
mkdir -p "$LOGS"
export MCD_TEST_QUICK=1
export WINEPREFIX="$PWD/build/wine" WINEDEBUG=-all WINEDLLOVERRIDES="mscoree,mshtml="

# tools PRESET: "program:apt-package ..." that the preset needs.
tools() {
    case "$1" in
        linux-x86_64) echo "cmake:cmake cc:gcc pkg-config:pkgconf" ;;
        linux-aarch64) echo "cmake:cmake aarch64-linux-gnu-gcc:gcc-aarch64-linux-gnu /usr/aarch64-linux-gnu/lib/libc.so:libc6-dev-arm64-cross qemu-aarch64:qemu-user pkg-config:pkgconf" ;;
        linux-s390x) echo "cmake:cmake s390x-linux-gnu-gcc:gcc-s390x-linux-gnu /usr/s390x-linux-gnu/lib/libc.so:libc6-dev-s390x-cross qemu-s390x:qemu-user pkg-config:pkgconf" ;;
        windows-x86_64) echo "cmake:cmake x86_64-w64-mingw32-gcc-posix:gcc-mingw-w64-x86-64-posix wine64:wine64 pkg-config:pkgconf" ;;
        *) return 1 ;;
    esac
}

# have PROGRAM-OR-PATH: wine64 lives outside PATH on Debian (/usr/lib/wine).
have() {
    case "$1" in
        /*) [ -e "$1" ] ;;
        wine64) command -v wine64 >/dev/null || [ -x /usr/lib/wine/wine64 ] || command -v wine >/dev/null ;;
        *) command -v "$1" >/dev/null ;;
    esac
}

missing_tools() {
    local t
    for t in $(tools "$1"); do have "${t%%:*}" || echo "$t"; done
}

for p in "${PRESETS[@]}"; do
    tools "$p" >/dev/null || { echo "platforms: unknown preset $p (known: ${ALL[*]})"; exit 2; }
done

# One apt-get for everything missing.
need=()
for p in "${PRESETS[@]}"; do
    for t in $(missing_tools "$p"); do need+=("${t#*:}"); done
done
if [ ${#need[@]} -gt 0 ]; then
    mapfile -t need < <(printf '%s\n' "${need[@]}" | sort -u)
    if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
        echo "platforms: installing ${need[*]} (apt)"
        # The lock: tests/apt_need.sh.
        flock /tmp/mocodec-apt.lock sh -c 'apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "$@"' \
            apt "${need[@]}" > "$LOGS/apt.log" 2>&1 || { echo "platforms: apt-get failed, see runtime_c/$LOGS/apt.log"; tail -n 5 "$LOGS/apt.log"; }
    else
        echo "platforms: missing ${need[*]} and cannot install them (not root or no apt-get)"
    fi
fi

passed=() failed=() skipped=()
# run_preset PRESET: configure, build, ctest, install; prints what it ran and one verdict line.
run_preset() {
    local p="$1" log="$LOGS/$1.log" start=$SECONDS miss suite consumer consumers
    miss="$(missing_tools "$p" | cut -d: -f1 | paste -sd ' ' -)"
    if [ -n "$miss" ]; then
        echo "!!! $p SKIPPED: not installed and not installable here: $miss"
        skipped+=("$p (no $miss)")
        return
    fi
    case "$p" in
        linux-aarch64|linux-s390x) echo "== $p: under ${p/linux-/qemu-}: sweeps shortened" ;;
        windows-x86_64) echo "== $p: under wine ($(wine64 --version 2>/dev/null || /usr/lib/wine/wine64 --version 2>/dev/null)): sweeps shortened" ;;
        *) echo "== $p: native: sweeps shortened (make test's gcc, clang and ASan runs sweep every byte)" ;;
    esac
    rm -rf "build/platforms/$p"
    if ! { cmake --preset "$p" && cmake --build --preset "$p" -j 2; } > "$log" 2>&1; then
        grep -E "error|Error" "$log" | head -n 20
        echo "$p: FAILED to build (runtime_c/$log), $((SECONDS - start)) s"
        failed+=("$p (build)")
        return
    fi
    ctest --preset "$p" --verbose >> "$log" 2>&1
    local rc=$?
    # The suite's summary lines (one per CTest test natively, one under an emulator), added up.
    suite="$(sed -n 's/^\([0-9]*: \)\{0,1\}\([0-9]*\) passed, \([0-9]*\) failed\(, \([0-9]*\) skipped\)\{0,1\}$/\2 \3 \5/p' "$log" |
             awk '{ p += $1; f += $2; s += $3; n++ } END { if (n) printf "%d passed, %d failed, %d skipped", p, f, s }')"
    # What failed: the suite's test lines and failed checks (file.c:line), crashes, the
    # consumer's failed checks.
    grep -E "^([0-9]+: )?[a-z0-9_]+ +(FAILED|skipped)|\.c:[0-9]+: |uncaught target signal|^[0-9]+: consumer: .*FAILED" "$log" |
        sed -E 's/^[0-9]+: +//' | sort -u | sed 's/^/   /' | head -n 30
    consumer="$(grep -cE "Test +#[0-9]+: consumer_[a-z_]+ .*Passed" "$log")"
    consumers="$(grep -cE "Test +#[0-9]+: consumer_[a-z_]+ " "$log")"
    grep -E "Test +#[0-9]+: .*(\*\*\*|Failed|Not Run|Skipped)" "$log" | sed 's/^/   /'
    grep -E "^[0-9]+: consumer: SKIPPED|^[0-9]+: exports: " "$log" | sed 's/^[0-9]*: /   /' | sort -u
    echo "   C test suite: ${suite:-no summary line}; consumer tests passed: $consumer of $consumers"
    if [ $rc -ne 0 ]; then
        echo "$p: FAILED (runtime_c/$log), $((SECONDS - start)) s"
        failed+=("$p")
        return
    fi
    # Stripped: these are the files the engine packages ship.
    if ! cmake --install "build/cmake/$p" --strip >> "$log" 2>&1; then
        echo "$p: FAILED to install (runtime_c/$log)"
        failed+=("$p (install)")
        return
    fi
    echo "   installed: runtime_c/build/platforms/$p/ ($(cd "build/platforms/$p" && find lib bin -maxdepth 1 \( -name '*.so' -o -name '*.dll' -o -name '*.a' \) 2>/dev/null | sort | paste -sd ' ' -))"
    echo "$p: passed, $((SECONDS - start)) s"
    passed+=("$p")
}

total=$SECONDS
for p in "${PRESETS[@]}"; do run_preset "$p"; done

echo "== platforms, $((SECONDS - total)) s: ${#passed[@]} passed, ${#failed[@]} failed, ${#skipped[@]} skipped"
[ ${#passed[@]} -gt 0 ] && echo "   passed: ${passed[*]}"
[ ${#failed[@]} -gt 0 ] && echo "   FAILED: ${failed[*]}"
for s in "${skipped[@]}"; do echo "!!! SKIPPED: $s"; done
[ ${#failed[@]} -eq 0 ]
