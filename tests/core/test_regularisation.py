"""Opt-in regularisation of the LM solver: containment (joints stay inside) and smoothness."""

from __future__ import annotations

import numpy as np

from curveskel_addon.core.problem import FitProblem
from curveskel_addon.core.solvers.lm import lm_steps
from tests.meshes import capsule


def _box(half=(2.0, 0.5, 0.5), n=16):
    """Closed, outward-oriented box mesh centred at the origin, each face an n x n grid."""
    h = np.asarray(half, float)
    V, F, o = [], [], 0
    g = np.linspace(-1.0, 1.0, n + 1)
    i = np.arange(n)[:, None] * (n + 1) + np.arange(n)[None, :]
    for ax in range(3):
        u, v = [k for k in range(3) if k != ax]
        for sgn in (1.0, -1.0):
            P = np.zeros((n + 1, n + 1, 3))
            P[..., ax] = sgn * h[ax]
            P[..., u] = g[:, None] * h[u]
            P[..., v] = g[None, :] * h[v]
            V.append(P.reshape(-1, 3))
            a, b, c, d = i, i + n + 1, i + n + 2, i + 1
            F.append(o + np.concatenate([np.stack([a, b, c], -1).reshape(-1, 3),
                                         np.stack([a, c, d], -1).reshape(-1, 3)]))
            o += (n + 1) ** 2
    V, inv = np.unique(np.round(np.concatenate(V), 9), axis=0, return_inverse=True)
    F = inv.ravel()[np.concatenate(F)]
    nrm = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    flip = np.einsum("ij,ij->i", nrm, V[F].mean(axis=1)) < 0      # convex: outward = away from 0
    F[flip] = F[flip][:, ::-1]
    return V, F


def _solve(pr, **kw):
    states = list(lm_steps(pr, max_iterations=100, **kw))
    return states


def _runaway_problem(containment):
    """A joint fitted only to a small flat patch of a box's face: a sphere through a plane
    patch fits better the bigger it is, so without containment the joint leaves the box."""
    V, F = _box()
    patch = (np.abs(V[:, 1] - 0.5) < 1e-9) & (np.abs(V[:, 0]) <= 0.5) & (np.abs(V[:, 2]) <= 0.3)
    P = V[patch]
    joints = np.array([[0.0, 0.2, 0.0, 0.3], [1.0, 0.0, 0.0, 0.3]])
    pr = FitProblem(P, np.ones(len(P)), joints, np.array([[0, 1]]), np.zeros(len(P), int),
                    np.ones(len(P)))
    pr.meta["regularisation"] = {"containment": containment, "smoothness": 0.0, "surface": (V, F)}
    return pr


def test_containment_keeps_a_runaway_joint_inside():
    free = _solve(_runaway_problem(0.0))[-1].joints[0]
    # ran away far outside the box (|y| <= 0.5): E keeps falling towards a plane's limit, and
    # the solver stops where a step gains less than its tolerance (y 5.7, r 5.2)
    assert free[1] > 5.0 and free[3] > 5.0
    for c, r_max in ((1.0, 0.7), (10.0, 0.6)):
        states = _solve(_runaway_problem(c))
        x = states[-1].joints[0]
        assert np.all(np.abs(x[:3]) <= [2.0, 0.5, 0.5])   # centre inside the box
        assert abs(x[1]) < 0.1                              # pulled to the middle of the slab
        assert 0.3 < x[3] < r_max                          # ball about as wide as the slab (0.5)
        assert states[-1].done


def test_zero_weights_change_nothing():
    pr = _runaway_problem(0.0)
    a = _solve(pr)
    pr.meta = {}
    b = _solve(pr)
    assert len(a) == len(b)
    np.testing.assert_array_equal(a[-1].joints, b[-1].joints)


