"""Quality measures (issue 5) on shapes with analytic answers. No timing assertions."""

from __future__ import annotations

import numpy as np
import pytest

from curveskel_addon.core.geometry.inside import inside_mesh
from curveskel_addon.core.skeleton import Skeleton
from curveskel_addon.measure.quality import (
    bone_points, closest_mapping, mesh_distance, mesh_topology, point_triangle_distance, quality,
    sample_silhouette_boundary, sd_round_cone, silhouette_sdf, skeleton_topology, winding_number)
from tests.meshes import capsule, torus

R, L = 1.0, 6.0


@pytest.fixture(scope="module")
def fine_capsule():
    return capsule(radius=R, length=L, n_around=128, n_body=100, cap_rings=48)


def axis_skeleton(V, r=R, shift=(0.0, 0.0, 0.0)):
    J = np.array([[0, 0, 0, r], [0, 0, L, r]], float)
    J[:, :3] += shift
    B = np.array([[0, 1]])
    bone, t = closest_mapping(V, J, B)
    return Skeleton(J, B, bone, t)


def ring_skeleton(n=48, R0=3.0, r=1.0):
    u = 2 * np.pi * np.arange(n) / n
    J = np.stack([R0 * np.cos(u), R0 * np.sin(u), 0 * u, np.full(n, r)], 1)
    B = np.stack([np.arange(n), (np.arange(n) + 1) % n], 1)
    return Skeleton(J, B, np.zeros(0, int), np.zeros(0))


# -- primitives ---------------------------------------------------------------------------------
def _brute_round_cone_surface(a, b, r1, r2, n=400_000, seed=0):
    """Dense points on the boundary of the hull of two balls, by sampling both spheres and the
    lateral surface then keeping points with sd ~ 0 (exact up to sampling density)."""
    rng = np.random.default_rng(seed)
    J = np.array([[*a, r1], [*b, r2]])
    return sample_silhouette_boundary(J, np.array([[0, 1]]), n, rng)


@pytest.mark.parametrize("r1,r2", [(1.0, 1.0), (1.0, 0.4), (0.3, 0.9), (0.0, 0.7)])
def test_sd_round_cone_matches_brute_force(r1, r2):
    a, b = np.array([0.1, -0.2, 0.3]), np.array([1.5, 0.8, -0.4])
    S = _brute_round_cone_surface(a, b, r1, r2)
    assert len(S) > 100_000
    # every boundary sample lies on the surface
    assert np.abs(sd_round_cone(S, a, b, r1, r2)).max() < 1e-6   # kept within tol of the seam
    rng = np.random.default_rng(1)
    P = rng.uniform(-2.5, 3.0, size=(300, 3))
    d = sd_round_cone(P, a, b, r1, r2)
    from scipy.spatial import cKDTree
    brute, _ = cKDTree(S).query(P)
    spacing = np.sqrt(4 * np.pi * 9 / len(S))     # generous sampling resolution
    assert np.allclose(np.abs(d), brute, atol=spacing)
    # sign: inside iff within the hull, i.e. within a ball swept along the segment
    t = np.linspace(0, 1, 2001)
    C = (1 - t)[:, None] * a + t[:, None] * b
    rad = (1 - t) * r1 + t * r2
    inside = np.any(np.linalg.norm(P[:, None] - C[None], axis=2) < rad[None], axis=1)
    far = np.abs(d) > 1e-3
    assert np.array_equal((d < 0)[far], inside[far])


def test_sd_round_cone_contained_ball_is_larger_ball():
    a, b = np.zeros(3), np.array([0.2, 0, 0])
    P = np.array([[3.0, 0, 0], [-3.0, 0, 0], [0, 0.5, 0]])
    assert np.allclose(sd_round_cone(P, a, b, 1.0, 0.5), np.linalg.norm(P, axis=1) - 1.0)
    assert np.allclose(sd_round_cone(P, b, a, 0.5, 1.0), np.linalg.norm(P, axis=1) - 1.0)


