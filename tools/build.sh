#!/usr/bin/env bash
# Builds the planetlod extension in place: planetlod/_native.abi3.so, the stable ABI
# of Python 3.11, which every Blender with Python 3.11 or later loads (Debian's
# 3.4.1, 4.2 LTS, 4.5 LTS, 5.0; 5.1 runs Python 3.13).
set -euo pipefail
cd "$(dirname "$0")/.."
PYTHON=${PYTHON:-/usr/bin/python3}
# A version-specific build left from before would shadow the abi3 one
# (CPython tries _native.cpython-3XY-*.so first); a module built at the
# repository root before the package existed would shadow the package.
rm -f planetlod/_native.cpython-*.so planetlod.cpython-*.so planetlod.abi3.so
"$PYTHON" setup.py -q build_ext --inplace
