"""rig_layout: roots, hierarchy, directions, chains, names and roll axes (no bpy)."""

import re

import numpy as np
import pytest

import meshes
from curveskel_addon.core import CurveSkelError, skeletonize
from curveskel_addon.rig.rig_layout import BLEND_HUB, BLEND_NONE, BLEND_SYMMETRIC, rig_layout

NAME = re.compile(r"^(root\.\d{2,}|branch\d{2,}\.\d{2,})$")


def star_skeleton(n_arms=4, per_arm=3, flip=True):
    """Centre joint + n_arms straight chains; bone (i, j) orientation alternates when ``flip``."""
    J, B = [[0.0, 0.0, 0.0, 0.5]], []
    for a in range(n_arms):
        u = np.array([np.cos(2 * np.pi * a / n_arms), np.sin(2 * np.pi * a / n_arms), 0.0])
        prev = 0
        for k in range(1, per_arm + 1):
            J.append([*(u * k), 0.5])
            cur = len(J) - 1
            B.append([cur, prev] if (flip and k % 2) else [prev, cur])
            prev = cur
    return np.array(J), np.array(B)


def ring_skeleton(n=16, R=3.0):
    a = 2 * np.pi * np.arange(n) / n
    J = np.stack([R * np.cos(a), R * np.sin(a), 0 * a, 0 * a + 1.0], 1)
    B = np.stack([np.arange(n), (np.arange(n) + 1) % n], 1)
    return J, B


def helix_skeleton(n=40):
    s = np.linspace(0, 4 * np.pi, n)
    J = np.stack([np.cos(s), np.sin(s), 0.3 * s, 0 * s + 0.2], 1)
    B = np.stack([np.arange(n - 1), np.arange(1, n)], 1)
    return J, B


def check_layout(lay, joints, bones):
    """Invariants every layout must satisfy."""
    R = lay.n_bones
    X = np.asarray(joints)[:, :3]
    # every bone has a positive length, names are unique and readable
    assert np.all(np.linalg.norm(lay.tails - lay.heads, axis=1) > lay.meta["merge_tol"])
    assert len(set(lay.names)) == R
    assert all(NAME.match(nm) for nm in lay.names), lay.names
    # parents: exactly one root bone per part, parents created before children, no cycles
    roots = np.flatnonzero(lay.parent < 0)
    assert len(roots) == len(lay.roots) == len(np.unique(lay.component))
    assert all(lay.names[r].startswith("root.") for r in roots)
    nonroot = np.flatnonzero(lay.parent >= 0)
    assert np.all(lay.parent[nonroot] < nonroot)
    assert np.all(lay.component[nonroot] == lay.component[lay.parent[nonroot]])
    # chains connected: the head of a bone is its parent's tail (or, under a root bone, its head)
    p = lay.parent[nonroot]
    under_root = lay.parent[p] < 0
    anchor = np.where(under_root[:, None], lay.heads[p], lay.tails[p])
    assert np.allclose(lay.heads[nonroot], anchor)
    assert np.all(lay.connect[nonroot] == ~under_root)
    # directed away from the root: the shortest path from the root to a bone's tail passes
    # through its head (the tail is never closer to the root than the head)
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import dijkstra
    E = np.asarray(bones)
    w = np.maximum(np.linalg.norm(X[E[:, 0]] - X[E[:, 1]], axis=1), 1e-12)
    G = coo_matrix((w, (E[:, 0], E[:, 1])), shape=(len(X), len(X))).tocsr()
    dist = dijkstra(G, directed=False, indices=lay.roots, min_only=True)
    hj, tj = lay.head_joint[nonroot], lay.tail_joint[nonroot]
    assert np.all(dist[hj] <= dist[tj] + 1e-9)
    # roll axes: unit, perpendicular to the bone, no flip between parent and child
    d = (lay.tails - lay.heads) / np.linalg.norm(lay.tails - lay.heads, axis=1, keepdims=True)
    assert np.allclose(np.linalg.norm(lay.z_axis, axis=1), 1.0)
    assert np.abs(np.einsum("ij,ij->i", d, lay.z_axis)).max() < 1e-9
    inner = nonroot[~under_root]
    dots = np.einsum("ij,ij->i", lay.z_axis[inner], lay.z_axis[lay.parent[inner]])
    assert np.all(dots > 0), dots.min()
    # each skeleton bone is carried by a rig bone spanning its joints (or merged into a joint)
    for b, (i, j) in enumerate(np.asarray(bones)):
        r = lay.bone_rig[b]
        if np.isnan(lay.bone_s[b]):
            ends = {lay.head_joint[r], lay.tail_joint[r]}
            assert ends == {lay.joint_map[i], lay.joint_map[j]}
            head = j if lay.bone_reversed[b] else i
            assert np.allclose(lay.heads[r], X[lay.joint_map[head]])
    # the root bone of each part sits on its root joint
    assert np.allclose(lay.heads[roots], X[lay.roots])
    return dots


