"""Choosing the first approximation: several poles and spacings, the lowest E wins.

The paper's conclusion: the method "allows to evaluate skeletons and to choose the best one
among others". Here the others are first approximations that differ in the random first vertex
of the pole search (hence possibly the pole, which decides the Reeb graph's shape) and in the
contour spacing. Each is optimised briefly and compared by E (eq. 20, area-weighted when
``params.area_weighted``, so that a finer or coarser sampling of the same surface gives
comparable numbers); the pipeline then runs the full solve on the winner only.

What the comparison means: E depends on the skeleton *and* its mapping, and more joints can
only help a piecewise-linear fat curve, so a finer spacing tends to win. That is the paper's
criterion taken literally (the best approximation of the shape by the silhouette); the
joint count is controlled afterwards by :func:`.postprocess.simplify_chains`.

Validity before E: definition 1 of the paper asks the skeleton to lie in the closed shape
(Gamma in the closure of Omega). A joint with few vertices can run away during the optimisation
(measured: joints 30-50 bounding-box diagonals away, radii of several diagonals, on elephant.obj
and rocker-arm.obj) while E still drops, because E only sees the vertices mapped to it. So a
candidate whose briefly optimised skeleton has a joint more than ``OUTSIDE_TOL`` diagonals
outside the mesh's bounding box, or a radius above half the diagonal, is ranked after every
valid one; among valid candidates the lowest E wins; if none is valid, the one that leaves the
box least (measured: elephant.obj, where all three candidates run away, 0.19 D versus 30 D).
"""

from __future__ import annotations

import time

import numpy as np

from .problem import FitProblem
from .vertex_area import vertex_areas

__all__ = ["best_of_candidates", "candidate_settings", "skeleton_extent", "SPACING_FACTORS",
           "OUTSIDE_TOL", "MAX_RADIUS"]

#: Spacing multipliers cycled through by :func:`candidate_settings`.
SPACING_FACTORS = (1.0, 0.75, 1.25)

#: A candidate is invalid if a joint lies farther than this (in bounding-box diagonals) outside
#: the mesh's bounding box, or a radius exceeds ``MAX_RADIUS`` diagonals.
OUTSIDE_TOL = 0.05
MAX_RADIUS = 0.5


def candidate_settings(n: int, spacing: float, seed: int) -> list[tuple[int, float]]:
    """The (seed, spacing) of each of ``n`` candidates; the first is the plain run.

    Candidate k uses seed ``seed + k`` (another random first vertex, so possibly another pole)
    and spacing ``spacing * SPACING_FACTORS[k % 3]`` clipped to (0, 0.5].

    Examples
    --------
    >>> candidate_settings(4, 0.04, 7)
    [(7, 0.04), (8, 0.03), (9, 0.05), (10, 0.04)]
    """
    out = []
    for k in range(max(int(n), 1)):
        s = min(round(spacing * SPACING_FACTORS[k % len(SPACING_FACTORS)], 12), 0.5)
        out.append((seed + k, s))
    return out


def skeleton_extent(joints: np.ndarray, V: np.ndarray) -> tuple[float, float]:
    """How far the skeleton leaves the mesh's bounding box, and its largest radius, both in
    bounding-box diagonals D.

    Returns
    -------
    outside : float
        ``max_j max_k (lo_k - x_jk, x_jk - hi_k) / D`` (negative when every joint is inside).
    radius : float
        ``max_j |r_j| / D``.
    """
    lo, hi = V.min(axis=0), V.max(axis=0)
    D = max(float(np.linalg.norm(hi - lo)), 1e-300)
    X = joints[:, :3]
    out = float(np.max(np.maximum(lo - X, X - hi))) / D
    return out, float(np.max(np.abs(joints[:, 3]))) / D


def _short_solve(pr: FitProblem, params, iterations: int, solve_steps) -> tuple[FitProblem, float]:
    last = None
    for state in solve_steps(pr, solver=params.solver, max_iterations=iterations,
                             tolerance=params.tolerance, refit_mapping=params.refit_mapping):
        last = state
    out = pr.copy()
    out.joints, out.bone, out.t = last.joints, last.bone, last.t
    return out, float(last.energy)


