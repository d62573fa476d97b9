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


def torus(R: float = 3.0, r: float = 1.0, n_major: int = 64, n_minor: int = 24, diagonal: int = 0):
    """Torus around z: genus 1. Each quad of the (u, v) grid is split along one diagonal
    (``diagonal`` 0) or the other (1): the same vertices, another triangulation."""
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
    if diagonal:
        F = np.concatenate([np.stack([a, b, d], -1).reshape(-1, 3), np.stack([b, c, d], -1).reshape(-1, 3)])
    else:
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


def star(n_arms: int = 4, arm: float = 4.0, radius: float = 0.5, n_around: int = 24, rings: int = 30):
    """``n_arms`` capsules from the origin in the xy-plane, united into ONE closed manifold mesh
    (manifold3d booleans). Arm k points along angle 2*pi*k/n_arms; its tip centre is at ``arm``;
    ``rings`` rings of ``n_around`` vertices along each arm."""
    ang = 2 * np.pi * np.arange(n_arms) / n_arms
    union = None
    for a in ang:
        u = np.array([np.cos(a), np.sin(a), 0.0])
        path = np.linspace(0, 1, rings)[:, None] * (arm * u)
        man = _manifold_from(*tube_along(path, radius, n_around))
        union = man if union is None else union + man
    return _to_arrays(union)


def two_capsules():
    """Two disjoint capsules: two components."""
    V1, F1 = capsule(length=4.0)
    V2, F2 = capsule(length=3.0)
    V2 = V2 + [5.0, 0, 0]
    return np.concatenate([V1, V2]), np.concatenate([F1, F2 + len(V1)])


# -- shapes with a known curve skeleton (issue 10), and their analytic curves --------------------
# A curve is returned as (X (k, 3) float, bones (b, 2) int): any form
# ``curveskel_addon.measure.quality.curve_distances`` takes.

__all__ += ["board", "board_with_tab", "BOARD"]
__all__ += ["plate_with_holes", "box_bar", "t_beam", "t_beam_centroid_y", "bent_tube", "polyline", "union_curves",
            "capsule_axis", "torus_axis", "bent_capsule_axis", "star_axes", "box_bar_axis",
            "bent_tube_axis", "plate_hole_rings", "PLATE", "BAR", "BENT_TUBE"]

#: The plate with three holes: size (x, y, z), hole radius, hole centres on the x axis.
PLATE = {"size": (6.0, 2.0, 0.4), "hole_radius": 0.5, "hole_x": (-2.0, 0.0, 2.0)}
#: The box-section bar: size (x, y, z), centred on the origin, axis along x.
BAR = {"size": (8.0, 1.0, 1.0)}
#: The bent tube: a quarter circle of radius ``bend`` in the xy-plane around the origin.
BENT_TUBE = {"bend": 3.0, "radius": 0.5, "angle": np.pi / 2}


def plate_with_holes(size=PLATE["size"], hole_radius=PLATE["hole_radius"], hole_x=PLATE["hole_x"],
                     n_hole: int = 48, edge: float = 0.15):
    """A box ``size`` centred on the origin minus vertical cylinders (the holes, through the
    plate along z) centred at ``(x, 0)`` for x in ``hole_x`` (manifold3d booleans), edges
    refined to at most ``edge``. Genus ``len(hole_x)``. Returns (V, F)."""
    import manifold3d as m3

    plate = m3.Manifold.cube(list(size), center=True)
    for x in hole_x:
        plate = plate - m3.Manifold.cylinder(2 * size[2], hole_radius, hole_radius, n_hole,
                                             True).translate([x, 0.0, 0.0])
    return _to_arrays(plate.refine_to_length(edge))


