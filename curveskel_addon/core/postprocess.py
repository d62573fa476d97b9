"""Skeleton quality beyond the paper: pruning noise branches and merging straight-chain joints.

Both operations change the *topology* of the skeleton (joint and bone counts), which the paper's
optimisation cannot do (section 5: "branches ... should be considered as noise which can't be
compensated by the minimization of (20)"; "smoothness ... is provided neither by Reeb graphs nor
by the optimization process"). Each is judged by the same energy E (eq. 20, weighted by
``FitProblem.weights``), so the decision is the paper's criterion applied to a discrete choice.

Pipeline order (:func:`postprocess`)::

    solved problem -> prune_branches -> solve -> simplify_chains -> solve

Definitions used below (all vectorised over vertices):

* residual of vertex v: ``e_v = |v - sigma_v|^2 - r(sigma_v)^2`` and ``E = sum_v w_v e_v^2``.
* leaf branch: the chain of bones from a joint of degree 1 through joints of degree 2 up to the
  first joint of degree >= 3 (its *root*, which is kept). A chain ending in another leaf is a whole
  component and is never a branch.
* the branch's vertices S: the vertices whose sigma lies on one of its bones.
"""

from __future__ import annotations

from typing import Callable

import numpy as np

from .problem import FitProblem

__all__ = ["postprocess", "prune_branches", "simplify_chains", "unfold_chains", "fold_joints",
           "leaf_branches", "branch_scores"]

Solve = Callable[[FitProblem], FitProblem]


# -- small vectorised helpers ------------------------------------------------------------------
def _residuals(points, joints, bones, bone, t) -> np.ndarray:
    """(n,) ``e_v = |v - sigma_v|^2 - r_v^2`` (the term of eq. 20 before squaring)."""
    i, j = bones[bone, 0], bones[bone, 1]
    tt = t[:, None]
    s = tt * joints[i, :3] + (1.0 - tt) * joints[j, :3]
    r = t * joints[i, 3] + (1.0 - t) * joints[j, 3]
    return np.einsum("ij,ij->i", points - s, points - s) - r * r


def _energy(pr: FitProblem) -> float:
    e = _residuals(pr.points, pr.joints, pr.bones, pr.bone, pr.t)
    return float(np.dot(pr.weights, e * e))


def _radius_at(pr: FitProblem) -> np.ndarray:
    """(n,) radius at sigma_v."""
    i, j = pr.bones[pr.bone, 0], pr.bones[pr.bone, 1]
    return pr.t * pr.joints[i, 3] + (1.0 - pr.t) * pr.joints[j, 3]


def _project(P, Xi, Xj):
    """Closest point parameters on segments: t with sigma = t*Xi + (1-t)*Xj, clamped to [0, 1].

    P, Xi, Xj : (..., 3) broadcastable. Returns (t, squared distance).
    """
    d = Xi - Xj
    dd = np.einsum("...k,...k->...", d, d)
    t = np.einsum("...k,...k->...", P - Xj, d) / np.where(dd > 0, dd, 1.0)
    t = np.clip(np.where(dd > 0, t, 0.5), 0.0, 1.0)
    q = P - (t[..., None] * Xi + (1.0 - t[..., None]) * Xj)
    return t, np.einsum("...k,...k->...", q, q)


def _closest_on_bones(points, joints, bones, cand):
    """Map ``points`` (m, 3) to the nearest of the candidate bones ``cand`` (k,) (Euclidean
    distance to the segment, :func:`.mapping.closest_on_bones`). Returns (bone (m,), t (m,))."""
    from .mapping import closest_on_bones

    cand = np.asarray(cand, np.int64)
    m = len(points)
    indptr = np.arange(m + 1, dtype=np.int64) * len(cand)
    bone, t, _ = closest_on_bones(points, joints, bones, (indptr, np.tile(cand, m)))
    return bone, t


def _degree(n_joints, bones) -> np.ndarray:
    return np.bincount(bones.ravel(), minlength=n_joints)


def _incidence(n_joints, bones) -> list[list[int]]:
    inc: list[list[int]] = [[] for _ in range(n_joints)]
    for b, (i, j) in enumerate(bones.tolist()):
        inc[i].append(b)
        inc[j].append(b)
    return inc


