"""The paper's solver (eqs. 28-31, :mod:`curveskel_addon.core.objective.paper`) and the
minimisation of J (:mod:`curveskel_addon.core.objective.minimise`).

The paper's solver's problems are built directly (no Reeb graph): points on a capsule of
radius 1 along z (a cylinder with hemispherical caps) and a chain of joints along z whose
positions and radii are perturbed. ``t`` comes from the *unperturbed* chain (cap points map to
the end joints), so the exact optimum is the unperturbed chain with r = 1 (E = 0 without noise).

Without the caps the problem is degenerate: shifting every joint by delta along the axis and
setting every radius to sqrt(1 + delta^2) keeps E unchanged for a fixed mapping, so the radius
would not be determined.

J's minimisation runs on a real objective (a capsule's surface samples, J's default weights):
it never raises J, it finds the capsule's axis and radius from a perturbed chain, and its steps
turn with the mesh.
"""

import numpy as np
import pytest
from scipy.optimize import minimize_scalar
from scipy.spatial.transform import Rotation

from curveskel_addon.core.config import CONFIG
from curveskel_addon.core.geometry.samples import face_samples
from curveskel_addon.core.graph import SkeletonGraph
from curveskel_addon.core.mesh import Mesh
from curveskel_addon.core.objective.energy import energy
from curveskel_addon.core.objective.minimise import minimise
from curveskel_addon.core.objective.objective import Objective
from curveskel_addon.core.objective.paper import paper_steps, radius_interval
from curveskel_addon.core.objective.problem import FitProblem
from meshes import capsule


def project_on_bones(P, joints, bones, bone):
    """t of each point's closest point on its own bone (t = 1 at joint bones[b, 0])."""
    xi, xj = joints[bones[bone, 0], :3], joints[bones[bone, 1], :3]
    d = xi - xj
    return np.clip(np.einsum("ij,ij->i", P - xj, d) / np.maximum(np.einsum("ij,ij->i", d, d), 1e-300),
                   0.0, 1.0)


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
    t = project_on_bones(P, true, bones, bone)          # caps: t = 0 / 1 at the end joints
    joints = true.copy()
    joints[:, :3] += perturb * rng.standard_normal((n_joints, 3))
    joints[:, 3] *= 1 + perturb * rng.standard_normal(n_joints)
    w = rng.uniform(0.5, 1.5, n) if weighted else np.ones(n)
    return FitProblem(P, w, joints, bones, bone, t), true


def solve_steps(pr, max_iterations=1000, tolerance=1e-3, stats=None):
    return list(paper_steps(pr, max_iterations=max_iterations, tolerance=tolerance, stats=stats))


def snapshot(pr):
    return [np.array(x, copy=True) for x in (pr.points, pr.weights, pr.joints, pr.bones, pr.bone, pr.t)]


def assert_unchanged(pr, snap):
    for a, b in zip(snap, (pr.points, pr.weights, pr.joints, pr.bones, pr.bone, pr.t)):
        np.testing.assert_array_equal(a, b)


# -- the paper's solver: its contract -------------------------------------------------------------

def test_contract_first_last_monotone_untouched():
    pr, _ = cylinder_problem(noise=0.02, seed=1)
    snap = snapshot(pr)
    states = solve_steps(pr, max_iterations=200)
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


def test_zero_iterations_and_zero_energy():
    pr, true = cylinder_problem(n=200)
    states = solve_steps(pr, max_iterations=0)
    assert len(states) == 1 and states[0].done and states[0].iteration == 0
    # E0 == 0 exactly (points at distance 1 from joints of radius 1, t = 0): nothing to do.
    joints = np.c_[np.zeros((3, 2)), [0.0, 1.0, 2.0], np.ones(3)]
    P = np.array([[1.0, 0, 0], [0, -1.0, 0], [-1.0, 0, 1], [0, 1.0, 1]])
    exact = FitProblem(P, np.ones(4), joints, np.array([[1, 0], [2, 1]]), np.array([0, 0, 1, 1]),
                       np.zeros(4))
    states = solve_steps(exact)
    assert len(states) == 1 and states[0].done and states[0].energy == 0.0


