"""Re-fitting the skeleton mapping sigma between solver steps (paper, section 6, future work 1).

Why: the paper keeps sigma (each vertex's bone and t) fixed at the first approximation's
contour-line mapping, so a joint that moves keeps "owning" vertices that are now closer to a
neighbouring bone, and the optimum of E is an optimum for a poor mapping. Between solver steps
we move each vertex to the closest point of the bones *near its current bone* (its own bone and
the bones sharing a joint with it), so a vertex migrates at most one bone per re-fit and the
topology of the mapping follows the skeleton continuously.

Which point is chosen, and why E never increases
-------------------------------------------------
The candidate is the **closest point** (Euclidean projection, ``t`` clamped to [0, 1], eq. 19
convention ``t = 1`` at joint ``i``), not the argmin of the vertex's energy term: minimising
``e_v^2`` over the bones would let a vertex slide to wherever some swept sphere happens to pass
through it, which is the silhouette-distance measure the paper rejects (its Fig. 2). The closest
point is then accepted **per vertex only when it strictly lowers that vertex's term**
``w_v e_v^2``; otherwise the vertex keeps its current (bone, t). E is a sum of these terms, so a
re-fit never raises E, and every change lowers it (so re-fits cannot cycle).

The projection is implemented here (vectorised, one pass per candidate slot) so this module does
not depend on :mod:`.mapping`.
"""

from __future__ import annotations

import numpy as np

from .energy import sigma_terms
from .problem import FitProblem

__all__ = ["bone_neighbours", "project_on_bones", "refit_mapping"]


