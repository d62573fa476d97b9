"""First approximation: Reeb graph topology (cycles = genus), chains, noise caps, non-uniform
meshes, open and non-manifold input, and leaf counts on the shared meshes."""

import numpy as np
import pytest
import scipy.sparse as sp
import trimesh
import trimesh.creation
from scipy.sparse.csgraph import connected_components

from curveskel_addon.core.errors import CurveSkelError
from curveskel_addon.core.config import CONFIG
from curveskel_addon.core.initialise.reeb import _group, _nudge_zero_bones, first_approximation
from meshes import bent_capsule, capsule, star, torus, tube_along

STAGES = ("pole", "contours", "reeb", "meb", "mapping")


def load(shared_meshes, name):
    m = trimesh.load(shared_meshes / name, process=False, force="mesh", maintain_order=True)
    return np.asarray(m.vertices, float), np.asarray(m.faces, np.int64)


def degrees(fa):
    return np.bincount(fa.bones.ravel(), minlength=len(fa.joints))


def graph_cycles(fa):
    """b1 of the skeleton graph (assumed connected, checked separately)."""
    return len(fa.bones) - len(fa.joints) + 1


def assert_valid(fa, n):
    J, B = fa.joints, fa.bones
    assert J.shape[1] == 4 and B.shape[1] == 2 and len(B) >= 1
    assert np.all(np.isfinite(J)) and np.all(J[:, 3] >= 0)
    assert B.min() >= 0 and B.max() < len(J) and np.all(B[:, 0] != B[:, 1])
    assert np.all(np.linalg.norm(J[B[:, 0], :3] - J[B[:, 1], :3], axis=1) > 0), "zero-length bone"
    assert fa.bone.shape == (n,) and fa.t.shape == (n,)
    assert fa.bone.min() >= 0 and fa.bone.max() < len(B)
    assert np.all((fa.t >= 0) & (fa.t <= 1))
    assert set(STAGES) <= set(fa.meta["timings"])
    # the skeleton is connected
    A = sp.coo_matrix((np.ones(len(B)), (B[:, 0], B[:, 1])), shape=(len(J), len(J)))
    assert connected_components(A, directed=False)[0] == 1


# ---------------------------------------------------------------------------------- topology


@pytest.mark.parametrize("name, genus", [("3holes.off", 3), ("fertility.off", 4), ("rocker-arm.obj", 1),
                                         ("horse.off", 0), ("hand.off", 0), ("octopus.off", 0)])
def test_cycles_equal_genus_shared(shared_meshes, name, genus):
    V, F = load(shared_meshes, name)
    fa = first_approximation(V, F, spacing=0.04, seed=0)
    assert_valid(fa, len(V))
    assert fa.meta["expected_cycles"] == genus
    assert fa.meta["cycles"] == genus
    assert graph_cycles(fa) == genus


@pytest.mark.parametrize("mesh, genus", [(torus, 1), (capsule, 0), (star, 0), (bent_capsule, 0)])
def test_cycles_equal_genus_procedural(mesh, genus):
    V, F = mesh()
    for seed in range(3):
        fa = first_approximation(V, F, spacing=0.04, seed=seed)
        assert_valid(fa, len(V))
        assert fa.meta["cycles"] == genus == graph_cycles(fa)


def test_a_coarse_spacing_still_finds_every_handle(shared_meshes):
    """At a spacing of 0.2 (five times the default) a handle of 3holes can fall inside one
    region of f; the first approximation still has its three cycles (it refines the levels, or
    lets f run through the inside, until the genus is found)."""
    V, F = load(shared_meshes, "3holes.off")
    fa = first_approximation(V, F, spacing=0.2, seed=0)
    assert_valid(fa, len(V))
    assert fa.meta["cycles"] == 3 == graph_cycles(fa)


# ---------------------------------------------------------------------------------- geometry


def chain_check(fa):
    deg = degrees(fa)
    assert deg.max() <= 2 and (deg == 1).sum() == 2
    assert len(fa.bones) == len(fa.joints) - 1


@pytest.mark.parametrize("seed", range(4))
def test_capsule_is_one_chain_along_z(seed):
    V, F = capsule(radius=1.0, length=6.0)
    fa = first_approximation(V, F, spacing=0.04, seed=seed)
    assert_valid(fa, len(V))
    chain_check(fa)
    J = fa.joints
    off = np.hypot(J[:, 0], J[:, 1])
    assert off.max() < 0.25                                   # cap joints: the pole may sit
    assert off[(J[:, 2] > 0) & (J[:, 2] < 6)].max() < 0.05    # one ring off the tip
    assert J[:, 2].min() < 0 and J[:, 2].max() > 6
    mid = J[(J[:, 2] > 1) & (J[:, 2] < 5)]
    assert len(mid) >= 5
    assert np.all(np.abs(mid[:, 3] - 1) < 0.15)


