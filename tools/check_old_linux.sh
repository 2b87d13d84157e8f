#!/usr/bin/env bash
# Runs the core tests against the manylinux wheel inside an older Linux:
# a Debian 11 (bullseye, glibc 2.31) root made with debootstrap.  Bullseye's
# own Python is 3.9, older than the wheel's stable ABI (3.11), so CPython
# 3.11 is built from Debian 12's source package inside the root, the way a
# user of an older system would get one.  NumPy, pytest and OpenImageIO (the
# image files) come as wheels from PyPI (manylinux2014 or _2_28).  Everything is cached under
# $PLANET_LOD_CACHE/bullseye (default ~/.cache/planetlod); the first run
# downloads ~300 MB and builds Python (tens of minutes on two cores).
#
#   sudo bash tools/check_old_linux.sh [PYTEST ARGS...]
#
# Needs root (debootstrap, chroot), debootstrap and network access to the
# Debian archive and PyPI.
set -euo pipefail
cd "$(dirname "$0")/.."
CACHE=${PLANET_LOD_CACHE:-$HOME/.cache/planetlod}
ROOTFS=$CACHE/bullseye
TESTS=(tests/test_module.py tests/test_abi3.py tests/test_threads.py tests/test_projection.py
       tests/test_refine.py tests/test_mesh.py tests/test_cull.py tests/test_robust.py)
[ $# -gt 0 ] && TESTS=("$@")

wheel=$(ls dist/planetlod-*-cp311-abi3-manylinux_2_17_x86_64*.whl 2>/dev/null | head -1)
[ -n "$wheel" ] || { echo "check_old_linux: no manylinux wheel in dist/: run tools/build.sh" >&2; exit 2; }

if [ ! -x "$ROOTFS/usr/bin/python3" ]; then
    echo "check_old_linux: debootstrap bullseye into $ROOTFS"
    debootstrap --variant=minbase --include=ca-certificates bullseye "$ROOTFS" \
        http://deb.debian.org/debian
fi
mountpoint -q "$ROOTFS/proc" || mount -t proc proc "$ROOTFS/proc"
trap 'umount "$ROOTFS/proc" 2>/dev/null || true' EXIT

PY=/opt/python3.11/bin/python3.11
if [ ! -x "$ROOTFS$PY" ]; then
    echo "check_old_linux: building CPython 3.11 from Debian 12's source inside the root"
    sources=$(mktemp -d)
    printf 'deb-src http://deb.debian.org/debian bookworm main\n' > "$sources/list"
    mkdir -p "$sources/lists/partial"
    apt_src=(-o Dir::Etc::SourceList="$sources/list" -o Dir::Etc::SourceParts=/dev/null
             -o Dir::State::Lists="$sources/lists")
    apt-get -q "${apt_src[@]}" update
    (cd "$sources" && apt-get -q "${apt_src[@]}" source --download-only python3.11)
    cp "$sources"/python3.11_*.orig.tar.* "$ROOTFS/tmp/"
    rm -rf "$sources"
    DEBIAN_FRONTEND=noninteractive chroot "$ROOTFS" apt-get -q update
    DEBIAN_FRONTEND=noninteractive chroot "$ROOTFS" apt-get install -y -q \
        --no-install-recommends gcc make libc6-dev zlib1g-dev libffi-dev
    chroot "$ROOTFS" sh -ec 'cd /tmp && tar xf python3.11_*.orig.tar.* && cd Python-3.11.* &&
        ./configure --prefix=/opt/python3.11 --without-ensurepip >/tmp/configure.log &&
        make -j"$(nproc)" >/tmp/make.log && make install >/tmp/install.log'
fi

# the wheel, NumPy and pytest unpacked into a fresh site folder (a wheel is
# a zip of its installed files)
wheels=$(mktemp -d)
PIP_PYTHON=python3
[ -x "$CACHE/toolchain/bin/python" ] && PIP_PYTHON=$CACHE/toolchain/bin/python  # tools/build_wheels.py's venv has pip
"$PIP_PYTHON" -m pip download -q --disable-pip-version-check --only-binary=:all: \
    --python-version 3.11 --implementation cp --platform manylinux2014_x86_64 \
    --platform manylinux_2_28_x86_64 -d "$wheels" numpy pytest OpenImageIO
cp "$wheel" "$wheels/"
rm -rf "$ROOTFS/opt/planetlod" && mkdir -p "$ROOTFS/opt/planetlod/site"
for w in "$wheels"/*.whl; do
    python3 -c 'import sys, zipfile; zipfile.ZipFile(sys.argv[1]).extractall(sys.argv[2])' \
        "$w" "$ROOTFS/opt/planetlod/site"
done
rm -rf "$wheels"
# the tests and what they read, not the checkout's planetlod/ (the wheel's is tested)
tar cf - tests tools presets data addon pytest.ini | tar xf - -C "$ROOTFS/opt/planetlod"
echo "check_old_linux: $(chroot "$ROOTFS" ldd --version | head -1); $(chroot "$ROOTFS" $PY --version)"
chroot "$ROOTFS" env -i PATH=/usr/bin:/bin HOME=/tmp PLANET_LOD_NATIVE=/opt/planetlod/site \
    PYTHONPATH=/opt/planetlod/site sh -c "cd /opt/planetlod && $PY -m pytest -q -p no:cacheprovider ${TESTS[*]}"