def bone_neighbours(bones: np.ndarray, n_joints: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """For each bone: itself, then every other bone sharing a joint with it.

    Parameters
    ----------
    bones : (B, 2) int
    n_joints : int, optional

    Returns
    -------
    table : (B, K) int
        Row ``b`` starts with ``b``; padded with ``b`` after ``count[b]`` entries.
    count : (B,) int
        Number of distinct candidates of each bone (>= 1).

    Examples
    --------
    >>> import numpy as np
    >>> table, count = bone_neighbours(np.array([[0, 1], [1, 2], [2, 3]]))
    >>> table.tolist(), count.tolist()
    ([[0, 1, 0], [1, 0, 2], [2, 1, 2]], [2, 3, 2])
    """
    bones = np.asarray(bones, dtype=np.int64).reshape(-1, 2)
    B = len(bones)
    if B == 0:
        return np.zeros((0, 1), np.int64), np.zeros(0, np.int64)
    nj = int(bones.max()) + 1 if n_joints is None else int(n_joints)
    incident: list[list[int]] = [[] for _ in range(nj)]
    for b, (i, j) in enumerate(bones.tolist()):
        incident[i].append(b)
        if j != i:
            incident[j].append(b)
    rows = []
    for b, (i, j) in enumerate(bones.tolist()):
        seen = dict.fromkeys([b] + incident[i] + incident[j])
        rows.append(list(seen))
    count = np.array([len(r) for r in rows], np.int64)
    table = np.empty((B, int(count.max())), np.int64)
    for b, r in enumerate(rows):
        table[b, :len(r)] = r
        table[b, len(r):] = b
    return table, count


def project_on_bones(points: np.ndarray, joints: np.ndarray, bones: np.ndarray,
                     bone_ids: np.ndarray, rows: np.ndarray | None = None
                     ) -> tuple[np.ndarray, np.ndarray]:
    """Closest point of bone ``bone_ids[k]`` to point ``points[rows[k]]`` (or ``points[k]``).

    Parameters
    ----------
    points : (n, 3) float
    joints : (J, 4) float
    bones : (B, 2) int
    bone_ids : (m,) int
    rows : (m,) int, optional
        Which points (default: all, ``m == n``).

    Returns
    -------
    t : (m,) float
        Clamped to [0, 1]; ``sigma = t x_i + (1 - t) x_j``. 0.5 on a zero-length bone.
    dist2 : (m,) float
        Squared distance to that closest point.

    Examples
    --------
    >>> import numpy as np
    >>> J = np.array([[0, 0, 2.0, 1], [0, 0, 0.0, 1]])
    >>> project_on_bones(np.array([[1, 0, 1.5], [0, 0, 3.0]]), J, np.array([[0, 1]]), np.array([0, 0]))
    (array([0.75, 1.  ]), array([1., 1.]))
    """
    X = joints[:, :3]
    xj = X[bones[:, 1]]
    u = X[bones[:, 0]] - xj
    uu = np.einsum("ij,ij->i", u, u)
    inv = np.divide(1.0, uu, out=np.zeros_like(uu), where=uu > 0)
    xj, u = np.ascontiguousarray(xj.T), np.ascontiguousarray(u.T)     # (3, B): 1-D takes
    m = len(bone_ids)
    a, ub = np.empty((3, m)), np.empty((3, m))
    for c in range(3):
        pc = points[:, c] if rows is None else np.take(points[:, c], rows)
        np.subtract(pc, np.take(xj[c], bone_ids), out=a[c])
        ub[c] = np.take(u[c], bone_ids)
    t = a[0] * ub[0] + a[1] * ub[1] + a[2] * ub[2]
    t *= np.take(inv, bone_ids)
    np.clip(t, 0.0, 1.0, out=t)
    if np.any(uu == 0):
        t[np.take(uu, bone_ids) == 0] = 0.5
    a -= t * ub
    return t, a[0] * a[0] + a[1] * a[1] + a[2] * a[2]


def refit_mapping(pr: FitProblem, neighbours: tuple[np.ndarray, np.ndarray] | None = None,
                  e_old: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """Move each vertex to the closest point of its bone's neighbourhood where that lowers E.

    Parameters
    ----------
    pr : FitProblem
        Current joints and mapping (not modified).
    neighbours : (table, count), optional
        :func:`bone_neighbours` of ``pr.bones`` (pass it to avoid rebuilding it every call).
    e_old : (n,) float, optional
        Current residuals, if already known.

    Returns
    -------
    bone : (n,) int
    t : (n,) float
        The new mapping (new arrays; vertices that did not change keep their old values).
    e : (n,) float
        Residuals under the new mapping (``E = sum w e^2`` never exceeds the old E).
    changed : int
        Number of vertices whose mapping changed.

    Examples
    --------
    >>> import numpy as np
    >>> from curveskel_addon.core.problem import FitProblem
    >>> J = np.array([[0, 0, 0, 1.0], [0, 0, 1, 1.0], [0, 0, 2, 1.0]])
    >>> pr = FitProblem(np.array([[1.0, 0, 1.5]]), np.ones(1), J, np.array([[0, 1], [1, 2]]),
    ...                 np.array([0]), np.array([0.9]))     # mapped to the wrong bone
    >>> bone, t, e, changed = refit_mapping(pr)
    >>> bone.tolist(), t.tolist(), e.tolist(), changed
    ([1], [0.5], [0.0], 1)
    """
    table, count = bone_neighbours(pr.bones, len(pr.joints)) if neighbours is None else neighbours
    if e_old is None:
        e_old = sigma_terms(pr)[2]
    P, bone = pr.points, pr.bone
    n = len(bone)
    best_b = bone.copy()
    best_t, best_d2 = project_on_bones(P, pr.joints, pr.bones, bone)
    if table.shape[1] > 1:
        c = np.take(count, bone)
        for k in range(1, table.shape[1]):
            cb = np.take(table[:, k], bone)       # padded with the own bone: never strictly closer
            sub = np.flatnonzero(c > k)           # points whose bone has a k-th candidate
            if len(sub) == 0:
                break
            if 2 * len(sub) > n:                  # most points: a full pass, no row gathers
                tk, d2k = project_on_bones(P, pr.joints, pr.bones, cb)
                better = d2k < best_d2
                np.copyto(best_b, cb, where=better)
                np.copyto(best_t, tk, where=better)
                np.copyto(best_d2, d2k, where=better)
            else:
                cb = cb[sub]
                tk, d2k = project_on_bones(P, pr.joints, pr.bones, cb, rows=sub)
                better = d2k < best_d2[sub]
                sb = sub[better]
                best_b[sb], best_t[sb], best_d2[sb] = cb[better], tk[better], d2k[better]
    # e = |v - sigma|^2 - rho^2 with |v - sigma|^2 = best_d2 already known: only rho is needed.
    r = pr.joints[:, 3]
    rj = r[pr.bones[:, 1]]
    rho = np.take(rj, best_b) + best_t * np.take(r[pr.bones[:, 0]] - rj, best_b)
    e_new = best_d2 - rho * rho
    take = np.abs(e_new) < np.abs(e_old)
    new_bone = np.where(take, best_b, bone)
    new_t = np.where(take, best_t, pr.t)
    changed = int(np.count_nonzero(take & ((new_bone != bone) | (new_t != pr.t))))
    return new_bone, new_t, np.where(take, e_new, e_old), changed
