"""The root joint of each connected part of a skeleton graph: its most central joint.

Used by the Blender layer to mark Skin-modifier roots (one per connected part, as the Skin
modifier needs) when ``rig_layout`` does not say otherwise.
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components, dijkstra

__all__ = ["central_joints"]


def central_joints(joints, bones) -> np.ndarray:
    """Index of the most central joint of every connected part of the skeleton graph.

    The centre minimises the largest bone-length distance to any joint of its part (the graph
    centre); ties go to the lower index. A part made of one joint is its own centre.

    Parameters
    ----------
    joints : (J, 3) or (J, 4) float
        Joint positions (a fourth column, the radius, is ignored).
    bones : (B, 2) int
        Joint indices of each bone.

    Returns
    -------
    (c,) int64
        One joint per connected part, in order of each part's lowest joint index.

    Examples
    --------
    >>> P = [[0, 0, 0], [1, 0, 0], [2, 0, 0], [3, 0, 0], [9, 0, 0]]
    >>> central_joints(P, [[0, 1], [1, 2], [2, 3]]).tolist()
    [1, 4]
    """
    P = np.asarray(joints, dtype=np.float64)
    if P.ndim != 2 or P.shape[1] < 3:
        raise ValueError(f"joints must have shape (J, 3) or (J, 4), got {P.shape}")
    E = np.asarray(bones, dtype=np.int64).reshape(-1, 2)
    J = len(P)
    if J == 0:
        return np.zeros(0, np.int64)
    # Zero-length bones still connect: give them a tiny positive weight (csgraph drops zeros).
    w = np.linalg.norm(P[E[:, 0], :3] - P[E[:, 1], :3], axis=1)
    w = np.maximum(w, 1e-12 * max(float(np.ptp(P[:, :3])), 1.0))
    G = coo_matrix((w, (E[:, 0], E[:, 1])), shape=(J, J)).tocsr()
    n_parts, label = connected_components(G, directed=False)
    roots = np.empty(n_parts, np.int64)
    for c in range(n_parts):
        ids = np.flatnonzero(label == c)
        if len(ids) == 1:
            roots[c] = ids[0]
            continue
        ecc = dijkstra(G, directed=False, indices=ids)[:, ids].max(axis=1)
        # Ties (within rounding, e.g. around a loop) go to the lowest joint index.
        roots[c] = ids[np.flatnonzero(ecc <= ecc.min() * (1.0 + 1e-9))[0]]
    # connected_components numbers parts by their lowest joint, so roots are already in that order.
    return roots
