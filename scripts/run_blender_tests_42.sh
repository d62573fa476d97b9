#!/usr/bin/env bash
# Run the Blender-layer tests (tests/blender) on Blender 4.2 LTS as a Python module (bpy 4.2.x).
#
# Creates its own virtual environment in .venv42 on first use (about 1 GB download), with numpy<2
# as Blender 4.2 ships it. Needs Python 3.11 (bpy 4.2 wheels are cp311 only).
#   bash scripts/run_blender_tests_42.sh            # all of tests/blender
#   bash scripts/run_blender_tests_42.sh -k torus   # extra pytest arguments pass through
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON311:-python3.11}
VENV=.venv42
if [ ! -x "$VENV/bin/python" ]; then
    if ! command -v "$PY" >/dev/null 2>&1; then
        # Fall back to the main venv's interpreter (Python 3.11).
        PY=$(.venv/bin/python -c 'import sys; print(sys._base_executable)')
    fi
    "$PY" -m venv "$VENV"
fi
if ! "$VENV/bin/python" -c "import bpy, numpy, scipy, trimesh, pytest, manifold3d" >/dev/null 2>&1; then
    "$VENV/bin/python" -m pip install -q --upgrade pip
    "$VENV/bin/python" -m pip install -q "bpy==4.2.*" "numpy<2" "scipy==1.15.3" "trimesh==4.5.3" \
        "pytest==8.3.4" "manifold3d==3.2.1"
fi
"$VENV/bin/python" -c "import bpy; print('bpy', bpy.app.version_string)"
exec "$VENV/bin/python" -m pytest tests/blender -q -p no:cacheprovider "$@"
