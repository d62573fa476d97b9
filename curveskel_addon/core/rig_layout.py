"""Rig layout of a Skeleton: root, bone directions, hierarchy, names and roll axes (pure maths).

The Blender layer (``armature.py``) turns a :class:`RigLayout` into edit bones one to one; the
skin weights (``skin_weights.py``) read the blend partners of each bone from it.

Rules
-----
- Coincident joints (a bone shorter than ``merge_tol``) are merged: such a bone gets no Blender
  bone (Blender 4.2 deletes zero-length bones) and its vertices go to the bone that holds the
  merged joint.
- Each connected part of the skeleton gets a root joint (its most central joint, or one given)
  and one root bone ``root.NN`` there, pointing "up"; every other bone descends from it.
- Bones run head -> tail away from the root (shortest-path tree from the root; a bone that closes
  a cycle runs from its end nearer the root). The parent of a bone is the tree bone that ends at
  its head (the root bone for bones leaving the root joint).
- A branch is a run of bones through joints of degree 2; a new branch starts at the root and at
  every junction. Names are ``branchBB.PP``: branch number (breadth first from the root) and
  position along the branch from its root end.
- Roll: a z-axis per bone, perpendicular to it, carried from the parent bone by projection
  (parallel transport), so consecutive bones never flip by 180 degrees.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components, dijkstra

from .errors import CurveSkelError
from .graph_root import central_joints

__all__ = ["RigLayout", "rig_layout", "BLEND_NONE", "BLEND_SYMMETRIC", "BLEND_HUB"]

#: Blend modes at the end of a bone (see ``skin_weights``): no neighbour (a leaf, or the bone
#: that owns a junction), a symmetric 50/50 blend at a chain joint, or a one-sided blend into
#: the hub bone of a junction / the root (the hub has weight 1 at the joint).
BLEND_NONE, BLEND_SYMMETRIC, BLEND_HUB = 0, 1, 2


@dataclass
class RigLayout:
    """Bones of an armature made from a Skeleton, in creation order (parents before children).

    Attributes
    ----------
    heads, tails : (R, 3) float
        Bone ends, in the skeleton's (input mesh's) space; every bone has a positive length.
    names : list of str
        ``root.NN`` for the root bone of part NN, ``branchBB.PP`` otherwise.
    parent : (R,) int
        Parent rig bone, -1 for root bones.
    connect : (R,) bool
        Head sits on the parent's tail (Blender ``use_connect``).
    z_axis : (R, 3) float
        Unit roll reference, perpendicular to the bone (Blender ``align_roll``).
    skeleton_bone : (R,) int
        Skeleton bone of each rig bone, -1 for root bones.
    head_joint, tail_joint : (R,) int
        Skeleton joints at the ends (tail_joint -1 for root bones).
    branch, position : (R,) int
        Branch number and position along it (-1 for root bones).
    component : (R,) int
        Connected part of the skeleton.
    roots : (C,) int
        Root joint of each part.
    bone_rig : (B,) int
        Rig bone that carries each skeleton bone's vertices.
    bone_reversed : (B,) bool
        True when the rig bone runs from joint j to joint i of skeleton bone (i, j).
    bone_s : (B,) float
        NaN, or the fixed position along ``bone_rig`` of a merged (zero-length) skeleton bone.
    head_mode, tail_mode : (R,) int
        Blend mode at each end (BLEND_NONE, BLEND_SYMMETRIC, BLEND_HUB).
    head_partner, tail_partner : (R,) int
        Rig bone blended with at each end, -1 for none.
    joint_map : (J,) int
        Representative of each joint after merging coincident joints.
    """

    heads: np.ndarray
    tails: np.ndarray
    names: list
    parent: np.ndarray
    connect: np.ndarray
    z_axis: np.ndarray
    skeleton_bone: np.ndarray
    head_joint: np.ndarray
    tail_joint: np.ndarray
    branch: np.ndarray
    position: np.ndarray
    component: np.ndarray
    roots: np.ndarray
    bone_rig: np.ndarray
    bone_reversed: np.ndarray
    bone_s: np.ndarray
    head_mode: np.ndarray
    tail_mode: np.ndarray
    head_partner: np.ndarray
    tail_partner: np.ndarray
    joint_map: np.ndarray
    meta: dict = field(default_factory=dict)

    @property
    def n_bones(self) -> int:
        return len(self.heads)

    @property
    def root_bones(self) -> np.ndarray:
        """(C,) rig index of each part's root bone."""
        return np.flatnonzero(self.parent < 0)

    def rig_coordinates(self, bone, t) -> tuple[np.ndarray, np.ndarray]:
        """Rig bone and position along it (0 at head, 1 at tail) of skeleton-mapped points.

        Parameters
        ----------
        bone : (n,) int
            Skeleton bone of each point.
        t : (n,) float
            sigma = t * x_i + (1 - t) * x_j for skeleton bone (i, j).

        Returns
        -------
        r : (n,) int
        s : (n,) float in [0, 1]
        """
        bone = np.asarray(bone, dtype=np.int64).ravel()
        t = np.clip(np.asarray(t, dtype=np.float64).ravel(), 0.0, 1.0)
        if bone.shape != t.shape:
            raise CurveSkelError(f"bone {bone.shape} and t {t.shape} differ in length")
        r = self.bone_rig[bone]
        s = np.where(self.bone_reversed[bone], t, 1.0 - t)
        fixed = self.bone_s[bone]
        s = np.where(np.isnan(fixed), s, fixed)
        return r, s


