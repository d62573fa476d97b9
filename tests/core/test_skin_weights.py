"""skin_weights: sums, influences, the values at bone middles and joints, continuity (no bpy)."""

import numpy as np
import pytest

import meshes
from curveskel_addon.core import CurveSkelError, skeletonize
from curveskel_addon.core.geometry.segments import closest_on_bones
from curveskel_addon.rig.rig_layout import rig_layout
from curveskel_addon.rig.skin_weights import (project_on_bones, skin_weights, smooth_weights,
                                               smoothing_iterations, smoothstep)
from test_rig_layout import ring_skeleton, star_skeleton


def dense(index, weight, R):
    """(n, R) weight matrix."""
    W = np.zeros((len(index), R))
    rows = np.repeat(np.arange(len(index)), index.shape[1])
    ok = index.ravel() >= 0
    np.add.at(W, (rows[ok], index.ravel()[ok]), weight.ravel()[ok])
    return W


def check_weights(index, weight, n):
    assert index.shape == weight.shape == (n, 4)
    assert np.allclose(weight.sum(axis=1), 1.0)
    assert np.all(weight >= 0)
    assert np.all((index >= 0) | (weight == 0))
    assert np.all((weight > 0).sum(axis=1) <= 4)
    assert np.all(np.diff(weight, axis=1) <= 1e-12)       # sorted, largest first


def test_middle_and_joint_values():
    J, B = star_skeleton(flip=True)
    lay = rig_layout(J, B)
    nb = len(B)
    # middle of every bone: weight 1 on it
    idx, w = skin_weights(lay, np.arange(nb), np.full(nb, 0.5))
    check_weights(idx, w, nb)
    assert np.allclose(w[:, 0], 1.0)
    assert np.array_equal(idx[:, 0], lay.bone_rig)
    # the chain joint between bones 0 and 1 of arm 0 (joint 1): 50/50 seen from either bone
    j = 1
    on = [b for b in range(nb) if j in B[b]][:2]
    t = [1.0 if B[b][0] == j else 0.0 for b in on]
    idx, w = skin_weights(lay, on, t)
    check_weights(idx, w, 2)
    assert np.allclose(w[:, :2], 0.5)
    assert set(idx[0, :2]) == set(idx[1, :2]) == {lay.bone_rig[on[0]], lay.bone_rig[on[1]]}


def test_junction_is_one_sided_and_siblings_share_nothing():
    J, B = star_skeleton(flip=False)                       # bones (prev, cur): t = 1 at the centre side
    lay = rig_layout(J, B)
    first = [b for b in range(len(B)) if B[b][0] == 0]     # the four bones leaving the centre
    idx, w = skin_weights(lay, first, np.ones(4))           # at the centre
    assert np.all(idx[:, 0] == 0) and np.allclose(w[:, 0], 1.0)   # all on the root bone
    idx, w = skin_weights(lay, first, np.full(4, 0.9))      # inside the blend zone
    W = dense(idx, w, lay.n_bones)
    for k, b in enumerate(first):
        others = [lay.bone_rig[o] for o in first if o != b]
        assert np.all(W[k, others] == 0)                    # no weight on sibling arms
        assert 0 < W[k, lay.bone_rig[b]] < 1 and 0 < W[k, 0] < 1


def test_continuity_along_a_chain():
    J, B = star_skeleton(flip=True)
    lay = rig_layout(J, B)
    # walk arm 0 (joints 0-1-2-3) finely, through its two chain joints
    arm = [0, 1, 2]
    s = np.linspace(0, 3, 3001)
    k = np.minimum(s.astype(int), 2)
    u = s - k                                               # fraction from joint k to joint k+1
    bone = np.array(arm)[k]
    t = np.where(B[bone, 0] == k, 1 - u, u)                 # sigma = t x_i + (1 - t) x_j
    idx, w = skin_weights(lay, bone, t, blend=0.25)
    check_weights(idx, w, len(s))
    W = dense(idx, w, lay.n_bones)
    jump = np.abs(np.diff(W, axis=0)).max()
    assert jump < 1.01 * 1.5 * 0.001 / 0.25               # smoothstep slope 1.5 per blend width
    # a different blend changes the zone width, never the sums
    for blend in (0.0, 0.1, 0.5):
        idx, w = skin_weights(lay, bone, t, blend=blend)
        check_weights(idx, w, len(s))
    idx, w = skin_weights(lay, bone, t, blend=0.0)
    assert np.allclose(w[:, 0], 1.0)


