"""The cross-section of a solid inside a disc: a centroid that moves continuously with the plane.

For a point ``x`` and a plane through it with unit normal ``n``, the region is

    S = {p in the plane : p inside the mesh, |p - x| <= R},

the part's cross-section near ``x``. Its area and area centroid are continuous functions of the
plane: where the plane sweeps over a saddle and two loops of the section join, S just grows by
the area that joins them (choosing one loop instead jumps; :mod:`.sections`). The disc also
keeps the section local: at a limb's root a plane across the limb takes in only the body within
``R``.

Computed exactly from the section polygon (the mesh's cut segments, inside on their left seen
along ``n``) by the fan formula about ``x``: each segment's part inside the disc gives the
triangle (x, p, q); the boundary of S also runs along the circle, from each point where the
section leaves the disc counter-clockwise to the next where it enters, and each such arc gives
its sector. A disc no section crosses is all inside S or all outside (one inside test decides).

Derivatives with respect to ``x`` and ``n`` are carried along by forward-mode differentiation
(:class:`_Dual`: every quantity with its 6 partial derivatives), from the crossing points' exact
derivatives (``dq/dx = (b - a) n^T / n.(b - a)``, ``dq/dn = (b - a)(x - q)^T / n.(b - a)``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .inside import InsideTest
from .face_tree import FaceTree
from .rows import row_cross

__all__ = ["DiscSections", "disc_sections"]


class _Dual:
    """Values (k, ...) with their derivatives (k, ..., 6) in the plane's point (3) and normal
    (3): just the operations the fan formula needs."""

    __slots__ = ("v", "d")

    def __init__(self, v, d):
        self.v, self.d = v, d

    def __add__(self, o):
        return _Dual(self.v + o.v, None if self.d is None else self.d + o.d)

    def __sub__(self, o):
        return _Dual(self.v - o.v, None if self.d is None else self.d - o.d)

    def scale(self, s):
        """Times a dual scalar per row ``s`` (values (k,), derivatives (k, 6))."""
        if self.d is None:
            return _Dual(self.v * (s.v if self.v.ndim == 1 else s.v[:, None]), None)
        if self.v.ndim == 1:
            return _Dual(self.v * s.v, self.d * s.v[:, None] + self.v[:, None] * s.d)
        return _Dual(self.v * s.v[:, None],
                     self.d * s.v[:, None, None] + self.v[:, :, None] * s.d[:, None, :])

    def times(self, c):
        """Times a constant (an array broadcasting over rows, or a number)."""
        c = np.asarray(c, np.float64)
        if self.d is None:
            return _Dual(self.v * (c if self.v.ndim == 1 or c.ndim == 0 else c[:, None]), None)
        if self.v.ndim == 1 or c.ndim == 0:
            return _Dual(self.v * c, self.d * (c[..., None] if c.ndim else c))
        return _Dual(self.v * c[:, None], self.d * c[:, None, None])

    def take(self, idx):
        return _Dual(self.v[idx], None if self.d is None else self.d[idx])


def _dot(a, b):
    if a.d is None:
        return _Dual(np.einsum("ij,ij->i", a.v, b.v), None)
    return _Dual(np.einsum("ij,ij->i", a.v, b.v),
                 np.einsum("ijk,ij->ik", a.d, b.v) + np.einsum("ij,ijk->ik", a.v, b.d))


def _cross(a, b):
    v = row_cross(a.v, b.v)
    if a.d is None:
        return _Dual(v, None)
    # d(a x b) = da x b + a x db, per derivative direction
    da = np.stack([row_cross(a.d[:, :, k], b.v) for k in range(6)], axis=2)
    db = np.stack([row_cross(a.v, b.d[:, :, k]) for k in range(6)], axis=2)
    return _Dual(v, da + db)


def _atan2(y, x):
    if y.d is None:
        return _Dual(np.arctan2(y.v, x.v), None)
    r2 = np.maximum(y.v * y.v + x.v * x.v, 1e-300)
    return _Dual(np.arctan2(y.v, x.v), (x.v[:, None] * y.d - y.v[:, None] * x.d) / r2[:, None])


def _sin_cos(a):
    s, c = np.sin(a.v), np.cos(a.v)
    if a.d is None:
        return _Dual(s, None), _Dual(c, None)
    return _Dual(s, c[:, None] * a.d), _Dual(c, -s[:, None] * a.d)


def _const(v, want=True):
    v = np.asarray(v, np.float64)
    return _Dual(v, np.zeros(v.shape + (6,)) if want else None)


@dataclass(frozen=True)
class DiscSections:
    """The section inside a disc round each of ``k`` points.

    Attributes
    ----------
    centroid : (k, 3) float
        Area centroid of the region (the point itself where the region is empty).
    area : (k,) float
        Its area (0: the disc lies outside the solid).
    dc_dx, dc_dn : (k, 3, 3) float or None
        Jacobians of the centroid with respect to the point and the normal (a free 3-vector;
        the caller chains its own normalisation).
    """

    centroid: np.ndarray
    area: np.ndarray
    dc_dx: np.ndarray | None = None
    dc_dn: np.ndarray | None = None


def disc_sections(V, F, X, N, R, *, tree=None, inside=None, jacobian=False) -> DiscSections:
    """The cross-section of the mesh inside the disc of radius ``R[k]`` round ``X[k]`` in the
    plane through it normal to ``N[k]``.

    Parameters
    ----------
    V : (n, 3) float, F : (m, 3) int
        A closed, consistently outward-oriented triangle mesh.
    X, N : (k, 3) float
        Points and unit normals of the planes.
    R : (k,) float or float
        The discs' radii.
    tree : FaceTree, optional
        The mesh's :class:`.face_tree.FaceTree` (built here if not given).
    inside : callable, optional
        The mesh's inside test (``inside(P) -> bool``), for discs no section crosses (built
        here if not given).
    jacobian : bool

    Returns
    -------
    DiscSections

    Examples
    --------
    >>> import numpy as np
    >>> V = np.array([[x, y, z] for x in (0., 1) for y in (0., 1) for z in (0., 1)])
    >>> F = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
    ...               [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
    >>> s = disc_sections(V, F, [[0.5, 0.2, 0.5]], [[1.0, 0, 0]], [0.3])
    >>> np.round(s.centroid, 4).tolist(), round(float(s.area[0]), 4)   # the disc, cut at y = 0
    ([[0.5, 0.2296, 0.5]], 0.2518)
    """
    V = np.asarray(V, np.float64)
    F = np.asarray(F, np.int64).reshape(-1, 3)
    X = np.asarray(X, np.float64).reshape(-1, 3)
    N = np.asarray(N, np.float64).reshape(-1, 3)
    k = len(X)
    R = np.broadcast_to(np.asarray(R, np.float64), (k,)).copy()
    tree = FaceTree(V, F) if tree is None else tree
    # per plane: the area A and the first moment M about its point, as duals
    A = _const(np.zeros(k), jacobian)
    M = _const(np.zeros((k, 3)), jacobian)
    n_dual = _Dual(N, np.concatenate([np.zeros((k, 3, 3)), np.broadcast_to(np.eye(3), (k, 3, 3))], 2)
                   if jacobian else None)
    crossings = []                               # (plane, angle, is_exit, point dual)
    pi, fi = tree.cut_by_planes(X, N, R) if k else (np.zeros(0, np.int64),) * 2
    if len(pi):
        h = np.einsum("fcd,fd->fc", tree.corners[fi] - X[pi][:, None, :], N[pi])
        neg = h < 0
        cut = neg.any(axis=1) & ~neg.all(axis=1)
        pi, fi, h, neg = pi[cut], fi[cut], h[cut], neg[cut]
    if len(pi):
        a, b = _segment_ends(V, tree.F[fi], N, X, pi, h, neg, tree.normals[fi], jacobian)
        A, M, crossings = _fan(a, b, pi, X, n_dual, R, A, M)
    A, M = _arcs(crossings, X, N, n_dual, R, A, M, inside, V, F)
    area = A.v
    ok = area > 0
    centroid = X.copy()
    c = M.v[ok] / area[ok, None]
    centroid[ok] += c
    dc_dx = dc_dn = None
    if jacobian:
        # c = x + M / A:  dc = dx + dM / A - M dA / A^2
        Jc = np.zeros((k, 3, 6))
        Jc[ok] = (M.d[ok] / area[ok, None, None]
                  - M.v[ok][:, :, None] * A.d[ok][:, None, :] / (area[ok] ** 2)[:, None, None])
        Jc[:, :, :3] += np.eye(3)
        dc_dx, dc_dn = Jc[:, :, :3], Jc[:, :, 3:]
    return DiscSections(centroid, area, dc_dx, dc_dn)


def _segment_ends(V, Fc, N, X, pi, h, neg, fn, want):
    """The two ends of each cut face's segment, relative to its plane's point, as duals
    (values only unless ``want``), oriented with the section's inside on the left seen
    along n."""
    f = len(Fc)
    P = np.empty((2, f, 3))
    Pd = np.empty((2, f, 3, 6)) if want else None
    slot = np.zeros(f, np.int64)
    rows = np.arange(f)
    x, n = X[pi], N[pi]
    for i, j in ((0, 1), (1, 2), (2, 0)):
        hit = rows[neg[:, i] != neg[:, j]]
        va, vb = Fc[hit, i], Fc[hit, j]
        first = va < vb
        lo, hi = np.where(first, va, vb), np.where(first, vb, va)
        hlo = np.where(first, h[hit, i], h[hit, j])
        hhi = np.where(first, h[hit, j], h[hit, i])
        w = hlo / (hlo - hhi)
        Va = V[lo]
        d = V[hi] - Va
        q = Va + w[:, None] * d
        sl = slot[hit]
        P[sl, hit] = q - x[hit]                                  # relative to the point
        if want:
            den = np.einsum("ij,ij->i", n[hit], d)[:, None, None]
            dq_dx = d[:, :, None] * n[hit][:, None, :] / den
            dq_dn = d[:, :, None] * (x[hit] - q)[:, None, :] / den
            Pd[sl, hit] = np.concatenate([dq_dx - np.eye(3), dq_dn], axis=2)
        slot[hit] += 1
    dvec = P[1] - P[0]
    flip = np.einsum("ij,ij->i", row_cross(n, dvec), fn) > 0
    o0, o1 = flip.astype(np.int64), 1 - flip.astype(np.int64)
    if not want:
        return _Dual(P[o0, rows], None), _Dual(P[o1, rows], None)
    return _Dual(P[o0, rows], Pd[o0, rows]), _Dual(P[o1, rows], Pd[o1, rows])


def _fan(a, b, pi, X, n_dual, R, A, M):
    """Each segment's part inside the disc: the triangle (x, p, q) into A and M; the points where
    segments cross the circle, for the arcs."""
    d = b - a
    dd = _dot(d, d)
    ad = _dot(a, d)
    aa = _dot(a, a)
    Rp = R[pi]
    disc = ad.v ** 2 - dd.v * (aa.v - Rp ** 2)
    has = (disc > 0) & (dd.v > 0)
    sq = np.sqrt(np.where(has, disc, 0.0))
    inv = 1.0 / np.where(dd.v > 0, dd.v, 1.0)
    t_lo = np.where(has, (-ad.v - sq) * inv, np.inf)
    t_hi = np.where(has, (-ad.v + sq) * inv, -np.inf)
    s0 = np.clip(t_lo, 0.0, 1.0)
    s1 = np.clip(t_hi, 0.0, 1.0)
    inside = has & (s1 > s0)
    # dual t of a circle crossing: |a + t d| = R: t = (-a.d -+ sqrt(D)) / d.d, differentiated
    # implicitly: (w.d) dt = -w.(da + t dd)
    crossings = []
    for t, clipped, entering in ((t_lo, s0, True), (t_hi, s1, False)):
        at = np.flatnonzero(inside & (t > 0) & (t < 1))
        if len(at):
            tt = t[at]
            w_v = a.v[at] + tt[:, None] * d.v[at]
            if a.d is None:
                crossings.append((pi[at], _Dual(w_v, None), not entering))
                continue
            wd = np.einsum("ij,ij->i", w_v, d.v[at])
            base = a.d[at] + tt[:, None, None] * d.d[at]
            dt = -np.einsum("ij,ijk->ik", w_v, base) / np.where(np.abs(wd) > 0, wd, 1e-300)[:, None]
            w = _Dual(w_v, base + d.v[at][:, :, None] * dt[:, None, :])
            crossings.append((pi[at], w, not entering))        # (plane, point, is_exit)
    # the inside parts: p = a + s0 d, q = a + s1 d (s0, s1 the clipped parameters, duals where
    # they are circle crossings)
    sel = np.flatnonzero(inside)
    if len(sel):
        p = _end(a, d, s0, t_lo, sel, entering=True)
        q = _end(a, d, s1, t_hi, sel, entering=False)
        nd = n_dual.take(pi[sel])
        tri = _dot(_cross(p, q), nd).times(0.5)                # signed area of (x, p, q)
        mom = (p + q).scale(tri).times(1.0 / 3.0)
        A = _accumulate(A, pi[sel], tri)
        M = _accumulate(M, pi[sel], mom)
    return A, M, crossings


def _end(a, d, s, t, sel, *, entering):
    """The dual point a + s d at the clipped parameter s: where s is the circle crossing t
    (0 < t < 1) its derivative follows t's; at a segment end (s = 0 or 1) it is the end's."""
    av, ad_ = a.v[sel], None if a.d is None else a.d[sel]
    dv, dd_ = d.v[sel], None if d.d is None else d.d[sel]
    sv = s[sel]
    on = (t[sel] > 0) & (t[sel] < 1)
    w_v = av + sv[:, None] * dv
    if ad_ is None:
        return _Dual(w_v, None)
    base = ad_ + sv[:, None, None] * dd_
    wd = np.einsum("ij,ij->i", w_v, dv)
    dt = -np.einsum("ij,ijk->ik", w_v, base) / np.where(np.abs(wd) > 0, wd, 1e-300)[:, None]
    dt = np.where(on[:, None], dt, 0.0)
    return _Dual(w_v, base + dv[:, :, None] * dt[:, None, :])


def _accumulate(total, rows, part):
    k = len(total.v)
    if part.d is None:
        if part.v.ndim == 1:
            return _Dual(total.v + np.bincount(rows, part.v, k), None)
        return _Dual(total.v + np.stack([np.bincount(rows, part.v[:, c], k) for c in range(3)], 1), None)
    if part.v.ndim == 1:
        v = np.bincount(rows, part.v, k)
        d = np.stack([np.bincount(rows, part.d[:, j], k) for j in range(6)], 1)
    else:
        v = np.stack([np.bincount(rows, part.v[:, c], k) for c in range(3)], 1)
        d = np.stack([np.stack([np.bincount(rows, part.d[:, c, j], k) for j in range(6)], 1)
                      for c in range(3)], 1)
    return total + _Dual(v, d)


def _arcs(crossings, X, N, n_dual, R, A, M, inside, V, F):
    """The circle's arcs that bound the region: from each point where the section leaves the
    disc, counter-clockwise about n to the next where it enters; a disc no section crosses is
    all inside or all outside the solid."""
    k = len(X)
    crossed = np.zeros(k, bool)
    if crossings:
        plane = np.concatenate([c[0] for c in crossings])
        w = _Dual(np.concatenate([c[1].v for c in crossings]),
                  None if n_dual.d is None else np.concatenate([c[1].d for c in crossings]))
        is_exit = np.concatenate([np.full(len(c[0]), c[2]) for c in crossings])
        crossed[plane] = True
        # angles about n in a frame of each plane, to order the crossings round the circle
        e1 = _perpendicular(N)
        e2 = row_cross(N, e1)
        ang = np.arctan2(np.einsum("ij,ij->i", w.v, e2[plane]), np.einsum("ij,ij->i", w.v, e1[plane]))
        order = np.lexsort((ang, plane))
        plane, ang, is_exit = plane[order], ang[order], is_exit[order]
        w = w.take(order)
        start = np.searchsorted(plane, plane, side="left")
        stop = np.searchsorted(plane, plane, side="right")
        nxt = np.where(np.arange(len(plane)) + 1 < stop, np.arange(len(plane)) + 1, start)
        ex = np.flatnonzero(is_exit & ~is_exit[nxt])          # an exit followed by an entry
        if len(ex):
            p, q = w.take(ex), w.take(nxt[ex])
            pl = plane[ex]
            nd = n_dual.take(pl)
            # the CCW angle from p to q in [0, 2 pi): atan2 gives (-pi, pi]; an exit and the
            # next entry CCW can span more than pi
            delta = _atan2(_dot(_cross(p, q), nd), _dot(p, q))
            delta = _Dual(np.where(delta.v < 0, delta.v + 2 * np.pi, delta.v), delta.d)
            Rp = R[pl]
            area = delta.times(0.5 * Rp ** 2)
            # sector moment: (R^3/3) (sin delta e + (1 - cos delta) (n x e)), e = p / R
            sin_d, cos_d = _sin_cos(delta)
            e = p.times(1.0 / Rp)
            ne = _cross(nd, e)
            one_minus = _Dual(1.0 - cos_d.v, None if cos_d.d is None else -cos_d.d)
            mom = (e.scale(sin_d) + ne.scale(one_minus)).times(Rp ** 3 / 3.0)
            A = _accumulate(A, pl, area)
            M = _accumulate(M, pl, mom)
    free = np.flatnonzero(~crossed)
    if len(free):
        # no section crosses the circle: it lies all inside the solid or all outside
        probe = X[free] + R[free, None] * _perpendicular(N[free])
        test = inside if inside is not None else _inside_of(V, F)
        full = free[test(probe)]
        if len(full):
            disc = _const(np.zeros(k), n_dual.d is not None)
            disc.v[full] = np.pi * R[full] ** 2
            A = A + disc
    return A, M


def _perpendicular(N):
    """A unit vector perpendicular to each row of N (a continuous choice away from one axis)."""
    helper = np.where(np.abs(N[:, :1]) < 0.9, np.array([[1.0, 0, 0]]), np.array([[0, 1.0, 0]]))
    e = row_cross(N, helper)
    return e / np.maximum(np.linalg.norm(e, axis=1), 1e-300)[:, None]


def _inside_of(V, F):
    return InsideTest(V, F)
