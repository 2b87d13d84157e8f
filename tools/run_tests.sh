#!/usr/bin/env bash
# The README's test command: installs what is missing, builds, runs every test
# (pytest for the C module, then the headless Blender tests in Debian's Blender
# 3.4 and in Blender 4.2, 4.5 and 5.0: tools/blender_versions.py).
# With CI=true (the CI runner, .ci/run) it also runs a short fuzz smoke
# (FUZZ_SMOKE_SECONDS, default 10 s per harness, ~1 min with the build) and the
# whole suite again under ASan+UBSan+LSan (tools/sanitize.sh, ~2 min).
set -euo pipefail
cd "$(dirname "$0")/.."
if [ "${CI:-}" = true ]; then
    bash tools/install_deps.sh ci
else
    bash tools/install_deps.sh tests
fi
bash tools/build.sh
PYTHON=${PYTHON:-/usr/bin/python3}
# Blender 4.2 LTS, 4.5 LTS and 5.0 as bpy wheels, each in a venv cached under
# ~/.cache/planetlod (downloaded on the first run only); the Blender tests run
# in each of them and in Debian's Blender.
start=$(date +%s)
"$PYTHON" tools/blender_versions.py install
echo "tests: Blender versions ready ($(( $(date +%s) - start )) s): $("$PYTHON" tools/blender_versions.py list | cut -d' ' -f1 | tr '\n' ' ')"
# The Open Job Description runtime for the farm's job templates (tests/test_openjd.py)
"$PYTHON" -m tools.openjd_env install
"$PYTHON" -m pytest -q tests "$@"
if [ "${CI:-}" = true ]; then
    start=$(date +%s)
    FUZZ_SMOKE_SECONDS=${FUZZ_SMOKE_SECONDS:-10} bash tools/fuzz.sh smoke
    echo "ci: fuzz smoke took $(( $(date +%s) - start )) s"
    start=$(date +%s)
    bash tools/sanitize.sh
    echo "ci: sanitize took $(( $(date +%s) - start )) s"
fi
