"""Levenberg-Marquardt on the residuals ``r_v = sqrt(w_v) e_v`` (issue 5: a solver that converges).

Why: E is a sum of squares of residuals that each depend on only 8 unknowns (the two joints of
one bone), so the Gauss-Newton matrix ``J^T J`` is block-sparse with the skeleton's own sparsity
(4x4 blocks on the diagonal and for each bone) and a damped Gauss-Newton step costs one pass over
the vertices plus a tiny sparse solve. Gradient descent (the paper) needs hundreds of passes for
the same decrease because E is badly conditioned.

Assembly in one pass
--------------------
With ``G_v = (d_v, rho_v)`` (``d = v - sigma``), the Jacobian row of ``r_v`` has the 8 entries
``-2 sqrt(w) (t G, (1-t) G)`` on the joints (i, j) of the vertex's bone. Stack per vertex
``X_v = sqrt(w_v) (t G, (1-t) G, e)`` (9 values). For the vertices of bone ``b``, the 9x9 Gram
matrix ``X_b^T X_b`` holds, up to the factors 4 and -2, the bone's four 4x4 blocks of ``J^T J``
(ii, jj, ij, ji), its contributions to ``J^T r`` and its share of E. The solver keeps the
vertices sorted by bone, so each Gram matrix is one BLAS product on a contiguous slice: one pass
over the vertices per assembly, no (n x 64) intermediates, no scatter over the vertices. The B
blocks are then scattered into the (4J x 4J) sparse system, which SuperLU factorises in
milliseconds (its fill follows the skeleton graph, a tree or nearly).

Damping, exact line search and acceptance
-----------------------------------------
Marquardt's scaled damping ``(J^T J + mu diag(J^T J)) h = -J^T r`` (scale invariant, like
``x_scale='jac'``), ``mu`` adapted with Nielsen's rule from the gain ratio (actual over
predicted decrease) of the plain step ``lam = 1``. The step actually taken is ``lam* h`` with
``lam*`` the exact minimiser of ``E(joints + lam h)``, which is a quartic in ``lam`` (the same
closed form as the paper's line search, eq. 29, along the LM direction instead of the gradient).
E is far from quadratic (e.g. near joints of almost zero radius, or where vertices lie inside the
silhouette): without the line search plain LM stalled at large ``mu`` on some first
approximations (two capsules: E 0.084 after 100 iterations, against 4e-9 with it). A step is
accepted only if E decreases, so E never increases. Negative radii are flipped when that keeps
the decrease (r enters squared, as in the paper), otherwise the line search is restricted to
radii >= 0.

Stopping
--------
After an accepted iteration (step plus optional re-fit): stop when it lowered E by less than
``ftol * E`` *and* the gradient is small: ``jtr^T diag(J^T J)^-1 jtr < ftol * E`` (the decrease
a Newton step on the diagonal would promise; the step just taken may have been small only
because it was heavily damped, and the undamped Gauss-Newton step is unbounded along the nearly
flat directions of E, e.g. joints sliding along a straight tube); or when E has fallen below
``ftol^2 * E0`` (an exact fit: relative decreases stay large all the way to 0), with
``ftol = tolerance / 10`` (the default ``tolerance = 1e-3`` stops at a relative change of 1e-4,
which on our test problems leaves E within 1e-5 of a tight ``scipy.optimize.least_squares``
optimum; with re-fitting the mapping keeps improving E by ever smaller amounts, and this rule
stops that tail); or when no damping up to ``mu_max`` gives a decrease; or after
``max_iterations``.
Regularisation (opt-in)
-----------------------
With ``problem.meta["regularisation"] = {"smoothness": s, "containment": c, "surface": (V, F)}``
and ``s > 0`` or ``c > 0`` (the pipeline sets it from :class:`..params.SkeletonParams`), extra
least-squares residuals join the data residuals (:class:`_Regulariser`):

* containment, per joint ``j = (x, r)`` and per sample along every bone (``BONE_SAMPLES``,
  ``x, r`` interpolated; a bone's samples together weigh ``BONE_SAMPLE_WEIGHT`` joints):
  ``sqrt(c S w_s) max(0, r - d(x))`` with ``d`` the signed
  distance to the surface, positive inside (unsigned distance to the surface points, vertices and
  face centroids, from one KD-tree built once per solve, with normals: area-weighted vertex
  normals and face normals; ``d`` is smoothed over the nearest points, see
  :meth:`_Regulariser._containment`). The ball must lie inside the
  mesh, at the joints and along the bones (joints alone let a straight bone between two inside
  joints cut a corner: on horse, homer and fertility that alone kept 2-4 % of the bone points
  outside). Without it a joint that few vertices map to can run away: a big sphere fits a small
  nearly flat patch, and E keeps falling while the joint leaves the mesh. Linearised at every
  assembly: gradient ``-grad d(x)`` in x (about ``+n``, the outward normal of the nearest
  surface point; exact, the blending weights included) and +1 in r.
* smoothness, per joint of degree 2 with neighbours a, b: ``sqrt(s S) (x_j - (x_a + x_b) / 2)``
  (3 linear residuals): straightens chains, removes hairpins and zig-zags.

``S = E0 / (J median(r0)^2)`` (E0, r0: data energy and radii at the start) makes the weights
relative to E: a violation of one median radius at every joint costs ``c E0``. The solver
minimises the total ``E + R`` and is monotone in it (steps and the stopping rules use the
total; the line search minimises the data quartic plus the regulariser's linearised quadratic
along the direction, and a step is accepted only if the true total falls; if that line-search
step fails, the plain damped step ``lam = 1`` is tried before raising mu, because the
linearised model can otherwise undo the damping). ``SolverState.energy`` reports the data term
E alone, so it may rise slightly when the regulariser pulls a joint back. With both weights 0
nothing changes (the pipeline's defaults are containment 1, smoothness 0: containment was
better on all six reference meshes, smoothness not clearly better).
"""

