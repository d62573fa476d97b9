"""Refinement (bones that leave the mesh are split), the reusable inside test, and the
containment samples along the bones in the LM solver (issue 5: skeletons inside the shape)."""

from __future__ import annotations

import numpy as np
import pytest

from curveskel_addon.core import skeletonize
from curveskel_addon.core.problem import FitProblem
from curveskel_addon.core.quality import InsideTest, inside_mesh, winding_number
from curveskel_addon.core.refine import outside_samples, pull_in_joints, refine, split_bones
from curveskel_addon.core.refit import refit_mapping
from curveskel_addon.core.solvers.lm import _Regulariser, _sample_matrix, lm_steps
from tests.core.test_regularisation import _box
from tests.meshes import bent_capsule, capsule, torus


def _sigma(pr):
    i, j = pr.bones[pr.bone, 0], pr.bones[pr.bone, 1]
    return pr.t[:, None] * pr.joints[i, :3] + (1 - pr.t[:, None]) * pr.joints[j, :3]


def _corner_cut():
    """The L-shaped capsule with ONE bone from the end of one arm to the end of the other: both
    joints inside, the middle of the bone far outside (it cuts the corner)."""
    V, F = bent_capsule()
    joints = np.array([[-4.0, 0.0, 0.0, 0.5], [0.0, 0.0, 4.0, 0.5]])
    pr = FitProblem(V, np.ones(len(V)), joints, np.array([[0, 1]]), np.zeros(len(V), np.int64),
                    np.full(len(V), 0.5))
    pr.bone, pr.t, _, _ = refit_mapping(pr)
    pr.meta["regularisation"] = {"containment": 1.0, "smoothness": 0.0, "surface": (V, F)}
    return V, F, pr


def _lm(pr, iterations=100):
    last = None
    for last in lm_steps(pr, max_iterations=iterations, refit_mapping=True):
        pass
    out = pr.copy()
    out.joints, out.bone, out.t = last.joints, last.bone, last.t
    return out


def test_inside_test_reused_equals_one_off_and_winding_number():
    V, F = torus()
    rng = np.random.default_rng(1)
    test = InsideTest(V, F)
    for _ in range(2):                                   # built once, queried twice
        P = rng.uniform(-4.2, 4.2, size=(400, 3)) * [1, 1, 0.35]
        ins = test(P)
        assert np.array_equal(ins, inside_mesh(P, V, F))
        assert np.array_equal(ins, winding_number(P, V, F) > 0.5)
        assert 0.1 < ins.mean() < 0.9


def test_outside_samples_finds_the_corner_cut():
    V, F, pr = _corner_cut()
    t, out, joint_out = outside_samples(pr.joints, pr.bones, InsideTest(V, F), per_bone=16)
    assert not joint_out.any()
    # The bone's middle is outside, its ends inside (distance of the midpoint (-2, 0, 2) to the
    # L's axis is about 1.6, the radius 0.5).
    assert out[0, 6:10].all() and not out[0, [0, -1]].any()


def test_split_keeps_sigma_and_places_the_joint_inside():
    V, F, pr = _corner_cut()
    sp = split_bones(pr, np.array([0]), np.array([0.5]))
    assert sp.joints.shape == (3, 4) and sp.bones.tolist() == [[0, 2], [2, 1]]
    # The new joint starts at the centre of the cross-section the bone explains there: inside.
    assert inside_mesh(sp.joints[2:, :3], V, F)[0]
    assert 0.2 < sp.joints[2, 3] < 1.2
    # The mapping is carried over exactly: with the new joint at the interpolated point, every
    # vertex's sigma is where it was.
    exact = sp.copy()
    exact.joints[2] = 0.5 * pr.joints[0] + 0.5 * pr.joints[1]
    np.testing.assert_allclose(_sigma(exact), _sigma(pr), atol=1e-12)
    assert np.all((sp.t >= 0) & (sp.t <= 1))


