"""Inside test of a closed triangle mesh: ray parity, built once, queried many times.

Used by the guards (no bone outside the mesh) and by the measures. The rays are random lines
(seeded), so rays along a procedural mesh's symmetry planes do not graze its edges; three rays
vote.

With ``union=True`` a ray counts its crossings with their signs (the winding number) instead of
their parity: a point is inside when it is inside any of the mesh's closed, outward parts. Where
parts overlap (a limb pushed into a body) parity calls the overlap outside; the winding number
sees the solid the parts make together. On parts that do not overlap the two agree.
"""

from __future__ import annotations

import numpy as np

from ..config import CONFIG


__all__ = ["InsideTest", "inside_mesh"]

_NUM = CONFIG.numerics


class _RayGrid:
    """Triangles rotated by ``R`` and bucketed in 2D grids orthogonal to the ray (+x after the
    rotation); built once, then queried for any number of points.

    Every triangle is stored in one level only: the finest of a stack of square grids (cells
    ``_NUM.grid_level`` times wider from one level to the next; the finest at least as wide as the median
    triangle and about ``_NUM.grid_cell_faces`` triangles per cell of the bounding box) where it spans at
    most two cells per axis, in the 1-4 cells it overlaps there. A point then reads its own
    cell on every level. At most 4 entries per triangle whatever its shape (the long slivers of
    a cap would otherwise fill hundreds of cells each) and a radix sort make the build O(faces)
    with a small constant: the pipeline's queries are a few thousand points, so the build
    dominates.
    """

    def __init__(self, V, F, R):
        self.R = R
        self.Vr = Vr = V @ R.T
        self.F = F
        m = len(F)
        # the two grid axes (y, z after the rotation) as separate columns: numpy's operations
        # on (m, 2) arrays with a (2,) operand go one row at a time (2-4x slower; the same values)
        Y = [np.ascontiguousarray(Vr[:, 1]), np.ascontiguousarray(Vr[:, 2])]
        lo, hi = [], []
        for y in Y:
            a, b, c = y.take(F[:, 0]), y.take(F[:, 1]), y.take(F[:, 2])
            lo.append(np.minimum(np.minimum(a, b), c))
            hi.append(np.maximum(np.maximum(a, b), c))
        del a, b, c
        self.glo = glo = np.array([y.min() for y in Y]) if len(Vr) else np.zeros(2)
        self.ghi = np.array([y.max() for y in Y]) if len(Vr) else np.zeros(2)
        ext = np.maximum(self.ghi - glo, 1e-300)
        side = np.sqrt(ext[0] * ext[1] * _NUM.grid_cell_faces / max(m, 1))
        if m:
            side = max(side, _NUM.grid_side_median * float(np.median(np.maximum(hi[0] - lo[0],
                                                                       hi[1] - lo[1]))))
        self.levels = []
        tris, n_prev = [], 0
        rest = np.arange(m, dtype=np.int32 if m < 2**31 else np.int64)
        lo_r, hi_r = lo, hi
        while True:
            G = np.clip(np.ceil(ext / max(side, 1e-300)), 1, 2048).astype(np.int64)
            cell = ext / G
            i0, span = [], []
            for x in range(2):
                i = ((lo_r[x] - glo[x]) / cell[x]).astype(np.int32)
                np.clip(i, 0, np.int32(G[x] - 1), out=i)
                s = ((hi_r[x] - glo[x]) / cell[x]).astype(np.int32)
                np.clip(s, 0, np.int32(G[x] - 1), out=s)
                s -= i
                i0.append(i)
                span.append(s)
            here = (span[0] <= 1) & (span[1] <= 1)
            # each triangle of this level in every cell it overlaps (1, 2 or 4): one sort of the
            # triangles by their lower corner's cell; the four runs (corner, +z, +y, +y+z cell)
            # are then each sorted by cell (a shift keeps the order) and are scattered into cell
            # order by counting, without sorting the entries
            h_tri = rest[here]
            nc = int(G[0] * G[1])
            base = i0[0][here].astype(np.int64) * G[1] + i0[1][here]
            o = _radix_argsort(base, nc)
            base, h_tri = base.take(o), h_tri.take(o)
            h_span = [span[0][here].take(o), span[1][here].take(o)]
            runs = []
            for a, b in ((0, 0), (0, 1), (1, 0), (1, 1)):
                sel = (h_span[0] >= a) & (h_span[1] >= b)
                k = base[sel] + (a * G[1] + b)
                runs.append((k, h_tri[sel], np.bincount(k, minlength=nc)))
            starts = np.concatenate([[0], np.cumsum(sum(c for _, _, c in runs))])
            out = np.empty(int(starts[-1]), rest.dtype)
            before = np.zeros(nc, np.int64)
            for k, t, c in runs:
                rank = np.arange(len(k)) - (np.cumsum(c) - c)[k]     # rank in its cell's run
                out[starts[k] + before[k] + rank] = t
                before += c
            tris.append(out)
            # cell starts into the concatenation of every level's sorted triangles
            starts = starts + n_prev
            n_prev += len(out)
            self.levels.append((G, cell, starts))
            far = ~here
            rest = rest[far]
            lo_r, hi_r = [x[far] for x in lo_r], [x[far] for x in hi_r]
            if not rest.size:
                break
            side *= _NUM.grid_level
        self.tri = np.concatenate(tris)

    def _sources(self, P2):
        """Per point (k, 2) (yz, rotated): (k, levels) starts and counts in ``self.tri`` of
        the triangles of the point's cell on every level."""
        S, N = [], []
        for G, cell, starts in self.levels:
            pc = np.clip(((P2 - self.glo) / cell).astype(np.int64), 0, G - 1)
            cc = pc[:, 0] * G[1] + pc[:, 1]
            S.append(starts[cc])
            N.append(starts[cc + 1] - starts[cc])
        return np.stack(S, axis=1), np.stack(N, axis=1)

    def parity(self, P):
        """Parity of crossings of the ray from each point (n, 3) along the grid's direction."""
        return self.parities(P)[0]

    def parities(self, P, union=False):
        """Parities of crossings of the two rays from each point (n, 3) along the grid's line,
        forwards and backwards: (n,) int each. On a closed surface they agree unless the line
        grazes an edge or a vertex, which spoils one side only (the graze is on one side of the
        point): two independent votes for the price of one grid. ``union``: 1 where the signed
        count of crossings (the winding number) is not zero instead (inside any outward part)."""
        glo, ghi = self.glo, self.ghi
        Pr = P @ self.R.T
        parity = np.zeros(len(P), np.int64)
        back = np.zeros(len(P), np.int64)
        pin = np.all((Pr[:, 1:] >= glo) & (Pr[:, 1:] <= ghi), axis=1)
        pids = np.flatnonzero(pin)
        S, N = self._sources(Pr[pids, 1:])
        n_per = N.sum(axis=1)
        # expand (point, triangle) pairs in chunks of points of about _NUM.block pairs
        cum = np.cumsum(n_per)
        s = 0
        while s < len(pids):
            e = int(np.searchsorted(cum, (cum[s - 1] if s else 0) + _NUM.block, side="right"))
            e = min(max(e, s + 1), len(pids))
            nn = N[s:e].ravel()
            pp = np.repeat(np.repeat(pids[s:e], N.shape[1]), nn)
            off = np.arange(nn.sum()) - np.repeat(np.cumsum(nn) - nn, nn)
            tt = self.tri[np.repeat(S[s:e].ravel(), nn) + off]
            s = e
            t = self.Vr[self.F[tt]]                      # (pairs, 3, 3)
            py, pz = Pr[pp, 1], Pr[pp, 2]
            y, z = t[:, :, 1], t[:, :, 2]
            # edge functions of (py, pz) against the three edges in the yz-plane
            w0 = (y[:, 1] - py) * (z[:, 2] - pz) - (y[:, 2] - py) * (z[:, 1] - pz)
            w1 = (y[:, 2] - py) * (z[:, 0] - pz) - (y[:, 0] - py) * (z[:, 2] - pz)
            w2 = (y[:, 0] - py) * (z[:, 1] - pz) - (y[:, 1] - py) * (z[:, 0] - pz)
            hit = ((w0 > 0) & (w1 > 0) & (w2 > 0)) | ((w0 < 0) & (w1 < 0) & (w2 < 0))
            ws = w0 + w1 + w2
            with np.errstate(divide="ignore", invalid="ignore"):
                xh = (w0 * t[:, 0, 0] + w1 * t[:, 1, 0] + w2 * t[:, 2, 0]) / ws
            ahead = xh > Pr[pp, 0]
            fwd, bwd = hit & ahead, hit & (xh < Pr[pp, 0])
            # the sign of the projected area says which way the face's normal crosses the ray
            sign = np.where(ws > 0, 1, -1) if union else np.ones(len(ws), np.int64)
            parity += np.bincount(pp[fwd], sign[fwd], minlength=len(P)).astype(np.int64)
            back += np.bincount(pp[bwd], sign[bwd], minlength=len(P)).astype(np.int64)
        if union:
            return (parity != 0).astype(np.int64), (back != 0).astype(np.int64)
        return parity % 2, back % 2