from __future__ import annotations

from typing import Iterator

import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree
from scipy.sparse.linalg import splu

from ..energy import bone_to_joints, line_residuals, quartic_from_residuals, sigma_terms
from ..medial import surface_points
from ..line_search import minimize_quartic, minimize_quartic_on
from ..problem import FitProblem, SolverState
from ..refit import bone_neighbours, refit_mapping as _refit
from .paper import radius_interval

__all__ = ["lm_steps", "NormalEquations"]


class NormalEquations:
    """Gauss-Newton system of E for one fixed mapping, vertices sorted by bone.

    Parameters
    ----------
    pr : FitProblem
        Points, weights, bones and mapping, with ``pr.bone`` sorted (non-decreasing).

    Examples
    --------
    >>> ne = NormalEquations(pr_sorted)                  # doctest: +SKIP
    >>> E, jtr, H = ne.assemble(pr_sorted.joints)        # doctest: +SKIP
    >>> H.shape == (4 * len(pr_sorted.joints),) * 2      # doctest: +SKIP
    True
    """

    def __init__(self, pr: FitProblem):
        self.pr = pr
        B, J = len(pr.bones), len(pr.joints)
        self.n_joints = J
        self.starts = np.searchsorted(pr.bone, np.arange(B + 1))
        sw = np.sqrt(pr.weights)
        self.a = sw * pr.t                # sqrt(w) t
        self.b = sw - self.a              # sqrt(w) (1 - t)
        self.sw = sw
        self.X = np.empty((9, len(pr.points)))      # rows: sqrt(w) (t G, (1-t) G, e)
        self.busy = np.flatnonzero(np.diff(self.starts) > 0)     # bones with vertices
        # (row, col) of each bone's four 4x4 blocks in the (4J x 4J) matrix: ii, jj, ij, ji.
        bi, bj = pr.bones[self.busy, 0], pr.bones[self.busy, 1]
        k = np.arange(4)
        def block(r, c):
            rr = np.broadcast_to((4 * r)[:, None, None] + k[None, :, None], (len(r), 4, 4))
            cc = np.broadcast_to((4 * c)[:, None, None] + k[None, None, :], (len(r), 4, 4))
            return rr.ravel(), cc.ravel()
        rc = [block(bi, bi), block(bj, bj), block(bi, bj), block(bj, bi)]
        self.rows = np.concatenate([r for r, _ in rc])
        self.cols = np.concatenate([c for _, c in rc])

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
        pr, X = self.pr, self.X
        d, rho, e = self.terms = sigma_terms(pr, joints)      # kept for the line search
        np.multiply(d, self.a, out=X[0:3])
        np.multiply(rho, self.a, out=X[3])
        np.multiply(d, self.b, out=X[4:7])
        np.multiply(rho, self.b, out=X[7])
        np.multiply(e, self.sw, out=X[8])
        st = self.starts
        M = np.empty((len(self.busy), 9, 9))
        for m, b in enumerate(self.busy):
            Xb = X[:, st[b]:st[b + 1]]
            np.dot(Xb, Xb.T, out=M[m])
        E = float(M[:, 8, 8].sum())
        busy_bones = pr.bones[self.busy]
        jtr = bone_to_joints(busy_bones, -2.0 * M[:, 0:4, 8], -2.0 * M[:, 4:8, 8], self.n_joints)
        vals = 4.0 * np.concatenate([M[:, 0:4, 0:4].ravel(), M[:, 4:8, 4:8].ravel(),
                                     M[:, 0:4, 4:8].ravel(), M[:, 4:8, 0:4].ravel()])
        J4 = 4 * self.n_joints
        H = sp.csc_matrix((vals, (self.rows, self.cols)), shape=(J4, J4))
        return E, jtr.ravel(), H