def test_refine_brings_a_corner_cutting_bone_inside():
    V, F, pr = _corner_cut()
    out, log = refine(_lm(pr), V, F, _lm, max_joints=300, rounds=3)
    assert log["outside_before"] > 0.2
    assert log["outside_after"] == 0.0
    assert log["split"][0] == 1 and log["kept"][0]
    assert len(out.joints) > 2
    _, o, jo = outside_samples(out.joints, out.bones, InsideTest(V, F), per_bone=32)
    assert not o.any() and not jo.any()


def test_refine_respects_the_joint_budget():
    V, F, pr = _corner_cut()
    out, log = refine(pr, V, F, _lm, max_joints=2, rounds=3)
    assert sum(log["split"]) == 0 and len(out.joints) == 2    # joints may move, none is added


def test_pull_in_moves_an_outside_leaf_along_its_bone():
    V, F = capsule(radius=1.0, length=6.0)            # axis z from 0 to 6, caps beyond
    joints = np.array([[0.0, 0.0, 7.5, 0.1], [0.0, 0.0, 3.0, 1.0], [0.0, 0.0, 0.5, 0.5]])
    bones = np.array([[0, 1], [1, 2]])
    moved, n = pull_in_joints(joints, bones, InsideTest(V, F))
    assert n == 1
    assert inside_mesh(moved[:1, :3], V, F)[0]
    assert 6.0 < moved[0, 2] < 7.0                     # just inside the cap (its top is z = 7)
    np.testing.assert_array_equal(moved[1:], joints[1:])


def test_sample_matrix_interpolates_joints_and_radii():
    bones = np.array([[0, 1], [1, 2]])
    W, sw = _sample_matrix(bones, 3, np.array([0.25, 0.5, 0.75]), 1.0)
    J = np.array([[0.0, 0, 0, 1.0], [4.0, 0, 0, 3.0], [4.0, 4, 0, 1.0]])
    X = W @ J
    np.testing.assert_allclose(X[:3], J)
    np.testing.assert_allclose(X[3], [1.0, 0, 0, 1.5])          # u = 1/4 from joint 0
    np.testing.assert_allclose(X[7], [4.0, 2, 0, 2.0])          # the middle of bone 1
    np.testing.assert_allclose(sw, [1, 1, 1] + [1 / 3] * 6)


def test_containment_gradient_matches_finite_differences():
    V, F, pr = _corner_cut()
    reg = _Regulariser(pr, pr.joints, 1.0)
    # Off the L's symmetry plane x = -z, where the nearest surface switches arms (a kink).
    J0 = pr.joints + np.array([[0.3, 0.05, 0.1, 0.1], [-0.1, 0.02, 0.25, 0.2]])
    g, grad = reg._containment(J0)
    X = reg.W @ J0
    h = 1e-6
    for k in range(4):
        # Moving both joints by h moves every sample by h: the sample gradient, column k.
        Jp, Jm = J0.copy(), J0.copy()
        Jp[:, k] += h
        Jm[:, k] -= h
        fd = (reg._containment(Jp)[0] - reg._containment(Jm)[0]) / (2 * h)
        np.testing.assert_allclose(fd, grad[:, k], rtol=1e-4, atol=1e-6)
    assert len(g) == len(X) == 2 + 3


def test_signed_distance_is_negative_just_outside_a_thin_plate():
    # A plate 0.04 thick on a 0.25 grid: the 8 nearest surface points of a point just above it
    # include the far side, whose planes would say "inside"; only the near side must count.
    V, F = _box(half=(2.0, 0.02, 2.0), n=16)
    pr = FitProblem(V, np.ones(len(V)), np.array([[0.0, 0.03, 0.0, 0.0]]), np.zeros((0, 2), int),
                    np.zeros(len(V), int), np.ones(len(V)))
    pr.meta["regularisation"] = {"containment": 1.0, "smoothness": 0.0, "surface": (V, F)}
    reg = _Regulariser(pr, pr.joints, 1.0)
    for y, sign in ((0.03, -1), (0.06, -1), (0.0, 1), (-0.03, -1)):
        g, _ = reg._containment(np.array([[0.1, y, 0.1, 0.0]]))
        assert np.sign(-g[0]) == sign, (y, -g[0])


