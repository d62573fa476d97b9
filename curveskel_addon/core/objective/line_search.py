"""Exact line search: the global minimiser of a real quartic (eq. 29).

Why exact: along any direction E is a quartic in the step (see :mod:`.energy`), so the paper's
"minimise it analytically" is cheap and leaves no step-size parameter to tune. The minimiser is
one of the real roots of the cubic derivative; we take all roots of the derivative (with their
leading zero coefficients trimmed, so degenerate quartics -- cubic, quadratic, linear -- are
handled by the same code), evaluate the quartic at each and keep the lowest.

When the quartic is unbounded below (negative leading coefficient, or odd degree) there is no
global minimiser; we then return the lowest *local* minimiser, or 0 (no step) when there is none.
For E, ``c4 = sum w C^2 >= 0`` and when ``c4 == 0`` also ``c3 == 0`` and ``c2 >= 0``, so the
unbounded case only arises for arbitrary user quartics.
"""

from __future__ import annotations

import numpy as np

__all__ = ["minimize_quartic", "minimize_quartic_on"]


def _eval(c: np.ndarray, lam) -> np.ndarray:
    lam = np.asarray(lam, dtype=np.float64)
    return (((c[4] * lam + c[3]) * lam + c[2]) * lam + c[1]) * lam + c[0]


def _critical_points(c: np.ndarray) -> np.ndarray:
    """Real parts of all roots of E'(lam) = c1 + 2 c2 lam + 3 c3 lam^2 + 4 c4 lam^3.

    Near-real roots of a (numerically) double root come back with a tiny imaginary part; keeping
    every real part is harmless because the caller chooses by value and by E''.
    """
    dc = np.array([4.0 * c[4], 3.0 * c[3], 2.0 * c[2], c[1]])     # highest degree first
    nz = np.flatnonzero(dc != 0.0)
    if len(nz) == 0 or nz[0] == 3:                                 # E' constant: no critical point
        return np.empty(0)
    roots = np.roots(dc[nz[0]:])
    lam = roots.real
    # One Newton polish on E' (np.roots uses a companion-matrix eigensolver).
    d1 = ((dc[0] * lam + dc[1]) * lam + dc[2]) * lam + dc[3]
    d2 = (3.0 * dc[0] * lam + 2.0 * dc[1]) * lam + dc[2]
    ok = np.abs(d2) > 0
    polished = lam.copy()
    polished[ok] = lam[ok] - d1[ok] / d2[ok]
    better = np.abs(((dc[0] * polished + dc[1]) * polished + dc[2]) * polished + dc[3]) < np.abs(d1)
    return np.where(better & np.isfinite(polished), polished, lam)


def minimize_quartic(c) -> float:
    """Global minimiser over real ``lam`` of ``c0 + c1 lam + c2 lam^2 + c3 lam^3 + c4 lam^4``.

    Parameters
    ----------
    c : (5,) array_like
        Coefficients in increasing degree (as returned by :func:`.energy.line_quartic`).

    Returns
    -------
    float
        The minimiser. If the polynomial is unbounded below, the lowest local minimiser, or 0.0
        if there is none (constant, linear, concave quadratic, ...). Ties go to the smallest
        ``|lam|``.

    Examples
    --------
    >>> round(minimize_quartic([0, 0.5, -2, 0, 1]), 6)   # lam^4 - 2 lam^2 + lam/2: two minima
    -1.057454
    >>> minimize_quartic([1, -2, 1, 0, 0])      # (lam - 1)^2
    1.0
    >>> minimize_quartic([5, 0, 0, 0, 0])       # constant
    0.0
    """
    c = np.asarray(c, dtype=np.float64).reshape(5)
    if not np.all(np.isfinite(c)):
        raise ValueError(f"quartic coefficients must be finite, got {c}")
    lam = _critical_points(c)
    if len(lam) == 0:
        return 0.0
    bounded = (c[4] > 0) or (c[4] == 0 and c[3] == 0 and c[2] > 0)
    if not bounded:
        d2 = (12.0 * c[4] * lam + 6.0 * c[3]) * lam + 2.0 * c[2]
        lam = lam[d2 > 0]
        if len(lam) == 0:
            return 0.0
    vals = _eval(c, lam)
    best = np.flatnonzero(vals == vals.min())
    return float(lam[best[np.argmin(np.abs(lam[best]))]])


def minimize_quartic_on(c, lo: float, hi: float) -> float:
    """Minimiser of the quartic on the closed interval ``[lo, hi]``.

    Used by the paper solver when flipping negative radii would raise E: the step is then
    restricted to where every radius stays non-negative.

    Parameters
    ----------
    c : (5,) array_like
    lo, hi : float
        Interval ends, ``lo <= hi``.

    Returns
    -------
    float

    Examples
    --------
    >>> minimize_quartic_on([1, -2, 1, 0, 0], 0.0, 0.5)
    0.5
    """
    c = np.asarray(c, dtype=np.float64).reshape(5)
    lam = _critical_points(c)
    cand = np.concatenate([[lo, hi], lam[(lam >= lo) & (lam <= hi)]])
    return float(cand[np.argmin(_eval(c, cand))])