class _Sorted:
    """The problem's per-vertex arrays sorted by bone, and the way back to the input order."""

    def __init__(self, problem: FitProblem, bone: np.ndarray, t: np.ndarray, order=None):
        if order is None:
            order = np.argsort(bone, kind="stable")
        self.order = order
        self.pr = FitProblem(problem.points[order], problem.weights[order], problem.joints,
                             problem.bones, bone[order], t[order])

    def resorted(self, problem: FitProblem, bone_s: np.ndarray, t_s: np.ndarray) -> "_Sorted":
        """After a re-fit changed the (sorted-order) mapping: sort again (nearly sorted: fast)."""
        o2 = np.argsort(bone_s, kind="stable")
        new = object.__new__(_Sorted)
        new.order = self.order[o2]
        p = self.pr
        new.pr = FitProblem(p.points[o2], p.weights[o2], p.joints, p.bones, bone_s[o2], t_s[o2])
        return new

    def mapping(self) -> tuple[np.ndarray, np.ndarray]:
        """(bone, t) in the input vertex order."""
        bone = np.empty_like(self.pr.bone)
        t = np.empty_like(self.pr.t)
        bone[self.order] = self.pr.bone
        t[self.order] = self.pr.t
        return bone, t


def blended_signed_distance(x, pts, nrm, tree, K, h2):
    """A smooth signed distance to the surface, positive inside, and its gradient.

    A weighted mean over the K nearest surface points p_i of their plane distances
    ``-n_i . (x - p_i)``, weights ``a_i f_i / (|x - p_i|^2 + h^2)`` (h^2 = ``h2``: the median
    spacing of the surface points, squared). The plain distance to the point set is a min of
    cones, whose kinks stalled LM (no damping gave a descent); the planes of neighbouring points
    nearly agree, so this ``d`` is smooth at the scale of the mesh.

    - ``a_i = max(n_i . m, 0)^2``: only the surface on the near side counts (across a part
      thinner than the blending radius, a tentacle, the planes of the far side would say "inside"
      just outside); m is the normals' mean weighted by ``f_i / (|x - p_i|^2 + h^2)^2``, which
      the nearest points dominate and which, unlike the nearest point's own normal, does not
      jump when the nearest point changes under rounding (homer rotated: 1.8e-3 -> 3e-6 D);
    - ``f_i = (1 - (|x - p_i| / |x - p_{K+1}|)^2)^2`` fades each weight to 0 at the (K+1)-th
      neighbour's distance, so a swap of the K-th and (K+1)-th neighbours (a tie under rounding:
      a rotated mesh) is no jump in d (issue 12: armadillo rotated, 1.2e-2 -> 9.8e-4 D).

    The gradient differentiates the distance weights; ``a`` and ``f`` are taken as locally fixed.

    Parameters
    ----------
    x : (S, 3) float
    pts, nrm : (P, 3) float   surface points and unit outward normals
    tree : cKDTree of ``pts``
    K : int
    h2 : float

    Returns
    -------
    d : (S,) float
    grad_d : (S, 3) float
    """
    k = min(K + 1, len(pts))
    # every core (the same neighbours): the samples lie on the curve, nearly equidistant from a
    # band of the surface, so even ~100 queries take a millisecond or two (torus-100k: 37 calls)
    dist, idx = tree.query(x, k=k, workers=-1)
    dist, idx = dist.reshape(len(x), k), idx.reshape(len(x), k)
    if k > 1:
        far = dist[:, -1:]
        fade = np.clip(1.0 - (dist[:, :-1] / np.maximum(far, 1e-300)) ** 2, 0.0, 1.0) ** 2
        dist, idx = dist[:, :-1], idx[:, :-1]
    else:
        fade = np.ones_like(dist)
    diff = x[:, None, :] - pts[idx]                           # (S, k, 3)
    n = nrm[idx]
    sd = -np.einsum("jki,jki->jk", diff, n)                   # plane distances, + inside
    q = 1.0 / (dist * dist + h2)
    ref = np.einsum("jk,jki->ji", fade * q * q, n)           # the near side's normal, smooth in x
    rn = np.linalg.norm(ref, axis=1, keepdims=True)
    ref = np.where(rn > 0, ref / np.where(rn > 0, rn, 1.0), n[:, 0])
    a = np.clip(np.einsum("jki,ji->jk", n, ref), 0.0, 1.0) ** 2
    w = a * fade * q
    # A sample whose nearest surface point has a zero normal (a vertex whose face normals
    # cancel) would have no weight: it takes the nearest point alone, with weight 1.
    lone = ~(w.sum(axis=1) > 0)
    if lone.any():
        w[lone, 0] = 1.0
    W = w.sum(axis=1)
    d = (w * sd).sum(axis=1) / W
    dw = -2.0 * (w * q)[:, :, None] * diff                     # dw_i/dx (a, f: locally fixed)
    grad_d = ((w[:, :, None] * -n).sum(axis=1)
              + ((sd - d[:, None])[:, :, None] * dw).sum(axis=1)) / W[:, None]
    return d, grad_d


