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

The armature's bones come from :func:`named_rig`: the layout's bones with readable names
(``root``, ``spine.01``, ``limbK.L.01`` / ``limbK.R.01``, ``chainK.01``), mirrored exactly about
the mesh's mirror plane (:func:`mirror_plane`) when it has one; see :func:`named_rig`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components, dijkstra
from scipy.spatial import cKDTree

from ..core.errors import CurveSkelError
from .graph_root import central_joints

__all__ = ["RigLayout", "rig_layout", "BLEND_NONE", "BLEND_SYMMETRIC", "BLEND_HUB", "MirrorPlane",
           "mirror_plane", "Rig", "named_rig"]

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


def _roll_axes(d, parent, up, from_root):
    """Each bone's z (roll) axis, parents first: a root bone's is perpendicular to it and to a
    fixed reference, a bone hanging from a root's is perpendicular to ``up``, any other the
    parent's transported along the bend (:func:`_transport`).

    Parameters
    ----------
    d : (R, 3) unit bone directions; parent : (R,) int, -1 for roots, parents before children
    up : (3,) float; from_root : (R,) bool, the bones whose parent is a root bone
    """
    R = len(d)
    z = np.zeros((R, 3))
    ref = np.array([0.0, -1.0, 0.0]) if abs(up[2]) > 0.5 else np.array([0.0, 0.0, 1.0])
    for r in range(R):
        if parent[r] < 0:
            z[r] = _perpendicular(d[r], ref)
        elif from_root[r]:
            z[r] = _perpendicular(d[r], up)
        else:
            z[r] = _transport(z[parent[r]], d[parent[r]], d[r])
    return z


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
    z = _roll_axes(_unit(tails - heads), parent, up, np.isin(parent, root_rig))

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


# == mirror plane and readable, mirrored names ========================================================
@dataclass
class MirrorPlane:
    """A plane ``normal . x = offset`` (unit normal) about which a mesh is symmetric.

    ``error``: mean distance of a mirrored vertex sample to the mesh's vertices, as a fraction of
    the bounding-box diagonal.
    """

    normal: np.ndarray
    offset: float
    error: float

    def signed_distance(self, P) -> np.ndarray:
        return np.asarray(P, dtype=np.float64) @ self.normal - self.offset

    def reflect(self, P) -> np.ndarray:
        """Mirror image of points (..., 3)."""
        P = np.asarray(P, dtype=np.float64)
        return P - 2.0 * self.signed_distance(P)[..., None] * self.normal

    def reflect_vector(self, v) -> np.ndarray:
        v = np.asarray(v, dtype=np.float64)
        return v - 2.0 * (v @ self.normal)[..., None] * self.normal