def _compact(pr: FitProblem, keep_bone: np.ndarray) -> FitProblem:
    """Drop bones not in ``keep_bone`` (bool (B,)) and joints no kept bone uses; re-index.

    Every vertex must already be mapped to a kept bone.
    """
    bones = pr.bones[keep_bone]
    used = np.zeros(len(pr.joints), bool)
    used[bones.ravel()] = True
    jmap = np.cumsum(used) - 1
    bmap = np.cumsum(keep_bone) - 1
    assert keep_bone[pr.bone].all(), "a vertex is mapped to a removed bone"
    return FitProblem(pr.points, pr.weights, pr.joints[used].copy(), jmap[bones], bmap[pr.bone],
                      pr.t.copy(), dict(pr.meta))


# -- pruning -----------------------------------------------------------------------------------
def leaf_branches(n_joints: int, bones: np.ndarray) -> list[tuple[int, list[int], list[int]]]:
    """Leaf branches of a skeleton graph.

    Returns
    -------
    list of (root, joints, bones)
        ``root`` the first joint of degree >= 3 reached from a leaf (kept when pruning);
        ``joints`` the branch's own joints (leaf first, root excluded); ``bones`` its bones.
    """
    deg = _degree(n_joints, bones)
    inc = _incidence(n_joints, bones)
    out = []
    for leaf in np.flatnonzero(deg == 1).tolist():
        cur, prev_b, js, bs = leaf, -1, [], []
        while True:
            nxt_b = [b for b in inc[cur] if b != prev_b]
            if deg[cur] == 1 and prev_b >= 0:      # reached another leaf: a whole chain
                bs = None
                break
            if deg[cur] >= 3:
                break
            js.append(cur)
            b = nxt_b[0]
            bs.append(b)
            i, j = bones[b]
            cur = j if i == cur else i
            prev_b = b
            if len(bs) > len(bones):                # safety; cannot happen on a simple graph
                bs = None
                break
        if bs:
            out.append((cur, js, bs))
    return out


def branch_scores(pr: FitProblem, branches=None, hops: int = 2):
    """Score each leaf branch: what removing it would cost, relative to what it explains.

    For a branch with vertices S, let e_v be their current residuals and e'_v, r'_v, d'_v the
    residual, radius and distance to sigma'_v after mapping them to the nearest remaining bone
    within ``hops`` bones of the root (nothing else moves). Then

    * cost (increase of E):   ``dE = sum_S w_v (e'_v^2 - e_v^2)``
    * what the branch explains: ``X = sum_S w_v max(d'_v^2, r'_v^2)^2``, the energy its vertices
      would have if the remaining skeleton explained nothing of them (the largest of the two
      terms of e'_v); since ``|e'_v| <= max(d'^2, r'^2)``, ``dE <= X``.
    * score ``s = dE / X`` in [0, 1] (below 0 when removal even lowers E): the fraction of the
      branch's geometry that the rest of the skeleton cannot account for. For a bump of height h
      on a tube of radius r, ``s ~ (2h/r)^2``; for a real limb of length L >> r, ``s`` approaches 1.

    Returns
    -------
    branches : list of (root, joints, bones)
    scores : (k,) float
    mappings : list of (vertex ids, new bone, new t) for each branch
    """
    if branches is None:
        branches = leaf_branches(len(pr.joints), pr.bones)
    order = np.argsort(pr.bone, kind="stable")
    starts = np.searchsorted(pr.bone[order], np.arange(len(pr.bones) + 1))
    e_now = _residuals(pr.points, pr.joints, pr.bones, pr.bone, pr.t)
    scores, maps = np.empty(len(branches)), []
    for k, (root, _js, bs) in enumerate(branches):
        vids = np.concatenate([order[starts[b]:starts[b + 1]] for b in bs]) if bs else np.zeros(0, int)
        cand = _near_bones(pr.bones, root, set(bs), hops)
        if len(vids) == 0:
            scores[k] = -np.inf
            maps.append((vids, vids, np.zeros(0)))
            continue
        if len(cand) == 0:
            scores[k] = np.inf
            maps.append((vids, vids, np.zeros(0)))
            continue
        P = pr.points[vids]
        nb, nt = _closest_on_bones(P, pr.joints, pr.bones, cand)
        e_new = _residuals(P, pr.joints, pr.bones, nb, nt)
        w = pr.weights[vids]
        i, j = pr.bones[nb, 0], pr.bones[nb, 1]
        r_new = nt * pr.joints[i, 3] + (1 - nt) * pr.joints[j, 3]
        d2 = e_new + r_new ** 2
        dE = float(np.dot(w, e_new ** 2 - e_now[vids] ** 2))
        X = float(np.dot(w, np.maximum(d2, r_new ** 2) ** 2))
        scores[k] = dE / X if X > 0 else 0.0
        maps.append((vids, nb, nt))
    return branches, scores, maps


