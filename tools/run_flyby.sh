#!/usr/bin/env bash
# The README's main command: installs what is needed (apt), builds the extension,
# installs the add-on into Blender's user add-on folder, and renders a short
# Cycles flyby of the default planet (Earth) to out/flyby/: PNG frames,
# stats.csv (per-frame LOD statistics) and contact_sheet.png.
# Extra arguments go to tools/flyby.py (e.g. --frames 31-60 --samples 32).
set -euo pipefail
cd "$(dirname "$0")/.."
bash tools/install_deps.sh flyby
bash tools/build.sh
BLENDER=${BLENDER:-blender}
/usr/bin/python3 tools/install_addon.py --blender "$BLENDER"
"$BLENDER" -b --python-exit-code 1 --python tools/flyby.py -- \
    --preset earth --frames 1-48 --path-frames 48 --resolution 640x360 --samples 16 \
    --out out/flyby "$@"
echo "planet_lod: flyby frames, stats.csv and contact_sheet.png are in out/flyby/"
