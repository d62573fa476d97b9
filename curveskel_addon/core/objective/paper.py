"""The paper's solver: gradient descent with exact line search (eqs. 28-31).

Why keep it: it reproduces the published method (``SkeletonParams.paper()``), so results can be
compared with the paper's figures. It converges slowly (E is badly conditioned: positions and
radii of joints with many vertices dominate the gradient), which is why "lm" is the default.

Each iteration::

    g   = grad E(J_k)                             (exact, :func:`..energy.energy_and_gradient`)
    lam = argmin_lam E(J_k - lam g)               (eq. 29; a quartic, :func:`..line_search`)
    J_{k+1} = J_k - lam g, negative radii flipped (section 4.2, last paragraph)
    stop when |E_k - E_{k+1}| < tolerance * E_0   (eqs. 30-31, tolerance = 1e-3 in the paper)

One deviation, needed to keep E monotone: r enters E through ``rho = t r_i + (1-t) r_j``, so
flipping the sign of one radius is *not* neutral (the paper's argument holds only at the joints
themselves). When the flip would leave E above E_k, the step is instead restricted to the
interval of ``lam`` on which every radius stays >= 0 (the exact minimiser of the quartic on that
interval; ``lam = 0`` is in it, so E cannot increase). Counters of both cases are kept in the
optional ``stats`` dict for reports.

The mapping sigma is the first approximation's, held (the paper's): each vertex on the bones of
its Reeb region (:mod:`..initialise.reeb`).
"""

from __future__ import annotations

from typing import Iterator

import numpy as np

from .energy import energy, energy_and_gradient, line_quartic
from .line_search import minimize_quartic, minimize_quartic_on
from .problem import FitProblem, SolverState

__all__ = ["paper_steps", "paper_fit", "radius_interval"]


def radius_interval(r: np.ndarray, g_r: np.ndarray) -> tuple[float, float]:
    """Interval of ``lam`` on which ``r - lam g_r >= 0`` for every joint (contains 0 if r >= 0).

    Parameters
    ----------
    r, g_r : (J,) float

    Returns
    -------
    lo, hi : float

    Examples
    --------
    >>> radius_interval(np.array([1.0, 2.0]), np.array([2.0, -1.0]))
    (-2.0, 0.5)
    """
    pos, neg = g_r > 0, g_r < 0
    hi = float(np.min(r[pos] / g_r[pos])) if pos.any() else np.inf
    lo = float(np.max(r[neg] / g_r[neg])) if neg.any() else -np.inf
    return min(lo, 0.0), max(hi, 0.0)


def paper_steps(problem: FitProblem, *, max_iterations: int, tolerance: float,
                stats: dict | None = None) -> Iterator[SolverState]:
    """Gradient descent with exact line search, one iteration per ``next()``.

    Parameters
    ----------
    problem : FitProblem
        Start point (never modified).
    max_iterations : int
        Stop after this many iterations.
    tolerance : float
        Eq. 31: stop when one iteration changes E by less than ``tolerance * E0``.
    stats : dict, optional
        Filled with counters: ``"flips"`` (steps whose negative radii were flipped),
        ``"restricted"`` (steps restricted to keep radii >= 0).

    Yields
    ------
    SolverState
        Iteration 0 (E0, nothing changed), then one state per iteration; the last has
        ``done=True``.

    Examples
    --------
    >>> states = list(paper_steps(pr, max_iterations=50))   # doctest: +SKIP
    >>> states[-1].done, states[-1].energy <= states[0].energy   # doctest: +SKIP
    (True, True)
    """
    stats = {} if stats is None else stats
    stats.update(flips=0, restricted=0)
    pts, w, bones = problem.points, problem.weights, problem.bones
    joints = np.array(problem.joints, dtype=np.float64)
    bone = np.array(problem.bone, dtype=np.int64)
    t = np.array(problem.t, dtype=np.float64)

    def view(J, b, tt):
        return FitProblem(pts, w, J, bones, b, tt)

    E0 = energy(view(joints, bone, t))
    done = max_iterations <= 0 or not E0 > 0
    yield SolverState(0, joints, bone, t, E0, done)
    if done:
        return
    E = E0
    for k in range(1, max_iterations + 1):
        pr = view(joints, bone, t)
        _, g = energy_and_gradient(pr)
        c = line_quartic(pr, g)
        lam = minimize_quartic(c)
        new = joints - lam * g
        E_new = energy(pr, new)            # exact, not the quartic's value (round-off)
        if np.any(new[:, 3] < 0):
            flipped = new.copy()
            flipped[:, 3] = np.abs(flipped[:, 3])
            E_flip = energy(pr, flipped)
            if E_flip <= E:
                new, E_new = flipped, E_flip
                stats["flips"] += 1
            else:
                lo, hi = radius_interval(joints[:, 3], g[:, 3])
                lam = minimize_quartic_on(c, lo, hi)
                new = joints - lam * g
                new[:, 3] = np.maximum(new[:, 3], 0.0)      # round-off at the interval end
                E_new = energy(pr, new)
                stats["restricted"] += 1
        if E_new > E:            # only by round-off near a minimum: never report an increase
            new, E_new = joints, E
        done = abs(E - E_new) < tolerance * E0 or k == max_iterations
        joints, E = new, E_new
        yield SolverState(k, joints, bone, t, E, done)
        if done:
            return


def paper_fit(V, graph, bone, t, *, max_iterations, tolerance):
    """The paper's fit of its first approximation: yields ``(stage, joints, bone, t, E,
    iterations)`` for the first approximation ("initialise", E0) and the fitted skeleton
    ("fit"): E (eq. 20) is the vertex sum, every vertex weighing 1."""
    pr = FitProblem(np.asarray(V, np.float64), np.ones(len(V)), np.array(graph.joints),
                    graph.bones, np.asarray(bone, np.int64), np.asarray(t, np.float64))
    last = None
    for state in paper_steps(pr, max_iterations=max_iterations, tolerance=tolerance):
        if state.iteration == 0:
            yield "initialise", state.joints, state.bone, state.t, float(state.energy), 0
        last = state
    if last is not None and last.iteration > 0:
        yield "fit", last.joints, last.bone, last.t, float(last.energy), int(last.iteration)