class _Regulariser:
    """Containment and smoothness residuals (see the module docstring), built once per solve.

    ``active`` is False when both weights are 0 or there is nothing to regularise; then the
    solver never calls it.
    """

    K = 8      # nearest surface points blended into the signed distance
    MAX_SURFACE_POINTS = 20000

    def __init__(self, problem: FitProblem, joints: np.ndarray, E0: float):
        cfg = (getattr(problem, "meta", None) or {}).get("regularisation") or {}
        c = float(cfg.get("containment", 0.0) or 0.0)
        s = float(cfg.get("smoothness", 0.0) or 0.0)
        surface = cfg.get("surface")
        J = len(joints)
        self.n_joints = J
        self.kc = self.ks = 0.0
        self.active = False
        self._memo = None
        if J == 0 or not (c > 0 or s > 0 or float(cfg.get("anchor", 0.0) or 0.0) > 0) or not E0 > 0:
            return
        r = joints[:, 3]
        pos = r[r > 0]
        med = float(np.median(pos)) if pos.size else 0.0
        if not med > 0:
            ext = np.ptp(problem.points, axis=0) if len(problem.points) else np.ones(3)
            med = max(float(np.linalg.norm(ext)) * 1e-2, 1e-12)
        S = E0 / (J * med * med)
        if c > 0 and surface is not None and len(surface[1]) > 0:
            pts, nrm = surface_points(surface[0], surface[1])
            if len(pts) > self.MAX_SURFACE_POINTS:
                # k-NN queries from a joint equidistant to much of the surface (a cap centre)
                # visit every such point: a fixed-size subset bounds the cost. Every m-th point
                # by distance from the centroid: the same points whatever their numbering,
                # position, rotation or scale (issue 12).
                rel = pts - pts.mean(axis=0)
                r2 = np.einsum("ij,ij->i", rel, rel)
                del rel
                order = np.argsort(r2, kind="stable")
                keep = order[np.linspace(0, len(pts) - 1, self.MAX_SURFACE_POINTS).astype(np.int64)]
                pts, nrm = pts[keep], nrm[keep]
            self.pts, self.nrm = pts, nrm
            # leaves of 64: the samples lie on the curve, nearly equidistant from a band of the
            # surface, and bigger leaves mean fewer cells visited (as medial.MedialBalls; the same
            # neighbours, 1.8x faster on the 100k torus)
            self.tree = cKDTree(pts, leafsize=64)
            sp2 = self.tree.query(pts, k=2, workers=-1)[0][:, 1]     # every core: same result
            self.h2 = max(float(np.median(sp2)) ** 2, 1e-300)
            self.kc = c * S
            u = np.asarray(cfg.get("bone_samples", BONE_SAMPLES), dtype=np.float64)
            bw = float(cfg.get("bone_sample_weight", BONE_SAMPLE_WEIGHT))
            self.W, self.sw = _sample_matrix(np.asarray(problem.bones, np.int64).reshape(-1, 2),
                                             J, u, bw)
        if s > 0:
            bones = np.asarray(problem.bones, dtype=np.int64).reshape(-1, 2)
            deg = np.bincount(bones.ravel(), minlength=J)
            mids = np.flatnonzero(deg == 2)
            if mids.size:
                nb = [[] for _ in range(J)]
                for a, b in bones:
                    nb[a].append(b)
                    nb[b].append(a)
                rows, cols, vals = [], [], []
                for m, j in enumerate(mids):
                    a, b = nb[j]
                    for k in range(3):
                        rows += [3 * m + k] * 3
                        cols += [4 * j + k, 4 * a + k, 4 * b + k]
                        vals += [1.0, -0.5, -0.5]
                self.L = sp.csr_matrix((vals, (rows, cols)), shape=(3 * len(mids), 4 * J))
                self.ks = s * S
                self.LtL = (self.ks * (self.L.T @ self.L)).tocsc()
        # anchor: joints held towards given positions (the centred curve), sqrt(ka) (x - a)
        self.ka = 0.0
        an = float(cfg.get("anchor", 0.0) or 0.0)
        apts = cfg.get("anchor_points")
        if an > 0 and apts is not None and len(apts) == J:
            self.ka = an * S
            self.apts = np.asarray(apts, np.float64)[:, :3]
            self.amask = np.zeros((J, 4))
            self.amask[:, :3] = 1.0
            self.AtA = sp.diags(self.ka * self.amask.ravel()).tocsc()
        self.active = self.kc > 0 or self.ks > 0 or self.ka > 0

    def _containment(self, joints):
        """Violation ``g = r - d(x)`` (S,) at every containment sample (joints and points along
        the bones, ``x, r`` interpolated linearly), and its gradient in the sample (S, 4).

        ``d``: :func:`blended_signed_distance`.
        """
        key = joints.tobytes()
        if self._memo is not None and self._memo[0] == key:
            # The step just accepted was evaluated as a trial: the next assembly asks again.
            return self._memo[1]
        X = self.W @ joints
        d, grad_d = blended_signed_distance(X[:, :3], self.pts, self.nrm, self.tree, self.K, self.h2)
        g = X[:, 3] - d
        grad = np.empty((len(X), 4))
        grad[:, :3] = -grad_d
        grad[:, 3] = 1.0
        self._memo = (key, (g, grad))
        return g, grad

    def value(self, joints) -> float:
        """R(joints): the regulariser's share of the total objective."""
        R = 0.0
        if self.kc > 0:
            g = np.maximum(self._containment(joints)[0], 0.0)
            R += self.kc * float(self.sw @ (g * g))
        if self.ks > 0:
            v = self.L @ joints.ravel()
            R += self.ks * float(v @ v)
        if self.ka > 0:
            v = joints[:, :3] - self.apts
            R += self.ka * float(np.sum(v * v))
        return R

    def add(self, joints, jtr, H):
        """R, and ``jtr``, ``H`` with the regulariser's Gauss-Newton terms added."""
        R = 0.0
        jtr = jtr.copy()
        z = joints.ravel()
        self._lin = None
        if self.kc > 0:
            g, grad = self._containment(joints)
            on = np.flatnonzero(g > 0)
            if on.size:
                # Jacobian of the active residuals sqrt(w_s) g_s in the joints: the sample's
                # gradient spread over its bone's joints by the interpolation weights.
                Ws = self.W[on].tocoo()
                jac = sp.csr_matrix(((Ws.data[:, None] * grad[on][Ws.row]).ravel(),
                                     (np.repeat(Ws.row, 4),
                                      (4 * Ws.col[:, None] + np.arange(4)).ravel())),
                                    shape=(on.size, H.shape[0]))
                sw = self.sw[on]
                self._lin = (g[on], jac, sw)
                R += self.kc * float(sw @ (g[on] * g[on]))
                jtr += self.kc * (jac.T @ (sw * g[on]))
                H = H + self.kc * (jac.T @ sp.diags(sw) @ jac)
        if self.ks > 0:
            v = self.L @ z
            R += self.ks * float(v @ v)
            jtr += self.ks * (self.L.T @ v)
            H = H + self.LtL
        if self.ka > 0:
            v = (joints[:, :3] - self.apts)
            R += self.ka * float(np.sum(v * v))
            g = np.zeros_like(joints)
            g[:, :3] = v
            jtr += self.ka * g.ravel()
            H = H + self.AtA
        return R, jtr, H.tocsc()

    def line_quadratic(self, joints, h) -> np.ndarray:
        """c0..c4 (c3 = c4 = 0) of the linearised R(joints + lam h) (from the last ``add``)."""
        q = np.zeros(5)
        if self.kc > 0 and self._lin is not None:
            g, jac, sw = self._lin
            gh = jac @ h.ravel()
            q[:3] += self.kc * np.array([sw @ (g * g), 2.0 * sw @ (g * gh), sw @ (gh * gh)])
        if self.ks > 0:
            v0, v1 = self.L @ joints.ravel(), self.L @ h.ravel()
            q[:3] += self.ks * np.array([v0 @ v0, 2.0 * v0 @ v1, v1 @ v1])
        if self.ka > 0:
            v0 = (joints[:, :3] - self.apts).ravel()
            v1 = h.reshape(-1, 4)[:, :3].ravel()
            q[:3] += self.ka * np.array([v0 @ v0, 2.0 * v0 @ v1, v1 @ v1])
        return q


