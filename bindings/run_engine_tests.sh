#!/usr/bin/env bash
# Everything about the engine bindings that can run on this machine, in one command:
#   csharp   the C# P/Invoke core + the Unity package's NUnit tests, mono + nunit-console 2.6
#   unity    the package's UnityEngine/UnityEditor code parsed by mcs; the UPM tarball packed
#            from the package as committed (pack.py refuses it without its .meta files and plugins)
#   native   runtime_c's CMake preset linux-x86_64, the engine plugin build (runtime_c/test_platforms.sh
#            builds and runs the cross-built ones: Linux aarch64, Windows x86-64)
#   godot3   the GDNative binding tested in the real headless engine, godot3-server 3.2.3
#   godot4   the GDExtension built (gcc, clang) and driven by a stand-in host
# Installs the Debian packages and fetches the crates it needs when they are missing (quietly
# when they are there). Ends with "engines: N passed, N failed, N skipped"; exits non-zero when
# anything failed. A part is skipped only when its tool cannot be installed, and says so.
set -uo pipefail
HERE="$(cd "$(dirname "$0")" && pwd)"
source "$HERE/common.sh"
mkdir -p "$MCD_BUILD"

APT_PACKAGES=(mono-devel nunit-console libnunit-cil-dev godot3-server)
missing=()
for p in "${APT_PACKAGES[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
    if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
        echo "engines: installing ${missing[*]}"
        export DEBIAN_FRONTEND=noninteractive
        # The lock: tests/apt_need.sh.
        flock /tmp/mocodec-apt.lock sh -c 'apt-get update -qq && apt-get install -y -qq --no-install-recommends "$@"' \
            apt "${missing[@]}" > "$MCD_BUILD/apt.log" 2>&1 || { echo "engines: apt-get install failed, see $MCD_BUILD/apt.log"; tail -n 20 "$MCD_BUILD/apt.log"; }
    else
        echo "engines: missing ${missing[*]} and cannot install them (not root or no apt-get)"
    fi
fi

total_passed=0 total_failed=0 total_skipped=0
declare -a summary

# run NAME COMMAND...: runs one part, keeps its log, adds up its "NAME: N passed, N failed" line.
run() {
    local name="$1" log="$MCD_BUILD/$1.log" rc line p f s
    shift
    echo "=== $name: $*"
    "$@" > "$log" 2>&1
    rc=$?
    grep -E "FAIL|error|Error|skipped:|ran |built |compiles |unity package" "$log" | grep -v "engine error print" | tail -n 40
    line="$(grep -E "^$name: [0-9]+ passed, [0-9]+ failed" "$log" | tail -n 1)"
    if [ -z "$line" ]; then
        tail -n 30 "$log"
        line="$name: 0 passed, 1 failed"
    elif [ $rc -ne 0 ] && echo "$line" | grep -q " 0 failed"; then
        line="$name: $(echo "$line" | awk '{ print $2 }') passed, 1 failed (exit $rc)"
    fi
    p="$(echo "$line" | awk '{ print $2 }')"
    f="$(echo "$line" | awk '{ print $4 }' | tr -d ',')"
    s="$(echo "$line" | sed -n 's/.* \([0-9]*\) skipped.*/\1/p')"
    total_passed=$((total_passed + p))
    total_failed=$((total_failed + f))
    total_skipped=$((total_skipped + ${s:-0}))
    summary+=("$line")
    echo "$line"
}

skip() {
    echo "=== $1: SKIPPED: $2"
    echo "!!! $1 SKIPPED: $2"
    summary+=("$1: SKIPPED ($2)")
    total_skipped=$((total_skipped + 1))
}

have() { command -v "$1" >/dev/null; }

# The encoder writes the test assets; without it nothing below is meaningful.
if ! PYTHONPATH="$MCD_REPO/encoder" "$(mcd_python)" -c "import mocodec_runtime, mocodec.encode" 2>/dev/null; then
    echo "engines: the encoder (mocodec + mocodec_runtime) is not importable by $(mcd_python); install the dev environment first"
    echo "engines: 0 passed, 1 failed"
    exit 1
fi
# Encode the test assets once; every part copies them.
rm -rf "$MCD_BUILD/test_data"
if ! mcd_test_data "$MCD_BUILD/test_data"; then
    echo "engines: the encoder failed to make the test assets"
    echo "engines: 0 passed, 1 failed"
    exit 1
fi
export MCD_ENGINE_TEST_DATA="$MCD_BUILD/test_data"

if have mcs && have mono && have nunit-console; then
    run csharp "$HERE/csharp/run_tests.sh"
else
    skip csharp "mono-devel / nunit-console not installable here"
fi

unity_check() {
    local passed=0 failed=0
    if mcs --parse "$MCD_REPO"/unity_package/Runtime/Unity/*.cs "$MCD_REPO"/unity_package/Editor/*.cs \
            "$MCD_REPO"/unity_package/Samples~/*/*.cs; then
        echo "unity: UnityEngine/UnityEditor code and the sample parsed by mcs (compiled only inside Unity)"
        passed=$((passed + 1))
    else
        failed=$((failed + 1))
    fi
    # The package as committed (plugins, .meta files), with the test assets for the Test Runner.
    mcd_test_data "$MCD_BUILD/unity_data" &&
        python3 "$MCD_REPO/unity_package/Tools~/pack.py" "$MCD_BUILD" --test-data "$MCD_BUILD/unity_data" &&
        passed=$((passed + 1)) || failed=$((failed + 1))
    echo "unity: $passed passed, $failed failed"
    [ $failed = 0 ]
}
if have mcs; then run unity unity_check; else skip unity "mcs not installable here"; fi

native_check() {
    local build="$MCD_RUNTIME/build/cmake/linux-x86_64"
    cmake -S "$MCD_RUNTIME" --preset linux-x86_64 > /dev/null &&
        cmake --build "$build" -- -s > /dev/null &&
        ctest --test-dir "$build" -R '^library_exports$' --no-tests=error --output-on-failure &&
        echo "native: built preset linux-x86_64 (libmocodec.so exports exactly the mcd_ API)" &&
        echo "native: 1 passed, 0 failed" && return 0
    echo "native: 0 passed, 1 failed"
    return 1
}
if have cmake; then run native native_check; else skip native "cmake not installed"; fi

if have cargo; then
    if have godot3-server; then
        run godot3 "$HERE/godot/godot3/run_tests.sh"
    else
        skip godot3 "godot3-server not installable here"
    fi
    run godot4 "$HERE/godot/godot4/run_tests.sh"
else
    skip godot3 "cargo (for the gdnative-sys headers) not found"
    skip godot4 "cargo (for the gdextension-api header) not found"
fi

echo "=== summary"
for line in "${summary[@]}"; do echo "  $line"; done
echo "engines: $total_passed passed, $total_failed failed, $total_skipped skipped"
[ "$total_failed" = 0 ]