def _near_bones(bones: np.ndarray, root: int, removed: set, hops: int) -> np.ndarray:
    """Bones not in ``removed`` with an endpoint within ``hops - 1`` joints of ``root``."""
    keep = np.ones(len(bones), bool)
    keep[list(removed)] = False
    kb = np.flatnonzero(keep)
    near = {root}
    for _ in range(max(hops - 1, 0)):
        sel = np.isin(bones[kb], list(near)).any(axis=1)
        near |= set(bones[kb[sel]].ravel().tolist())
    sel = np.isin(bones[kb], list(near)).any(axis=1)
    return kb[sel]


def prune_branches(pr: FitProblem, threshold: float, *, max_rounds: int = 50) -> tuple[FitProblem, list]:
    """Remove leaf branches whose :func:`branch_scores` score is below ``threshold``.

    Greedy in rounds: each round scores every leaf branch and removes, lowest score first, the
    branches below ``threshold`` whose roots differ (so the scores stay valid within a round: a
    removal only changes its own root's degree). Vertices of a removed branch are mapped to the
    nearest remaining bone near its root; its joints and bones are dropped and the rest re-indexed.
    A root left with degree 2 joins two chains, which the next round may score as one branch.

    Parameters
    ----------
    pr : FitProblem
        Usually an optimised one; not modified.
    threshold : float in [0, 1]
        0 prunes nothing; 1 prunes every branch whose removal costs less than everything it
        explains (nearly all of them). See :func:`branch_scores`.

    Returns
    -------
    FitProblem, list of dict
        The pruned problem (not re-optimised) and one record per removed branch
        (root, joints, bones, vertices, score).
    """
    pr = pr.copy()
    removed_log = []
    if threshold <= 0:
        return pr, removed_log
    for _ in range(max_rounds):
        branches, scores, maps = branch_scores(pr)
        if not branches:
            break
        roots_done: set[int] = set()
        keep_bone = np.ones(len(pr.bones), bool)
        bone, t = pr.bone.copy(), pr.t.copy()
        n_removed = 0
        for k in np.argsort(scores, kind="stable"):
            if not scores[k] < threshold:
                break
            root, js, bs = branches[k]
            if root in roots_done:
                continue
            roots_done.add(root)
            vids, nb, nt = maps[k]
            bone[vids], t[vids] = nb, nt
            keep_bone[bs] = False
            n_removed += 1
            removed_log.append({"root": int(root), "joints": len(js), "bones": len(bs),
                                "vertices": int(len(vids)), "score": float(scores[k])})
        if n_removed == 0:
            break
        pr.bone, pr.t = bone, t
        pr = _compact(pr, keep_bone)
    return pr, removed_log


