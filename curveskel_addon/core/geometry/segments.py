"""The skeleton mapping sigma: each point's bone and its parameter t on it (paper eqs. 18-19).

The paper derives sigma from the contour a vertex lies on (eq. 13). We map each vertex to the
closest point of a short list of *candidate* bones: the bones of the Reeb region it lies in
(see :mod:`reeb`). Restricting to the region keeps sigma consistent with the topology (a vertex
of one finger never maps onto the neighbouring finger's bone, however close it is in space),
while taking the closest point on those bones, rather than the contour's joint itself, gives a
continuous t along each bone, which the optimiser needs (eq. 20 is then exact for a cylinder).

The same function re-fits sigma for the solvers (``candidates=None``: every bone, in chunks).

Convention (eq. 19): sigma = t * x_i + (1 - t) * x_j for bone (i, j): t = 1 at joint i and
t = 0 at joint j.
"""

from __future__ import annotations

import numpy as np

from ..config import CONFIG
from ..errors import CurveSkelError
from .rows import col_max, col_min, mul_rows, take_rows

__all__ = ["closest_on_bones", "closest_bone", "nearest_on_silhouette"]

_NUM = CONFIG.numerics


def _pair_closest(points, xi, xj):
    """t (eq. 19) and squared distance of each point to the segment [xj, xi] (row-wise)."""
    d = xi - xj
    w = points - xj
    dd = np.einsum("ij,ij->i", d, d)
    num = np.einsum("ij,ij->i", w, d)
    t = np.divide(num, dd, out=np.zeros_like(num), where=dd > 0)
    np.clip(t, 0.0, 1.0, out=t)
    diff = w - mul_rows(t, d)
    return t, np.einsum("ij,ij->i", diff, diff)


def _on_bones(points, X, bones, pb):
    """:func:`_pair_closest` of each point to its bone ``pb`` (gathers by ``take``: the same
    values, 2-3x faster than fancy indexing)."""
    return _pair_closest(points, take_rows(X[bones[:, 0]], pb), take_rows(X[bones[:, 1]], pb))


def closest_on_bones(points, joints, bones, candidates=None):
    """Closest point of each point on its candidate bones.

    Parameters
    ----------
    points : (n, 3) float
    joints : (J, 3 or 4) float
        Joint positions (a 4th column, the radius, is ignored).
    bones : (B, 2) int
        Joint indices of each bone.
    candidates : tuple (indptr (n + 1,) int, bone_ids (p,) int) or None
        CSR-like list: the candidate bones of point v are
        ``bone_ids[indptr[v]:indptr[v + 1]]``. A point with no candidate falls back to all
        bones. ``None``: every bone is a candidate for every point (evaluated in chunks of
        about 256k point-bone pairs to bound memory).

    Returns
    -------
    bone : (n,) int64
        Index of the chosen bone (the first among equally close ones).
    t : (n,) float
        In [0, 1]; sigma = t * x_i + (1 - t) * x_j for bone (i, j). A zero-length bone gives
        t = 0 (no NaN).
    dist2 : (n,) float
        Squared distance from the point to sigma.

    Raises
    ------
    CurveSkelError
        If there are points but no bones, or shapes disagree.

    Examples
    --------
    >>> J = np.array([[0., 0, 0, 1], [0, 0, 2, 1]])
    >>> b, t, d2 = closest_on_bones(np.array([[1., 0, 0.5]]), J, np.array([[0, 1]]))
    >>> int(b[0]), float(t[0]), float(d2[0])
    (0, 0.75, 1.0)
    """
    P = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    X = np.asarray(joints, dtype=np.float64)
    if X.ndim != 2 or X.shape[1] not in (3, 4):
        raise CurveSkelError(f"joints must be (J, 3) or (J, 4), got {X.shape}")
    X = X[:, :3]
    bones = np.asarray(bones, dtype=np.int64).reshape(-1, 2)
    n, nb = len(P), len(bones)
    if n == 0:
        return np.zeros(0, np.int64), np.zeros(0), np.zeros(0)
    if nb == 0:
        raise CurveSkelError("closest_on_bones: the skeleton has no bones")
    if bones.min() < 0 or bones.max() >= len(X):
        raise CurveSkelError("closest_on_bones: bone joint index out of range")
    if candidates is None:
        return _all_bones(P, X, bones)
    indptr, ids = (np.asarray(a, dtype=np.int64) for a in candidates)
    if len(indptr) != n + 1:
        raise CurveSkelError(f"candidates indptr must have n + 1 = {n + 1} entries, got {len(indptr)}")
    cnt = np.diff(indptr)
    if np.any(cnt < 0) or (len(ids) and (ids.min() < 0 or ids.max() >= nb)):
        raise CurveSkelError("closest_on_bones: invalid candidate list")
    bone = np.zeros(n, np.int64)
    t = np.zeros(n)
    d2 = np.full(n, np.inf)
    one = np.flatnonzero(cnt == 1)                 # the common case: no choice to make
    if len(one):
        pb = ids[indptr[one]]
        bone[one] = pb
        t[one], d2[one] = _on_bones(P if len(one) == n else take_rows(P, one), X, bones, pb)
    many = np.flatnonzero(cnt > 1)
    if len(many):
        c = cnt[many]
        pt = np.repeat(many, c)
        # pair k of point v reads ids[indptr[v] + local]
        starts = np.cumsum(c) - c
        local = np.arange(len(pt)) - np.repeat(starts, c)
        pb = ids[np.repeat(indptr[many], c) + local]
        pt_t, pt_d2 = _on_bones(take_rows(P, pt), X, bones, pb)
        mins = np.minimum.reduceat(pt_d2, starts)
        pos = np.arange(len(pt))
        first = np.minimum.reduceat(np.where(pt_d2 == np.repeat(mins, c), pos, len(pt)), starts)
        bone[many], t[many], d2[many] = pb[first], pt_t[first], pt_d2[first]
    none = np.flatnonzero(cnt == 0)
    if len(none):
        bone[none], t[none], d2[none] = _all_bones(P[none], X, bones)
    return bone, t, d2