def test_ring_meeting_point_is_continuous():
    J, B = ring_skeleton(n=12)
    lay = rig_layout(J, B)
    # the far joint where the two halves meet: both bones give 50/50 there
    meet = [r for r in range(1, lay.n_bones) if lay.tail_joint[r] == lay.tail_joint[lay.tail_partner[r]]]
    bones = [lay.skeleton_bone[r] for r in meet]
    j = lay.tail_joint[meet[0]]
    t = [1.0 if B[b][0] == j else 0.0 for b in bones]
    idx, w = skin_weights(lay, bones, t)
    assert np.allclose(w[:, :2], 0.5)


def test_rejects_bad_blend():
    J, B = star_skeleton()
    lay = rig_layout(J, B)
    with pytest.raises(CurveSkelError):
        skin_weights(lay, [0], [0.5], blend=0.7)
    assert np.allclose(smoothstep(np.array([-1, 0, 0.5, 1, 2])), [0, 0, 0.5, 1, 1])


def test_project_on_bones_matches_all_bones():
    rng = np.random.default_rng(0)
    J, B = star_skeleton(per_arm=6)
    P = rng.normal(size=(5000, 3)) * 2
    b1, t1, d1 = project_on_bones(P, J, B)
    b2, t2, d2 = closest_on_bones(P, J, B)
    assert np.allclose(d1, d2)
    ok = b1 == b2
    assert ok.mean() > 0.99 and np.allclose(t1[ok], t2[ok])


@pytest.mark.parametrize("name", ["star", "bent_capsule", "torus"])
def test_real_mesh_weights(name):
    V, F = getattr(meshes, name)()
    sk = skeletonize(V, F)
    lay = rig_layout(sk.joints, sk.bones)
    idx, w = skin_weights(lay, sk.bone, sk.t)
    check_weights(idx, w, len(V))
    assert np.all(idx[:, 0] >= 0)                          # every vertex has a weight


def test_smooth_weights_closes_seams_and_keeps_sums():
    # a strip of vertices 0..99 in a row: bone 0 on the left half, bone 1 on the right (a seam)
    n = 100
    idx = np.full((n, 4), -1)
    w = np.zeros((n, 4))
    idx[:, 0] = (np.arange(n) >= 50).astype(int)
    w[:, 0] = 1.0
    E = np.stack([np.arange(n - 1), np.arange(1, n)], 1)
    i2, w2 = smooth_weights(idx, w, E, iterations=20)
    check_weights(i2, w2, n)
    W = dense(i2, w2, 2)
    assert np.abs(np.diff(W[:, 0])).max() < 0.2             # the jump of 1 is spread out
    assert np.allclose(W[:20, 0], 1.0) and np.allclose(W[-20:, 1], 1.0)   # far away: unchanged
    assert np.allclose(W[:, 0], W[::-1, 1])                 # symmetric
    i0, w0 = smooth_weights(idx, w, E, iterations=0)
    assert np.array_equal(i0, idx) and np.array_equal(w0, w)


