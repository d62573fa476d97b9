"""Per-vertex area: the quadrature weight that turns the vertex sum into the surface integral (eq. 8)."""

from __future__ import annotations

import numpy as np

__all__ = ["vertex_areas"]


def vertex_areas(V: np.ndarray, F: np.ndarray) -> np.ndarray:
    """(n,) barycentric vertex areas: a third of the area of every incident triangle.

    Sums to the surface area, so ``sum(w * g(v))`` approximates the integral of g over the
    surface whatever the sampling density.

    Examples
    --------
    >>> V = np.array([[0., 0, 0], [1, 0, 0], [0, 1, 0]]); F = np.array([[0, 1, 2]])
    >>> vertex_areas(V, F).round(4).tolist()
    [0.1667, 0.1667, 0.1667]
    """
    a = np.linalg.norm(np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]]), axis=1) / 2
    return np.bincount(F.ravel(), weights=np.repeat(a / 3.0, 3), minlength=len(V))
