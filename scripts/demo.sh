#!/usr/bin/env bash
# Set everything up (first run) and run the main job on the bundled example mesh:
# skeleton JSON, a .blend with armature and silhouette, and a Cycles preview PNG in out/.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/bootstrap.sh requirements-dev.txt
mkdir -p out
exec .venv/bin/python scripts/skeletonize.py examples/spot.obj \
  --json out/spot.json --blend out/spot.blend --render out/spot.png "$@"