@pytest.mark.parametrize("iterations", [1, 6])
def test_smooth_weights_dense_and_sparse_diffusion_agree(monkeypatch, iterations):
    # the same diffusion on a dense float32 array (small meshes) and on sparse matrices (large
    # ones): a capsule with 8 bones along it, two influences per vertex near the joints
    import curveskel_addon.rig.skin_weights as sw
    V, F = meshes.capsule()
    z = (V[:, 2] - V[:, 2].min()) / np.ptp(V[:, 2]) * 8
    b = np.minimum(z.astype(int), 7)
    frac = z - b
    idx = np.full((len(V), 4), -1)
    w = np.zeros((len(V), 4))
    idx[:, 0], w[:, 0] = b, 1.0 - 0.5 * frac
    idx[:, 1], w[:, 1] = np.minimum(b + 1, 7), 0.5 * frac
    idx[b == 7, 1], w[b == 7, 0], w[b == 7, 1] = -1, 1.0, 0.0
    E = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    i_d, w_d = smooth_weights(idx, w, E, iterations=iterations)
    monkeypatch.setattr(sw, "DENSE_SMOOTH_WORK", 0)
    i_s, w_s = smooth_weights(idx, w, E, iterations=iterations)
    check_weights(i_d, w_d, len(V))
    assert np.abs(dense(i_d, w_d, 8) - dense(i_s, w_s, 8)).max() < 5e-4
    assert np.array_equal(i_d[:, 0], i_s[:, 0])           # the same main bone everywhere


def test_smooth_weights_keeps_four_largest():
    # a star graph: centre vertex 0 joined to 6 vertices each on its own bone
    idx = np.full((7, 4), -1)
    w = np.zeros((7, 4))
    idx[:, 0] = np.arange(7)
    w[:, 0] = 1.0
    E = np.stack([np.zeros(6, int), np.arange(1, 7)], 1)
    i2, w2 = smooth_weights(idx, w, E, iterations=1)
    check_weights(i2, w2, 7)
    assert i2[0, 0] == 0 and (i2[0] >= 0).sum() == 4
    assert smoothing_iterations(1.0, 0.1, cap=50) == 50 and smoothing_iterations(0.1, 0.1) == 1
    assert smoothing_iterations(0.0, 0.1) == 0


# -- weights from the bones as they are (issue 14) ---------------------------------------------------
from curveskel_addon.rig.rig_layout import BLEND_HUB as _HUB, BLEND_NONE as _NONE, BLEND_SYMMETRIC as _SYM  # noqa: E402
from curveskel_addon.rig.skin_weights import bone_partners, bone_weights, surface_labels  # noqa: E402

GAP, FR = 0.03, 0.1
FX = FR + GAP / 2


def two_fingers():
    """Palm (radius 0.25, top at z = 0) + two fingers of radius 0.1 whose surfaces are 0.03 apart."""
    from meshes import _manifold_from, _to_arrays, tube_along

    union = _manifold_from(*tube_along(np.array([[0.0, 0.0, -0.4], [0.0, 0.0, 0.0]]), 0.25, 32))
    for sx in (-FX, FX):
        path = np.stack([np.full(40, sx), np.zeros(40), np.linspace(-0.05, 1.0, 40)], 1)
        union = union + _manifold_from(*tube_along(path, FR, 24))
    return _to_arrays(union)


def hand_bones(right_tip=(FX, 0.0, 1.0)):
    """palm, then two 2-bone fingers hanging from the palm's tail (a junction)."""
    H = [(0, 0, -0.4), (-FX, 0, 0.2), (-FX, 0, 0.6), (FX, 0, 0.2), (FX, 0, 0.6)]
    T = [(0, 0, 0.2), (-FX, 0, 0.6), (-FX, 0, 1.0), (FX, 0, 0.6), right_tip]
    return np.array(H, float), np.array(T, float), np.array([-1, 0, 1, 0, 3])