def frames_and_bar(frame=(2.0, 2.0, 0.4), hole_radius=0.55, frame_x=2.5, bar=(3.2, 0.3, 0.3),
                   edge: float = 0.15):
    """Two square frames (a box ``frame`` with a hole of ``hole_radius`` through it along z)
    centred at x = -``frame_x`` and ``frame_x``, joined by a square bar ``bar`` along x
    (a pair of glasses: two loops and a bridge of their own); manifold3d, edges refined to
    ``edge``. Genus 2. Returns (V, F)."""
    import manifold3d as m3

    solid = m3.Manifold.cube(list(bar), center=True)
    for x in (-frame_x, frame_x):
        f = (m3.Manifold.cube(list(frame), center=True)
             - m3.Manifold.cylinder(2 * frame[2], hole_radius, hole_radius, 48, True))
        solid = solid + f.translate([x, 0.0, 0.0])
    return _to_arrays(solid.refine_to_length(edge))


def t_beam(length: float = 8.0, web=(1.5, 0.2), flange=(1.2, 0.2), edge: float = 0.15):
    """A T-section beam along x (rocker-arm's lever, made plain): a web ``web`` = (height,
    thickness) from y = -height to 0, centred on z = 0, under a flange ``flange`` = (width,
    thickness) from y = 0 up, centred on z = 0; manifold3d union, edges refined to ``edge``.
    The section's area centroid is at y = :func:`t_beam_centroid_y`, z = 0. Returns (V, F)."""
    import manifold3d as m3

    (wh, wt), (fw, ft) = web, flange
    w = m3.Manifold.cube([length, wh, wt], center=True).translate([0.0, -wh / 2, 0.0])
    # the flange overlaps the web by a hair so the union is one solid
    f = m3.Manifold.cube([length, ft + 1e-3, fw], center=True).translate([0.0, ft / 2 - 5e-4, 0.0])
    return _to_arrays((w + f).refine_to_length(edge))


def t_beam_centroid_y(web=(1.5, 0.2), flange=(1.2, 0.2)) -> float:
    """The y of :func:`t_beam`'s section's area centroid."""
    (wh, wt), (fw, ft) = web, flange
    return (wh * wt * (-wh / 2) + fw * ft * (ft / 2)) / (wh * wt + fw * ft)


def box_bar(size=BAR["size"], edge: float = 0.15):
    """A box of ``size`` centred on the origin (long axis x), every edge refined to at most
    ``edge`` (a plain 12-triangle box has no vertices to fit). Returns (V, F)."""
    import manifold3d as m3

    return _to_arrays(m3.Manifold.cube(list(size), center=True).refine_to_length(edge))


#: A board (plank): size (x, y, z), long axis x, flat in z.
BOARD = {"size": (6.0, 2.0, 0.4)}


def board(size=BOARD["size"], edge: float = 0.15):
    """A flat box ``size`` centred on the origin (a plank, long axis x, thin along z), edges
    refined to at most ``edge``. Its curve skeleton is the middle line y = z = 0. Returns
    (V, F)."""
    return box_bar(size, edge)


def board_with_tab(size=BOARD["size"], tab=(0.8, 0.8), at: float = 0.5, edge: float = 0.12):
    """:func:`board` with a square tab ``tab`` = (along x, out along y) of the board's
    thickness on its +y side, centred at x = ``at`` (manifold3d union): a part as wide as it is
    long, in the board's own sheet. Returns (V, F)."""
    import manifold3d as m3

    L, W, t = size
    tx, ty = tab
    # the tab overlaps the board by 0.1 so the union is one solid
    part = m3.Manifold.cube([tx, ty + 0.1, t], center=True)
    part = part.translate([at, W / 2 + ty / 2 - 0.05, 0])
    return _to_arrays((m3.Manifold.cube(list(size), center=True) + part).refine_to_length(edge))


def bent_tube(bend=BENT_TUBE["bend"], radius=BENT_TUBE["radius"], angle=BENT_TUBE["angle"],
              n: int = 40, n_around: int = 24):
    """A tube of ``radius`` along the arc of radius ``bend`` around the z axis from angle 0 to
    ``angle`` (in the xy-plane), hemispherical caps. Returns (V, F)."""
    th = np.linspace(0.0, angle, n)
    path = np.stack([bend * np.cos(th), bend * np.sin(th), 0 * th], 1)
    return tube_along(path, radius, n_around)


