"""Skin weights (pure, vectorised): from the armature's bones as they are now
(:func:`bone_weights`, what ``curveskel.bind`` uses), or from the skeleton mapping sigma
(:func:`skin_weights`).

``bone_weights`` gives each vertex the bone of the part of the body it lies on: its closest bone,
restricted to that bone's connected patch of the surface (:func:`surface_labels`), then blended at
the joints as below and smoothed along the surface, keeping only a bone, its parent and its
children per vertex (no weight on a sibling limb or across a gap).

With sigma, each vertex weighs its own bone; within ``blend`` (a fraction of the bone's length) of a joint it
is blended smoothly (smoothstep) with the neighbouring bone there:

- at a chain joint (degree 2) the two bones meet 50/50 at the joint;
- at a junction or the root the blend is one-sided: the hub bone (the parent that ends at the
  junction, or the root bone) has weight 1 at the joint and hands over to each child bone within
  the child's blend zone. Sibling branches never share weights, so posing a bone moves only its
  own vertices and its descendants', and weights are continuous across every joint.

With ``blend <= 0.5`` a vertex has at most 2 influences; arrays keep 4 columns (the usual limit
of game engines), unused columns have index -1 and weight 0.

The mapping itself can jump between bones where two branches' regions meet on the surface away
from a joint (a thigh against the flank). :func:`smooth_weights` diffuses the weights a short
distance over the mesh's edges (never across gaps in space) to close such seams, then keeps the 4
largest influences per vertex.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components, dijkstra
from scipy.spatial import cKDTree

from ..core.errors import CurveSkelError
from ..core.geometry.segments import closest_bone, closest_on_bones
from .rig_layout import BLEND_HUB, BLEND_SYMMETRIC, RigLayout

__all__ = ["skin_weights", "smooth_weights", "smoothing_iterations", "smoothstep", "project_on_bones",
           "bone_partners", "surface_labels", "bone_weights", "MAX_INFLUENCES"]

MAX_INFLUENCES = 4
#: Most smoothing steps of :func:`bone_weights` (the joints are already blended; the steps only
#: soften the seams between bone regions, and each costs a sparse product).
SMOOTH_CAP = 12
#: Largest (closed 1-ring entries x bones) smoothed on a dense array (about 0.3 ns each per step
#: here; the sparse product wins beyond, e.g. on a 43k-vertex mesh with 71 bones).
DENSE_SMOOTH_WORK = 16_000_000


def smoothstep(x):
    """3x^2 - 2x^3 on [0, 1] (clamped): 0 -> 0, 1 -> 1, zero slope at both ends."""
    x = np.minimum(np.maximum(x, 0.0), 1.0)                 # np.clip
    return x * x * (3.0 - 2.0 * x)


def skin_weights(layout: RigLayout, bone, t, *, blend: float = 0.25,
                 max_influences: int = MAX_INFLUENCES) -> tuple[np.ndarray, np.ndarray]:
    """Per-vertex (rig bone, weight) pairs from the skeleton mapping.

    Parameters
    ----------
    layout : RigLayout
        From :func:`rig_layout` on the same skeleton.
    bone : (n,) int
        Skeleton bone of each vertex (``Skeleton.bone``).
    t : (n,) float
        Position on it (``Skeleton.t``: sigma = t * x_i + (1 - t) * x_j).
    blend : float in [0, 0.5]
        Width of the blend zone at each end of a bone, as a fraction of the bone's length.
        0 gives rigid (one bone per vertex) weights.
    max_influences : int >= 2
        Columns of the result.

    Returns
    -------
    index : (n, max_influences) int
        Rig bone indices (``layout.names[index]`` is the vertex group), -1 where unused.
    weight : (n, max_influences) float
        Weights, sorted decreasing per row, summing to 1.

    Examples
    --------
    >>> from curveskel_addon.rig.rig_layout import rig_layout
    >>> J = [[0, 0, 0, .1], [1, 0, 0, .1], [2, 0, 0, .1], [3, 0, 0, .1]]
    >>> lay = rig_layout(J, [[0, 1], [1, 2], [2, 3]], root=0)
    >>> idx, w = skin_weights(lay, [1, 1], [0.5, 1.0])      # middle of bone 1; its joint with bone 0
    >>> [lay.names[i] for i in idx[0, :1]], w[0, :2].tolist(), w[1, :2].tolist()
    (['branch00.01'], [1.0, 0.0], [0.5, 0.5])
    """
    if not 0.0 <= blend <= 0.5:
        raise CurveSkelError(f"blend must be in [0, 0.5] of a bone's length, got {blend}")
    if max_influences < 2:
        raise CurveSkelError(f"max_influences must be at least 2, got {max_influences}")
    r, s = layout.rig_coordinates(bone, t)
    n = len(r)
    near_head = s < 0.5
    u = np.where(near_head, s, 1.0 - s)                     # distance to the nearer end, in [0, 0.5]
    mode = np.where(near_head, layout.head_mode[r], layout.tail_mode[r])
    partner = np.where(near_head, layout.head_partner[r], layout.tail_partner[r])
    if blend > 0:
        f = smoothstep(u / blend)
        share = np.where(mode == BLEND_SYMMETRIC, 0.5 * (1.0 - f),
                         np.where(mode == BLEND_HUB, 1.0 - f, 0.0))
    else:
        share = np.zeros(n)
    share = np.where(partner >= 0, share, 0.0)
    own = 1.0 - share
    index = np.full((n, max_influences), -1, np.int64)
    weight = np.zeros((n, max_influences))
    first = own >= share
    index[:, 0] = np.where(first, r, partner)
    weight[:, 0] = np.where(first, own, share)
    has = share > 0
    index[:, 1] = np.where(has, np.where(first, partner, r), -1)
    weight[:, 1] = np.where(has, np.where(first, share, own), 0.0)
    return index, weight


def smoothing_iterations(radius: float, edge_length: float, *, cap: int = 30) -> int:
    """Averaging steps that spread weights over about ``radius`` on a mesh of ``edge_length``.

    Averaging over the closed 1-ring moves weight about ``edge_length * sqrt(k)`` in k steps;
    capped at ``cap`` (dense meshes are then smoothed over a shorter distance).
    """
    if radius <= 0 or edge_length <= 0:
        return 0
    return int(min(cap, np.ceil((radius / edge_length) ** 2)))


def smooth_weights(index, weight, edges, *, iterations: int = 10,
                   max_influences: int = MAX_INFLUENCES, prune: float = 1e-4):
    """Diffuse per-vertex weights over the mesh's edges; keep the largest influences.

    Each step replaces a vertex's weights by their average over its closed 1-ring (itself and
    its neighbours), so rows keep summing to 1 and regions of constant weights do not change.

    Parameters
    ----------
    index : (n, k) int
        Bone of each influence, -1 for none (as returned by :func:`skin_weights`).
    weight : (n, k) float
    edges : (e, 2) int
        Mesh edges (vertex pairs).
    iterations : int >= 0
        Steps (see :func:`smoothing_iterations`).
    max_influences : int
        Columns of the result; the smallest weights beyond it are dropped.
    prune : float
        Weights below this are dropped: after each step on large meshes (keeps the sparse
        matrices sparse), after the last one where the weights fit a dense array.

    Returns
    -------
    index : (n, max_influences) int
    weight : (n, max_influences) float
        Sorted decreasing per row, summing to 1.
    """
    index = np.asarray(index, dtype=np.int64)
    weight = np.asarray(weight, dtype=np.float64)
    n = len(index)
    E = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
    if index.shape != weight.shape or index.ndim != 2:
        raise CurveSkelError(f"index {index.shape} and weight {weight.shape} must be equal (n, k) arrays")
    if len(E) and (E.min() < 0 or E.max() >= n):
        raise CurveSkelError("edge vertex index out of range")
    return _smooth(index, weight, _Graph(E, n) if iterations > 0 and len(E) else None, iterations,
                   max_influences, prune)


def _smooth(index, weight, graph, iterations, max_influences, prune):
    """:func:`smooth_weights` on a built graph (None or ``iterations`` 0: no diffusion)."""
    n = len(index)
    nb = int(index.max()) + 1 if index.size else 0
    ok = index >= 0
    rows = np.nonzero(ok)[0]                   # the row of each influence, in row-major order
    if iterations > 0 and graph is not None and nb and len(graph.indices) * nb <= DENSE_SMOOTH_WORK:
        return _smooth_dense(rows, index[ok], weight[ok], n, nb, graph, iterations,
                             max_influences, prune)
    W = sp.csr_matrix((weight[ok], (rows, index[ok])), shape=(n, max(nb, 1)))
    if iterations > 0 and graph is not None:
        S = graph.averaging()
        W.indices, W.indptr = W.indices.astype(S.indices.dtype), W.indptr.astype(S.indptr.dtype)
        for _ in range(int(iterations)):
            W = S @ W                          # drops the zeros pruned by the previous step
            W.data[W.data < prune] = 0.0
        W.eliminate_zeros()
    return _largest(W, max_influences)


def _smooth_dense(rows, cols, vals, n, nb, graph, iterations, max_influences, prune):
    """The diffusion of :func:`_smooth` on a dense (n, bones) float32 array: on small and
    middle-sized meshes a sparse-times-dense product per step costs 2-4x less than the sparse
    product (whose per-step bookkeeping dominates there). Weights below ``prune`` are dropped
    after the last step (not after each), the 4 largest kept as in :func:`_largest`.

    The 4 largest are picked on the transposed (bones, n) array: each pick's maximum and its
    first column are reductions along the vertices (contiguous), where ``argmax`` along a row
    of a few dozen bones costs 5-10x more on a small mesh. The weights below ``prune`` are
    smaller than any kept one, so they are dropped as they come up instead of in a pass
    of their own (the same result).
    """
    S = graph.averaging(np.float32)
    Wd = np.bincount(rows * nb + cols, weights=vals, minlength=n * nb).astype(np.float32)
    Wd = Wd.reshape(n, nb)
    for _ in range(int(iterations)):
        Wd = S @ Wd
    out_i = np.full((n, max_influences), -1, np.int64)
    out_w = np.zeros((n, max_influences))
    WT = np.ascontiguousarray(Wd.T)
    rank = np.arange(nb, 0, -1, dtype=np.int16 if nb < 2**15 else np.int64)[:, None]
    at = np.arange(n)
    floor = max(float(prune), 0.0)
    for j in range(min(max_influences, nb)):
        v = WT.max(axis=0)
        best = nb - (WT == v) * rank                 # the first of equal values: the lower column
        best = best.min(axis=0)
        keep = v >= floor if floor > 0 else v > 0
        out_i[:, j] = np.where(keep, best, -1)
        out_w[:, j] = np.where(keep, v, 0.0)         # 0 where the row has no weight left
        WT[best, at] = 0.0
    total = out_w.sum(axis=1, keepdims=True)
    out_w = np.divide(out_w, total, out=np.zeros_like(out_w), where=total > 0)
    return out_i, out_w


def _largest(W, max_influences):
    """Per row of the CSR matrix W, the ``max_influences`` largest entries (ties: the lower
    column first), normalised to sum 1: (index, weight), -1 / 0 where unused."""
    n = W.shape[0]
    W.sum_duplicates()                          # canonical: columns sorted in each row
    count = np.diff(W.indptr)
    K = int(count.max()) if n else 0
    out_i = np.full((n, max_influences), -1, np.int64)
    out_w = np.zeros((n, max_influences))
    if K:
        r = np.repeat(np.arange(n), count)
        pos = np.arange(len(r)) - W.indptr[r]
        val = np.full((n, K), -np.inf)
        val[r, pos] = W.data
        col = np.zeros((n, K), np.int64)
        col[r, pos] = W.indices
        rank = np.arange(n)
        for j in range(min(max_influences, K)):
            best = np.argmax(val, axis=1)        # the first of equal values: the lower column
            v = val[rank, best]
            has = v > -np.inf
            out_i[has, j] = col[has, best[has]]
            out_w[has, j] = v[has]
            val[rank, best] = -np.inf
    total = out_w.sum(axis=1, keepdims=True)
    out_w = np.divide(out_w, total, out=np.zeros_like(out_w), where=total > 0)
    return out_i, out_w


def project_on_bones(points, joints, bones, *, k: int = 8):
    """Closest point of every point on the bone segments (the skeleton mapping sigma by distance).

    Candidate bones of a point are those of its ``k`` nearest samples along the bones (every bone
    when there are at most ``k``); the exact closest point over the candidates comes from
    :func:`..core.geometry.segments.closest_on_bones`. Unlike the skeletonizer's own mapping this ignores the
    mesh's topology (a vertex may land on a neighbouring branch that is closer in space).

    Parameters
    ----------
    points : (n, 3) float
    joints : (J, 3) or (J, 4) float
    bones : (B, 2) int

    Returns
    -------
    bone : (n,) int
    t : (n,) float
        sigma = t * x_i + (1 - t) * x_j for bone (i, j).
    dist2 : (n,) float
        Squared distance to sigma.
    """
    Pt = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    X = np.asarray(joints, dtype=np.float64)[:, :3]
    E = np.asarray(bones, dtype=np.int64).reshape(-1, 2)
    if len(E) == 0:
        raise CurveSkelError("the skeleton has no bones")
    n = len(Pt)
    if len(E) <= k or n == 0:
        return closest_on_bones(Pt, X, E)
    A, Bp = X[E[:, 0]], X[E[:, 1]]
    Ls = np.linalg.norm(A - Bp, axis=1)
    pos = Ls[Ls > 0]
    h = float(np.median(pos)) / 4 if len(pos) else 1.0
    total = float(np.sum(np.ceil(Ls / h) + 1))
    if total > 400_000:
        h *= total / 400_000
    m = (np.ceil(Ls / h) + 1).astype(np.int64)
    sb = np.repeat(np.arange(len(E)), m)
    st = np.concatenate([np.linspace(0.0, 1.0, mm) for mm in m])
    S = Bp[sb] + st[:, None] * (A - Bp)[sb]
    _, nn = cKDTree(S).query(Pt, k=min(k, len(S)))
    cand = np.sort(sb[np.asarray(nn).reshape(n, -1)], axis=1)
    keep = np.ones(cand.shape, bool)
    keep[:, 1:] = cand[:, 1:] != cand[:, :-1]                # drop repeated bones
    indptr = np.r_[0, np.cumsum(keep.sum(axis=1))]
    return closest_on_bones(Pt, X, E, candidates=(indptr, cand[keep]))


# == weights from the armature's current bones, respecting the surface ================================
def bone_partners(heads, tails, parent, deform=None, *, tol=None):
    """Blend partners of bones as they are now (any armature, edited or not).

    A child whose head sits on its parent's tail continues the parent: when it is the parent's
    only (deforming) child the two blend symmetrically at the joint; otherwise (a junction) it
    hands over to the parent (the hub: weight 1 at the joint). Children whose
    head sits on the parent's head (under a root bone) hand over to the parent the same way.
    Non-deforming bones take no part.

    Parameters
    ----------
    heads, tails : (R, 3) float
    parent : (R,) int, -1 for none
    deform : (R,) bool, optional
    tol : float, optional
        Distance under which two bone ends coincide (default 1e-4 of the bones' extent).

    Returns
    -------
    head_mode, tail_mode : (R,) int
        BLEND_NONE, BLEND_SYMMETRIC or BLEND_HUB.
    head_partner, tail_partner : (R,) int
    attached : (R,) bool
        The bone's head sits on its (deforming) parent.
    """
    H = np.asarray(heads, dtype=np.float64).reshape(-1, 3)
    T = np.asarray(tails, dtype=np.float64).reshape(-1, 3)
    par = np.asarray(parent, dtype=np.int64).ravel()
    R = len(H)
    deform = np.ones(R, bool) if deform is None else np.asarray(deform, bool).ravel()
    if tol is None:
        HT = np.concatenate([H, T])
        ext = HT.max(axis=0) - HT.min(axis=0) if R else np.zeros(3)         # np.ptp
        tol = max(1e-4 * float(np.sqrt(ext.dot(ext))), 1e-9)                # np.linalg.norm
    head_mode = np.zeros(R, np.int64)
    tail_mode = np.zeros(R, np.int64)
    head_partner = np.full(R, -1, np.int64)
    tail_partner = np.full(R, -1, np.int64)
    n_kids = np.bincount(par[(par >= 0) & deform], minlength=R) if R else np.zeros(0, np.int64)
    pp = np.maximum(par, 0)
    live = (par >= 0) & deform & deform[pp] if R else np.zeros(0, bool)
    # np.linalg.norm(x, axis=1) is sqrt(add.reduce(x * x, axis=1)): the same, without its checks
    dT, dH = H - T[pp], H - H[pp]
    on_tail = live & (np.sqrt(np.add.reduce(dT * dT, axis=1)) <= tol)
    on_head = live & ~on_tail & (np.sqrt(np.add.reduce(dH * dH, axis=1)) <= tol)
    attached = on_tail | on_head
    head_mode[on_head], head_partner[on_head] = BLEND_HUB, par[on_head]
    # a chain joint: the parent's only (deforming) child, on its tail; other children on the
    # tail hand over to the parent (a junction)
    tail_kids = np.bincount(par[on_tail], minlength=R) if R else np.zeros(0, np.int64)
    chain = on_tail & (tail_kids[pp] == 1) & (n_kids[pp] == 1)
    hub = on_tail & ~chain
    head_mode[hub], head_partner[hub] = BLEND_HUB, par[hub]
    c = np.flatnonzero(chain)
    head_mode[c], head_partner[c] = BLEND_SYMMETRIC, par[c]
    tail_mode[par[c]], tail_partner[par[c]] = BLEND_SYMMETRIC, c
    return head_mode, tail_mode, head_partner, tail_partner, attached


def _closest_on_segments(P, A, B):
    """Parameter s in [0, 1] (0 at A) and squared distance of points P to segments A-B (row-wise)."""
    D = B - A
    L2 = np.einsum("ij,ij->i", D, D)
    s = np.einsum("ij,ij->i", P - A, D) / np.where(L2 > 0, L2, 1.0)
    s = np.minimum(np.maximum(np.where(L2 > 0, s, 0.0), 0.0), 1.0)       # np.clip
    Q = A + s[:, None] * D
    return s, np.einsum("ij,ij->i", P - Q, P - Q)


def surface_labels(V, edges, heads, tails, deform=None, *, k: int = 8):
    """The bone each vertex belongs to: the closest bone, then restricted to the surface region
    of that bone that is connected on the mesh.

    The closest deforming bone (straight-line distance to the segment) labels each vertex; for
    each bone only the largest edge-connected patch of its vertices keeps the label, and every
    other patch (an island of a neighbouring limb that is near the bone in space but not on the
    same part of the surface: the inner side of the next finger, a flank next to a thigh) takes
    the label of the nearest kept vertex along the surface (multi-source Dijkstra over the
    edges). Vertices that no kept patch reaches keep their closest bone.

    Parameters
    ----------
    V : (n, 3) float
        Vertex positions, in the bones' space.
    edges : (e, 2) int
        Mesh edges.
    heads, tails : (R, 3) float
    deform : (R,) bool, optional
        Bones that may carry vertices (default all).
    k : int
        Not used (kept for callers): every deforming bone is scored for every vertex.

    Returns
    -------
    label : (n,) int
        Bone of each vertex.
    s : (n,) float
        Position of its closest point on that bone, 0 at the head, 1 at the tail.
    dist : (n,) float
        Distance to that point.
    closest : (n,) int
        The closest bone of each vertex (before the surface restriction).
    """
    P = np.asarray(V, dtype=np.float64).reshape(-1, 3)
    H = np.asarray(heads, dtype=np.float64).reshape(-1, 3)
    T = np.asarray(tails, dtype=np.float64).reshape(-1, 3)
    deform = np.ones(len(H), bool) if deform is None else np.asarray(deform, bool).ravel()
    return _labels(P, _Graph(np.asarray(edges, dtype=np.int64).reshape(-1, 2), len(P)), H, T, deform)


# == one bind's shared work: the edge graph built once, the closest bone without a KD-tree =========
class _Graph:
    """The mesh's edge graph, built once per bind: CSR arrays of the closed 1-ring (each vertex
    and its neighbours, columns sorted, duplicate edges once) and the undirected edges."""

    __slots__ = ("n", "edges", "indptr", "indices", "rows", "diag", "deg")

    def __init__(self, E, n):
        E = np.asarray(E, dtype=np.int64).reshape(-1, 2)
        loops = E[:, 0] == E[:, 1]
        if loops.any():                  # a mesh's edges have none: no copy then
            E = E[~loops]
        # each (row, column) pair as the key row * n + column, sorted, duplicates once: the CSR
        # arrays with columns sorted in each row, as scipy's COO -> CSR conversion and
        # sort_indices give them, for half the cost of building that matrix
        key = np.concatenate([E[:, 0] * n + E[:, 1], E[:, 1] * n + E[:, 0],
                              np.arange(n, dtype=np.int64) * (n + 1)])
        key.sort()
        if len(key):
            key = key[np.concatenate(([True], key[1:] != key[:-1]))]
        self.n = n
        self.edges = E
        self.rows = key // max(n, 1)
        self.indices = key - self.rows * n
        counts = np.bincount(self.rows, minlength=n)
        self.indptr = np.zeros(n + 1, np.int64)
        np.cumsum(counts, out=self.indptr[1:])
        self.diag = self.indices == self.rows
        self.deg = counts - 1

    def nearest(self, P, kept):
        """For each vertex, the kept vertex nearest along the edges (edge length at least
        1e-12; -1 where none is reached).

        Only the vertices not kept and their kept neighbours take part: the shortest path from
        a vertex to the nearest kept one runs through vertices not kept until its last step.
        """
        out = np.where(kept, np.arange(self.n), -1)
        free = ~kept
        part = np.zeros(self.n, bool)
        part[self.indices[free[self.rows]]] = True            # the free vertices and their neighbours
        sub = np.flatnonzero(part)
        loc = np.full(self.n, -1, np.int64)
        loc[sub] = np.arange(len(sub))
        e = part[self.rows] & part[self.indices] & ~self.diag
        r, c = self.rows[e], self.indices[e]
        w = np.maximum(np.sqrt(np.einsum("ij,ij->i", P[r] - P[c], P[r] - P[c])), 1e-12)
        indptr = np.zeros(len(sub) + 1, np.int64)
        np.cumsum(np.bincount(loc[r], minlength=len(sub)), out=indptr[1:])
        G = _csr(w, loc[c], indptr, len(sub))
        src = np.flatnonzero(kept[sub])
        # the graph is symmetric: directed=True walks the same edges without a transposed copy
        dist, _, sources = dijkstra(G, directed=True, indices=src, min_only=True,
                                    return_predecessors=True)
        ok = free[sub] & np.isfinite(dist) & (sources >= 0)
        out[sub[ok]] = sub[sources[ok]]
        return out

    def averaging(self, dtype=np.float64):
        """S = D^-1 (A + I): each vertex's average over its closed 1-ring. Columns are stored in
        decreasing order in each row, as scipy's product D^-1 @ (A + I) leaves them: the sums
        of a step then add up in the same order (ties between bones break the same way).
        ``dtype`` of the entries (float32: the float64 ones rounded)."""
        data = np.repeat((1.0 / (self.deg + 1.0)).astype(dtype, copy=False), self.deg + 1)
        rev = self.indptr[self.rows] + self.indptr[self.rows + 1] - 1 - np.arange(len(self.rows))
        return _csr(data, self.indices[rev], self.indptr, self.n)

    def components(self, keep):
        """Connected components (labels) of the graph restricted to the stored pairs ``keep``."""
        keep = keep | self.diag
        indptr = np.zeros(self.n + 1, np.int64)
        np.cumsum(np.bincount(self.rows[keep], minlength=self.n), out=indptr[1:])
        G = _csr(np.ones(int(indptr[-1])), self.indices[keep], indptr, self.n)
        return connected_components(G, directed=True, connection="strong")[1]


def _csr(data, indices, indptr, n):
    """The (n, n) CSR matrix of these arrays, its index arrays in int32 where they fit: the type
    scipy would choose itself, after scanning int64 arrays to find that they fit (which costs
    more than the conversion on small meshes)."""
    idx = np.int32 if max(len(indices), n) < 2**31 - 1 else np.int64
    return sp.csr_matrix((data, indices.astype(idx, copy=False), indptr.astype(idx, copy=False)),
                         shape=(n, n))


def _closest_bones(P, H, T, ids):
    """Closest of the segments H[ids]-T[ids] for each point (a position in ``ids``); the same
    choice as :func:`project_on_bones` (the first of equally close bones), without its KD-tree:
    :func:`..core.geometry.segments.closest_on_bones` with every segment a candidate (scored in float32, near-ties
    compared exactly)."""
    n, B = len(P), len(ids)
    if n == 0 or B == 1:
        return np.zeros(n, np.int64)
    X = np.concatenate([H[ids], T[ids]])              # sigma = t * head + (1 - t) * tail
    segs = np.arange(2 * B).reshape(2, B).T                       # bone k: (k, B + k)
    return closest_bone(P, X, segs)


def _kept_patches(label, comp, R):
    """Vertices in the patch their bone keeps: each bone's largest connected patch (``comp``:
    the patch of each vertex, one bone per patch); of equally large ones, that of the bone's
    lowest vertex (the first in a stable sort by bone, then by decreasing size)."""
    n = len(label)
    size = np.bincount(comp)
    sz = size[comp]
    top = np.zeros(R, np.int64)
    np.maximum.at(top, label, sz)
    cand = np.flatnonzero(sz == top[label])
    first = np.full(R, n, np.int64)
    np.minimum.at(first, label[cand], cand)
    keep = np.zeros(len(size), bool)
    keep[comp[first[first < n]]] = True
    return keep[comp]


def _labels(P, graph, H, T, deform):
    """surface_labels on a built graph: (label, s, dist, closest)."""
    ids = np.flatnonzero(deform)
    if len(ids) == 0:
        raise CurveSkelError("the armature has no deforming bones")
    n = len(P)
    label = closest = ids[_closest_bones(P, H, T, ids)]
    if n and len(graph.edges):
        same = label[graph.rows] == label[graph.indices]
        kept = _kept_patches(label, graph.components(same), len(H))
        if not kept.all():
            near = graph.nearest(P, kept)
            move = (~kept) & (near >= 0)
            label = label.copy()
            label[move] = label[near[move]]
    s, d2 = _closest_on_segments(P, H[label], T[label])
    return label, s, np.sqrt(d2), closest


def bone_weights(V, F, heads, tails, parent, deform=None, *, blend: float = 0.25,
                 smooth: float = 0.5, junction_blend: float = 0.0, max_influences: int = MAX_INFLUENCES,
                 edges=None):
    """Skin weights for the bones as they are now, respecting the surface.

    1. :func:`surface_labels`: each vertex belongs to one bone (closest bone, restricted to the
       bone's connected patch of the surface).
    2. Near the ends of its bone a vertex blends with the bone's partner there
       (:func:`bone_partners`): 50/50 at a chain joint with a smoothstep over ``blend`` of the
       bone's length (as :func:`skin_weights`). Where a chain leaves a junction (or the root)
       the hand-over into the hub is one-sided over ``junction_blend`` of the child's length;
       0 (the default) keeps chain boundaries rigid, so posing a chain never moves a vertex
       that belongs to another chain.
    3. The weights are diffused along the surface over ``smooth`` times the median
       vertex-to-bone distance (:func:`smooth_weights`, at most ``SMOOTH_CAP`` steps), then each vertex keeps
       only its main bone and either that bone's parent or its children (the heavier side), and
       only across joints that blend: weights never spread to a sibling limb, across a gap, or
       over a rigid chain boundary.

    Parameters
    ----------
    V : (n, 3) float
        Vertices in the bones' space.
    F : (m, 3) int or None
        Triangles (only their edges are used).
    heads, tails : (R, 3) float
    parent : (R,) int
    deform : (R,) bool, optional
    blend : float in [0, 0.5]
    smooth : float >= 0
    junction_blend : float in [0, 0.5]
    max_influences : int
    edges : (e, 2) int, optional
        The mesh's edges, used instead of the triangles' (any polygons).

    Returns
    -------
    index : (n, max_influences) int
        Bone of each influence, -1 where unused.
    weight : (n, max_influences) float
        Sorted decreasing per row, summing to 1.
    info : dict
        ``relabelled`` (vertices moved to another bone by the surface restriction),
        ``smooth_iterations``.
    """
    if not 0.0 <= blend <= 0.5:
        raise CurveSkelError(f"blend must be in [0, 0.5] of a bone's length, got {blend}")
    if not 0.0 <= junction_blend <= 0.5:
        raise CurveSkelError(f"junction_blend must be in [0, 0.5] of a bone's length, got {junction_blend}")
    if not smooth >= 0:
        raise CurveSkelError(f"smooth must be >= 0, got {smooth}")
    P = np.asarray(V, dtype=np.float64).reshape(-1, 3)
    Fa = np.zeros((0, 3), np.int64) if F is None else np.asarray(F, dtype=np.int64).reshape(-1, 3)
    n = len(P)
    H = np.asarray(heads, dtype=np.float64).reshape(-1, 3)
    T = np.asarray(tails, dtype=np.float64).reshape(-1, 3)
    par = np.asarray(parent, dtype=np.int64).ravel()
    R = len(H)
    if T.shape != H.shape or len(par) != R:
        raise CurveSkelError(f"heads {H.shape}, tails {T.shape} and parent {par.shape} must match")
    if len(Fa) and (Fa.min() < 0 or Fa.max() >= n):
        raise CurveSkelError("face vertex index out of range")
    deform = np.ones(R, bool) if deform is None else np.asarray(deform, bool).ravel()
    if edges is not None:
        E = np.asarray(edges, dtype=np.int64).reshape(-1, 2)
        if len(E) and (E.min() < 0 or E.max() >= n):
            raise CurveSkelError("edge vertex index out of range")
    else:
        E = np.concatenate([Fa[:, [0, 1]], Fa[:, [1, 2]], Fa[:, [2, 0]]]) if len(Fa) else np.zeros((0, 2), np.int64)
        E = np.sort(E, axis=1)
        key = np.unique(E[:, 0] * max(n, 1) + E[:, 1])             # 1-D unique: 10x faster
        E = np.stack([key // max(n, 1), key % max(n, 1)], 1)
    graph = _Graph(E, n)
    label, s, dist, closest = _labels(P, graph, H, T, deform)
    hm, tm, hp, tp, attached = bone_partners(H, T, par, deform)
    near_head = s < 0.5
    u = np.where(near_head, s, 1.0 - s)
    mode = np.where(near_head, hm[label], tm[label])
    partner = np.where(near_head, hp[label], tp[label])
    f = smoothstep(u / blend) if blend > 0 else np.ones(n)
    fj = smoothstep(u / junction_blend) if junction_blend > 0 else np.ones(n)
    share = np.where(mode == BLEND_SYMMETRIC, 0.5 * (1.0 - f), np.where(mode == BLEND_HUB, 1.0 - fj, 0.0))
    share = np.where(partner >= 0, share, 0.0)
    index = np.full((n, 2), -1, np.int64)
    weight = np.zeros((n, 2))
    index[:, 0], weight[:, 0] = label, 1.0 - share
    has = share > 0
    index[has, 1], weight[has, 1] = partner[has], share[has]
    k = 0
    if smooth > 0 and len(E) and n:
        dE = P[E[:, 0]] - P[E[:, 1]]
        h = float(np.sqrt(np.einsum("ij,ij->i", dE, dE)).sum()) / len(E)    # mean edge length
        k = smoothing_iterations(smooth * _median(dist), h, cap=SMOOTH_CAP)
    index, weight = _smooth(index, weight, graph, k, max_influences, 1e-4)
    # keep the main bone's family only: itself and, across a joint that blends (a chain joint;
    # any attached parent when junctions blend too), its parent or one child
    blends = (hm == BLEND_SYMMETRIC) | ((hm == BLEND_HUB) & (junction_blend > 0))
    index, weight = _keep_family(index, weight, np.where(blends, par, -2))
    return index, weight, {"relabelled": int(np.sum(label != closest)), "smooth_iterations": int(k)}


def _median(x) -> float:
    """``np.median`` of a 1-D float array without NaN (the mean of the two middle values when
    the length is even, as numpy computes it), without its generic machinery."""
    m = len(x) // 2
    if len(x) % 2:
        return float(np.partition(x, m)[m])
    part = np.partition(x, (m - 1, m))
    return float((part[m - 1] + part[m]) / 2)


def _keep_family(index, weight, blend_parent):
    """Per vertex, the main bone (column 0) and at most one neighbour across a blending joint.

    ``index``/``weight`` (n, m): distinct bones per row, weights decreasing along the row
    (as :func:`_smooth` returns them); ``blend_parent`` (R,): the parent each bone blends
    with at its head, else -2. The neighbour is the main bone's blend parent or its heaviest
    blending child (the first such column: weights decrease), whichever weighs more (the parent
    on a tie): the parent and a child of the main bone are not neighbours, and siblings never
    share a vertex. The two are renormalised and sorted by decreasing weight (the main bone
    first on a tie); other columns -1 / 0. Equal, bit for bit, to masking the whole (n, m)
    array once per condition and sorting each row (tests/core/test_skin_weights.py keeps that
    version as the reference), in about half the array passes: on a small mesh each pass costs
    more than its arithmetic.
    """
    n, m = index.shape
    out_i = np.full((n, m), -1, np.int64)
    out_w = np.zeros((n, m))
    main = index[:, 0]
    live = main >= 0
    if m < 2:
        out_i[live, 0], out_w[live, 0] = main[live], 1.0
        return out_i, out_w
    bp = np.concatenate((blend_parent, [-2]))            # bp[-1]: an unused column has none
    mp = np.where(live, bp[main], -2)
    # column by column (m - 1 = 3 at most in a bind): the per-row max / argmax over 3
    # columns cost more than the arithmetic on a small mesh. up: the main bone's blend parent
    # (at most one per row); down: the first child blending with it (weights decrease, so the
    # heaviest); -1 for none
    w_up = np.zeros(n)
    i_up = np.full(n, -1, np.int64)
    w_down = np.zeros(n)
    i_down = np.full(n, -1, np.int64)
    for c in range(m - 1, 0, -1):                        # the first match wins: last column first
        col, w = index[:, c], weight[:, c]
        ok = col >= 0
        up = ok & (col == mp)
        down = ok & (bp[col] == main) & live
        w_up = np.where(up, w, w_up)
        i_up = np.where(up, col, i_up)
        w_down = np.where(down, w, w_down)
        i_down = np.where(down, col, i_down)
    take_up = w_up >= w_down                              # w_up 0 (no parent): the child, if any
    other = np.where(take_up, i_up, i_down)
    w_other = np.where(take_up, w_up, w_down)
    other = np.where(w_other > 0, other, -1)
    w_main = np.where(live, weight[:, 0], 0.0)
    total = w_main + w_other
    ok = total > 0
    w_main = np.divide(w_main, total, out=np.zeros(n), where=ok)
    w_other = np.divide(w_other, total, out=np.zeros(n), where=ok)
    swap = w_other > w_main
    out_i[:, 0] = np.where(swap, other, np.where(w_main > 0, main, -1))
    out_w[:, 0] = np.where(swap, w_other, w_main)
    out_i[:, 1] = np.where(swap, main, other)
    out_w[:, 1] = np.where(swap, w_main, w_other)
    out_i[:, 1] = np.where(out_w[:, 1] > 0, out_i[:, 1], -1)
    return out_i, out_w
