"""Continuous minimisation of J over the joints' positions and radii, the graph held.

Levenberg-Marquardt on J's Gauss-Newton model (:meth:`.objective.Objective.model`) with sigma
held during a step; a step is kept only when the *exact* J (sigma mapped again) falls, so J
never rises. Marquardt's scaled damping (rotation-invariant: :func:`_damping_scale`), Nielsen's adaptation. It stops when a kept step
lowers J by less than ``tolerance`` of J, or when no damping gives a decrease. Negative radii
are flipped (r enters J squared, as in the paper).

Run to convergence, the result is a local minimum, and a tiny change of the input (the
vertices' last bits) moves it by as little: stopping early would let the number of steps, a
discrete thing, decide where the joints end.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu

__all__ = ["minimise"]


def minimise(objective, graph, *, max_iterations, tolerance, fixed=None,
             evaluation=None):
    """Minimise J over the joints of ``graph`` (positions and radii).

    Parameters
    ----------
    objective : Objective
    graph : SkeletonGraph
    max_iterations : int
    tolerance : float
        Stop when a kept step lowers J by less than this fraction of it.
    fixed : (J,) bool, optional
        Joints that do not move (their radii still fit).
    evaluation : Evaluation, optional
        J of ``graph`` if already known.

    Returns
    -------
    graph, evaluation, iterations
    """
    ev = objective.evaluate(graph) if evaluation is None else evaluation
    n = 4 * graph.n_joints
    free = np.ones(n, bool)
    if fixed is not None:
        fx = np.flatnonzero(np.asarray(fixed, bool))
        for c in range(3):
            free[4 * fx + c] = False
    mu = 1e-3
    nu = 2.0
    it = 0
    for it in range(1, max_iterations + 1):
        H, g = objective.model(graph, ev.sigma)
        Hf, gf = H[free][:, free], g[free]
        dg = _damping_scale(H)[free]
        dg = np.maximum(dg, 1e-12 * max(float(dg.max(initial=0.0)), 1e-300))
        kept = False
        for _ in range(20):
            try:
                step = splu((Hf + sp.diags(mu * dg)).tocsc()).solve(-gf)
            except RuntimeError:                     # singular: more damping
                mu *= 10.0
                continue
            trial = _moved(graph, free, step)
            ev_t = objective.evaluate(trial)
            # the model's predicted decrease, for Nielsen's damping update
            predicted = -(gf @ step + 0.5 * step @ (Hf @ step))
            if ev_t.value < ev.value:
                kept = True
                rho = (ev.value - ev_t.value) / max(predicted, 1e-300)
                mu *= max(1.0 / 3.0, 1.0 - (2.0 * min(rho, 1.0) - 1.0) ** 3)
                mu = max(mu, 1e-12)
                nu = 2.0
                break
            mu *= nu
            nu *= 2.0
        if not kept:
            break
        drop = ev.value - ev_t.value
        graph, ev = trial, ev_t
        if drop < tolerance * ev.value:
            break
    return graph, ev, it


def _damping_scale(H):
    """Marquardt's scale of the damping, the same in any orientation of the axes: a joint's
    three position entries share the mean of their diagonal entries (the trace of the block
    turns with the mesh; each entry alone does not, and a rotated mesh would take other steps),
    its radius keeps its own."""
    d = np.asarray(H.diagonal(), np.float64).reshape(-1, 4).copy()
    d[:, :3] = d[:, :3].mean(axis=1, keepdims=True)
    return d.ravel()


def _moved(graph, free, step):
    """``graph`` with ``step`` added to its free variables (radii kept positive: r enters J
    squared, as in the paper)."""
    z = np.array(graph.joints).ravel()
    z[free] += step
    Z = z.reshape(-1, 4)
    Z[:, 3] = np.abs(Z[:, 3])
    return graph.with_joints(Z)
