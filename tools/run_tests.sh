#!/usr/bin/env bash
# The README's test command: installs what is missing, builds, runs every test
# (pytest for the C module, then Blender headless tests).
set -euo pipefail
cd "$(dirname "$0")/.."
bash tools/install_deps.sh --blender
bash tools/build.sh
PYTHON=${PYTHON:-/usr/bin/python3}
"$PYTHON" -m pytest -q tests "$@"
