"""Flaps (ears, fins, flat lobes): a leaf chain laid from its junction into the flap's middle.

Why: a flap's medial surface is a sheet, so no one curve is its skeleton, and its Reeb branch
runs to where the geodesic distance f peaks: a corner of the flap. The elephant's ear chains
ended at the ears' top outer corners, 0.07-0.13 D from where CGAL's ear lines end (issue 10).
A rigger's ear bone pivots at the ear's root and points into the ear's middle; mean-curvature
flow shrinks a flap towards the same line. The cross-sections the polish centres a chain on do not help here:
across a flap they are long strips, beyond any reach a limb's section has.

A leaf chain is a flap's when its cross-sections are flat: the area of the section loop across
the chain is below ``ROUNDNESS`` times the disc of the loop's reach (a strip more than about 8.5
times wider than thick; a round limb's sections are 0.4-0.9), at the median of its sections at
``SECTION_AT`` of its length beyond the junction's ball (a section there cuts the body). Its
joints are then laid evenly on the straight line from the junction towards the area centroid of
the vertices closest to the chain, ending where the flap's half-width fits behind the tip (a
round flap ends at its centre, a long fin half a width short of its end), moved onto the flap's
medial sheet (the nearest medial point of the flap: a cupped ear's centroid lies off the ear).
The line must lie inside the mesh, else the chain is left as it was.

Examples
--------
>>> idx, Y = lay_flaps(V, F, w, joints, bones, inside, medial)    # doctest: +SKIP
>>> joints[idx, :3] = Y                                           # doctest: +SKIP
"""

from __future__ import annotations

import numpy as np

from .cross_section import section_loops
from .edit import leaf_chains
from .mapping import closest_on_bones

__all__ = ["lay_flaps", "flap_chains", "leaf_roundness", "section_roundness", "ROUNDNESS",
           "SECTION_REACH", "MIN_SECTIONS", "SECTION_AT", "LINE_SAMPLES"]

#: A section whose area is below this fraction of the disc of its reach is a flap's.
ROUNDNESS = 0.15
#: Sections are looked for up to this many joint radii (a flap's reach is its half-width, and
#: its radius about half its thickness: a disc 20 times wider than thick reaches 20 radii from
#: a chain through its middle; at 10 a chain wandering across such a flap found no section
#: and was not laid). A round limb's section lies within 1-2 radii; the leaf chains of the
#: 18 shared and held-out meshes read the same at 10 and 30 but for the cat (0.45 -> 0.37)
#: and the human (0.63 -> 0.60), far from ``ROUNDNESS``.
SECTION_REACH = 30.0
#: Where a leaf chain's sections are taken: fractions of its length beyond its junction's ball.
SECTION_AT = np.array([0.2, 0.35, 0.5, 0.65, 0.8])
#: A chain needs this many of them found (a closed loop round the point within reach).
MIN_SECTIONS = 2
#: Points per laid line tested for being inside the mesh.
LINE_SAMPLES = 40
# the far edge and the half-width: quantiles of the flap's vertices (a stray vertex of the body
# mapped to the chain does not set them)
_FAR_QUANTILE = 0.99
_HALF_QUANTILE = 0.90


def section_roundness(area, extent):
    """Section area ÷ the area of the disc of its reach: 1 for a round section, ~4t/(pi w) for
    a strip of width w and thickness t; 0 where no loop was found (``extent`` inf).

    Examples
    --------
    >>> section_roundness(np.array([np.pi, 0.4]), np.array([1.0, 1.0])).round(3).tolist()
    [1.0, 0.127]
    """
    area = np.asarray(area, np.float64)
    extent = np.asarray(extent, np.float64)
    ok = np.isfinite(extent) & (extent > 0)
    return np.where(ok, area / (np.pi * np.where(ok, extent, 1.0) ** 2), 0.0)


def leaf_roundness(V, F, joints, bones, *, face_of=None, vertex_edge=None):
    """Every leaf chain of three joints or more with the median :func:`section_roundness` of
    its sections at ``SECTION_AT`` of its length (nan with fewer than ``MIN_SECTIONS`` found).

    Returns
    -------
    list of (joints (k,) int, bones (k - 1,) int, roundness float): each from its junction to
    its tip.
    """
    J = np.asarray(joints, np.float64)
    bones = np.asarray(bones, np.int64).reshape(-1, 2)
    cand = [(js, bs) for js, bs in leaf_chains(len(J), bones) if len(js) >= 3]
    # planes across the chain at fixed fractions of its length beyond the junction's ball (as
    # many for a chain of few joints as of many), along the bone there: none in the body (a
    # section there cuts the body) or at the tip (the end cap)
    pts, tan, rad, own = [], [], [], []
    for k, (js, _) in enumerate(cand):
        X = J[js, :3]
        seg = np.linalg.norm(np.diff(X, axis=0), axis=1)
        s = np.concatenate([[0.0], np.cumsum(seg)])
        start = abs(J[js[0], 3])                       # out of the junction's ball
        if not s[-1] > start:
            continue
        at = start + SECTION_AT * (s[-1] - start)
        b = np.clip(np.searchsorted(s, at, side="right") - 1, 0, len(seg) - 1)
        u = np.divide(at - s[b], seg[b], out=np.zeros_like(at), where=seg[b] > 0)[:, None]
        pts.append(X[b] + u * (X[b + 1] - X[b]))
        tan.append(X[b + 1] - X[b])
        rad.append((1 - u[:, 0]) * J[js[b], 3] + u[:, 0] * J[js[b + 1], 3])
        own.append(np.full(len(at), k))
    if not pts:
        return [(js, bs, float("nan")) for js, bs in cand]
    P, T, r, own = (np.concatenate(x) for x in (pts, tan, rad, own))
    nt = np.linalg.norm(T, axis=1, keepdims=True)
    T = np.divide(T, nt, out=np.zeros_like(T), where=nt > 0)
    _, extent, area = section_loops(V, F, P, T, SECTION_REACH * np.abs(r), face_of=face_of,
                                    vertex_edge=vertex_edge)
    rnd = section_roundness(area, extent)
    found = np.isfinite(extent)
    out = []
    for k, (js, bs) in enumerate(cand):
        sel = np.flatnonzero((own == k) & found)
        out.append((js, bs, float(np.median(rnd[sel])) if len(sel) >= MIN_SECTIONS
                    else float("nan")))
    return out


