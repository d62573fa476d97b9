"""Topology moves: pure functions ``SkeletonGraph -> (SkeletonGraph, bone_map)``.

Each move proposes a new graph; the search (:mod:`..search`) keeps it only when J falls and
the guards hold. ``bone_map`` has rows ``(old bone, new bone)``: the surface that mapped to an
old bone may map to each of its new bones (:func:`..graph.rewrite_pairs`). New joints are
appended, removed joints dropped; the kept joints keep their order.

merge
    A chain joint (two bones) is removed and its neighbours joined by one bone.
contract
    A bone is shrunk to one joint at its middle (two junctions that are one).
prune
    A leaf chain (from a tip to its junction) is removed; its surface maps to the junction's
    other bones.
split
    A bone gets a joint at its middle.
"""

from __future__ import annotations

import numpy as np

from ..geometry.rows import row_norm
from ..graph import SkeletonGraph, carry_thickness, rewrite_pairs

__all__ = ["merge_joints", "contract_bones", "prune_chains", "split_bones", "leaf_chains",
           "incident"]


def incident(bones, n_joints):
    """CSR (start (J + 1,), bone ids) of the bones at each joint."""
    bones = np.asarray(bones, np.int64).reshape(-1, 2)
    ends = np.concatenate([bones[:, 0], bones[:, 1]])
    order = np.argsort(ends, kind="stable")
    start = np.concatenate([[0], np.cumsum(np.bincount(ends, minlength=n_joints))])
    return start, np.concatenate([np.arange(len(bones))] * 2)[order]


def _rebuild(graph, joints, bones, keep_joint, bone_map) -> tuple:
    """Drop the joints not kept, renumber, rewrite the pairs, carry the thickness."""
    new_id = np.cumsum(keep_joint) - 1
    B = new_id[bones]
    pairs = rewrite_pairs(graph.pairs, bone_map)
    Z = np.asarray(graph.joints)
    old_len = row_norm(Z[graph.bones[:, 0], :3] - Z[graph.bones[:, 1], :3])
    thick = carry_thickness(graph.thick, old_len, bone_map, len(B))
    return SkeletonGraph(joints[keep_joint], B, pairs, thick), bone_map


def merge_joints(graph, ks):
    """Remove the chain joints ``ks`` (no two sharing a bone), joining their neighbours.

    Examples
    --------
    >>> g = SkeletonGraph([[0, 0, 0, 1], [1, 0, 0, 1], [2, 0, 0, 1]], [[0, 1], [1, 2]],
    ...                   [[0, 0], [1, 1]])
    >>> h, bm = merge_joints(g, [1])
    >>> np.sort(h.bones, axis=1).tolist(), sorted(bm.tolist()), h.pairs.tolist()
    ([[0, 1]], [[0, 0], [1, 0]], [[0, 0], [1, 0]])
    """
    ks = np.asarray(ks, np.int64)
    J, Bn = graph.n_joints, len(graph.bones)
    start, ids = incident(graph.bones, J)
    if np.any(start[ks + 1] - start[ks] != 2):
        raise ValueError("merge_joints: every joint must have exactly two bones")
    b1, b2 = ids[start[ks]], ids[start[ks] + 1]
    if len(np.unique(np.concatenate([b1, b2]))) != 2 * len(ks):
        raise ValueError("merge_joints: two merged joints share a bone")
    bones = graph.bones
    other = lambda b: np.where(bones[b, 0] == ks, bones[b, 1], bones[b, 0])  # noqa: E731
    a, c = other(b1), other(b2)
    gone = np.zeros(Bn, bool)
    gone[b1] = gone[b2] = True
    kept = np.flatnonzero(~gone)
    new_bones = np.concatenate([bones[kept], np.stack([a, c], 1)])
    bone_map = np.concatenate([np.stack([kept, np.arange(len(kept))], 1),
                               np.stack([b1, len(kept) + np.arange(len(ks))], 1),
                               np.stack([b2, len(kept) + np.arange(len(ks))], 1)])
    keep = np.ones(J, bool)
    keep[ks] = False
    return _rebuild(graph, np.asarray(graph.joints), new_bones, keep, bone_map)


