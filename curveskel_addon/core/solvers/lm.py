"""Levenberg-Marquardt on the residuals ``r_v = sqrt(w_v) e_v`` (issue 5: a solver that converges).

Why: E is a sum of squares of residuals that each depend on only 8 unknowns (the two joints of
one bone), so the Gauss-Newton matrix ``J^T J`` is block-sparse with the skeleton's own sparsity
(4x4 blocks on the diagonal and for each bone) and a damped Gauss-Newton step costs one pass over
the vertices plus a tiny sparse solve. Gradient descent (the paper) needs hundreds of passes for
the same decrease because E is badly conditioned.

Assembly in one pass
--------------------
With ``G_v = (d_v, rho_v)`` (``d = v - sigma``), ``de/dJ_i = -2 t G`` and
``de/dJ_j = -2 (1-t) G``. So every block of ``J^T J`` for bone ``b = (i, j)`` is a per-bone sum of
``G G^T`` (10 distinct products) weighted by ``4 w t^2`` (block ii), ``4 w (1-t)^2`` (jj) or
``4 w t (1-t)`` (ij and ji), and ``J^T r`` is a per-bone sum of ``w e G`` weighted by ``-2 t`` or
``-2 (1-t)``. The per-bone sums are two sparse (bones x vertices) matrix products, whose
matrices depend only on the mapping (rebuilt only when a re-fit changes it); the few bone
blocks are then scattered into the (4J x 4J) sparse system, which SuperLU factorises in
milliseconds (its fill follows the skeleton graph, a tree or nearly).

Damping and acceptance
----------------------
Marquardt's scaled damping ``(J^T J + mu diag(J^T J)) h = -J^T r`` (scale invariant, like
``x_scale='jac'``), ``mu`` adapted with Nielsen's rule from the gain ratio (actual over
predicted decrease). A step is accepted only if E decreases, so E never increases. Radii are
replaced by their absolute values after each step (r enters squared, as in the paper) before E
is evaluated, so acceptance sees the true E.

Stopping
--------
After an accepted iteration (step plus optional re-fit): stop when it lowered E by less than
``ftol * E`` *and* the Gauss-Newton model predicted less than ``ftol * E`` for it, with
``ftol = tolerance * 1e-2`` (so the default ``tolerance = 1e-3`` stops at a relative change of
1e-5; see the report of issue 5 for the measured distance to a tight reference); or when no
damping up to ``mu_max`` gives a decrease; or after ``max_iterations``.
"""

from __future__ import annotations

from typing import Iterator

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu

from ..energy import bone_terms, energy
from ..problem import FitProblem, SolverState
from ..refit import bone_neighbours, refit_mapping as _refit

__all__ = ["lm_steps", "NormalEquations"]

# The 10 distinct products G_k G_l (k <= l) of a 4-vector, and where each lands in a 4x4 block.
_IU = np.triu_indices(4)
_FULL = np.zeros((4, 4), np.int64)
_FULL[_IU] = np.arange(10)
_FULL = np.maximum(_FULL, _FULL.T).ravel()        # (16,) index into the 10 products


class NormalEquations:
    """Gauss-Newton system of E for one fixed mapping (bone, t); joints vary.

    Parameters
    ----------
    pr : FitProblem
        Points, weights, bones, mapping (the joints given to :meth:`assemble` are used instead
        of ``pr.joints``).

    Examples
    --------
    >>> ne = NormalEquations(pr)                         # doctest: +SKIP
    >>> E, jtr, H = ne.assemble(pr.joints)               # doctest: +SKIP
    >>> H.shape == (4 * len(pr.joints),) * 2             # doctest: +SKIP
    True
    """

    def __init__(self, pr: FitProblem):
        self.pr = pr
        n, B, J = len(pr.points), len(pr.bones), len(pr.joints)
        self.n_joints = J
        t, w = pr.t, pr.weights
        s = 1.0 - t
        cols = np.arange(n)
        b = pr.bone
        # Per-bone weights of G G^T: rows [0, B) t^2, [B, 2B) (1-t)^2, [2B, 3B) t(1-t).
        self.S3 = sp.csr_matrix((np.concatenate([4 * w * t * t, 4 * w * s * s, 4 * w * t * s]),
                                 (np.concatenate([b, b + B, b + 2 * B]), np.tile(cols, 3))),
                                shape=(3 * B, n))
        # Per-bone weights of w e G: rows [0, B) -2 t, [B, 2B) -2 (1-t).
        self.S2 = sp.csr_matrix((np.concatenate([-2 * w * t, -2 * w * s]),
                                 (np.concatenate([b, b + B]), np.tile(cols, 2))), shape=(2 * B, n))
        # Where each bone's 3 kinds of 4x4 block go in the (4J x 4J) matrix: ii, jj, ij, ji.
        bi, bj = pr.bones[:, 0], pr.bones[:, 1]
        k = np.arange(4)
        def block(r, c):   # (B, 16) row / column indices of the 4x4 block (r, c)
            return ((4 * r[:, None, None] + k[None, :, None]).repeat(4, 2).reshape(B, 16),
                    (4 * c[:, None, None] + k[None, None, :]).repeat(4, 1).reshape(B, 16))
        rc = [block(bi, bi), block(bj, bj), block(bi, bj), block(bj, bi)]
        self.rows = np.concatenate([r.ravel() for r, _ in rc])
        self.cols = np.concatenate([c.ravel() for _, c in rc])

    def assemble(self, joints: np.ndarray):
        """E, ``J^T r`` (4J,) and ``J^T J`` (sparse CSC, 4J x 4J) at ``joints``.

        Parameters
        ----------
        joints : (J, 4) float

        Returns
        -------
        E : float
        jtr : (4J,) float
            Half the gradient of E.
        H : scipy.sparse.csc_matrix
        """
        pr = self.pr
        i, j, d, rho, e = bone_terms(pr, joints)
        G = np.empty((len(e), 4))
        G[:, :3] = d
        G[:, 3] = rho
        E = float(np.dot(pr.weights * e, e))
        P = G[:, _IU[0]] * G[:, _IU[1]]                  # (n, 10)
        M = self.S3 @ P                                  # (3B, 10)
        G *= e[:, None]
        R = self.S2 @ G                                  # (2B, 4): per-bone sums for i and j
        B, J = len(pr.bones), self.n_joints
        jtr = np.zeros((J, 4))
        np.add.at(jtr, pr.bones[:, 0], R[:B])            # B-sized: tiny
        np.add.at(jtr, pr.bones[:, 1], R[B:])
        blocks = M[:, _FULL].reshape(3, B, 16)
        vals = np.concatenate([blocks[0].ravel(), blocks[1].ravel(), blocks[2].ravel(),
                               blocks[2].ravel()])
        H = sp.csc_matrix((vals, (self.rows, self.cols)), shape=(4 * J, 4 * J))
        return E, jtr.ravel(), H


