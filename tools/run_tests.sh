#!/usr/bin/env bash
# The README's test command: installs what is missing, builds, runs every test
# (pytest for the C module, then Blender headless tests).
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
"$PYTHON" -m pytest -q tests "$@"
if [ "${CI:-}" = true ]; then
    start=$(date +%s)
    FUZZ_SMOKE_SECONDS=${FUZZ_SMOKE_SECONDS:-10} bash tools/fuzz.sh smoke
    echo "ci: fuzz smoke took $(( $(date +%s) - start )) s"
    start=$(date +%s)
    bash tools/sanitize.sh
    echo "ci: sanitize took $(( $(date +%s) - start )) s"
fi
