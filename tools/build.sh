#!/usr/bin/env bash
# Builds the planetlod extension in place with Debian's Python (the ABI
# Debian's Blender uses).
set -euo pipefail
cd "$(dirname "$0")/.."
PYTHON=${PYTHON:-/usr/bin/python3}
"$PYTHON" setup.py -q build_ext --inplace