# -- chain simplification ----------------------------------------------------------------------
def _merge_costs(pr: FitProblem, max_offset: float = np.inf, only=None):
    """For every joint of degree 2 (of ``only``, a (J,) bool mask, if given): the E increase of
    merging its two bones into one.

    The vertices of the two bones are re-mapped to the closest point of the merged bone *or* of
    a bone sharing one of its end joints (a local re-fit of sigma, as between solver steps), so
    a vertex that the merged bone explains badly can move to a neighbouring bone.

    Returns
    -------
    cand : (k,) int           the joints that can be merged
    cost : (k,) float         exact change of E of each merge, nothing else moving
    nbrs : (k, 2) int         (a, c): the merged bone
    cb : (k, 2) int           the two bones replaced (the first is re-used for (a, c))
    new : list of 2 (bone (n,), t (n,))
        For the merge at end s of each vertex's bone: its new bone (-1 = the merged bone) and t;
        bone -2 where end s of its bone is no candidate.
    """
    J, B = len(pr.joints), pr.bones
    nB = len(B)
    deg = _degree(J, B)
    # Incidence lists (CSR) by sorting the bone ends.
    ends = B.ravel()                                        # joint of (bone, end)
    binc = np.repeat(np.arange(nB), 2)
    o = np.argsort(ends, kind="stable")
    inc_ptr = np.searchsorted(ends[o], np.arange(J + 1))
    inc_b = binc[o]
    cand = np.flatnonzero((deg == 2) if only is None else (deg == 2) & only)
    b1, b2 = inc_b[inc_ptr[cand]], inc_b[inc_ptr[cand] + 1]
    other = lambda b, j: np.where(B[b, 0] == j, B[b, 1], B[b, 0])  # noqa: E731
    a, c = other(b1, cand), other(b2, cand)
    ok = (a != c) & (b1 != b2)
    # The merged bone must not duplicate an existing bone (that would change the topology).
    key = lambda x, y: np.minimum(x, y) * J + np.maximum(x, y)  # noqa: E731
    existing = np.unique(key(B[:, 0], B[:, 1]))
    ok &= ~np.isin(key(a, c), existing)
    # Geometric guard: the joint must lie within max_offset * r_j of the merged bone, so the
    # new bone stays inside the old silhouette (E alone does not see a bone leaving the shape).
    _, d2j = _project(pr.joints[cand, :3], pr.joints[a, :3], pr.joints[c, :3])
    if np.isfinite(max_offset):
        ok &= np.sqrt(d2j) <= max_offset * np.abs(pr.joints[cand, 3])
    cand, b1, b2, a, c = cand[ok], b1[ok], b2[ok], a[ok], c[ok]
    k = len(cand)

    # Candidate bones of each merge: the merged bone (index nB + m in Bx), then the other bones
    # at a and at c. A loop over merges (a few hundred), not over vertices.
    Bx = np.concatenate([B, np.stack([a, c], 1)])
    lists = []
    for m in range(k):
        nb = np.concatenate([inc_b[inc_ptr[a[m]]:inc_ptr[a[m] + 1]], inc_b[inc_ptr[c[m]]:inc_ptr[c[m] + 1]]])
        nb = np.unique(nb[(nb != b1[m]) & (nb != b2[m])])
        lists.append(np.concatenate([[nB + m], nb]))
    cnt = np.array([len(x) for x in lists], np.int64)
    cptr = np.concatenate([[0], np.cumsum(cnt)])
    cids = np.concatenate(lists) if lists else np.zeros(0, np.int64)

    slot = np.full(J, -1)
    slot[cand] = np.arange(k)
    e_now = _residuals(pr.points, pr.joints, B, pr.bone, pr.t)
    w = pr.weights
    cost = np.zeros(k)
    new = []
    from .mapping import closest_on_bones

    for s in (0, 1):
        cv = slot[B[pr.bone, s]]
        m = np.flatnonzero(cv >= 0)
        nbone = np.full(len(pr.points), -2, np.int64)
        nt = np.zeros(len(pr.points))
        if len(m):
            ci = cv[m]
            cc = cnt[ci]
            indptr = np.concatenate([[0], np.cumsum(cc)])
            local = np.arange(indptr[-1]) - np.repeat(indptr[:-1], cc)
            ids = cids[np.repeat(cptr[ci], cc) + local]
            bb, tt, _ = closest_on_bones(pr.points[m], pr.joints, Bx, (indptr, ids))
            en = _residuals(pr.points[m], pr.joints, Bx, bb, tt)
            cost += np.bincount(ci, weights=w[m] * (en * en - e_now[m] ** 2), minlength=k)
            nbone[m] = np.where(bb >= nB, -1, bb)
            nt[m] = tt
        new.append((nbone, nt))
    return cand, cost, np.stack([a, c], 1), np.stack([b1, b2], 1), new


