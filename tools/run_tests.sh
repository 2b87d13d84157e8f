#!/usr/bin/env bash
# The README's test command: installs what is missing, builds, runs every test
# (pytest for the C module, then the headless Blender tests: the whole suite in
# Debian's Blender 3.4 and in the newest bpy wheel, 5.3; the smoke tests --
# install, add, render, farm split -- in 4.2, 4.5, 5.0, 5.1 and 5.2:
# tools/blender_versions.py, tests/test_blender.py).  pytest prints the time
# of each part (no Blender, each Blender) at its end.
# Arguments name tests to run instead of the suite.  The suite runs as two
# streams side by side (below).
# With CI=true (the CI runner, .ci/run) it also runs a short fuzz smoke
# (FUZZ_SMOKE_SECONDS, default 10 s per harness, ~1 min with the build) and the
# suite's in-process tests again under ASan+UBSan+LSan (tools/sanitize.sh).
set -euo pipefail
cd "$(dirname "$0")/.."
if [ "${CI:-}" = true ]; then
    bash tools/install_deps.sh ci
else
    bash tools/install_deps.sh tests
fi
start=$(date +%s)
bash tools/build.sh
echo "tests: build took $(( $(date +%s) - start )) s"
PYTHON=${PYTHON:-/usr/bin/python3}
# Blender 4.2 LTS, 4.5 LTS, 5.0 (CPython 3.11), 5.1, 5.2 LTS and 5.3 (CPython
# 3.13) as bpy wheels, each in a venv cached under ~/.cache/planetlod
# (downloaded on the first run only).
start=$(date +%s)
"$PYTHON" tools/blender_versions.py install
echo "tests: Blender versions ready ($(( $(date +%s) - start )) s): $("$PYTHON" tools/blender_versions.py list | cut -d' ' -f1 | tr '\n' ' ')"
# The Open Job Description runtime for the farm's job templates (tests/test_openjd.py)
"$PYTHON" -m tools.openjd_env install
if [ $# -gt 0 ]; then  # the tests named, in one pytest
    start=$(date +%s)
    "$PYTHON" -m pytest -q --durations=40 "$@"
    echo "tests: pytest took $(( $(date +%s) - start )) s"
    exit 0
fi
# Two streams side by side, each mostly one busy thread (Blender's Python,
# the UI's event waits, one C test at a time), of about equal length:
# 1. the headless Blender tests (every Blender version, the farm, the batch
#    renders, the OpenJD runtime), the wheels under Wine and the SIMD-path
#    rebuilds; then, under CI=true, the sanitizer pass;
# 2. the rest: the UI tests in Blender's real interface, the core's tests;
#    then, under CI=true, the fuzz smoke.
# The second stream's output is printed when both have ended.
FIRST=(tests/test_blender.py tests/test_farm.py tests/test_batch.py tests/test_ground_relief.py
       tests/test_openjd.py tests/test_wheels.py tests/test_cpu_paths.py)
logs=$(mktemp -d "${TMPDIR:-/tmp}/planetlod-tests.XXXXXX")
second_stream() {
    local start status=0
    start=$(date +%s)
    "$PYTHON" -m pytest -q --durations=30 --basetemp "$logs/rest-tmp" tests \
        "${FIRST[@]/#/--ignore=}" || status=1
    echo "tests: pytest (UI, core) took $(( $(date +%s) - start )) s"
    if [ "${CI:-}" = true ]; then
        start=$(date +%s)
        FUZZ_SMOKE_SECONDS=${FUZZ_SMOKE_SECONDS:-10} bash tools/fuzz.sh smoke || status=1
        echo "ci: fuzz smoke took $(( $(date +%s) - start )) s"
    fi
    return $status
}
start=$(date +%s)
second_stream > "$logs/second.log" 2>&1 &
second_pid=$!
first_status=0
"$PYTHON" -m pytest -q --durations=30 --basetemp "$logs/first-tmp" "${FIRST[@]}" \
    || first_status=1
echo "tests: pytest (headless Blender, wheels) took $(( $(date +%s) - start )) s"
if [ "${CI:-}" = true ]; then
    sanitize_start=$(date +%s)
    SANITIZE_REUSE_BUILD=1 bash tools/sanitize.sh || first_status=1
    echo "ci: sanitize took $(( $(date +%s) - sanitize_start )) s"
fi
second_status=0
wait "$second_pid" || second_status=1
echo "======== the second stream: UI and core tests$([ "${CI:-}" = true ] && echo ", fuzz smoke") ========"
cat "$logs/second.log"
echo "tests: both streams took $(( $(date +%s) - start )) s"
rm -rf "$logs"
[ "$first_status" = 0 ] && [ "$second_status" = 0 ]
