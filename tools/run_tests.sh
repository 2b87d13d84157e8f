#!/usr/bin/env bash
# The README's test command: installs what is missing, builds, runs every test
# (pytest for the C module, then the headless Blender tests: the whole suite in
# Debian's Blender 3.4 and in the newest bpy wheel, 5.3; the smoke tests --
# install, add, render, farm split -- in 4.2, 4.5, 5.0, 5.1 and 5.2:
# tools/blender_versions.py, tests/test_blender.py).  pytest prints the time
# of each part (no Blender, each Blender) at its end.
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
start=$(date +%s)
"$PYTHON" -m pytest -q tests "$@"
echo "tests: pytest took $(( $(date +%s) - start )) s"
if [ "${CI:-}" = true ]; then
    start=$(date +%s)
    FUZZ_SMOKE_SECONDS=${FUZZ_SMOKE_SECONDS:-10} bash tools/fuzz.sh smoke
    echo "ci: fuzz smoke took $(( $(date +%s) - start )) s"
    start=$(date +%s)
    bash tools/sanitize.sh
    echo "ci: sanitize took $(( $(date +%s) - start )) s"
fi
