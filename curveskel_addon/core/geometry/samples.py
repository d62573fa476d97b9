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

from ..config import CONFIG
from .rows import row_cross, row_norm

__all__ = ["Samples", "face_samples", "subdivision_count", "canonical_subset"]


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


def face_samples(V, F, h: float, *, max_k: int | None = None) -> Samples:
    """Centroids of each face's ``k^2`` sub-triangles with their areas (see the module doc).

    Parameters
    ----------
    V : (n, 3) float, F : (m, 3) int
    h : float > 0
        Sample length: no sub-triangle has a side longer than ``h`` (up to ``max_k``).
    max_k : int, optional
        Most sub-divisions of one side (bounds the count on a degenerate sliver); by default
        as many as make one face hold the whole sample budget.

    Returns
    -------
    Samples
    """
    V = np.asarray(V, np.float64)
    F = np.asarray(F, np.int64).reshape(-1, 3)
    cross = row_cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    dbl = row_norm(cross)
    normal = cross / np.maximum(dbl, 1e-300)[:, None]
    if max_k is None:
        max_k = int(np.ceil(np.sqrt(CONFIG.objective.max_samples)))
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


#: Cycles of the draw's uniform over the key's range (see :func:`canonical_subset`). A 1e-9 D
#: move of every vertex changes the geodesic key by ~1e-7 of its range (rounding summed along
#: the paths), so u moves by ~1e-3 and a pick flips only within that of the k-th score: about
#: one of 3,000 samples, where ranks flipped 4-6 near-tied pairs (docs/benchmarks.md).
#: Adjacent vertices differ by ~1e-3 of the range even on a 1M-vertex mesh: ~10 cycles apart,
#: so the draw still looks independent from one vertex to the next.


def canonical_subset(key, k, seed=0, p=None):
    """``k`` indices drawn without replacement (probabilities ``p``, uniform if None) from a
    quantity of the shape, ``key`` (e.g. the geodesic distance from the pole), so a permuted,
    moved, rotated or scaled copy of the mesh gets the same points, and a copy whose vertices
    moved by their last bits gets nearly all of them (issue 12). Sorted indices.

    Efraimidis & Spirakis's weighted sampling without replacement: the ``k`` points with the
    largest ``u ** (1 / p)``. Each point's ``u`` is a continuous function of its own key,
    ``frac(c z + phase)`` with ``z`` the key scaled to [0, 1] and ``c`` ~ :data:`CONFIG.objective.draw_cycles`
    (``seed`` changes ``c`` and the phase), so a point's pick depends on its own key and weight
    only and changes only where its score is within rounding of the k-th. Uniforms drawn from
    a generator in key order (the previous sampler) handed two near-tied keys each other's
    draws when their order flipped: 6 of 3,000 samples of a shared mesh changed under a
    1e-9 D jitter and a joint moved 2.2e-3 D (docs/benchmarks.md). The randomness is the key's fine structure:
    points whose keys differ by a multiple of ``1 / c`` of the range share ``u`` (a regular
    grid of keys is drawn in a regular pattern; a mesh's geodesic distances are not a grid).
    ``rng.choice`` with probabilities walks a cumulative sum instead: one last-bit change of
    the weights moved 26 of 3,000 samples that way (and it is O(n k)).

    Examples
    --------
    >>> key = np.random.default_rng(0).random(1000)
    >>> pick = canonical_subset(key, 10)
    >>> perm = np.random.default_rng(1).permutation(1000)     # numbered otherwise
    >>> np.array_equal(np.sort(perm[canonical_subset(key[perm], 10)]), pick)
    True
    """
    key = np.asarray(key, np.float64)
    n = len(key)
    if k >= n:
        return np.arange(n)
    lo, hi = float(key.min()), float(key.max())
    z = (key - lo) / (hi - lo) if hi > lo else np.zeros(n)
    golden = 0.6180339887498949
    c = CONFIG.objective.draw_cycles * (1.0 + (seed * golden) % 1.0)
    u = np.modf(z * c + (seed * np.sqrt(2.0)) % 1.0)[0]
    score = np.log(np.maximum(u, 1e-300))     # log u / p: the same order as u ** (1 / p)
    if p is not None:
        w = np.asarray(p, np.float64)
        score = np.where(w > 0, score / np.where(w > 0, w, 1.0), -np.inf)
    pick = np.argpartition(-score, k - 1)[:k]
    return np.sort(pick)