def closest_bone(points, joints, bones) -> np.ndarray:
    """The bone :func:`closest_on_bones` chooses with every bone a candidate (the first of
    equally close bones), without its t and distance (a bind needs only the bone).

    The same float32 screen as :func:`_all_bones` (near-ties within 1e-5 of the squared extent
    compared exactly, with the arithmetic of :func:`closest_on_bones`), laid out bones x
    points: every reduction over the bones then runs along the points (contiguous), where
    numpy's per-row reductions over a few dozen bones (``argmin``/``min`` along axis 1) cost
    10-25x more than the arithmetic on a small mesh. A point with one bone within the
    tolerance takes it (the float32 argmin); the near-ties' pairs come grouped by point from
    the screen, so they are compared without building candidate lists.
    """
    P = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    X = np.asarray(joints, dtype=np.float64)[:, :3]
    bones = np.asarray(bones, dtype=np.int64).reshape(-1, 2)
    n, nb = len(P), len(bones)
    if n and not nb:
        raise CurveSkelError("closest_bone: the skeleton has no bones")
    bone = np.zeros(n, np.int64)
    if n == 0 or nb == 1:
        return bone
    Pc, A, D, DD, AD, AA, inv, tol = _bone_frame(P, X, bones)
    f32 = np.float32
    PcT = np.ascontiguousarray(Pc.T, f32)
    Am, Dm = (-2.0 * A).astype(f32), D.astype(f32)
    AD, AA, inv, DD = (a.astype(f32)[:, None] for a in (AD, AA, inv, DD))
    ar = np.arange(nb, dtype=np.int32 if nb < 2**31 else np.int64)[:, None]
    rows, pairs, counts = [], [], []
    step = max(1, _NUM.block // nb)
    for s in range(0, n, step):
        p = PcT[:, s:s + step]
        d2 = _screen(Dm @ p, Am @ p, AD, AA, inv, DD)     # bones x points
        # the bones within tol of the least: one (the f32 argmin, kept) or near-ties, whose
        # candidates (the f32 best included) are compared exactly below
        near = d2 <= d2.min(axis=0) + tol
        count = np.add.reduce(near, axis=0, dtype=ar.dtype)
        bone[s:s + d2.shape[1]] = np.add.reduce(near * ar, axis=0)     # where count is 1
        many = np.flatnonzero(count > 1)
        if len(many):
            r, c = np.nonzero(near[:, many].T)        # grouped by point, bones increasing
            rows.append(s + many)
            pairs.append((s + many[r], c))
            counts.append(count[many])
    if rows:
        # exactly as closest_on_bones compares a point's candidates (the same arithmetic), the
        # pairs already grouped by point
        pt, pb = (np.concatenate(x) for x in zip(*pairs))
        c = np.concatenate(counts).astype(np.int64)
        d2 = _on_bones(take_rows(P, pt), X, bones, pb)[1]
        starts = np.cumsum(c) - c
        least = np.minimum.reduceat(d2, starts)
        first = np.minimum.reduceat(np.where(d2 == np.repeat(least, c), np.arange(len(pt)), len(pt)),
                                    starts)
        bone[np.concatenate(rows)] = pb[first]
    return bone


def _bone_frame(P, X, bones):
    """The bones' dot-product terms about the points' centre o: (P - o, a = x_j - o, d = x_i - x_j,
    d.d, a.d, a.a, 1 / d.d (0 for a zero-length bone), and the float32 screen's tolerance, 1e-5
    of the squared extent)."""
    o = 0.5 * (col_min(P) + col_max(P))
    A = X[bones[:, 1]] - o
    D = X[bones[:, 0]] - X[bones[:, 1]]
    DD = np.einsum("ij,ij->i", D, D)
    AD = np.einsum("ij,ij->i", A, D)
    AA = np.einsum("ij,ij->i", A, A)
    inv = np.divide(1.0, DD, out=np.zeros_like(DD), where=DD > 0)
    Pc = P - o
    scale = max(float(np.einsum("ij,ij->i", Pc, Pc).max()), float(AA.max()), float(DD.max()), 1e-300)
    return Pc, A, D, DD, AD, AA, inv, np.float32(1e-5 * scale)


def _screen(num, d2, AD, AA, inv, DD):
    """|p - sigma|^2 - |p|^2 for every (point, bone) from the products ``num = p.d`` and
    ``d2 = -2 p.a`` (either layout; the bone terms broadcast along it), in place: with
    num' = p.d - a.d and t = clip(num' / d.d), the value is a.a - 2 p.a - t (2 num' - t d.d)."""
    num -= AD
    t = num * inv
    np.clip(t, 0.0, 1.0, out=t)
    d2 += AA
    num *= 2.0
    num -= t * DD
    num *= t
    d2 -= num
    return d2


def _all_bones(P, X, bones):
    """Every bone a candidate: choose the bone with dot products, then exact t and dist2.

    For point p and bone (xi, xj) with a = xj, d = xi - xj: num = p.d - a.d, t = num / d.d and
    |p - sigma|^2 - |p|^2 = -2 p.a + a.a - t (2 num - t d.d), from the (k, B) products P A^T and
    P D^T, in float32 (BLAS) with coordinates relative to the points' centre. The bones within
    rounding of the best (1e-5 of the squared extent: a few per cent of the points, mostly those
    behind a shared joint) are compared exactly with candidate lists, so the choice is the exact
    one: the first of equally close bones. t and dist2 of the chosen bone are computed exactly.
    """
    n, nb = len(P), len(bones)
    bone = np.zeros(n, np.int64)
    if n == 0 or nb == 1:
        return (bone, *_on_bones(P, X, bones, bone))
    Pc, A, D, DD, AD, AA, inv, tol = _bone_frame(P, X, bones)
    f32 = np.float32
    Pc, At, Dt = Pc.astype(f32), np.ascontiguousarray(-2.0 * A.T, f32), np.ascontiguousarray(D.T, f32)
    AD, AA, inv, DD = AD.astype(f32), AA.astype(f32), inv.astype(f32), DD.astype(f32)
    rows, cands, counts = [], [], []
    step = max(1, _NUM.block // nb)
    for s in range(0, n, step):
        p = Pc[s:s + step]
        d2 = _screen(p @ Dt, p @ At, AD, AA, inv, DD)
        best = np.argmin(d2, axis=1)
        bone[s:s + len(d2)] = best
        # rows where another bone is within tol of the best: the best set aside, the least
        # of the others; their candidates (best included) only for those rows
        at = np.arange(len(d2))
        within = d2[at, best] + tol
        d2[at, best] = np.inf
        many = np.flatnonzero(d2.min(axis=1) <= within)
        if len(many):
            near = d2[many] <= within[many, None]
            near[np.arange(len(many)), best[many]] = True
            rows.append(s + many)
            cands.append(np.nonzero(near)[1])
            counts.append(np.count_nonzero(near, axis=1))
    if rows:
        rows = np.concatenate(rows)
        indptr = np.r_[0, np.cumsum(np.concatenate(counts))]
        bone[rows] = closest_on_bones(P[rows], X, bones, candidates=(indptr, np.concatenate(cands)))[0]
    t, d2 = _on_bones(P, X, bones, bone)
    return bone, t, d2


def nearest_on_silhouette(points, joints, bones, k: int = 1):
    """For each point, the bone whose round cone's surface is nearest along the bone's own
    normal: the bone minimising ``|p - s_b| - r_b(s_b)``, ``s_b`` the point's closest point on
    bone ``b`` and ``r_b`` the radius there (linear between the joints' radii).

    The least of these is the signed distance from the point to the silhouette (the union of
    the bones' round cones, measured to each cone along its axis' normal): a point inside a
    fat neighbour's cone maps to it with a negative value, where the closest bone's axis would
    hide the overlap.

    Parameters
    ----------
    points : (n, 3) float
    joints : (J, 4) float
    bones : (B, 2) int

    k : int
        How many bones to return per point (the ``k`` least values, least first).

    Returns
    -------
    bone : (n,) int, or (n, k) for ``k > 1``
    t : (n,) float, or (n, k)
        sigma = t x_i + (1 - t) x_j on bone (i, j), as :func:`closest_on_bones`.
    dist2 : (n,) float, or (n, k)
        Squared distance from the point to sigma.

    Examples
    --------
    >>> J = np.array([[0., 0, 0, 0.1], [0, 0, 2, 0.1], [0, 0, 0, 1.5], [2, 0, 0, 1.5]])
    >>> b, t, d2 = nearest_on_silhouette(np.array([[0.5, 0, 1.0]]), J, np.array([[0, 1], [2, 3]]))
    >>> int(b[0])                  # 0.5 from the thin bone's axis, 1.0 inside the fat one
    1
    """
    P = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    Z = np.asarray(joints, dtype=np.float64)
    bones = np.asarray(bones, dtype=np.int64).reshape(-1, 2)
    n, nb = len(P), len(bones)
    if n == 0:
        return np.zeros(0, np.int64), np.zeros(0), np.zeros(0)
    if nb == 0:
        raise CurveSkelError("nearest_on_silhouette: the skeleton has no bones")
    # about the points' centre, with BLAS products (the same algebra as _screen, in float64):
    # num = p.d - a.d, t = clip(num / d.d), |p - s|^2 = |p|^2 - 2 p.a + a.a - t (2 num - t d.d)
    o = 0.5 * (col_min(P) + col_max(P))
    Pc = P - o
    A = Z[bones[:, 1], :3] - o
    Dv = Z[bones[:, 0], :3] - Z[bones[:, 1], :3]
    DD = np.einsum("ij,ij->i", Dv, Dv)
    AD = np.einsum("ij,ij->i", A, Dv)
    AA = np.einsum("ij,ij->i", A, A)
    inv = np.divide(1.0, DD, out=np.zeros_like(DD), where=DD > 0)
    ri, rj = Z[bones[:, 0], 3], Z[bones[:, 1], 3]
    At, Dt = np.ascontiguousarray(-2.0 * A.T), np.ascontiguousarray(Dv.T)
    kk = min(int(k), nb)
    bone = np.zeros((n, kk), np.int64)
    step = max(1, _NUM.block // nb)
    # Values within a tie (a share of the points' extent) are equal, and equal values rank by
    # bone number: a point beyond a joint is exactly as far from both of the joint's bones, and
    # the last bits of the products (which depend on the point's place in the block, the
    # mesh's numbering) would choose otherwise.
    quantum = CONFIG.initial.tie * max(float(np.linalg.norm(col_max(P) - col_min(P))), 1e-300)
    for s in range(0, n, step):
        p = Pc[s:s + step]
        d2 = _screen(p @ Dt, p @ At, AD, AA, inv, DD)
        d2 += np.einsum("ij,ij->i", p, p)[:, None]
        t = np.clip((p @ Dt - AD) * inv, 0.0, 1.0)
        value = np.round((np.sqrt(np.maximum(d2, 0.0)) - (rj + t * (ri - rj))) / quantum)
        if kk == 1:
            bone[s:s + step, 0] = np.argmin(value, axis=1)
            continue
        part = np.argpartition(value, kk - 1, axis=1)[:, :kk] if kk < nb else \
            np.broadcast_to(np.arange(nb), value.shape).copy()
        part = np.sort(part, axis=1)
        rows = np.arange(len(p))[:, None]
        order = np.argsort(value[rows, part], axis=1, kind="stable")
        bone[s:s + step] = part[rows, order]
    flat = bone.ravel()
    t, d2 = _on_bones(np.repeat(P, kk, axis=0), Z[:, :3], bones, flat)
    if k == 1:
        return bone[:, 0], t, d2
    return bone, t.reshape(n, kk), d2.reshape(n, kk)