def flap_chains(V, F, joints, bones, *, face_of=None, vertex_edge=None):
    """The leaf chains whose cross-sections are flat (see the module docstring).

    Returns
    -------
    list of (joints (k,) int, bones (k - 1,) int): each from its junction to its tip.
    """
    return [(js, bs) for js, bs, rnd in leaf_roundness(V, F, joints, bones, face_of=face_of,
                                                       vertex_edge=vertex_edge)
            if rnd < ROUNDNESS]


def _weighted_quantile(x, w, q):
    order = np.argsort(x, kind="stable")
    c = np.cumsum(w[order])
    return float(x[order][min(np.searchsorted(c, q * c[-1]), len(x) - 1)])


def _flap_line(V, w, a):
    """(unit direction, length) of the line from ``a`` into the flap of vertices ``V`` with
    area weights ``w``; None if the flap's centroid is at ``a``."""
    c = (w[:, None] * V).sum(axis=0) / w.sum()
    d = c - a
    L = float(np.linalg.norm(d))
    if not L > 0:
        return None
    d /= L
    s = (V - a) @ d
    perp = np.linalg.norm((V - a) - s[:, None] * d, axis=1)
    far = _weighted_quantile(s, w, _FAR_QUANTILE)
    ahead = s > 0
    half = _weighted_quantile(perp[ahead], w[ahead], _HALF_QUANTILE) if ahead.any() else 0.0
    return d, max(L, far - half)


def lay_flaps(V, F, weights, joints, bones, inside, medial, *, face_of=None,
              vertex_edge=None):
    """New places for the joints of every flap's chain (see the module docstring).

    Parameters
    ----------
    V, F : the mesh
    weights : (n,) float
        Vertex area weights (the flap's centroid is an area centroid).
    joints : (J, 4) float
    bones : (B, 2) int
    inside : callable (k, 3) -> (k,) bool
        The mesh's inside test.
    medial : (k, 3) float
        Medial points of the mesh (:func:`.centreline.centre_stage`'s): the tip goes to the
        flap's one nearest the line's end.
    face_of, vertex_edge : optional
        The faces around each vertex (:func:`.mesh_graph.faces_around`) and the longest side
        of those faces (:func:`.cross_section.vertex_edges`), if at hand.

    Returns
    -------
    idx : (k,) int
        The joints laid (every joint of each flap's chain but its junction).
    Y : (k, 3) float
        Their new places.
    """
    J = np.asarray(joints, np.float64)
    bones = np.asarray(bones, np.int64).reshape(-1, 2)
    V = np.asarray(V, np.float64)
    w = np.asarray(weights, np.float64)
    flaps = flap_chains(V, F, J, bones, face_of=face_of, vertex_edge=vertex_edge)
    idx, Y = [], []
    if not flaps:
        return np.zeros(0, np.int64), np.zeros((0, 3))
    M = np.asarray(medial, np.float64).reshape(-1, 3)
    bone, _, _ = closest_on_bones(V, J[:, :3], bones)
    mbone = closest_on_bones(M, J[:, :3], bones)[0] if len(M) else np.zeros(0, np.int64)
    for js, bs in flaps:
        mine = np.isin(bone, bs)
        sheet = M[np.isin(mbone, bs)]
        a = J[js[0], :3]
        line = _flap_line(V[mine], w[mine], a) if mine.any() and len(sheet) else None
        if line is None:
            continue
        d, length = line
        end = a + length * d
        tip = sheet[np.argmin(np.einsum("ij,ij->i", sheet - end, sheet - end))]
        if not inside(a + (tip - a) * np.linspace(0.0, 1.0, LINE_SAMPLES + 1)[1:, None]).all():
            continue
        m = len(js) - 1
        idx.append(js[1:])
        Y.append(a + (tip - a) * (np.arange(1, m + 1) / m)[:, None])
    if not idx:
        return np.zeros(0, np.int64), np.zeros((0, 3))
    return np.concatenate(idx), np.concatenate(Y)