def _uneven_capsule():
    """Same capsule, rings crowded at z=0 and sparse at z=6 (ring gaps from 0.005 to 0.3)."""
    u = np.linspace(0, 1, 40)
    z = 6 * u ** 2
    return tube_along(np.c_[0 * z, 0 * z, z], 1.0, 32, 8)


def _long_edge_capsule():
    """Only 4 body rings: axial edges of 2.0, over 5x the mean edge length."""
    return capsule(radius=1.0, length=6.0, n_body=4)


@pytest.mark.parametrize("make", [_uneven_capsule, _long_edge_capsule])
def test_non_uniform_meshes_give_the_same_skeleton(make):
    Vu, Fu = capsule(radius=1.0, length=6.0)
    V, F = make()
    E = np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1)
    L = np.linalg.norm(V[E[:, 0]] - V[E[:, 1]], axis=1)
    assert L.max() > 5 * L.mean() or L.max() > 50 * L.min()   # really non-uniform
    ref = first_approximation(Vu, Fu, spacing=0.04, seed=0)
    fa = first_approximation(V, F, spacing=0.04, seed=0)
    assert_valid(fa, len(V))
    chain_check(fa)
    assert abs(len(fa.joints) - len(ref.joints)) <= 0.1 * len(ref.joints)
    J, R = fa.joints, ref.joints
    assert np.hypot(J[:, 0], J[:, 1]).max() < 0.1
    body = (J[:, 2] > 0.5) & (J[:, 2] < 5.5)
    assert np.all(np.abs(J[body, 3] - 1) < 0.15)
    # every joint has a joint of the uniform skeleton nearby (within half a level spacing)
    s = ref.meta["spacing_used"] * np.linalg.norm(Vu.max(0) - Vu.min(0))
    d = np.linalg.norm(J[:, None, :3] - R[None, :, :3], axis=2).min(axis=1)
    assert np.all(d < 0.5 * s + 0.05), d.max()


# ---------------------------------------------------------------------------------- noise


@pytest.mark.parametrize("seed", range(3))
def test_noisy_capsule_has_two_leaves(seed):
    V, F = capsule(n_around=48, n_body=80)
    rng = np.random.default_rng(seed)
    Vn = V + rng.normal(scale=0.04, size=V.shape)          # 4 % of the radius
    fa = first_approximation(Vn, F, spacing=0.04, seed=seed)
    assert_valid(fa, len(V))
    chain_check(fa)


def test_noise_caps_are_removed_not_just_absent():
    """Without cap removal the noisy sphere grows spurious branches; with it, one chain."""
    S = trimesh.creation.icosphere(subdivisions=5)
    removed = 0
    for seed in range(4):
        rng = np.random.default_rng(seed)
        Vn = S.vertices + rng.normal(scale=0.02, size=S.vertices.shape)
        fa = first_approximation(Vn, S.faces, spacing=0.04, seed=seed)
        assert_valid(fa, len(Vn))
        chain_check(fa)
        removed += fa.meta["noise_caps_removed"]
    assert removed >= 4


# ---------------------------------------------------------------------------------- shared meshes


# (min, max) leaves: hand 5 fingers + wrist; octopus 8 arms (+ head); horse 4 legs + head
# (its tail touches a hind leg in this mesh, so no separate tail tip); others: no dozens of stubs.
LEAVES = {"hand.off": (5, 8), "octopus.off": (7, 10), "horse.off": (5, 8), "armadillo.obj": (5, 12),
          "elephant.obj": (5, 12), "homer.obj": (4, 10), "spot.obj": (2, 8)}


@pytest.mark.parametrize("name", sorted(LEAVES))
def test_leaf_counts_shared(shared_meshes, name):
    V, F = load(shared_meshes, name)
    lo, hi = LEAVES[name]
    fa = first_approximation(V, F, spacing=0.04, seed=0)
    assert_valid(fa, len(V))
    leaves = int((degrees(fa) == 1).sum())
    assert lo <= leaves <= hi, leaves


# ---------------------------------------------------------------------------------- awkward input