#: With regularisation: iterations over which the total must fall by ``tolerance`` (relative).
STALL_WINDOW = 5
#: Containment samples along every bone (besides its joints), as the bone parameter u in (0, 1).
BONE_SAMPLES = (0.25, 0.5, 0.75)
#: Weight of a bone's samples together, relative to one joint.
BONE_SAMPLE_WEIGHT = 1.0


def _sample_matrix(bones, n_joints, u, bone_weight):
    """Sparse (S, J) interpolation matrix of the containment samples and their weights (S,).

    Rows: every joint (weight 1), then for every bone and every ``u`` the point
    ``(1 - u) x_i + u x_j`` with its radius interpolated alike (weight ``bone_weight / len(u)``:
    each bone counts ``bone_weight`` times one joint).
    """
    J, Bn, k = n_joints, len(bones), len(u)
    rows = [np.arange(J)]
    cols = [np.arange(J)]
    vals = [np.ones(J)]
    if Bn and k and bone_weight > 0:
        r = J + np.arange(Bn * k)
        rows += [r, r]
        cols += [np.repeat(bones[:, 0], k), np.repeat(bones[:, 1], k)]
        uu = np.tile(u, Bn)
        vals += [1.0 - uu, uu]
        S = J + Bn * k
        sw = np.concatenate([np.ones(J), np.full(Bn * k, bone_weight / k)])
    else:
        S, sw = J, np.ones(J)
    W = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                      shape=(S, J))
    return W, sw


