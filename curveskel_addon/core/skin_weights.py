"""Skin weights from the skeleton mapping sigma (pure, vectorised).

Each vertex weighs its own bone; within ``blend`` (a fraction of the bone's length) of a joint it
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
from scipy.spatial import cKDTree

from .errors import CurveSkelError
from .mapping import closest_on_bones
from .rig_layout import BLEND_HUB, BLEND_SYMMETRIC, RigLayout

__all__ = ["skin_weights", "smooth_weights", "smoothing_iterations", "smoothstep", "project_on_bones",
           "MAX_INFLUENCES"]

MAX_INFLUENCES = 4


def smoothstep(x):
    """3x^2 - 2x^3 on [0, 1] (clamped): 0 -> 0, 1 -> 1, zero slope at both ends."""
    x = np.clip(x, 0.0, 1.0)
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
    >>> from curveskel_addon.core.rig_layout import rig_layout
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
        Weights below this are dropped during the steps (keeps the matrices sparse).

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
    nb = int(index.max()) + 1 if index.size else 0
    ok = index >= 0
    rows = np.broadcast_to(np.arange(n)[:, None], index.shape)
    W = sp.csr_matrix((weight[ok], (rows[ok], index[ok])), shape=(n, max(nb, 1)))
    if iterations > 0 and len(E):
        E = E[E[:, 0] != E[:, 1]]
        A = sp.coo_matrix((np.ones(2 * len(E)), (np.r_[E[:, 0], E[:, 1]], np.r_[E[:, 1], E[:, 0]])),
                          shape=(n, n)).tocsr()
        A.data[:] = 1.0                                     # duplicate edges count once
        deg = np.asarray(A.sum(axis=1)).ravel()
        S = (sp.diags(1.0 / (deg + 1.0)) @ (A + sp.identity(n, format="csr"))).tocsr()
        for _ in range(int(iterations)):
            W = S @ W
            W.data[W.data < prune] = 0.0
            W.eliminate_zeros()
    W = W.tocsr()
    W.sort_indices()
    r = np.repeat(np.arange(n), np.diff(W.indptr))
    order = np.lexsort((-W.data, r))                        # per row, largest first
    rank = np.arange(len(order)) - W.indptr[r[order]]
    sel = rank < max_influences
    keep, rk = order[sel], rank[sel]
    out_i = np.full((n, max_influences), -1, np.int64)
    out_w = np.zeros((n, max_influences))
    out_i[r[keep], rk] = W.indices[keep]
    out_w[r[keep], rk] = W.data[keep]
    total = out_w.sum(axis=1, keepdims=True)
    out_w = np.divide(out_w, total, out=np.zeros_like(out_w), where=total > 0)
    return out_i, out_w


def project_on_bones(points, joints, bones, *, k: int = 8):
    """Closest point of every point on the bone segments (the skeleton mapping sigma by distance).

    Candidate bones of a point are those of its ``k`` nearest samples along the bones (every bone
    when there are at most ``k``); the exact closest point over the candidates comes from
    :func:`mapping.closest_on_bones`. Unlike the skeletonizer's own mapping this ignores the
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
