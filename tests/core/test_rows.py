"""The row-wise helpers (core/geometry/rows.py) give numpy's own results bit for bit: the pipeline uses
them where a changed last bit could change a skeleton."""

from __future__ import annotations

import numpy as np
import pytest

from curveskel_addon.core.geometry.rows import (col_max, col_min, col_ptp, mul_rows, row_cross, row_norm,
                                            take_rows)
from curveskel_addon.core.geometry.areas import face_cross, vertex_areas
from tests.meshes import torus


def _arrays(seed):
    rng = np.random.default_rng(seed)
    # mixed magnitudes, so the sums' rounding differs between orders
    X = rng.normal(size=(5000, 3)) * 10.0 ** rng.integers(-6, 6, size=(5000, 1)) + 1e-3
    return rng, X


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_bit_identical_to_numpy(seed):
    rng, X = _arrays(seed)
    Y = rng.normal(size=X.shape) * 1e3
    for A in (X, X[:, :2], X.astype(np.float32), np.ascontiguousarray(X.T)[:2].T):
        assert np.array_equal(col_min(A), A.min(axis=0))
        assert np.array_equal(col_max(A), A.max(axis=0))
        assert np.array_equal(col_ptp(A), np.ptp(A, axis=0))
        assert col_min(A).dtype == A.min(axis=0).dtype
    for c in range(1, 8):
        A = rng.normal(size=(3000, c)) * 10.0 ** rng.integers(-6, 6, size=(3000, c))
        assert np.array_equal(row_norm(A), np.linalg.norm(A, axis=1))
    assert np.array_equal(row_cross(X, Y), np.cross(X, Y))
    idx = rng.integers(-len(X), len(X), size=20000)
    assert np.array_equal(take_rows(X, idx), X[idx])


def test_vertex_areas_from_face_cross():
    V, F = torus(n_major=40, n_minor=20)
    V = V + 0.123
    a = np.linalg.norm(np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]), axis=1) / 2
    old = np.bincount(F.ravel(), weights=np.repeat(a / 3.0, 3), minlength=len(V))
    assert np.array_equal(vertex_areas(V, F), old)
    assert np.array_equal(vertex_areas(V, F, face_cross(V, F)), old)


def test_nan_and_empty_like_numpy():
    X = np.array([[1.0, np.nan, 3.0], [0.0, 2.0, -1.0]])
    np.testing.assert_array_equal(col_min(X), X.min(axis=0))
    np.testing.assert_array_equal(col_max(X), X.max(axis=0))
    with pytest.raises(ValueError):
        col_min(np.zeros((0, 3)))


def test_mul_rows_like_numpy():
    rng, X = _arrays(3)
    t = rng.normal(size=len(X)) * 1e3
    assert np.array_equal(mul_rows(t, X), t[:, None] * X)
    assert np.array_equal(mul_rows(1.0 - t, X[:, :2]), (1.0 - t[:, None]) * X[:, :2])
