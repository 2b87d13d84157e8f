#!/usr/bin/env bash
# Builds the planetlod extension in place: planetlod.abi3.so, the stable ABI
# of Python 3.11, which every Blender with Python 3.11 or later loads (Debian's
# 3.4.1, 4.2 LTS, 4.5 LTS, 5.0; 5.1 runs Python 3.13).
set -euo pipefail
cd "$(dirname "$0")/.."
PYTHON=${PYTHON:-/usr/bin/python3}
# A version-specific build left from before would shadow the abi3 one
# (CPython tries planetlod.cpython-3XY-*.so first).
rm -f planetlod.cpython-*.so
"$PYTHON" setup.py -q build_ext --inplace