def _unit(v):
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.where(n > 0, n, 1.0)


def _perpendicular(d, ref):
    """Unit vector perpendicular to unit ``d``, closest to ``ref`` (fallback axes if parallel)."""
    for cand in (ref, np.array([0.0, 0.0, 1.0]), np.array([0.0, -1.0, 0.0]), np.array([1.0, 0.0, 0.0])):
        z = cand - d * (cand @ d)
        n = np.linalg.norm(z)
        if n > 0.1 * max(np.linalg.norm(cand), 1e-300):
            return z / n
    raise AssertionError("unreachable: three axes cannot all be parallel to d")


def _transport(z_prev, d_prev, d):
    """Carry the roll axis ``z_prev`` of a bone along ``d_prev`` onto a bone along ``d``.

    Projection onto the plane perpendicular to ``d`` (the perpendicular closest to ``z_prev``, so
    the two axes never point apart); when ``d`` is nearly along ``z_prev`` the minimal rotation
    taking ``d_prev`` to ``d`` is applied instead.
    """
    z = z_prev - d * (z_prev @ d)
    n = np.linalg.norm(z)
    if n > 1e-3:
        return z / n
    axis = np.cross(d_prev, d)
    s = np.linalg.norm(axis)
    if s < 1e-12:
        return _perpendicular(d, z_prev)
    axis /= s
    c = float(np.clip(d_prev @ d, -1.0, 1.0))
    ang = np.arctan2(s, c)
    zr = (z_prev * np.cos(ang) + np.cross(axis, z_prev) * np.sin(ang)
          + axis * (axis @ z_prev) * (1.0 - np.cos(ang)))
    return _perpendicular(d, zr)


