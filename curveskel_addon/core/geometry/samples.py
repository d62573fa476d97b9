"""Quadrature points of a triangle mesh's surface: the fit's integral over faces, not vertices.

The paper's E is a surface integral (its eq. 8); its vertex sum (eq. 20) fits the vertices, so
where they are sparse or uneven the fit follows the triangulation (its open problem 2: a
capsule whose cylinder has vertices only on its two rims). Here every face is split into
``k^2`` congruent sub-triangles, ``k`` = its longest side over the sample length ``h``
(rounded up), and each sub-triangle contributes its centroid with its area: the midpoint rule
on a mesh finer than ``h``, whatever the triangulation. Long thin faces get as many points as
their length needs, small faces one.

The points are functions of the vertices and of ``h`` only: a tiny move of the vertices moves
them by as little (the sub-division count changes only where a side crosses a multiple of
``h``, and then the integral it estimates barely changes).

Examples
--------
>>> import numpy as np
>>> V = np.array([[0., 0, 0], [2, 0, 0], [0, 2, 0]]); F = np.array([[0, 1, 2]])
>>> s = face_samples(V, F, 1.0)
>>> len(s.points), float(s.weights.sum())          # k = 3: 9 sub-triangles, area 2
(9, 2.0)
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .rows import row_cross, row_norm

__all__ = ["Samples", "face_samples", "subdivision_count"]


@dataclass(frozen=True)
class Samples:
    """Surface quadrature points.

    Attributes
    ----------
    points : (s, 3) float
    weights : (s,) float
        Area each point stands for (they sum to the surface area).
    face : (s,) int
        The face each point lies on.
    bary : (s, 3) float
        Its barycentric coordinates in that face.
    normal : (s, 3) float
        The face's unit normal (outward on an outward-oriented closed surface).
    """

    points: np.ndarray
    weights: np.ndarray
    face: np.ndarray
    bary: np.ndarray
    normal: np.ndarray

    def subset(self, idx, scale: float = 1.0) -> "Samples":
        """The points ``idx``, their weights times ``scale``."""
        return Samples(self.points[idx], self.weights[idx] * scale, self.face[idx],
                       self.bary[idx], self.normal[idx])


def subdivision_count(V, F, h: float) -> np.ndarray:
    """(m,) sub-division count ``k`` of each face: its longest side over ``h``, rounded up."""
    longest = np.zeros(len(F))
    for a, b in ((0, 1), (1, 2), (2, 0)):
        np.maximum(longest, row_norm(V[F[:, a]] - V[F[:, b]]), out=longest)
    return np.maximum(1, np.ceil(longest / max(h, 1e-300) - 1e-9)).astype(np.int64)


def _pattern(k: int) -> np.ndarray:
    """(k^2, 3) barycentric centroids of the k^2 sub-triangles of one face."""
    i, j = np.meshgrid(np.arange(k), np.arange(k), indexing="ij")
    up = (i + j) <= k - 1
    down = (i + j) <= k - 2
    a = np.concatenate([(i[up] + 1 / 3) / k, (i[down] + 2 / 3) / k])
    b = np.concatenate([(j[up] + 1 / 3) / k, (j[down] + 2 / 3) / k])
    return np.stack([1.0 - a - b, a, b], axis=1)


def face_samples(V, F, h: float, *, max_k: int = 64) -> Samples:
    """Centroids of each face's ``k^2`` sub-triangles with their areas (see the module doc).

    Parameters
    ----------
    V : (n, 3) float, F : (m, 3) int
    h : float > 0
        Sample length: no sub-triangle has a side longer than ``h`` (up to ``max_k``).
    max_k : int
        Most sub-divisions of one side (bounds the count on a degenerate sliver).

    Returns
    -------
    Samples
    """
    V = np.asarray(V, np.float64)
    F = np.asarray(F, np.int64).reshape(-1, 3)
    cross = row_cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    dbl = row_norm(cross)
    normal = cross / np.maximum(dbl, 1e-300)[:, None]
    k = np.minimum(subdivision_count(V, F, h), max_k)
    faces, bary, weight = [], [], []
    for kk in np.unique(k):                  # one pass per distinct count, not per face
        fs = np.flatnonzero(k == kk)
        pat = _pattern(int(kk))
        faces.append(np.repeat(fs, len(pat)))
        bary.append(np.tile(pat, (len(fs), 1)))
        weight.append(np.repeat(dbl[fs] / (2.0 * kk * kk), len(pat)))
    face = np.concatenate(faces)
    bary = np.concatenate(bary)
    order = np.lexsort((bary[:, 2], bary[:, 1], face))      # face order, not count order
    face, bary, w = face[order], bary[order], np.concatenate(weight)[order]
    P = (bary[:, :1] * V[F[face, 0]] + bary[:, 1:2] * V[F[face, 1]]
         + bary[:, 2:] * V[F[face, 2]])
    return Samples(P, w, face, bary, normal[face])