def _neighbours_csr(bones, n_joints):
    """``ptr`` (J+1,) and ``partner``: the joints next to joint x are ``partner[ptr[x]:ptr[x+1]]``
    (in bone order; the array form of :func:`_incidence`)."""
    ends = bones.ravel()
    o = np.argsort(ends, kind="stable")
    return np.searchsorted(ends[o], np.arange(n_joints + 1)), bones[:, ::-1].ravel()[o]


def _independent(pr, cand, nbrs, order, cost, budget=np.inf, spent=0.0):
    """Merges to make in one round, taken in ``order`` while ``spent + cost`` stays within
    ``budget``, skipping any within the 2-ring of one already taken (the merge re-maps vertices
    onto bones at a and c, which must not change in the same round). Returns (acc, spent)."""
    blocked = np.zeros(len(pr.joints), bool)
    ptr, partner = _neighbours_csr(pr.bones, len(pr.joints))
    nbr_of = lambda x: partner[ptr[x]:ptr[x + 1]]  # noqa: E731
    acc = []
    for k in order:
        if spent + cost[k] > budget:
            if cost[k] > 0:
                break
            continue
        j = cand[k]
        if blocked[j]:
            continue
        acc.append(k)
        spent += cost[k]
        ring = np.concatenate([[j], nbrs[k], nbr_of(nbrs[k, 0]), nbr_of(nbrs[k, 1])])
        blocked[ring] = True
    return np.asarray(acc, np.int64), spent


def _apply_merges(pr, cand, acc, nbrs, cb, new) -> FitProblem:
    """Make the merges ``acc`` of :func:`_merge_costs`' candidates (vertices re-mapped as costed)."""
    bones, bone, t = pr.bones.copy(), pr.bone.copy(), pr.t.copy()
    keep_bone = np.ones(len(bones), bool)
    slot = np.full(len(pr.joints), -1)
    slot[cand[acc]] = acc
    for s in (0, 1):                                  # vertices whose bone end s is merged
        nbone, nt = new[s]
        m = np.flatnonzero((slot[pr.bones[pr.bone, s]] >= 0) & (nbone > -2))
        merged_bone = cb[slot[pr.bones[pr.bone[m], s]], 0]
        bone[m] = np.where(nbone[m] == -1, merged_bone, nbone[m])
        t[m] = nt[m]
    bones[cb[acc, 0]] = nbrs[acc]                     # (a, c) replaces (a, j); t refers to a, c
    keep_bone[cb[acc, 1]] = False
    pr.bones, pr.bone, pr.t = bones, bone, t
    pr = _compact(pr, keep_bone)
    return pr


