# mocodec: the two set-up commands of README.md, and what they stand on.
#   make demo   encode + decode the bundled sample clips through the C runtime, print ratio and error
#   make test   every test: C (gcc, clang, ASan/UBSan, fuzz smoke), Python, engine bindings, web
#   make fuzz   every fuzz target for FUZZ_SECONDS each: the C runtime's (make -C runtime_c fuzz)
#               and the BVH and glTF readers' (make fuzz-readers, atheris; tests/fuzz_readers.py)
#   make web    rebuild what `mocodec view` ships: the wasm runtime and the viewer's bundle
#   make bench  every codec beside ACL 2.1 in one process: bytes, engine bytes, open, µs per pose
#               (bench/engine_bench.py; BENCH_ASSETS="rma:1,0.02 spline:1" ROUNDS=11 SHARED=../shared),
#               then make bench-bake
#   make bench-bake  baking: MB/s per core per codec, 1 and 2 workers (local, Dask LocalCluster),
#               --cache re-bake, peak memory of a 2,000-clip library (bench/bake.py; BAKE_ARGS="--fast")
#   make unity-plugins  rebuild and test the runtime for Linux x86-64, Linux arm64 and Windows
#               x86-64 (make -C runtime_c platforms) and copy them into unity_package/Plugins, to commit
#   make bench-rd  the rate-distortion sweeps of rma and spline, and docs/rd_curve.png
# demo and test install what they need (a Python venv in .venv; clang and the engine tools from apt);
# bench also needs a C++17 compiler.

PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
FUZZ_SECONDS ?= 20
# bench: codec:tolerances (cm) to measure, timed rounds, and where the dev clips and ACL live
BENCH_ASSETS ?= rma:1,0.02 spline:1 fk-wavelet:1 ik-predict:1 neural:1
ROUNDS ?= 11
SHARED ?= ../shared
# bench-bake: bench/bake.py's arguments (--fast: a few clips, a 40-clip library, to try it out)
BAKE_ARGS ?= --clips 12 --codec-clips 3 --clip-seconds 1

.PHONY: demo test fuzz fuzz-readers web unity-plugins venv test-c test-python test-engines bench bench-bake bench-rd clean

$(VENV)/.installed: encoder/pyproject.toml encoder/build_native.py $(wildcard encoder/native/*.c encoder/native/*.h) bindings/python/pyproject.toml bindings/python/build_ffi.py $(wildcard runtime_c/src/*.c runtime_c/src/*.h runtime_c/include/*.h)
	@test -x $(PY) || $(PYTHON) -m venv $(VENV)
	@$(PY) -m pip install -q --upgrade pip
	@$(PY) -m pip install -q ./bindings/python
	@$(PY) -m pip install -q -e './encoder[test]'
	@touch $@

venv: $(VENV)/.installed

demo: venv
	$(VENV)/bin/mocodec demo -o out/demo

test: venv
	@bash tests/run_all.sh

fuzz: venv
	$(MAKE) -C runtime_c fuzz FUZZ_SECONDS=$(FUZZ_SECONDS)
	$(MAKE) fuzz-readers

# Corpora grow in runtime_c/build/fuzz_corpus/<reader>, crashes land in runtime_c/build/fuzz_artifacts
# (beside the C targets'). 10 s and 1,024 MB per input: tests/test_malformed_inputs.py's limits.
# A run is cut into runs of at most READER_CHUNK seconds on the one corpus: under atheris 3.0 the
# process grows by about 3.5 KB per input (the same parses outside the fuzzer hold steady), so one
# long run would reach the memory limit in minutes without any input being at fault.
READER_FUZZ := runtime_c/build/fuzz_corpus
READER_CHUNK ?= 60
fuzz-readers: venv
	@mkdir -p runtime_c/build/fuzz_artifacts
	@for r in bvh gltf; do \
	  $(PY) tests/fuzz_readers.py $$r --write-seeds $(READER_FUZZ)/reader_$$r || exit 1; \
	  left=$(FUZZ_SECONDS); \
	  while [ "$$left" -gt 0 ]; do \
	    t=$$left; [ "$$t" -le $(READER_CHUNK) ] || t=$(READER_CHUNK); \
	    $(PY) tests/fuzz_readers.py $$r -max_total_time=$$t -timeout=10 -rss_limit_mb=1024 \
	      -print_final_stats=1 -artifact_prefix=runtime_c/build/fuzz_artifacts/reader_$$r- \
	      $(READER_FUZZ)/reader_$$r || exit 1; \
	    left=$$((left - t)); \
	  done; \
	done

# The page's parts, in encoder/mocodec/view/static/ (committed: users need neither clang nor node).
VIEW_STATIC := encoder/mocodec/view/static
web:
	$(MAKE) -C runtime_c wasm
	install -m 644 runtime_c/build/wasm/mocodec.wasm $(VIEW_STATIC)/mocodec.wasm
	cd viewer && { [ -d node_modules ] || npm ci --no-audit --no-fund --silent; } && node build.mjs

# The Unity package ships these (a git-URL install has no build step); tests/test_unity_package.py
# fails when they are missing or older than runtime_c/.
unity-plugins:
	$(MAKE) -C runtime_c platforms PLATFORMS="linux-x86_64 linux-aarch64 windows-x86_64"
	python3 unity_package/Tools~/update_plugins.py

# Encodes (cached in bench/results/assets/), builds and runs the driver; the timed part holds
# flock /tmp/mocodec-bench.lock. Writes bench/results/engine_bench/<UTC time>.md and .json.
bench: venv
	MOCODEC_SHARED=$(SHARED) $(PY) bench/engine_bench.py --assets $(BENCH_ASSETS) --rounds $(ROUNDS)
	$(MAKE) bench-bake

# Each timed part holds flock /tmp/mocodec-bench.lock; writes bench/results/bake/<UTC time>.json.
bench-bake: venv
	@mkdir -p bench/results/bake
	MOCODEC_SHARED=$(SHARED) nice -n 10 $(PY) bench/bake.py $(BAKE_ARGS) --json bench/results/bake/$$(date -u +%Y%m%dT%H%MZ).json

bench-rd: venv
	$(PY) bench/run_bench.py --codec rma --tolerances 0.02 0.1 0.5 1 2 3 6
	$(PY) bench/run_bench.py --codec spline --tolerances 0.02 0.1 0.5 1 2 3 6
	$(PY) bench/rd_plot.py

clean:
	rm -rf $(VENV) out runtime_c/build bench/results/*.mcd bench/results/build