def test_bone_partners_chain_junction_root_and_detached():
    # root bone 0 at the origin pointing up; bones 1 and 2 leave its head; 1 -> 3 a chain;
    # 3 ends at a junction with 4 and 5; 6 is detached from its parent; 7 does not deform
    H = np.array([[0, 0, 0], [0, 0, 0], [0, 0, 0], [1, 0, 0], [2, 0, 0], [2, 0, 0], [5, 5, 5], [2, 0, 0]], float)
    T = np.array([[0, 0, 1], [1, 0, 0], [-1, 0, 0], [2, 0, 0], [3, 0, 0], [2, 1, 0], [6, 5, 5], [2, 0, 1]], float)
    par = np.array([-1, 0, 0, 1, 3, 3, 4, 3])
    deform = np.array([1, 1, 1, 1, 1, 1, 1, 0], bool)
    hm, tm, hp, tp, att = bone_partners(H, T, par, deform)
    assert hm[1] == hm[2] == _HUB and hp[1] == hp[2] == 0           # under the root bone
    assert tm[1] == _SYM and tp[1] == 3 and hm[3] == _SYM and hp[3] == 1   # a chain joint
    assert hm[4] == hm[5] == _HUB and hp[4] == hp[5] == 3 and tm[3] == _NONE   # a junction
    assert hm[6] == _NONE and not att[6]                            # detached
    assert hm[7] == _NONE and not att[7] and tp[3] == -1            # not deforming: no partner


def test_two_fingers_0_03_apart_share_no_weight():
    V, F = two_fingers()
    H, T, par = hand_bones()
    idx, w, info = bone_weights(V, F, H, T, par)
    check_weights(idx, w, len(V))
    Wd = dense(idx, w, len(H))
    left, right = (V[:, 0] < -GAP / 2) & (V[:, 2] > 0.25), (V[:, 0] > GAP / 2) & (V[:, 2] > 0.25)
    assert Wd[right][:, [1, 2]].max() == 0.0 and Wd[left][:, [3, 4]].max() == 0.0
    up = V[:, 2] > 0.4
    assert Wd[left & up][:, [1, 2]].sum(axis=1).min() > 0.9   # each finger is its own
    # weights are continuous along a finger: the chain joint at z = 0.6 is a 50/50 blend
    ring = left & (np.abs(V[:, 2] - 0.6) < 0.02)
    assert ring.any() and np.allclose(Wd[ring][:, 1], 0.5, atol=0.1)


def test_surface_restriction_moves_islands_to_the_part_they_lie_on():
    """A bone of the right finger bent over towards the left one: the left finger's inner side
    is closer to it in space, but that patch is not connected to the right finger's vertices
    on the surface, so it stays with the left finger."""
    V, F = two_fingers()
    H, T, par = hand_bones(right_tip=(-0.02, 0.0, 1.0))
    E = np.unique(np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1), axis=0)
    label, s, dist, closest = surface_labels(V, E, H, T)
    left = (V[:, 0] < -GAP / 2) & (V[:, 2] > 0.3)
    assert np.isin(closest[left], [3, 4]).sum() > 5               # straight-line distance is fooled
    assert not np.isin(label[left], [3, 4]).any()                 # the surface is not
    assert np.all((s >= 0) & (s <= 1)) and np.all(dist >= 0)
    idx, w, info = bone_weights(V, F, H, T, par)
    assert info["relabelled"] > 5
    assert dense(idx, w, len(H))[left][:, [3, 4]].max() == 0.0


def test_bone_weights_rejects_bad_input():
    V, F = meshes.capsule()
    H = np.array([[0, 0, 0.0], [0, 0, 3.0]])
    T = np.array([[0, 0, 3.0], [0, 0, 6.0]])
    with pytest.raises(CurveSkelError):
        bone_weights(V, F, H, T, [-1, 0], blend=0.7)
    with pytest.raises(CurveSkelError):
        bone_weights(V, F, H, T, [-1, 0], deform=[False, False])
    with pytest.raises(CurveSkelError):
        bone_weights(V, F + len(V), H, T, [-1, 0])
    idx, w, _ = bone_weights(V, F, H, T, [-1, 0], smooth=0.0)
    check_weights(idx, w, len(V))
    Wd = dense(idx, w, 2)
    assert np.allclose(Wd[V[:, 2] < 1.0, 0], 1.0) and np.allclose(Wd[V[:, 2] > 5.0, 1], 1.0)


