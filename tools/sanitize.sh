#!/usr/bin/env bash
# Builds planetlod with ASan+UBSan (PLANETLOD_SANITIZE=1) into build/sanitize/
# and runs the suite's in-process tests against that build with zero tolerance:
# any AddressSanitizer, UndefinedBehaviorSanitizer or LeakSanitizer report
# fails the run.
#
#   bash tools/sanitize.sh                # the in-process tests
#   bash tools/sanitize.sh tests/test_projection.py -x  # args replace "tests"
#
# How: Debian's python3 is not instrumented, so libasan (gcc's, the one the
# extension is linked against) is LD_PRELOADed into the interpreter; libubsan
# comes in as a dependency of the extension.  A small driver imports the
# sanitized module first (so conftest's `import planetlod` gets it, not an
# in-place build), then drops LD_PRELOAD from its environment so that child
# processes (Blender in the add-on tests) run uninstrumented.
# Leaks: LeakSanitizer stays on.  tools/lsan.supp suppresses only what
# CPython and OpenImageIO keep for the process lifetime (matched on the
# allocating frames of the interpreter / OIIO's static state), so a block
# malloc'ed by our code and never freed is still reported.
# The C unit tests (tests/c, run_c_test) are built with -fsanitize=address,
# undefined here, so they run instrumented too.
# Tests that only drive other processes (Blender, Wine, the OpenJD runtime,
# the benchmark and soak scripts, the SIMD-path rebuilds) load no sanitized
# code and are left out unless named.
# SANITIZE_REUSE_BUILD=1: the checkout's module is already built and is not
# rebuilt (the test command runs this beside the UI tests, which must not see
# it replaced).
# Output is kept in build/sanitize/sanitize.log (pytest runs with
# --capture=sys so reports written to fd 2 by a dying test are not lost);
# any sanitizer report, or a pytest failure, fails the script.
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$PWD
PYTHON=${PYTHON:-/usr/bin/python3}
BUILD=$ROOT/build/sanitize
LOG=$BUILD/sanitize.log

bash tools/install_deps.sh sanitize
# The uninstrumented in-place build too: tests that spawn python/blender
# subprocesses import that one.
if [ "${SANITIZE_REUSE_BUILD:-}" != 1 ]; then
    bash tools/build.sh
fi

echo "sanitize: building ASan+UBSan extension into $BUILD/lib"
PLANETLOD_SANITIZE=1 "$PYTHON" setup.py -q build_ext --force \
    --build-lib "$BUILD/lib" --build-temp "$BUILD/tmp"
# the package's Python modules beside the sanitized module (build_ext builds
# only the extension)
cp planetlod/*.py "$BUILD/lib/planetlod/"

LIBASAN=$(gcc -print-file-name=libasan.so)
[ -e "$LIBASAN" ] || { echo "sanitize: libasan not found (gcc $(gcc -dumpversion))" >&2; exit 2; }
# libstdc++ must be loaded when ASan initialises: its __cxa_throw
# interceptor resolves the real one then, and python3 itself does not link
# libstdc++ (OpenImageIO throws internally; without this ASan CHECK-fails).
LIBSTDCXX=$(g++ -print-file-name=libstdc++.so)

mkdir -p "$BUILD"
# allocator_may_return_null: absurd sizes must reach our NULL checks (the
# product's contract) instead of aborting inside ASan.
export ASAN_OPTIONS="detect_leaks=1:allocator_may_return_null=1:abort_on_error=0:\
halt_on_error=1:strict_string_checks=1:detect_stack_use_after_return=1:\
check_initialization_order=1:malloc_context_size=2"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1"
export LSAN_OPTIONS="suppressions=$ROOT/tools/lsan.supp:print_suppressions=0"
export PYTHONFAULTHANDLER=1

# Blender subprocesses load the uninstrumented in-place build whatever runs
# them, so one Blender (Debian's) is enough here; run_tests.sh covers the rest.
export PLANET_LOD_BLENDERS=${PLANET_LOD_BLENDERS:-blender}

set +e -o pipefail
# -P: no working directory on sys.path, so the sanitized package (first on
# PYTHONPATH) is the one imported, not the checkout's.
(LD_PRELOAD="$LIBASAN $LIBSTDCXX" PYTHONPATH="$BUILD/lib" "$PYTHON" -P - "$BUILD/lib" "$@" <<'PY'
import os
import sys

build_lib = sys.argv[1]
import planetlod  # noqa: E402  the sanitized build, cached for conftest

native = planetlod.require_native().__file__
if not os.path.realpath(native).startswith(os.path.realpath(build_lib)):
    sys.exit(f"sanitize: imported {native}, not the sanitized build")
print(f"sanitize: testing {native}", flush=True)
os.environ.pop("LD_PRELOAD", None)  # children run uninstrumented
os.environ.pop("PYTHONPATH", None)  # and import the checkout's build

import pytest  # noqa: E402

IN_OTHER_PROCESSES = ["test_batch.py", "test_bench_smoke.py", "test_blender.py",
                      "test_cpu_paths.py", "test_farm.py", "test_ground_relief.py",
                      "test_openjd.py", "test_soak.py", "test_ui.py", "test_wheels.py"]
os.environ["PLANETLOD_SANITIZER"] = "1"  # conftest.UNDER_SANITIZER
default = ["tests"] + [f"--ignore=tests/{name}" for name in IN_OTHER_PROCESSES]
sys.exit(pytest.main(["-q", "-p", "no:cacheprovider", "--capture=sys", "--durations=25"] + (sys.argv[2:] or default)))
PY
) 2>&1 | tee "$LOG"
status=${PIPESTATUS[0]}
set -e

reports=$(grep -cE "ERROR: (AddressSanitizer|LeakSanitizer)|Sanitizer: CHECK failed|runtime error:|SUMMARY: (Address|UndefinedBehavior|Leak)Sanitizer" "$LOG" || true)
if [ "$reports" -ne 0 ]; then
    echo "sanitize: FAILED: $reports sanitizer report line(s), see $LOG (pytest exit $status)" >&2
    exit 1
fi
if [ "$status" -ne 0 ]; then
    echo "sanitize: FAILED: pytest exit $status, no sanitizer report" >&2
    exit "$status"
fi
echo "sanitize: OK: pytest passed under ASan+UBSan+LSan, zero reports"
