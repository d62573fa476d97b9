"""Exact line search: minimize_quartic against brute force."""

import numpy as np
import pytest

from curveskel_addon.core.objective.line_search import minimize_quartic, minimize_quartic_on


def quartic(c, lam):
    return sum(c[k] * lam ** k for k in range(5))


def brute_force(c, lo=-10.0, hi=10.0, n=200001):
    lam = np.linspace(lo, hi, n)
    return lam[np.argmin(quartic(c, lam))]


@pytest.mark.parametrize("seed", range(20))
def test_random_quartics_match_brute_force(seed):
    rng = np.random.default_rng(seed)
    # Minimiser well inside [-10, 10]: roots of E' drawn in [-3, 3].
    r = rng.uniform(-3, 3, 3)
    d = np.poly(r)[::-1] * rng.uniform(0.5, 2)           # E' = k (x-r1)(x-r2)(x-r3), increasing
    c = np.r_[rng.normal(), d[0], d[1] / 2, d[2] / 3, d[3] / 4]
    lam = minimize_quartic(c)
    ref = brute_force(c)
    # Same value as the dense sampling (grid step 1e-4), and a stationary point.
    assert quartic(c, lam) <= quartic(c, ref) + 1e-9 * (1 + abs(quartic(c, ref)))
    assert abs(lam - ref) < 1e-3 or abs(quartic(c, lam) - quartic(c, ref)) < 1e-7


@pytest.mark.parametrize("seed", range(10))
def test_line_search_coefficients_shape(seed):
    # Quartics of the form sum w (A + B lam + C lam^2)^2, as E is along any direction.
    rng = np.random.default_rng(seed)
    A, B, C, w = rng.normal(size=(4, 50))
    w = np.abs(w)
    c = np.array([w @ (A * A), 2 * w @ (A * B), w @ (B * B + 2 * A * C), 2 * w @ (B * C), w @ (C * C)])
    lam = minimize_quartic(c)
    assert quartic(c, lam) <= quartic(c, brute_force(c)) + 1e-9 * abs(c[0])


def test_degenerate_quadratic_cubic_linear_constant():
    assert minimize_quartic([1, -2, 1, 0, 0]) == pytest.approx(1.0)          # (lam - 1)^2
    assert minimize_quartic([0, 3, 0, 0, 0]) == 0.0                          # linear: unbounded
    assert minimize_quartic([5, 0, 0, 0, 0]) == 0.0                          # constant
    assert minimize_quartic([0, 0, 0, 0, 0]) == 0.0
    # cubic lam^3 - 3 lam: unbounded below, local minimum at lam = 1
    assert minimize_quartic([0, -3, 0, 1, 0]) == pytest.approx(1.0)
    # concave quadratic: no minimum at all
    assert minimize_quartic([0, 1, -1, 0, 0]) == 0.0
    # negative leading coefficient: local minimum only (-lam^4 + 2 lam^2 has its at 0)
    assert minimize_quartic([0, 0, 2, 0, -1]) == pytest.approx(0.0, abs=1e-12)


def test_pure_quartic_and_double_roots():
    assert minimize_quartic([0, 0, 0, 0, 1]) == pytest.approx(0.0, abs=1e-12)
    # (lam - 2)^4: E' has a triple root; the answer must still be ~2
    c = np.polynomial.Polynomial.fromroots([2, 2, 2, 2]).coef
    assert minimize_quartic(c) == pytest.approx(2.0, abs=1e-4)
    # (lam^2 - 1)^2 has two global minima; either is fine
    assert abs(minimize_quartic([1, 0, -2, 0, 1])) == pytest.approx(1.0)


def test_tiny_leading_coefficient():
    # Nearly quadratic: (lam - 1)^2 + 1e-12 lam^4; global minimum next to 1.
    lam = minimize_quartic([1, -2, 1, 0, 1e-12])
    assert lam == pytest.approx(1.0, abs=1e-9)


def test_global_not_local_minimum():
    # Local minimum near -1.3 (higher) and global near +1.5.
    c = np.array([0.0, -1.0, -3.0, 0.2, 1.0])
    lam = minimize_quartic(c)
    assert lam == pytest.approx(brute_force(c), abs=1e-3)
    assert lam > 0


def test_non_finite_raises():
    with pytest.raises(ValueError):
        minimize_quartic([0, np.nan, 1, 0, 1])


@pytest.mark.parametrize("lo,hi", [(0.0, 0.5), (-1.0, 3.0), (1.5, 4.0), (-2.0, -1.0)])
def test_minimize_on_interval(lo, hi):
    c = np.array([0.3, -1.0, -3.0, 0.2, 1.0])
    lam = minimize_quartic_on(c, lo, hi)
    assert lo <= lam <= hi
    assert quartic(c, lam) <= quartic(c, brute_force(c, lo, hi, 100001)) + 1e-9
