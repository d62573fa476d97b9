"""Shared test set-up: the repo root and tests/ on sys.path; paths to the shared meshes."""

import sys
from pathlib import Path

import pytest

TESTS = Path(__file__).resolve().parent
ROOT = TESTS.parent
for p in (ROOT, TESTS):
    if str(p) not in sys.path:
        sys.path.insert(0, str(p))

SHARED_MESHES = ROOT.parent / "shared" / "meshes"


@pytest.fixture(scope="session")
def shared_meshes() -> Path:
    if not SHARED_MESHES.is_dir():
        pytest.fail(f"../shared/meshes not found beside the repo ({SHARED_MESHES})")
    return SHARED_MESHES
