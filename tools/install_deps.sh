#!/usr/bin/env bash
# Installs the Debian packages Planet LOD needs (only those missing).
# Usage: bash tools/install_deps.sh [--blender] [--bench]
set -euo pipefail
packages=(build-essential pkg-config python3 python3-dev python3-setuptools python3-pytest
          python3-numpy libopenimageio-dev wcslib-dev)
for arg in "$@"; do
  case "$arg" in
    --blender) packages+=(blender xvfb xauth python3-openimageio) ;;
    --bench) packages+=(blender python3-matplotlib python3-openimageio clang) ;;
    --fuzz) packages+=(clang llvm) ;;
  esac
done
missing=()
for p in "${packages[@]}"; do
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
