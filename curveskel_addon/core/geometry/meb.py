"""Exact minimum enclosing ball (MEB) of a 3-D point set.

The paper places each skeleton joint at the centre of the MEB of a contour line, found with
Welzl's algorithm. Welzl is exact and expected linear time, but as a Python loop over every
point it is far too slow for contours and regions of million-vertex meshes. So we combine:

* an exact move-to-front Welzl (recursion depth <= 4: each level adds one support point) run on
  a small *working set*, with the containment test of each level vectorised;
* an outer loop that checks ALL points against that ball at once (NumPy) and adds the worst
  violators to the working set.

The final ball is the MEB of a subset S that contains every point: any ball containing all
points also contains S, so it cannot be smaller than MEB(S); hence MEB(S) is MEB(all points).
Each round strictly grows the radius, so the loop ends (in practice after 2-6 rounds).

Degenerate supports (duplicates, collinear or co-planar/co-circular points) are handled by
computing the circumcentre inside the affine hull of the support with a least-squares solve,
so no division by zero occurs and the result stays the smallest ball through those points.
"""

from __future__ import annotations

import numpy as np

from ..config import CONFIG
from ..errors import CurveSkelError

__all__ = ["min_enclosing_ball", "ball_through", "size_of"]

_NUM = CONFIG.numerics


def ball_through(R: np.ndarray) -> tuple[np.ndarray, float]:
    """Smallest ball with all points of R (k <= 4) on its boundary.

    The centre is the circumcentre in the affine hull of R: c = p0 + A^T l with A the rows
    p_i - p0, solving (A A^T) l = |p_i - p0|^2 / 2 by least squares (well-defined for
    duplicate, collinear or co-planar supports).

    Parameters
    ----------
    R : (k, 3) float, 0 <= k <= 4

    Returns
    -------
    centre : (3,) float
    radius2 : float
        Squared radius (-1 for an empty R: contains nothing).

    Examples
    --------
    >>> c, r2 = ball_through(np.array([[0., 0, 0], [2, 0, 0]]))
    >>> c.tolist(), r2
    ([1.0, 0.0, 0.0], 1.0)
    """
    k = len(R)
    if k == 0:
        return np.zeros(3), -1.0
    p0 = R[0]
    if k == 1:
        return p0.copy(), 0.0
    A = R[1:] - p0
    b = 0.5 * np.einsum("ij,ij->i", A, A)
    M = A @ A.T
    lam = np.linalg.lstsq(M, b, rcond=1e-12)[0]
    c = p0 + lam @ A
    r2 = float(max(np.max(np.einsum("ij,ij->i", R - c, R - c)), 0.0))
    return c, r2


def _ball_py(R: list) -> tuple[tuple, float]:
    """ball_through for k <= 4 points as float tuples: closed forms, lstsq only if degenerate."""
    k = len(R)
    if k == 0:
        return (0.0, 0.0, 0.0), -1.0
    x0, y0, z0 = R[0]
    if k == 1:
        return R[0], 0.0
    if k == 2:
        x1, y1, z1 = R[1]
        c = (0.5 * (x0 + x1), 0.5 * (y0 + y1), 0.5 * (z0 + z1))
        return c, 0.25 * ((x1 - x0) ** 2 + (y1 - y0) ** 2 + (z1 - z0) ** 2)
    ax, ay, az = R[1][0] - x0, R[1][1] - y0, R[1][2] - z0
    bx, by, bz = R[2][0] - x0, R[2][1] - y0, R[2][2] - z0
    aa, bb = ax * ax + ay * ay + az * az, bx * bx + by * by + bz * bz
    if k == 3:
        nx, ny, nz = ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx
        nn = nx * nx + ny * ny + nz * nz
        if nn <= 1e-20 * aa * bb or nn == 0.0:
            return _ball_np(R)
        ux, uy, uz = aa * bx - bb * ax, aa * by - bb * ay, aa * bz - bb * az
        d = 2.0 * nn
        cx = (uy * nz - uz * ny) / d
        cy = (uz * nx - ux * nz) / d
        cz = (ux * ny - uy * nx) / d
        return (x0 + cx, y0 + cy, z0 + cz), cx * cx + cy * cy + cz * cz
    qx, qy, qz = R[3][0] - x0, R[3][1] - y0, R[3][2] - z0
    qq = qx * qx + qy * qy + qz * qz
    bcx, bcy, bcz = by * qz - bz * qy, bz * qx - bx * qz, bx * qy - by * qx
    det = ax * bcx + ay * bcy + az * bcz
    if abs(det) <= 1e-10 * (aa * bb * qq) ** 0.5 or det == 0.0:
        return _ball_np(R)
    cax, cay, caz = qy * az - qz * ay, qz * ax - qx * az, qx * ay - qy * ax
    abx, aby, abz = ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx
    d = 2.0 * det
    cx = (aa * bcx + bb * cax + qq * abx) / d
    cy = (aa * bcy + bb * cay + qq * aby) / d
    cz = (aa * bcz + bb * caz + qq * abz) / d
    return (x0 + cx, y0 + cy, z0 + cz), cx * cx + cy * cy + cz * cz


