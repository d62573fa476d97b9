"""Radii fitted to the silhouette itself: the union of round cones against the surface.

Why: :func:`.centreline.fit_radii_surface` fits each joint's radius to the distances from the
vertices to their nearest bone, ``| |v - sigma(v)| - r(sigma(v)) |``. The silhouette a rigger
sees (and ``recon`` measures) is the union of round cones, whose surface is not at distance
``r(t)`` from the axis where the radius changes along a bone (a cone's side is tilted), and where
two cones overlap the nearer surface is the other bone's. So the radii that minimise the
distance from the surface to the silhouette are found on the silhouette: iteratively
reweighted Gauss-Newton on ``sum_i w_i |sdf(p_i)|``, ``sdf`` the exact signed distance to the
union (:func:`.quality.sd_round_cone`), each sample's derivative taken on the cone that is
nearest to it. On the ten shared meshes this lowers the surface-to-silhouette distance by 6-45 %
against the nearest-bone fit, with the curve unchanged.

Examples
--------
>>> r = fit_radii_silhouette(P, w, joints, bones)          # doctest: +SKIP
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree

from .quality import (primitive_joints, round_cone_geometry, sd_round_cone_radii,
                      take_round_cone_geometry)

__all__ = ["fit_radii_silhouette", "ITERATIONS", "CANDIDATES", "SAMPLES", "FLOOR", "BAND"]

#: Gauss-Newton iterations (each one solve of a joints x joints system).
ITERATIONS = 8
#: Cones a sample is compared with: the nearest by centre (the union's value near the surface
#: comes from a cone close by; fixed for the whole fit).
CANDIDATES = 8
#: The radii stay within these factors of the starting (nearest-bone) radii.
BAND = (0.7, 1.4)
#: IRLS weights are capped at 1 / (FLOOR * median |sdf|).
FLOOR = 0.1
#: Above 3x this many vertices the pipeline fits with an area-weighted draw of this many (held
#: out on armadillo and horse, the same surface-to-silhouette distance as with 10,000).
SAMPLES = 5000


def fit_radii_silhouette(P, w, joints, bones, *, iterations=ITERATIONS, smooth=0.01,
                         candidates=CANDIDATES):
    """Joint radii minimising the weighted mean |signed distance| of ``P`` to the silhouette.

    Parameters
    ----------
    P : (n, 3) float
        Surface samples.
    w : (n,) float
        Their weights (areas).
    joints : (J, 4) float
        Positions (held fixed) and the starting radii.
    bones : (B, 2) int
    iterations : int
    smooth : float
        Ridge towards the previous radii, relative to each joint's own weight (keeps a joint
        that explains few samples where it was).
    candidates : int

    Returns
    -------
    r : (J,) float, > 0, within ``BAND`` of the starting radii
    history : list of float
        The weighted mean |sdf| before each iteration and after the last.
    """
    P = np.asarray(P, np.float64).reshape(-1, 3)
    w = np.asarray(w, np.float64)
    J = np.asarray(joints, np.float64)
    r = np.abs(J[:, 3]).copy()
    if len(P) == 0 or len(J) == 0:
        return r, []
    # within a band around the starting radii: where the neighbours' balls cover a joint the
    # silhouette does not care about its radius, and the fit would pinch the skin there (45
    # chain joints under 0.4x both neighbours' radii over the ten shared meshes, 4 with the band)
    pos = r[r > 0]
    scale = float(np.median(pos)) if pos.size else 1.0
    lo = np.maximum(BAND[0] * r, 1e-6 * scale)
    hi = np.maximum(BAND[1] * r, lo)
    ii, jj = primitive_joints(len(J), bones)
    a, b = J[ii, :3], J[jj, :3]
    # each sample against the cones that can be nearest to it: of the 4k nearest by centre, the
    # k with the smallest lower bound |p - centre| - (half length + radius); fixed for the fit
    centres = (a + b) / 2
    reach = np.linalg.norm(b - a, axis=1) / 2 + np.maximum(r[ii], r[jj])
    kk = min(4 * candidates, len(ii))
    dist, near = cKDTree(centres).query(P, k=kk)
    dist, near = np.asarray(dist).reshape(len(P), kk), np.asarray(near).reshape(len(P), kk)
    k = min(candidates, kk)
    keep = np.argsort(dist - reach[near], axis=1, kind="stable")[:, :k]
    near = np.take_along_axis(near, keep, axis=1)
    pi = np.repeat(np.arange(len(P)), k)
    pj = near.ravel()
    # the point-cone geometry does not change with the radii: once for the whole fit
    geom = round_cone_geometry(P[pi], a[pj], b[pj])
    rows2 = np.r_[np.arange(len(P)), np.arange(len(P))]
    rows = np.arange(len(P))

    def union(radii):
        v = sd_round_cone_radii(geom, radii[ii[pj]], radii[jj[pj]]).reshape(len(P), k)
        best = np.argmin(v, axis=1)
        return v[rows, best], near[rows, best], rows * k + best

    def cost(sv):
        return float(np.sum(w * np.abs(sv)) / max(float(w.sum()), 1e-300))

    s, c, at = union(r)
    history = [cost(s)]
    for it in range(iterations):
        ci, cj = ii[c], jj[c]
        d = 1e-4 * scale
        gc = take_round_cone_geometry(geom, at)        # each sample's nearest cone
        g1 = (sd_round_cone_radii(gc, r[ci] + d, r[cj]) - s) / d
        g2 = (sd_round_cone_radii(gc, r[ci], r[cj] + d) - s) / d
        lone = ci == cj
        g1 = np.where(lone, g1 + g2, g1)
        g2 = np.where(lone, 0.0, g2)
        # least absolute deviations by reweighting (a sample's weight / its |sdf|), the weights
        # capped at 10x the median sample's: a sample on a crease of the union, where rounding
        # decides which cone is nearer, would otherwise steer the step (1e-3 of the median:
        # radii of the hand scaled by 1e6 differed by 8e-6 of themselves, now 7e-9)
        floor = FLOOR * max(float(np.median(np.abs(s))), 1e-300)
        ww = w / np.maximum(np.abs(s), floor)
        G = sp.csr_matrix((np.r_[g1, g2], (rows2, np.r_[ci, cj])), shape=(len(P), len(J)))
        A = (G.T @ sp.diags(ww) @ G).toarray()
        rhs = -(G.T @ (ww * s))
        diag = np.diag(A).copy()
        A[np.diag_indices(len(J))] += smooth * diag + 1e-9 * max(float(diag.max()), 1e-300)
        step = np.linalg.solve(A, rhs)
        # a Gauss-Newton step can overshoot where the nearest cone changes: halve it until the
        # mean |sdf| goes down by a margin (at most 4 times), else stop. The margin keeps a
        # converged fit from taking steps that rounding alone decides (a mesh scaled by 1e6)
        for _ in range(5):
            trial = np.clip(r + step, lo, hi)
            s_t, c_t, at_t = union(trial)
            if cost(s_t) < history[-1] * (1.0 - 1e-6):
                break
            step *= 0.5
        else:
            break
        r, s, c, at = trial, s_t, c_t, at_t
        history.append(cost(s))
    return r, history
