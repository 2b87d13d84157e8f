# Entry points (each target is one documented command; see README "## Robustness").
#   make test         build + whole pytest suite (C module and headless Blender)
#   make ci           what CI runs: test + fuzz smoke + sanitize (CI=true)
#   make sanitize     in-process tests against an ASan+UBSan+LSan build (tools/sanitize.sh)
#   make fuzz-smoke   each libFuzzer harness for FUZZ_SMOKE_SECONDS (default 10)
#   make fuzz         each harness to 10M executions or 1 h (tools/fuzz.sh full; long)
#   make soak         1000-frame C soak + 200-frame Blender soak (tools/soak*.py)
#   make bench        the benchmarks (bench/run_all.sh)
PYTHON ?= /usr/bin/python3
BLENDER ?= blender
FUZZ_SMOKE_SECONDS ?= 10

.PHONY: all build test ci sanitize fuzz-smoke fuzz soak bench clean

all: test

build:
	bash tools/build.sh

test:
	bash tools/run_tests.sh

ci:
	CI=true bash tools/run_tests.sh

sanitize:
	bash tools/sanitize.sh

fuzz-smoke:
	FUZZ_SMOKE_SECONDS=$(FUZZ_SMOKE_SECONDS) bash tools/fuzz.sh smoke

fuzz:
	bash tools/fuzz.sh full

soak:
	bash tools/install_deps.sh soak
	bash tools/build.sh
	$(PYTHON) -m tools.soak --frames 1000
	$(PYTHON) -m tools.soak --frames 1000 --budget 300 --max-pixel-error 0.5
	PLANET_LOD_NATIVE=$(CURDIR) PYTHONPATH=$(CURDIR) $(BLENDER) -b --factory-startup --python-exit-code 1 \
	    --python tools/soak_blender.py -- --frames 200

bench: build
	bash bench/run_all.sh

clean:
	rm -rf build fuzz/build fuzz/build-nocmp planetlod*.so planetlod/_native*.so
