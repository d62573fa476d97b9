"""What each candidate merge would change in J, all candidates at once.

Removing chain joint ``k`` (neighbours ``a``, ``b``) changes J only near it, the other joints
held: the samples on its two bones move onto the new bone ``(a, b)`` (fit), the chain terms
at ``a``, ``k`` and ``b`` change (centre: ``a`` and ``b`` get new tangents; smooth), the
containment of the new bone replaces that of the two old ones, and one joint's price is saved.
These estimates rank the candidates; the search then applies the best ones and keeps them only
if the exact J, after the joints are fitted again, has fallen.
"""

from __future__ import annotations

import numpy as np

from ..geometry.rows import row_norm
from ..geometry.segments import nearest_on_silhouette
from ..objective.terms import bone_centres, bone_contain, chain_neighbours, fit_values, smooth_triplets

__all__ = ["merge_gains", "prune_gains"]


def _seg_t(P, A, B):
    d = A - B
    dd = np.einsum("ij,ij->i", d, d)
    t = np.einsum("ij,ij->i", P - B, d) / np.maximum(dd, 1e-300)
    return np.clip(t, 0.0, 1.0)


def _smooth(Z, k, a, b, D):
    """Smooth values of chain joints ``k`` with neighbours ``a``, ``b`` (rows may repeat a
    joint with different neighbours), as J's term computes them."""
    return smooth_triplets(Z, k, a, b, D, jacobian=None)


def _contain(objective, A, B):
    """Containment value of the bones ``A -> B`` (rows), as
    :func:`..objective.terms.contain_term` computes it."""
    s = objective.samples
    return bone_contain(A, B, np.zeros((len(A), 2), np.int64), objective.mesh.inside,
                        objective.tree, s.points, s.normal, objective.D,
                        objective.margin(len(A)), 0, jacobian=None)


def merge_gains(objective, graph, evaluation):
    """Estimated change of J for removing each chain joint.

    Returns
    -------
    k, a, b : (c,) int
        The chain joints and their neighbours.
    delta : (c,) float
        Estimated J after minus J before (negative: the merge pays).
    """
    Z = np.asarray(graph.joints)
    X = Z[:, :3]
    D, w = objective.D, objective.weights
    J = len(Z)
    k, a, b = chain_neighbours(graph.bones, J)
    if not len(k):
        return k, a, b, np.zeros(0)
    bones = graph.bones
    # the two bones of each chain joint
    ends = np.concatenate([bones[:, 0], bones[:, 1]])
    order = np.argsort(ends, kind="stable")
    bid = np.concatenate([np.arange(len(bones))] * 2)[order]
    start = np.concatenate([[0], np.cumsum(np.bincount(ends, minlength=J))])
    b1, b2 = bid[start[k]], bid[start[k] + 1]
    # fit: the samples of b1 and b2 onto the new bone (a, b)
    bone, t = evaluation.bone, evaluation.t
    nb = len(bones)
    cnt = np.bincount(bone, minlength=nb)
    sorder = np.argsort(bone, kind="stable")
    sstart = np.concatenate([[0], np.cumsum(cnt)])

    def gather(bl):
        c = cnt[bl]
        loc = np.arange(c.sum()) - np.repeat(np.cumsum(c) - c, c)
        return sorder[np.repeat(sstart[bl], c) + loc], np.repeat(np.arange(len(bl)), c)

    s1, c1 = gather(b1)
    s2, c2 = gather(b2)
    s, cand = np.concatenate([s1, s2]), np.concatenate([c1, c2])
    P = objective.samples.points[s]
    ws, sc = objective.samples.weights[s], objective.scale[s]
    ij = bones[bone[s]]
    ts = t[s]
    S = ts[:, None] * Z[ij[:, 0]] + (1 - ts)[:, None] * Z[ij[:, 1]]
    ca, cb = a[cand], b[cand]
    tn = _seg_t(P, X[ca], X[cb])
    Sn = tn[:, None] * Z[ca] + (1 - tn)[:, None] * Z[cb]
    d_fit = np.bincount(cand, fit_values(P, ws, Sn, objective.area, sc)
                        - fit_values(P, ws, S, objective.area, sc), len(k))
    # chain terms at a, k, b before and after
    is_chain = np.zeros(J, bool)
    is_chain[k] = True
    nbr = {int(kk): (int(aa), int(bb)) for kk, aa, bb in zip(k, a, b)}
    rows_k, rows_a, rows_b, owner, sign = [], [], [], [], []
    for c, (kk, aa, bb) in enumerate(zip(k, a, b)):
        rows_k.append(kk); rows_a.append(aa); rows_b.append(bb); owner.append(c); sign.append(-1.0)
        for v, old, new in ((aa, kk, bb), (bb, kk, aa)):
            if is_chain[v]:
                p, q = nbr[int(v)]
                far = q if p == old else p
                rows_k += [v, v]; rows_a += [p, far]; rows_b += [q, new]
                owner += [c, c]; sign += [-1.0, 1.0]
    rows_k, rows_a, rows_b = map(np.asarray, (rows_k, rows_a, rows_b))
    owner, sign = np.asarray(owner), np.asarray(sign)
    smooth = _smooth(Z, rows_k, rows_a, rows_b, D)
    d_smooth = np.bincount(owner, sign * smooth, len(k))
    d_centre = np.zeros(len(k))
    # the new bone (a, b) replaces b1 and b2; its thickness the mean of theirs
    thick = objective.thickness(graph)
    if w.centre:
        old = bone_centres(X[bones[:, 0]], X[bones[:, 1]], bones, objective.section_mesh, D, thick,
                           J, jacobian=None)
        new = bone_centres(X[a], X[b], np.stack([a, b], 1), objective.section_mesh, D,
                           0.5 * (thick[b1] + thick[b2]), J, jacobian=None)
        d_centre = new - old[b1] - old[b2]
    old_con = _contain(objective, X[bones[:, 0]], X[bones[:, 1]])
    d_contain = (_contain(objective, X[a], X[b])
                 - old_con[b1] - old_con[b2])
    delta = (d_fit + w.centre * d_centre + w.smooth * d_smooth + w.contain * d_contain
             - w.joint)
    return k, a, b, delta


