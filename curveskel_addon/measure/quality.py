"""Quality measures of a curve-skeleton against its mesh (issue 5).

Every measure is dimensionless: lengths are divided by ``D``, the diagonal of the mesh's
bounding box, and energies by ``D**4`` (E has units of length^4).

The silhouette (paper, definition 3) of a skeleton with straight bones and linear radii is the
union, over bones, of "round cones": the convex hull of the two end balls
``B(x_i, r_i)`` and ``B(x_j, r_j)``. A joint without any bone contributes its ball.

Measures returned by :func:`quality`
------------------------------------
energy_vertex
    ``sum_v e_v^2 / (|V| D^4)`` with ``e_v = |v - sigma(v)|^2 - r(sigma(v))^2`` (eq. 20, w = 1):
    the mean squared residual per vertex.
energy_area
    ``sum_v a_v e_v^2 / (A D^4)`` with ``a_v`` the barycentric vertex area and ``A`` the surface
    area: the surface integral of eq. 8 divided by the area (a mean over the surface, independent
    of the tessellation density).
energy_mapping
    "skeleton" (the skeleton's own ``bone``/``t``), "closest" (no per-vertex mapping given: each
    vertex to its closest bone point) or "none" (no bones).
recon_mean, recon_p95, recon_max
    Mesh -> silhouette: over ``n_samples`` area-uniform samples ``x`` of the mesh surface, the
    mean, 95th percentile and maximum of ``|sdf_S(x)| / D``, where ``sdf_S = min_b sdRoundCone_b``
    is the signed distance of the union (exact outside the silhouette, a lower bound inside).
recon_rev_mean, recon_rev_p95, recon_rev_max
    Silhouette -> mesh: samples of the silhouette's boundary (area-uniform on every round cone's
    surface, keeping only those not strictly inside any primitive) to the mesh surface (exact
    point-to-triangle distance), / D. A silhouette bulging out of the mesh is penalised here.
recon_sym
    ``(recon_mean + recon_rev_mean) / 2``.
inside
    Fraction of points along the bones (``bone_samples`` per bone at ``t = (k + 1/2) / n``) that
    are inside the mesh: the core's ray-parity test
    (:func:`curveskel_addon.core.geometry.inside.inside_mesh`, three random directions, majority
    vote), exact for closed meshes (up to rays grazing an edge, which the vote absorbs) and
    O(points + faces).
skeleton_components, skeleton_cycles
    Connected components ``C`` of the joint graph and independent cycles ``B - J + C``.
mesh_components, mesh_genus, mesh_boundaries, mesh_euler, mesh_nonmanifold_edges
    Of the cleaned mesh (duplicate positions merged): per component ``chi = V - E + F`` and
    ``g = (2 - chi - b) / 2`` with ``b`` boundary loops; genus and boundaries are summed.
    Edges with more than two faces are counted (the genus formula assumes none).
topology_match
    ``skeleton_components == mesh_components and skeleton_cycles == mesh_genus`` (for a mesh of
    separate parts joined into figures, the figures' trees and the loops their seams close).
joints, bones, leaves, branch_points
    Sizes; leaves have degree 1, branch points degree >= 3.
D, measure_seconds
    The normalising length, and seconds spent per group of measures.
zigzag, turn_p90, folds, fold_pairs; with ``reference=``: to_ref_mean, to_ref_p95,
from_ref_mean, from_ref_p95, length_ratio
    The shape of the curve (issue 10), below.

Shape of the curve (issue 10)
-----------------------------
recon, inside and E reward balls that fill the shape even when the bones zig-zag or criss-cross
inside it. :func:`shape_measures` (against a reference curve skeleton) and
:func:`curve_measures` (on its own, for use inside the pipeline) look at the curve:

to_ref_mean, to_ref_p95 / from_ref_mean, from_ref_p95
    Points every D/400 along our bones -> distance to the nearest of the points every D/2000
    along the reference's bones (mean, 95th percentile); and the reverse.
length_ratio
    Sum of bone lengths / sum of the reference's bone lengths.
zigzag
    Fraction of degree-2 joints where the chain turns by more than 60 degrees (the angle between
    ``x_j - x_a`` and ``x_b - x_j``).
folds
    Bone pairs whose segments pass within 0.01 D of each other although the shortest path
    between them along the skeleton is longer than 0.1 D (pairs in different connected parts do
    not count), divided by the number of bones.

Cost
----
No Python loop over points or faces. Nearest-primitive queries (round cones, triangles) use a
KD-tree on primitive centres with an exact stopping rule, so results equal brute force; points far
from every primitive (a silhouette bulging far out of the mesh) are the slow case. On armadillo
(86k faces, 2 cores) the whole set takes about 2-6 s with 20,000 samples.
"""

from __future__ import annotations

import itertools
import json
import os
import time

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components, dijkstra
from scipy.spatial import cKDTree

from ..core.errors import CurveSkelError
from ..core.geometry.areas import vertex_areas
from ..core.geometry.inside import inside_mesh
from ..core.geometry.mesh_graph import adjacency
from ..core.geometry.rows import col_ptp
from ..core.geometry.sections import cross_sections
from ..core.geometry.segments import closest_on_bones
from ..core.initialise.pole import bilateral_plane
from ..core.objective.terms import chain_neighbours

__all__ = ["quality", "sd_round_cone", "round_cone_geometry", "sd_round_cone_radii",
           "take_round_cone_geometry", "silhouette_sdf", "point_triangle_distance",
           "mesh_distance", "winding_number", "sample_surface", "sample_silhouette_boundary",
           "bone_points", "closest_mapping", "energy_measures", "skeleton_topology",
           "mesh_topology", "bbox_diagonal", "curve_arrays", "segment_points", "curve_points",
           "segment_segment_distance", "turn_angles", "close_bone_pairs", "fold_pairs", "crossing_pairs",
           "curve_measures", "curve_distances", "shape_measures", "mirror_asymmetry"]

#: Elements per temporary array in chunked pairwise evaluations (bounds memory to ~tens of MB).
_CHUNK = 1 << 18


# ---------------------------------------------------------------------------------------------
# Round cones (one silhouette primitive per bone)
# ---------------------------------------------------------------------------------------------
def sd_round_cone(p, a, b, r1, r2):
    """Exact signed distance from points to round cones (Inigo Quilez's sdRoundCone).

    The round cone is the convex hull of the balls ``B(a, r1)`` and ``B(b, r2)``. All arguments
    broadcast against each other (``p, a, b`` with a trailing axis of 3).

    Parameters
    ----------
    p, a, b : (..., 3) float
    r1, r2 : (...) float, >= 0

    Returns
    -------
    (...) float
        Negative inside, positive outside, exact on both sides. When one ball contains the other
        (``|b - a| <= |r1 - r2|``) the shape is the larger ball.

    Examples
    --------
    >>> float(sd_round_cone(np.array([0., 2, 0]), np.zeros(3), np.array([0., 0, 1]), 1.0, 1.0))
    1.0
    """
    return sd_round_cone_radii(round_cone_geometry(p, a, b), r1, r2)


def round_cone_geometry(p, a, b):
    """The radius-free part of :func:`sd_round_cone` for points ``p`` against axes ``a-b``:
    computed once where only the radii change (a radius fit evaluates the same point-cone
    pairs a dozen times). Pass it to :func:`sd_round_cone_radii`; ``take`` rows of it with
    :func:`take_round_cone_geometry`."""
    p, a, b = (np.asarray(x, dtype=np.float64) for x in (p, a, b))
    ba = b - a
    l2 = np.einsum("...i,...i->...", ba, ba)
    pa = p - a
    y = np.einsum("...i,...i->...", pa, ba)
    z = y - l2
    with np.errstate(divide="ignore", invalid="ignore"):
        il2 = 1.0 / l2
        q = pa * l2[..., None] - ba * y[..., None]
        x2 = np.einsum("...i,...i->...", q, q)
        y2 = y * y * l2
        z2 = z * z * l2
        # the end balls' distances before their radii: sqrt(...) / l2
        sb = np.sqrt(x2 + z2) * il2
        sa = np.sqrt(x2 + y2) * il2
    # p, a, b: for the contained-ball case (one ball inside the other), rare
    return {"l2": l2, "y": y, "il2": il2, "x2": x2, "y2": y2, "z2": z2, "sz": np.sign(z),
            "sy": np.sign(y), "sb": sb, "sa": sa, "p": p, "a": a, "b": b}


