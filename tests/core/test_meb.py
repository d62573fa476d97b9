"""Exact minimum enclosing ball: brute force on small sets, analytic cases, optimality on big sets."""

import itertools

import numpy as np
import pytest
from scipy.optimize import nnls

from curveskel_addon.core.errors import CurveSkelError
from curveskel_addon.core.geometry.meb import ball_through, min_enclosing_ball


def brute_force(P):
    """Smallest ball, among those through 1..4 support points, that contains every point."""
    best_r, best_c = np.inf, None
    for k in range(1, 5):
        for S in itertools.combinations(range(len(P)), k):
            c, r2 = ball_through(P[list(S)])
            r = np.sqrt(r2)
            if r < best_r and np.all(np.linalg.norm(P - c, axis=1) <= r * (1 + 1e-9) + 1e-12):
                best_r, best_c = r, c
    return best_c, best_r


def _random_set(rng, kind, n):
    P = rng.normal(size=(n, 3))
    if kind == "coplanar":
        P[:, 2] = 0.3
    elif kind == "collinear":
        P = np.outer(rng.normal(size=n), [1.0, -2.0, 0.5]) + [1, 2, 3]
    elif kind == "duplicates":
        P = np.concatenate([P, P[: max(1, n // 2)]])
    elif kind == "cocircular":
        a = rng.uniform(0, 2 * np.pi, n)
        P = np.stack([np.cos(a), np.sin(a), np.zeros(n)], 1)
    elif kind == "integer":
        P = rng.integers(-2, 3, size=(n, 3)).astype(float)   # many exact ties
    return P


@pytest.mark.parametrize("kind", ["general", "coplanar", "collinear", "duplicates", "cocircular", "integer"])
def test_matches_brute_force(kind):
    rng = np.random.default_rng(hash(kind) % 2**32)
    for _ in range(40):
        P = _random_set(rng, kind, int(rng.integers(1, 10)))
        c, r = min_enclosing_ball(P)
        bc, br = brute_force(P)
        assert r == pytest.approx(br, rel=1e-7, abs=1e-9)
        assert np.all(np.linalg.norm(P - c, axis=1) <= r * (1 + 1e-9) + 1e-12)


def test_analytic_cases():
    c, r = min_enclosing_ball(np.array([[1.0, 2, 3]]))
    assert r == 0 and np.allclose(c, [1, 2, 3])
    c, r = min_enclosing_ball(np.array([[0.0, 0, 0], [0, 0, 4]]))
    assert r == pytest.approx(2) and np.allclose(c, [0, 0, 2])
    # equilateral triangle of side 1: circumradius 1/sqrt(3)
    T = np.array([[0.0, 0, 0], [1, 0, 0], [0.5, np.sqrt(3) / 2, 0]])
    c, r = min_enclosing_ball(T)
    assert r == pytest.approx(1 / np.sqrt(3)) and np.allclose(c, T.mean(0))
    # obtuse triangle: the ball on the longest side
    c, r = min_enclosing_ball(np.array([[0.0, 0, 0], [4, 0, 0], [2, 0.5, 0]]))
    assert r == pytest.approx(2) and np.allclose(c, [2, 0, 0])
    # regular tetrahedron with vertices on the unit sphere
    tet = np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]]) / np.sqrt(3)
    c, r = min_enclosing_ball(tet + 5)
    assert r == pytest.approx(1) and np.allclose(c, 5)
    # all duplicates
    c, r = min_enclosing_ball(np.ones((7, 3)))
    assert r == 0 and np.allclose(c, 1)


def _is_optimal(P, c, r):
    """KKT: the centre is a convex combination of the points on the sphere."""
    on = P[np.abs(np.linalg.norm(P - c, axis=1) - r) <= 1e-7 * r]
    A = np.vstack([on.T, np.ones(len(on))])
    lam, res = nnls(A, np.r_[c, 1.0])
    return res < 1e-6 * max(r, 1)


@pytest.mark.parametrize("n", [1000, 200_000])
def test_large_sets_optimal(n):
    rng = np.random.default_rng(n)
    for P in (rng.random((n, 3)) * [3, 1, 2],
              rng.normal(size=(n, 3)) / 1.0,
              np.c_[np.cos(a := rng.uniform(0, 2 * np.pi, n)), np.sin(a), 0.01 * rng.random(n)]):
        c, r = min_enclosing_ball(P)
        d = np.linalg.norm(P - c, axis=1)
        assert d.max() <= r * (1 + 1e-12)
        assert _is_optimal(P, c, r)


def test_points_on_sphere():
    rng = np.random.default_rng(3)
    P = rng.normal(size=(50_000, 3))
    P /= np.linalg.norm(P, axis=1, keepdims=True)
    c, r = min_enclosing_ball(2 * P + [1, -1, 0.5])
    assert r == pytest.approx(2, rel=1e-9) and np.allclose(c, [1, -1, 0.5], atol=1e-6)


@pytest.mark.parametrize("bad", [np.zeros((0, 3)), np.zeros((3, 2)), np.array([[0, 0, np.nan]])])
def test_bad_input(bad):
    with pytest.raises(CurveSkelError):
        min_enclosing_ball(bad)
