"""Cross-sections of a closed triangle mesh by planes, with the derivative of their centroids.

The plane through a point ``x`` with unit normal ``n`` cuts the surface in closed loops; the
loop that winds round ``x`` (the innermost one, when loops nest) bounds the part's
cross-section there. Its area centroid is the centre of the part across ``n``: a tube's axis,
the middle of a plate's strip, whatever the section's shape. The centring term of the
objective (:mod:`..objective.terms`) pulls each chain joint towards it.

Each crossing point lies on a mesh edge ``(a, b)``: ``q = a + w (b - a)`` with
``w = n.(x - a) / n.(b - a)``, so, for a fixed loop, ``q`` and hence the centroid are smooth
functions of the plane:

    dq/dx = (b - a) n^T / n.(b - a),      dq/dn = (b - a) (x - q)^T / n.(b - a).

With ``u = q_k - x``, ``v = q_(k+1) - x`` per segment and ``s = (u x v).n``, the loop's area is
``A = 1/2 sum s`` and its centroid ``c = x + M / A`` with ``M = 1/6 sum (u + v) s`` (the
polygon formulas, about ``x``); :func:`cross_sections` differentiates these through ``q`` by
the chain rule (``jacobian=True``). The derivative holds while the loop keeps its edges: a
plane sweeping over a vertex changes which edges it cuts but not the loop itself, so the
centroid stays continuous there.

Where no closed loop winds round the point within ``reach`` (the plane misses the part, or
the point lies outside the mesh) ``found`` is False and the centroid is the point itself.

Examples
--------
>>> import numpy as np
>>> V = np.array([[x, y, z] for x in (0., 1) for y in (0., 1) for z in (0., 1)])
>>> F = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
...               [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
>>> s = cross_sections(V, F, [[0.5, 0.2, 0.3]], [[1.0, 0, 0]], [2.0])
>>> np.round(s.centroid, 6).tolist(), np.round(s.area, 6).tolist()
([[0.5, 0.5, 0.5]], [1.0])
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from .face_tree import FaceTree
from .rows import row_cross

__all__ = ["Sections", "cross_sections"]


@dataclass(frozen=True)
class Sections:
    """The cross-section round each of ``k`` points.

    Attributes
    ----------
    centroid : (k, 3) float
        Area centroid of the loop round the point (the point itself where none was found).
    area : (k,) float
        The loop's area (0 where none was found).
    spread : (k,) float
        Root mean square distance of the section's area from its centroid: a disc of radius
        ``R`` has ``R / sqrt(2)``; a smooth measure of how far the section reaches.
    found : (k,) bool
    dc_dx, dc_dn : (k, 3, 3) float or None
        Jacobians of the centroid with respect to the plane's point and normal (the normal
        taken as a free 3-vector: the caller chains its own normalisation); zero where none.
    ds_dx, ds_dn : (k, 3) float or None
        Gradients of the spread likewise.
    extent : (k,) float
        The farthest the loop reaches from the point (0 where none was found).
    de_dx, de_dn : (k, 3) float or None
        Gradients of the extent likewise (of its farthest crossing point's distance).
    """

    centroid: np.ndarray
    area: np.ndarray
    spread: np.ndarray
    found: np.ndarray
    dc_dx: np.ndarray | None = None
    dc_dn: np.ndarray | None = None
    ds_dx: np.ndarray | None = None
    ds_dn: np.ndarray | None = None
    extent: np.ndarray | None = None
    de_dx: np.ndarray | None = None
    de_dn: np.ndarray | None = None


def cross_sections(V, F, X, N, reach, *, tree=None, jacobian: bool = False) -> Sections:
    """Cross-section of the mesh by the plane through each point ``X[k]`` normal to ``N[k]``.

    Parameters
    ----------
    V : (n, 3) float, F : (m, 3) int
        A closed, consistently outward-oriented triangle mesh.
    X : (k, 3) float
        Points on the planes.
    N : (k, 3) float
        Unit normals of the planes (a zero row: no plane, nothing found).
    reach : (k,) float or float
        A loop with a point farther than this from ``X[k]`` is not the part's own: ignored.
    tree : FaceTree, optional
        :class:`.face_tree.FaceTree` of the mesh (built here if not given): the faces near
        each plane are found in it.
    jacobian : bool
        Also return the centroids' derivatives (see the module docstring).

    Returns
    -------
    Sections
    """
    V = np.asarray(V, np.float64)
    F = np.asarray(F, np.int64).reshape(-1, 3)
    X = np.asarray(X, np.float64).reshape(-1, 3)
    N = np.asarray(N, np.float64).reshape(-1, 3)
    k = len(X)
    reach = np.broadcast_to(np.asarray(reach, np.float64), (k,))
    centroid, area = X.copy(), np.zeros(k)
    spread, found = np.zeros(k), np.zeros(k, bool)
    dc_dx = np.zeros((k, 3, 3)) if jacobian else None
    dc_dn = np.zeros((k, 3, 3)) if jacobian else None
    ds_dx = np.zeros((k, 3)) if jacobian else None
    ds_dn = np.zeros((k, 3)) if jacobian else None
    extent = np.zeros(k)
    de_dx = np.zeros((k, 3)) if jacobian else None
    de_dn = np.zeros((k, 3)) if jacobian else None
    empty = Sections(centroid, area, spread, found, dc_dx, dc_dn, ds_dx, ds_dn, extent, de_dx,
                     de_dn)
    if not k or not len(F):
        return empty
    if tree is None:
        tree = FaceTree(V, F)
    pi, fi = tree.cut_by_planes(X, N, reach)
    if not len(pi):
        return empty
    h = np.einsum("fcd,fd->fc", tree.corners[fi] - X[pi][:, None, :], N[pi])
    neg = h < 0
    cut = neg.any(axis=1) & ~neg.all(axis=1)
    pi, fi, h, neg = pi[cut], fi[cut], h[cut], neg[cut]
    if not len(pi):
        return empty
    seg = _segments(V, tree.F[fi], N, pi, h, neg, tree.normals[fi])
    loops = _loops(seg, X, N)
    if loops is None:
        return empty
    seg_loop, owner, chosen = loops
    keep = np.isin(seg_loop, chosen)
    lid = np.full(int(seg_loop.max()) + 1, -1, np.int64)
    lid[chosen] = np.arange(len(chosen))
    sl = lid[seg_loop[keep]]
    pts = owner[chosen]
    xp = X[pi[keep]]
    nv = N[pi[keep]]
    u = seg.p[keep] - xp
    v = seg.q[keep] - xp
    s = np.einsum("ij,ij->i", row_cross(u, v), nv)
    L = len(chosen)
    A = np.bincount(sl, s, L) / 2.0
    M = np.stack([np.bincount(sl, (u[:, c] + v[:, c]) * s, L) for c in range(3)], 1) / 6.0
    # second moment about x (the polygon formula), then about the centroid
    uu = np.einsum("ij,ij->i", u, u) + np.einsum("ij,ij->i", u, v) + np.einsum("ij,ij->i", v, v)
    I0 = np.bincount(sl, s * uu, L) / 12.0
    ok = A > 0
    pts, A, M, I0, chosen_ok = pts[ok], A[ok], M[ok], I0[ok], np.flatnonzero(ok)
    m = M / A[:, None]
    centroid[pts] = X[pts] + m
    area[pts] = A
    spread[pts] = np.sqrt(np.maximum(I0 / A - np.einsum("ij,ij->i", m, m), 0.0))
    found[pts] = True
    # the extent: every crossing point is the first end (p) of one segment of its loop
    sel = np.isin(sl, chosen_ok)
    remap = np.full(L, -1, np.int64)
    remap[chosen_ok] = np.arange(len(chosen_ok))
    loop_ok = remap[sl[sel]]
    du2 = np.einsum("ij,ij->i", u[sel], u[sel])
    far = np.zeros(len(chosen_ok))
    np.maximum.at(far, loop_ok, du2)
    extent[pts] = np.sqrt(far)
    if jacobian and len(pts):
        _centroid_jacobian(seg, keep, sel, loop_ok, u[sel], v[sel], s[sel], nv[sel],
                           xp[sel], A, M, I0, spread[pts], pts, (dc_dx, dc_dn), (ds_dx, ds_dn))
        # the farthest crossing point of each loop: d|u| = u^T du / |u|, u = p - x
        at = np.flatnonzero(du2 == far[loop_ok])
        at = at[np.unique(loop_ok[at], return_index=True)[1]]
        idx = np.flatnonzero(keep)[sel][at]
        um = u[sel][at]
        nvm = nv[sel][at]
        d = seg.pd[idx]
        den = np.einsum("ij,ij->i", nvm, d)
        unit = um / np.maximum(np.sqrt(du2[at]), 1e-300)[:, None]
        # dp/dx = d n^T / (n.d): u^T dp/dx = (u.d) n^T / (n.d); du/dx = dp/dx - I
        ud = np.einsum("ij,ij->i", unit, d) / den
        de_dx[pts[loop_ok[at]]] = ud[:, None] * nvm - unit
        de_dn[pts[loop_ok[at]]] = ud[:, None] * (xp[sel][at] - seg.p[idx])
    return Sections(centroid, area, spread, found, dc_dx, dc_dn, ds_dx, ds_dn, extent, de_dx,
                    de_dn)


@dataclass
class _Segments:
    p: np.ndarray        # (f, 3) first end (the section's inside on its left, seen along n)
    q: np.ndarray        # (f, 3) second end
    pa: np.ndarray       # (f, 3) p's edge: start vertex
    pd: np.ndarray       # (f, 3) p's edge: end - start
    qa: np.ndarray       # (f, 3) q's edge
    qd: np.ndarray
    key: np.ndarray      # (f, 2) one key per (cut edge, point): joins segments into loops
    point: np.ndarray    # (f,) the point whose plane cut this face


def _segments(V, Fc, N, pi, h, neg, fn) -> _Segments:
    """The segment each cut face (corners ``Fc``, corner heights ``h`` above its point's plane,
    outward normal ``fn``) leaves in the plane, oriented with the section's inside on its
    left (the face's normal, projected into the plane, points to its right)."""
    f = len(Fc)
    ends = np.empty((2, f, 3))
    edge_a = np.empty((2, f, 3))
    edge_d = np.empty((2, f, 3))
    key = np.empty((f, 2), np.int64)
    slot = np.zeros(f, np.int64)
    rows = np.arange(f)
    n, k = len(V), int(pi.max()) + 1
    for a, b in ((0, 1), (1, 2), (2, 0)):
        hit = rows[neg[:, a] != neg[:, b]]
        va, vb = Fc[hit, a], Fc[hit, b]
        first = va < vb
        lo, hi = np.where(first, va, vb), np.where(first, vb, va)
        # measured from the edge's lower-numbered end: both faces of an edge compute one point
        hlo = np.where(first, h[hit, a], h[hit, b])
        hhi = np.where(first, h[hit, b], h[hit, a])
        w = hlo / (hlo - hhi)
        Va = V[lo]
        Vd = V[hi] - Va
        sl = slot[hit]
        ends[sl, hit] = Va + w[:, None] * Vd
        edge_a[sl, hit] = Va
        edge_d[sl, hit] = Vd
        key[hit, sl] = (lo * n + hi) * k + pi[hit]
        slot[hit] += 1
    d = ends[1] - ends[0]
    # inside on the left of p -> q (seen along n): (n x d) points inwards, against the normal
    flip = np.einsum("ij,ij->i", row_cross(N[pi], d), fn) > 0
    o0, o1 = flip.astype(np.int64), 1 - flip.astype(np.int64)
    return _Segments(ends[o0, rows], ends[o1, rows], edge_a[o0, rows], edge_d[o0, rows],
                     edge_a[o1, rows], edge_d[o1, rows],
                     np.stack([key[rows, o0], key[rows, o1]], 1), pi)


def _loops(seg: _Segments, X, N):
    """Segments joined into loops; per point its innermost closed loop winding round it (the
    smallest positive area), or, for a point no loop winds round (it lies outside the part),
    the closed loop whose centroid is nearest: a point crossing the surface keeps its loop, so
    the centroid, and J, do not jump there. Returns (loop of each segment, point of each loop,
    chosen loops) or None when no point has one."""
    f = len(seg.p)
    uk, inv = np.unique(seg.key.ravel(), return_inverse=True)
    inv = inv.reshape(-1, 2)
    G = sp.coo_matrix((np.ones(f), (inv[:, 0], inv[:, 1])), shape=(len(uk), len(uk)))
    nc, lab = connected_components(G, directed=False)
    seg_loop = lab[inv[:, 0]]
    # closed: every cut edge of the loop shared by two of its segments
    ends = np.bincount(inv.ravel(), minlength=len(uk))
    closed = np.ones(nc, bool)
    closed[lab[ends != 2]] = False
    owner = np.zeros(nc, np.int64)
    owner[seg_loop] = seg.point
    u = seg.p - X[seg.point]
    v = seg.q - X[seg.point]
    cr = np.einsum("ij,ij->i", row_cross(u, v), N[seg.point])
    area = np.bincount(seg_loop, cr, nc) / 2.0
    wind = np.bincount(seg_loop, np.arctan2(cr, np.einsum("ij,ij->i", u, v)), nc) / (2 * np.pi)
    good = closed & (area > 0)
    if not good.any():
        return None
    # rank: winding loops first (innermost: smallest area), then the others by the distance of
    # their centroid (M / A about the point, the polygon formula)
    s_ = cr
    M = np.stack([np.bincount(seg_loop, (u[:, c] + v[:, c]) * s_, nc) for c in range(3)], 1) / 6.0
    dist = np.linalg.norm(M, axis=1) / np.maximum(np.abs(area), 1e-300)
    winds = wind > 0.5
    cand = np.flatnonzero(good)
    key2 = np.where(winds[cand], area[cand], np.inf)
    cand = cand[np.lexsort((dist[cand], key2, ~winds[cand], owner[cand]))]
    cand = cand[np.r_[True, owner[cand][1:] != owner[cand][:-1]]]
    return seg_loop, owner, cand


def _centroid_jacobian(seg, keep, sel, loop, u, v, s, nv, xp, A, M, I0, spread, pts, dc, dsp):
    """dc/dx, dc/dn and the spread's gradients of the chosen loops (see the module docstring),
    written in place into ``dc`` and ``dsp`` at rows ``pts``."""
    idx = np.flatnonzero(keep)[sel]
    eye = np.eye(3)

    def dq(d, q):
        # dq/dx = d n^T / (n.d), dq/dn = d (x - q)^T / (n.d)
        den = np.einsum("ij,ij->i", nv, d)[:, None, None]
        return (d[:, :, None] * nv[:, None, :]) / den, (d[:, :, None] * (xp - q)[:, None, :]) / den

    dpx, dpn = dq(seg.pd[idx], seg.p[idx])
    dqx, dqn = dq(seg.qd[idx], seg.q[idx])
    vxn = row_cross(v, nv)
    nxu = row_cross(nv, u)
    uxv = row_cross(u, v)
    uu = np.einsum("ij,ij->i", u, u) + np.einsum("ij,ij->i", u, v) + np.einsum("ij,ij->i", v, v)
    L = len(A)
    m = M / A[:, None]
    for name, du, dv in (("x", dpx - eye, dqx - eye), ("n", dpn, dqn)):
        ds = np.einsum("ij,ijk->ik", vxn, du) + np.einsum("ij,ijk->ik", nxu, dv)
        if name == "n":
            ds = ds + uxv
        dA = np.stack([np.bincount(loop, ds[:, c], L) for c in range(3)], 1) / 2.0     # (L, 3)
        term = s[:, None, None] * (du + dv) + (u + v)[:, :, None] * ds[:, None, :]
        dM = np.stack([np.bincount(loop, term[:, r, c], L) for r in range(3) for c in range(3)],
                      1).reshape(L, 3, 3) / 6.0
        Jc = dM / A[:, None, None] - M[:, :, None] * dA[:, None, :] / (A ** 2)[:, None, None]
        # spread^2 = I0 / A - |m|^2 (m = M / A: the centroid about x)
        duu = (np.einsum("ij,ijk->ik", 2 * u + v, du) + np.einsum("ij,ijk->ik", u + 2 * v, dv))
        dI0 = np.stack([np.bincount(loop, ds[:, c] * uu + s * duu[:, c], L)
                        for c in range(3)], 1) / 12.0
        dvar = dI0 / A[:, None] - I0[:, None] * dA / (A ** 2)[:, None] - 2 * np.einsum("li,lik->lk", m, Jc)
        dsp[0 if name == "x" else 1][pts] = dvar / (2.0 * np.maximum(spread, 1e-300))[:, None]
        if name == "x":
            Jc = Jc + eye
        dc[0 if name == "x" else 1][pts] = Jc