def test_max_iterations_is_respected():
    pr, _ = cylinder_problem(noise=0.02, seed=2)
    states = solve_steps(pr, max_iterations=2, tolerance=1e-12)
    assert [s.iteration for s in states] == [0, 1, 2] and states[-1].done


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
    f = lambda lam: energy(pr, joints - lam * g)  # noqa: E731
    lam = minimize_scalar(f, bracket=(0, 1e-3), tol=1e-12).x
    expected = joints - lam * g
    assert np.all(expected[:, 3] > 0)          # no flip in this example
    states = solve_steps(pr, max_iterations=1)
    np.testing.assert_allclose(states[1].joints, expected, rtol=1e-6, atol=1e-9)
    assert states[1].energy == pytest.approx(f(lam), rel=1e-9)


@pytest.mark.parametrize("tolerance", [1e-2, 1e-3])
def test_paper_stops_by_eq30(tolerance):
    pr, _ = cylinder_problem(noise=0.05, seed=3)
    states = solve_steps(pr, tolerance=tolerance, max_iterations=10_000)
    E = np.array([s.energy for s in states])
    drops = -np.diff(E)
    eps = tolerance * E[0]                                      # eq. 31
    assert drops[-1] < eps                                      # eq. 30 stopped it
    assert np.all(drops[:-1] >= eps)                            # and not earlier
    assert len(states) - 1 < 10_000


def test_negative_radii_are_handled():
    # Points on the axis: the best radius is 0 and exact line searches overshoot below it.
    rng = np.random.default_rng(4)
    n = 400
    z = rng.uniform(0, 2, n)
    P = np.c_[0.01 * rng.standard_normal((n, 2)), z]
    joints = np.array([[0.05, 0, 0, 0.3], [0, 0.05, 2, 0.05]])
    t = project_on_bones(P, joints, np.array([[1, 0]]), np.zeros(n, int))
    pr = FitProblem(P, np.ones(n), joints, np.array([[1, 0]]), np.zeros(n, int), t)
    stats = {}
    states = solve_steps(pr, max_iterations=300, tolerance=1e-9, stats=stats)
    assert stats["flips"] + stats["restricted"] > 0
    E = [s.energy for s in states]
    assert E[-1] < 1e-3 * E[0]
    assert np.all(np.diff(E) <= 0)
    assert all(np.all(s.joints[:, 3] >= 0) for s in states)


def test_radius_interval_keeps_every_radius_non_negative():
    lo, hi = radius_interval(np.array([1.0, 2.0]), np.array([2.0, -1.0]))
    assert (lo, hi) == (-2.0, 0.5)
    r = np.array([0.3, 1.0, 0.0, 2.0])
    g = np.array([1.0, -0.5, 0.0, 4.0])
    lo, hi = radius_interval(r, g)
    assert lo <= 0 <= hi
    for lam in (lo, hi, 0.5 * (lo + hi)):
        assert np.all(r - lam * g >= -1e-15)
    assert np.any(np.isclose(r - hi * g, 0)) and np.any(np.isclose(r - lo * g, 0))


def test_unused_joint_and_empty_bone():
    # A joint no bone uses and a bone no vertex maps to: both must stay put, nothing breaks.
    pr, _ = cylinder_problem(n=2000, noise=0.02, seed=11)
    J = len(pr.joints)
    joints = np.vstack([pr.joints, [[5, 5, 5, 1], [6, 6, 6, 1]]])
    bones = np.vstack([pr.bones, [[J, J + 1]]])                    # bone J -> J+1, no vertices
    joints = np.vstack([joints, [[9, 9, 9, 2]]])                   # joint J+2, no bone
    big = FitProblem(pr.points, pr.weights, joints, bones, pr.bone, pr.t)
    last = solve_steps(big)[-1]
    np.testing.assert_array_equal(last.joints[J:], joints[J:])
    assert last.energy < 0.1 * energy(big)


def test_paper_solver_reaches_the_exact_optimum_of_exact_data():
    """Points exactly on the capsule, the mapping of the true chain: gradient descent with the
    exact line search drives E towards 0 and the joints towards the true chain."""
    pr, true = cylinder_problem(n=2000, seed=7, perturb=0.1)
    last = solve_steps(pr, max_iterations=3000, tolerance=1e-9)[-1]
    assert last.energy < 1e-4 * energy(pr)
    np.testing.assert_allclose(last.joints[:, [0, 1, 3]], true[:, [0, 1, 3]], atol=0.02)


# -- J's minimisation ---------------------------------------------------------------------------------