def test_round_cone_geometry_reused_with_new_radii_matches_direct():
    # the radius fit computes the point-cone geometry once and evaluates it with many radii,
    # some pairs degenerate (one ball inside the other), under broadcasting and row takes
    from curveskel_addon.measure.quality import (round_cone_geometry, sd_round_cone_radii,
                                              take_round_cone_geometry)
    rng = np.random.default_rng(4)
    P = rng.uniform(-2, 2, size=(50, 3))
    a = rng.uniform(-1, 1, size=(6, 3))
    b = a + rng.uniform(-0.5, 0.5, size=(6, 3))
    g = round_cone_geometry(P[:, None], a[None], b[None])
    for r1, r2 in [(np.full(6, 0.3), np.full(6, 0.2)), (np.full(6, 2.0), np.full(6, 0.1))]:
        # the second: every ball at a contains the one at b (the larger ball alone)
        got = sd_round_cone_radii(g, r1[None], r2[None])
        want = np.array([[sd_round_cone(p, a[j], b[j], r1[j], r2[j]) for j in range(6)] for p in P])
        assert np.allclose(got, want, rtol=0, atol=1e-12)
    degenerate = np.linalg.norm(b - a, axis=1) <= 2.0 - 0.1
    assert degenerate.all()
    r1 = np.where(np.arange(6) % 2 == 0, 2.0, 0.3)          # half the pairs contained balls
    rows = (np.arange(50), np.arange(50) % 6)
    gt = take_round_cone_geometry(g, rows)
    got = sd_round_cone_radii(gt, r1[rows[1]], 0.1)
    want = np.array([sd_round_cone(P[i], a[j], b[j], r1[j], 0.1) for i, j in zip(*rows)])
    assert np.allclose(got, want, rtol=0, atol=1e-12)
    big = r1[rows[1]] == 2.0
    assert np.allclose(got[big], np.linalg.norm(P[big] - a[rows[1][big]], axis=1) - 2.0)


def test_silhouette_sdf_is_min_over_bones():
    sk = ring_skeleton(n=40)
    rng = np.random.default_rng(2)
    P = rng.uniform(-5, 5, size=(500, 3))
    a, b = sk.joints[sk.bones[:, 0], :3], sk.joints[sk.bones[:, 1], :3]
    full = sd_round_cone(P[:, None], a[None], b[None], sk.joints[sk.bones[:, 0], 3][None],
                         sk.joints[sk.bones[:, 1], 3][None]).min(axis=1)
    assert np.allclose(silhouette_sdf(P, sk.joints, sk.bones), full)


def test_point_triangle_distance_and_mesh_distance_match_brute_force():
    V, F = torus(n_major=24, n_minor=12)
    rng = np.random.default_rng(3)
    P = rng.uniform(-5, 5, size=(400, 3))
    T = V[F]
    # brute force against dense samples of each triangle's closure
    u, v = np.meshgrid(np.linspace(0, 1, 41), np.linspace(0, 1, 41))
    m = (u + v) <= 1
    u, v = u[m], v[m]
    S = (T[:, None, 0] + (T[:, None, 1] - T[:, None, 0]) * u[None, :, None]
         + (T[:, None, 2] - T[:, None, 0]) * v[None, :, None]).reshape(-1, 3)
    from scipy.spatial import cKDTree
    brute, _ = cKDTree(S).query(P)
    d = mesh_distance(P, V, F)
    edge = np.linalg.norm(T[:, 1] - T[:, 0], axis=1).max()
    assert np.all(d <= brute + 1e-12)
    assert np.all(brute - d < edge / 40 * 1.5)
    # exact: equals the minimum of the row-wise exact distance over all triangles
    PI = np.repeat(np.arange(50), len(F))
    full = point_triangle_distance(P[PI], np.tile(T[:, 0], (50, 1)), np.tile(T[:, 1], (50, 1)),
                                   np.tile(T[:, 2], (50, 1))).reshape(50, -1).min(axis=1)
    assert np.allclose(d[:50], full, atol=1e-12)


def test_point_triangle_distance_regions():
    a, b, c = np.zeros(3), np.array([1.0, 0, 0]), np.array([0, 1.0, 0])
    P = np.array([[0.2, 0.2, 2.0],     # face
                  [-1.0, -1.0, 0.0],   # vertex a
                  [2.0, -0.5, 0.0],    # vertex b... region of b
                  [0.5, -1.0, 0.0],    # edge ab
                  [1.0, 1.0, 0.0],     # edge bc
                  [-1.0, 0.5, 0.0]])   # edge ac
    want = [2.0, np.sqrt(2), np.hypot(1.0, 0.5), 1.0, np.sqrt(2) / 2, 1.0]
    n = len(P)
    got = point_triangle_distance(P, np.tile(a, (n, 1)), np.tile(b, (n, 1)), np.tile(c, (n, 1)))
    assert np.allclose(got, want)
    # zero-area triangle falls back to its edges
    got = point_triangle_distance(np.array([[0.5, 1.0, 0]]), a[None], b[None], (2 * b)[None])
    assert np.allclose(got, [1.0])


