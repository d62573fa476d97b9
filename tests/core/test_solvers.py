"""The paper's solver (eqs. 28-31), Levenberg-Marquardt, and re-fitting of the mapping sigma.

Test problems are built directly (no Reeb graph): points on a capsule of radius 1 along z (a
cylinder with hemispherical caps) and a chain of joints along z whose positions and radii are
perturbed. ``t`` comes from the *unperturbed* chain (cap points map to the end joints), so the
exact optimum is the unperturbed chain with r = 1 (E = 0 without noise).

Without the caps the problem is degenerate: shifting every joint by delta along the axis and
setting every radius to sqrt(1 + delta^2) keeps E unchanged for a fixed mapping, so the radius
would not be determined.
"""

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.optimize import least_squares, minimize_scalar

from curveskel_addon.core.energy import energy, residuals
from curveskel_addon.core.errors import CurveSkelError
from curveskel_addon.core.problem import FitProblem
from curveskel_addon.core.refit import bone_neighbours, project_on_bones, refit_mapping
from curveskel_addon.core.solvers import solve, solve_steps


def cylinder_problem(n=3000, n_joints=7, length=6.0, noise=0.0, perturb=0.15, seed=0,
                     weighted=False, caps=True):
    rng = np.random.default_rng(seed)
    n_cap = n // 8 if caps else 0                       # per cap
    n_side = n - 2 * n_cap
    th = rng.uniform(0, 2 * np.pi, n_side)
    z = rng.uniform(0, length, n_side)
    side = np.c_[np.cos(th), np.sin(th), z]
    u = rng.standard_normal((2 * n_cap, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    u[:n_cap, 2] = -np.abs(u[:n_cap, 2])                # bottom cap around joint 0
    u[n_cap:, 2] = np.abs(u[n_cap:, 2])                 # top cap around the last joint
    caps_P = u + np.c_[np.zeros((2 * n_cap, 2)), np.r_[np.zeros(n_cap), np.full(n_cap, length)]]
    P = np.r_[side, caps_P]
    r = 1.0 + noise * rng.standard_normal(n)
    centre = np.c_[np.zeros((n, 2)), np.clip(P[:, 2], 0, length)]
    P = centre + (P - centre) * r[:, None]
    zj = np.linspace(0, length, n_joints)
    true = np.c_[np.zeros((n_joints, 2)), zj, np.ones(n_joints)]
    bones = np.c_[np.arange(1, n_joints), np.arange(n_joints - 1)]      # t = 1 at the upper joint
    bone = np.clip(np.searchsorted(zj, np.clip(P[:, 2], 0, length)) - 1, 0, n_joints - 2)
    t, _ = project_on_bones(P, true, bones, bone)       # caps: t = 0 / 1 at the end joints
    joints = true.copy()
    joints[:, :3] += perturb * rng.standard_normal((n_joints, 3))
    joints[:, 3] *= 1 + perturb * rng.standard_normal(n_joints)
    w = rng.uniform(0.5, 1.5, n) if weighted else np.ones(n)
    return FitProblem(P, w, joints, bones, bone, t), true


def least_squares_reference(pr):
    """Tight scipy reference: trf, x_scale='jac', tolerances 1e-12, sparse Jacobian."""
    n, J = len(pr.points), len(pr.joints)
    ij = pr.bones[pr.bone]
    cols = np.c_[4 * ij[:, :1] + np.arange(4), 4 * ij[:, 1:] + np.arange(4)]
    rows = np.repeat(np.arange(n), 8)
    sw, t = np.sqrt(pr.weights), pr.t

    def view(x):
        return FitProblem(pr.points, pr.weights, x.reshape(J, 4), pr.bones, pr.bone, pr.t)

    def fun(x):
        return sw * residuals(view(x))

    def jac(x):
        Jx = x.reshape(J, 4)
        s = t[:, None] * Jx[ij[:, 0]] + (1 - t[:, None]) * Jx[ij[:, 1]]
        G = np.c_[pr.points - s[:, :3], s[:, 3]] * (-2 * sw)[:, None]
        vals = np.c_[t[:, None] * G, (1 - t[:, None]) * G]
        return sp.csr_matrix((vals.ravel(), (rows, cols.ravel())), shape=(n, 4 * J))

    res = least_squares(fun, pr.joints.ravel(), jac=jac, method="trf", x_scale="jac",
                        ftol=1e-12, xtol=1e-12, gtol=1e-12,
                        jac_sparsity=sp.csr_matrix((np.ones(8 * n), (rows, cols.ravel())),
                                                   shape=(n, 4 * J)))
    return 2 * res.cost, res.x.reshape(J, 4)


def snapshot(pr):
    return [np.array(x, copy=True) for x in (pr.points, pr.weights, pr.joints, pr.bones, pr.bone, pr.t)]


def assert_unchanged(pr, snap):
    for a, b in zip(snap, (pr.points, pr.weights, pr.joints, pr.bones, pr.bone, pr.t)):
        np.testing.assert_array_equal(a, b)


# -- common contract ----------------------------------------------------------------------------

@pytest.mark.parametrize("solver", ["paper", "lm"])
@pytest.mark.parametrize("refit", [False, True])
def test_contract_first_last_monotone_untouched(solver, refit):
    pr, _ = cylinder_problem(noise=0.02, seed=1)
    snap = snapshot(pr)
    states = list(solve_steps(pr, solver=solver, max_iterations=200, refit_mapping=refit))
    s0 = states[0]
    assert s0.iteration == 0 and not s0.done
    assert s0.energy == pytest.approx(energy(pr), rel=1e-12)
    np.testing.assert_array_equal(s0.joints, pr.joints)
    assert [s.iteration for s in states] == list(range(len(states)))
    assert states[-1].done and not any(s.done for s in states[:-1])
    E = np.array([s.energy for s in states])
    assert np.all(np.diff(E) <= 0)
    assert E[-1] < 0.05 * E[0]
    for s in states:
        assert np.all(s.joints[:, 3] >= 0)
        # the reported energy is the energy of the reported state
        st = FitProblem(pr.points, pr.weights, s.joints, pr.bones, s.bone, s.t)
        assert s.energy == pytest.approx(energy(st), rel=1e-9)
    assert_unchanged(pr, snap)


@pytest.mark.parametrize("solver", ["paper", "lm"])
def test_zero_iterations_and_zero_energy(solver):
    pr, true = cylinder_problem(n=200)
    states = list(solve_steps(pr, solver=solver, max_iterations=0))
    assert len(states) == 1 and states[0].done and states[0].iteration == 0
    # E0 == 0 exactly (points at distance 1 from joints of radius 1, t = 0): nothing to do.
    joints = np.c_[np.zeros((3, 2)), [0.0, 1.0, 2.0], np.ones(3)]
    P = np.array([[1.0, 0, 0], [0, -1.0, 0], [-1.0, 0, 1], [0, 1.0, 1]])
    exact = FitProblem(P, np.ones(4), joints, np.array([[1, 0], [2, 1]]), np.array([0, 0, 1, 1]),
                       np.zeros(4))
    states = list(solve_steps(exact, solver=solver))
    assert len(states) == 1 and states[0].done and states[0].energy == 0.0


@pytest.mark.parametrize("solver", ["paper", "lm"])
def test_max_iterations_is_respected(solver):
    pr, _ = cylinder_problem(noise=0.02, seed=2)
    states = list(solve_steps(pr, solver=solver, max_iterations=2, tolerance=1e-12))
    assert [s.iteration for s in states] == [0, 1, 2] and states[-1].done


def test_unknown_solver():
    pr, _ = cylinder_problem(n=50)
    with pytest.raises(CurveSkelError):
        solve_steps(pr, solver="newton")


# -- the paper's solver -------------------------------------------------------------------------

def test_paper_one_iteration_by_hand():
    # Tiny problem; gradient written out per vertex and lambda by a scalar minimiser of E itself.
    P = np.array([[1.2, 0.1, 0.2], [-0.9, 0.3, 0.7], [0.2, -1.1, 0.5], [0.5, 0.5, 0.9]])
    joints = np.array([[0.1, 0.0, 0.0, 0.8], [0.0, 0.1, 1.0, 1.1]])
    bones = np.array([[1, 0]])
    t = np.array([0.2, 0.6, 0.5, 0.9])
    pr = FitProblem(P, np.ones(4), joints, bones, np.zeros(4, int), t)
    g = np.zeros((2, 4))
    for v in range(4):
        x = t[v] * joints[1] + (1 - t[v]) * joints[0]       # t = 1 at joint 1 = bones[0, 0]
        d = P[v] - x[:3]
        e = d @ d - x[3] ** 2
        dv = -4 * e * np.r_[d, x[3]]
        g[1] += t[v] * dv
        g[0] += (1 - t[v]) * dv
    f = lambda lam: energy(pr, joints - lam * g)
    lam = minimize_scalar(f, bracket=(0, 1e-3), tol=1e-12).x
    expected = joints - lam * g
    assert np.all(expected[:, 3] > 0)          # no flip in this example
    states = list(solve_steps(pr, solver="paper", max_iterations=1))
    np.testing.assert_allclose(states[1].joints, expected, rtol=1e-6, atol=1e-9)
    assert states[1].energy == pytest.approx(f(lam), rel=1e-9)


@pytest.mark.parametrize("tolerance", [1e-2, 1e-3])
def test_paper_stops_by_eq30(tolerance):
    pr, _ = cylinder_problem(noise=0.05, seed=3)
    states = list(solve_steps(pr, solver="paper", tolerance=tolerance, max_iterations=10_000))
    E = np.array([s.energy for s in states])
    drops = -np.diff(E)
    eps = tolerance * E[0]                                      # eq. 31
    assert drops[-1] < eps                                      # eq. 30 stopped it
    assert np.all(drops[:-1] >= eps)                            # and not earlier
    assert len(states) - 1 < 10_000


@pytest.mark.parametrize("solver", ["paper", "lm"])
def test_negative_radii_are_handled(solver):
    # Points on the axis: the best radius is 0 and exact line searches overshoot below it.
    rng = np.random.default_rng(4)
    n = 400
    z = rng.uniform(0, 2, n)
    P = np.c_[0.01 * rng.standard_normal((n, 2)), z]
    joints = np.array([[0.05, 0, 0, 0.3], [0, 0.05, 2, 0.05]])
    t, _ = project_on_bones(P, joints, np.array([[1, 0]]), np.zeros(n, int))
    pr = FitProblem(P, np.ones(n), joints, np.array([[1, 0]]), np.zeros(n, int), t)
    stats = {}
    states = list(solve_steps(pr, solver=solver, max_iterations=300, tolerance=1e-9, stats=stats))
    if solver == "paper":
        assert stats["flips"] + stats["restricted"] > 0
    E = [s.energy for s in states]
    assert E[-1] < 1e-3 * E[0]
    assert np.all(np.diff(E) <= 0)
    assert all(np.all(s.joints[:, 3] >= 0) for s in states)


# -- Levenberg-Marquardt -------------------------------------------------------------------------

@pytest.mark.parametrize("solver", ["paper", "lm"])
def test_unused_joint_and_empty_bone(solver):
    # A joint no bone uses and a bone no vertex maps to: both must stay put, nothing breaks.
    pr, _ = cylinder_problem(n=2000, noise=0.02, seed=11)
    J = len(pr.joints)
    joints = np.vstack([pr.joints, [[5, 5, 5, 1], [6, 6, 6, 1]]])
    bones = np.vstack([pr.bones, [[J, J + 1]]])                    # bone J -> J+1, no vertices
    joints = np.vstack([joints, [[9, 9, 9, 2]]])                   # joint J+2, no bone
    big = FitProblem(pr.points, pr.weights, joints, bones, pr.bone, pr.t)
    last = solve(big, solver=solver, refit_mapping=True)
    np.testing.assert_array_equal(last.joints[J:], joints[J:])
    assert last.energy < 0.1 * energy(big)


@pytest.mark.parametrize("seed,noise,weighted", [(0, 0.01, False), (5, 0.03, True), (3, 0.02, False)])
def test_lm_matches_least_squares(seed, noise, weighted):
    pr, true = cylinder_problem(n=4000, n_joints=8, noise=noise, seed=seed, weighted=weighted)
    E_ref, x_ref = least_squares_reference(pr)
    states = list(solve_steps(pr, solver="lm"))
    assert np.all(np.diff([s.energy for s in states]) <= 0)
    last = states[-1]
    assert last.energy <= 1.01 * E_ref                          # issue 5 target: within 1%
    assert last.energy <= 1.001 * E_ref                         # what we actually get
    assert last.energy >= 0.999 * E_ref                         # the reference is an optimum
    assert len(states) - 1 <= 30
    assert np.mean(last.joints[:, 3]) == pytest.approx(1.0, abs=0.02)


def test_lm_recovers_cylinder_radius():
    # Radius and axis are well determined; the joints' positions *along* the axis are not (for a
    # straight tube, E barely changes when an interior joint slides along it), so only r and x, y
    # are checked.
    pr, true = cylinder_problem(n=4000, n_joints=8, noise=0.01, seed=0)
    last = solve(pr, solver="lm")
    np.testing.assert_allclose(last.joints[:, 3], 1.0, atol=0.01)      # cylinder radius, 1%
    np.testing.assert_allclose(last.joints[:, :2], 0.0, atol=0.02)     # on the axis
    np.testing.assert_allclose(last.joints[[0, -1], 2], [0.0, 6.0], atol=0.01)   # caps pin the ends


def test_lm_much_better_than_paper_stop():
    pr, _ = cylinder_problem(n=3000, noise=0.02, seed=6)
    E_lm = solve(pr, solver="lm").energy
    E_paper = solve(pr, solver="paper").energy
    assert E_lm < E_paper


def test_lm_exact_data_reaches_zero():
    pr, true = cylinder_problem(n=2000, seed=7, perturb=0.1)
    last = solve(pr, solver="lm", tolerance=1e-8, max_iterations=200)
    assert last.energy < 1e-12 * energy(pr)
    np.testing.assert_allclose(last.joints[:, [0, 1, 3]], true[:, [0, 1, 3]], atol=1e-6)
    # Along the axis E grows only like the 4th power of a joint's shift: a looser match.
    np.testing.assert_allclose(last.joints[:, 2], true[:, 2], atol=1e-3)


# -- re-fitting sigma ----------------------------------------------------------------------------

def scrambled(seed=8, fraction=0.3):
    pr, true = cylinder_problem(n=3000, n_joints=7, seed=seed, noise=0.01)
    pr = FitProblem(pr.points, pr.weights, true.copy(), pr.bones, pr.bone, pr.t)
    rng = np.random.default_rng(seed)
    bad = rng.random(len(pr.bone)) < fraction
    shift = rng.choice([-1, 1], size=len(pr.bone))
    bone = pr.bone.copy()
    bone[bad] = np.clip(bone[bad] + shift[bad], 0, len(pr.bones) - 1)
    t = pr.t.copy()
    t[bad] = rng.random(np.count_nonzero(bad))
    return FitProblem(pr.points, pr.weights, pr.joints, pr.bones, bone, t), pr


def test_refit_lowers_energy_of_scrambled_mapping():
    bad, good = scrambled()
    E_bad = energy(bad)
    bone, t, e, changed = refit_mapping(bad)
    E_new = float(np.dot(bad.weights, e * e))
    refit = FitProblem(bad.points, bad.weights, bad.joints, bad.bones, bone, t)
    assert E_new == pytest.approx(energy(refit), rel=1e-12)
    assert E_new < 0.05 * E_bad
    assert changed > 0
    # Points sent to a neighbouring bone come back to the true one (up to ties at the joints).
    agree = np.mean((bone == good.bone) | (np.abs(t - np.round(t)) < 1e-9))
    assert agree > 0.99


def test_refit_never_raises_any_vertex_term():
    bad, _ = scrambled(seed=9, fraction=0.5)
    e_old = residuals(bad)
    _, _, e_new, _ = refit_mapping(bad)
    assert np.all(np.abs(e_new) <= np.abs(e_old))


def test_refit_candidates_are_neighbour_bones_only():
    table, count = bone_neighbours(np.array([[0, 1], [1, 2], [2, 3], [1, 4]]))
    assert count.tolist() == [3, 4, 2, 3]
    assert set(table[1].tolist()) == {0, 1, 2, 3} and table[1, 0] == 1
    assert set(table[2].tolist()) == {1, 2} and table[2, 0] == 2
    # A point next to bone 2 but mapped to bone 0 cannot jump to bone 2 in one re-fit.
    J = np.array([[0, 0, 0, 1.0], [0, 0, 1, 1.0], [0, 0, 2, 1.0], [0, 0, 3, 1.0], [1, 0, 1, 1.0]])
    pr = FitProblem(np.array([[1.0, 0, 2.5]]), np.ones(1), J,
                    np.array([[0, 1], [1, 2], [2, 3], [1, 4]]), np.array([0]), np.array([0.0]))
    bone, _, _, _ = refit_mapping(pr)
    assert bone[0] in (0, 1, 3)


@pytest.mark.parametrize("solver", ["paper", "lm"])
def test_solvers_with_refit_beat_fixed_mapping(solver):
    bad, _ = scrambled(seed=10)
    moved = FitProblem(bad.points, bad.weights, bad.joints + [0.05, -0.05, 0.1, 0.1], bad.bones,
                       bad.bone, bad.t)
    fixed = solve(moved, solver=solver, max_iterations=300)
    refit = solve(moved, solver=solver, max_iterations=300, refit_mapping=True)
    assert refit.energy < 0.1 * fixed.energy
    assert np.any(refit.bone != moved.bone)


def test_lm_steps_turn_with_the_problem():
    """Rotating the points and joints rotates every LM iterate: the damping is the same in any
    orientation of the axes. Marquardt's diag(J^T J) of a joint's position block is not (it
    changes with the axes), and damping by it made a rotated 3holes take another first step
    (the skeleton 1.6e-3 D apart); each joint's position entries now share their mean."""
    from scipy.spatial.transform import Rotation
    pr, _ = cylinder_problem(n=1500, perturb=0.3, seed=3)
    R = Rotation.from_rotvec([0.7, -1.1, 0.4]).as_matrix()
    turned = FitProblem(pr.points @ R.T, pr.weights, np.c_[pr.joints[:, :3] @ R.T, pr.joints[:, 3]],
                        pr.bones, pr.bone, pr.t)
    a = [s.joints.copy() for s in solve_steps(pr, solver="lm", max_iterations=6, tolerance=1e-9)]
    b = [s.joints.copy() for s in solve_steps(turned, solver="lm", max_iterations=6, tolerance=1e-9)]
    assert len(a) == len(b) == 7
    for x, y in zip(a, b):
        assert np.abs(x[:, :3] - y[:, :3] @ R).max() < 1e-9
        assert np.abs(x[:, 3] - y[:, 3]).max() < 1e-9