def rig_layout(joints, bones, *, root=None, up=(0.0, 0.0, 1.0), merge_tol=None) -> RigLayout:
    """Armature layout of a skeleton graph.

    Parameters
    ----------
    joints : (J, 4) or (J, 3) float
        Joint positions (and radii, used for the root bone's length).
    bones : (B, 2) int
        Joint pairs.
    root : int or sequence of int, optional
        Root joint(s); a part without a given root uses its most central joint.
    up : (3,) float
        Direction of the root bones, in the joints' space (world "up" seen from the object).
    merge_tol : float, optional
        Bones shorter than this are merged into a joint; default
        ``max(1e-6 * diagonal, 1e-5)`` (Blender drops bones shorter than 1e-6).

    Returns
    -------
    RigLayout

    Raises
    ------
    CurveSkelError
        If the skeleton has no bones or an index is out of range.
    """
    P = np.asarray(joints, dtype=np.float64)
    if P.ndim != 2 or P.shape[1] not in (3, 4):
        raise CurveSkelError(f"joints must have shape (J, 3) or (J, 4), got {P.shape}")
    X = P[:, :3]
    Rj = P[:, 3] if P.shape[1] == 4 else np.zeros(len(P))
    E = np.asarray(bones, dtype=np.int64).reshape(-1, 2)
    J, B = len(P), len(E)
    if B == 0:
        raise CurveSkelError("the skeleton has no bones: nothing to rig")
    if E.min() < 0 or E.max() >= J:
        raise CurveSkelError("bone joint index out of range")
    up = _unit(np.asarray(up, dtype=np.float64).reshape(3))
    if not np.any(up):
        up = np.array([0.0, 0.0, 1.0])
    diag = float(np.linalg.norm(np.ptp(X, axis=0))) if J > 1 else 0.0
    tol = max(1e-6 * diag, 1e-5) if merge_tol is None else float(merge_tol)

    # -- merge coincident joints (bones shorter than tol) --------------------------------------------
    L = np.linalg.norm(X[E[:, 0]] - X[E[:, 1]], axis=1)
    short = L < tol
    Gs = coo_matrix((np.ones(short.sum()), (E[short, 0], E[short, 1])), shape=(J, J))
    _, lab = connected_components(Gs, directed=False)
    first = np.full(lab.max() + 1, J, np.int64)
    np.minimum.at(first, lab, np.arange(J))
    jmap = first[lab]
    M = jmap[E]
    collapsed = M[:, 0] == M[:, 1]
    live = np.flatnonzero(~collapsed)

    # -- parts and roots -----------------------------------------------------------------------------
    used = np.zeros(J, bool)
    used[M.ravel()] = True
    w = np.maximum(L[live], tol)
    G = coo_matrix((w, (M[live, 0], M[live, 1])), shape=(J, J)).tocsr()
    # coo sums duplicate bones: keep the minimum length per joint pair instead.
    if len(live):
        a, b = np.minimum(M[live, 0], M[live, 1]), np.maximum(M[live, 0], M[live, 1])
        key = a * J + b
        order = np.lexsort((w, key))
        keep = order[np.r_[True, key[order][1:] != key[order][:-1]]]
        G = coo_matrix((w[keep], (a[keep], b[keep])), shape=(J, J)).tocsr()
    _, plabel = connected_components(G, directed=False)
    parts = [int(c) for c in np.unique(plabel[used])]  # parts that carry at least one bone
    part_roots = {}
    if root is not None:
        for rj in np.atleast_1d(np.asarray(root, dtype=np.int64)):
            if not 0 <= rj < J:
                raise CurveSkelError(f"root joint {int(rj)} out of range (0..{J - 1})")
            rr = jmap[rj]
            part_roots.setdefault(plabel[rr], int(rr))
    auto = central_joints(X, M[live]) if len(live) else np.zeros(0, np.int64)
    for c_root in auto:
        if used[c_root]:
            part_roots.setdefault(plabel[c_root], int(c_root))
    for c in parts:  # a part of merged joints only (no live bone): its single joint
        if c not in part_roots:
            part_roots[c] = int(np.flatnonzero((plabel == c) & used)[0])
    parts = sorted(parts, key=lambda c: int(np.flatnonzero(plabel == c)[0]))
    roots = np.array([part_roots[c] for c in parts], np.int64)
    comp_of_part = {c: k for k, c in enumerate(parts)}

    # -- shortest-path tree from the roots -----------------------------------------------------------
    dist, pred, _ = dijkstra(G, directed=False, indices=roots, min_only=True, return_predecessors=True)
    dist = np.where(np.isfinite(dist), dist, np.inf)
    head = np.where(dist[M[:, 0]] <= dist[M[:, 1]], M[:, 0], M[:, 1])
    tail = np.where(head == M[:, 0], M[:, 1], M[:, 0])
    # tree bone of every non-root joint: the shortest live bone between pred[v] and v
    in_tree = np.full(J, -1, np.int64)
    for b in live[np.argsort(L[live], kind="stable")]:
        h, t_ = head[b], tail[b]
        if pred[t_] == h and in_tree[t_] < 0:
            in_tree[t_] = b
    is_root = np.zeros(J, bool)
    is_root[roots] = True
    deg = np.bincount(M[live].ravel(), minlength=J)

    # -- branches ------------------------------------------------------------------------------------
    # A bone continues its parent's branch when its head is a non-root joint of degree 2.
    cont = np.zeros(B, bool)
    cont[live] = (~is_root[head[live]]) & (deg[head[live]] == 2)
    nxt = np.full(B, -1, np.int64)
    for b in live[cont[live]]:
        nxt[in_tree[head[b]]] = b
    part_index = np.full(J, -1, np.int64)
    for c, k in comp_of_part.items():
        part_index[plabel == c] = k
    comp_b = part_index[head]
    starts = live[~cont[live]]
    starts = starts[np.lexsort((starts, dist[tail[starts]], dist[head[starts]], comp_b[starts]))]
    branch = np.full(B, -1, np.int64)
    position = np.full(B, -1, np.int64)
    chain_order = []
    for k, s0 in enumerate(starts):
        b, p = s0, 0
        while b >= 0 and branch[b] < 0:
            branch[b], position[b] = k, p
            chain_order.append(b)
            b, p = nxt[b], p + 1

    # -- rig bones: root bones first per part, then branches in order ----------------------------------
    C = len(roots)
    R = C + len(chain_order)
    rig_of_bone = np.full(B, -1, np.int64)
    skel = np.full(R, -1, np.int64)
    comp = np.empty(R, np.int64)
    comp[:C] = np.arange(C)
    order_by_comp = sorted(chain_order, key=lambda b: (comp_b[b], branch[b], position[b]))
    # interleave: root bone of part c, then that part's bones
    idx = 0
    slot = {}
    for c in range(C):
        slot[("root", c)] = idx
        idx += 1
        for b in order_by_comp:
            if comp_b[b] == c:
                slot[b] = idx
                idx += 1
    root_rig = np.array([slot[("root", c)] for c in range(C)], np.int64)
    for b in chain_order:
        rig_of_bone[b] = slot[b]
        skel[slot[b]] = b
        comp[slot[b]] = comp_b[b]
    for c in range(C):
        comp[root_rig[c]] = c

    heads = np.zeros((R, 3))
    tails = np.zeros((R, 3))
    parent = np.full(R, -1, np.int64)
    connect = np.zeros(R, bool)
    head_joint = np.full(R, -1, np.int64)
    tail_joint = np.full(R, -1, np.int64)
    br = np.full(R, -1, np.int64)
    pos = np.full(R, -1, np.int64)
    root_rig_of_joint = {int(roots[c]): int(root_rig[c]) for c in range(C)}
    for c in range(C):
        rj = roots[c]
        in_c = live[comp_b[live] == c]
        med = float(np.median(L[in_c])) if len(in_c) else 0.0
        length = Rj[rj] if Rj[rj] > 10 * tol else (0.5 * med if med > 0 else max(0.05 * diag, 10 * tol, 1e-3))
        length = max(length, 10 * tol)
        r = root_rig[c]
        heads[r] = X[rj]
        tails[r] = X[rj] + up * length
        head_joint[r] = rj
    for b in chain_order:
        r = rig_of_bone[b]
        h, t_ = head[b], tail[b]
        heads[r], tails[r] = X[h], X[t_]
        head_joint[r], tail_joint[r] = h, t_
        br[r], pos[r] = branch[b], position[b]
        if is_root[h]:
            parent[r] = root_rig_of_joint[int(h)]
        else:
            parent[r] = rig_of_bone[in_tree[h]]
            connect[r] = True

    # -- blend partners ------------------------------------------------------------------------------
    def hub(j):
        return root_rig_of_joint[int(j)] if is_root[j] else int(rig_of_bone[in_tree[j]])

    incident = [[] for _ in range(J)]
    for b in live:
        incident[M[b, 0]].append(int(rig_of_bone[b]))
        incident[M[b, 1]].append(int(rig_of_bone[b]))
    head_mode = np.zeros(R, np.int64)
    tail_mode = np.zeros(R, np.int64)
    head_partner = np.full(R, -1, np.int64)
    tail_partner = np.full(R, -1, np.int64)
    for b in chain_order:
        r = int(rig_of_bone[b])
        for end, j in (("head", head[b]), ("tail", tail[b])):
            if deg[j] == 2 and not is_root[j]:
                other = [x for x in incident[j] if x != r]
                mode, partner = BLEND_SYMMETRIC, (other[0] if other else -1)
            elif deg[j] == 1 and not is_root[j]:
                mode, partner = BLEND_NONE, -1
            else:
                hb = hub(j)
                mode, partner = (BLEND_NONE, -1) if hb == r else (BLEND_HUB, hb)
            if partner < 0:
                mode = BLEND_NONE
            if end == "head":
                head_mode[r], head_partner[r] = mode, partner
            else:
                tail_mode[r], tail_partner[r] = mode, partner

    # -- skeleton bone -> rig bone -------------------------------------------------------------------
    bone_rig = rig_of_bone.copy()
    bone_reversed = np.zeros(B, bool)
    bone_reversed[live] = head[live] == M[live, 1]
    bone_s = np.full(B, np.nan)
    for b in np.flatnonzero(collapsed):
        j = M[b, 0]
        if is_root[j]:
            bone_rig[b], bone_s[b] = root_rig_of_joint[int(j)], 0.0
        else:
            bone_rig[b], bone_s[b] = rig_of_bone[in_tree[j]], 1.0

    # -- roll axes, parents first ------------------------------------------------------------------------
    d = _unit(tails - heads)
    z = np.zeros((R, 3))
    for r in range(R):
        if parent[r] < 0:
            ref = np.array([0.0, -1.0, 0.0]) if abs(up[2]) > 0.5 else np.array([0.0, 0.0, 1.0])
            z[r] = _perpendicular(d[r], ref)
        elif parent[r] in root_rig:
            z[r] = _perpendicular(d[r], up)
        else:
            z[r] = _transport(z[parent[r]], d[parent[r]], d[r])

    # -- names ---------------------------------------------------------------------------------------
    nb = max(len(starts), 1)
    wb = max(2, len(str(nb - 1)))
    wp = max(2, len(str(max(int(pos.max()), 0))))
    wc = max(2, len(str(C - 1)))
    names = []
    for r in range(R):
        if parent[r] < 0:
            names.append(f"root.{comp[r]:0{wc}d}")
        else:
            names.append(f"branch{br[r]:0{wb}d}.{pos[r]:0{wp}d}")

    return RigLayout(heads=heads, tails=tails, names=names, parent=parent, connect=connect, z_axis=z,
                     skeleton_bone=skel, head_joint=head_joint, tail_joint=tail_joint, branch=br,
                     position=pos, component=comp, roots=roots, bone_rig=bone_rig,
                     bone_reversed=bone_reversed, bone_s=bone_s, head_mode=head_mode,
                     tail_mode=tail_mode, head_partner=head_partner, tail_partner=tail_partner,
                     joint_map=jmap, meta={"merge_tol": tol, "merged_bones": int(collapsed.sum()),
                                           "branches": int(len(starts)), "parts": int(C)})