def simplify_chains(pr: FitProblem, threshold: float, *, max_offset: float = 0.25,
                    floor: float = 0.01, max_rounds: int = 200) -> tuple[FitProblem, dict]:
    """Merge degree-2 joints whose removal barely changes E, cheapest first.

    A merge removes joint j with bones (a, j), (j, c) and puts the bone (a, c) in their place;
    the vertices of both bones are re-mapped to the closest point (t clamped to [0, 1]) of the
    new bone or of another bone at a or c (a local re-fit of sigma, as between solver steps).
    Its cost is the exact change of E with nothing else moving. The total cost of all merges
    is kept within a budget of ``threshold * max(E, floor^2 * S)``, where E is the input's energy
    and ``S = sum_v w_v |v - sigma_v|^4`` the energy of the same mapping with zero radii (the
    scale of E). The floor is the E of a fit whose residual is ``floor`` (1 %) of ``|v - sigma|^2``
    at every vertex: without it a near-exact fit (a cylinder, E ~ 1e-12) could merge nothing.
    So ``E_after <= E_before + threshold * max(E_before, floor^2 S)`` before any re-optimisation
    (which only lowers E).

    Each round computes every candidate's cost in one vectorised pass over the vertices, then
    accepts candidates in increasing cost while the budget lasts, skipping a candidate within two
    joints of one accepted in the same round (their costs interact). Rounds repeat until nothing
    is accepted.
    Merges that would duplicate a bone (collapse a triangle cycle) or create a loop are never made,
    so the skeleton's topology (components, cycles, branch joints, leaves) is kept.

    Parameters
    ----------
    pr : FitProblem
        Usually optimised; not modified.
    threshold : float >= 0
        Allowed relative increase of E (0 disables; 0.01 allows 1 %).
    max_offset : float
        A joint is merged only if it lies within ``max_offset * r_j`` of the merged bone
        (a geometric guard keeping bones inside the shape; ``np.inf`` disables it).
    floor : float
        Relative residual below which a fit counts as exact (see above; 0 disables the floor).

    Returns
    -------
    FitProblem, dict
        The simplified problem and {"merged", "rounds", "energy_before", "energy_after",
        "budget"}.
    """
    pr = pr.copy()
    E0 = _energy(pr)
    info = {"merged": 0, "rounds": 0, "energy_before": E0, "energy_after": E0, "budget": 0.0}
    if threshold <= 0:
        return pr, info
    d2 = _residuals(pr.points, pr.joints, pr.bones, pr.bone, pr.t) + _radius_at(pr) ** 2
    S = float(np.dot(pr.weights, d2 * d2))
    budget = threshold * max(E0, floor * floor * S)
    info["budget"] = budget
    spent = 0.0
    for _ in range(max_rounds):
        cand, cost, nbrs, cb, new = _merge_costs(pr, max_offset)
        if len(cand) == 0:
            break
        acc, spent = _independent(pr, cand, nbrs, np.argsort(cost, kind="stable"), cost, budget, spent)
        if not len(acc):
            break
        pr = _apply_merges(pr, cand, acc, nbrs, cb, new)
        info["merged"] += int(len(acc))
        info["rounds"] += 1
    info["energy_after"] = _energy(pr)
    return pr, info


#: A chain joint whose two bones turn by more than this (cosine of the turn below -0.9:
#: more than 154 degrees) is a fold: the chain doubles back on itself...
FOLD_COS = -0.9
#: ... when both bones are longer than this many times the joint's radius.
FOLD_MIN_LENGTH = 2.0


def fold_joints(joints: np.ndarray, bones: np.ndarray, cos_max: float = FOLD_COS, *,
                min_length: float = FOLD_MIN_LENGTH, overlap: bool = True,
                short: float = np.inf) -> np.ndarray:
    """(J,) bool: joints of degree 2 where the chain doubles back (turn beyond ``cos_max``,
    both bones longer than ``min_length`` times the joint's radius, the shorter one shorter
    than ``short`` times it and, with ``overlap``, one of them inside the silhouette of
    another bone).

    The turn at j between (a, j) and (j, c) is the angle between ``x_j - x_a`` and
    ``x_c - x_j``; a straight chain turns 0, a hairpin almost 180 degrees.
    """
    J = len(joints)
    deg = _degree(J, bones)
    out = np.zeros(J, bool)
    mid = np.flatnonzero(deg == 2)
    if not mid.size:
        return out
    ptr, partner = _neighbours_csr(bones, J)
    a, c = partner[ptr[mid]], partner[ptr[mid] + 1]
    u = joints[mid, :3] - joints[a, :3]
    v = joints[c, :3] - joints[mid, :3]
    nu, nv = np.linalg.norm(u, axis=1), np.linalg.norm(v, axis=1)
    # A turn between bones shorter than twice the joint's radius is hidden in its ball (and the
    # direction of a near-zero bone is noise): not a fold.
    r = min_length * np.abs(joints[mid, 3])
    ok = (nu > r) & (nv > r) & (nu > 0) & (nv > 0)
    if np.isfinite(short):
        ok &= np.minimum(nu, nv) < short * np.abs(joints[mid, 3])
    cos = np.einsum("ij,ij->i", u, v) / np.where(ok, nu * nv, 1.0)
    sharp = np.flatnonzero(ok & (cos < cos_max))
    if not overlap:
        out[mid[sharp]] = True
        return out
    # ... and one of its bones runs inside the silhouette of a bone elsewhere (not at j): the
    # chain doubles another part of the skeleton (a zig-zag across a flat part does not).
    from .quality import sd_round_cone

    X, r_all = joints[:, :3], np.abs(joints[:, 3])
    for k in sharp:
        j = mid[k]
        others = np.flatnonzero((bones[:, 0] != j) & (bones[:, 1] != j))
        if not others.size:
            continue
        M = np.stack([(X[a[k]] + X[j]) / 2, (X[j] + X[c[k]]) / 2])       # bone midpoints
        bi, bj = bones[others, 0], bones[others, 1]
        sd = sd_round_cone(M[:, None, :], X[bi][None], X[bj][None], r_all[bi][None], r_all[bj][None])
        out[j] = bool((sd < 0).any())
    return out


