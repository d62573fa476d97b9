"""Procedural test meshes with known answers (closed, consistently oriented, triangle meshes)."""

from __future__ import annotations

import numpy as np

__all__ = ["capsule", "torus", "tube_along", "star", "bent_capsule", "two_capsules"]


def _ring_strip(n_rings: int, n_around: int, offset: int = 0) -> np.ndarray:
    """Triangles joining consecutive rings of n_around vertices (rings stored one after another)."""
    r = np.arange(n_rings - 1)[:, None]
    k = np.arange(n_around)[None, :]
    a = offset + r * n_around + k
    b = offset + r * n_around + (k + 1) % n_around
    c = a + n_around
    d = b + n_around
    return np.concatenate([np.stack([a, b, d], -1).reshape(-1, 3), np.stack([a, d, c], -1).reshape(-1, 3)])


def tube_along(path: np.ndarray, radius, n_around: int = 24, cap_rings: int = 6):
    """A closed tube of given radius around a polyline ``path`` (p, 3), with hemispherical caps.

    ``radius`` is a scalar or one value per path point. Returns (V, F).
    """
    path = np.asarray(path, float)
    R = np.broadcast_to(np.asarray(radius, float), (len(path),)).copy()
    T = np.gradient(path, axis=0)
    T /= np.linalg.norm(T, axis=1, keepdims=True)
    # Parallel-transport frame so rings do not twist.
    N = np.zeros_like(T)
    ref = np.array([0.0, 0.0, 1.0]) if abs(T[0, 2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    N[0] = np.cross(T[0], ref); N[0] /= np.linalg.norm(N[0])
    for i in range(1, len(T)):
        n = N[i - 1] - T[i] * (N[i - 1] @ T[i]); N[i] = n / np.linalg.norm(n)
    B = np.cross(T, N)
    ang = 2 * np.pi * np.arange(n_around) / n_around
    ca, sa = np.cos(ang), np.sin(ang)
    rings = []
    # start cap (excluding pole), body, end cap
    phis = np.linspace(0, np.pi / 2, cap_rings + 1)[1:-1]
    for phi in phis:  # from near the start pole towards the equator
        c = path[0] - T[0] * R[0] * np.cos(phi)
        rings.append(c + R[0] * np.sin(phi) * (ca[:, None] * N[0] + sa[:, None] * B[0]))
    for i in range(len(path)):
        rings.append(path[i] + R[i] * (ca[:, None] * N[i] + sa[:, None] * B[i]))
    for phi in phis[::-1]:
        c = path[-1] + T[-1] * R[-1] * np.cos(phi)
        rings.append(c + R[-1] * np.sin(phi) * (ca[:, None] * N[-1] + sa[:, None] * B[-1]))
    body = np.concatenate(rings)
    nr = len(rings)
    p0 = path[0] - T[0] * R[0]
    p1 = path[-1] + T[-1] * R[-1]
    V = np.concatenate([body, p0[None], p1[None]])
    F = [_ring_strip(nr, n_around)]
    k = np.arange(n_around)
    i0, i1 = len(body), len(body) + 1
    F.append(np.stack([np.full(n_around, i0), (k + 1) % n_around, k], -1))
    last = (nr - 1) * n_around
    F.append(np.stack([np.full(n_around, i1), last + k, last + (k + 1) % n_around], -1))
    F = np.concatenate(F).astype(np.int64)
    # Orient outwards (signed volume positive).
    if _signed_volume(V, F) < 0:
        F = F[:, ::-1].copy()
    return V, F


def _signed_volume(V, F) -> float:
    return float(np.einsum("ij,ij->i", V[F[:, 0]], np.cross(V[F[:, 1]], V[F[:, 2]])).sum() / 6)


def capsule(radius: float = 1.0, length: float = 6.0, n_around: int = 32, n_body: int = 40, cap_rings: int = 8):
    """Capsule along z from 0 to ``length`` (segment between cap centres), radius ``radius``."""
    path = np.stack([np.zeros(n_body), np.zeros(n_body), np.linspace(0, length, n_body)], 1)
    return tube_along(path, radius, n_around, cap_rings)


def bent_capsule(radius: float = 0.5, arm: float = 4.0, n: int = 30, n_around: int = 24):
    """A capsule bent into an L: along +x then +z, a rounded corner of radius 1 at the bend."""
    s = np.linspace(0, 1, n)
    a = np.stack([-arm + (arm - 1) * s, 0 * s, 0 * s], 1)
    th = np.linspace(0, np.pi / 2, 12)[1:-1]
    corner = np.stack([np.sin(th) - 1 + 0 * th, 0 * th, 1 - np.cos(th)], 1) + [0, 0, 0]
    corner = np.stack([-1 + np.sin(th), 0 * th, 1 - np.cos(th)], 1)
    b = np.stack([0 * s, 0 * s, 1 + (arm - 1) * s], 1)
    path = np.concatenate([a, corner, b])
    return tube_along(path, radius, n_around)


def torus(R: float = 3.0, r: float = 1.0, n_major: int = 64, n_minor: int = 24):
    """Torus around z: genus 1."""
    u = 2 * np.pi * np.arange(n_major) / n_major
    v = 2 * np.pi * np.arange(n_minor) / n_minor
    U, W = np.meshgrid(u, v, indexing="ij")
    X = (R + r * np.cos(W)) * np.cos(U)
    Y = (R + r * np.cos(W)) * np.sin(U)
    Z = r * np.sin(W)
    V = np.stack([X, Y, Z], -1).reshape(-1, 3)
    i = np.arange(n_major)[:, None]; j = np.arange(n_minor)[None, :]
    a = i * n_minor + j
    b = ((i + 1) % n_major) * n_minor + j
    c = ((i + 1) % n_major) * n_minor + (j + 1) % n_minor
    d = i * n_minor + (j + 1) % n_minor
    F = np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3), np.stack([a, c, d], -1).reshape(-1, 3)])
    if _signed_volume(V, F) < 0:
        F = F[:, ::-1].copy()
    return V, F.astype(np.int64)


def _manifold_from(V, F):
    import manifold3d as m3

    return m3.Manifold(m3.Mesh(vert_properties=np.asarray(V, np.float32), tri_verts=np.asarray(F, np.uint32)))


def _to_arrays(man):
    mesh = man.to_mesh()
    return np.asarray(mesh.vert_properties[:, :3], float), np.asarray(mesh.tri_verts, np.int64)


def star(n_arms: int = 4, arm: float = 4.0, radius: float = 0.5, n_around: int = 24):
    """``n_arms`` capsules from the origin in the xy-plane, united into ONE closed manifold mesh
    (manifold3d booleans). Arm k points along angle 2*pi*k/n_arms; its tip centre is at ``arm``."""
    ang = 2 * np.pi * np.arange(n_arms) / n_arms
    union = None
    for a in ang:
        u = np.array([np.cos(a), np.sin(a), 0.0])
        path = np.linspace(0, 1, 30)[:, None] * (arm * u)
        man = _manifold_from(*tube_along(path, radius, n_around))
        union = man if union is None else union + man
    return _to_arrays(union)


def two_capsules():
    """Two disjoint capsules: two components."""
    V1, F1 = capsule(length=4.0)
    V2, F2 = capsule(length=3.0)
    V2 = V2 + [5.0, 0, 0]
    return np.concatenate([V1, V2]), np.concatenate([F1, F2 + len(V1)])
