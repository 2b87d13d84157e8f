#!/usr/bin/env bash
# Builds the planetlod extension as users get it: this machine's wheel
# (manylinux2014, the stable ABI of Python 3.11, which every Blender with
# Python 3.11 or later loads) with tools/build_wheels.py, into dist/, and
# installs it into build/site, where the tests import it from
# (tests/conftest.py).  The wheel's module is also copied to
# planetlod/_native.abi3.so, so the checkout itself imports the same binary
# (tools, benchmarks, the add-on from the repository).
#
# PLANETLOD_BUILD=inplace builds with this machine's compiler through
# setup.py instead (no toolchain download; GCC's per-CPU clones of the SIMD
# loops), for the checkout only.
set -euo pipefail
cd "$(dirname "$0")/.."
PYTHON=${PYTHON:-/usr/bin/python3}
# A version-specific build left from before would shadow the abi3 one
# (CPython tries _native.cpython-3XY-*.so first); a module built at the
# repository root before the package existed would shadow the package.
rm -f planetlod/_native.cpython-*.so planetlod.cpython-*.so planetlod.abi3.so
if [ "${PLANETLOD_BUILD:-wheel}" = inplace ]; then
    rm -rf build/site  # the tests then import the checkout's build
    "$PYTHON" setup.py -q build_ext --inplace
    exit 0
fi
"$PYTHON" tools/build_wheels.py --host --install build/site
# a new file renamed into place: a process that has the old one mapped keeps it
cp build/site/planetlod/_native.abi3.so planetlod/_native.abi3.so.new
mv -f planetlod/_native.abi3.so.new planetlod/_native.abi3.so