def take_round_cone_geometry(g, idx):
    """Rows ``idx`` (along the first axis) of a :func:`round_cone_geometry`."""
    points = ("p", "a", "b")                 # (..., 3); the rest are scalars per pair
    shape = np.broadcast_shapes(*(np.shape(v) for k, v in g.items() if k not in points))
    out = {k: np.broadcast_to(v, shape)[idx] for k, v in g.items() if k not in points}
    out.update({k: np.broadcast_to(g[k], shape + (3,))[idx] for k in points})
    return out


def sd_round_cone_radii(g, r1, r2):
    """:func:`sd_round_cone` from its :func:`round_cone_geometry` and the radii."""
    r1 = np.asarray(r1, dtype=np.float64)
    r2 = np.asarray(r2, dtype=np.float64)
    l2, y, il2, x2 = g["l2"], g["y"], g["il2"], g["x2"]
    rr = r1 - r2
    a2 = l2 - rr * rr
    with np.errstate(divide="ignore", invalid="ignore"):
        k = np.sign(rr) * rr * rr * x2
        d_b = g["sb"] - r2
        d_a = g["sa"] - r1
        d_side = (np.sqrt(np.maximum(x2 * a2 * il2, 0.0)) + y * rr) * il2 - r1
        d = np.where(g["sz"] * a2 * g["z2"] > k, d_b, np.where(g["sy"] * a2 * g["y2"] < k, d_a, d_side))
    # One ball contains the other (or a == b): the larger ball.
    degenerate = a2 <= 0
    if np.any(degenerate):
        # only where it applies (a few pairs; the whole array took half of a radius fit)
        shape = np.broadcast_shapes(np.shape(d), degenerate.shape)
        at = np.flatnonzero(np.broadcast_to(degenerate, shape))
        def flat(x, *tail):
            return np.broadcast_to(x, shape + tail).reshape((-1,) + tail)[at]

        p, a, b = (flat(g[key], 3) for key in ("p", "a", "b"))
        R1, R2 = flat(r1), flat(r2)
        centre = np.where((R1 >= R2)[:, None], a, b)
        d = np.array(np.broadcast_to(d, shape)).reshape(-1)
        d[at] = np.linalg.norm(p - centre, axis=-1) - np.maximum(R1, R2)
        d = d.reshape(shape)
    return d


def primitive_joints(n_joints, bones):
    """(i, j): the end joints of every silhouette primitive, one per bone, then one ball
    (i == j) per bone-less joint."""
    bones = np.asarray(bones, dtype=np.int64).reshape(-1, 2)
    lonely = np.setdiff1d(np.arange(n_joints), bones.ravel())
    return np.concatenate([bones[:, 0], lonely]), np.concatenate([bones[:, 1], lonely])


def _primitives(joints, bones):
    """(a, b, r1, r2) of every silhouette primitive (:func:`primitive_joints`)."""
    joints = np.asarray(joints, dtype=np.float64).reshape(-1, 4)
    i, j = primitive_joints(len(joints), bones)
    r = np.abs(joints[:, 3])
    return joints[i, :3], joints[j, :3], r[i], r[j]


