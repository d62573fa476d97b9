"""An armature's bones as a curve-skeleton's segments, and back (issue 33).

An armature is a forest of bones, each a head and a tail; a curve-skeleton is joints and the
bones between them. The conversion, as the issue states it:

* every bone is a segment from its head to its tail;
* a bone connected to its parent starts at the parent's tail: they share that joint;
* a child *not* connected to its parent is joined to the parent's tail by one more segment (a
  link: the skeleton stays one piece, as the rig is);
* points that coincide (within ``tolerance`` of the armature's size) are one joint: siblings
  that start at one place share it, and a link of no length is no segment; a segment that
  repeats another (a link running back along its parent) is kept once.

Positions and the result of a refinement go back to the bones through ``head`` and ``tail``:
each bone's head and tail joint. Pure NumPy: the Blender layer reads the bones' heads and tails
in world space and writes them back.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

# the roll rule of curveskel's own armatures (a private helper of the layout: one rule, one place)
from .rig_layout import _roll_axes

__all__ = ["ArmatureSegments", "armature_segments", "bone_roll_axes", "COINCIDENT"]

#: Points closer than this share of the armature's extent are one joint (a head placed on a
#: tail by snapping, or typed, agrees to far better than this; two joints a rigger means apart
#: are farther).
COINCIDENT = 1e-6


@dataclass(frozen=True)
class ArmatureSegments:
    """An armature as joints and segments.

    Attributes
    ----------
    joints : (J, 3) float
    segments : (S, 2) int
        Joint pairs; the first ones are bones' own, then the links.
    head, tail : (nb,) int
        Each bone's head and tail joint.
    segment_of_bone : (nb,) int
        Each bone's own segment, or -1 for a bone of no length.
    """

    joints: np.ndarray
    segments: np.ndarray
    head: np.ndarray
    tail: np.ndarray
    segment_of_bone: np.ndarray

    def fixed_joints(self, bone_mask) -> np.ndarray:
        """(J,) bool: the head and tail joints of the bones in ``bone_mask``."""
        out = np.zeros(len(self.joints), bool)
        m = np.asarray(bone_mask, bool)
        out[self.head[m]] = True
        out[self.tail[m]] = True
        return out

    def bone_ends(self, joints) -> tuple[np.ndarray, np.ndarray]:
        """Heads (nb, 3) and tails (nb, 3) of the bones for joint positions ``joints``."""
        X = np.asarray(joints, np.float64)[:, :3]
        return X[self.head], X[self.tail]


def armature_segments(heads, tails, parent, connected, *, tolerance=COINCIDENT) -> ArmatureSegments:
    """Joints and segments of an armature (module doc).

    Parameters
    ----------
    heads, tails : (nb, 3) float
        In one space (world space, for evaluating against a mesh).
    parent : (nb,) int
        Each bone's parent bone, -1 for a root.
    connected : (nb,) bool
        Whether the bone's head is its parent's tail (Blender's *Connected*).
    tolerance : float
        Share of the armature's extent within which points are one joint.

    Returns
    -------
    ArmatureSegments

    Examples
    --------
    >>> heads = np.array([[0., 0, 0], [0, 0, 1], [0, 0, 1]])
    >>> tails = np.array([[0., 0, 1], [0, 1, 2], [0, -1, 2]])
    >>> s = armature_segments(heads, tails, [-1, 0, 0], [False, True, False])
    >>> len(s.joints), s.segments.tolist()
    (4, [[0, 1], [1, 2], [1, 3]])
    """
    H = np.asarray(heads, np.float64).reshape(-1, 3)
    T = np.asarray(tails, np.float64).reshape(-1, 3)
    par = np.asarray(parent, np.int64).ravel()
    con = np.asarray(connected, bool).ravel()
    nb = len(H)
    # candidate points: every head, then every tail; a connected bone's head is its parent's tail
    P = np.concatenate([H, T])
    owner = np.arange(2 * nb)
    child = np.flatnonzero(con & (par >= 0))
    owner[child] = nb + par[child]
    size = float(np.ptp(P, axis=0).max()) if len(P) else 0.0
    # coincident points are one joint: label each point with the smallest index near it
    tree = cKDTree(P)
    pairs = tree.query_pairs(max(tolerance * size, 0.0), output_type="ndarray")
    E = np.concatenate([pairs.reshape(-1, 2), np.stack([np.arange(2 * nb), owner], 1)])
    _, label = connected_components(coo_matrix((np.ones(len(E)), (E[:, 0], E[:, 1])),
                                               shape=(2 * nb, 2 * nb)), directed=False)
    # each joint where its group's first point is (coincident points: any would do)
    first = np.full(label.max(initial=-1) + 1, 2 * nb)
    np.minimum.at(first, label, np.arange(2 * nb))
    head, tail = label[:nb], label[nb:]
    X = P[first]
    link = np.flatnonzero(~con & (par >= 0))
    seg = np.concatenate([np.stack([head, tail], 1), np.stack([tail[par[link]], head[link]], 1)])
    own = np.concatenate([np.arange(nb), np.full(len(link), -1)])
    ok = seg[:, 0] != seg[:, 1]
    seg, own = seg[ok], own[ok]
    _, first = np.unique(np.sort(seg, axis=1), axis=0, return_index=True)
    first = np.sort(first)                       # the first of repeated segments: a bone's own
    seg, own = seg[first], own[first]
    segment_of_bone = np.full(nb, -1, np.int64)
    segment_of_bone[own[own >= 0]] = np.flatnonzero(own >= 0)
    return ArmatureSegments(X, seg, head, tail, segment_of_bone)



def bone_roll_axes(heads, tails, parent, up) -> np.ndarray:
    """(nb, 3) each bone's roll (z) axis by the rule curveskel's own armatures follow
    (:func:`.rig_layout._roll_axes`): a root bone's perpendicular to it and to a fixed
    reference, a bone hanging from a root's perpendicular to ``up``, any other its parent's
    carried along the bend. For Blender's ``EditBone.align_roll``.

    Parameters
    ----------
    heads, tails : (nb, 3) float
        In the armature's space.
    parent : (nb,) int
        -1 for a root; any order (parents are taken first).
    up : (3,) float
        World up in the armature's space.
    """
    H = np.asarray(heads, np.float64).reshape(-1, 3)
    T = np.asarray(tails, np.float64).reshape(-1, 3)
    par = np.asarray(parent, np.int64).ravel()
    nb = len(H)
    depth = np.zeros(nb, np.int64)
    for b in range(nb):                      # a rig's depth is small; bones, not vertices
        p, n = par[b], 0
        while p >= 0 and n <= nb:
            p, n = par[p], n + 1
        depth[b] = n
    order = np.argsort(depth, kind="stable")           # parents before children
    rank = np.empty(nb, np.int64)
    rank[order] = np.arange(nb)
    par_sorted = np.where(par[order] >= 0, rank[np.maximum(par[order], 0)], -1)
    d = T[order] - H[order]
    d = d / np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-300)
    from_root = (par_sorted >= 0) & (par[np.maximum(par[order], 0)] < 0)
    z = _roll_axes(d, par_sorted, np.asarray(up, np.float64), from_root)
    out = np.empty_like(z)
    out[order] = z
    return out