def test_bone_samples_see_and_reduce_a_corner_cut():
    V, F, pr = _corner_cut()
    test = InsideTest(V, F)
    regs = {}
    for weight in (0.0, 1.0):
        q = pr.copy()
        q.meta = {"regularisation": dict(pr.meta["regularisation"], bone_sample_weight=weight)}
        regs[weight] = (q, _Regulariser(q, q.joints, 1.0))
    # Both joints are inside with their balls (up to the faceting of the tube): only the
    # samples along the bone see the cut.
    assert regs[0.0][1].value(pr.joints) < 1e-3 * regs[1.0][1].value(pr.joints)
    q, reg = regs[1.0]
    sol = _lm(q)
    assert reg.value(sol.joints) < 0.5 * reg.value(pr.joints)
    assert outside_samples(sol.joints, sol.bones, test)[1].mean() < outside_samples(
        pr.joints, pr.bones, test)[1].mean()


def test_default_pipeline_records_the_refinement():
    V, F = bent_capsule()
    sk = skeletonize(V, F)
    log = sk.meta["refine"]
    assert log["outside_after"] <= log["outside_before"]
    assert sk.n_joints <= 300
    off = skeletonize(V, F, refine=0)
    assert "refine" not in off.meta and "refine" not in off.timings


def test_pull_in_moves_an_outside_chain_joint_towards_its_neighbours():
    V, F = capsule(radius=1.0, length=6.0)
    # The middle joint of a chain pokes out sideways (x = 1.6, the tube's radius is 1).
    joints = np.array([[0.0, 0.0, 1.0, 1.0], [1.6, 0.0, 3.0, 1.0], [0.0, 0.0, 5.0, 1.0]])
    moved, n = pull_in_joints(joints, np.array([[0, 1], [1, 2]]), InsideTest(V, F))
    assert n == 1 and inside_mesh(moved[1:2, :3], V, F)[0]
    assert moved[1, 0] == pytest.approx(0.8) and moved[1, 2] == 3.0   # half-way: the first step in
    np.testing.assert_array_equal(moved[[0, 2]], joints[[0, 2]])


def test_local_rounds_alone_repair_without_a_solver():
    V, F, pr = _corner_cut()

    def no_solver(q):
        raise AssertionError("rounds=0: the solver must not run")

    out, log = refine(pr, V, F, no_solver, rounds=0, local_rounds=6)
    assert log["local"] >= 1 and all(log["kept"])
    assert log["outside_after"] < 0.5 * log["outside_before"]
    assert len(out.joints) > 2