def test_star_by_hand():
    J, B = star_skeleton()
    lay = rig_layout(J, B)
    check_layout(lay, J, B)
    assert lay.roots.tolist() == [0]                        # the centre
    assert lay.n_bones == len(B) + 1
    # four branches of three bones, named by branch and position
    assert sorted(n for n in lay.names if n.endswith(".02")) == [f"branch0{k}.02" for k in range(4)]
    # every arm bone points away from the centre
    assert np.all(np.linalg.norm(lay.tails[1:], axis=1) > np.linalg.norm(lay.heads[1:], axis=1))
    # flat star, z up: all arm rolls point up
    assert np.allclose(lay.z_axis[1:], [0, 0, 1])
    # blend partners: chain joints symmetric, tips none, bones leaving the root blend into it
    first = [r for r in range(lay.n_bones) if re.match(r"branch\d+\.00$", lay.names[r])]
    assert len(first) == 4
    assert all(lay.head_mode[r] == BLEND_HUB and lay.head_partner[r] == 0 for r in first)
    tips = [r for r in range(lay.n_bones) if lay.names[r].endswith(".02")]
    assert all(lay.tail_mode[r] == BLEND_NONE for r in tips)
    mid = [r for r in range(lay.n_bones) if lay.names[r].endswith(".01")]
    assert all(lay.head_mode[r] == BLEND_SYMMETRIC and lay.tail_mode[r] == BLEND_SYMMETRIC for r in mid)


def test_given_root_at_a_tip():
    J, B = star_skeleton()
    lay = rig_layout(J, B, root=3)                         # tip of arm 0
    check_layout(lay, J, B)
    assert lay.roots.tolist() == [3]
    # the centre is now a junction of degree 4 reached from arm 0
    assert lay.meta["branches"] == 4


def test_ring_has_one_root_and_closes():
    J, B = ring_skeleton()
    lay = rig_layout(J, B)
    check_layout(lay, J, B)
    assert lay.n_bones == len(B) + 1
    # the two halves of the ring meet at the far joint with a symmetric blend
    meet = [r for r in range(1, lay.n_bones) if lay.tail_mode[r] == BLEND_SYMMETRIC
            and lay.tail_joint[r] == lay.tail_joint[lay.tail_partner[r]]]
    assert len(meet) == 2


def test_helix_rolls_follow_without_flips():
    J, B = helix_skeleton()
    lay = rig_layout(J, B, root=0)
    dots = check_layout(lay, J, B)
    assert dots.min() > 0.8                                 # smooth: consecutive rolls close


def test_two_parts_two_roots():
    J1, B1 = star_skeleton()
    J2, B2 = ring_skeleton()
    J2 = J2 + [20, 0, 0, 0]
    J = np.concatenate([J1, J2])
    B = np.concatenate([B1, B2 + len(J1)])
    lay = rig_layout(J, B)
    check_layout(lay, J, B)
    assert [lay.names[r] for r in lay.root_bones] == ["root.00", "root.01"]


def test_zero_length_bone_is_merged():
    J, B = star_skeleton(flip=False)
    J = np.concatenate([J, [J[2]]])                         # a joint on top of joint 2 of arm 0
    B = np.concatenate([B, [[2, len(J) - 1]], [[len(J) - 1, 0]]])
    B[1] = [len(J) - 1, 3]                                  # arm 0 continues from the duplicate
    lay = rig_layout(J, B)
    check_layout(lay, J, B)
    assert lay.meta["merged_bones"] == 1
    zero = len(B) - 2
    assert not np.isnan(lay.bone_s[zero])                   # carried by a neighbouring bone


def test_rejects_bad_input():
    with pytest.raises(CurveSkelError):
        rig_layout(np.zeros((2, 4)), np.zeros((0, 2), int))
    with pytest.raises(CurveSkelError):
        rig_layout(np.zeros((2, 4)), [[0, 5]])
    with pytest.raises(CurveSkelError):
        rig_layout(np.zeros((2, 2)), [[0, 1]])


