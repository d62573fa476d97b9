"""Per-vertex area: the quadrature weight that turns the vertex sum into the surface integral (eq. 8)."""

from __future__ import annotations

import numpy as np

from .rows import row_cross, row_norm, take_rows

__all__ = ["vertex_areas", "face_cross"]


def face_cross(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """(m, 3) ``(v1 - v0) x (v2 - v0)`` of every triangle: twice its area times its unit normal
    (outward on a consistently oriented closed surface). Computed once per run and shared by the
    vertex areas and the surface normals (:func:`.medial.surface_points`)."""
    A = take_rows(V, F[:, 0])
    return row_cross(take_rows(V, F[:, 1]) - A, take_rows(V, F[:, 2]) - A)


def vertex_areas(V: np.ndarray, F: np.ndarray, fn: np.ndarray | None = None) -> np.ndarray:
    """(n,) barycentric vertex areas: a third of the area of every incident triangle.

    Sums to the surface area, so ``sum(w * g(v))`` approximates the integral of g over the
    surface whatever the sampling density. ``fn``: :func:`face_cross` of (V, F), if at hand.

    Examples
    --------
    >>> V = np.array([[0., 0, 0], [1, 0, 0], [0, 1, 0]]); F = np.array([[0, 1, 2]])
    >>> vertex_areas(V, F).round(4).tolist()
    [0.1667, 0.1667, 0.1667]
    """
    a = row_norm(face_cross(V, F) if fn is None else fn) / 2
    return np.bincount(F.ravel(), weights=np.repeat(a / 3.0, 3), minlength=len(V))