# -- inside -------------------------------------------------------------------------------------
def test_inside_mesh_agrees_with_winding_number():
    V, F = torus(n_major=32, n_minor=16)
    rng = np.random.default_rng(4)
    P = rng.uniform(-4.5, 4.5, size=(2000, 3))
    w = winding_number(P, V, F)
    assert np.all((np.abs(w) < 1e-6) | (np.abs(w - 1) < 1e-6))
    assert np.array_equal(inside_mesh(P, V, F), w > 0.5)


def test_inside_on_symmetry_axis_of_procedural_mesh(fine_capsule):
    V, F = fine_capsule
    P = np.stack([np.zeros(50), np.zeros(50), np.linspace(-0.9, 6.9, 50)], 1)
    assert inside_mesh(P, V, F).all()
    P[:, 0] = 1.5
    assert not inside_mesh(P, V, F).any()


# -- topology -----------------------------------------------------------------------------------
def test_topology_torus():
    V, F = torus()
    mt = mesh_topology(V, F)
    assert (mt["mesh_components"], mt["mesh_genus"], mt["mesh_boundaries"], mt["mesh_euler"]) == (1, 1, 0, 0)
    st = skeleton_topology(48, ring_skeleton().bones)
    assert st["skeleton_cycles"] == 1 and st["skeleton_components"] == 1
    assert st["leaves"] == 0 and st["branch_points"] == 0


def test_topology_open_mesh_counts_boundary():
    V, F = capsule(n_around=16, n_body=10, cap_rings=4)
    keep = np.ones(len(F), bool)
    keep[0] = False                            # punch a one-triangle hole
    mt = mesh_topology(V, F[keep])
    assert mt["mesh_boundaries"] == 1 and mt["mesh_genus"] == 0 and mt["mesh_euler"] == 1


def test_topology_star_graph():
    bones = np.array([[0, 1], [0, 2], [0, 3], [3, 4]])
    st = skeleton_topology(6, bones)            # joint 5 isolated
    assert st == {"skeleton_components": 2, "skeleton_cycles": 0, "leaves": 3, "branch_points": 1}


# -- the whole measure set ----------------------------------------------------------------------
def test_capsule_exact_skeleton(fine_capsule):
    V, F = fine_capsule
    q = quality(V, F, axis_skeleton(V), n_samples=5000)
    D = q["D"]
    assert q["recon_mean"] < 1e-3 and q["recon_rev_mean"] < 1e-3
    assert q["recon_p95"] < 1e-3 and q["recon_rev_p95"] < 1e-3
    assert q["inside"] == 1.0
    assert q["energy_vertex"] < 1e-6 and q["energy_area"] < 1e-6
    assert q["topology_match"] and q["skeleton_cycles"] == 0 and q["mesh_genus"] == 0
    assert (q["joints"], q["bones"], q["leaves"], q["branch_points"]) == (2, 1, 2, 0)
    assert np.isclose(D, np.linalg.norm([2 * R, 2 * R, L + 2 * R]))


def test_capsule_radii_doubled(fine_capsule):
    V, F = fine_capsule
    q = quality(V, F, axis_skeleton(V, r=2 * R), n_samples=5000)
    assert q["recon_mean"] == pytest.approx(R / q["D"], rel=0.01)
    assert q["recon_rev_mean"] == pytest.approx(R / q["D"], rel=0.01)
    assert q["inside"] == 1.0
    # e = d^2 - (2R)^2 = -3 R^2 at every vertex
    assert q["energy_vertex"] == pytest.approx(9 * R ** 4 / q["D"] ** 4, rel=0.02)


def test_skeleton_outside_mesh(fine_capsule):
    V, F = fine_capsule
    q = quality(V, F, axis_skeleton(V, shift=(5.0, 0, 0)), n_samples=2000)
    assert q["inside"] == 0.0
    assert q["recon_mean"] > 0.3


