"""Chain joints moved towards the area centroid of the mesh's cross-section through them.

Why: the centring stage puts the curve on the medial points, which on a tube lie on its axis but
on a flat or boxy part (a plate, a torso, an ear) spread over a medial *sheet*, so a joint can
sit anywhere across the part: the curve runs off-centre or wiggles in depth (rocker-arm's ring,
spot's head, armadillo's torso). The plane through a chain joint across the chain (normal along
the chain's direction there) cuts the surface in closed loops; the loop round the joint bounds
the part's cross-section, and its area centroid is the centre a rigger expects, whatever the
section's shape (a tube's axis, the middle of a plate's strip). This is the classic
cross-sectional centring of curve skeletons (e.g. the rotational-symmetry-axis refinement of
Tagliasacchi, Zhang and Cohen-Or, SIGGRAPH 2009, which slices the shape across the curve).

Each polishing round moves every chain joint ``STEP`` of the way to its centroid and every tip
``LEAF_STEP`` of the way (its plane lies across its chain one joint in), then smooths the chains
a little (a centroid of a plane slanted by a neighbouring bend is noise across a short bone).
Junctions are not moved, nor is a joint whose new place is outside the mesh. A section that
reaches far beyond the joint's radius is not the part's own (the plane cuts the body next to a
limb's root, or a neighbouring part): the step fades from full at ``REACH`` radii to none at
``REACH + FADE``, so a section near the limit does not switch a joint's move on and off.

Planar sections have one weakness: where the plane nearly touches a saddle (between two
fingers), a tiny tilt joins or splits loops and the centroid jumps. The fade bounds how far such
a joint can go (armadillo jittered by 1e-9 D: one joint next to a finger tip moved 0.01 D
differently at commit 1010aee, where the polish started from curves 2e-4 D apart; issue 12).

Examples
--------
>>> C, extent = section_centroids(V, F, X, T, reach)       # doctest: +SKIP
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from .mesh_graph import faces_around
from .quality import orthonormal_frame
from .rows import row_cross, take_rows

__all__ = ["section_centroids", "section_loops", "section_shapes", "shared_sections",
           "shared_sections_many",
           "vertex_edges", "polish_chains", "STEP", "ROUNDS", "REACH", "FADE", "TIP_REACH", "SMOOTH",
           "LEAF_STEP", "OWN_REACH", "OWN_RATIO"]

#: Fraction of the way to the centroid a joint moves per round.
STEP = 0.5
#: Polishing rounds (tangents and sections recomputed each round).
ROUNDS = 2
#: A section loop reaching farther than this times the joint's radius is not the part's own.
REACH = 2.0
#: ... and the step fades to none at this many radii farther (a continuous decision).
FADE = 0.5
#: ... plus this many for a tip (its radius, fitted to the surface near the limb's end, is
#: smaller than its end section: a box bar's tip 0.4 for a 1 x 1 section).
TIP_REACH = 1.0
#: Chain smoothing weight after each round (:func:`.centreline.smooth_chains`).
SMOOTH = 0.3
#: Fraction of the way a tip moves per round (its section is the limb's end; the whole way: a
#: tip left off the axis tilts its neighbour's plane).
LEAF_STEP = 1.0
#: A section beyond ``REACH`` radii is still the part's own, and its joint moves a full step,
#: when no other part of the skeleton crosses the plane inside the loop and the chain's
#: neighbouring joints' sections reach as far (within ``OWN_RATIO``): the part is a prism there
#: whose section is wider than the radius says, not a limb's root whose plane takes in the
#: body. rocker-arm's lever is a T-section beam (a thin web 0.3 wide under a flange): its fitted
#: radii are 0.05-0.1 and its sections reach 2.2-3.7 radii; held to ``REACH`` the lever ran
#: along the web's free edge, 0.06 below the centroid. Up to this many radii...
OWN_REACH = 8.0
#: ... fading to none over ``FADE`` ratios beyond this one (spot's hind leg: its root joint's
#: section takes in the belly, 1.6x its neighbour's; a T-beam's run within 1.2x).
OWN_RATIO = 1.5


def section_centroids(V, F, X, T, reach, *, face_of=None, vertex_edge=None):
    """Area centroid of the cross-section loop round each point.

    Parameters
    ----------
    V : (n, 3) float, F : (m, 3) int
        A closed, consistently oriented triangle mesh.
    X : (k, 3) float
        Points (chain joints).
    T : (k, 3) float
        Unit plane normals (the chain's direction at each point).
    reach : (k,) float
        A loop with a point farther than this from its X is not accepted.
    face_of : (indptr, faces), optional
        The faces around each vertex (CSR; built if None).
    vertex_edge : (n,) float, optional
        The longest side of the faces around each vertex (:func:`vertex_edges`; computed if
        None).

    Returns
    -------
    C : (k, 3) float
        The centroids (X where not found).
    extent : (k,) float
        How far the loop reaches from its point (``inf`` where no closed loop winding round
        the point was found within ``reach``).

    Examples
    --------
    The unit cube's section across x through (0.5, 0.2, 0.3) is the square [0, 1]^2 of y and
    z, centroid (0.5, 0.5, 0.5):

    >>> V = np.array([[x, y, z] for x in (0., 1) for y in (0., 1) for z in (0., 1)])
    >>> F = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
    ...               [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
    >>> C, extent = section_centroids(V, F, [[0.5, 0.2, 0.3]], [[1.0, 0, 0]], [2.0])
    >>> np.round(C, 6).tolist(), np.round(extent, 6).tolist()
    ([[0.5, 0.5, 0.5]], [1.063015])
    """
    C, extent, _ = section_loops(V, F, X, T, reach, face_of=face_of, vertex_edge=vertex_edge)
    return C, extent


def section_loops(V, F, X, T, reach, *, face_of=None, vertex_edge=None):
    """:func:`section_centroids` with each loop's area: (C, extent, area), area 0 where no
    loop was found. A round section of radius r has area pi r^2 and extent r; a flat strip's
    area is a small part of the disc of its extent (:mod:`.flaps`).

    Examples
    --------
    >>> V = np.array([[x, y, z] for x in (0., 1) for y in (0., 1) for z in (0., 1)])
    >>> F = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
    ...               [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
    >>> C, extent, area = section_loops(V, F, [[0.5, 0.2, 0.3]], [[1.0, 0, 0]], [2.0])
    >>> np.round(area, 6).tolist()
    [1.0]
    """
    return _loops(V, F, X, T, reach, face_of, vertex_edge, False)[:3]


def section_shapes(V, F, X, T, reach, *, face_of=None, vertex_edge=None):
    """:func:`section_loops` with each loop's width and thickness: the sides of the rectangle
    with the loop's second moments of area (``sqrt(12 lambda)`` for the eigenvalues ``lambda``
    of its covariance), robust where the reach (the farthest point) is not. A w x t rectangle
    gives (w, t); a disc of radius r gives (sqrt(3) r, sqrt(3) r); 0 where no loop was found.

    Returns
    -------
    C, extent, area : as :func:`section_loops`
    width, thickness : (k,) float
    thin : (k, 3) float
        The unit direction of the thickness (a plate's normal; 0 where no loop was found).

    Examples
    --------
    The cube [0, 1] x [0, 1] x [0, 3], across x: a 1 x 3 rectangle.

    >>> V = np.array([[x, y, z] for x in (0., 1) for y in (0., 1) for z in (0., 3)])
    >>> F = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
    ...               [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
    >>> *_, w, t, thin = section_shapes(V, F, [[0.5, 0.5, 1.0]], [[1.0, 0, 0]], [4.0])
    >>> np.round([w[0], t[0]], 6).tolist(), np.abs(np.round(thin[0], 6)).tolist()
    ([3.0, 1.0], [0.0, 1.0, 0.0])
    """
    return _loops(V, F, X, T, reach, face_of, vertex_edge, True)


def _loops(V, F, X, T, reach, face_of, vertex_edge, moments):
    """The work of :func:`section_loops` (``moments``: also width and thickness)."""
    V = np.asarray(V, np.float64)
    F = np.asarray(F, np.int64).reshape(-1, 3)
    X = np.asarray(X, np.float64).reshape(-1, 3)
    T = np.asarray(T, np.float64).reshape(-1, 3)
    reach = np.broadcast_to(np.asarray(reach, np.float64), (len(X),))
    k, n = len(X), len(V)
    C = X.copy()
    extent = np.full(k, np.inf)
    area_out = np.zeros(k)
    width, thick, normal = np.zeros(k), np.zeros(k), np.zeros((k, 3))
    if not k or not len(F):
        return C, extent, area_out, width, thick, normal
    if face_of is None:
        face_of = faces_around(F, n)
    if vertex_edge is None:
        vertex_edge = vertex_edges(V, F, face_of)
    vi, pi = _slab_vertices(V, X, T, reach, vertex_edge)
    # the faces around them, once per point: every face the plane cuts near the point
    indptr, faces = face_of
    cnt = indptr[vi + 1] - indptr[vi]
    first = np.repeat(indptr[vi] - np.cumsum(cnt) + cnt, cnt) + np.arange(cnt.sum())
    m = len(F)
    pf = np.unique(np.repeat(pi, cnt) * m + faces[first])
    pi, fi = pf // m, pf % m
    Fc = F[fi]
    h = np.einsum("fcd,fd->fc", V[Fc] - X[pi][:, None, :], T[pi])     # corners' heights
    neg = h < 0
    cut = neg.any(axis=1) & ~neg.all(axis=1)
    pi, Fc, h, neg = pi[cut], Fc[cut], h[cut], neg[cut]
    f = len(Fc)
    if not f:
        return C, extent, area_out, width, thick, normal
    # the two edges of each cut face whose ends lie on opposite sides, in corner order
    P = np.empty((f, 2, 3))
    key = np.empty((f, 2), np.int64)
    slot = np.zeros(f, np.int64)
    rows = np.arange(f)
    for a, b in ((0, 1), (1, 2), (2, 0)):
        hit = rows[neg[:, a] != neg[:, b]]
        va, vb = Fc[hit, a], Fc[hit, b]
        w = h[hit, a] / (h[hit, a] - h[hit, b])
        P[hit, slot[hit]] = V[va] + w[:, None] * (V[vb] - V[va])
        # one key per (cut edge, point): the loops of different points never join
        key[hit, slot[hit]] = (np.minimum(va, vb) * n + np.maximum(va, vb)) * k + pi[hit]
        slot[hit] += 1
    E1, E2 = orthonormal_frame(T)
    e1, e2 = E1[pi], E2[pi]
    rel = P - X[pi][:, None, :]
    p = np.stack([np.einsum("fd,fd->f", rel[:, 0], e1), np.einsum("fd,fd->f", rel[:, 0], e2)], 1)
    q = np.stack([np.einsum("fd,fd->f", rel[:, 1], e1), np.einsum("fd,fd->f", rel[:, 1], e2)], 1)
    # orient each segment so that the section's inside lies on its left: the face's outward
    # normal, projected into the plane, points to the right of p -> q
    fn = row_cross(take_rows(V, Fc[:, 1]) - take_rows(V, Fc[:, 0]),
                   take_rows(V, Fc[:, 2]) - take_rows(V, Fc[:, 0]))
    fx, fy = np.einsum("fd,fd->f", fn, e1), np.einsum("fd,fd->f", fn, e2)
    d = q - p
    flip = d[:, 1] * fx - d[:, 0] * fy < 0
    p[flip], q[flip] = q[flip].copy(), p[flip].copy()
    # loops: segments joined where they share a cut edge
    uk, inv = np.unique(key.ravel(), return_inverse=True)
    inv = inv.reshape(-1, 2)
    G = sp.coo_matrix((np.ones(f), (inv[:, 0], inv[:, 1])), shape=(len(uk), len(uk)))
    nc, lab = connected_components(G, directed=False)
    seg = lab[inv[:, 0]]
    # closed: every cut edge of the loop shared by two of its faces
    ends = np.bincount(inv.ravel(), minlength=len(uk))
    closed = np.ones(nc, bool)
    closed[lab[ends != 2]] = False
    owner = np.zeros(nc, np.int64)
    owner[seg] = pi
    cr = p[:, 0] * q[:, 1] - p[:, 1] * q[:, 0]
    area = np.bincount(seg, weights=cr, minlength=nc) / 2.0
    wind = np.bincount(seg, weights=np.arctan2(cr, np.einsum("ij,ij->i", p, q)),
                       minlength=nc) / (2.0 * np.pi)
    far = np.zeros(nc)
    np.maximum.at(far, seg, np.einsum("ij,ij->i", p, p))
    cx = np.bincount(seg, weights=(p[:, 0] + q[:, 0]) * cr, minlength=nc)
    cy = np.bincount(seg, weights=(p[:, 1] + q[:, 1]) * cr, minlength=nc)
    # per point, the innermost closed loop winding round it (smallest area), if within reach
    cand = np.flatnonzero(closed & (wind > 0.5) & (area > 0))
    cand = cand[np.lexsort((area[cand], owner[cand]))]
    cand = cand[np.r_[True, owner[cand][1:] != owner[cand][:-1]][:len(cand)]]
    cand = cand[far[cand] <= reach[owner[cand]] ** 2]
    j = owner[cand]
    C[j] = (X[j] + (cx[cand] / (6.0 * area[cand]))[:, None] * E1[j]
            + (cy[cand] / (6.0 * area[cand]))[:, None] * E2[j])
    extent[j] = np.sqrt(far[cand])
    area_out[j] = area[cand]
    if moments and len(cand):
        # second moments about the point (the polygon formulas, each edge with the origin),
        # then about the centroid: the covariance of the section's area
        sxx = np.bincount(seg, weights=cr * (p[:, 0] ** 2 + p[:, 0] * q[:, 0] + q[:, 0] ** 2),
                          minlength=nc)[cand] / 12.0
        syy = np.bincount(seg, weights=cr * (p[:, 1] ** 2 + p[:, 1] * q[:, 1] + q[:, 1] ** 2),
                          minlength=nc)[cand] / 12.0
        sxy = np.bincount(seg, weights=cr * (p[:, 0] * q[:, 1] + 2 * p[:, 0] * p[:, 1]
                                             + 2 * q[:, 0] * q[:, 1] + q[:, 0] * p[:, 1]),
                          minlength=nc)[cand] / 24.0
        A = area[cand]
        mx, my = cx[cand] / (6.0 * A), cy[cand] / (6.0 * A)
        vxx, vyy, vxy = sxx / A - mx * mx, syy / A - my * my, sxy / A - mx * my
        half, disc = (vxx + vyy) / 2, np.sqrt(((vxx - vyy) / 2) ** 2 + vxy ** 2)
        width[j] = np.sqrt(12.0 * np.maximum(half + disc, 0.0))
        thick[j] = np.sqrt(12.0 * np.maximum(half - disc, 0.0))
        # the thin direction: across the major axis (angle of the major axis: atan2 / 2)
        phi = 0.5 * np.arctan2(2.0 * vxy, vxx - vyy) + np.pi / 2
        normal[j] = np.cos(phi)[:, None] * E1[j] + np.sin(phi)[:, None] * E2[j]
    return C, extent, area_out, width, thick, normal


def shared_sections(V, F, P, Q, reach, *, face_of=None, vertex_edge=None, test=None):
    """Which points of the polyline ``P`` share their cross-section with the polyline ``Q``.

    The plane through ``P[i]`` across ``P`` (normal along ``P`` there) cuts the mesh in loops;
    point i shares its section when ``Q`` crosses that plane (at its crossing nearest ``P[i]``)
    inside the same loop: the two curves run through one part of the shape there, however far
    apart across it (two loops' sides in one web between two holes). Two limbs side by side
    each have their own loop. :func:`shared_sections_many` does many pairs in one pass.

    Parameters
    ----------
    V, F : the mesh
    P : (k, 3) float, Q : (m, 3) float
        The two polylines.
    reach : float
        Loops reaching farther than this from ``P[i]`` are not looked for.
    face_of, vertex_edge : optional, as :func:`section_loops`.
    test : (k,) bool, optional
        Test only these points (the others False; tangents still from all).

    Returns
    -------
    (k,) bool

    Examples
    --------
    Two segments along x through the unit cube share every section:

    >>> V = np.array([[x, y, z] for x in (0., 1) for y in (0., 1) for z in (0., 1)])
    >>> F = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
    ...               [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
    >>> shared_sections(V, F, [[0.2, 0.3, 0.5], [0.8, 0.3, 0.5]],
    ...                 [[0.1, 0.7, 0.5], [0.9, 0.7, 0.5]], 2.0).tolist()
    [True, True]
    """
    return shared_sections_many(V, F, [(P, Q, reach, test)], face_of=face_of,
                                vertex_edge=vertex_edge)[0]


def shared_sections_many(V, F, pairs, *, face_of=None, vertex_edge=None):
    """:func:`shared_sections` of many ``(P, Q, reach, test)`` at once (one pass of the
    section loops over all their points). Returns a list of (len(P),) bool."""
    out, pts, nrm, rch, where = [], [], [], [], []
    for n, (P, Q, reach, test) in enumerate(pairs):
        P = np.asarray(P, np.float64).reshape(-1, 3)
        Q = np.asarray(Q, np.float64).reshape(-1, 3)
        out.append(np.zeros(len(P), bool))
        i, q, T = _crossings(P, Q, test)
        if len(i):
            pts += [P[i], q]
            nrm += [T[i], T[i]]
            # a loop within `reach` of P[i] lies within reach + |q - P[i]| of its crossing q:
            # with `reach` alone the crossing nearer the loop's far side missed it (the plate's
            # web, 1.3 wide: the second point's loop reached 1.09 against 0.84 from the first)
            rch.append(np.r_[np.full(len(i), float(reach)),
                             reach + np.linalg.norm(q - P[i], axis=1)])
            where.append((n, i))
    if not where:
        return out
    X, TT, R = np.concatenate(pts), np.concatenate(nrm), np.concatenate(rch)
    C, extent, area = section_loops(V, F, X, TT, R, face_of=face_of, vertex_edge=vertex_edge)
    at = 0
    for n, i in where:
        k = len(i)
        a, b = slice(at, at + k), slice(at + k, at + 2 * k)
        at += 2 * k
        out[n][i] = (np.isfinite(extent[a]) & (area[a] > 0)
                     & _same_loop(C[a], area[a], C[b], extent[b], area[b],
                                  max(float(R[a][0]), 1e-300)))
    return out


def _same_loop(C, area, Cq, extent_q, area_q, scale):
    """(k,) bool: whether the loops found from two points are one loop (each point's loop is
    computed on its own: the same area and centroid, to rounding; ``scale`` a length of the
    loops')."""
    return (np.isfinite(extent_q) & (np.abs(area_q - area) <= 1e-9 * area)
            & (np.linalg.norm(Cq - C, axis=1) <= 1e-9 * np.asarray(scale)))


def _crossings(P, Q, test=None):
    """(i, q, T): the points of P (indices ``i``, among ``test``) whose plane across P (unit
    normals ``T``, one per point of P) the polyline Q crosses, and Q's crossing ``q`` nearest
    each of them."""
    k = len(P)
    none = (np.zeros(0, np.int64), np.zeros((0, 3)), np.zeros((k, 3)))
    if k < 2 or len(Q) < 2:
        return none
    T = np.zeros_like(P)
    T[1:-1] = P[2:] - P[:-2]
    T[0], T[-1] = P[1] - P[0], P[-1] - P[-2]
    nt = np.linalg.norm(T, axis=1, keepdims=True)
    T = np.divide(T, nt, out=np.zeros_like(T), where=nt > 0)
    h = np.einsum("kmd,kd->km", Q[None, :, :] - P[:, None, :], T)
    # a segment whose ends lie on either side, or whose far end lies on the plane (a path
    # ending there: its last joint)
    flip = ((h[:, :-1] <= 0) != (h[:, 1:] <= 0)) | (h[:, 1:] == 0)
    den = h[:, :-1] - h[:, 1:]
    w = np.divide(h[:, :-1], den, out=np.ones_like(den), where=flip & (den != 0))
    C = Q[None, :-1] + w[..., None] * (Q[None, 1:] - Q[None, :-1])     # (k, m-1, 3)
    d = np.where(flip, np.linalg.norm(C - P[:, None, :], axis=2), np.inf)
    has = flip.any(axis=1) & (nt[:, 0] > 0)
    if test is not None:
        has &= np.asarray(test, bool)
    i = np.flatnonzero(has)
    return i, C[i, np.argmin(d[i], axis=1)], T


def _slab_vertices(V, X, T, reach, vertex_edge):
    """(vertex, point) pairs: the vertices v within ``vertex_edge[v]`` of each point's plane
    and within ``reach + vertex_edge[v]`` of the point. A face the plane cuts has a corner on
    each side, so the corner nearer the plane lies within a side's length of it; and a loop
    within ``reach`` of the point has such a corner within ``reach`` plus that length.

    The heights are screened in float32 with a margin for its rounding (one matrix-vector
    product per point: 4-8x faster than one (n, k) product and its 2-D ``nonzero``); the
    faces' heights are recomputed exactly afterwards."""
    V32 = V.astype(np.float32)
    tol = (vertex_edge + 1e-5 * float(np.abs(V).max(initial=0.0) + np.abs(X).max(initial=0.0)))
    tol32 = tol.astype(np.float32)
    off = np.einsum("ij,ij->i", X, T)
    vs, ps = [], []
    for j in range(len(X)):
        if not T[j].any():                  # no plane (two neighbours at one place)
            continue
        s = V32 @ T[j].astype(np.float32)
        s -= np.float32(off[j])
        v = np.flatnonzero(np.abs(s) <= tol32)
        d = V[v] - X[j]
        v = v[np.einsum("ij,ij->i", d, d) <= (reach[j] + vertex_edge[v]) ** 2]
        vs.append(v)
        ps.append(np.full(len(v), j, np.int64))
    if not vs:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    return np.concatenate(vs), np.concatenate(ps)


def vertex_edges(V, F, face_of=None):
    """(n,) the longest side of the faces around each vertex (0 for a vertex in no face).

    Examples
    --------
    >>> vertex_edges(np.array([[0., 0, 0], [3, 0, 0], [0, 4, 0], [9, 9, 9]]),
    ...              np.array([[0, 1, 2]])).tolist()
    [5.0, 5.0, 5.0, 0.0]
    """
    V = np.asarray(V, np.float64)
    F = np.asarray(F, np.int64).reshape(-1, 3)
    if face_of is None:
        face_of = faces_around(F, len(V))
    indptr, faces = face_of
    side = np.zeros(len(F))
    for a, b in ((0, 1), (1, 2), (2, 0)):
        d = take_rows(V, F[:, a]) - take_rows(V, F[:, b])
        np.maximum(side, np.einsum("ij,ij->i", d, d), out=side)
    side = np.sqrt(side)
    out = np.zeros(len(V))
    has = indptr[1:] > indptr[:-1]
    if len(faces):
        out[has] = np.maximum.reduceat(side[faces], indptr[:-1][has])
    return out


def polish_chains(V, F, joints, bones, inside, *, rounds=ROUNDS, step=STEP, reach=REACH,
                  smooth=SMOOTH, face_of=None, vertex_edge=None, fixed=()):
    """Chain joints moved towards their cross-sections' centroids (see the module docstring).

    Parameters
    ----------
    V, F : the mesh
    joints : (J, 4) float
    bones : (B, 2) int
    inside : callable (k, 3) -> (k,) bool
        The mesh's inside test: a joint whose new place is outside stays where it was.
    face_of : optional
        The faces around each vertex (:func:`.mesh_graph.faces_around`), if at hand.
    vertex_edge : (n,) float, optional
        :func:`vertex_edges` of the mesh, if at hand.
    fixed : sequence of int
        Joints that stay where they are, as junctions do (chains laid by :mod:`.flaps`).

    Returns
    -------
    X : (J, 3) float
        New positions (radii untouched).
    moved : int
        Joints that moved in the last round (a closed section round them within reach).
    """
    from .centreline import smooth_chains
    J = np.asarray(joints, np.float64)
    X = J[:, :3].copy()
    bones = np.asarray(bones, np.int64).reshape(-1, 2)
    hub = np.bincount(bones.ravel(), minlength=len(X)) >= 3       # junctions stay
    hub[np.asarray(fixed, np.int64)] = True
    if not len(F):
        return X, 0
    face_of = faces_around(F, len(V)) if face_of is None else face_of
    vertex_edge = vertex_edges(V, F, face_of) if vertex_edge is None else vertex_edge
    moved = 0
    moving, a, b, tip = _planes(bones, len(X))
    if not len(moving):
        return X, 0
    for _ in range(rounds):
        T = X[b] - X[a]
        nt = np.linalg.norm(T, axis=1, keepdims=True)
        T = np.divide(T, nt, out=np.zeros_like(T), where=nt > 0)
        r = J[moving, 3]
        rr = reach + np.where(tip, TIP_REACH, 0.0)
        C, extent, area = section_loops(V, F, X[moving], T, (rr + FADE) * r, face_of=face_of,
                                        vertex_edge=vertex_edge)
        # the loops beyond that, for the own-section rule, looked for only where none was
        # found (a loop winding round a point lies inside any larger one: the innermost loop
        # within the small reach is the innermost within the large one)
        far = np.flatnonzero(~tip & ~np.isfinite(extent))
        if len(far) and OWN_REACH > REACH + FADE:
            C[far], extent[far], area[far] = section_loops(
                V, F, X[moving[far]], T[far], OWN_REACH * r[far], face_of=face_of,
                vertex_edge=vertex_edge)
        # full step for a section within `reach` radii, none beyond `reach + FADE`: a loop
        # near the limit (a limb's root) does not switch a joint's move on and off
        er = extent / np.maximum(r, 1e-300)
        w = np.clip((rr + FADE) - er, 0.0, FADE) / FADE
        w = np.maximum(w, _own_weight(V, F, X, T, moving, tip, C, extent, area, er, w, bones,
                                      face_of, vertex_edge))
        moved = int(np.count_nonzero(w > 0))
        Y = X.copy()
        Y[moving] += (np.where(tip, LEAF_STEP, step) * w)[:, None] * (C - X[moving])
        if smooth > 0:
            # a tip keeps its section's place: the smoothing would pull it along the chain (out
            # into a capsule's cap)
            Z = smooth_chains(Y, bones, smooth)
            Z[moving[tip]] = Y[moving[tip]]
            Y = Z
        Y[hub] = X[hub]
        stay = ~inside(Y)
        Y[stay] = X[stay]
        X = Y
    return X, moved


def _own_weight(V, F, X, T, moving, tip, C, extent, area, er, w, bones, face_of, vertex_edge):
    """(k,) the step weight of the moving joints whose sections reach beyond ``REACH`` radii
    but are their part's own (``OWN_REACH``, ``OWN_RATIO``); 0 for the others. Only a joint
    between two chain joints (not a tip, not next to a junction or a tip) can tell: its run's
    sections on both sides are the comparison."""
    from .centreline import chain_neighbours
    out = np.zeros(len(moving))
    ex = np.full(len(X) + 1, np.nan)                 # the last slot: no neighbour
    ex[moving[~tip]] = extent[~tip]
    chain, na, nb = chain_neighbours(bones, len(X))
    nbr = np.full((len(X), 2), len(X))
    nbr[chain, 0], nbr[chain, 1] = na, nb
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.max(extent[:, None] / ex[nbr[moving]], axis=1)
    ratio[tip | ~np.isfinite(ratio)] = np.inf
    wo = (np.clip(OWN_REACH - er, 0.0, FADE) / FADE
          * np.clip(OWN_RATIO + FADE - ratio, 0.0, FADE) / FADE)
    ask = np.flatnonzero((wo > w) & np.isfinite(extent) & (area > 0))
    if not len(ask):
        return out
    own = ~_holds_other_bones(V, F, X, bones, moving[ask], T[ask], C[ask], extent[ask],
                              area[ask], face_of, vertex_edge)
    out[ask[own]] = wo[ask[own]]
    return out


def _holds_other_bones(V, F, X, bones, idx, T, C, extent, area, face_of, vertex_edge):
    """(k,) bool: whether a bone not at joint ``idx[i]`` crosses the plane through ``X[idx[i]]``
    (normal ``T[i]``) inside the same section loop (centroid ``C[i]``, ``area[i]``,
    ``extent[i]``)."""
    A, B = X[bones[:, 0]], X[bones[:, 1]]
    hA = np.einsum("kbd,kd->kb", A[None] - X[idx][:, None], T)
    hB = np.einsum("kbd,kd->kb", B[None] - X[idx][:, None], T)
    cross = ((hA <= 0) != (hB <= 0)) & (bones[None, :, 0] != idx[:, None]) \
        & (bones[None, :, 1] != idx[:, None])
    i, j = np.nonzero(cross)
    t = hA[i, j] / (hA[i, j] - hB[i, j])
    q = A[j] + t[:, None] * (B[j] - A[j])
    near = np.linalg.norm(q - X[idx[i]], axis=1) <= extent[i]
    i, q = i[near], q[near]
    out = np.zeros(len(idx), bool)
    if not len(i):
        return out
    Cq, eq, aq = section_loops(V, F, q, T[i], 2.0 * extent[i], face_of=face_of,
                               vertex_edge=vertex_edge)
    same = _same_loop(C[i], area[i], Cq, eq, aq, extent[i])
    out[i[same]] = True
    return out


def _planes(bones, n_joints):
    """The joints to move and the direction of each one's plane, ``x_b - x_a``.

    Chain joints (degree 2) take their neighbours' difference; next to a tip the direction
    points away from it (a tip is the least certain place of a chain: it ends where the Reeb
    graph's pole was, often off the axis). A tip takes its chain's direction one joint in
    (its neighbour's other neighbour to its neighbour), or its bone's next to a junction.

    Returns
    -------
    moving, a, b : (k,) int
    tip : (k,) bool
    """
    from .centreline import chain_neighbours
    chain, a0, b0 = chain_neighbours(bones, n_joints)
    deg = np.bincount(bones.ravel(), minlength=n_joints)
    la, lb = deg[a0] == 1, deg[b0] == 1
    a = np.where(la & ~lb, chain, a0)
    b = np.where(lb & ~la, chain, b0)
    ends = np.r_[bones[:, 0], bones[:, 1]]
    other = np.r_[bones[:, 1], bones[:, 0]]
    sel = (deg[ends] == 1) & (ends != other)
    tips, n1 = ends[sel], other[sel]
    # where the neighbour is a chain joint: its other neighbour
    pos = np.minimum(np.searchsorted(chain, n1), max(len(chain) - 1, 0))
    mid = (chain[pos] == n1) if len(chain) else np.zeros(len(n1), bool)
    n2 = np.where(a0[pos] == tips, b0[pos], a0[pos]) if len(chain) else n1
    src = np.where(mid, n2, n1)
    dst = np.where(mid, n1, tips)
    return (np.r_[chain, tips], np.r_[a, src], np.r_[b, dst],
            np.r_[np.zeros(len(chain), bool), np.ones(len(tips), bool)])