def lm_steps(problem: FitProblem, *, max_iterations: int = 100, tolerance: float = 1e-3,
             refit_mapping: bool = False, mu0: float = 1e-3, mu_max: float = 1e12,
             line_search: bool = True, stats: dict | None = None) -> Iterator[SolverState]:
    """Levenberg-Marquardt iterations, one accepted step (plus optional re-fit) per ``next()``.

    Parameters
    ----------
    problem : FitProblem
        Start point (never modified).
    max_iterations : int
        Upper bound on iterations (accepted steps).
    tolerance : float
        ``ftol = tolerance / 10``: stop when an iteration lowers E by less than ``ftol * E``
        and ``jtr^T diag(J^T J)^-1 jtr`` (a scale-invariant gradient size) is below that too.
    refit_mapping : bool
        Re-fit sigma (:mod:`..refit`) after every accepted step.
    mu0, mu_max : float
        Initial damping (relative to ``diag(J^T J)``) and the damping at which we give up.
    line_search : bool
        Take the exact minimiser of E along each LM direction (default) instead of the plain
        step ``lam = 1`` (kept for comparisons).
    stats : dict, optional
        Filled with ``"trials"`` (linear solves), ``"rejected"``, ``"line_search"`` (accepted
        steps whose exact line search moved ``lam`` away from 1), ``"refit_changed"``.

    Yields
    ------
    SolverState
        Iteration 0 (E0), then one per accepted step; the last has ``done=True``.
        ``energy`` is the data term E; E never increases without regularisation (with it the
        total ``E + R`` never increases, see the module docstring).

    Examples
    --------
    >>> for state in lm_steps(pr, max_iterations=30):      # doctest: +SKIP
    ...     print(state.iteration, state.energy)
    """
    stats = {} if stats is None else stats
    stats.update(trials=0, rejected=0, line_search=0, refit_changed=0)
    joints = np.array(problem.joints, dtype=np.float64)
    bone = np.array(problem.bone, dtype=np.int64)
    t = np.array(problem.t, dtype=np.float64)
    J = len(joints)
    ftol = tolerance * 0.1
    srt = _Sorted(problem, bone, t)                  # vertices sorted by bone (internal only)
    ne = NormalEquations(srt.pr)
    E, jtr, H = ne.assemble(joints)
    E0 = E
    history: list[float] = [E0]                  # data energy per accepted iteration
    reg = _Regulariser(problem, joints, E0)
    R = 0.0
    if reg.active:
        R, jtr, H = reg.add(joints, jtr, H)
    Ft = E + R                           # the objective minimised: data E plus regulariser R
    F0 = Ft
    done = max_iterations <= 0 or not E > 0 or J == 0
    yield SolverState(0, joints, bone, t, E, done)
    if done:
        return
    neighbours = bone_neighbours(problem.bones, J) if refit_mapping else None
    mu, nu = mu0, 2.0
    for k in range(1, max_iterations + 1):
        D = _damping_scale(H)
        accepted = False
        while mu <= mu_max:
            stats["trials"] += 1
            h = _solve(H, D, mu, jtr)
            # E(joints + lam h) is a quartic in lam: take its exact minimiser (lam = 1 is the plain
            # LM step), so the step is never worse than LM's and can cross ridges it cannot.
            A, B, C = line_residuals(srt.pr, -h.reshape(J, 4), joints, ne.terms)
            c = quartic_from_residuals(srt.pr.weights, A, B, C)
            if reg.active:                # plus the regulariser's (linearised) quadratic
                c = c + reg.line_quadratic(joints, h.reshape(J, 4))
            lam = minimize_quartic(c) if line_search else 1.0
            new = joints + lam * h.reshape(J, 4)
            if np.any(new[:, 3] < 0):
                new, lam, e_new = _nonnegative_radii(srt.pr, joints, h.reshape(J, 4), c, lam,
                                                     new, Ft, reg if reg.active else None)
            else:
                e_new = A + lam * (B + lam * C)          # exact: e is quadratic along the line
            E_new = float(np.dot(srt.pr.weights * e_new, e_new))
            R_new = reg.value(new) if reg.active else 0.0
            if reg.active and not E_new + R_new < Ft and lam != 1.0:
                # The regulariser is only linearised in the line search (and absent for joints
                # not yet violating it): its minimiser can undo the damping by jumping far along
                # h. Fall back to the plain damped step before raising mu.
                new1 = joints + h.reshape(J, 4)
                if not np.any(new1[:, 3] < 0):
                    e1 = A + B + C
                    E1 = float(np.dot(srt.pr.weights * e1, e1))
                    R1 = reg.value(new1)
                    if E1 + R1 < Ft:
                        new, lam, e_new, E_new, R_new = new1, 1.0, e1, E1, R1
            # Nielsen's update from the quality of the Gauss-Newton model at lam = 1.
            pred = float(-h @ jtr + mu * (h * D) @ h)     # model decrease of E = |r|^2 at lam = 1
            gain = (Ft - float(np.sum(c))) / pred if pred > 0 else -1.0
            if E_new + R_new < Ft:
                stats["line_search"] += int(abs(lam - 1.0) > 1e-3)
                if gain > 0:
                    mu *= max(1.0 / 3.0, 1.0 - (2.0 * gain - 1.0) ** 3)
                else:
                    mu *= 2.0                   # model poor, but the line search made progress
                nu = 2.0
                accepted = True
                break
            stats["rejected"] += 1
            mu *= nu
            nu *= 2.0
        if not accepted:
            yield SolverState(k, joints, bone, t, E, True)
            return
        F_prev = Ft
        joints, E, R = new, E_new, R_new
        if refit_mapping:
            cur = srt.pr
            bone_s, t_s, e, changed = _refit(FitProblem(cur.points, cur.weights, joints, cur.bones,
                                                        cur.bone, cur.t), neighbours, e_old=e_new)
            if changed:
                stats["refit_changed"] += changed
                E = float(np.dot(cur.weights, e * e))
                srt = srt.resorted(problem, bone_s, t_s)
                bone, t = srt.mapping()
                ne = NormalEquations(srt.pr)
        Ft = E + R                        # the re-fit lowers E only; R does not see the mapping
        done = k == max_iterations or Ft <= ftol * ftol * F0      # max, or an exact fit
        history.append(E)
        if reg.active and not done and len(history) > STALL_WINDOW:
            # The containment term is only piecewise smooth, so the gradient test below may
            # never pass near its kinks: stop, as the paper's eq. 30 does, when the data energy
            # fell by less than tolerance * E0 over the last STALL_WINDOW iterations.
            done = (history[-STALL_WINDOW - 1] - E) < tolerance * history[0]
        if not done and (F_prev - Ft) < ftol * F_prev:
            # Small decrease: stop only if the gradient is small too, measured as the decrease a
            # Newton step on the diagonal of J^T J would promise, jtr^T diag(J^T J)^-1 jtr (scale
            # invariant; a heavily damped step being small proves nothing, and the undamped
            # Gauss-Newton step is unbounded along the nearly flat directions of E).
            _, jtr, H = ne.assemble(joints)
            if reg.active:
                _, jtr, H = reg.add(joints, jtr, H)
            done = float(jtr @ (jtr / _damping_scale(H))) < ftol * Ft
            fresh = True
        else:
            fresh = False
        yield SolverState(k, joints, bone, t, E, done)
        if done:
            return
        if not fresh:
            _, jtr, H = ne.assemble(joints)
            if reg.active:
                _, jtr, H = reg.add(joints, jtr, H)