def star_bones():
    """A root bone at the centre of meshes.star() pointing up, and two bones along each arm
    leaving its head (a junction: the chains hand over into the root bone)."""
    H, T, par = [(0, 0, 0.0)], [(0, 0, 0.5)], [-1]
    for a in range(4):
        u = np.array([np.cos(a * np.pi / 2), np.sin(a * np.pi / 2), 0.0])
        H += [tuple(0 * u), tuple(2 * u)]
        T += [tuple(2 * u), tuple(4 * u)]
        par += [0, len(H) - 2]
    return np.array(H, float), np.array(T, float), np.array(par)


@pytest.mark.parametrize("junction_blend", [0.0, 0.25])
def test_chain_boundaries_rigid_by_default(junction_blend):
    V, F = meshes.star()
    H, T, par = star_bones()
    idx, w, _ = bone_weights(V, F, H, T, par, junction_blend=junction_blend)
    check_weights(idx, w, len(V))
    Wd = dense(idx, w, len(H))
    chain = np.array([0, 1, 1, 2, 2, 3, 3, 4, 4])          # root, then one chain per arm
    Wc = np.zeros((len(V), 5))
    for r in range(len(H)):
        Wc[:, chain[r]] += Wd[:, r]
    arms = (Wc[:, 1:] > 1e-9).sum(axis=1)
    assert arms.max() == 1                                   # never two arms
    mixed = (Wc[:, 0] > 0.1) & (Wc[:, 1:].max(axis=1) > 0.1)
    if junction_blend == 0:
        assert not ((Wc > 1e-9).sum(axis=1) > 1).any()       # one chain per vertex
    else:
        assert mixed.sum() > 10                              # the hand-over at the centre
    # inside a chain the joint at the arm's middle still blends 50/50
    mid = (np.abs(V[:, 0] - 2.0) < 0.07) & (np.abs(V[:, 1]) < 0.6)
    assert mid.any() and np.allclose(Wd[mid][:, 1], 0.5, atol=0.1)


# -- the bind's building blocks against straightforward references (issue 14's faster bind) ---------
def test_graph_arrays_equal_scipys_csr_of_the_closed_one_ring():
    """_Graph builds its CSR arrays from sorted keys; they must be scipy's COO -> CSR of the
    closed 1-ring (duplicate and reversed edges once, self-loops dropped, columns sorted)."""
    import scipy.sparse as sp

    from curveskel_addon.rig.skin_weights import _Graph

    rng = np.random.default_rng(3)
    n = 40
    E = rng.integers(0, n, size=(150, 2))
    E = np.concatenate([E, E[:20, ::-1], E[:10], [[5, 5], [7, 7]]])     # reversed, repeated, loops
    g = _Graph(E, n)
    keep = E[E[:, 0] != E[:, 1]]
    ar = np.arange(n)
    C = sp.csr_matrix((np.ones(2 * len(keep) + n), (np.r_[keep[:, 0], keep[:, 1], ar],
                                                    np.r_[keep[:, 1], keep[:, 0], ar])), shape=(n, n))
    C.sort_indices()
    assert np.array_equal(g.indptr, C.indptr) and np.array_equal(g.indices, C.indices)
    assert np.array_equal(g.rows, np.repeat(ar, np.diff(C.indptr)))
    assert np.array_equal(g.deg, np.diff(C.indptr) - 1)
    assert np.array_equal(g.diag, g.indices == g.rows)
    empty = _Graph(np.zeros((0, 2), np.int64), 0)
    assert len(empty.indptr) == 1 and len(empty.indices) == 0
    lone = _Graph(np.zeros((0, 2), np.int64), 3)                         # no edges: the diagonal
    assert np.array_equal(lone.indices, [0, 1, 2]) and np.array_equal(lone.indptr, [0, 1, 2, 3])


def test_float32_averaging_is_the_float64_one_rounded():
    from curveskel_addon.rig.skin_weights import _Graph

    V, F = meshes.capsule()
    E = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    g = _Graph(E, len(V))
    S64, S32 = g.averaging(), g.averaging(np.float32)
    assert S32.dtype == np.float32 and S64.dtype == np.float64
    assert np.array_equal(S32.indptr, S64.indptr) and np.array_equal(S32.indices, S64.indices)
    assert np.array_equal(S32.data, S64.data.astype(np.float32))
    assert np.allclose(np.asarray(S64.sum(axis=1)).ravel(), 1.0)