def _min_over_primitives(P, centres, rho, fn, *, k=8, upper=None):
    """Exact ``min_j fn(P_i, j)`` for every point, with pruning.

    ``fn(pi, pj)`` evaluates the (signed) distance of points ``P[pi]`` to primitives ``pj``
    (index arrays of equal length); it must satisfy ``fn >= |P_i - centres_j| - rho_j``
    (the primitive lies in the ball ``B(centres_j, rho_j)``). Candidates are the k nearest
    centres, k growing 4-fold until ``|P - c_(k)| - max rho`` reaches the best value (no unseen
    primitive can then be smaller); within the candidates, ``fn`` is evaluated only where the
    bound ``|P - c_j| - rho_j`` is below the best value so far. Primitives with an outlying
    ``rho`` are evaluated for every point (brute force) so one huge primitive does not defeat
    the pruning.

    Parameters
    ----------
    upper : (n,) float, optional
        A value known to be attained by some primitive (e.g. the distance to the nearest mesh
        vertex): tightens the pruning from the start.

    Returns
    -------
    best : (n,) float, arg : (n,) int
    """
    n, m = len(P), len(centres)
    best = np.full(n, np.inf)
    arg = np.full(n, -1, np.int64)
    ub = np.full(n, np.inf) if upper is None else np.asarray(upper, dtype=np.float64).copy()
    if n == 0 or m == 0:
        return best, arg

    def brute(ids):
        step = max(1, _CHUNK // max(len(ids), 1))
        for s in range(0, n, step):
            pi = np.arange(s, min(s + step, n))
            PI = np.repeat(pi, len(ids))
            PJ = np.tile(ids, len(pi))
            v = fn(PI, PJ).reshape(len(pi), len(ids))
            a = np.argmin(v, axis=1)
            vmin = v[np.arange(len(pi)), a]
            upd = vmin < best[pi]
            best[pi[upd]] = vmin[upd]
            arg[pi[upd]] = ids[a[upd]]

    if m <= 32:
        brute(np.arange(m))
        return best, arg
    thr = max(3.0 * float(np.median(rho)), float(np.quantile(rho, 0.999)))
    big = rho > thr
    if big.any():
        brute(np.flatnonzero(big))
    small = np.flatnonzero(~big)
    if small.size == 0:
        return best, arg
    tree = cKDTree(centres[small], balanced_tree=False, compact_nodes=False)
    rmax = float(rho[small].max())
    todo = np.arange(n)
    kprev, kk = 0, min(k, small.size)
    while todo.size:
        step = max(1, _CHUNK // kk)
        settled = []
        for s in range(0, todo.size, step):
            pi = todo[s:s + step]
            d, idx = tree.query(P[pi], k=kk)
            d = d.reshape(len(pi), kk)
            pj = small[idx.reshape(len(pi), kk)[:, kprev:]]
            lb = d[:, kprev:] - rho[pj]
            need = lb <= np.minimum(best[pi], ub[pi])[:, None]
            rows, cols = np.nonzero(need)
            if rows.size:
                jj = pj[rows, cols]
                v = fn(pi[rows], jj)
                order = np.lexsort((v, rows))          # per row, smallest value first
                rows, v, jj = rows[order], v[order], jj[order]
                first = np.concatenate([[True], rows[1:] != rows[:-1]])
                r0, v0, j0 = rows[first], v[first], jj[first]
                upd = v0 < best[pi[r0]]
                best[pi[r0[upd]]] = v0[upd]
                arg[pi[r0[upd]]] = j0[upd]
            if kk < small.size:
                far = d[:, -1] - rmax
                ok = (far >= best[pi]) | (far > ub[pi])
            else:
                ok = np.ones(len(pi), bool)
            settled.append(ok)
        todo = todo[~np.concatenate(settled)]
        kprev, kk = kk, min(kk * 4, small.size)
        if kk > 32 and todo.size:
            break
    if todo.size:
        # Far points (many primitives at similar distances): every primitive whose ball can beat
        # the best value, from one ball query each (no k-nearest heap of huge k).
        step = max(1, _CHUNK // 1024)
        for s in range(0, todo.size, step):
            pi = todo[s:s + step]
            radius = np.minimum(best[pi], ub[pi]) + rmax
            lists = tree.query_ball_point(P[pi], radius, return_sorted=False)
            cnt = np.fromiter((len(x) for x in lists), np.int64, len(lists))
            if cnt.sum() == 0:
                continue
            jj = small[np.fromiter(itertools.chain.from_iterable(lists), np.int64, int(cnt.sum()))]
            pp = np.repeat(pi, cnt)
            lb = np.linalg.norm(P[pp] - centres[jj], axis=1) - rho[jj]
            keep = lb <= np.minimum(best[pp], ub[pp])
            pp, jj = pp[keep], jj[keep]
            for c0 in range(0, pp.size, _CHUNK):
                pc, jc = pp[c0:c0 + _CHUNK], jj[c0:c0 + _CHUNK]
                v = fn(pc, jc)
                order = np.lexsort((v, pc))
                pc, v, jc = pc[order], v[order], jc[order]
                first = np.concatenate([[True], pc[1:] != pc[:-1]])
                p0, v0, j0 = pc[first], v[first], jc[first]
                upd = v0 < best[p0]
                best[p0[upd]] = v0[upd]
                arg[p0[upd]] = j0[upd]
    return best, arg


def silhouette_sdf(P, joints, bones):
    """Signed distance of points to the silhouette (union of round cones): ``min_b sd_b``.

    Exact outside the silhouette; inside it is the standard union bound (``|sdf|`` never exceeds
    the true distance to the union's boundary).

    Parameters
    ----------
    P : (n, 3) float
    joints : (J, 4) float
    bones : (B, 2) int

    Returns
    -------
    (n,) float
    """
    P = np.asarray(P, dtype=np.float64).reshape(-1, 3)
    a, b, r1, r2 = _primitives(joints, bones)
    if len(a) == 0:
        raise CurveSkelError("the skeleton has no joints")
    centres = (a + b) / 2
    rho = np.linalg.norm(b - a, axis=1) / 2 + np.maximum(r1, r2)

    def fn(pi, pj):
        return sd_round_cone(P[pi], a[pj], b[pj], r1[pj], r2[pj])

    best, _ = _min_over_primitives(P, centres, rho, fn)
    return best


# ---------------------------------------------------------------------------------------------
# Triangles
# ---------------------------------------------------------------------------------------------
def _dot(u, v):
    return np.einsum("ij,ij->i", u, v)


def point_triangle_distance(p, a, b, c):
    """Exact distance from points to triangles, row by row (Ericson's closest-point regions).

    Parameters
    ----------
    p, a, b, c : (n, 3) float

    Returns
    -------
    (n,) float

    Examples
    --------
    >>> z = np.zeros((1, 3)); e = np.eye(3)
    >>> float(point_triangle_distance(np.array([[0.2, 0.2, 1.0]]), z, e[:1], e[1:2])[0])
    1.0
    """
    p, a, b, c = (np.asarray(x, dtype=np.float64).reshape(-1, 3) for x in (p, a, b, c))
    ab, ac = b - a, c - a
    ap, bp, cp = p - a, p - b, p - c
    d1, d2 = _dot(ab, ap), _dot(ac, ap)
    d3, d4 = _dot(ab, bp), _dot(ac, bp)
    d5, d6 = _dot(ab, cp), _dot(ac, cp)
    va = d3 * d6 - d5 * d4
    vb = d5 * d2 - d1 * d6
    vc = d1 * d4 - d3 * d2
    with np.errstate(divide="ignore", invalid="ignore"):
        den = va + vb + vc
        v = vb / den
        w = vc / den
        q = a + ab * v[:, None] + ac * w[:, None]                                # face region
        # edges (checked in reverse precedence so the earlier regions win)
        wbc = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        m = (va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0)
        q = np.where(m[:, None], b + (c - b) * wbc[:, None], q)
        wac = d2 / (d2 - d6)
        m = (vb <= 0) & (d2 >= 0) & (d6 <= 0)
        q = np.where(m[:, None], a + ac * wac[:, None], q)
        vab = d1 / (d1 - d3)
        m = (vc <= 0) & (d1 >= 0) & (d3 <= 0)
        q = np.where(m[:, None], a + ab * vab[:, None], q)
    q = np.where(((d6 >= 0) & (d5 <= d6))[:, None], c, q)
    q = np.where(((d3 >= 0) & (d4 <= d3))[:, None], b, q)
    q = np.where(((d1 <= 0) & (d2 <= 0))[:, None], a, q)
    dist = np.linalg.norm(p - q, axis=1)
    bad = ~np.isfinite(dist)
    if bad.any():   # zero-area triangle: nearest of its three edges
        dist[bad] = np.min([_point_segment_distance(p[bad], s, e)
                            for s, e in ((a[bad], b[bad]), (b[bad], c[bad]), (a[bad], c[bad]))], axis=0)
    return dist


def _segment_param(p, s, e):
    """Parameter u in [0, 1] of the closest point s + u (e - s) to p, row by row."""
    d = e - s
    dd = _dot(d, d)
    with np.errstate(divide="ignore", invalid="ignore"):
        u = np.where(dd > 0, _dot(p - s, d) / dd, 0.0)
    return np.clip(u, 0.0, 1.0)


def _point_segment_distance(p, s, e):
    u = _segment_param(p, s, e)
    return np.linalg.norm(p - (s + (e - s) * u[:, None]), axis=1)


def mesh_distance(P, V, F):
    """Exact unsigned distance from points to a triangle mesh surface.

    Candidate triangles come from a KD-tree on triangle centroids; a point is settled once no
    remaining triangle can be closer (centroid distance minus the triangle's circumscribing
    radius about its centroid). No Python loop over points.

    Parameters
    ----------
    P : (n, 3) float
    V : (nv, 3) float
    F : (m, 3) int

    Returns
    -------
    (n,) float
    """
    P = np.asarray(P, dtype=np.float64).reshape(-1, 3)
    V = np.asarray(V, dtype=np.float64)
    F = np.asarray(F, dtype=np.int64)
    T = V[F]
    cen = T.mean(axis=1)
    rho = np.linalg.norm(T - cen[:, None, :], axis=2).max(axis=1)

    def fn(pi, pj):
        return point_triangle_distance(P[pi], T[pj, 0], T[pj, 1], T[pj, 2])

    used = np.unique(F)
    upper = cKDTree(V[used], balanced_tree=False).query(P)[0]    # nearest vertex: attained
    best, _ = _min_over_primitives(P, cen, rho, fn, upper=upper)
    return best


# ---------------------------------------------------------------------------------------------
# Sampling
# ---------------------------------------------------------------------------------------------
def sample_surface(V, F, n, rng):
    """``n`` area-uniform random points on a triangle mesh. Returns (n, 3)."""
    T = np.asarray(V, dtype=np.float64)[np.asarray(F, dtype=np.int64)]
    area = np.linalg.norm(np.cross(T[:, 1] - T[:, 0], T[:, 2] - T[:, 0]), axis=1) / 2
    if not area.sum() > 0:
        raise CurveSkelError("the mesh has no area to sample")
    f = rng.choice(len(T), size=n, p=area / area.sum())
    u, v = rng.random(n), rng.random(n)
    flip = u + v > 1
    u[flip], v[flip] = 1 - u[flip], 1 - v[flip]
    t = T[f]
    return t[:, 0] + (t[:, 1] - t[:, 0]) * u[:, None] + (t[:, 2] - t[:, 0]) * v[:, None]


def _unit_vectors(n, rng):
    x = rng.normal(size=(n, 3))
    return x / np.maximum(np.linalg.norm(x, axis=1, keepdims=True), 1e-300)


def orthonormal_frame(u):
    """Two unit vectors (e1, e2) orthogonal to each unit row of u (zero for a zero row)."""
    ref = np.where((np.abs(u[:, 0]) < 0.9)[:, None], np.array([1.0, 0, 0]), np.array([0, 1.0, 0]))
    e1 = np.cross(u, ref)
    e1 /= np.maximum(np.linalg.norm(e1, axis=1, keepdims=True), 1e-300)
    return e1, np.cross(u, e1)


def sample_silhouette_boundary(joints, bones, n, rng, *, tol=1e-7):
    """Area-uniform samples of the boundary of the silhouette (union of round cones).

    Candidate surfaces are every joint's sphere and every bone's lateral cone (the frustum
    tangent to both end spheres); ``n`` candidates are drawn in proportion to area, and only
    those not strictly inside any primitive (``sdf > -tol * size``) are kept, so the kept points
    are area-uniform on the union's boundary.

    Returns
    -------
    (k, 3) float, k <= n
        Empty if every radius is zero (then the silhouette has no surface; see
        :func:`bone_points`).
    """
    joints = np.asarray(joints, dtype=np.float64).reshape(-1, 4)
    bones = np.asarray(bones, dtype=np.int64).reshape(-1, 2)
    r = np.abs(joints[:, 3])
    x = joints[:, :3]
    # lateral surfaces
    a, b = x[bones[:, 0]], x[bones[:, 1]]
    r1, r2 = r[bones[:, 0]], r[bones[:, 1]]
    ba = b - a
    L = np.linalg.norm(ba, axis=1)
    has_side = L > np.abs(r1 - r2)
    with np.errstate(divide="ignore", invalid="ignore"):
        sin = np.where(has_side, (r1 - r2) / L, 0.0)
    cos = np.sqrt(np.maximum(1 - sin * sin, 0.0))
    rho1, rho2 = r1 * cos, r2 * cos
    side_area = np.where(has_side, np.pi * (rho1 + rho2) * L * cos, 0.0)
    sphere_area = 4 * np.pi * r * r
    areas = np.concatenate([sphere_area, side_area])
    total = areas.sum()
    if not total > 0:
        return np.zeros((0, 3))
    which = rng.choice(len(areas), size=n, p=areas / total)
    on_sphere = which < len(r)
    out = np.empty((n, 3))
    js = which[on_sphere]
    out[on_sphere] = x[js] + r[js, None] * _unit_vectors(js.size, rng)
    bs = which[~on_sphere] - len(r)
    if bs.size:
        u = ba[bs] / L[bs, None]
        e1, e2 = orthonormal_frame(u)
        ang = rng.random(bs.size) * 2 * np.pi
        radial = np.cos(ang)[:, None] * e1 + np.sin(ang)[:, None] * e2
        nrm = cos[bs, None] * radial + sin[bs, None] * u        # outward normal of the frustum
        # s in [0, 1] with density proportional to the ring radius (1 - s) rho1 + s rho2
        g = rng.random(bs.size)
        p1, p2 = rho1[bs], rho2[bs]
        s = (p1 + p2) * g / (p1 + np.sqrt(p1 * p1 + (p2 * p2 - p1 * p1) * g))
        s = np.nan_to_num(s, nan=g)
        start = a[bs] + r1[bs, None] * nrm
        end = b[bs] + r2[bs, None] * nrm
        out[~on_sphere] = start + (end - start) * s[:, None]
    size = float(np.linalg.norm(np.ptp(x, axis=0))) + float(r.max())
    keep = silhouette_sdf(out, joints, bones) > -tol * max(size, 1e-300)
    return out[keep]


def bone_points(joints, bones, per_bone=10):
    """Points along every bone at ``t = (k + 1/2) / per_bone``; bone-less joints once each."""
    joints = np.asarray(joints, dtype=np.float64).reshape(-1, 4)
    bones = np.asarray(bones, dtype=np.int64).reshape(-1, 2)
    t = (np.arange(per_bone) + 0.5) / per_bone
    xi, xj = joints[bones[:, 0], :3], joints[bones[:, 1], :3]
    P = (t[None, :, None] * xi[:, None, :] + (1 - t)[None, :, None] * xj[:, None, :]).reshape(-1, 3)
    lonely = np.setdiff1d(np.arange(len(joints)), bones.ravel())
    return np.concatenate([P, joints[lonely, :3]])


# ---------------------------------------------------------------------------------------------
# Inside / outside (the fast test is the core's: :mod:`curveskel_addon.core.geometry.inside`)
# ---------------------------------------------------------------------------------------------
def winding_number(P, V, F):
    """Exact generalized winding number (Jacobson et al. 2013), chunked O(points x faces).

    Slow on big meshes; :func:`inside_mesh` is the fast test. Used as a reference in tests.
    """
    P = np.asarray(P, dtype=np.float64).reshape(-1, 3)
    T = np.asarray(V, dtype=np.float64)[np.asarray(F, dtype=np.int64)]
    out = np.zeros(len(P))
    step = max(1, _CHUNK // max(len(T), 1))
    for s in range(0, len(P), step):
        p = P[s:s + step, None, None, :]
        A = T[None] - p                                # (c, m, 3, 3)
        n = np.linalg.norm(A, axis=3)
        a, b, c = A[:, :, 0], A[:, :, 1], A[:, :, 2]
        la, lb, lc = n[:, :, 0], n[:, :, 1], n[:, :, 2]
        det = np.einsum("...i,...i->...", a, np.cross(b, c))
        den = (la * lb * lc + np.einsum("...i,...i->...", a, b) * lc
               + np.einsum("...i,...i->...", b, c) * la + np.einsum("...i,...i->...", c, a) * lb)
        out[s:s + step] = np.arctan2(det, den).sum(axis=1) / (2 * np.pi)
    return out


# ---------------------------------------------------------------------------------------------
# Energy, mapping, topology
# ---------------------------------------------------------------------------------------------
def closest_mapping(V, joints, bones):
    """A skeleton mapping for skeletons that carry none: each vertex to its closest bone point
    (:func:`curveskel_addon.core.geometry.segments.closest_on_bones` over every bone).

    Returns
    -------
    bone : (n,) int, t : (n,) float
        With the convention of :class:`Skeleton`: ``sigma = t x_i + (1 - t) x_j``.
    """
    bones = np.asarray(bones, dtype=np.int64).reshape(-1, 2)
    if len(bones) == 0:
        raise CurveSkelError("a skeleton without bones has no mapping")
    bone, t, _ = closest_on_bones(np.asarray(V, dtype=np.float64).reshape(-1, 3),
                                  np.asarray(joints, dtype=np.float64).reshape(-1, 4), bones)
    return bone, t


def energy_measures(V, F, joints, bones, bone, t, D):
    """Normalised energies: (vertex mean, area mean) of the squared residuals, / D^4."""
    V = np.asarray(V, dtype=np.float64)
    i, j = bones[bone, 0], bones[bone, 1]
    sig = t[:, None] * joints[i, :3] + (1 - t[:, None]) * joints[j, :3]
    rad = t * joints[i, 3] + (1 - t) * joints[j, 3]
    e = np.sum((V - sig) ** 2, axis=1) - rad ** 2
    a = vertex_areas(V, F)
    D4 = D ** 4
    return float(np.mean(e * e) / D4), float(np.sum(a * e * e) / (a.sum() * D4))


def skeleton_topology(n_joints, bones):
    """Components, independent cycles (B - J + C), leaves and branch points of a joint graph."""
    bones = np.asarray(bones, dtype=np.int64).reshape(-1, 2)
    if n_joints == 0:
        return {"skeleton_components": 0, "skeleton_cycles": 0, "leaves": 0, "branch_points": 0}
    C, _ = connected_components(adjacency(n_joints, bones), directed=False)
    deg = np.bincount(bones.ravel(), minlength=n_joints)
    return {"skeleton_components": int(C), "skeleton_cycles": int(len(bones) - n_joints + C),
            "leaves": int((deg == 1).sum()), "branch_points": int((deg >= 3).sum())}


def mesh_topology(V, F):
    """Components, Euler characteristic, boundary loops and genus of a mesh (duplicates merged).

    Per component, ``chi = V - E + F`` and ``g = (2 - chi - b) / 2`` with ``b`` the boundary
    loops (cycles of edges with one face); totals are summed over components.
    """
    V = np.asarray(V, dtype=np.float64).reshape(-1, 3)
    F = np.asarray(F, dtype=np.int64).reshape(-1, 3)
    # merge identical positions (lexsort is much faster than np.unique(axis=0) on big meshes)
    order = np.lexsort(V.T[::-1])
    Vs = V[order]
    new_group = np.concatenate([[True], np.any(Vs[1:] != Vs[:-1], axis=1)])
    gid = np.empty(len(V), np.int64)
    gid[order] = np.cumsum(new_group) - 1
    Fw = gid[F]
    Fw = Fw[(Fw[:, 0] != Fw[:, 1]) & (Fw[:, 1] != Fw[:, 2]) & (Fw[:, 0] != Fw[:, 2])]
    if len(Fw) == 0:
        raise CurveSkelError("the mesh has no non-degenerate face")
    used, Fw = np.unique(Fw, return_inverse=True)
    Fw = Fw.reshape(-1, 3)
    n = len(used)
    E = np.concatenate([Fw[:, [0, 1]], Fw[:, [1, 2]], Fw[:, [2, 0]]])
    E.sort(axis=1)
    keys, cnt = np.unique(E[:, 0] * n + E[:, 1], return_counts=True)
    Eu = np.stack([keys // n, keys % n], axis=1)
    C, lab = connected_components(adjacency(n, Eu), directed=False)
    nv = np.bincount(lab, minlength=C)
    ne = np.bincount(lab[Eu[:, 0]], minlength=C)
    nf = np.bincount(lab[Fw[:, 0]], minlength=C)
    chi = nv - ne + nf
    bnd = Eu[cnt == 1]
    if len(bnd):
        # boundary loops: components of the boundary-edge graph (vertices on the boundary only)
        bv = np.unique(bnd)
        loc = np.searchsorted(bv, bnd)
        nb, blab = connected_components(adjacency(len(bv), loc), directed=False)
        loop_comp = np.zeros(nb, np.int64)
        loop_comp[blab] = lab[bv]
        b = np.bincount(loop_comp, minlength=C)
    else:
        b = np.zeros(C, np.int64)
    g = (2 - chi - b) // 2
    return {"mesh_components": int(C), "mesh_euler": int(chi.sum()), "mesh_genus": int(g.sum()),
            "mesh_boundaries": int(b.sum()), "mesh_nonmanifold_edges": int((cnt > 2).sum())}


# ---------------------------------------------------------------------------------------------
# All measures
# ---------------------------------------------------------------------------------------------
def quality(V, F, skeleton, *, n_samples=20000, seed=0, bone_samples=10, reference=None) -> dict:
    """Measures of a skeleton's quality against its mesh (see the module docstring).

    Parameters
    ----------
    V : (n, 3) float
        Mesh vertices (the skeleton's mapping, if any, is in this order).
    F : (m, 3) int
        Triangles.
    skeleton : Skeleton or object with ``joints`` (J, 4) and ``bones`` (B, 2)
        ``bone`` and ``t`` (per vertex) are used for the energies when present with one entry
        per vertex; otherwise the closest-point mapping is used and ``energy_mapping`` says so.
    n_samples : int
        Samples of the mesh surface and (candidates) of the silhouette's boundary.
    seed : int
        Seed of every random choice; results are reproducible.
    bone_samples : int
        Points per bone for ``inside``.
    reference : skeleton, optional
        A reference curve skeleton in any form of :func:`curve_arrays` (e.g. the path of
        ``../shared/reference/<mesh>.json``): adds ``to_ref_*``, ``from_ref_*`` and
        ``length_ratio`` (:func:`shape_measures`).

    Returns
    -------
    dict
        Floats and ints, JSON-ready; keys as in the module docstring plus ``D`` and
        ``measure_seconds`` (time per measure group); always the reference-free shape measures
        ``zigzag``, ``turn_p90``, ``folds``, ``fold_pairs`` (:func:`curve_measures`).

    Examples
    --------
    >>> q = quality(V, F, skeletonize(V, F))                 # doctest: +SKIP
    >>> q["recon_mean"], q["inside"], q["topology_match"]    # doctest: +SKIP
    """
    V = np.asarray(V, dtype=np.float64).reshape(-1, 3)
    F = np.asarray(F, dtype=np.int64).reshape(-1, 3)
    joints = np.asarray(skeleton.joints, dtype=np.float64).reshape(-1, 4)
    bones = np.asarray(skeleton.bones, dtype=np.int64).reshape(-1, 2)
    if len(joints) == 0:
        raise CurveSkelError("the skeleton has no joints")
    used = np.unique(F)
    D = float(np.linalg.norm(col_ptp(V[used])))
    if not D > 0:
        raise CurveSkelError("the mesh has zero size")
    rng = np.random.default_rng(seed)
    out: dict = {"D": D}
    secs: dict = {}

    t0 = time.perf_counter()
    bone = getattr(skeleton, "bone", None)
    t = getattr(skeleton, "t", None)
    if len(bones) and bone is not None and t is not None and len(bone) == len(V) and len(t) == len(V):
        out["energy_mapping"] = "skeleton"
        bone = np.asarray(bone, np.int64)
        t = np.asarray(t, np.float64)
    elif len(bones):
        out["energy_mapping"] = "closest"
        bone, t = closest_mapping(V, joints, bones)
    if len(bones):
        out["energy_vertex"], out["energy_area"] = energy_measures(V, F, joints, bones, bone, t, D)
    else:
        out["energy_mapping"] = "none"
        out["energy_vertex"] = out["energy_area"] = float("nan")
    secs["energy"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    S = sample_surface(V, F, n_samples, rng)
    d = np.abs(silhouette_sdf(S, joints, bones)) / D
    out["recon_mean"] = float(d.mean())
    out["recon_p95"] = float(np.quantile(d, 0.95))
    out["recon_max"] = float(d.max())
    secs["recon"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    B = sample_silhouette_boundary(joints, bones, n_samples, rng)
    if len(B) == 0:        # all radii zero: the silhouette is the curve itself
        B = bone_points(joints, bones, max(1, n_samples // max(len(bones), 1)))
    dr = mesh_distance(B, V, F) / D
    out["recon_rev_mean"] = float(dr.mean())
    out["recon_rev_p95"] = float(np.quantile(dr, 0.95))
    out["recon_rev_max"] = float(dr.max())
    out["recon_sym"] = (out["recon_mean"] + out["recon_rev_mean"]) / 2
    secs["recon_rev"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    P = bone_points(joints, bones, bone_samples)
    out["inside"] = float(inside_mesh(P, V, F, seed=seed).mean())
    secs["inside"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    st = skeleton_topology(len(joints), bones)
    mt = mesh_topology(V, F)
    out.update(st)
    out.update(mt)
    # separate parts joined into figures count as one each (issue 31), and a seam between
    # parts already joined closes a loop the parts' own genus does not have
    parts = (getattr(skeleton, "meta", None) or {}).get("parts")
    want_c = int(parts["trees"]) if parts and "trees" in parts else mt["mesh_components"]
    want_g = mt["mesh_genus"] + (int(parts.get("loops", 0)) if parts else 0)
    out["expected_components"], out["expected_cycles"] = want_c, want_g
    out["topology_match"] = bool(st["skeleton_components"] == want_c
                                 and st["skeleton_cycles"] == want_g)
    out["joints"] = int(len(joints))
    out["bones"] = int(len(bones))
    secs["topology"] = time.perf_counter() - t0

    t0 = time.perf_counter()
    sm = shape_measures(V, F, (joints, bones), reference, D=D)
    out.update({k: sm[k] for k in ("zigzag", "turn_p90", "folds", "fold_pairs", "to_ref_mean",
                                   "to_ref_p95", "from_ref_mean", "from_ref_p95", "length_ratio")
                if k in sm})
    secs["shape"] = time.perf_counter() - t0
    out["measure_seconds"] = secs
    return out


# ---------------------------------------------------------------------------------------------
# Shape of the curve (issue 10): against a reference curve skeleton, and on its own
# ---------------------------------------------------------------------------------------------
#: Sampling steps of the to/from-reference distances, as fractions of D: the measured curve is
#: sampled every D/400 and compared with the other curve sampled every D/2000.
SHAPE_COARSE_STEP = 1.0 / 400
SHAPE_FINE_STEP = 1.0 / 2000
#: A degree-2 joint zig-zags when its chain turns by more than this many degrees.
ZIGZAG_DEGREES = 60.0
#: A fold: two bones within FOLD_NEAR * D of each other, more than FOLD_FAR * D apart along the
#: skeleton.
FOLD_NEAR = 0.01
FOLD_FAR = 0.1
#: A crossing: two bones within CROSS_WITHIN of the smaller radius of each other, more than
#: FOLD_FAR * D apart along the skeleton (see crossing_pairs).
CROSS_WITHIN = 0.3


def bbox_diagonal(V, F=None) -> float:
    """Diagonal of the bounding box of the vertices (only those used by ``F`` when given).

    The normalising length ``D`` of every measure in this module.

    Examples
    --------
    >>> bbox_diagonal(np.array([[0., 0, 0], [3, 4, 0], [9, 9, 9]]), np.array([[0, 1, 0]]))
    5.0
    """
    V = np.asarray(V, dtype=np.float64).reshape(-1, 3)
    if F is not None:
        V = V[np.unique(np.asarray(F, dtype=np.int64))]
    if len(V) == 0:
        return 0.0
    return float(np.linalg.norm(col_ptp(V)))


def curve_arrays(skeleton):
    """Joint positions (J, 3) and bones (B, 2) of a skeleton given in any usual form.

    Parameters
    ----------
    skeleton : Skeleton, object with ``joints``/``bones``, dict with those keys (e.g. a loaded
        curveskel-skeleton/1 JSON), a ``(joints, bones)`` pair, or a path to a JSON file.
        Joints may be (J, 3) or (J, 4) (the radius is ignored).

    Returns
    -------
    X : (J, 3) float, bones : (B, 2) int
        Bones joining a joint to itself are dropped.
    """
    if isinstance(skeleton, (str, os.PathLike)):
        with open(skeleton) as fh:
            skeleton = json.load(fh)
    if isinstance(skeleton, dict):
        joints, bones = skeleton["joints"], skeleton.get("bones", [])
    elif isinstance(skeleton, (tuple, list)):
        joints, bones = skeleton
    else:
        joints, bones = skeleton.joints, skeleton.bones
    J = np.asarray(joints, dtype=np.float64)
    J = J.reshape(len(J), -1) if J.size else np.zeros((0, 3))
    X = np.ascontiguousarray(J[:, :3])
    B = np.asarray(bones, dtype=np.int64).reshape(-1, 2)
    return X, B[B[:, 0] != B[:, 1]]


def segment_points(A, B, step):
    """Points every ``step`` (at most) along segments ``A[k] -> B[k]``, both ends included.

    Segment ``k`` of length ``L`` gets ``n = max(1, ceil(L / step))`` equal intervals, i.e.
    ``n + 1`` points (a joint shared by several segments appears once per segment).

    Parameters
    ----------
    A, B : (s, 3) float
    step : float, > 0

    Returns
    -------
    P : (p, 3) float
    owner : (p,) int
        The segment of each point.

    Examples
    --------
    >>> P, owner = segment_points(np.zeros((1, 3)), np.array([[1.0, 0, 0]]), 0.5)
    >>> P[:, 0].tolist(), owner.tolist()
    ([0.0, 0.5, 1.0], [0, 0, 0])
    """
    A = np.asarray(A, dtype=np.float64).reshape(-1, 3)
    B = np.asarray(B, dtype=np.float64).reshape(-1, 3)
    L = np.linalg.norm(B - A, axis=1)
    n = np.maximum(1, np.ceil(L / step)).astype(np.int64)
    owner = np.repeat(np.arange(len(A)), n + 1)
    start = np.cumsum(n + 1) - (n + 1)
    k = np.arange(owner.size) - np.repeat(start, n + 1)
    t = k / np.repeat(n, n + 1)
    return A[owner] + t[:, None] * (B[owner] - A[owner]), owner


def curve_points(X, bones, step):
    """Points every ``step`` along every bone (:func:`segment_points`); the joints if no bone."""
    X = np.asarray(X, dtype=np.float64)[:, :3]
    bones = np.asarray(bones, dtype=np.int64).reshape(-1, 2)
    if len(bones) == 0:
        return X.copy()
    return segment_points(X[bones[:, 0]], X[bones[:, 1]], step)[0]


def segment_segment_distance(p1, q1, p2, q2):
    """Exact distance between segments ``p1 q1`` and ``p2 q2``, row by row.

    Closest points of two segments (Ericson, *Real-Time Collision Detection*, 5.1.9), with
    degenerate (point) segments handled.

    Parameters
    ----------
    p1, q1, p2, q2 : (n, 3) float

    Returns
    -------
    (n,) float

    Examples
    --------
    >>> o, x = np.zeros((1, 3)), np.array([[1.0, 0, 0]])
    >>> float(segment_segment_distance(o, x, np.array([[0.5, 1, -1]]), np.array([[0.5, 1, 1]]))[0])
    1.0
    """
    p1, q1, p2, q2 = (np.asarray(x, dtype=np.float64).reshape(-1, 3) for x in (p1, q1, p2, q2))
    d1, d2, r = q1 - p1, q2 - p2, p1 - p2
    a, e = _dot(d1, d1), _dot(d2, d2)
    f, c, b = _dot(d2, r), _dot(d1, r), _dot(d1, d2)
    tiny = 1e-30
    den = a * e - b * b
    safe = lambda x: np.where(x > tiny, x, 1.0)  # noqa: E731
    # s on the infinite line pair (0 when parallel), clamped; then t, and s again if t clamps
    s = np.where(den > tiny * np.maximum(a * e, tiny), np.clip((b * f - c * e) / safe(den), 0, 1), 0.0)
    t = (b * s + f) / safe(e)
    s = np.where(t < 0, np.clip(-c / safe(a), 0, 1), np.where(t > 1, np.clip((b - c) / safe(a), 0, 1), s))
    t = np.clip(t, 0, 1)
    # point segments: the point's projection on the other segment
    s = np.where(a <= tiny, 0.0, np.where(e <= tiny, np.clip(-c / safe(a), 0, 1), s))
    t = np.where(e <= tiny, 0.0, np.where(a <= tiny, np.clip(f / safe(e), 0, 1), t))
    return np.linalg.norm(p1 + s[:, None] * d1 - (p2 + t[:, None] * d2), axis=1)


def turn_angles(X, bones):
    """Turning angle (degrees) of the chain at every degree-2 joint.

    At a joint ``j`` whose two bones lead to ``a`` and ``b`` the angle between ``x_j - x_a`` and
    ``x_b - x_j``: 0 for a straight chain, 180 where it doubles back. Joints with a zero-length
    bone are skipped.

    Parameters
    ----------
    X : (J, 3) float
    bones : (B, 2) int

    Returns
    -------
    joints : (k,) int
        The degree-2 joints measured.
    angles : (k,) float
        Degrees in [0, 180].

    Examples
    --------
    >>> X = np.array([[0., 0, 0], [1, 0, 0], [1, 1, 0]])
    >>> turn_angles(X, np.array([[0, 1], [1, 2]]))[1].round(6).tolist()
    [90.0]
    """
    X = np.asarray(X, dtype=np.float64)[:, :3]
    bones = np.asarray(bones, dtype=np.int64).reshape(-1, 2)
    bones = bones[bones[:, 0] != bones[:, 1]]
    if len(bones) < 2:
        return np.zeros(0, np.int64), np.zeros(0)
    # every (joint, other end) pair; a degree-2 joint's two entries are adjacent after sorting
    me = bones.ravel()
    other = bones[:, ::-1].ravel()
    order = np.argsort(me, kind="stable")
    me, other = me[order], other[order]
    deg = np.bincount(me, minlength=len(X))
    first = np.flatnonzero((deg[me] == 2) & np.concatenate([[True], me[1:] != me[:-1]]))
    j, a, b = me[first], other[first], other[first + 1]
    u, w = X[j] - X[a], X[b] - X[j]
    nu, nw = np.linalg.norm(u, axis=1), np.linalg.norm(w, axis=1)
    scale = max(float(np.linalg.norm(np.ptp(X, axis=0))), 1e-300)
    ok = (nu > 1e-12 * scale) & (nw > 1e-12 * scale)
    cos = _dot(u[ok], w[ok]) / (nu[ok] * nw[ok])
    return j[ok], np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))


def close_bone_pairs(X, bones, dist):
    """Pairs of distinct bones whose segments pass within ``dist`` of each other (``< dist``).

    Candidates come from a KD-tree on points sampled every ``dist`` along the bones (two
    segments within ``dist`` have samples within ``2 dist``), then the exact segment-segment
    distance decides. No O(B^2) pass.

    Parameters
    ----------
    X : (J, 3) float
    bones : (B, 2) int
    dist : float, > 0

    Returns
    -------
    pairs : (k, 2) int
        Bone indices, ``pairs[:, 0] < pairs[:, 1]``, sorted.
    d : (k,) float
        Their distances.
    """
    X = np.asarray(X, dtype=np.float64)[:, :3]
    bones = np.asarray(bones, dtype=np.int64).reshape(-1, 2)
    if len(bones) < 2 or not dist > 0:
        return np.zeros((0, 2), np.int64), np.zeros(0)
    A, B = X[bones[:, 0]], X[bones[:, 1]]
    total = float(np.linalg.norm(B - A, axis=1).sum())
    step = max(dist, total / 200_000)          # bound the number of samples
    P, owner = segment_points(A, B, step)
    # nearest samples to the closest points are within step / 2 each
    pp = cKDTree(P).query_pairs(dist + step, output_type="ndarray")
    if len(pp) == 0:
        return np.zeros((0, 2), np.int64), np.zeros(0)
    bp = np.sort(owner[pp], axis=1)
    bp = bp[bp[:, 0] != bp[:, 1]]
    if len(bp) == 0:
        return np.zeros((0, 2), np.int64), np.zeros(0)
    bp = np.unique(bp, axis=0)
    d = segment_segment_distance(A[bp[:, 0]], B[bp[:, 0]], A[bp[:, 1]], B[bp[:, 1]])
    keep = d < dist
    return bp[keep], d[keep]


def fold_pairs(X, bones, D, *, near=FOLD_NEAR, far=FOLD_FAR):
    """Bone pairs that pass within ``near * D`` of each other but are ``> far * D`` apart along
    the skeleton (a chain doubling back, a criss-cross). Pairs in different connected parts of
    the skeleton do not count.

    The distance along the skeleton between two bones is the shortest path (bone lengths as
    weights) between an end of one and an end of the other; bones sharing a joint are 0 apart.
    Shortest paths run (``scipy.sparse.csgraph.dijkstra``, limited to ``far * D``) only from the
    ends of bones in close pairs.

    Parameters
    ----------
    X : (J, 3) float
    bones : (B, 2) int
    D : float
        The normalising length (mesh bounding-box diagonal).
    near, far : float
        Fractions of D.

    Returns
    -------
    (k, 2) int
        Bone index pairs (smaller first).
    """
    X = np.asarray(X, dtype=np.float64)[:, :3]
    bones = np.asarray(bones, dtype=np.int64).reshape(-1, 2)
    pairs, _ = close_bone_pairs(X, bones, near * D)
    return _far_along(X, bones, pairs, far * D, D)


def crossing_pairs(joints, bones, D, *, within=CROSS_WITHIN, far=FOLD_FAR):
    """Bone pairs that pass within ``within`` times the smaller of their radii of each other
    but are ``> far * D`` apart along the skeleton: two bones in one part of the body (a
    criss-cross in a plate, two loops' sides doubled between two holes) where a fold's
    absolute 0.01 D misses them in a thick part. Pairs in different connected parts do not
    count; a bone's radius is the smaller of its joints'.

    Parameters
    ----------
    joints : (J, 4) float
        Positions and radii.
    bones : (B, 2) int
    D : float
        The normalising length of ``far`` (mesh bounding-box diagonal).

    Returns
    -------
    (k, 2) int
        Bone index pairs (smaller first).

    Examples
    --------
    A chain that turns back and crosses its first bone 0.1 apart (radius 1):

    >>> J = np.array([[0, 0, 0, 1], [4, 0, 0, 1], [4, 3, 0, 1], [2, 3, 0, 1], [2, -1, 0.1, 1]])
    >>> crossing_pairs(J, np.array([[0, 1], [1, 2], [2, 3], [3, 4]]), 10.0).tolist()
    [[0, 3]]
    """
    J = np.asarray(joints, dtype=np.float64).reshape(-1, 4)
    bones = np.asarray(bones, dtype=np.int64).reshape(-1, 2)
    r = np.minimum(J[bones[:, 0], 3], J[bones[:, 1], 3]) if len(bones) else np.zeros(0)
    if len(bones) < 2 or not np.any(r > 0):
        return np.zeros((0, 2), np.int64)
    pairs, d = close_bone_pairs(J[:, :3], bones, within * float(r.max()))
    pairs = pairs[d < within * np.minimum(r[pairs[:, 0]], r[pairs[:, 1]])]
    return _far_along(J[:, :3], bones, pairs, far * D, D)


def _far_along(X, bones, pairs, far_abs, D):
    """The ``pairs`` of bones (no shared joint) more than ``far_abs`` apart along the skeleton,
    in one connected part of it."""
    if len(pairs) == 0:
        return pairs
    e1, e2 = bones[pairs[:, 0]], bones[pairs[:, 1]]
    share = np.any(e1[:, :, None] == e2[:, None, :], axis=(1, 2))
    pairs, e1, e2 = pairs[~share], e1[~share], e2[~share]
    if len(pairs) == 0:
        return pairs
    n = len(X)
    # bone graph (duplicate bones once), with a tiny floor so zero-length bones still connect
    key = np.unique(np.sort(bones, axis=1), axis=0)
    w = np.linalg.norm(X[key[:, 1]] - X[key[:, 0]], axis=1) + 1e-12 * D
    G = csr_matrix((np.r_[w, w], (np.r_[key[:, 0], key[:, 1]], np.r_[key[:, 1], key[:, 0]])),
                   shape=(n, n))
    _, comp = connected_components(G, directed=False)
    same = comp[e1[:, 0]] == comp[e2[:, 0]]
    pairs, e1, e2 = pairs[same], e1[same], e2[same]
    if len(pairs) == 0:
        return pairs
    src, inv = np.unique(e1, return_inverse=True)
    inv = inv.reshape(-1, 2)
    limit = far_abs * (1 + 1e-9)
    g = np.full(len(pairs), np.inf)
    step = max(1, _CHUNK // max(n, 1))
    for s0 in range(0, len(src), step):            # chunks of sources bound the dense rows
        Dm = dijkstra(G, directed=False, indices=src[s0:s0 + step], limit=limit)
        for a in (0, 1):
            rows = inv[:, a] - s0
            ok = (rows >= 0) & (rows < len(Dm))
            for b in (0, 1):
                g[ok] = np.minimum(g[ok], Dm[rows[ok], e2[ok, b]])
    return pairs[g > far_abs]


def curve_measures(joints, bones=None, D=None, *, turn=ZIGZAG_DEGREES, near=FOLD_NEAR,
                   far=FOLD_FAR) -> dict:
    """Shape measures of a curve skeleton on its own (no reference, no mesh): zig-zag and folds.

    Parameters
    ----------
    joints : (J, 3|4) float, or any skeleton form of :func:`curve_arrays` (then ``bones=None``)
    bones : (B, 2) int
    D : float, optional
        The normalising length (the mesh's bounding-box diagonal, :func:`bbox_diagonal`); the
        skeleton's own bounding-box diagonal if omitted (folds then depend on the skeleton only).
    turn : float
        Degrees beyond which a degree-2 joint counts as a zig-zag.
    near, far : float
        Fold thresholds, fractions of D (see :func:`fold_pairs`).

    Returns
    -------
    dict
        zigzag
            Fraction of the degree-2 joints (with two non-zero bones) whose chain turns by more
            than ``turn`` degrees (0 if there is none).
        turn_p90
            90th percentile of those turning angles, degrees.
        folds
            Number of :func:`fold_pairs` divided by the number of bones.
        fold_pairs
            That number.
        crossings
            Number of :func:`crossing_pairs` divided by the number of bones (None without
            radii: joints given as (J, 3) or a reference curve).
        pinches
            Number of :func:`radius_pinches` (None without radii).
        length
            Sum of bone lengths / D.
        bones, degree2, leaves
            Counts.

    Examples
    --------
    >>> X = np.array([[0., 0, 0], [1, 0, 0], [2, 0, 0]])
    >>> m = curve_measures(X, np.array([[0, 1], [1, 2]]), D=2.0)
    >>> m["zigzag"], m["folds"], m["length"]
    (0.0, 0.0, 1.0)
    """
    r = _radii_of(joints)
    if bones is None:
        X, bones = curve_arrays(joints)
    else:
        X, bones = curve_arrays((joints, bones))
    if D is None:
        D = float(np.linalg.norm(np.ptp(X, axis=0))) if len(X) else 0.0
    _, ang = turn_angles(X, bones)
    L = float(np.linalg.norm(X[bones[:, 1]] - X[bones[:, 0]], axis=1).sum()) if len(bones) else 0.0
    folds = fold_pairs(X, bones, D, near=near, far=far) if D > 0 else np.zeros((0, 2), np.int64)
    deg = np.bincount(bones.ravel(), minlength=len(X))
    cross = (len(crossing_pairs(np.column_stack([X, r]), bones, D, far=far))
             if r is not None and len(r) == len(X) and D > 0 else None)
    pinch = (len(radius_pinches(r, bones)) if r is not None and len(r) == len(X) else None)
    return {
        "zigzag": float((ang > turn).mean()) if len(ang) else 0.0,
        "turn_p90": float(np.percentile(ang, 90)) if len(ang) else 0.0,
        "folds": float(len(folds) / max(len(bones), 1)),
        "fold_pairs": int(len(folds)),
        "crossings": float(cross / max(len(bones), 1)) if cross is not None else None,
        "pinches": pinch,
        "length": L / D if D > 0 else float("nan"),
        "bones": int(len(bones)),
        "degree2": int((deg == 2).sum()),
        "leaves": int((deg == 1).sum()),
    }


#: A chain joint whose radius is below this fraction of both its neighbours' pinches the skin.
PINCH_RATIO = 0.4


def radius_pinches(r, bones, ratio=PINCH_RATIO):
    """Chain joints (degree 2) whose radius is below ``ratio`` times both neighbours' radii: an
    hourglass waist in the silhouette and in Blender's Skin modifier that no part of the shape
    asks for (what a radius fit that the neighbours' balls make indifferent to a joint leaves).

    Returns
    -------
    (k,) int

    Examples
    --------
    >>> radius_pinches(np.array([1.0, 0.3, 1.0, 0.9]), np.array([[0, 1], [1, 2], [2, 3]])).tolist()
    [1]
    """
    r = np.abs(np.asarray(r, np.float64))
    chain, a, b = chain_neighbours(bones, len(r))
    return chain[r[chain] < ratio * np.minimum(r[a], r[b])]


def _radii_of(skeleton):
    """The joint radii of a skeleton given as (J, 4) joints, a (joints, bones) tuple or an object
    with ``.joints`` (J, 4); None for anything else (a curve without radii, a file)."""
    J = skeleton[0] if isinstance(skeleton, tuple) else getattr(skeleton, "joints", skeleton)
    if not isinstance(J, (np.ndarray, list)):
        return None
    J = np.asarray(J, dtype=np.float64)
    return J[:, 3] if J.ndim == 2 and J.shape[1] == 4 else None


def curve_distances(ours, reference, D, *, coarse=SHAPE_COARSE_STEP, fine=SHAPE_FINE_STEP) -> dict:
    """Distances between two curve skeletons, both ways, / D.

    ``to_ref``: points every ``coarse * D`` along our bones, each to the nearest of the points
    every ``fine * D`` along the reference's bones; ``from_ref``: the reverse (reference sampled
    coarsely, ours finely). The fine sampling's error is at most ``fine / 2`` (D/4000).

    Parameters
    ----------
    ours, reference : skeleton in any form of :func:`curve_arrays`
    D : float
    coarse, fine : float
        Sampling steps, fractions of D.

    Returns
    -------
    dict
        ``to_ref_mean``, ``to_ref_p95``, ``to_ref_max``, ``from_ref_mean``, ``from_ref_p95``,
        ``from_ref_max``.
    """
    X, b = curve_arrays(ours)
    Xr, br = curve_arrays(reference)
    if len(X) == 0 or len(Xr) == 0:
        raise CurveSkelError("a skeleton without joints has no distance to another")
    out = {}
    for name, (Xa, ba, Xb, bb) in (("to_ref", (X, b, Xr, br)), ("from_ref", (Xr, br, X, b))):
        P = curve_points(Xa, ba, coarse * D)
        Q = curve_points(Xb, bb, fine * D)
        d = cKDTree(Q).query(P)[0] / D
        out[f"{name}_mean"] = float(d.mean())
        out[f"{name}_p95"] = float(np.percentile(d, 95))
        out[f"{name}_max"] = float(d.max())
    return out


def mirror_asymmetry(V, skeleton, D) -> float | None:
    """How far a skeleton of a mirror-symmetric mesh is from its own mirror image, / D.

    The mesh's mirror plane is its one principal plane across which it is its own mirror image
    (:func:`curveskel_addon.core.initialise.pole.bilateral_plane`); the measure is the mean of
    :func:`curve_distances` both ways between the skeleton and its reflection across that plane.
    Why: a rigger mirrors a character's left side onto its right; a skeleton whose paired limbs
    branch off at different places (the elephant's front legs 25 units apart, the human's neck
    off one shoulder) was not caught by to_ref, which the reference's own asymmetry and a
    rounder curve elsewhere outweigh. The references of shared/ measure 0.003-0.004 D (spot,
    homer, elephant).

    Parameters
    ----------
    V : (n, 3) float
        The mesh's vertices (used by its faces).
    skeleton : any form of :func:`curve_arrays`
    D : float
        The normalising length (the bounding-box diagonal).

    Returns
    -------
    float, or None when the mesh is not mirror-symmetric across exactly one principal plane.
    """
    plane = bilateral_plane(np.asarray(V, np.float64))
    if plane is None:
        return None
    c, e = plane
    X, b = curve_arrays(skeleton)
    M = X - 2.0 * ((X - c) @ e)[:, None] * e
    d = curve_distances((X, b), (M, b), D)
    return 0.5 * (d["to_ref_mean"] + d["from_ref_mean"])


def section_offsets(V, F, skeleton, D=None, *, step=SHAPE_COARSE_STEP, reach=0.25,
                    centroids=False):
    """How far a curve runs from the centres of the mesh's cross-sections across it, / D.

    Points every ``step`` D along each bone are cut by the plane across the bone (normal along
    it); the section loop round each point (within ``reach`` D) has an area centroid, and the
    point's offset is its distance to that centroid. Why: issue 10 asks for joints held to the
    centre of their cross-section, and to_ref cannot say it where the reference itself runs
    off-centre (CGAL's loops on 3holes lie 0.03 D towards the holes): a curve brought nearer
    the centres scored worse there while the picture got better. Junctions and tips, where a
    plane across one bone cuts the body or a cap, read high: the median is the measure.

    Parameters
    ----------
    V : (n, 3) float, F : (m, 3) int
    skeleton : any form of :func:`curve_arrays`
    D : float, optional
        The normalising length (default: the bounding-box diagonal).

    Returns
    -------
    found : float
        The share of the points with a closed section loop round them.
    offsets : (k,) float
        Each found point's distance to its section's centroid, / D.
    C : (k, 3) float
        With ``centroids``: those centroids.

    Examples
    --------
    A straight bar's axis is its sections' centre; moved 0.1 off it, the offset is 0.1 / D:

    >>> from tests.meshes import box_bar                          # doctest: +SKIP
    >>> V, F = box_bar()                                          # doctest: +SKIP
    >>> found, off = section_offsets(V, F, ([[-3, 0.1, 0], [3, 0.1, 0]], [[0, 1]]))
    ... # doctest: +SKIP
    """
    V = np.asarray(V, np.float64)
    if D is None:
        D = bbox_diagonal(V, F)
    X, bones = curve_arrays(skeleton)
    a, b = X[bones[:, 0]], X[bones[:, 1]]
    L = np.linalg.norm(b - a, axis=1)
    keep = L > 0
    a, b, L = a[keep], b[keep], L[keep]
    if not len(L):
        return (0.0, np.zeros(0)) + ((np.zeros((0, 3)),) if centroids else ())
    n = np.maximum(1, np.ceil(L / (step * D))).astype(np.int64)
    bone = np.repeat(np.arange(len(L)), n)
    t = (np.arange(n.sum()) - np.repeat(np.cumsum(n) - n, n) + 0.5) / n[bone]
    P = a[bone] + t[:, None] * (b - a)[bone]
    T = ((b - a) / L[:, None])[bone]
    sec = cross_sections(V, np.asarray(F, np.int64), P, T, reach * D)
    ok, C = sec.found, sec.centroid
    out = (float(ok.mean()), np.linalg.norm(C[ok] - P[ok], axis=1) / D)
    return out + ((C[ok],) if centroids else ())


def shape_measures(V, F, skeleton, reference=None, *, D=None) -> dict:
    """All shape measures of issue 10 of a skeleton of mesh (V, F), against a reference curve.

    Parameters
    ----------
    V : (n, 3) float
    F : (m, 3) int
        Only used for ``D`` (the bounding-box diagonal of the vertices ``F`` uses).
    skeleton : Skeleton, ``(joints, bones)``, dict or JSON path (see :func:`curve_arrays`)
    reference : the same forms, optional
        E.g. ``../shared/reference/<mesh>.json``. Without it only the reference-free measures
        are returned.
    D : float, optional
        Overrides the normalising length.

    Returns
    -------
    dict
        ``D``; :func:`curve_measures` (``zigzag``, ``turn_p90``, ``folds``, ``fold_pairs``,
        ``length``, counts); ``mirror_asymmetry`` (:func:`mirror_asymmetry`, None unless the
        mesh is mirror-symmetric); with a reference also :func:`curve_distances` (``to_ref_*``,
        ``from_ref_*``), ``length_ratio`` (our total bone length / the reference's) and
        ``ref_length``, ``ref_leaves``.

    Examples
    --------
    >>> m = shape_measures(V, F, sk, "../shared/reference/horse.json")      # doctest: +SKIP
    >>> m["to_ref_mean"], m["from_ref_mean"], m["length_ratio"], m["zigzag"], m["folds"]  # doctest: +SKIP
    """
    if D is None:
        D = bbox_diagonal(V, F)
    if not D > 0:
        raise CurveSkelError("the mesh has zero size")
    X, b = curve_arrays(skeleton)
    out = {"D": float(D)}
    r = _radii_of(skeleton)                    # kept for the crossings where it has them
    out.update(curve_measures(X if r is None or len(r) != len(X) else np.column_stack([X, r]),
                              b, D))
    F = np.asarray(F, np.int64)
    out["mirror_asymmetry"] = mirror_asymmetry(np.asarray(V, np.float64)[np.unique(F)] if F.size
                                               else V, (X, b), D)
    if reference is not None:
        Xr, br = curve_arrays(reference)
        out.update(curve_distances((X, b), (Xr, br), D))
        Lr = float(np.linalg.norm(Xr[br[:, 1]] - Xr[br[:, 0]], axis=1).sum()) / D if len(br) else 0.0
        out["ref_length"] = Lr
        out["length_ratio"] = out["length"] / Lr if Lr > 0 else float("nan")
        out["ref_leaves"] = int((np.bincount(br.ravel(), minlength=len(Xr)) == 1).sum())
    return out