def contract_bones(graph, bs):
    """Shrink each bone of ``bs`` (no two sharing a joint) to one joint at its middle (radius:
    the mean). A contraction whose two joints share a neighbour would fuse two bones (and lose
    a cycle): refused."""
    bs = np.asarray(bs, np.int64)
    bones, Z = graph.bones, np.array(graph.joints)
    i, j = bones[bs, 0], bones[bs, 1]
    if len(np.unique(np.concatenate([i, j]))) != 2 * len(bs):
        raise ValueError("contract_bones: two contracted bones share a joint")
    J = len(Z)
    target = np.arange(J)
    target[j] = i
    Z[i] = 0.5 * (Z[i] + Z[j])
    nb = target[bones]
    keepb = nb[:, 0] != nb[:, 1]
    key = np.sort(nb[keepb], axis=1)
    if len(np.unique(key, axis=0)) != len(key):
        raise ValueError("contract_bones: a contraction would fuse two bones (a lost cycle)")
    kept = np.flatnonzero(keepb)
    bone_map = np.stack([kept, np.arange(len(kept))], 1)
    # a contracted bone's surface maps to every bone at its new joint
    start, ids = incident(nb[kept], J)
    extra = [np.stack([np.full(start[v + 1] - start[v], b), ids[start[v]:start[v + 1]]], 1)
             for b, v in zip(bs, i)]
    bone_map = np.concatenate([bone_map] + extra) if extra else bone_map
    keep = np.ones(J, bool)
    keep[j] = False
    return _rebuild(graph, Z, nb[kept], keep, bone_map)


def leaf_chains(graph):
    """Each tip's chain up to (not including) its first joint of three or more bones: a list of
    (joints from the tip, bones, junction or -1 for a skeleton that is one chain)."""
    J = graph.n_joints
    deg = graph.degree
    start, ids = incident(graph.bones, J)
    bones = graph.bones
    out = []
    for tip in np.flatnonzero(deg == 1):
        js, bs = [int(tip)], []
        prev_b = -1
        v = int(tip)
        while True:
            nb = [b for b in ids[start[v]:start[v + 1]] if b != prev_b]
            if deg[v] != 2 and v != tip or not nb:
                break
            b = int(nb[0])
            w = int(bones[b, 0] if bones[b, 1] == v else bones[b, 1])
            bs.append(b)
            prev_b, v = b, w
            if deg[v] != 2:
                break
            js.append(v)
        out.append((js, bs, v if deg[v] >= 3 else -1))
    return out


def prune_chains(graph, chains):
    """Remove leaf chains ``[(joints, bones, junction), ...]`` (as :func:`leaf_chains`); the
    surface of their bones maps to the junction's remaining bones."""
    J, Bn = graph.n_joints, len(graph.bones)
    keep = np.ones(J, bool)
    gone = np.zeros(Bn, bool)
    for js, bs, _ in chains:
        keep[js] = False
        gone[bs] = True
    kept = np.flatnonzero(~gone)
    bones = graph.bones[kept]
    bone_map = [np.stack([kept, np.arange(len(kept))], 1)]
    start, ids = incident(bones, J)
    for js, bs, v in chains:
        if v < 0:
            continue
        for b in bs:
            nb = ids[start[v]:start[v + 1]]
            bone_map.append(np.stack([np.full(len(nb), b), nb], 1))
    return _rebuild(graph, np.asarray(graph.joints), bones, keep, np.concatenate(bone_map))


def split_bones(graph, bs):
    """A joint at the middle of each bone of ``bs``; the bone's surface maps to both halves."""
    bs = np.asarray(bs, np.int64)
    Z = np.asarray(graph.joints)
    J, Bn = len(Z), len(graph.bones)
    i, j = graph.bones[bs, 0], graph.bones[bs, 1]
    mid = J + np.arange(len(bs))
    joints = np.concatenate([Z, 0.5 * (Z[i] + Z[j])])
    rest = np.setdiff1d(np.arange(Bn), bs)
    bones = np.concatenate([graph.bones[rest], np.stack([i, mid], 1), np.stack([mid, j], 1)])
    n = len(rest)
    bone_map = np.concatenate([np.stack([rest, np.arange(n)], 1),
                               np.stack([bs, n + np.arange(len(bs))], 1),
                               np.stack([bs, n + len(bs) + np.arange(len(bs))], 1)])
    return _rebuild(graph, joints, bones, np.ones(len(joints), bool), bone_map)


def contract_short(graph, length):
    """Contract bones shorter than ``length`` (shortest first, in rounds of bones that share no
    joint) wherever that fuses no two bones. Returns the graph and the composed bone map."""
    total = np.stack([np.arange(len(graph.bones))] * 2, 1)
    while True:
        Z = np.asarray(graph.joints)
        L = row_norm(Z[graph.bones[:, 0], :3] - Z[graph.bones[:, 1], :3])
        short = np.flatnonzero(L < length)
        if not len(short):
            return graph, total
        short = short[np.argsort(L[short], kind="stable")]
        nbrs = _neighbour_sets(graph)
        used = np.zeros(graph.n_joints, bool)
        pick = []
        for b in short:
            i, j = graph.bones[b]
            if used[i] or used[j] or nbrs[i] & nbrs[j]:
                continue
            used[i] = used[j] = True
            pick.append(b)
        if not pick:
            return graph, total
        graph, bm = contract_bones(graph, pick)
        total = _compose(total, bm)