def _radix_argsort(key, n_keys):
    """Stable argsort of non-negative integer keys below ``n_keys`` by 16-bit radix passes
    (numpy's stable sort of 16-bit integers is a counting sort: O(n), 2-3x faster than a
    comparison sort of int64)."""
    key = np.asarray(key, np.int64)
    order = np.arange(len(key))
    shift = 0
    while True:
        digit = ((key[order] >> shift) & 0xFFFF).astype(np.uint16)
        order = order[np.argsort(digit, kind="stable")]
        shift += 16
        if (n_keys - 1) >> shift <= 0:
            return order


class InsideTest:
    """Inside test of a closed triangle mesh, built once and queried many times.

    Ray parity along ``n_rays`` rays (majority vote): both ways along a random line, then along
    a second line where those two disagree. Each line is a random rotation (seeded), so rays
    along symmetry planes of a procedural mesh do not graze its edges; a grazing ray can
    miscount, the vote absorbs it (a graze spoils one way only). Building costs O(faces) per
    line, a query O(points) plus the triangles in the points' grid cells.

    Parameters
    ----------
    V : (nv, 3) float
    F : (m, 3) int
    seed : int
    n_rays : int, odd
    union : bool
        Inside any of the mesh's outward parts (the winding number), not by parity: see the
        module's doc.

    Examples
    --------
    >>> test = InsideTest(V, F)            # doctest: +SKIP
    >>> test(np.zeros((1, 3)))             # doctest: +SKIP
    array([ True])
    """

    def __init__(self, V, F, *, seed=0, n_rays=None, union=False):
        n_rays = CONFIG.input.inside_rays if n_rays is None else n_rays
        self.union = bool(union)
        self._V = np.asarray(V, dtype=np.float64)
        self._F = np.asarray(F, dtype=np.int64)
        self.n_rays = n_rays
        rng = np.random.default_rng(seed)
        self._rotations = []
        for _ in range((n_rays + 1) // 2):             # two rays (both ways) per line
            Q, Rm = np.linalg.qr(rng.normal(size=(3, 3)))
            self._rotations.append(Q * np.sign(np.diag(Rm)))
        self._grids: list = [None] * len(self._rotations)

    def _grid(self, k):
        # Built on first use: once a majority agrees the other lines are not needed (on a
        # closed mesh the two ways along the first line nearly always agree; a grid costs
        # O(faces)).
        if self._grids[k] is None:
            self._grids[k] = _RayGrid(self._V, self._F, self._rotations[k])
        return self._grids[k]

    def __call__(self, P):
        """(n,) bool: whether each point of ``P`` (n, 3) is inside."""
        P = np.asarray(P, dtype=np.float64).reshape(-1, 3)
        n = self.n_rays
        need = n // 2 + 1                               # votes that decide
        votes = np.zeros(len(P), np.int64)
        open_ = np.arange(len(P))
        # The rays in order: both ways along the first grid's line, then the next grids' lines
        # (one way, or both if the votes still need two): one grid decides nearly every point.
        k = cast = 0
        while cast < n and open_.size:
            ahead, back = self._grid(k).parities(P[open_], self.union)
            both = cast + 2 <= n
            votes[open_] += ahead + back if both else ahead
            cast += 2 if both else 1
            k += 1
            # Still open: no majority yet, and the rays left could still make one.
            v = votes[open_]
            open_ = open_[(v < need) & (v + n - cast >= need)]
        return votes >= need


def inside_mesh(P, V, F, *, seed=0, n_rays=None):
    """Whether each point is inside a closed triangle mesh (ray parity, majority of ``n_rays``).

    One-off form of :class:`InsideTest` (build and query once).

    Parameters
    ----------
    P : (n, 3) float
    V : (nv, 3) float
    F : (m, 3) int
    seed : int
    n_rays : int, odd

    Returns
    -------
    (n,) bool
    """
    return InsideTest(V, F, seed=seed, n_rays=n_rays)(P)
