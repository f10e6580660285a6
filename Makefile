# mocodec: the two set-up commands of README.md, and what they stand on.
#   make demo   encode + decode the bundled sample clips through the C runtime, print ratio and error
#   make test   every test: C (gcc, clang, ASan/UBSan, fuzz smoke), Python, engine bindings, web
#   make web    rebuild what `mocodec view` ships: the wasm runtime and the viewer's bundle
# Both install what they need (a Python venv in .venv; clang and the engine tools from apt).

PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
FUZZ_SECONDS ?= 20

.PHONY: demo test web venv test-c test-python test-engines bench clean

$(VENV)/.installed: encoder/pyproject.toml bindings/python/pyproject.toml bindings/python/build_ffi.py $(wildcard runtime_c/src/*.c runtime_c/src/*.h runtime_c/include/*.h)
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

# The page's parts, in encoder/mocodec/view/static/ (committed: users need neither clang nor node).
VIEW_STATIC := encoder/mocodec/view/static
web:
	$(MAKE) -C runtime_c wasm
	install -m 644 runtime_c/build/wasm/mocodec.wasm $(VIEW_STATIC)/mocodec.wasm
	cd viewer && { [ -d node_modules ] || npm ci --no-audit --no-fund --silent; } && node build.mjs

bench: venv
	$(PY) bench/run_bench.py --codec rma --tolerances 0.02 0.1 0.5 1 2 3 6
	$(PY) bench/run_bench.py --codec spline --tolerances 0.02 0.1 0.5 1 2 3 6
	$(PY) bench/rd_plot.py

clean:
	rm -rf $(VENV) out runtime_c/build bench/results/*.mcd bench/results/sample_speed
