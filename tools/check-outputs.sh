#!/usr/bin/env bash
# Independent read-back of a `nusselt solve` output folder: installs the
# OpenEXR Python bindings and the Khronos glTF Validator (from PyPI and npm)
# if missing, then runs tools/check_outputs.py on the folder.
# Usage: bash tools/check-outputs.sh OUTDIR
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
python3 -c 'import OpenEXR, numpy' 2>/dev/null || python3 -m pip install --quiet 'OpenEXR>=3' numpy
for package in gltf-validator three playwright-core; do
    [ -d "$here/node_modules/$package" ] || { npm ci --prefix "$here" --silent --no-audit --no-fund; break; }
done
python3 "$here/check_outputs.py" "$1"
