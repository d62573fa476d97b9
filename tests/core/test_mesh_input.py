"""Bad input gets one clear CurveSkelError, and repairable input is repaired without touching the caller's arrays."""

import numpy as np
import pytest

from curveskel_addon.core.errors import CurveSkelError
from curveskel_addon.core.geometry.mesh_graph import edge_table
from curveskel_addon.core.mesh_input import clean_mesh, triangulate
from meshes import capsule, torus

TET_V = np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
TET_F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])


@pytest.mark.parametrize(
    "V, F, message",
    [
        (np.zeros((0, 3)), TET_F, "no vertices"),
        (TET_V, np.zeros((0, 3), int), "no faces"),
        (TET_V, None, "no faces"),
        (TET_V[:, :2], TET_F, "shape (n, 3)"),
        (np.where(np.arange(12).reshape(4, 3) == 4, np.nan, TET_V), TET_F, "NaN"),
        (np.where(np.arange(12).reshape(4, 3) == 0, np.inf, TET_V), TET_F, "NaN or infinite"),
        (TET_V, TET_F + 1, "out of range"),
        (TET_V, TET_F - 1, "out of range"),
        (TET_V, TET_F + 0.5, "integers"),
        (TET_V, np.array([[0, 0, 1], [2, 2, 2]]), "degenerate"),
        (np.c_[np.arange(4.0), np.zeros((4, 2))], TET_F, "zero area"),  # collinear
        (np.array([["a", "b", "c"]]), [[0, 0, 0]], "numbers"),
    ],
)
def test_bad_input_raises_our_error_with_a_clear_message(V, F, message):
    with pytest.raises(CurveSkelError, match=message.replace("(", r"\(").replace(")", r"\)")):
        clean_mesh(V, F)


def test_error_type_is_a_value_error_for_callers_that_catch_those():
    assert issubclass(CurveSkelError, ValueError)


def test_quads_and_mixed_polygons_are_fan_triangulated():
    assert triangulate([[0, 1, 2, 3]]).tolist() == [[0, 1, 2], [0, 2, 3]]
    T = triangulate([[0, 1, 2], [3, 4, 5, 6, 7]])
    assert len(T) == 1 + 3
    assert sorted(map(tuple, T.tolist()))[0] == (0, 1, 2)


def test_duplicate_vertices_are_merged_for_connectivity_and_mapped_back():
    # A triangle soup (STL-style): every face has its own three vertices.
    Vs = TET_V[TET_F.ravel()]
    Fs = np.arange(12).reshape(4, 3)
    m = clean_mesh(Vs, Fs)
    assert len(m.V) == 4 and len(m.F) == 4
    assert m.info["merged_duplicates"] == 8
    np.testing.assert_array_equal(m.V[m.work_index], Vs)  # every input vertex maps to its position


def test_degenerate_faces_dropped_isolated_vertices_flagged_input_untouched():
    V = np.vstack([TET_V, [[5.0, 5, 5]]])  # vertex 4 is isolated
    F = np.vstack([TET_F, [[0, 0, 1]]])    # a face with a repeated index
    V0, F0 = V.copy(), F.copy()
    m = clean_mesh(V, F)
    assert m.info["degenerate_faces_dropped"] == 1
    assert m.info["isolated_vertices"] == 1
    assert m.work_index[4] == -1 and np.all(m.work_index[:4] >= 0)
    assert len(m.F) == 4 and len(m.V) == 4
    np.testing.assert_array_equal(V, V0)
    np.testing.assert_array_equal(F, F0)


def test_edge_table_from_the_census_is_the_working_meshs():
    # the cleaning's edge census serves the first approximation's edge table when no repair
    # changed the triangles after it (else None): the same arrays as mesh_graph.edge_table
    V, F = torus(n_major=30, n_minor=12)
    flipped = F.copy()
    flipped[::3] = flipped[::3, ::-1]                   # turned over, then made consistent
    for Vi, Fi in ((V, F), (V, flipped), (TET_V, TET_F), capsule()):
        cm = clean_mesh(Vi, Fi)
        E, count = cm.edge_table()
        E0, count0 = edge_table(cm.F, len(cm.V))
        assert E.dtype == E0.dtype and count.dtype == count0.dtype
        np.testing.assert_array_equal(E, E0)
        np.testing.assert_array_equal(count, count0)
    # repairs after the census (an isolated vertex, a hole capped): no table
    assert clean_mesh(np.vstack([TET_V, [[5.0, 5, 5]]]), TET_F).edge_table() is None
    assert clean_mesh(V, F[1:]).edge_table() is None
