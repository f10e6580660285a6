#!/usr/bin/env bash
# Every test of the project, as `make test` and CI run it. Installs the system tools it needs
# (clang for the second compiler, sanitizers and libFuzzer) when they are missing and it can.
#
# The steps are jobs for two workers, one per core of the 2-core machines this project runs on:
# each worker takes the next job of the list when its last one ends, the longest jobs first.
# The C objects and binaries are built first, in one make, so no two makes write into
# runtime_c/build at once; the engine bindings wait for the platforms step, whose CMake
# linux-x86_64 folder they build in. Each step's output is printed whole when it ends (two
# steps' lines never interleave), then its verdict, wall and CPU time and the load average.
#   PYTEST_WORKERS=N   pytest-xdist workers (default 2; 0 runs pytest in one process)
set -euo pipefail
cd "$(dirname "$0")/.."

need_apt=()
command -v clang >/dev/null || need_apt+=(clang)
[ -n "$(ls /usr/lib/llvm-*/lib/clang/*/lib/linux/libclang_rt.fuzzer-x86_64.a 2>/dev/null)" ] || need_apt+=(libclang-rt-14-dev)
source tests/apt_need.sh
apt_need "${need_apt[@]}" || exit 1

LOGS=$(mktemp -d)
trap 'rm -rf "$LOGS"' EXIT
ALL_START=$SECONDS
touch "$LOGS/times" "$LOGS/failed"

# cpu_of FILE: the CPU seconds (user + system) of a shell's finished children, from what `times`
# wrote into FILE. `times` itself must run in the shell in question, not in a $(...) subshell.
cpu_of() {
  awk 'NR == 2 { for (i = 1; i <= 2; i++) { split($i, t, "m"); s += t[1] * 60 + t[2] } } END { printf "%.0f", s }' "$1"
}

# step TITLE COMMAND...: runs one step with its output kept, then prints it under the print lock
# with its wall time and CPU time (the CPU time does not grow with other work on the machine).
step() {
  local title="$1" log start=$SECONDS cpu rc=0 verdict wall
  shift
  log=$(mktemp "$LOGS/step.XXXXXX")
  times > "$log.times"
  cpu=$(cpu_of "$log.times")
  echo "-- started: $title" >&2
  "$@" > "$log" 2>&1 || rc=$?
  times > "$log.times"
  cpu=$(( $(cpu_of "$log.times") - cpu ))
  wall=$((SECONDS - start))
  if [ "$rc" = 0 ]; then verdict=passed; else verdict="FAILED (exit $rc)"; echo "$title" >> "$LOGS/failed"; fi
  printf '%5d s %5d s  %s  %s\n' "$wall" "$cpu" "$verdict" "$title" >> "$LOGS/times"
  {
    flock 9
    echo
    echo "== $title"
    cat "$log"
    echo "== $verdict, $wall s, CPU $cpu s (load average $(cut -d' ' -f1-3 /proc/loadavg)): $title"
  } 9> "$LOGS/print.lock"
}

pytest_args=(-q -ra)
if [ "${PYTEST_WORKERS:-2}" != 0 ]; then
  # loadfile: a test file's module fixtures (the expensive encodes) are made once, on one worker.
  pytest_args+=(-n "${PYTEST_WORKERS:-2}" --dist loadfile)
fi

web_tests() {
  local fixtures rc=0
  fixtures=$(mktemp -d "$LOGS/web.XXXXXX")
  FIXTURES="$fixtures" bindings/web/run_tests.sh || rc=1
  FIXTURES="$fixtures" viewer/run_tests.sh || rc=1
  return "$rc"
}

job_c_gcc() {
  step "C runtime, gcc: header as C99 and C++, warnings at -O1 ... -Os, no allocation, the test suite" \
    make -s -C runtime_c check-header check-warnings check-no-alloc run-tests-gcc
}
job_c_clang() { step "C runtime, clang: the test suite" make -s -C runtime_c run-tests-clang; }
job_c_asan() { step "C runtime, clang ASan+UBSan: the test suite" make -s -C runtime_c run-tests-asan; }
# 8 runtime targets and 2 reader targets at FUZZ_SECONDS (20 s) each: about 3.5 minutes.
job_fuzz() {
  step "C runtime: fuzz smoke (${FUZZ_SECONDS:-20} s each target)" make -s -C runtime_c fuzz FUZZ_SECONDS="${FUZZ_SECONDS:-20}"
  step "BVH and glTF readers: fuzz smoke (${FUZZ_SECONDS:-20} s each)" make -s fuzz-readers FUZZ_SECONDS="${FUZZ_SECONDS:-20}"
}
job_platforms() {
  step "C runtime on every platform here: Linux x86-64, aarch64 (qemu), s390x big-endian (qemu), Windows x86-64 (wine); CMake package and consumers" \
    make -s -C runtime_c platforms
  touch "$LOGS/platforms.done"
}
job_engines() {
  [ -x bindings/run_engine_tests.sh ] || return 0
  # The platforms job was taken before this one (the list's order): this waits, never forever.
  while [ ! -e "$LOGS/platforms.done" ]; do sleep 2; done
  step "Engine bindings: C# (mono NUnit), Godot 3 headless, GDExtension build" bindings/run_engine_tests.sh
}
job_pytest() {
  step "Python: encoder, binding, CLI, cross-checks with the C runtime" .venv/bin/python -m pytest "${pytest_args[@]}" tests
}
job_web() {
  step "Web: the runtime in wasm (node tests against the native runtime), the viewer in headless Chromium" web_tests
}
# Longest first (their times are printed at the end of every run).
JOBS=(job_c_asan job_platforms job_c_gcc job_c_clang job_pytest job_engines job_web job_fuzz)

echo 0 > "$LOGS/next"
# next_job: the index of the next job not taken yet.
next_job() {
  {
    flock 8
    local n
    n=$(cat "$LOGS/next")
    echo $((n + 1)) > "$LOGS/next"
    echo "$n"
  } 8> "$LOGS/queue.lock"
}
worker() {
  local i
  while i=$(next_job) && [ "$i" -lt "${#JOBS[@]}" ]; do "${JOBS[$i]}"; done
}

step "C runtime: the test, fuzz and shared-library builds (make -j2 test-build)" make -s -C runtime_c -j2 test-build
worker &
w1=$!
worker &
w2=$!
# A worker that exits non-zero broke outside its steps (a step's failure is recorded, not raised).
wait "$w1" || echo "a test worker itself (exit $?)" >> "$LOGS/failed"
wait "$w2" || echo "a test worker itself (exit $?)" >> "$LOGS/failed"

times > "$LOGS/all.times"
echo
echo "== step times: wall, CPU (user + system), two steps at once; total wall $((SECONDS - ALL_START)) s, CPU $(cpu_of "$LOGS/all.times") s"
cat "$LOGS/times"
# The last line counts the steps, failures outside a step (a broken worker) among the failed.
steps_line="steps: $(awk '/ passed  / { n++ } END { print n + 0 }' "$LOGS/times") passed, $(wc -l < "$LOGS/failed") failed"
if [ -s "$LOGS/failed" ]; then
  echo "SOME TEST SUITES FAILED:"
  sed 's/^/  /' "$LOGS/failed"
  echo "$steps_line"
  exit 1
fi
echo "all test suites passed"
echo "$steps_line"
