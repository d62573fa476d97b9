"""Paths through the inside (core/initialise/interior.py) and what they are for: on surfaces with
handles the first approximation's cycles go round their holes instead of across them."""

import time

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from curveskel_addon.core.geometry.inside import InsideTest
from curveskel_addon.core.geometry.mesh_graph import edge_table
from curveskel_addon.core.initialise import reeb
from curveskel_addon.core.initialise.interior import InteriorGrid, inside_cells
from curveskel_addon.core.initialise.reeb import first_approximation
from meshes import capsule, torus
from skeletons import bone_points, shared_mesh, shared_skeleton


def test_the_scanline_grid_agrees_with_the_ray_parity_test():
    V, F = torus(R=3.0, r=1.0)
    g = InteriorGrid(V, F, resolution=40)
    ii = np.indices(g.dims).reshape(3, -1).T
    P = g.mean + (g.mid + (ii - (g.dims - 1) / 2) * g.h) @ g.axes.T
    ref = InsideTest(V, F)(P)
    origin = g.mid - (g.dims - 1) / 2 * g.h
    # the scanlines' rays are offset a hair to one side of the lattice, or the other
    for side in (1.0, -1.0):
        fast = inside_cells(g.Y, F, origin, g.dims, g.h, side=side).ravel()
        assert fast.sum() > 1000
        assert np.count_nonzero(fast != ref) <= 1e-3 * len(P)


def test_the_torus_hole_is_outside_and_its_tube_inside():
    V, F = torus(R=3.0, r=1.0)
    g = InteriorGrid(V, F)
    core = np.c_[3 * np.cos(np.linspace(0, 6, 7)), 3 * np.sin(np.linspace(0, 6, 7)), np.zeros(7)]
    assert g.contains(core).all()
    assert not g.contains(np.zeros((1, 3))).any()                       # the hole
    assert not g.contains(np.array([[0.0, 0.0, 50.0]])).any()           # off the grid


def test_a_rotated_mesh_gets_the_same_cubes():
    V, F = torus(R=3.0, r=1.0, n_major=48, n_minor=16)
    V = V * [1.0, 0.8, 1.1]                     # distinct principal axes
    R = Rotation.random(random_state=5).as_matrix()
    a, b = InteriorGrid(V, F), InteriorGrid(V @ R.T, F)
    assert np.array_equal(np.sort(a.dims), np.sort(b.dims))
    assert abs(int(a.inside.sum()) - int(b.inside.sum())) <= 2
    na, Ea, wa = a.graph()
    nb, Eb, wb = b.graph()
    assert abs(na - nb) <= 2 and np.isclose(wa.sum(), wb.sum(), rtol=1e-3)


def test_a_shape_without_handles_keeps_the_surface_distance():
    V, F = capsule()
    fa = first_approximation(V, F, spacing=0.04, seed=0)
    assert fa.meta["interior_paths"] is False


@pytest.mark.parametrize("name", ["3holes.off", "rocker-arm.obj"])
def test_cycles_go_round_their_holes_not_across_them(name):
    """With f over the surface alone, 17 (3holes) and 7 (rocker-arm) first-approximation joints
    lay in the holes and the final skeletons had 9 % and 7 % of their bone points outside the
    shape (bones across the holes). With the paths through the inside fewer joints lie outside
    (the first approximation records both counts), every cycle is kept, and the final skeleton
    stays inside."""
    V, F = shared_mesh(name)
    inside = InsideTest(V, F)
    fa = first_approximation(V, F, spacing=0.025, seed=0)
    assert fa.meta["interior_paths"] is True
    assert fa.meta["cycles"] == fa.meta["expected_cycles"]
    # the same construction with f over the surface alone (no paths through the inside)
    E, count = edge_table(F, len(V))
    surface = reeb._approximate(V, F, E, fa.meta["expected_cycles"], 0.025, 0, None, {},
                                time.perf_counter())
    assert (~inside(fa.joints[:, :3])).sum() < (~inside(surface.joints[:, :3])).sum()
    sk = shared_skeleton(name)
    assert inside(bone_points(sk.joints, sk.bones, per_bone=10)).mean() >= 0.98


@pytest.mark.parametrize("shape", ["torus", "3holes.off"])
def test_the_exact_inside_test_changes_no_first_approximation(shape):
    """Given the exact inside test the pipeline builds anyway, a surface with handles whose
    joints are all inside (the torus) skips the grid, one with joints in its holes (3holes)
    still takes the paths through the inside: the same first approximation either way."""
    V, F = torus(R=3.0, r=1.0) if shape == "torus" else shared_mesh(shape)
    plain = first_approximation(V, F, spacing=0.025, seed=0)
    given = first_approximation(V, F, spacing=0.025, seed=0, inside=lambda: InsideTest(V, F))
    assert given.meta["interior_paths"] is plain.meta["interior_paths"] is (shape != "torus")
    np.testing.assert_array_equal(given.joints, plain.joints)
    np.testing.assert_array_equal(given.bones, plain.bones)