def _neighbour_sets(graph):
    out = [set() for _ in range(graph.n_joints)]
    for i, j in graph.bones.tolist():
        out[i].add(j)
        out[j].add(i)
    return out


def _compose(first, second):
    """Bone maps (old, mid) then (mid, new) -> (old, new)."""
    o = np.argsort(second[:, 0], kind="stable")
    s = second[o]
    lo = np.searchsorted(s[:, 0], first[:, 1], "left")
    hi = np.searchsorted(s[:, 0], first[:, 1], "right")
    cnt = hi - lo
    rows = np.repeat(np.arange(len(first)), cnt)
    idx = np.repeat(lo, cnt) + (np.arange(cnt.sum()) - np.repeat(np.cumsum(cnt) - cnt, cnt))
    return np.unique(np.stack([first[rows, 0], s[idx, 1]], 1), axis=0)


def split_long(graph, length):
    """Split every bone longer than ``length`` into equal pieces no longer than it (new joints
    on the segment, radii interpolated); each piece explains its bone's surface."""
    Z = np.asarray(graph.joints)
    bones = graph.bones
    L = row_norm(Z[bones[:, 0], :3] - Z[bones[:, 1], :3])
    k = np.maximum(1, np.ceil(L / max(length, 1e-300) - 1e-9).astype(np.int64))
    if np.all(k == 1):
        return graph, np.stack([np.arange(len(bones))] * 2, 1)
    J = len(Z)
    owner = np.repeat(np.arange(len(bones)), k)                 # piece -> original bone
    first = np.concatenate([[0], np.cumsum(k)[:-1]])
    piece = np.arange(len(owner)) - np.repeat(first, k)         # 0..k-1 along the bone
    inner = piece > 0
    u = (piece[inner] / k[owner[inner]])[:, None]
    bi, bj = bones[owner[inner], 0], bones[owner[inner], 1]
    new = Z[bi] + u * (Z[bj] - Z[bi])
    new_id = np.full(len(owner), -1, np.int64)
    new_id[inner] = J + np.arange(int(inner.sum()))
    start = np.where(piece == 0, bones[owner, 0], new_id)
    end = np.where(piece == k[owner] - 1, bones[owner, 1], np.roll(new_id, -1))
    joints = np.concatenate([Z, new])
    bone_map = np.stack([owner, np.arange(len(owner))], 1)
    return _rebuild(graph, joints, np.stack([start, end], 1), np.ones(len(joints), bool),
                    bone_map)


def split_joint(graph, j, group, fraction):
    """A junction ``j`` split in two: the bones from ``j`` to the neighbours ``group`` move to a
    new joint, ``fraction`` of the way from ``j`` towards those neighbours' centroid, joined to
    ``j`` by a new bone (a four-way crossing becomes two three-way junctions and a rung). The
    new bone explains what the moved bones explained."""
    Z = np.asarray(graph.joints)
    bones = graph.bones
    J = len(Z)
    group = np.asarray(group, np.int64)
    moved = np.flatnonzero(((bones[:, 0] == j) & np.isin(bones[:, 1], group))
                           | ((bones[:, 1] == j) & np.isin(bones[:, 0], group)))
    new = Z[j].copy()
    new[:3] += fraction * (Z[group, :3].mean(axis=0) - Z[j, :3])
    joints = np.concatenate([Z, new[None]])
    B2 = bones.copy()
    B2[moved] = np.where(B2[moved] == j, J, B2[moved])
    B2 = np.concatenate([B2, [[j, J]]])
    nb = len(bones)
    bone_map = np.concatenate([np.stack([np.arange(nb)] * 2, 1),
                               np.stack([moved, np.full(len(moved), nb)], 1)])
    return _rebuild(graph, joints, B2, np.ones(J + 1, bool), bone_map)


def junction_splits(graph):
    """Every way to split a junction of four bones (a crossing) into two of two bones each:
    (joint, the two neighbours that move) pairs."""
    out = []
    nbrs = _neighbour_sets(graph)
    for j in np.flatnonzero(graph.degree == 4):
        first, *rest = sorted(nbrs[j])
        for other in rest:                      # the partner of the first neighbour
            out.append((int(j), [first, other]))
    return out
