#!/usr/bin/env bash
# The one list of the Debian 12 packages Planet LOD needs, by command.  Every
# command of the README, the Makefile and .ci/run installs what it uses from
# here (only what is missing), so a fresh machine needs nothing by hand.
#
#   bash tools/install_deps.sh COMMAND...
#
# COMMAND  who calls it                       groups
# flyby    tools/run_flyby.sh (main command)  build toolchain blender
# tests    tools/run_tests.sh (test command)  build toolchain test blender wheels
# ci       tools/run_tests.sh with CI=true    build toolchain test blender fuzz wheels
# sanitize tools/sanitize.sh                  build toolchain test blender
# fuzz     tools/fuzz.sh                      build fuzz
# bench    bench/run_all.sh                   build toolchain test blender
# soak     make soak                          build toolchain blender
#
# Debian's Blender is installed without its recommends, and then lacks what
# it loads at run time: libepoxy opens libEGL.so.1 (Blender aborts without
# it, even in background mode) and the viewport under Xvfb needs Mesa's GL;
# the add-on's per-vertex work uses NumPy, which official Blenders bundle and
# Debian's does not depend on.
# python3-venv: the venvs of the bpy wheels (tools/blender_versions.py).
# The extension is plain C (libc and libm only); image files are read and
# written by OpenImageIO's Python module: python3-openimageio for Debian's
# Python and Blender 3.4, and, for another python3 first on PATH (pyenv's:
# the CLI, bench), the OpenImageIO wheel from PyPI.
# toolchain: tools/build.sh builds the wheels with Zig from PyPI (the
# `ziglang` wheel) in a venv of its own.  wheels: what tests/test_wheels.py
# inspects and runs them with (Wine runs the core's C tests built for
# Windows; the mingw-w64 binutils read the Windows module).
set -euo pipefail

declare -A GROUP=(
    [build]="build-essential pkg-config python3 python3-dev python3-setuptools
             wcslib-dev"
    [test]="python3-pytest python3-numpy python3-matplotlib nodejs python3-openimageio"
    [blender]="blender libegl1 libgl1 libegl-mesa0 libglx-mesa0 libgl1-mesa-dri
               xvfb xauth python3-openimageio python3-numpy python3-venv"
    [fuzz]="clang llvm libclang-rt-14-dev"
    [toolchain]="python3-venv"
    [wheels]="wine64 binutils-mingw-w64-x86-64"
)
declare -A COMMAND=(
    [flyby]="build toolchain blender"
    [tests]="build toolchain test blender wheels"
    [ci]="build toolchain test blender fuzz wheels"
    [sanitize]="build toolchain test blender"
    [fuzz]="build fuzz"
    [bench]="build toolchain test blender"
    [soak]="build toolchain blender"
)

[ $# -gt 0 ] || { echo "usage: $0 {${!COMMAND[*]}}..." | tr ' ' '|' >&2; exit 2; }
packages=()
for command in "$@"; do
    [ -n "${COMMAND[$command]:-}" ] || { echo "install_deps: unknown command '$command'" >&2; exit 2; }
    for group in ${COMMAND[$command]}; do
        packages+=(${GROUP[$group]})
    done
done
missing=()
for p in $(printf '%s\n' "${packages[@]}" | sort -u); do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
    echo "planetlod: installing ${missing[*]}"
    SUDO=""
    [ "$(id -u)" -ne 0 ] && SUDO="sudo"
    export DEBIAN_FRONTEND=noninteractive
    $SUDO apt-get update -q
    $SUDO apt-get install -y -q --no-install-recommends "${missing[@]}"
fi

# A python3 on PATH other than Debian's: the OpenImageIO wheel (and NumPy);
# every command but fuzz runs Python that reads images.
reads_images=0
for command in "$@"; do
    [ "$command" = fuzz ] || reads_images=1
done
if [ "$reads_images" = 1 ] && command -v python3 >/dev/null; then
    plain=$(python3 -c 'import sys; print(sys.executable)')
    if [ "$(readlink -f "$plain")" != "$(readlink -f /usr/bin/python3)" ] &&
        ! python3 -c 'import OpenImageIO, numpy' 2>/dev/null; then
        echo "planetlod: installing the OpenImageIO wheel for $plain"
        python3 -m pip install --quiet --disable-pip-version-check OpenImageIO numpy ||
            echo "planetlod: WARNING: no OpenImageIO wheel for $plain (no route to PyPI?):" \
                "it cannot read image files; /usr/bin/python3 can" >&2
    fi
fi
