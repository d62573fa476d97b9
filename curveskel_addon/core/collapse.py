"""Contracting zero-length bones at the end of a run.

Why: on shapes the fat curve fits exactly (a capsule) the optimum puts several chain joints on
the same point — E cannot tell them apart — and the skeleton carries bones of length zero.
An armature cannot hold them (Blender 4.2 deletes them) and a user sees joints that are not
there. Contracting them changes neither E nor the silhouette; we refuse a contraction that
would change the skeleton's topology (components or cycles).
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

__all__ = ["collapse_short_bones"]


def _betti(n_joints: int, bones: np.ndarray) -> tuple[int, int]:
    A = coo_matrix((np.ones(len(bones)), (bones[:, 0], bones[:, 1])), shape=(n_joints, n_joints))
    c, _ = connected_components(A, directed=False)
    return c, len(bones) - n_joints + c


def collapse_short_bones(joints, bones, bone, t, tol: float):
    """Merge the joints of every bone not longer than ``tol``.

    Parameters
    ----------
    joints : (J, 4) float
    bones : (B, 2) int
    bone, t : (n,) int, (n,) float
        Skeleton mapping (eq. 19 convention, t = 1 at a bone's first joint).
    tol : float or (B,) float
        Length at or below which a bone is contracted (one value per bone allowed).

    Returns
    -------
    joints, bones, bone, t
        The contracted skeleton and the remapped mapping (the inputs if nothing was short or
        the contraction would change the topology). Merged joints take the mean position and
        radius of their group; parallel bones created by the merge are kept once.

    Examples
    --------
    >>> J = np.array([[0, 0, 0, 1.], [0, 0, 0, 1.], [0, 0, 6, 1.]])
    >>> out = collapse_short_bones(J, np.array([[0, 1], [1, 2]]), np.array([0, 1]), np.array([.5, .5]), 1e-9)
    >>> out[1].tolist(), out[2].tolist()
    ([[0, 1]], [0, 0])
    """
    joints = np.asarray(joints, float)
    bones = np.asarray(bones, np.int64)
    L = np.linalg.norm(joints[bones[:, 0], :3] - joints[bones[:, 1], :3], axis=1)
    short = L <= tol
    if not short.any():
        return joints, bones, bone, t
    J = len(joints)
    A = coo_matrix((np.ones(int(short.sum())), (bones[short, 0], bones[short, 1])), shape=(J, J))
    n, lab = connected_components(A, directed=False)
    cnt = np.bincount(lab, minlength=n).astype(float)
    new_joints = np.stack([np.bincount(lab, weights=joints[:, k], minlength=n) / cnt for k in range(4)], 1)
    nb = lab[bones]
    alive = nb[:, 0] != nb[:, 1]
    key = np.sort(nb, axis=1)
    # One bone per unordered pair of merged joints (first occurrence).
    kk = key[:, 0] * n + key[:, 1]
    kk[~alive] = -1
    uniq, first = np.unique(kk[alive], return_index=True)
    alive_idx = np.flatnonzero(alive)
    kept_old = alive_idx[first]
    new_bones = nb[kept_old]
    if len(new_bones) == 0 or _betti(n, new_bones) != _betti(J, bones):
        return joints, bones, bone, t
    # Old bone -> new bone, and whether its direction is reversed.
    pos = np.full(len(bones), -1, np.int64)
    pos[alive] = np.searchsorted(uniq, kk[alive])
    flip = np.zeros(len(bones), bool)
    flip[alive] = nb[alive, 0] != new_bones[pos[alive], 0]
    # A contracted bone's vertices go to a bone at its merged joint, at that joint's end.
    inc_b = np.concatenate([np.arange(len(new_bones))] * 2)
    inc_j = np.concatenate([new_bones[:, 0], new_bones[:, 1]])
    at_first = np.concatenate([np.ones(len(new_bones), bool), np.zeros(len(new_bones), bool)])
    some = np.full(n, -1, np.int64)
    some_first = np.zeros(n, bool)
    some[inc_j[::-1]] = inc_b[::-1]
    some_first[inc_j[::-1]] = at_first[::-1]
    dead = np.flatnonzero(~alive)
    g = nb[dead, 0]
    if np.any(some[g] < 0):                 # a whole component would vanish into one joint
        return joints, bones, bone, t
    pos[dead] = some[g]
    bone = np.asarray(bone, np.int64)
    t = np.asarray(t, float)
    new_t = np.where(flip[bone], 1.0 - t, t)
    is_dead = ~alive[bone]
    new_t[is_dead] = np.where(some_first[lab[bones[bone[is_dead], 0]]], 1.0, 0.0)
    return new_joints, new_bones, pos[bone], new_t