def mirror_plane(V, *, tol: float = 0.01, sample: int = 2000, seed: int = 0, all_planes: bool = False):
    """The mesh's best mirror plane, or None when no plane mirrors it within ``tol``.

    For naming bones (``.L``/``.R``): it prefers the object's local X axis, as Blender's X-Axis
    Mirror does. The method's own test of symmetry, which must not depend on the pose, is
    :func:`..core.initialise.pole.bilateral_plane`.

    Candidate normals are the three coordinate axes and the three principal axes of the vertices,
    through their centroid; each candidate is refined by matching every sampled vertex to the
    vertex nearest its mirror image (a few rounds: the normal is the main direction of
    ``p - match``, the offset the mean of ``(p + match) / 2`` along it). A plane whose normal is
    within 1 degree of a coordinate axis is snapped onto that axis. Among planes whose error is
    within 25 % of the best (or below ``tol / 5``), a normal along local x is preferred
    (Blender's X-Axis Mirror), then the lower error.

    Parameters
    ----------
    V : (n, 3) float
        Vertex positions.
    tol : float
        Largest accepted error: mean distance of mirrored vertices to the mesh's vertices, as a
        fraction of the bounding-box diagonal.
    sample : int
        Vertices used (a seeded random subset above this many).
    all_planes : bool
        Return every accepted (distinct) plane, best first, instead of the best one.

    Returns
    -------
    MirrorPlane or None (a list of MirrorPlane with ``all_planes``)
    """
    P = np.asarray(V, dtype=np.float64).reshape(-1, 3)
    diag = float(np.linalg.norm(np.ptp(P, axis=0))) if len(P) else 0.0
    if len(P) < 4 or diag <= 0:
        return [] if all_planes else None
    tree = cKDTree(P)
    rng = np.random.default_rng(seed)
    S = P if len(P) <= sample else P[rng.choice(len(P), sample, replace=False)]
    c = S.mean(axis=0)
    _, _, vt = np.linalg.svd(S - c, full_matrices=False)
    cands = [np.eye(3)[k] for k in range(3)] + [vt[k] for k in range(3)]
    found = []
    for n in cands:
        n = n / np.linalg.norm(n)
        d = float(c @ n)
        for _ in range(3):
            R = S - 2.0 * (S @ n - d)[:, None] * n
            _, nn = tree.query(R)
            Q = P[nn]
            D = S - Q
            M = D.T @ D
            if np.trace(M) <= 1e-20 * diag * diag:
                break
            w, v = np.linalg.eigh(M)
            n_new = v[:, -1] * (1.0 if v[:, -1] @ n >= 0 else -1.0)
            if n_new @ n < 0.9:          # not converging to this plane
                break
            n = n_new
            d = float(np.mean((S + Q) @ n) / 2.0)
        ax = int(np.argmax(np.abs(n)))
        if abs(n[ax]) > np.cos(np.radians(1.0)):
            n = np.sign(n[ax]) * np.eye(3)[ax]
            R = S - 2.0 * (S @ n - c @ n)[:, None] * n
            _, nn = tree.query(R)
            d = float(np.mean((S + P[nn]) @ n) / 2.0)
        if n[int(np.argmax(np.abs(n)))] < 0:
            n = -n
            d = -d
        R = S - 2.0 * (S @ n - d)[:, None] * n
        err = float(np.mean(tree.query(R)[0])) / diag
        found.append(MirrorPlane(n, d, err))
    best = min(p.error for p in found)
    if best > tol:
        return [] if all_planes else None
    near = [p for p in found if p.error <= max(1.25 * best, 0.2 * tol)]
    near.sort(key=lambda p: (-int(abs(p.normal[0]) > 0.999), p.error))
    if not all_planes:
        return near[0]
    out = []
    for p in near:          # distinct planes only
        if not any(abs(p.normal @ q.normal) > 0.999 and abs(p.offset - q.offset) < 1e-3 * diag for q in out):
            out.append(p)
    return out


@dataclass
class Rig:
    """Bones to create, in order (parents first), with readable, mirror-aware names.

    Attributes
    ----------
    heads, tails, z_axis : (R, 3) float
    names : list of str
    parent : (R,) int, -1 for root bones
    connect : (R,) bool
    chain : (R,) int
        Chain of each bone (-1 for root bones).
    side : (R,) str
        "L", "R" or "" (on the plane, unpaired, or no plane).
    mirror : (R,) int
        The mirrored bone of each bone (itself on the plane, -1 when it has none).
    plane : MirrorPlane or None
    """

    heads: np.ndarray
    tails: np.ndarray
    z_axis: np.ndarray
    names: list
    parent: np.ndarray
    connect: np.ndarray
    chain: np.ndarray
    side: np.ndarray
    mirror: np.ndarray
    plane: MirrorPlane | None = None
    meta: dict = field(default_factory=dict)

    @property
    def n_bones(self) -> int:
        return len(self.heads)


def _resample(pts, m):
    """``m + 1`` points at equal arc-length fractions along the polyline ``pts``."""
    pts = np.asarray(pts, dtype=np.float64)
    if len(pts) == m + 1:
        return pts.copy()
    s = _arc_lengths(pts)
    if s[-1] <= 0:
        return np.repeat(pts[:1], m + 1, axis=0)
    return _at_lengths(pts, s, np.linspace(0.0, s[-1], m + 1))


def _arc_lengths(pts):
    """(k,) the arc length from the first point to each point of the polyline ``pts``."""
    return np.r_[0.0, np.cumsum(np.linalg.norm(np.diff(pts, axis=0), axis=1))]


def _at_lengths(pts, s, u):
    """The points at arc lengths ``u`` along the polyline ``pts`` (its arc lengths ``s``)."""
    return np.stack([np.interp(u, s, pts[:, k]) for k in range(3)], 1)