def _ball_np(R: list) -> tuple[tuple, float]:
    c, r2 = ball_through(np.array(R, dtype=np.float64))
    return (float(c[0]), float(c[1]), float(c[2])), r2


def _welzl_mtf(L: list, end: int, R: list, tol: float):
    """Move-to-front Welzl: MEB of L[:end] (float tuples) with the points R on the boundary.

    Recursion depth is at most 4 (each level adds one support point). ``L`` is reordered in
    place (points that forced the ball to grow move to the front).
    """
    (cx, cy, cz), r2 = _ball_py(R)
    if len(R) == 4:
        return (cx, cy, cz), r2
    i = 0
    while i < end:
        p = L[i]
        if (p[0] - cx) ** 2 + (p[1] - cy) ** 2 + (p[2] - cz) ** 2 > r2 + tol:
            (cx, cy, cz), r2 = _welzl_mtf(L, i, R + [p], tol)
            del L[i]
            L.insert(0, p)
        i += 1
    return (cx, cy, cz), r2


def min_enclosing_ball(P) -> tuple[np.ndarray, float]:
    """Exact minimum enclosing ball of a point set.

    Parameters
    ----------
    P : (k, 3) float, k >= 1
        Points; duplicates and degenerate (collinear, co-planar) configurations are fine.

    Returns
    -------
    centre : (3,) float
    radius : float
        Every point lies within ``radius`` of ``centre`` (up to ~1e-6 relative rounding).

    Raises
    ------
    CurveSkelError
        If P is empty, not (k, 3), or not finite.

    Examples
    --------
    >>> c, r = min_enclosing_ball(np.array([[0., 0, 0], [2, 0, 0], [1, 0.5, 0]]))
    >>> np.round(c, 6).tolist(), round(r, 6)
    ([1.0, 0.0, 0.0], 1.0)
    """
    P = np.asarray(P, dtype=np.float64)
    if P.ndim != 2 or P.shape[1] != 3 or len(P) == 0:
        raise CurveSkelError(f"min_enclosing_ball needs (k, 3) points with k >= 1, got {P.shape}")
    if not np.all(np.isfinite(P)):
        raise CurveSkelError("min_enclosing_ball: points must be finite")
    k = len(P)
    if k == 1:
        return P[0].copy(), 0.0
    # Work relative to the centroid for better conditioning.
    o = P.mean(axis=0)
    Q = P - o
    scale2 = float(np.max(np.einsum("ij,ij->i", Q, Q)))
    if scale2 == 0.0:
        return o, 0.0
    if k <= _NUM.meb_batch:
        work = list(range(k))
    else:
        # Extremes along the axes and diagonals + a farthest-point pair: a good first guess.
        dirs = np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1], [1, 1, -1], [1, -1, 1],
                         [-1, 1, 1]], float)
        proj = Q @ dirs.T
        seed = np.concatenate([proj.argmin(0), proj.argmax(0)])
        d0 = np.einsum("ij,ij->i", Q, Q)
        seed = np.concatenate([seed, [int(np.argmax(d0))]])
        work = list(dict.fromkeys(int(s) for s in seed))
    in_work = np.zeros(k, bool)
    in_work[work] = True
    tol = _NUM.meb_tolerance * scale2
    pts = [tuple(q) for q in Q[work].tolist()]
    while True:
        c, r2 = _welzl_mtf(pts, len(pts), [], tol)
        c = np.array(c)
        d2 = np.einsum("ij,ij->i", Q - c, Q - c)
        viol = d2 > r2 + 1e-10 * max(r2, scale2)
        viol &= ~in_work
        nv = int(viol.sum())
        if nv == 0:
            break
        cand = np.flatnonzero(viol)
        if nv > _NUM.meb_batch:
            cand = cand[np.argpartition(-d2[cand], _NUM.meb_batch)[:_NUM.meb_batch]]
        in_work[cand] = True
        # New (violating) points first: move-to-front order makes them support candidates early.
        pts = [tuple(q) for q in Q[cand].tolist()] + pts
    radius = float(np.sqrt(max(r2, float(d2.max()))))
    return c + o, radius


def size_of(P) -> float:
    """The size of a point set that no rotation, translation, reordering or permutation of the
    points changes: the diameter of its minimum enclosing ball (the bounding box's diagonal,
    used before, grows by up to 73 % when a shape is turned, which moved every contour level).

    Examples
    --------
    >>> size_of(np.array([[0., 0, 0], [2, 0, 0], [1, 1, 0]]))
    2.0
    """
    P = np.asarray(P, dtype=np.float64).reshape(-1, 3)
    if len(P) == 0:
        return 0.0
    return 2.0 * float(min_enclosing_ball(P)[1])
