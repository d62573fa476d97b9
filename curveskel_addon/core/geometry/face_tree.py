"""A bounding-volume hierarchy of a mesh's faces, queried by many planes at once.

A cross-section needs the faces a plane cuts near a point. Screening every vertex against every
plane costs O(n k) for k planes; here the faces are sorted along a space-filling (Morton) curve
and grouped into a complete binary tree of boxes (leaves of ``CONFIG.numerics.tree_leaf`` faces), and each
plane descends only into the boxes it cuts within its reach: O(k sqrt(m)) for a mesh of m faces.
All planes descend together, one tree level per step, so the work is a few array operations
per level, not a loop over planes or faces.

Examples
--------
>>> import numpy as np
>>> V = np.array([[x, y, z] for x in (0., 1) for y in (0., 1) for z in (0., 1)])
>>> F = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
...               [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
>>> tree = FaceTree(V, F)
>>> p, f = tree.cut_by_planes([[0.5, 0.5, 0.5]], [[1.0, 0, 0]], [2.0])
>>> {4, 5, 6, 7, 8, 9, 10, 11} <= set(tree.order[f].tolist())   # the side walls, and more
True
>>> len(tree.cut_by_planes([[0.5, 0.5, 5.0]], [[0, 0, 1.0]], [2.0])[1])    # above the cube
0
"""

from __future__ import annotations

import numpy as np

from ..config import CONFIG

__all__ = ["FaceTree"]

_NUM = CONFIG.numerics


def _morton(P, bits):
    """Morton (Z-order) keys of points, ``bits`` per axis, over their bounding box."""
    lo, hi = P.min(axis=0), P.max(axis=0)
    q = ((P - lo) / np.maximum(hi - lo, 1e-300) * ((1 << bits) - 1)).astype(np.uint64)
    key = np.zeros(len(P), np.uint64)
    for b in range(bits):
        for c in range(3):
            key |= ((q[:, c] >> np.uint64(b)) & np.uint64(1)) << np.uint64(3 * b + c)
    return key