def _zigzag_problem(smoothness):
    """A straight tube, a chain whose inner joints zig-zag; the vertices map only to the two
    end bones, so the data term does not see the inner joints."""
    V, F = capsule(radius=1.0, length=6.0)         # axis z, body z in [0, 6]
    z = np.arange(7, dtype=float)
    joints = np.zeros((7, 4))
    joints[:, 2] = z
    joints[:, 0] = [0.0, 0.3, -0.3, 0.3, -0.3, 0.3, 0.0]
    joints[:, 3] = 1.0
    bones = np.array([[i, i + 1] for i in range(6)])
    keep = (V[:, 2] < 1.0) | (V[:, 2] > 5.0)
    P = V[keep]
    bone = np.where(P[:, 2] < 1.0, 0, 5)
    t = np.where(bone == 0, 1.0 - np.clip(P[:, 2], 0, 1), 1.0 - np.clip(P[:, 2] - 5.0, 0, 1))
    pr = FitProblem(P, np.ones(len(P)), joints, bones, bone, t)
    pr.meta["regularisation"] = {"containment": 0.0, "smoothness": smoothness, "surface": (V, F)}
    return pr


def _zigzag(joints):
    x = joints[:, :3]
    return float(np.abs(x[1:-1] - 0.5 * (x[:-2] + x[2:])).max())


def test_smoothness_straightens_a_zigzag_chain():
    start = _zigzag(_zigzag_problem(0.0).joints)
    assert np.isclose(start, 0.6)
    free = _zigzag(_solve(_zigzag_problem(0.0))[-1].joints)
    smooth = _zigzag(_solve(_zigzag_problem(0.1))[-1].joints)
    assert free > 0.25                 # unobserved inner joints keep their zig-zag
    assert smooth < 0.05 * start


def test_regularised_objective_never_increases():
    from curveskel_addon.core.solvers.lm import _Regulariser
    pr = _runaway_problem(1.0)
    states = _solve(pr)
    reg = _Regulariser(pr, pr.joints, states[0].energy)
    total = [s.energy + reg.value(s.joints) for s in states]
    assert np.all(np.diff(total) <= 1e-12 * total[0])


def _ellipsoid_points(n=2000, axes=(1.0, 0.7, 0.5)):
    """Fibonacci points on an ellipsoid and their unit outward normals (on a sphere every point
    at the same distance from x has the same plane distance, which would hide a jump)."""
    i = np.arange(n) + 0.5
    z = 1.0 - 2.0 * i / n
    phi = np.pi * (1.0 + 5 ** 0.5) * i
    r = np.sqrt(1.0 - z * z)
    a = np.asarray(axes)
    P = np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1) * a
    N = P / a ** 2
    return P, N / np.linalg.norm(N, axis=1, keepdims=True)


def test_blended_signed_distance_is_continuous_and_its_gradient_matches():
    # The blend of the K nearest planes must not jump where the K-th and (K+1)-th neighbours
    # swap (a tie under rounding: a rotated mesh gave another fit, issue 12): along a fine path
    # d changes by at most a few times the step; its gradient matches finite differences.
    from scipy.spatial import cKDTree

    from curveskel_addon.core.solvers.lm import blended_signed_distance

    P, N = _ellipsoid_points()
    tree = cKDTree(P)
    h2 = float(np.median(tree.query(P, k=2)[0][:, 1])) ** 2
    t = np.linspace(0.0, 1.0, 20001)[:, None]
    x = np.array([0.0, 0.0, 0.2]) + t * np.array([0.3, 0.2, 0.05])
    d, g = blended_signed_distance(x, P, N, tree, 8, h2)
    step = float(np.linalg.norm(x[1] - x[0]))
    assert np.max(np.abs(np.diff(d))) / step < 5.0
    assert np.all(d > 0) and np.all(d < 0.5)                 # inside, less than the half-axis
    # the gradient (exact for the distance weights) against central differences
    x0 = np.array([[0.1, 0.05, 0.22], [0.2, -0.1, 0.1]])
    eps = 1e-6
    for k in range(3):
        e = np.zeros(3)
        e[k] = eps
        fd = (blended_signed_distance(x0 + e, P, N, tree, 8, h2)[0]
              - blended_signed_distance(x0 - e, P, N, tree, 8, h2)[0]) / (2 * eps)
        np.testing.assert_allclose(blended_signed_distance(x0, P, N, tree, 8, h2)[1][:, k], fd,
                                   atol=0.05)