#: A capsule (radius 1, axis z from 0 to 6) with a flat round flap (an ear) on its side: a disc
#: of ``radius`` and ``thickness`` in the xz-plane, centred at ``centre``, its near edge 0.2
#: inside the capsule.
FLAP = {"radius": 1.5, "thickness": 0.15, "centre": (2.3, 0.0, 3.0)}
__all__ += ["capsule_with_flap", "FLAP"]


def capsule_with_flap(radius=FLAP["radius"], thickness=FLAP["thickness"], centre=FLAP["centre"],
                      edge: float = 0.15):
    """:func:`capsule` united with a disc (the flap, see ``FLAP``), manifold3d booleans, edges
    refined to at most ``edge``. Returns (V, F)."""
    import manifold3d as m3

    disc = m3.Manifold.cylinder(thickness, radius, radius, 64, True).rotate([90, 0, 0])
    body = _manifold_from(*capsule(radius=1.0, length=6.0))
    return _to_arrays((body + disc.translate(list(centre))).refine_to_length(edge))


def polyline(P, closed: bool = False):
    """The curve through points ``P`` (k, 3) in order (and back to the first if ``closed``)."""
    P = np.asarray(P, float).reshape(-1, 3)
    k = len(P)
    bones = np.stack([np.arange(k - 1), np.arange(1, k)], 1)
    if closed:
        bones = np.vstack([bones, [[k - 1, 0]]])
    return P, bones.astype(np.int64)


def union_curves(*curves):
    """One curve made of several (joints renumbered)."""
    X, B, off = [], [], 0
    for x, b in curves:
        X.append(np.asarray(x, float))
        B.append(np.asarray(b, np.int64) + off)
        off += len(x)
    return np.vstack(X), np.vstack(B)


def capsule_axis(length: float = 6.0):
    """:func:`capsule`'s axis: the segment between its cap centres."""
    return polyline([[0.0, 0, 0], [0, 0, length]])


def torus_axis(R: float = 3.0, n: int = 512):
    """:func:`torus`'s core circle (radius R in the xy-plane)."""
    u = 2 * np.pi * np.arange(n) / n
    return polyline(np.stack([R * np.cos(u), R * np.sin(u), 0 * u], 1), closed=True)


def bent_capsule_axis(arm: float = 4.0, n: int = 128):
    """:func:`bent_capsule`'s axis: x from -arm to -1, a quarter circle of radius 1 around
    (-1, 0, 1), z from 1 to arm."""
    th = np.linspace(0, np.pi / 2, n)
    corner = np.stack([-1 + np.sin(th), 0 * th, 1 - np.cos(th)], 1)
    return polyline(np.vstack([[[-arm, 0, 0]], corner, [[0, 0, arm]]]))


def star_axes(n_arms: int = 4, arm: float = 4.0):
    """:func:`star`'s axes: a segment from the origin to each arm's tip centre."""
    ang = 2 * np.pi * np.arange(n_arms) / n_arms
    X = np.vstack([[0.0, 0, 0], np.stack([arm * np.cos(ang), arm * np.sin(ang), 0 * ang], 1)])
    return X, np.stack([np.zeros(n_arms, np.int64), 1 + np.arange(n_arms)], 1)


def bent_tube_axis(bend=BENT_TUBE["bend"], angle=BENT_TUBE["angle"], n: int = 512):
    """:func:`bent_tube`'s axis: the arc itself (the caps' medial axis ends at their centres)."""
    th = np.linspace(0, angle, n)
    return polyline(np.stack([bend * np.cos(th), bend * np.sin(th), 0 * th], 1))


def box_bar_axis(size=BAR["size"]):
    """:func:`box_bar`'s curve skeleton: the long axis where the medial axis is a line, i.e.
    up to half the (square) section's width from each end face (beyond it the medial axis
    opens into the end faces' pyramids of sheets)."""
    L, w = size[0], min(size[1], size[2])
    return polyline([[-L / 2 + w / 2, 0, 0], [L / 2 - w / 2, 0, 0]])


