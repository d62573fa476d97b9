"""E (eq. 20), its gradient and the line quartic against direct evaluation."""

import numpy as np
import pytest

from curveskel_addon.core.objective.energy import (bone_terms, energy, energy_and_gradient, line_quartic,
                                         residuals)
from curveskel_addon.core.objective.problem import FitProblem


def random_problem(seed, n=300, n_joints=7, weighted=True):
    """Random points around a random tree of joints, random mapping and weights."""
    rng = np.random.default_rng(seed)
    joints = np.c_[rng.normal(size=(n_joints, 3)), rng.uniform(0.3, 1.5, n_joints)]
    parent = [rng.integers(0, k) for k in range(1, n_joints)]
    bones = np.array([(k, p) for k, p in zip(range(1, n_joints), parent)])
    bone = rng.integers(0, len(bones), n)
    t = rng.uniform(0, 1, n)
    points = rng.normal(size=(n, 3)) * 1.5
    w = rng.uniform(0.2, 2.0, n) if weighted else np.ones(n)
    return FitProblem(points, w, joints, bones, bone, t)


def direct_energy(pr, joints):
    """Eq. 20 written out vertex by vertex (no vectorisation), with weights."""
    E = 0.0
    for v in range(len(pr.points)):
        i, j = pr.bones[pr.bone[v]]
        t = pr.t[v]
        sigma = t * joints[i, :3] + (1 - t) * joints[j, :3]
        rho = t * joints[i, 3] + (1 - t) * joints[j, 3]
        E += pr.weights[v] * (np.sum((pr.points[v] - sigma) ** 2) - rho ** 2) ** 2
    return E


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_energy_matches_vertex_by_vertex_sum(seed):
    pr = random_problem(seed)
    assert energy(pr) == pytest.approx(direct_energy(pr, pr.joints), rel=1e-12)
    e = residuals(pr)
    assert energy(pr) == pytest.approx(np.dot(pr.weights, e * e), rel=1e-14)


def test_bone_terms_shapes_and_convention():
    # t = 1 at joint i = bones[b, 0]: a vertex with t = 1 sits on joint i's sphere.
    joints = np.array([[0, 0, 0, 1.0], [0, 0, 4, 2.0]])
    pr = FitProblem(np.array([[2.0, 0, 4.0], [1.0, 0, 0.0]]), np.ones(2), joints, np.array([[1, 0]]),
                    np.array([0, 0]), np.array([1.0, 0.0]))
    i, j, d, rho, e = bone_terms(pr)
    assert d.shape == (2, 3) and i.tolist() == [1, 1] and j.tolist() == [0, 0]
    np.testing.assert_allclose(rho, [2.0, 1.0])
    np.testing.assert_allclose(e, [0.0, 0.0], atol=1e-15)


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_gradient_matches_central_differences(seed):
    pr = random_problem(seed)
    E, g = energy_and_gradient(pr)
    assert E == pytest.approx(energy(pr), rel=1e-14)
    h = 1e-6
    fd = np.zeros_like(g)
    for a in range(g.shape[0]):
        for b in range(4):
            Jp, Jm = pr.joints.copy(), pr.joints.copy()
            Jp[a, b] += h
            Jm[a, b] -= h
            fd[a, b] = (energy(pr, Jp) - energy(pr, Jm)) / (2 * h)
    assert np.abs(fd - g).max() / np.abs(g).max() < 1e-6


def test_gradient_of_unused_joint_is_zero():
    pr = random_problem(5)
    pr.joints = np.vstack([pr.joints, [9, 9, 9, 1]])    # a joint no bone uses
    _, g = energy_and_gradient(pr)
    assert g.shape == (len(pr.joints), 4)
    assert np.all(g[-1] == 0)


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_line_quartic_matches_direct_evaluation(seed):
    pr = random_problem(seed)
    rng = np.random.default_rng(100 + seed)
    D = rng.normal(size=pr.joints.shape)
    c = line_quartic(pr, D)
    assert c[0] == pytest.approx(energy(pr), rel=1e-12)
    assert c[4] >= 0
    for lam in np.linspace(-3, 3, 41):
        direct = energy(pr, pr.joints - lam * D)
        poly = sum(c[k] * lam ** k for k in range(5))
        assert poly == pytest.approx(direct, rel=1e-9)


def test_line_quartic_along_gradient_has_slope_minus_gradient_norm_squared():
    pr = random_problem(7)
    E, g = energy_and_gradient(pr)
    c = line_quartic(pr, g)
    # d/dlam E(J - lam g) at 0 = -|g|^2
    assert c[1] == pytest.approx(-np.sum(g * g), rel=1e-10)


def test_line_quartic_small_example_by_hand():
    # One vertex at distance 2 from the bone, radii 1: e(lam) = 4 - (1 - lam)^2 when both radii
    # shrink at unit speed, E = (3 + 2 lam - lam^2)^2 = 9 + 12 lam - 2 lam^2 - 4 lam^3 + lam^4.
    pr = FitProblem(np.array([[2.0, 0, 0.5]]), np.ones(1), np.array([[0, 0, 0, 1.0], [0, 0, 1, 1.0]]),
                    np.array([[0, 1]]), np.array([0]), np.array([0.5]))
    D = np.zeros((2, 4))
    D[:, 3] = 1.0
    np.testing.assert_allclose(line_quartic(pr, D), [9, 12, -2, -4, 1])


def test_paper_eq24_coefficients_are_misprinted():
    # ((a z + b)^2 - c)^2: the z^3 coefficient is 4 a^3 b and the z^2 one 6 a^2 b^2 - 2 a^2 c
    # (the paper prints 4 a^3 and 6 a^2 b^2 - 2 b^2 c). Checked numerically.
    a, b, c = 1.3, -0.7, 2.1
    poly = np.polynomial.Polynomial([b, a]) ** 2 - c
    coef = (poly ** 2).coef
    assert coef[3] == pytest.approx(4 * a ** 3 * b)
    assert coef[2] == pytest.approx(6 * a ** 2 * b ** 2 - 2 * a ** 2 * c)
    assert coef[3] != pytest.approx(4 * a ** 3)
    assert coef[2] != pytest.approx(6 * a ** 2 * b ** 2 - 2 * b ** 2 * c)


def test_energy_does_not_modify_problem():
    pr = random_problem(3)
    before = [x.copy() for x in (pr.points, pr.weights, pr.joints, pr.bones, pr.bone, pr.t)]
    energy_and_gradient(pr)
    line_quartic(pr, np.ones_like(pr.joints))
    for x, y in zip(before, (pr.points, pr.weights, pr.joints, pr.bones, pr.bone, pr.t)):
        np.testing.assert_array_equal(x, y)