def unfold_chains(pr: FitProblem, *, cos_max: float = FOLD_COS, max_rounds: int = 50,
                  min_length: float = FOLD_MIN_LENGTH, overlap: bool = True,
                  short: float = np.inf) -> tuple[FitProblem, int]:
    """Merge away every chain joint where the chain doubles back, whatever it costs in E.

    Why: E cannot see a fold. Where parts meet (a junction, a saddle) a chain that runs out
    along a neighbouring part and back lets overlapping bones explain the same vertices, which
    E rewards; a rigger sees an arm rooted half-way along another arm. A fold is a joint of
    degree 2 whose bones, both longer than its ball, turn by more than 154 degrees
    (:func:`fold_joints`); it is merged like :func:`simplify_chains` merges (vertices
    re-mapped to the merged bone or a neighbour), in joint order, non-adjacent ones together,
    without the cost budget or the offset guard. Topology is kept (no merge duplicates a bone).
    ``min_length``, ``overlap``, ``short``: as in :func:`fold_joints`.
    Returns (problem, joints merged).
    """
    pr = pr.copy()
    merged = 0
    for _ in range(max_rounds):
        folds = fold_joints(pr.joints, pr.bones, cos_max, min_length=min_length, overlap=overlap,
                            short=short)
        if not folds.any():
            break
        cand, cost, nbrs, cb, new = _merge_costs(pr, np.inf, only=folds)
        if len(cand) == 0:
            break
        acc, _ = _independent(pr, cand, nbrs, np.arange(len(cand)), np.zeros(len(cand)))
        pr = _apply_merges(pr, cand, acc, nbrs, cb, new)
        merged += int(len(acc))
    return pr, merged


# -- entry point -------------------------------------------------------------------------------
def postprocess(problem: FitProblem, params, solve: Solve) -> FitProblem:
    """Prune noise branches, then simplify straight chains, re-optimising after each change.

    Parameters
    ----------
    problem : FitProblem
        The solver's result (joints, bones, mapping). Not modified.
    params : SkeletonParams
        Uses ``params.prune`` (branch score threshold in [0, 1], 0 = off) and
        ``params.simplify`` (relative E budget, 0 = off).
    solve : callable(FitProblem) -> FitProblem
        Re-optimises a problem (short run of the configured solver).

    Returns
    -------
    FitProblem
        ``meta["postprocess"]`` records what was removed and E before/after each stage.
    """
    pr = problem.copy()
    log = {"energy_in": _energy(pr), "joints_in": int(len(pr.joints))}
    if getattr(params, "prune", 0.0) > 0:
        pr, removed = prune_branches(pr, float(params.prune))
        log["pruned"] = removed
        if removed:
            log["energy_pruned"] = _energy(pr)
            pr = solve(pr)
            log["energy_pruned_solved"] = _energy(pr)
    if getattr(params, "simplify", 0.0) > 0:
        pr, info = simplify_chains(pr, float(params.simplify))
        log["simplify"] = info
        if info["merged"]:
            pr = solve(pr)
            log["energy_simplified_solved"] = _energy(pr)
    log["energy_out"] = _energy(pr)
    log["joints_out"] = int(len(pr.joints))
    pr.meta = dict(pr.meta)
    pr.meta["postprocess"] = log
    return pr