def test_closest_bone_is_the_first_of_the_exactly_closest():
    """closest_bone (float32 screen, near-ties compared exactly) against every bone compared
    exactly, the first of equal distances kept; points on shared joints tie exactly."""
    from curveskel_addon.core.geometry.segments import _pair_closest, closest_bone

    rng = np.random.default_rng(7)
    X = rng.normal(size=(30, 3))
    bones = np.stack([np.arange(29), np.arange(1, 30)], 1)             # a chain: joints shared
    bones = np.concatenate([bones, [[0, 5], [10, 20], [3, 3]]])        # branches, a zero-length bone
    P = np.concatenate([rng.normal(size=(500, 3)) * 1.5, X, X[:5] + 1e-9])
    got = closest_bone(P, X, bones)
    d2 = np.stack([_pair_closest(P, np.broadcast_to(X[i], P.shape), np.broadcast_to(X[j], P.shape))[1]
                   for i, j in bones], 1)
    assert np.array_equal(got, np.argmin(d2, axis=1))                  # argmin: the first minimum
    assert np.array_equal(got, closest_on_bones(P, X, bones)[0])
    assert closest_bone(np.zeros((0, 3)), X, bones).shape == (0,)


def _family_reference(index, weight, par, blends):
    """bone_weights' family filter as first written: masks over the whole (n, m) array."""
    main = index[:, :1]
    ok = index >= 0
    idx = np.maximum(index, 0)
    pm = np.where(blends[main], par[main], -2)
    pi = np.where(blends[idx], par[idx], -2)
    up = ok & (idx == pm) & (idx != main)
    down = ok & (pi == main) & (idx != main)
    family = ok & ((idx == main) | up | down)
    weight = np.where(family, weight, 0.0)
    wd = np.where(down, weight, -1.0)
    heaviest = np.argmax(wd, axis=1)[:, None]
    down &= np.arange(down.shape[1])[None, :] == heaviest
    weight = np.where(family & ~(idx == main) & ~up & ~down, 0.0, weight)
    w_up = np.where(up, weight, 0.0).sum(axis=1, keepdims=True)
    w_down = np.where(down, weight, 0.0).sum(axis=1, keepdims=True)
    weight = np.where((up & (w_up < w_down)) | (down & (w_down <= w_up) & (w_up > 0)), 0.0, weight)
    index = np.where(family, index, -1)
    total = weight.sum(axis=1, keepdims=True)
    weight = np.divide(weight, total, out=np.zeros_like(weight), where=total > 0)
    order = np.argsort(-weight, axis=1, kind="stable")
    index = np.take_along_axis(index, order, axis=1)
    weight = np.take_along_axis(weight, order, axis=1)
    index[weight <= 0] = -1
    return index, weight


@pytest.mark.parametrize("seed", range(6))
def test_keep_family_equals_the_masked_reference(seed):
    """The one-pass family filter gives the masked reference's arrays bit for bit: random trees,
    rows of distinct bones with decreasing weights (ties included), empty rows and columns."""
    from curveskel_addon.rig.skin_weights import _keep_family

    rng = np.random.default_rng(seed)
    R, n, m = 12, 400, 4
    par = np.array([-1] + [int(rng.integers(0, r)) for r in range(1, R)])
    blends = (rng.random(R) < 0.7) & (par >= 0)
    index = np.full((n, m), -1, np.int64)
    weight = np.zeros((n, m))
    for v in range(n):
        k = int(rng.integers(0, m + 1)) if v % 50 else 0
        near = [b for b in range(R) if par[b] == v % R or b == par[v % R]]
        pool = list(dict.fromkeys([v % R] + near + list(rng.permutation(R))))[:k]
        w = np.sort(rng.choice([0.5, 0.25, 0.125, 0.3, 0.1], size=k))[::-1]   # ties likely
        index[v, :k], weight[v, :k] = pool, w / max(w.sum(), 1e-300)
    want = _family_reference(index, weight, par, blends)
    got = _keep_family(index, weight, np.where(blends, par, -2))
    assert np.array_equal(got[0], want[0]) and np.array_equal(got[1], want[1])
    assert (got[0][:, 1] >= 0).sum() > 50                      # rows with two influences occur