def _capsule_objective(V, F):
    """J on a capsule mesh: its surface samples, each sample's thickness the capsule's radius."""
    mesh = Mesh(V, F)
    s = face_samples(mesh.V, mesh.F, 0.25)
    return Objective(mesh, s, CONFIG.weights, np.ones(len(s.points)))


def _perturbed_chain(seed=0, n=6, length=6.0, perturb=0.15):
    rng = np.random.default_rng(seed)
    z = np.linspace(0.0, length, n)
    joints = np.c_[np.zeros((n, 2)), z, np.ones(n)]
    joints[:, :2] += perturb * rng.standard_normal((n, 2))
    joints[:, 3] *= 1 + perturb * rng.standard_normal(n)
    bones = np.c_[np.arange(n - 1), np.arange(1, n)]
    # every sample region maps to every bone; thickness per bone: the radius
    pairs = np.c_[np.zeros(n - 1, np.int64), np.arange(n - 1)]
    return SkeletonGraph(joints, bones, pairs, np.ones(n - 1))


@pytest.fixture(scope="module")
def capsule_objective():
    return _capsule_objective(*capsule(radius=1.0, length=6.0, n_around=24, n_body=24))


def test_minimise_lowers_j_and_finds_the_capsules_axis_and_radius(capsule_objective):
    obj = capsule_objective
    g0 = _perturbed_chain()
    ev0 = obj.evaluate(g0)
    g, ev, it = minimise(obj, g0, max_iterations=100, tolerance=1e-9)
    assert ev.value < ev0.value and it >= 1
    assert ev.value == pytest.approx(obj.evaluate(g).value, rel=1e-12)     # J of the result
    X = np.asarray(g.joints)
    inner = (X[:, 2] > 0.5) & (X[:, 2] < 5.5)
    assert inner.sum() >= 2
    # on the axis and the capsule's radius, away from the caps (a tip's radius and position
    # trade against each other along the axis)
    assert np.hypot(X[inner, 0], X[inner, 1]).max() < 0.05
    np.testing.assert_allclose(X[inner, 3], 1.0, atol=0.05)


def test_minimise_never_raises_j_step_by_step(capsule_objective):
    obj = capsule_objective
    g = _perturbed_chain(seed=3, perturb=0.3)
    values = [obj.evaluate(g).value]
    for _ in range(8):
        g, ev, _ = minimise(obj, g, max_iterations=1, tolerance=0.0)
        values.append(ev.value)
    assert np.all(np.diff(values) <= 0)
    assert values[-1] < values[0]
    assert np.all(np.asarray(g.joints)[:, 3] >= 0)


def test_minimise_holds_fixed_joints(capsule_objective):
    obj = capsule_objective
    g0 = _perturbed_chain(seed=1)
    fixed = np.zeros(g0.n_joints, bool)
    fixed[[0, 2]] = True
    g, ev, _ = minimise(obj, g0, max_iterations=20, tolerance=1e-6, fixed=fixed)
    np.testing.assert_array_equal(np.asarray(g.joints)[fixed, :3], np.asarray(g0.joints)[fixed, :3])
    assert not np.array_equal(np.asarray(g.joints)[~fixed, :3], np.asarray(g0.joints)[~fixed, :3])
    assert ev.value < obj.evaluate(g0).value


def test_minimise_steps_turn_with_the_mesh():
    """Rotating the mesh and the chain rotates every iterate: J and its damping are the same in
    any orientation of the axes (Marquardt's diag(J^T J) of a joint's position block is not:
    damping by it made a rotated 3holes take another first step)."""
    V, F = capsule(radius=1.0, length=6.0, n_around=24, n_body=24)
    R = Rotation.from_rotvec([0.7, -1.1, 0.4]).as_matrix()
    a, b = _capsule_objective(V, F), _capsule_objective(V @ R.T, F)
    g = _perturbed_chain(seed=2, perturb=0.3)
    h = SkeletonGraph(np.c_[np.asarray(g.joints)[:, :3] @ R.T, np.asarray(g.joints)[:, 3]],
                      g.bones, g.pairs, g.thick)
    for _ in range(4):
        g, _, _ = minimise(a, g, max_iterations=1, tolerance=0.0)
        h, _, _ = minimise(b, h, max_iterations=1, tolerance=0.0)
        x, y = np.asarray(g.joints), np.asarray(h.joints)
        assert np.abs(x[:, :3] - y[:, :3] @ R).max() < 1e-8
        assert np.abs(x[:, 3] - y[:, 3]).max() < 1e-8