def plate_hole_rings(size=PLATE["size"], hole_radius=PLATE["hole_radius"], hole_x=PLATE["hole_x"],
                     n: int = 720):
    """The plate's curve skeleton: one loop around each hole in the mid-plane z = 0 through
    the middle of the material.

    Loop k at angle theta is the point ``c_k + s u(theta)`` equidistant from hole k's wall and
    from the rest of the boundary (the plate's sides and the other holes): the medial axis of
    the plate's section, without the branches into its four corners. Neighbouring loops share
    the segment on the bisector between their holes (the rung ``x = (x_k + x_k+1) / 2``).
    """
    hx, hy = size[0] / 2, size[1] / 2
    C = np.array([[x, 0.0] for x in hole_x])
    th = 2 * np.pi * np.arange(n) / n
    u = np.stack([np.cos(th), np.sin(th)], 1)
    rings = []
    for k, c in enumerate(C):
        others = np.delete(C, k, axis=0)
        with np.errstate(divide="ignore"):
            sx = np.where(np.abs(u[:, 0]) > 1e-12, (hx - np.sign(u[:, 0]) * c[0]) / np.abs(u[:, 0]), np.inf)
            sy = np.where(np.abs(u[:, 1]) > 1e-12, (hy - np.sign(u[:, 1]) * c[1]) / np.abs(u[:, 1]), np.inf)
        lo, hi = np.full(n, float(hole_radius)), np.minimum(sx, sy)
        for _ in range(60):        # bisection: (s - a) - distance to the rest grows with s
            s = 0.5 * (lo + hi)
            p = c + s[:, None] * u
            rest = np.minimum(hx - np.abs(p[:, 0]), hy - np.abs(p[:, 1]))
            if len(others):
                rest = np.minimum(rest, (np.linalg.norm(p[:, None] - others[None], axis=2)
                                         - hole_radius).min(axis=1))
            inside = (s - hole_radius) < rest
            lo, hi = np.where(inside, s, lo), np.where(inside, hi, s)
        p = c + 0.5 * (lo + hi)[:, None] * u
        rings.append(polyline(np.column_stack([p, np.zeros(n)]), closed=True))
    return union_curves(*rings)


# -- many-part models (issue 31) -----------------------------------------------------------------
#: The six-part figure (z up, facing -y, mirror plane x = 0): each part a closed capsule or
#: ellipsoid, overlapping its neighbours as kitbashed game and CAD figures do. Capsules are
#: (axis start, axis end, radius): the surface reaches ``radius`` beyond both ends.
SIX_PART = {
    "torso": ((0.0, 0.0, 0.95), (0.0, 0.0, 1.55), 0.32),          # z 0.63 .. 1.87
    "head": ((0.0, 0.0, 2.05), (0.20, 0.22, 0.25)),                # ellipsoid: centre, semi-axes
    "arm.L": ((0.32, 0.0, 1.45), (1.37, 0.0, 1.45), 0.09),         # x 0.23 .. 1.46 (in the torso to 0.32)
    "arm.R": ((-0.32, 0.0, 1.45), (-1.37, 0.0, 1.45), 0.09),
    "leg.L": ((0.16, 0.0, 0.85), (0.16, 0.0, 0.20), 0.12),         # z 0.08 .. 0.97 (torso's bottom 0.67)
    "leg.R": ((-0.16, 0.0, 0.85), (-0.16, 0.0, 0.20), 0.12),
}
__all__ += ["six_part_figure", "SIX_PART"]


