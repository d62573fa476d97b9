"""Test support: skeletons of the shared and procedural meshes computed once per test session,
and small measures of a skeleton written here (graph figures, curve distances, turning, the
inside fraction) so the core's tests depend on the core alone.

A run of the method takes seconds on a small procedural mesh and 5-60 s on a shared one: every
test that needs the default skeleton of a mesh asks :func:`shared_skeleton` or
:func:`procedural_skeleton`, which run it once per session and parameter set.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components

import meshes
from curveskel_addon.core import SkeletonParams, skeletonize
from curveskel_addon.core.geometry.inside import InsideTest
from curveskel_addon.core.geometry.meb import size_of
from curveskel_addon.mesh_files import read_mesh

__all__ = ["SHARED", "HELDOUT", "shared_mesh", "shared_skeleton", "procedural_mesh",
           "procedural_skeleton", "topology", "bone_points", "inside_fraction", "unit_D",
           "bbox_D", "curve_samples", "distance_to_curve", "curve_gap", "curve_mean_gap",
           "turning_angles", "total_turning", "bending", "chain_straightness",
           "silhouette_distance"]

SHARED = Path(__file__).resolve().parents[2] / "shared" / "meshes"
HELDOUT = Path(__file__).resolve().parent / "data" / "heldout"


def _frozen(V, F):
    V = np.asarray(V, np.float64)
    F = np.asarray(F, np.int64)
    V.setflags(write=False)
    F.setflags(write=False)
    return V, F


@lru_cache(maxsize=None)
def shared_mesh(name: str):
    """(V, F) of a shared mesh (``"hand.off"``) or a held-out one (``"heldout/cat.obj"``),
    read-only."""
    path = HELDOUT / name.split("/", 1)[1] if name.startswith("heldout/") else SHARED / name
    return _frozen(*read_mesh(path))


def _params(params):
    return SkeletonParams.from_dict(dict(params)) if params else None


@lru_cache(maxsize=None)
def _shared_run(name, params):
    V, F = shared_mesh(name)
    return skeletonize(V, F, _params(params))


def shared_skeleton(name: str, paper: bool = False, **params):
    """The skeleton of a shared (or ``heldout/``) mesh with these parameters (default: the
    default ones; ``paper``: ``SkeletonParams.paper()`` with these overrides), computed once
    per session."""
    if paper:
        params = {**SkeletonParams.paper().to_dict(), **params}
    return _shared_run(name, tuple(sorted(params.items())))


@lru_cache(maxsize=None)
def procedural_mesh(name: str):
    """(V, F) of ``tests/meshes.<name>()``, read-only."""
    out = getattr(meshes, name)()
    return _frozen(out[0], out[1])


@lru_cache(maxsize=None)
def _procedural_run(name, params):
    V, F = procedural_mesh(name)
    return skeletonize(V, F, _params(params))


def procedural_skeleton(name: str, paper: bool = False, **params):
    """The skeleton of ``tests/meshes.<name>()`` with these parameters, once per session."""
    if paper:
        params = {**SkeletonParams.paper().to_dict(), **params}
    return _procedural_run(name, tuple(sorted(params.items())))


# -- figures of a skeleton ------------------------------------------------------------------------
def topology(n_joints, bones):
    """(independent cycles B - J + C, components C, degree of every joint)."""
    bones = np.asarray(bones, np.int64).reshape(-1, 2)
    A = csr_matrix((np.ones(len(bones)), (bones[:, 0], bones[:, 1])), shape=(n_joints, n_joints))
    C = connected_components(A, directed=False)[0]
    return len(bones) - n_joints + C, C, np.bincount(bones.ravel(), minlength=n_joints)


def bone_points(joints, bones, per_bone=10):
    """``per_bone`` points along every bone, both ends included."""
    X = np.asarray(joints, np.float64)[:, :3]
    bones = np.asarray(bones, np.int64).reshape(-1, 2)
    t = np.linspace(0.0, 1.0, per_bone)[None, :, None]
    return (X[bones[:, 0]][:, None] * (1 - t) + X[bones[:, 1]][:, None] * t).reshape(-1, 3)


def inside_fraction(V, F, joints, bones, per_bone=10):
    """The share of the points along the bones (:func:`bone_points`) inside the mesh (the
    core's exact ray-parity test)."""
    return float(InsideTest(V, F)(bone_points(joints, bones, per_bone)).mean())


def unit_D(V) -> float:
    """The method's unit of length: the diameter of the vertices' minimum enclosing ball."""
    return float(size_of(np.asarray(V, np.float64)))


def bbox_D(V) -> float:
    """The bounding-box diagonal (the unit of issue 10's shape figures)."""
    V = np.asarray(V, np.float64)
    return float(np.linalg.norm(V.max(axis=0) - V.min(axis=0)))


# -- curves ---------------------------------------------------------------------------------------
def _curve(c):
    if hasattr(c, "joints"):
        return np.asarray(c.joints, np.float64)[:, :3], np.asarray(c.bones, np.int64).reshape(-1, 2)
    X, B = c
    return np.asarray(X, np.float64)[:, :3], np.asarray(B, np.int64).reshape(-1, 2)


def curve_samples(curve, step):
    """The joints and points at most ``step`` apart along every bone of ``curve`` (a Skeleton
    or (joints, bones))."""
    X, B = _curve(curve)
    out = [X]
    for a, b in B:
        n = max(int(np.ceil(np.linalg.norm(X[b] - X[a]) / step)), 1)
        t = np.linspace(0.0, 1.0, n + 1)[:, None]
        out.append(X[a] * (1 - t) + X[b] * t)
    return np.vstack(out)


def distance_to_curve(P, curve, block=4096):
    """(n,) exact distance of each point to the nearest point of the bones of ``curve`` (a
    curve without bones: its joints)."""
    X, B = _curve(curve)
    P = np.asarray(P, np.float64).reshape(-1, 3)
    if not len(B):
        return np.sqrt(((P[:, None] - X[None]) ** 2).sum(-1)).min(axis=1)
    A, Bv = X[B[:, 0]], X[B[:, 1]]
    d = Bv - A
    dd = np.maximum((d * d).sum(1), 1e-300)
    out = np.empty(len(P))
    for s in range(0, len(P), block):
        Q = P[s:s + block, None, :]
        t = np.clip(((Q - A[None]) * d[None]).sum(-1) / dd[None], 0.0, 1.0)
        out[s:s + block] = np.sqrt(((Q - A[None] - t[..., None] * d[None]) ** 2).sum(-1)).min(1)
    return out


def curve_gap(a, b, D, step=1e-3):
    """The largest distance from a point of either curve to the other, / D (points every
    ``step`` D along each, joints included; distances to the other's bones exact)."""
    da = distance_to_curve(curve_samples(a, step * D), b)
    db = distance_to_curve(curve_samples(b, step * D), a)
    return float(max(da.max(), db.max()) / D)


def curve_mean_gap(a, b, D, step=1e-3):
    """The larger of the two mean distances (each curve's points, every ``step`` D along its
    bones, to the other curve), / D: a symmetric curve distance that a short stub barely
    changes."""
    da = distance_to_curve(curve_samples(a, step * D), b)
    db = distance_to_curve(curve_samples(b, step * D), a)
    return float(max(da.mean(), db.mean()) / D)


def turning_angles(joints, bones):
    """(joint ids, angle in degrees) at every joint of degree 2 between its two bones'
    directions (0: straight on); bones of no length are skipped."""
    X, B = _curve((joints, bones))
    deg = np.bincount(B.ravel(), minlength=len(X))
    ids, ang = [], []
    for j in np.flatnonzero(deg == 2):
        nb = [int(b[1] if b[0] == j else b[0]) for b in B if j in b]
        u, v = X[j] - X[nb[0]], X[nb[1]] - X[j]
        nu, nv = np.linalg.norm(u), np.linalg.norm(v)
        if nu == 0 or nv == 0:
            continue
        ids.append(j)
        ang.append(np.degrees(np.arccos(np.clip(u @ v / (nu * nv), -1.0, 1.0))))
    return np.asarray(ids, np.int64), np.asarray(ang, np.float64)


def total_turning(joints, bones) -> float:
    """The sum of the turning angles (degrees) at the chain joints: 0 for straight chains."""
    return float(turning_angles(joints, bones)[1].sum())


def bending(joints, bones) -> float:
    """The chains' discrete bending: the sum of ``1 - cos(theta)`` over the joints of degree 2
    (0 straight on, 1 at a right angle): how much the chains turn, each turn counted by its
    sharpness, whatever the curve's size."""
    return float((1.0 - np.cos(np.radians(turning_angles(joints, bones)[1]))).sum())


def chain_straightness(joints, bones) -> float:
    """The largest distance of a joint from the straight line through the curve's two farthest
    joints, relative to that line's length (0: every joint on one line)."""
    X, _ = _curve((joints, bones))
    d2 = ((X[:, None] - X[None]) ** 2).sum(-1)
    i, j = np.unravel_index(np.argmax(d2), d2.shape)
    u = X[j] - X[i]
    L = float(np.linalg.norm(u))
    if L == 0:
        return 0.0
    u = u / L
    off = (X - X[i]) - ((X - X[i]) @ u)[:, None] * u
    return float(np.linalg.norm(off, axis=1).max() / L)


def silhouette_distance(P, joints, bones, block=2048):
    """(n,) signed distance of each point to the skeleton's silhouette, the union of its bones'
    round cones (the balls at the joints and the cones tangent to each bone's two balls):
    negative inside. Exact (Quilez's round-cone distance), the minimum over the bones."""
    P = np.asarray(P, np.float64).reshape(-1, 3)
    Jn = np.asarray(joints, np.float64)
    bones = np.asarray(bones, np.int64).reshape(-1, 2)
    a, b = Jn[bones[:, 0], :3], Jn[bones[:, 1], :3]
    r1, r2 = np.abs(Jn[bones[:, 0], 3]), np.abs(Jn[bones[:, 1], 3])
    swap = r2 > r1                                   # the formula wants r1 >= r2
    a[swap], b[swap] = b[swap].copy(), a[swap].copy()
    r1[swap], r2[swap] = r2[swap].copy(), r1[swap].copy()
    ba = b - a
    l2 = np.maximum((ba * ba).sum(1), 1e-300)
    rr = r1 - r2
    a2 = l2 - rr * rr
    out = np.empty(len(P))
    for s0 in range(0, len(P), block):
        pa = P[s0:s0 + block, None, :] - a[None]
        y = (pa * ba[None]).sum(-1)
        z = y - l2
        x2 = ((pa * l2[None, :, None] - ba[None] * y[..., None]) ** 2).sum(-1)
        y2, z2 = y * y * l2, z * z * l2
        k = rr * rr * x2
        far = np.sign(z) * a2 * z2 > k
        near = np.sign(y) * a2 * y2 < k
        d = (np.sqrt(np.maximum(x2 * a2 / l2, 0.0)) + y * rr) / l2 - r1
        d = np.where(near, np.sqrt(x2 + y2) / l2 - r1, d)
        d = np.where(far, np.sqrt(x2 + z2) / l2 - r2, d)
        out[s0:s0 + block] = d.min(axis=1)
    return out
