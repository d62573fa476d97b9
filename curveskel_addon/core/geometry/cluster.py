"""A coarser copy of a closed mesh by vertex clustering, for work that needs only a resolution.

The vertices in each cube of a grid of side ``h`` (in the vertices' principal axes) become one, at their mean; faces with two
corners in one cube vanish, and pairs of faces that now lie on each other facing opposite ways
cancel. What is left is still a closed, oriented surface in the sense the cross-sections and the
inside test use (every edge is crossed as often one way as the other): the signed area of a plane
section is still the area of the solid's section, blurred by about ``h``.
"""

from __future__ import annotations

import numpy as np

__all__ = ["cluster_vertices"]


def cluster_vertices(V, F, h: float):
    """Merge the vertices of ``(V, F)`` within cubes of side ``h``.

    Parameters
    ----------
    V : (n, 3) float
    F : (m, 3) int
        A closed, consistently oriented triangle mesh.
    h : float
        The grid's cube side.

    Returns
    -------
    V2 : (n2, 3) float
        One vertex per occupied cube, at the mean of its vertices.
    F2 : (m2, 3) int
        The faces that keep three distinct corners, without pairs that cancel.

    Examples
    --------
    >>> V = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [0.01, 0, 0]], float)
    >>> F = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    >>> cluster_vertices(V, F, 0.5)[1].shape      # a tetrahedron stays one
    (4, 3)
    """
    V = np.asarray(V, np.float64)
    F = np.asarray(F, np.int64).reshape(-1, 3)
    used = np.unique(F)
    # the grid in the vertices' principal axes, symmetric about the middle of their box: a
    # rotated, moved or scaled copy of the mesh gets the same cubes (an axis the other way
    # round maps the grid onto itself)
    Y = V[used] - V[used].mean(axis=0)
    _, E = np.linalg.eigh(Y.T @ Y)
    Y = Y @ E
    mid = 0.5 * (Y.min(axis=0) + Y.max(axis=0))
    key = np.floor((Y - mid) / h).astype(np.int64)
    _, cell = np.unique(key, axis=0, return_inverse=True)
    cell = cell.ravel()
    n2 = int(cell.max()) + 1 if len(cell) else 0
    V2 = np.stack([np.bincount(cell, V[used, c], n2) for c in range(3)], 1)
    V2 /= np.bincount(cell, minlength=n2)[:, None]
    of = np.full(len(V), -1, np.int64)
    of[used] = cell
    F2 = of[F]
    keep = (F2[:, 0] != F2[:, 1]) & (F2[:, 1] != F2[:, 2]) & (F2[:, 2] != F2[:, 0])
    F2 = F2[keep]
    # a face and its reverse cancel: rotate each so its smallest corner leads, then match
    # (a, b, c) with (a, c, b)
    r = np.argmin(F2, axis=1)
    rows = np.arange(len(F2))[:, None]
    F2 = F2[rows, (r[:, None] + np.arange(3)) % 3]
    fwd = F2[:, 0] * n2 * n2 + F2[:, 1] * n2 + F2[:, 2]
    rev = F2[:, 0] * n2 * n2 + F2[:, 2] * n2 + F2[:, 1]
    keys, counts = np.unique(fwd, return_counts=True)
    c_fwd = counts[np.searchsorted(keys, fwd)]
    pos = np.searchsorted(keys, rev)
    pos = np.minimum(pos, len(keys) - 1)
    c_rev = np.where(keys[pos] == rev, counts[pos], 0)
    # each key keeps its surplus over its reverse: k faces one way and j the other leave
    # max(k - j, 0) of the first
    rank = _rank_within(fwd)
    F2 = F2[rank < c_fwd - c_rev]
    return V2, F2


def _rank_within(keys):
    """The position of each element among the elements with the same key (0, 1, ...)."""
    order = np.argsort(keys, kind="stable")
    sk = keys[order]
    start = np.flatnonzero(np.r_[True, sk[1:] != sk[:-1]])
    first = np.repeat(start, np.diff(np.r_[start, len(sk)]))
    rank = np.empty(len(keys), np.int64)
    rank[order] = np.arange(len(keys)) - first
    return rank