def _chain_distance(A, B):
    """Mean distance between two polylines resampled at equal arc-length fractions."""
    m = 16
    return float(np.mean(np.linalg.norm(_resample(A, m) - _resample(B, m), axis=1)))


#: Two limbs pair only if the longer is at most this many times the shorter.
LIMB_RATIO = 1.5


def _tip_distance(A, B):
    """Mean distance between two polylines from their last points back over the shorter one's
    length (points at equal arc lengths from the tips)."""
    m = 16
    A, B = np.asarray(A, np.float64)[::-1], np.asarray(B, np.float64)[::-1]
    sa, sb = _arc_lengths(A), _arc_lengths(B)
    u = np.linspace(0.0, min(sa[-1], sb[-1]), m + 1)
    return float(np.mean(np.linalg.norm(_at_lengths(A, sa, u) - _at_lengths(B, sb, u), axis=1)))


def named_rig(lay: RigLayout, plane: MirrorPlane | None = None, *, pair_tol: float = 0.1,
              central_tol: float = 0.05, up=(0.0, 0.0, 1.0)) -> Rig:
    """The bones of ``lay`` with readable names, mirrored exactly about ``plane`` when given.

    Naming scheme
    -------------
    - ``root`` (``root.NN`` for part NN when the skeleton has several parts): the root bones.
    - A *chain* is a run of bones between junctions (``RigLayout.branch``). Position along a
      chain from its root end: ``.01``, ``.02``, ...
    - With a plane: two chains on opposite sides whose mirror images match (mean distance below
      ``pair_tol`` of the chain's length, plus a few percent of the skeleton's size; two chains
      ending in tips, lengths within ``LIMB_RATIO``, also compared from their tips) are a pair,
      ``limbK.L.PP`` and ``limbK.R.PP`` (``.L`` on the plane normal's positive side; Blender flips
      ``.L``/``.R`` before a ``.NN`` number, so X-Axis Mirror and pose flipping find the pair).
      Unpaired chains whose joints all lie within ``central_tol`` of the diagonal from the plane
      are ``spineK.PP``; other unpaired chains ``chainK.PP``.
    - Without a plane every chain is ``chainK.PP``.
    - ``K`` counts chains of that kind from 1 in breadth-first order from the root, and is left out
      when there is only one (``spine.01``).

    Exact mirroring
    ---------------
    Central chains and the root joints are projected onto the plane (the root bones point along
    ``up`` projected onto it). A pair's chains are resampled to the same number of bones (the
    larger) at equal arc-length fractions and replaced by their mirrored mean, so the two are
    exact mirror images, rolls included. A chain keeps its head on its parent's tail when that
    point is still where its head belongs (same for both chains of a pair); otherwise its head
    moves to the mirrored position and the bone is not connected (``use_connect`` False).

    Parameters
    ----------
    lay : RigLayout
    plane : MirrorPlane, optional
    pair_tol, central_tol : float
    up : (3,) float
        Direction of the root bones.

    Returns
    -------
    Rig
    """
    R0 = lay.n_bones
    X = np.concatenate([lay.heads, lay.tails])
    diag = float(np.linalg.norm(np.ptp(X, axis=0))) if len(X) > 1 else 1.0
    diag = max(diag, 1e-12)
    up = _unit(np.asarray(up, dtype=np.float64).reshape(3))
    root_bones = [r for r in range(R0) if lay.parent[r] < 0]
    # chains in order of their first bone (parents before children)
    chains: dict[int, list[int]] = {}
    for r in range(R0):
        if lay.parent[r] >= 0:
            chains.setdefault(int(lay.branch[r]), []).append(r)
    order = sorted(chains, key=lambda c: chains[c][0])
    for c in order:
        chains[c].sort(key=lambda r: lay.position[r])
    pts = {c: np.vstack([lay.heads[chains[c][0]][None], lay.tails[chains[c]]]) for c in order}
    chain_of = np.full(R0, -1, np.int64)
    for c in order:
        chain_of[chains[c]] = c
    parent_chain = {c: int(chain_of[lay.parent[chains[c][0]]]) for c in order}   # -1: under a root
    has_child = np.zeros(R0, bool)
    has_child[lay.parent[lay.parent >= 0]] = True
    limb_end = {c: not has_child[chains[c][-1]] for c in order}     # the chain ends in a tip

    kind = {c: "chain" for c in order}
    partner: dict[int, int] = {}
    side = {c: "" for c in order}
    if plane is not None:
        sd = {c: plane.signed_distance(pts[c][1:]) for c in order}
        near_plane = {c: bool(np.abs(sd[c]).max() <= central_tol * diag) for c in order}
        near_plane[-1] = True                                  # the root joints
        length = {c: float(np.sum(np.linalg.norm(np.diff(pts[c], axis=0), axis=1))) for c in order}
        def pair_cost(a, b):
            ma, mb = float(np.mean(sd[a])), float(np.mean(sd[b]))
            if ma * mb >= 0:
                return None
            pa, pb = parent_chain[a], parent_chain[b]
            # a pair's parents are themselves a pair, the same chain, or both near the plane;
            # otherwise (a skeleton whose branching differs left and right) only a close match
            kin = pa == pb or partner.get(pa) == pb or (near_plane[pa] and near_plane[pb]
                                                        and pa not in partner and pb not in partner)
            cost = _chain_distance(pts[a], plane.reflect(pts[b]))
            if limb_end[a] and limb_end[b] and (max(length[a], length[b])
                                                <= LIMB_RATIO * min(length[a], length[b])):
                # two limbs also from their tips: where they branch off may differ left and
                # right (a T whose head chain meets one arm has that arm's junction out along
                # it, 0.7 from where the other arm's is)
                cost = min(cost, _tip_distance(pts[a], plane.reflect(pts[b])))
            limit = (pair_tol * max(length[a], length[b]) + 0.02 * diag) * (1.0 if kin else 0.75)
            # the chains must lie mostly off the plane (else both are central)
            if cost < limit and min(abs(ma), abs(mb)) > 0.5 * cost:
                return cost
            return None

        # parents first, so that children of a pair can pair in turn
        for a in order:
            if a in partner:
                continue
            best = None
            for b in order:
                if b == a or b in partner:
                    continue
                cost = pair_cost(a, b)
                if cost is not None and (best is None or cost < best[0]):
                    best = (cost, b)
            if best is not None:
                partner[a], partner[best[1]] = best[1], a
        for c in order:
            if c in partner:
                kind[c] = "limb"
                side[c] = "L" if np.mean(sd[c]) > 0 else "R"
            elif near_plane[c]:
                kind[c] = "spine"

    # -- new points per chain (parents first) ---------------------------------------------------------
    new_pts: dict[int, np.ndarray] = {}
    head_ok: dict[int, bool] = {}
    root_head = {r: lay.heads[r].copy() for r in root_bones}
    root_up = {r: up.copy() for r in root_bones}
    if plane is not None:
        for r in root_bones:
            if abs(plane.signed_distance(lay.heads[r])) <= central_tol * diag:
                root_head[r] = plane.reflect(lay.heads[r]) * 0.5 + lay.heads[r] * 0.5
                u = plane.reflect_vector(up) * 0.5 + up * 0.5
                root_up[r] = _unit(u) if np.linalg.norm(u) > 1e-6 else up

    def anchor(c):
        """Where chain c's head belongs now: its parent chain's new end, or its root's head."""
        p = parent_chain[c]
        first = chains[c][0]
        if p < 0:
            return root_head[int(lay.parent[first])]
        return new_pts[p][-1]

    for c in order:
        if c in new_pts:
            continue
        P = pts[c].copy()
        if kind[c] == "spine":
            P = 0.5 * (P + plane.reflect(P))
            new_pts[c] = P
        elif kind[c] == "limb":
            d = partner[c]
            m = max(len(pts[c]), len(pts[d])) - 1
            A, Bm = _resample(pts[c], m), plane.reflect(_resample(pts[d], m))
            mean = 0.5 * (A + Bm)
            new_pts[c], new_pts[d] = mean, plane.reflect(mean)
        else:
            new_pts[c] = P
    for c in order:
        # re-attach heads: connected where the (new) anchor is where the head belongs
        a = anchor(c)
        h = new_pts[c][0]
        tol = max(1e-6 * diag, 1e-9)
        if kind[c] == "limb":
            d = partner[c]
            ad = anchor(d)
            ok = np.linalg.norm(plane.reflect(a) - ad) < tol and np.linalg.norm(a - h) < 0.05 * diag
        elif kind[c] == "spine":
            ok = abs(plane.signed_distance(a)) < tol and np.linalg.norm(a - h) < 0.05 * diag
        else:
            ok = np.linalg.norm(a - lay.heads[chains[c][0]]) < 0.05 * diag
        if kind[c] == "chain" or ok:
            new_pts[c][0] = a
        head_ok[c] = bool(np.linalg.norm(new_pts[c][0] - a) < tol)

    # -- names -------------------------------------------------------------------------------------------
    counts = {"spine": 0, "limb": 0, "chain": 0}
    number = {}
    for c in order:
        if kind[c] == "limb" and partner[c] in number:
            number[c] = number[partner[c]]
            continue
        counts[kind[c]] += 1
        number[c] = counts[kind[c]]

    def chain_name(c):
        k = kind[c]
        base = k if counts[k] == 1 else f"{k}{number[c]}"
        return f"{base}.{side[c]}" if side[c] else base

    # -- bones -----------------------------------------------------------------------------------------
    heads, tails, names, parent, connect, chain_arr, side_arr = [], [], [], [], [], [], []
    new_root = {}
    C = len(root_bones)
    for k, r in enumerate(root_bones):
        L = float(np.linalg.norm(lay.tails[r] - lay.heads[r]))
        new_root[r] = len(heads)
        heads.append(root_head[r])
        tails.append(root_head[r] + root_up[r] * L)
        names.append("root" if C == 1 else f"root.{k:02d}")
        parent.append(-1)
        connect.append(False)
        chain_arr.append(-1)
        side_arr.append("")
    last_bone = {}
    first_bone = {}
    # creation order: parents first (chains are ordered so)
    for c in order:
        P = new_pts[c]
        p = parent_chain[c]
        par = new_root[int(lay.parent[chains[c][0]])] if p < 0 else last_bone[p]
        wp = max(2, len(str(len(P) - 1)))
        for k in range(len(P) - 1):
            if k == 0:
                first_bone[c] = len(heads)
            heads.append(P[k])
            tails.append(P[k + 1])
            names.append(f"{chain_name(c)}.{k + 1:0{wp}d}")
            parent.append(par)
            connect.append(bool(k > 0 or (p >= 0 and head_ok[c])))
            chain_arr.append(c)
            side_arr.append(side[c])
            par = len(heads) - 1
        last_bone[c] = len(heads) - 1
    heads = np.array(heads)
    tails = np.array(tails)
    parent = np.array(parent, np.int64)
    R = len(heads)
    # zero-length bones (a resampled or re-attached chain): nudge the tail along the chain
    d = tails - heads
    Ld = np.linalg.norm(d, axis=1)
    tiny = Ld < max(1e-6 * diag, 1e-5)
    if tiny.any():
        tails[tiny] = heads[tiny] + up * max(1e-4 * diag, 1e-4)

    # -- rolls: transported from the parent; the right side mirrors the left --------------------------
    dd = _unit(tails - heads)
    z = _roll_axes(dd, parent, up, (parent >= 0) & (parent < C))
    mirror = np.full(R, -1, np.int64)
    if plane is not None:
        for r in range(C):
            if abs(plane.signed_distance(heads[r])) < 1e-9 * diag + 1e-12:
                mirror[r] = r
        for c in order:
            rows = np.arange(first_bone[c], last_bone[c] + 1)
            if kind[c] == "spine":
                mirror[rows] = rows
            elif kind[c] == "limb":
                d_ = partner[c]
                mirror[rows] = np.arange(first_bone[d_], last_bone[d_] + 1)
                if side[c] == "R":
                    # Blender mirrors a bone's frame as (-Sx, Sy, Sz): its z-axis is reflected
                    z[rows] = plane.reflect_vector(z[mirror[rows]])
    return Rig(heads=heads, tails=tails, z_axis=z, names=names, parent=parent,
               connect=np.array(connect, bool), chain=np.array(chain_arr, np.int64),
               side=np.array(side_arr, dtype=object), mirror=mirror, plane=plane,
               meta={"pairs": len(partner) // 2, "central": sum(kind[c] == "spine" for c in order),
                     "chains": len(order)})