class FaceTree:
    """Boxes over the faces of (V, F), a complete binary tree in Morton order.

    Parameters
    ----------
    V : (n, 3) float, F : (m, 3) int
    """

    def __init__(self, V, F):
        V = np.asarray(V, np.float64)
        F = np.asarray(F, np.int64).reshape(-1, 3)
        m = len(F)
        corners = V[F]                                        # (m, 3, 3)
        flo, fhi = corners.min(axis=1), corners.max(axis=1)
        self.order = np.argsort(_morton((flo + fhi) / 2, _NUM.morton_bits), kind="stable")
        flo, fhi = flo[self.order], fhi[self.order]
        n_leaves = max(1, -(-m // _NUM.tree_leaf))
        self.depth = int(np.ceil(np.log2(n_leaves))) if n_leaves > 1 else 0
        size = 1 << self.depth                                # leaves, padded to a power of 2
        start = np.minimum(np.arange(size) * _NUM.tree_leaf, m)
        self.leaf_start = start
        self.leaf_stop = np.minimum(start + _NUM.tree_leaf, m)
        # leaf boxes (padding leaves hold no face: a point box at the first face)
        real = start < m
        lo = np.repeat(flo[:1], size, axis=0) if m else np.zeros((size, 3))
        hi = lo.copy()
        lo[real] = np.minimum.reduceat(flo, start[real], axis=0)
        hi[real] = np.maximum.reduceat(fhi, start[real], axis=0)
        self.levels = [(lo, hi)]
        while len(lo) > 1:
            lo = np.minimum(lo[0::2], lo[1::2])
            hi = np.maximum(hi[0::2], hi[1::2])
            self.levels.append((lo, hi))
        self.levels.reverse()                                 # root first
        self.m = m
        # the faces in tree order: their corners and outward normals, read in blocks
        self.F = F[self.order]
        self.corners = corners[self.order]
        self.normals = np.cross(self.corners[:, 1] - self.corners[:, 0],
                                self.corners[:, 2] - self.corners[:, 0])

    def cut_by_planes(self, X, N, reach):
        """(plane, face) pairs: faces whose box the plane through ``X[k]`` normal to ``N[k]``
        cuts within ``reach[k]`` of ``X[k]`` (a superset of the faces it cuts there).

        Parameters
        ----------
        X : (k, 3) float, N : (k, 3) float, reach : (k,) float

        Returns
        -------
        plane : (p,) int, face : (p,) int
            ``face`` indexes the faces in tree order (:attr:`F`, :attr:`corners`); the
            mesh's own face is ``order[face]``.
        """
        X = np.asarray(X, np.float64).reshape(-1, 3)
        N = np.asarray(N, np.float64).reshape(-1, 3)
        reach = np.broadcast_to(np.asarray(reach, np.float64), (len(X),))
        plane = np.flatnonzero(np.any(N != 0, axis=1))
        node = np.zeros(len(plane), np.int64)
        for d, (lo, hi) in enumerate(self.levels):
            if d:
                plane = np.repeat(plane, 2)
                node = (np.repeat(node, 2) << 1) | np.tile([0, 1], len(node))
            c, e = (lo[node] + hi[node]) / 2, (hi[node] - lo[node]) / 2
            x, n = X[plane], N[plane]
            # the plane cuts the box: |n.(c - x)| <= |n|.e; the box is within reach of x
            h = np.abs(np.einsum("ij,ij->i", n, c - x))
            cut = h <= np.einsum("ij,ij->i", np.abs(n), e)
            gap = np.maximum(np.abs(c - x) - e, 0.0)
            cut &= np.einsum("ij,ij->i", gap, gap) <= reach[plane] ** 2
            plane, node = plane[cut], node[cut]
        a, b = self.leaf_start[node], self.leaf_stop[node]
        cnt = b - a
        pos = np.repeat(a, cnt) + (np.arange(cnt.sum()) - np.repeat(np.cumsum(cnt) - cnt, cnt))
        return np.repeat(plane, cnt), pos

    def ray_hits(self, V, F, O, Dir, *, skip=None):
        """Distance along each ray ``O[k] + t Dir[k]`` (t > 0) to the first face it hits
        (inf where none); ``skip[k]``, a face the ray starts on, is not counted.

        The rays descend the tree together (slab tests against the boxes), then meet the
        triangles of the leaves they reach (Moller-Trumbore)."""
        V = np.asarray(V, np.float64)
        O = np.asarray(O, np.float64).reshape(-1, 3)
        Dir = np.asarray(Dir, np.float64).reshape(-1, 3)
        inv = 1.0 / np.where(Dir == 0, 1e-300, Dir)
        best = np.full(len(O), np.inf)
        ray = np.arange(len(O))
        node = np.zeros(len(O), np.int64)
        for d, (lo, hi) in enumerate(self.levels):
            if d:
                ray = np.repeat(ray, 2)
                node = (np.repeat(node, 2) << 1) | np.tile([0, 1], len(node))
            t1 = (lo[node] - O[ray]) * inv[ray]
            t2 = (hi[node] - O[ray]) * inv[ray]
            tmin = np.minimum(t1, t2).max(axis=1)
            tmax = np.maximum(t1, t2).min(axis=1)
            keep = (tmax >= np.maximum(tmin, 0.0)) & (tmin <= best[ray])
            ray, node = ray[keep], node[keep]
        a, b = self.leaf_start[node], self.leaf_stop[node]
        cnt = b - a
        pos = np.repeat(a, cnt) + (np.arange(cnt.sum()) - np.repeat(np.cumsum(cnt) - cnt, cnt))
        r, f = np.repeat(ray, cnt), self.order[pos]
        if skip is not None:
            keep = f != np.asarray(skip)[r]
            r, f = r[keep], f[keep]
        P0 = V[F[f, 0]]
        e1, e2 = V[F[f, 1]] - P0, V[F[f, 2]] - P0
        d = Dir[r]
        p = np.cross(d, e2)
        det = np.einsum("ij,ij->i", e1, p)
        ok = np.abs(det) > 1e-300
        idet = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
        s = O[r] - P0
        u = np.einsum("ij,ij->i", s, p) * idet
        q = np.cross(s, e1)
        v = np.einsum("ij,ij->i", d, q) * idet
        t = np.einsum("ij,ij->i", e2, q) * idet
        hit = ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0)
        np.minimum.at(best, r[hit], t[hit])
        return best