@pytest.mark.parametrize("name", ["star", "torus", "bent_capsule"])
def test_real_skeletons(name):
    V, F = getattr(meshes, name)()
    sk = skeletonize(V, F)
    lay = rig_layout(sk.joints, sk.bones)
    check_layout(lay, sk.joints, sk.bones)
    assert len(lay.roots) == 1
    if name == "star":
        # the root is near the centre, and the tips of the four arms are leaves of 4 branches
        assert np.linalg.norm(sk.joints[lay.roots[0], :3]) < 1.0
        leaves = [r for r in range(1, lay.n_bones) if lay.tail_mode[r] == BLEND_NONE
                  and not np.any(lay.parent == r)]
        assert len(leaves) == 4


# -- mirror plane and readable names (issue 14) --------------------------------------------------------
from curveskel_addon.rig.rig_layout import MirrorPlane, mirror_plane, named_rig  # noqa: E402

READABLE = re.compile(r"^(root(\.\d{2})?|(spine|limb|chain)\d*(\.[LR])?\.\d{2,})$")


def _flip(name):
    """Blender's flip for our names (.L <-> .R before the number)."""
    return name.replace(".L.", ".#.").replace(".R.", ".L.").replace(".#.", ".R.")


def _rotation(seed):
    q, _ = np.linalg.qr(np.random.default_rng(seed).normal(size=(3, 3)))
    return q * np.sign(np.linalg.det(q))


@pytest.mark.parametrize("seed", [0, 1])
def test_mirror_plane_found_in_any_orientation(seed):
    rng = np.random.default_rng(seed)
    half = rng.normal(size=(800, 3)) * [1.0, 2.0, 0.5] + [1.5, 0, 0]
    P = np.concatenate([half, half * [-1, 1, 1]])                    # symmetric about x = 0
    Rm = _rotation(seed + 10)
    t = np.array([0.3, -1.0, 2.0])
    pl = mirror_plane(P @ Rm.T + t)
    n_true = Rm @ np.array([1.0, 0.0, 0.0])
    assert pl is not None and abs(abs(pl.normal @ n_true) - 1) < 1e-6
    assert abs(pl.signed_distance(t)) < 1e-6 and pl.error < 1e-6
    # three boxes of different lengths along x, y, z from one corner: no mirror plane
    boxes = [rng.uniform(0, 1, size=(3000, 3)) * ext for ext in ([1, .2, .2], [.2, 2, .2], [.2, .2, 3])]
    assert mirror_plane(np.concatenate(boxes)) is None


def test_mirror_plane_prefers_local_x():
    V, F = meshes.capsule()            # symmetric about x = 0 and y = 0 (and more)
    pl = mirror_plane(V)
    assert np.allclose(pl.normal, [1, 0, 0]) and abs(pl.offset) < 1e-9
    assert len(mirror_plane(V, all_planes=True)) >= 2


def symmetric_body(noise=0.01, seed=0):
    """A spine on x = 0 (slightly off), arms to +-x with 3 and 4 bones (a skeleton that is
    symmetric in shape, not in topology), a hand with two fingers on each side."""
    rng = np.random.default_rng(seed)
    J = [[0, 0, 0], [0, 0, 1], [0, 0, 2], [0, 0, 3]]                  # 0..3 spine, 2 the shoulders
    B = [[0, 1], [1, 2], [2, 3]]

    def chain(start, pts):
        prev = start
        for p in pts:
            J.append(p)
            B.append([prev, len(J) - 1])
            prev = len(J) - 1
        return prev
    hl = chain(2, [[0.7, 0, 2], [1.4, 0, 2], [2.0, 0, 2]])
    hr = chain(2, [[-0.5, 0, 2], [-1.0, 0, 2], [-1.5, 0, 2], [-2.0, 0, 2]])
    for h, s in ((hl, 1), (hr, -1)):
        chain(h, [[s * 2.5, 0, 2.2]])
        chain(h, [[s * 2.5, 0, 1.8], [s * 2.9, 0, 1.7]])
    J = np.array(J, float) + rng.normal(scale=noise, size=(len(J), 3))
    return np.c_[J, np.full(len(J), 0.2)], np.array(B)


