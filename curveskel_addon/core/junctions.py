"""Junctions moved onto their trunks (part of the polish stage).

Why: a limb branches off a body, it does not bend the body towards itself. The first
approximation places a junction at the centre of the contour where a limb's level sets join the
body's, which lies towards the limb (the armpit side), and the centring and the polish keep
junctions where they are: the body's chain then kinks sideways at every shoulder and hip
(armadillo's spine drawn diagonally between its two shoulders, spot's spine dipping to its hind
legs, elephant's hips). Here each junction moves onto the straight line of its trunk: the two of
its chains that belong to the body, told from the limb by their radii (a body is thicker than
what branches off it).

Each pair of a junction's neighbours proposes the closest point to the junction on the segment
between them; the junction goes to the mean of the proposals weighted by the smaller radius of
each pair to the power ``TRUNK_POWER``. A pair twice as thick as another outweighs it 256 to 1,
and equal pairs share (a mirror-symmetric pelvis, its two legs alike: the junction moves
straight down the middle), so no rounding of the radii can flip a choice (issue 12).

Examples
--------
>>> X = np.array([[-1., 0, 0], [0, 0.3, 0], [1, 0, 0], [0, 2, 0]])
>>> r = np.array([1.0, 1.0, 1.0, 0.3])
>>> onto_trunks(X, r, np.array([[0, 1], [1, 2], [1, 3]]))[1].round(3).tolist()
[0.0, 0.0, 0.0]
"""

from __future__ import annotations

import numpy as np

from .centreline import joint_adjacency

__all__ = ["onto_trunks", "TRUNK_POWER"]

#: The pairs' weights: (the smaller radius of the pair) ** TRUNK_POWER.
TRUNK_POWER = 8.0


def onto_trunks(X, r, bones, *, power=TRUNK_POWER):
    """Junction positions on their trunks (see the module docstring); other joints unchanged.

    Parameters
    ----------
    X : (J, 3) float
        Joint positions.
    r : (J,) float
        Joint radii (their size decides which chains are the trunk).
    bones : (B, 2) int
    power : float

    Returns
    -------
    (J, 3) float
        New positions: every joint of degree >= 3 moved to the weighted mean of its
        neighbour pairs' closest points; the others as given.
    """
    X = np.asarray(X, np.float64)[:, :3]
    r = np.abs(np.asarray(r, np.float64))
    bones = np.asarray(bones, np.int64).reshape(-1, 2)
    Y = X.copy()
    if not len(bones):
        return Y
    start, other, _ = joint_adjacency(len(X), bones)
    deg = np.diff(start)
    scale = float(r.max()) if len(r) and r.max() > 0 else 1.0
    for d in np.unique(deg[deg >= 3]):
        s = np.flatnonzero(deg == d)                          # junctions of this degree
        nb = other[start[s][:, None] + np.arange(d)]          # (k, d) neighbours
        i, j = np.triu_indices(d, 1)
        a, b = nb[:, i], nb[:, j]                             # (k, pairs)
        seg = X[b] - X[a]
        L2 = np.einsum("kpc,kpc->kp", seg, seg)
        t = np.einsum("kpc,kpc->kp", X[s][:, None, :] - X[a], seg)
        t = np.clip(np.divide(t, L2, out=np.zeros_like(t), where=L2 > 0), 0.0, 1.0)
        proposal = X[a] + t[..., None] * seg
        # radii relative to the largest: no underflow of r ** power whatever the units
        w = (np.minimum(r[a], r[b]) / scale) ** power
        total = w.sum(axis=1)
        ok = total > 0
        Y[s[ok]] = np.einsum("kp,kpc->kc", w[ok], proposal[ok]) / total[ok, None]
    return Y