def test_torus_ring_skeleton():
    V, F = torus(n_major=128, n_minor=48)
    q = quality(V, F, ring_skeleton(n=128), n_samples=5000)
    assert q["skeleton_cycles"] == 1 and q["mesh_genus"] == 1 and q["topology_match"]
    assert q["inside"] == 1.0
    assert q["energy_mapping"] == "closest"
    assert q["recon_mean"] < 2e-3


def test_quality_is_reproducible_and_json_ready(fine_capsule):
    import json

    V, F = fine_capsule
    sk = axis_skeleton(V, r=1.3)
    a = quality(V, F, sk, n_samples=1000, seed=7)
    b = quality(V, F, sk, n_samples=1000, seed=7)
    a.pop("measure_seconds"), b.pop("measure_seconds")
    assert a == b
    json.dumps(a)


def test_closest_mapping_convention():
    J = np.array([[0, 0, 0, 1.0], [0, 0, 4, 1.0]])
    V = np.array([[1.0, 0, 1.0], [0, 1.0, 4.0], [0, 0, -3.0]])
    bone, t = closest_mapping(V, J, np.array([[0, 1]]))
    sk = Skeleton(J, np.array([[0, 1]]), bone, t)
    assert np.allclose(sk.sigma(), [[0, 0, 1.0], [0, 0, 4.0], [0, 0, 0]])


def test_bone_points_and_zero_radius_silhouette():
    V, F = capsule(radius=R, length=L, n_around=64, n_body=60, cap_rings=24)
    J = np.array([[0, 0, 0, 0.0], [0, 0, L, 0.0]])
    P = bone_points(J, np.array([[0, 1]]), 10)
    assert P.shape == (10, 3) and np.allclose(P[:, 2], np.linspace(0.3, 5.7, 10)[::-1])
    q = quality(V, F, Skeleton(J, np.array([[0, 1]]), np.zeros(0, int), np.zeros(0)), n_samples=500)
    # the silhouette is the segment itself: both directions ~ R / D (caps excepted)
    assert q["recon_rev_mean"] == pytest.approx(R / q["D"], rel=0.01)
    assert q["recon_mean"] == pytest.approx(R / q["D"], rel=0.05)


def test_pruned_minimum_is_exact_for_far_points():
    """Far points take the ball-query path of the pruning; it must still equal brute force."""
    V, F = torus(n_major=96, n_minor=32)
    T = V[F]
    rng = np.random.default_rng(5)
    P = rng.normal(size=(150, 3))
    P = P / np.linalg.norm(P, axis=1, keepdims=True) * rng.uniform(1, 12, size=(150, 1))
    P[:50, 2] = 0.0
    P[:50, :2] *= 0.25 / np.maximum(np.linalg.norm(P[:50, :2], axis=1, keepdims=True), 1e-9)  # near the hole's axis
    n, m = len(P), len(F)
    PI = np.repeat(np.arange(n), m)
    full = point_triangle_distance(P[PI], np.tile(T[:, 0], (n, 1)), np.tile(T[:, 1], (n, 1)),
                                   np.tile(T[:, 2], (n, 1))).reshape(n, m).min(axis=1)
    assert np.allclose(mesh_distance(P, V, F), full, rtol=0, atol=1e-12)
    sk = ring_skeleton(n=400, r=0.8)
    a, b = sk.joints[sk.bones[:, 0], :3], sk.joints[sk.bones[:, 1], :3]
    ra, rb = sk.joints[sk.bones[:, 0], 3], sk.joints[sk.bones[:, 1], 3]
    full = sd_round_cone(P[:, None], a[None], b[None], ra[None], rb[None]).min(axis=1)
    assert np.allclose(silhouette_sdf(P, sk.joints, sk.bones), full, rtol=0, atol=1e-12)


def test_topology_merges_duplicate_positions():
    V, F = torus(n_major=32, n_minor=12)
    V2 = np.concatenate([V, V])                  # a "triangle soup"-like split: half the faces
    F2 = F.copy()                                # use the second copy of every vertex
    F2[::2] += len(V)
    mt = mesh_topology(V2, F2)
    assert (mt["mesh_components"], mt["mesh_genus"], mt["mesh_boundaries"]) == (1, 1, 0)
