#!/usr/bin/env bash
# The README's main command: installs what is needed (apt), builds the extension,
# installs the add-on into Blender's user add-on folder, and renders a short
# Cycles flyby of the default planet (Earth) to out/flyby/: PNG frames,
# stats.csv (per-frame LOD statistics) and contact_sheet.png.
# Extra arguments go to tools/flyby.py (e.g. --frames 31-60 --samples 32).
#
# The Blender: the newest supported one that installs here, Blender 5.3 as the
# bpy wheel from PyPI (tools/blender_versions.py, cached in ~/.cache/planetlod;
# CPython 3.13), run through tools/bpy_run.py; if that cannot be installed (no
# network, no CPython 3.13), the next older pinned one that can, down to
# Blender 4.2; with none, Debian's Blender 3.4.  BLENDER=/path/to/blender picks
# a Blender binary.
set -euo pipefail
cd "$(dirname "$0")/.."
bash tools/install_deps.sh flyby
bash tools/build.sh
FLYBY_ARGS=(--preset earth --frames 1-48 --path-frames 48 --resolution 640x360 --samples 16
            --out out/flyby "$@")
BPY=""
if [ -z "${BLENDER:-}" ]; then
    # install reports a wheel it cannot install and goes on to the next older;
    # newest then says whether any bpy is there (exit 1: none)
    /usr/bin/python3 tools/blender_versions.py install --newest
    if ! BPY=$(/usr/bin/python3 tools/blender_versions.py newest); then
        BPY=""
        echo "planet_lod: no bpy wheel could be installed; rendering with Debian's Blender" >&2
    fi
fi
if [ -n "$BPY" ]; then
    /usr/bin/python3 tools/install_addon.py --bpy "$BPY"
    "$BPY" tools/bpy_run.py tools/flyby.py -- "${FLYBY_ARGS[@]}"
else
    BLENDER=${BLENDER:-blender}
    /usr/bin/python3 tools/install_addon.py --blender "$BLENDER"
    "$BLENDER" -b --python-exit-code 1 --python tools/flyby.py -- "${FLYBY_ARGS[@]}"
fi
echo "planet_lod: flyby frames, stats.csv and contact_sheet.png are in out/flyby/"