def six_part_figure(parts=SIX_PART, n_around: int = 16, head_subdivisions: int = 3):
    """A figure of six separate, overlapping closed parts (torso, head, two arms, two legs; see
    ``SIX_PART``), concatenated into one mesh of six components, never united: the shape of many
    game, kitbash and CAD assets. About 2.7k vertices.

    Returns (V, F, part): ``part`` (n,) int, the index into ``list(parts)`` of each vertex's part.
    """
    import trimesh

    Vs, Fs, ids = [], [], []
    off = 0
    for k, (name, spec) in enumerate(parts.items()):
        if len(spec) == 3:                      # capsule
            a, b, r = np.asarray(spec[0], float), np.asarray(spec[1], float), float(spec[2])
            n_path = max(int(np.ceil(np.linalg.norm(b - a) / (0.6 * r))), 2) + 1
            around = 2 * n_around if name == "torso" else n_around
            V, F = tube_along(a + np.linspace(0, 1, n_path)[:, None] * (b - a), r, around, 5)
        else:                                   # ellipsoid
            sphere = trimesh.creation.icosphere(subdivisions=head_subdivisions)
            V = np.asarray(sphere.vertices, float) * np.asarray(spec[1], float) + np.asarray(spec[0], float)
            F = np.asarray(sphere.faces, np.int64)
            if _signed_volume(V, F) < 0:
                F = F[:, ::-1].copy()
        Vs.append(V)
        Fs.append(F + off)
        ids.append(np.full(len(V), k))
        off += len(V)
    return np.concatenate(Vs), np.concatenate(Fs), np.concatenate(ids)


# -- awkward shapes of issue 30 (a new user's meshes, not tuned on) -----------------------------
#: A flat hexagonal nut: across-corners radius of the hexagon, hole radius, thickness (along z).
NUT = {"outer": 1.2, "hole": 0.5, "thickness": 0.4}
#: A bone with two knobs at each end: a shaft along x from -shaft/2 to shaft/2 of radius
#: ``radius``; at each end two balls of radius ``knob`` centred ``spread`` off the axis in y.
KNOBBED = {"shaft": 4.0, "radius": 0.3, "knob": 0.45, "spread": 0.4}
#: A T: a trunk along x from -4 to 4 (radius 1), a limb along +y from the trunk's axis to 4
#: (radius 0.5).
TEE = {"trunk": 4.0, "trunk_radius": 1.0, "limb": 4.0, "limb_radius": 0.5}
__all__ += ["hex_nut", "NUT", "knobbed_bone", "KNOBBED", "tee", "TEE", "uniform_capsule"]


def hex_nut(outer=NUT["outer"], hole=NUT["hole"], thickness=NUT["thickness"], edge: float = 0.08):
    """A flat hexagonal prism (corners at radius ``outer`` in the xy-plane, thickness along z,
    centred on the origin) with a round hole of radius ``hole`` through it along z (manifold3d
    booleans), edges refined to ``edge``: a ring whose outline has six corners. Genus 1.
    Its curve skeleton is one loop round the hole, through the middle of the material."""
    import manifold3d as m3

    prism = m3.Manifold.cylinder(thickness, outer, outer, 6, True)
    bore = m3.Manifold.cylinder(2 * thickness, hole, hole, 48, True)
    return _to_arrays((prism - bore).refine_to_length(edge))


def knobbed_bone(shaft=KNOBBED["shaft"], radius=KNOBBED["radius"], knob=KNOBBED["knob"],
                 spread=KNOBBED["spread"], edge: float = 0.08):
    """A bone (a femur, a dog's chew): a capsule along x with two balls at each end, their
    centres ``(+-(shaft/2 + knob/2), +-spread, 0)`` (manifold3d union), edges refined to
    ``edge``. Its curve skeleton forks at each end, one branch into each knob."""
    import manifold3d as m3

    path = np.linspace(0, 1, 30)[:, None] * [shaft, 0.0, 0.0] - [shaft / 2, 0.0, 0.0]
    solid = _manifold_from(*tube_along(path, radius, 24))
    for c in knob_centres(shaft, knob, spread):
        solid = solid + m3.Manifold.sphere(knob, 48).translate(list(c))
    return _to_arrays(solid.refine_to_length(edge))


def knob_centres(shaft=KNOBBED["shaft"], knob=KNOBBED["knob"], spread=KNOBBED["spread"]):
    """(4, 3) the centres of :func:`knobbed_bone`'s knobs: -x end first."""
    x = shaft / 2 + knob / 2
    return np.array([[-x, -spread, 0.0], [-x, spread, 0.0], [x, -spread, 0.0], [x, spread, 0.0]])