def lm_steps(problem: FitProblem, *, max_iterations: int = 100, tolerance: float = 1e-3,
             refit_mapping: bool = False, mu0: float = 1e-3, mu_max: float = 1e12,
             stats: dict | None = None) -> Iterator[SolverState]:
    """Levenberg-Marquardt iterations, one accepted step (plus optional re-fit) per ``next()``.

    Parameters
    ----------
    problem : FitProblem
        Start point (never modified).
    max_iterations : int
        Upper bound on iterations (accepted steps).
    tolerance : float
        ``ftol = tolerance * 1e-2``: stop when an iteration lowers E by less than ``ftol * E``
        and the model predicted less than that too.
    refit_mapping : bool
        Re-fit sigma (:mod:`..refit`) after every accepted step.
    mu0, mu_max : float
        Initial damping (relative to ``diag(J^T J)``) and the damping at which we give up.
    stats : dict, optional
        Filled with ``"trials"`` (linear solves), ``"rejected"``, ``"refit_changed"``.

    Yields
    ------
    SolverState
        Iteration 0 (E0), then one per accepted step; the last has ``done=True``.
        E never increases.

    Examples
    --------
    >>> for state in lm_steps(pr, max_iterations=30):      # doctest: +SKIP
    ...     print(state.iteration, state.energy)
    """
    stats = {} if stats is None else stats
    stats.update(trials=0, rejected=0, refit_changed=0)
    pts, w, bones = problem.points, problem.weights, problem.bones
    joints = np.array(problem.joints, dtype=np.float64)
    bone = np.array(problem.bone, dtype=np.int64)
    t = np.array(problem.t, dtype=np.float64)
    J = len(joints)
    ftol = tolerance * 1e-2

    def view(Jt, b, tt):
        return FitProblem(pts, w, Jt, bones, b, tt)

    ne = NormalEquations(view(joints, bone, t))
    E, jtr, H = ne.assemble(joints)
    done = max_iterations <= 0 or not E > 0 or J == 0
    yield SolverState(0, joints, bone, t, E, done)
    if done:
        return
    neighbours = bone_neighbours(bones, J) if refit_mapping else None
    mu, nu = mu0, 2.0
    for k in range(1, max_iterations + 1):
        if k > 1:
            _, jtr, H = ne.assemble(joints)
        diag = H.diagonal()
        dmax = float(diag.max()) if diag.size else 0.0
        D = np.maximum(diag, 1e-12 * dmax if dmax > 0 else 1.0)
        accepted = False
        while mu <= mu_max:
            stats["trials"] += 1
            A = (H + sp.diags(mu * D, format="csc")).tocsc()
            h = splu(A).solve(-jtr)
            new = joints + h.reshape(J, 4)
            new[:, 3] = np.abs(new[:, 3])
            E_new = energy(view(joints, bone, t), new)
            pred = float(-h @ jtr + mu * (h * D) @ h)     # model decrease of E = |r|^2
            gain = (E - E_new) / pred if pred > 0 else -1.0
            if E_new < E and gain > 0:
                mu *= max(1.0 / 3.0, 1.0 - (2.0 * gain - 1.0) ** 3)
                nu = 2.0
                accepted = True
                break
            stats["rejected"] += 1
            mu *= nu
            nu *= 2.0
        if not accepted:
            yield SolverState(k, joints, bone, t, E, True)
            return
        E_prev = E
        joints, E = new, E_new
        if refit_mapping:
            bone_new, t_new, e, changed = _refit(view(joints, bone, t), neighbours)
            if changed:
                stats["refit_changed"] += changed
                bone, t = bone_new, t_new
                E = float(np.dot(w, e * e))
                ne = NormalEquations(view(joints, bone, t))
        done = ((E_prev - E) < ftol * E_prev and pred < ftol * E_prev) or k == max_iterations
        yield SolverState(k, joints, bone, t, E, done)
        if done:
            return