def test_unfold_removes_a_chain_doubling_back_along_another_part():
    from curveskel_addon.core.postprocess import fold_joints, unfold_chains

    V, F = capsule(radius=0.5, length=8.0)
    # From joint 0 the chain goes down to 1, back up to 2 (along bone (0, 4), inside its round
    # cone), down again to 3 and on to 5: folds at 1 and 2.
    joints = np.array([[0, 0, 4.0, 0.5], [0, 0, 2.0, 0.5], [0, 0, 6.5, 0.5], [0, 0, 1.5, 0.5],
                       [0, 0, 7.5, 0.5], [0, 0, 0.0, 0.5]])
    bones = np.array([[0, 1], [1, 2], [2, 3], [3, 5], [0, 4]])
    folds = fold_joints(joints, bones)
    assert folds.tolist() == [False, True, True, False, False, False]
    pr = FitProblem(V, np.ones(len(V)), joints, bones, np.zeros(len(V), np.int64), np.full(len(V), 0.5))
    pr.bone, pr.t, _, _ = refit_mapping(pr)
    out, merged = unfold_chains(pr)
    assert merged >= 2
    assert not fold_joints(out.joints, out.bones).any()
    # Topology kept: one component, no cycle, the same leaves.
    deg = np.bincount(out.bones.ravel(), minlength=len(out.joints))
    assert len(out.bones) == len(out.joints) - 1 and (deg == 1).sum() == 2
    # A straight chain and a zig-zag that overlaps nothing else are not folds.
    straight = np.array([[0, 0, z, 0.5] for z in (0.0, 2.0, 4.0, 6.0)])
    assert not fold_joints(straight, np.array([[0, 1], [1, 2], [2, 3]])).any()
    zig = np.array([[0, 0, 0, 0.1], [3, 0, 0, 0.1], [0.2, 0, 0.5, 0.1]])
    assert not fold_joints(zig, np.array([[0, 1], [1, 2]])).any()


def test_star_skeleton_has_no_fold():
    from curveskel_addon.core.postprocess import fold_joints
    from tests.meshes import star

    V, F = star()
    sk = skeletonize(V, F)
    assert not fold_joints(sk.joints, sk.bones).any()
    # ... nor a short reversal at the junction (a bone pointing back inside the joint's ball):
    # the refinement merged them (the first approximation of the star has two).
    assert not fold_joints(sk.joints, sk.bones, min_length=0.0, overlap=False).any()
    assert sk.meta["refine"]["reversals"] >= 1
    L = np.linalg.norm(sk.joints[sk.bones[:, 0], :3] - sk.joints[sk.bones[:, 1], :3], axis=1).sum()
    assert L < 1.15 * 16.0                           # four arms of 4: no long doubling back



def test_local_split_places_a_medial_joint_when_the_bone_explains_no_points():
    # All points mapped at the bone's end: no cross-section near the split to take a centroid
    # from (a tentacle bone of the octopus explains 4-18 vertices). The medial balls of the
    # surface place the new joints inside the tube with the tube's radius.
    V, F, pr = _corner_cut()
    pr.t[:] = 0.999
    out, log = refine(pr, V, F, None, rounds=0, local_rounds=6)
    assert log["outside_before"] == 0.75 and log["outside_after"] == 0.0
    new = out.joints[2:]
    assert len(new) >= 1 and InsideTest(V, F)(new[:, :3]).all()
    np.testing.assert_allclose(new[:, 3], 0.5, atol=0.06)


def _straight_capsule_problem():
    V, F = capsule(radius=1.0, length=6.0)
    joints = np.array([[0.0, 0.0, 0.0, 1.0], [0.0, 0.0, 3.0, 1.0], [0.0, 0.0, 6.0, 1.0]])
    bones = np.array([[0, 1], [1, 2]])
    pr = FitProblem(V, np.ones(len(V)), joints, bones, np.zeros(len(V), np.int64),
                    np.full(len(V), 0.5))
    pr.bone, pr.t, _, _ = refit_mapping(pr)
    return V, F, pr


def test_refine_solves_only_when_enough_is_outside_or_the_problem_is_unsolved():
    V, F, pr = _straight_capsule_problem()
    calls = []

    def solve(q):
        calls.append(len(q.joints))
        return q

    out, log = refine(pr, V, F, solve, rounds=3)
    assert log["outside_before"] == 0.0 and calls == []          # inside: nothing to re-solve
    out, log = refine(pr, V, F, solve, rounds=3, solved=False)
    assert calls == [3]                                           # solved once, as it was
    V, F, pr = _corner_cut()                                      # 75 % outside: solved rounds
    refine(pr, V, F, solve, rounds=1)
    assert calls == [3, 3]