def best_of_candidates(V, F, params, *, seed: int | None = None, weights=None,
                       iterations: int = 10, first_approximation=None, solve_steps=None):
    """The first approximation of lowest E after a short optimisation, among ``params.candidates``.

    Parameters
    ----------
    V : (n, 3) float
    F : (m, 3) int
        ONE connected component (the contract of ``reeb.first_approximation``).
    params : SkeletonParams
        ``candidates`` (how many), ``spacing``, ``seed``, ``solver``, ``tolerance``,
        ``refit_mapping``, ``area_weighted``.
    seed : int, optional
        Base seed (default ``params.seed``); the pipeline passes ``params.seed + component``.
    weights : (n,) float, optional
        Vertex weights for E; default: barycentric areas normalised to mean 1 when
        ``params.area_weighted``, else ones.
    iterations : int
        Solver iterations per candidate (short: the ranking settles quickly).
    first_approximation, solve_steps : callables, optional
        Injected for tests; default the package's ``reeb.first_approximation`` and
        ``solvers.solve_steps``.

    Returns
    -------
    FirstApproximation
        The winner, *not* optimised (the pipeline solves it in full), with
        ``meta["candidates"]``: one dict per candidate (seed, spacing, pole, joints, E0, E,
        outside, max_radius, valid, seconds, chosen) and ``meta["candidate_index"]``: the valid
        candidate of lowest E (see the module notes). Ties go to the earlier candidate, so the
        result is deterministic for a fixed seed.
    """
    if first_approximation is None:
        from .reeb import first_approximation
    if solve_steps is None:
        from .solvers import solve_steps
    V = np.asarray(V, np.float64)
    F = np.asarray(F, np.int64)
    seed = params.seed if seed is None else seed
    if weights is None:
        if params.area_weighted:
            w = vertex_areas(V, F)
            weights = w * (len(V) / max(w.sum(), 1e-300))
        else:
            weights = np.ones(len(V))
    settings = candidate_settings(params.candidates, params.spacing, seed)
    records, results, seen = [], [], {}
    for k, (s, sp) in enumerate(settings):
        t0 = time.perf_counter()
        fa = first_approximation(V, F, spacing=sp, seed=s)
        key = (fa.meta.get("pole"), fa.meta.get("spacing_used", sp), len(fa.joints), len(fa.bones))
        if key[0] is not None and key in seen:        # same pole and spacing: same candidate
            j = seen[key]
            records.append(dict(records[j], seed=s, spacing=sp, duplicate_of=j, seconds=0.0,
                                chosen=False))
            results.append(None)
            continue
        seen[key] = k
        pr = FitProblem(V, weights, np.asarray(fa.joints, np.float64), np.asarray(fa.bones),
                        np.asarray(fa.bone), np.asarray(fa.t, np.float64))
        solved, E = _short_solve(pr, params, iterations, solve_steps)
        e0 = _plain_energy(pr)
        outside, rmax = skeleton_extent(solved.joints, V)
        records.append({"seed": int(s), "spacing": float(sp), "pole": _int_or_none(fa.meta.get("pole")),
                        "joints": int(len(fa.joints)), "E0": e0, "E": E,
                        "outside": outside, "max_radius": rmax,
                        "valid": bool(outside <= OUTSIDE_TOL and rmax <= MAX_RADIUS),
                        "seconds": time.perf_counter() - t0, "chosen": False})
        results.append(fa)
    Es = np.array([r["E"] if results[k] is not None else np.inf for k, r in enumerate(records)])
    valid = np.array([r["valid"] for r in records])
    fresh = np.array([results[k] is not None for k in range(len(records))])
    if np.any(valid & fresh):
        best = int(np.argmin(np.where(valid, Es, np.inf)))   # first minimum: deterministic ties
    else:                                              # none valid: the one least outside
        out = np.array([max(r["outside"], r["max_radius"] - MAX_RADIUS) for r in records])
        best = int(np.argmin(np.where(fresh, out, np.inf)))
    records[best]["chosen"] = True
    win = results[best]
    win.meta = dict(win.meta)
    win.meta["candidates"] = records
    win.meta["candidate_index"] = best
    return win


def _plain_energy(pr: FitProblem) -> float:
    from .energy import energy

    return energy(pr)


def _int_or_none(x):
    try:
        return int(x)
    except (TypeError, ValueError):
        return None