def tee(trunk=TEE["trunk"], trunk_radius=TEE["trunk_radius"], limb=TEE["limb"],
        limb_radius=TEE["limb_radius"], n_around: int = 32):
    """A trunk (a capsule along x from -trunk to trunk) and a thinner limb (a capsule along +y
    from the trunk's axis to ``limb``), united (manifold3d). Its curve skeleton: the trunk's
    axis and the limb's, meeting in one junction on the trunk's axis."""
    a = np.linspace(-trunk, trunk, 40)[:, None] * [1.0, 0, 0]
    b = np.linspace(0, limb, 20)[:, None] * [0, 1.0, 0]
    return _to_arrays(_manifold_from(*tube_along(a, trunk_radius, n_around))
                      + _manifold_from(*tube_along(b, limb_radius, n_around)))


def uniform_capsule(radius: float = 0.4, height: float = 2.0, edge: float | None = None):
    """trimesh's ``creation.capsule(height, radius)`` shape (cap centres at z = -height/2 and
    height/2) triangulated evenly: rings as far apart as the points around them (``edge``,
    default a 32nd of the circumference), caps of as many rings."""
    edge = 2 * np.pi * radius / 32 if edge is None else edge
    n_around = int(np.ceil(2 * np.pi * radius / edge))
    n_body = int(np.ceil(height / edge)) + 1
    cap_rings = int(np.ceil(np.pi * radius / 2 / edge))
    path = np.stack([np.zeros(n_body), np.zeros(n_body), np.linspace(-height / 2, height / 2, n_body)], 1)
    return tube_along(path, radius, n_around, cap_rings)


#: The 15-part insect (z up, head towards -y, mirror plane x = 0): head and body (ellipsoids:
#: centre, semi-axes), the two antennae as one tube bent inside the head (a path and its
#: radius: :func:`_antennae_path`), and six legs of two capsules each (femur from inside the body to the knee, tibia
#: from the knee to the ground; capsules (axis start, axis end, radius) overlap at the knee).
INSECT = {
    "head": ((0.0, -0.58, 0.55), (0.15, 0.14, 0.13)),
    "body": ((0.0, 0.10, 0.50), (0.22, 0.60, 0.18)),
    "antennae": ("path", 0.018),
}
for _k, (_y, _dy) in enumerate(((-0.2, -0.15), (0.0, 0.0), (0.2, 0.15))):
    for _side, _sx in (("L", 1.0), ("R", -1.0)):
        INSECT[f"femur{_k}.{_side}"] = ((0.10 * _sx, _y, 0.50), (0.45 * _sx, _y + _dy, 0.66), 0.035)
        INSECT[f"tibia{_k}.{_side}"] = ((0.45 * _sx, _y + _dy, 0.66), (0.62 * _sx, _y + 2 * _dy, 0.02), 0.03)
__all__ += ["insect", "INSECT", "sphere_grid"]


def _antennae_path(n: int = 12):
    """The antennae's axis: two straight feelers out and up from the head, joined by a bend at
    the head's centre (inside the head: only the feelers show)."""
    centre = np.array([0.0, -0.58, 0.55])
    tips = np.array([[0.30, -0.90, 0.85], [-0.30, -0.90, 0.85]])
    u = (tips - centre) / np.linalg.norm(tips - centre, axis=1, keepdims=True)
    p1, p2 = centre + 0.06 * u[0], centre + 0.06 * u[1]
    s = np.linspace(0.0, 1.0, n)[:, None]
    t = np.linspace(0.0, 1.0, 9)[1:-1, None]
    bend = (1 - t) ** 2 * p1 + 2 * t * (1 - t) * centre + t * t * p2      # a smooth turn
    return np.concatenate([tips[0] + s * (p1 - tips[0]), bend, p2 + s * (tips[1] - p2)])