def test_containment_memo_never_returns_a_stale_value():
    V, F, pr = _corner_cut()
    reg = _Regulariser(pr, pr.joints, 1.0)
    J0, J1 = pr.joints.copy(), pr.joints + 0.1
    g0 = reg._containment(J0)[0].copy()
    g1 = reg._containment(J1)[0].copy()
    assert not np.allclose(g0, g1)
    np.testing.assert_array_equal(reg._containment(J0)[0], g0)
    fresh = _Regulariser(pr, pr.joints, 1.0)
    np.testing.assert_array_equal(fresh._containment(J1)[0], g1)


def test_relocate_moves_an_inside_joint_whose_bones_jump_between_parts():
    # The chain A - M - B with A, B on one arm of the L and M inside the other: every joint is
    # inside, both bones cut the corner (the octopus: a radius-0 joint between two tentacles).
    from curveskel_addon.core.refine import relocate_joints

    V, F = bent_capsule()
    test = InsideTest(V, F)
    joints = np.array([[-4.0, 0.0, 0.0, 0.5], [0.0, 0.0, 3.0, 0.5], [-2.0, 0.0, 0.0, 0.5]])
    bones = np.array([[0, 1], [1, 2]])
    assert test(joints[:, :3]).all()
    before = outside_samples(joints, bones, test)[1].sum()
    moved, n = relocate_joints(joints, bones, test)
    assert before > 10 and n == 1
    assert outside_samples(moved, bones, test)[1].sum() == 0
    np.testing.assert_array_equal(moved[[0, 2]], joints[[0, 2]])
    np.testing.assert_allclose(moved[1, :3], [-3.0, 0.0, 0.0])   # the chord of its neighbours


def test_worst_fitting_bones_ranks_by_share_of_E():
    from curveskel_addon.core.energy import sigma_terms
    from curveskel_addon.core.refine import worst_fitting_bones

    V, F, pr = _straight_capsule_problem()
    pr.joints[2, 3] = 0.3                    # the upper bone's radius is wrong: it holds most of E
    e = sigma_terms(pr)[2]
    share = np.bincount(pr.bone, weights=pr.weights * e * e, minlength=2)
    assert share[1] > 10 * share[0]
    assert worst_fitting_bones(pr, 0.5).tolist() == [1]
    assert worst_fitting_bones(pr, 1.0).tolist() == [1, 0]
    assert worst_fitting_bones(pr, 1.0, exclude=[1]).tolist() == [0]
    assert worst_fitting_bones(pr, 0.0).tolist() == []


def test_split_on_the_bone_leaves_sigma_and_E_unchanged():
    from curveskel_addon.core.energy import energy

    V, F, pr = _corner_cut()
    sp = split_bones(pr, np.array([0]), np.array([0.3]), centroid=False)
    np.testing.assert_allclose(sp.joints[2], 0.3 * pr.joints[0] + 0.7 * pr.joints[1])
    np.testing.assert_allclose(_sigma(sp), _sigma(pr), atol=1e-12)
    assert energy(sp) == pytest.approx(energy(pr), rel=1e-12)
    moved = split_bones(pr, np.array([0]), np.array([0.3]))          # at the cross-section
    assert energy(moved) != pytest.approx(energy(pr), rel=1e-6)


def test_inside_test_builds_a_third_direction_only_where_two_disagree():
    V, F = torus()
    rng = np.random.default_rng(3)
    P = rng.uniform(-4.2, 4.2, size=(2000, 3)) * [1, 1, 0.35]
    lazy = InsideTest(V, F)
    got = lazy(P)
    full = InsideTest(V, F)
    votes = sum(g.parity(P) for g in full.grids)             # every direction, all points
    np.testing.assert_array_equal(got, votes >= 2)
    p0, p1 = full.grids[0].parity(P), full.grids[1].parity(P)
    assert (lazy._grids[2] is None) == bool(np.all(p0 == p1))
    cell = full.grids[0].cell
    assert cell[0] == pytest.approx(cell[1], rel=0.05)          # square cells