def test_open_mesh_with_boundary():
    V, F = capsule()
    top = V[:, 2] > 6.5
    F = F[~np.any(top[F], axis=1)]                       # cut one cap off: a boundary loop
    used = np.unique(F)
    remap = np.full(len(V), -1)
    remap[used] = np.arange(len(used))
    V, F = V[used], remap[F]
    fa = first_approximation(V, F, spacing=0.04, seed=0)
    assert_valid(fa, len(V))
    assert fa.meta["expected_cycles"] is None
    chain_check(fa)


def test_non_manifold_edge_and_pinched_vertex():
    V, F = capsule()
    # a fin: a third triangle on an existing edge (non-manifold edge)
    a, b = F[100, 0], F[100, 1]
    fin = V[a] + [3.0, 0, 0]
    V1 = np.vstack([V, fin])
    F1 = np.vstack([F, [[a, b, len(V)]]])
    fa = first_approximation(V1, F1, spacing=0.04, seed=0)
    assert_valid(fa, len(V1))
    # two capsules sharing one tip vertex (pinched, non-manifold vertex)
    V2, F2 = capsule()
    tip = np.argmax(V2[:, 2])
    other = np.argmin(V2[:, 2])
    shift = V2[tip] - V2[other]
    Vb = V2 + shift
    idx = np.arange(len(V2)) + len(V2)
    idx[other] = tip
    keep = np.ones(len(V2), bool)
    keep[other] = False
    new = np.full(len(V2), -1)
    new[keep] = len(V2) + np.arange(keep.sum())
    new[other] = tip
    V3 = np.vstack([V2, Vb[keep]])
    F3 = np.vstack([F2, new[F2]])
    fa = first_approximation(V3, F3, spacing=0.04, seed=0)
    assert_valid(fa, len(V3))
    assert fa.meta["cycles"] == 0


def test_tiny_and_degenerate_components():
    fa = first_approximation(np.array([[0.0, 0, 0], [1, 0, 0], [0, 1, 0]]), np.array([[0, 1, 2]]),
                             spacing=0.04, seed=0)
    assert_valid(fa, 3)
    fa = first_approximation(np.ones((3, 3)), np.array([[0, 1, 2]]), spacing=0.04, seed=0)
    assert_valid(fa, 3)
    assert len(fa.bones) == 1


@pytest.mark.parametrize("V, F, spacing", [
    (np.zeros((0, 3)), np.zeros((0, 3), int), 0.04),
    (np.zeros((3, 3)), np.array([[0, 1, 1]]), 0.04),
    (np.zeros((3, 3)), np.array([[0, 1, 3]]), 0.04),
    (np.array([[0, 0, np.nan], [1, 0, 0], [0, 1, 0]]), np.array([[0, 1, 2]]), 0.04),
    (np.eye(3), np.array([[0, 1, 2]]), 0.0),
])
def test_bad_input(V, F, spacing):
    with pytest.raises(CurveSkelError):
        first_approximation(V, F, spacing=spacing, seed=0)


def test_zero_length_bone_is_nudged():
    """A region joint that coincides with its loop's joint moves a little towards the region."""
    joints = np.array([[0.0, 0, 0, 1], [5, 0, 0, 1], [5, 0, 0, 0.5]])   # 2 loop joints + 1 own
    bones = np.array([[0, 1], [2, 1]])
    bone_reg = np.array([1, 0])
    V = np.array([[6.0, 1, 0], [6, -1, 0], [0, 1, 0]])
    reg_v = np.array([0, 0, 1])
    vorder, vstarts = _group(reg_v, 2)
    diag = 10.0
    _nudge_zero_bones(joints, bones, bone_reg, V, vorder, vstarts, diag, 2)
    assert np.allclose(joints[:2, :3], [[0, 0, 0], [5, 0, 0]])                # loop joints kept
    step = joints[2, :3] - [5, 0, 0]
    assert np.linalg.norm(step) == pytest.approx(CONFIG.initial.tie * diag)
    assert step[0] > 0                                                       # towards (6, 0, 0)
    ln = np.linalg.norm(joints[bones[:, 0], :3] - joints[bones[:, 1], :3], axis=1)
    assert np.all(ln > 0)


def test_meta_contract():
    V, F = torus()
    fa = first_approximation(V, F, spacing=0.04, seed=3)
    for key in ("pole", "spacing_used", "levels", "cycles", "expected_cycles", "noise_caps_removed"):
        assert key in fa.meta
    assert all(fa.meta["timings"][k] >= 0 for k in STAGES)
    assert fa.meta["spacing_used"] == pytest.approx(0.04)
    assert fa.meta["levels"] >= 6
    # the pole of the torus is an actual vertex at distance 0
    assert 0 <= fa.meta["pole"] < len(V)