def insect(parts=INSECT, n_around: int = 12, subdivisions: int = 2):
    """An insect of 15 separate, overlapping closed parts (see ``INSECT``): body segments
    (head, body), the antennae (one tube through the head, its two ends outside) and six legs
    of two parts each. About 4.7k faces.

    Returns (V, F, part): ``part`` (n,) int, the index into ``list(parts)`` of each vertex's part.
    """
    import trimesh

    Vs, Fs, ids = [], [], []
    off = 0
    for k, (name, spec) in enumerate(parts.items()):
        if spec[0] == "path":
            V, F = tube_along(_antennae_path(), spec[1], n_around, 3)
        elif len(spec) == 3:
            a, b, r = np.asarray(spec[0], float), np.asarray(spec[1], float), float(spec[2])
            n_path = max(int(np.ceil(np.linalg.norm(b - a) / (1.5 * r))), 2) + 1
            V, F = tube_along(a + np.linspace(0, 1, n_path)[:, None] * (b - a), r, n_around, 3)
        else:
            sphere = trimesh.creation.icosphere(subdivisions=subdivisions)
            V = np.asarray(sphere.vertices, float) * np.asarray(spec[1], float) + np.asarray(spec[0], float)
            F = np.asarray(sphere.faces, np.int64)
            if _signed_volume(V, F) < 0:
                F = F[:, ::-1].copy()
        Vs.append(V)
        Fs.append(F + off)
        ids.append(np.full(len(V), k))
        off += len(V)
    return np.concatenate(Vs), np.concatenate(Fs), np.concatenate(ids)


def sphere_grid(rows: int = 10, cols: int = 20, radius: float = 0.5, pitch: float = 1.6,
                subdivisions: int = 1):
    """``rows * cols`` equal closed spheres on a grid in the xy-plane, ``pitch`` apart (a gap of
    ``pitch - 2 radius`` between neighbours), each an icosphere: one mesh of that many parts.

    Returns (V, F, part)."""
    import trimesh

    sphere = trimesh.creation.icosphere(subdivisions=subdivisions)
    S = np.asarray(sphere.vertices, float) * radius
    T = np.asarray(sphere.faces, np.int64)
    if _signed_volume(S, T) < 0:
        T = T[:, ::-1].copy()
    i, j = np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")
    centres = np.stack([j.ravel() * pitch, i.ravel() * pitch, np.zeros(rows * cols)], 1)
    n = len(centres)
    V = (S[None] + centres[:, None]).reshape(-1, 3)
    F = (T[None] + (np.arange(n) * len(S))[:, None, None]).reshape(-1, 3)
    return V, F, np.repeat(np.arange(n), len(S))


#: Small free parts on the six-part figure (sphere centre, radius): two eyes just off the
#: head's front and a button just off the torso's front, each a gap of more than half its own
#: radius away (not touching: they float free).
DETAILS = {
    "eye.L": ((0.08, -0.25, 2.10), 0.03),
    "eye.R": ((-0.08, -0.25, 2.10), 0.03),
    "button": ((0.0, -0.39, 1.20), 0.04),
}
__all__ += ["figure_with_details", "DETAILS"]


def figure_with_details(details=DETAILS, subdivisions: int = 2):
    """The six-part figure (:func:`six_part_figure`) with small free parts (``DETAILS``): nine
    parts. Returns (V, F, part), ``part`` indexing ``list(SIX_PART) + list(details)``."""
    import trimesh

    V, F, part = six_part_figure()
    sphere = trimesh.creation.icosphere(subdivisions=subdivisions)
    S, T = np.asarray(sphere.vertices, float), np.asarray(sphere.faces, np.int64)
    if _signed_volume(S, T) < 0:
        T = T[:, ::-1].copy()
    Vs, Fs, ids = [V], [F], [part]
    off, k = len(V), len(SIX_PART)
    for centre, radius in details.values():
        Vs.append(S * radius + np.asarray(centre, float))
        Fs.append(T + off)
        ids.append(np.full(len(S), k))
        off += len(S)
        k += 1
    return np.concatenate(Vs), np.concatenate(Fs), np.concatenate(ids)