def test_named_rig_pairs_and_mirrors_exactly():
    J, B = symmetric_body()
    lay = rig_layout(J, B, root=0)
    plane = MirrorPlane(np.array([1.0, 0.0, 0.0]), 0.0, 0.0)
    rig = named_rig(lay, plane)
    assert len(set(rig.names)) == rig.n_bones and all(READABLE.match(n) for n in rig.names), rig.names
    assert rig.meta["pairs"] == 3                                    # arms and both fingers
    idx = {n: k for k, n in enumerate(rig.names)}
    left = [n for n in rig.names if ".L." in n]
    assert len(left) == 4 + 1 + 2                                     # the longer arm: 4 bones
    for n in left:
        a, b = idx[n], idx[_flip(n)]
        assert rig.mirror[a] == b and rig.mirror[b] == a
        assert np.allclose(plane.reflect(rig.heads[a]), rig.heads[b], atol=1e-12)
        assert np.allclose(plane.reflect(rig.tails[a]), rig.tails[b], atol=1e-12)
        assert np.allclose(plane.reflect_vector(rig.z_axis[a]), rig.z_axis[b], atol=1e-12)
        assert rig.heads[a][0] >= -1e-12 and rig.tails[a][0] > 0     # .L on the normal's side
        assert rig.parent[a] < 0 or rig.parent[b] == rig.mirror[rig.parent[a]]
    central = [k for k, n in enumerate(rig.names) if n.startswith(("spine", "root"))]
    assert np.abs(rig.heads[central, 0]).max() < 1e-12 and np.abs(rig.tails[central, 0]).max() < 1e-12
    # a rig: parents first, connected heads on their parent's tail, unit rolls perpendicular
    for r in range(rig.n_bones):
        assert rig.parent[r] < r
        if rig.connect[r]:
            assert np.allclose(rig.heads[r], rig.tails[rig.parent[r]])
    d = rig.tails - rig.heads
    assert np.all(np.linalg.norm(d, axis=1) > 0)
    assert np.abs(np.einsum("ij,ij->i", d, rig.z_axis)).max() < 1e-9


def test_named_rig_without_plane_keeps_the_layout():
    J, B = symmetric_body()
    lay = rig_layout(J, B, root=0)
    rig = named_rig(lay)
    assert rig.n_bones == lay.n_bones and np.allclose(rig.heads, lay.heads) and np.allclose(rig.tails, lay.tails)
    assert all(READABLE.match(n) and ".L" not in n and ".R" not in n for n in rig.names)
    assert rig.names[0] == "root" and np.array_equal(rig.parent, lay.parent)


def test_two_limbs_pair_by_their_tips_when_their_junctions_differ():
    """A T whose head chain meets its left arm 0.7 out from the middle (the skeleton of a shape
    symmetric across two planes, drawn from a pole in one arm): the left arm branches off at
    x = -0.7, the right one at the middle. Compared at equal fractions of their lengths the arms
    lie 0.35 apart on average, over the limit for chains whose parents differ; from their tips
    they are each other's mirror image, and pair."""
    X, B = [], []

    def chain(start, points):
        prev = start
        for p in points:
            X.append(p)
            B.append((prev, len(X) - 1))
            prev = len(X) - 1
        return prev

    X.append([0.0, 0, 0])                                                    # 0: bottom
    mid = chain(0, [[0, 0, 1.2], [0, 0, 2.4], [0, 0, 3.5]])                  # the body
    chain(mid, [[0.75, 0, 3.5], [1.5, 0, 3.5], [2.25, 0, 3.5], [3.0, 0, 3.5]])    # right arm
    left = chain(mid, [[-0.35, 0, 3.5], [-0.7, 0, 3.5]])                      # to the junction
    chain(left, [[-1.27, 0, 3.5], [-1.85, 0, 3.5], [-2.42, 0, 3.5], [-3.0, 0, 3.5]])
    chain(left, [[-0.4, 0, 4.2], [0, 0, 4.8], [0, 0, 5.2]])                   # head chain
    J = np.c_[np.array(X, float), np.full(len(X), 0.35)]
    rig = named_rig(rig_layout(J, np.array(B), root=0), MirrorPlane(np.array([1.0, 0.0, 0.0]), 0.0, 0.0))
    arms = [n for n in rig.names if ".L." in n or ".R." in n]
    assert rig.meta["pairs"] == 1 and len(arms) == 8, rig.names
