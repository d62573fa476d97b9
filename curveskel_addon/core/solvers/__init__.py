"""Solvers of the fitting problem, behind one steppable interface.

Why a generator: the Blender operator steps the solver from a modal timer (one ``next()`` per
tick, redrawing the preview in between) and can stop it at any time; the command line and the
pipeline simply exhaust it. Every solver yields iteration 0 first (E0, nothing changed), then one
state per iteration, the last with ``done=True``, and never modifies the problem's arrays.

* ``"paper"`` -- :mod:`.paper`: gradient descent with exact line search, eqs. 28-31.
* ``"lm"`` -- :mod:`.lm`: Levenberg-Marquardt on the block-sparse normal equations (default).
"""

from __future__ import annotations

from typing import Iterator

from ..errors import CurveSkelError
from ..problem import FitProblem, SolverState
from .lm import lm_steps
from .paper import paper_steps

__all__ = ["solve_steps", "solve", "SOLVER_STEPS"]

SOLVER_STEPS = {"paper": paper_steps, "lm": lm_steps}


def solve_steps(problem: FitProblem, *, solver: str = "lm", max_iterations: int = 100,
                tolerance: float = 1e-3, refit_mapping: bool = False,
                stats: dict | None = None) -> Iterator[SolverState]:
    """Iterate a solver on ``problem``.

    Parameters
    ----------
    problem : FitProblem
        Start point; its arrays are never modified (states hold new arrays).
    solver : {"paper", "lm"}
    max_iterations : int
        Upper bound on iterations after iteration 0.
    tolerance : float
        "paper": stop when an iteration changes E by less than ``tolerance * E0`` (eqs. 30-31).
        "lm": stop when an iteration lowers E by less than ``tolerance / 10 * E`` and the
        scaled gradient is as small (see :mod:`.lm`).
    refit_mapping : bool
        Re-fit sigma (each vertex's bone and t) between steps; E still never increases.
    stats : dict, optional
        Filled with solver counters (see each solver).

    Yields
    ------
    SolverState
        ``iteration`` 0 first (E0), the last with ``done=True``; ``energy`` never increases.

    Raises
    ------
    CurveSkelError
        Unknown solver name.

    Examples
    --------
    >>> states = list(solve_steps(pr, solver="lm"))         # doctest: +SKIP
    >>> states[0].iteration, states[-1].done                # doctest: +SKIP
    (0, True)
    """
    try:
        steps = SOLVER_STEPS[solver]
    except KeyError:
        raise CurveSkelError(f"unknown solver {solver!r}; choose one of "
                             f"{', '.join(SOLVER_STEPS)}") from None
    return steps(problem, max_iterations=max_iterations, tolerance=tolerance,
                 refit_mapping=refit_mapping, stats=stats)


def solve(problem: FitProblem, **kwargs) -> SolverState:
    """Run :func:`solve_steps` to the end and return the last state.

    Examples
    --------
    >>> solve(pr, solver="paper").done                      # doctest: +SKIP
    True
    """
    state = None
    for state in solve_steps(problem, **kwargs):
        pass
    return state