def _top4_reference(Wd, max_influences, prune):
    """The dense smoothing's 4 largest as first written: prune, then argmax along each row."""
    Wd = Wd.copy()
    n, nb = Wd.shape
    Wd[Wd < prune] = 0.0
    out_i = np.full((n, max_influences), -1, np.int64)
    out_w = np.zeros((n, max_influences))
    rank = np.arange(n)
    for j in range(min(max_influences, nb)):
        best = np.argmax(Wd, axis=1)
        v = Wd[rank, best]
        out_i[:, j] = np.where(v > 0, best, -1)
        out_w[:, j] = v
        Wd[rank, best] = 0.0
    total = out_w.sum(axis=1, keepdims=True)
    out_w = np.divide(out_w, total, out=np.zeros_like(out_w), where=total > 0)
    return out_i, out_w


@pytest.mark.parametrize("seed", range(4))
def test_dense_top4_equals_the_argmax_reference(seed):
    """_smooth_dense picks the 4 largest on the transposed array, dropping weights below the
    prune threshold as they come up: bit for bit the row-wise argmax after a pruning pass (ties
    to the lower column, rows with fewer than 4 weights, rows with none, values under prune)."""
    from curveskel_addon.rig.skin_weights import _Graph, _smooth_dense

    rng = np.random.default_rng(seed)
    n, nb = 300, 9
    Wd = rng.choice([0.0, 0.0, 0.0, 5e-5, 0.125, 0.25, 0.5, 0.3], size=(n, nb)).astype(np.float32)
    Wd[::17] = 0.0                                                    # rows with no weight
    Wd[1::13] = np.float32(0.25)                                     # rows of equal weights
    rows, cols = np.nonzero(Wd)
    graph = _Graph(np.zeros((0, 2), np.int64), n)
    for prune in (1e-4, 0.0):
        got = _smooth_dense(rows, cols, Wd[rows, cols].astype(np.float64), n, nb, graph, 0, 4, prune)
        want = _top4_reference(Wd, 4, prune)
        assert np.array_equal(got[0], want[0]) and np.array_equal(got[1], want[1])
    assert (want[0][:, 3] >= 0).any() and (want[0][:, 0] < 0).any()


def test_median_is_numpys():
    from curveskel_addon.rig.skin_weights import _median

    rng = np.random.default_rng(5)
    for n in (1, 2, 3, 10, 11, 451, 2930):
        x = rng.random(n) * 10.0 ** rng.integers(-3, 3)
        for y in (x, np.round(x, 1)):                                   # ties too
            assert _median(y) == float(np.median(y))


@pytest.mark.parametrize("seed", range(5))
def test_kept_patches_equal_the_sorted_reference(seed):
    """Each bone keeps its largest patch, of equal ones that of its lowest vertex: the same as
    the first patch per bone after a stable sort by bone, then by decreasing size (ties made
    likely: patches of 1-3 vertices)."""
    from curveskel_addon.rig.skin_weights import _kept_patches

    rng = np.random.default_rng(seed)
    R, P = 7, 60
    patch_bone = rng.integers(0, R, P)
    comp = rng.permutation(np.repeat(np.arange(P), rng.integers(1, 4, P)))
    label = patch_bone[comp]
    size = np.bincount(comp)
    order = np.lexsort((-size[comp], label))
    first = np.r_[True, label[order][1:] != label[order][:-1]]
    keep = np.zeros(len(size), bool)
    keep[comp[order[first]]] = True
    assert np.array_equal(_kept_patches(label, comp, R), keep[comp])
