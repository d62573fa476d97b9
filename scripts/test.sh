#!/usr/bin/env bash
# Set everything up (first run) and run the whole test suite: core tests and headless Blender tests.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/bootstrap.sh requirements-dev.txt
exec .venv/bin/python -m pytest -q "$@"
