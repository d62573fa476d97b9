"""The pole lies at an extremity (the tip of a capsule) and f is the graph-geodesic distance."""

import numpy as np
import pytest
from scipy.sparse.csgraph import dijkstra
from scipy.spatial import cKDTree

from curveskel_addon.core.errors import CurveSkelError
from curveskel_addon.core.geometry.mesh_graph import adjacency, edge_lengths, edge_table
from curveskel_addon.core.initialise.pole import bilateral_plane, find_pole, principal_mirrors
from curveskel_addon.mesh_files import read_mesh
from meshes import bent_capsule, capsule


def _graph(V, F):
    E, _ = edge_table(F)
    return E, edge_lengths(V, E)


@pytest.mark.parametrize("seed", range(6))
def test_capsule_pole_is_an_axis_endpoint(seed):
    V, F = capsule(radius=1.0, length=6.0)          # axis from z=-1 (tip) to z=7 (tip)
    E, L = _graph(V, F)
    p, f = find_pole(V, E, L, seed)
    tip = min(abs(V[p, 2] + 1.0), abs(V[p, 2] - 7.0))
    assert tip < 0.05, f"pole {V[p]} is not at a tip"
    assert np.hypot(V[p, 0], V[p, 1]) < 0.3
    assert f[p] == 0
    # the far tip is 6 + pi away along the surface (the meridian polyline is slightly shorter)
    assert 0.98 * (6 + np.pi) <= f.max() < 1.1 * (6 + np.pi)


def test_f_is_graph_geodesic_distance():
    V, F = bent_capsule()
    E, L = _graph(V, F)
    p, f = find_pole(V, E, L, seed=1)
    ref = dijkstra(adjacency(len(V), E, L), directed=False, indices=p)
    assert np.allclose(f, ref)
    # the pole of an L-shaped tube is at one of its two ends, not at the bend
    ends = np.array([[-4.5, 0, 0], [0, 0, 4.5]])
    assert np.min(np.linalg.norm(ends - V[p], axis=1)) < 0.3


def test_seed_reproducible_and_unsorted_edges():
    V, F = capsule()
    E, L = _graph(V, F)
    p1, f1 = find_pole(V, E, L, 7)
    p2, f2 = find_pole(V, E[::-1, ::-1], L[::-1], 7)      # any edge order / orientation
    assert p1 == p2 and np.allclose(f1, f2)


def test_zero_length_edge_is_an_edge():
    V = np.array([[0.0, 0, 0], [0, 0, 0], [1, 0, 0]])
    p, f = find_pole(V, np.array([[0, 1], [1, 2]]), np.array([0.0, 1.0]), seed=0)
    assert np.all(np.isfinite(f)) and f.max() == pytest.approx(1.0)


def test_bad_input():
    with pytest.raises(CurveSkelError):
        find_pole(np.zeros((0, 3)), np.zeros((0, 2), int), np.zeros(0), 0)
    with pytest.raises(CurveSkelError):
        find_pole(np.zeros((2, 3)), np.array([[0, 1]]), np.zeros(2), 0)


def test_mirror_symmetric_shape_grows_f_from_the_pole_and_its_image(shared_meshes):
    """spot is its own mirror image: with ``mirror`` f is the distance to the nearer of the pole
    (a hoof) and its twin, so mirror-image vertices get the same f (up to its triangulation,
    which is not mirrored edge for edge: 1.3 % of the maximum); from the pole alone they differ
    by a leg's length."""
    V, F = read_mesh(shared_meshes / "spot.obj")
    E, L = _graph(V, F)
    c, e = bilateral_plane(V)
    assert min(score for score, _ in principal_mirrors(V)[1]) < 1e-9
    twin = cKDTree(V).query(V - 2.0 * ((V - c) @ e)[:, None] * e)[1]
    p0, f0 = find_pole(V, E, L, 0)
    p, f = find_pole(V, E, L, 0, mirror=True)
    assert p == p0 and f.min() == 0 and f[p] <= 1e-5 * f.max()
    assert np.abs(f - f[twin]).max() <= 0.02 * f.max()
    assert np.abs(f0 - f0[twin]).max() >= 0.1 * f0.max()


def test_mirror_leaves_shapes_with_several_mirror_planes_alone():
    # a capsule is its own mirror image across every plane through its axis and across its
    # middle: f from its two tips would peak in the middle; f stays the distance from one tip
    V, F = capsule(radius=1.0, length=6.0)
    E, L = _graph(V, F)
    p0, f0 = find_pole(V, E, L, 0)
    p, f = find_pole(V, E, L, 0, mirror=True)
    assert p == p0 and np.array_equal(f, f0)