def _nonnegative_radii(pr, joints, h, c, lam, new, E, reg=None):
    """Radii went negative along the step: flip them (r enters squared, as in the paper) if that
    keeps the objective (E, plus R when ``reg`` is given) below ``E``; otherwise restrict ``lam``
    to where every radius stays >= 0. Returns (joints, lam, e at those joints)."""
    flipped = new.copy()
    flipped[:, 3] = np.abs(flipped[:, 3])
    e = sigma_terms(pr, flipped)[2]
    if float(np.dot(pr.weights * e, e)) + (reg.value(flipped) if reg is not None else 0.0) < E:
        return flipped, lam, e
    lo, hi = radius_interval(joints[:, 3], -h[:, 3])
    lam = minimize_quartic_on(c, lo, hi)
    new = joints + lam * h
    new[:, 3] = np.maximum(new[:, 3], 0.0)
    return new, lam, sigma_terms(pr, new)[2]


def _damping_scale(H) -> np.ndarray:
    """Marquardt's scaling diag(J^T J), floored so unobserved unknowns stay regular; the unknowns
    are (x, y, z, r) per joint and a joint's three position entries share their mean (a third of
    the trace of its 3x3 block).

    Why shared: diag(J^T J) of a position block depends on the orientation of the axes, so the
    damped step did too; a rotated mesh took another first step (3holes rotated: the same E0 to
    5e-15, the first step's E 3.6e-5 apart, the skeleton 1.6e-3 D apart; issue 12). The trace is
    the same in any orientation, and a joint is damped alike in every direction.
    """
    diag = H.diagonal()
    if diag.size % 4 == 0:
        d4 = diag.reshape(-1, 4).copy()
        d4[:, :3] = d4[:, :3].mean(axis=1, keepdims=True)
        diag = d4.ravel()
    dmax = float(diag.max()) if diag.size else 0.0
    return np.maximum(diag, 1e-12 * dmax if dmax > 0 else 1.0)


def _solve(H, D, mu, rhs) -> np.ndarray:
    """Solve ``(H + mu diag(D)) h = -rhs`` by sparse LU (SuperLU)."""
    A = (H + sp.diags(mu * D, format="csc")).tocsc()
    return splu(A).solve(-rhs)