def prune_gains(objective, graph, evaluation, chains):
    """Estimated change of J for removing each leaf chain of ``chains`` (as
    :func:`.topology.leaf_chains` gives them), the other joints held: the chain's samples move
    to the closest of the junction's other bones, the chain's centre, smooth and containment
    terms go, the junction's smooth term appears if it is left with two bones, and the chain's
    joints and its tip are no longer priced."""
    Z = np.asarray(graph.joints)
    X = Z[:, :3]
    D, w = objective.D, objective.weights
    bones = graph.bones
    B = len(bones)
    out = np.full(len(chains), np.inf)
    thick = objective.thickness(graph)
    cen = (bone_centres(X[bones[:, 0]], X[bones[:, 1]], bones, objective.section_mesh, D, thick,
                        len(Z), jacobian=None) if w.centre else np.zeros(B))
    con = _contain(objective, X[bones[:, 0]], X[bones[:, 1]])
    k_all, a_all, b_all = chain_neighbours(bones, len(Z))
    sm_all = smooth_triplets(Z, k_all, a_all, b_all, D, jacobian=None)
    sm_of = np.zeros(len(Z))
    sm_of[k_all] = sm_all
    bone, t = evaluation.bone, evaluation.t
    deg = graph.degree
    for c, (js, bs, v) in enumerate(chains):
        if v < 0:
            continue
        bs = np.asarray(bs)
        s = np.flatnonzero(np.isin(bone, bs))
        other = np.flatnonzero(((bones == v).any(1)) & ~np.isin(np.arange(B), bs))
        if not len(other) or len(bs) == B:
            continue
        P = objective.samples.points[s]
        ws, sc = objective.samples.weights[s], objective.scale[s]
        ij = bones[bone[s]]
        S = t[s, None] * Z[ij[:, 0]] + (1 - t[s, None]) * Z[ij[:, 1]]
        rest = np.setdiff1d(np.arange(B), bs)
        nb, tn, _ = nearest_on_silhouette(P, Z, bones[rest])
        bi, bj = bones[rest[nb], 0], bones[rest[nb], 1]
        Sn = tn[:, None] * Z[bi] + (1 - tn)[:, None] * Z[bj]
        d_fit = float((fit_values(P, ws, Sn, objective.area, sc)
                       - fit_values(P, ws, S, objective.area, sc)).sum())
        d_cen = -float(cen[bs].sum())
        d_sm = -float(sm_of[np.asarray(js)].sum())
        if deg[v] == 3:                       # the junction becomes a chain joint
            p, q = [int(bones[ob, 0] if bones[ob, 1] == v else bones[ob, 1]) for ob in other]
            d_sm += float(smooth_triplets(Z, np.array([v]), np.array([p]), np.array([q]), D,
                                          jacobian=None)[0])
        d_con = -float(con[bs].sum())
        out[c] = (d_fit + w.centre * d_cen + w.smooth * d_sm + w.contain * d_con
                  - w.joint * len(js) - w.branch)
    return out
