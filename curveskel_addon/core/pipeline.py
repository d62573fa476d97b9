"""skeletonize(): the stages of the method in order, timed, one component at a time.

mesh arrays -> clean_mesh -> components -> first_approximation (per component)
            -> one joint FitProblem -> solver steps -> Skeleton in input vertex order
"""

from __future__ import annotations

import time
from contextlib import contextmanager
from typing import Callable, Iterator

import numpy as np
from scipy.spatial import cKDTree

from .candidates import best_of_candidates
from .collapse import collapse_short_bones
from .energy import energy
from .errors import CurveSkelError
from .mesh_graph import components
from .mapping import closest_on_bones
from .mesh_input import clean_mesh
from .params import SkeletonParams, check_params
from .postprocess import postprocess, unfold_chains
from .problem import FitProblem, SolverState
from .reeb import first_approximation
from .refine import refine
from .refit import bone_neighbours
from .skeleton import Skeleton
from .solvers import solve_steps
from .vertex_area import vertex_areas

__all__ = ["skeletonize", "SkeletonRun"]

Progress = Callable[[str, float], None]

#: Bones not longer than this fraction of the bounding-box diagonal are contracted at the end.
COLLAPSE_RADIUS = 0.02   # ... or than this fraction of the smaller end radius
#: Solver iterations after each refinement round (the split is local: the rest is converged).
REFINE_ITERATIONS = 20
#: Above this many faces the refinement is skipped (see ``_refine``).
REFINE_MAX_FACES = 500_000
COLLAPSE_TOL = 1e-4   # 0.01 % of the size: invisible, and the solver leaves such pairs only ~1e-6 apart


class SkeletonRun:
    """One skeletonization, exposed stage by stage so a UI can step the solver and stop it.

    Examples
    --------
    >>> run = SkeletonRun(V, F, SkeletonParams())          # doctest: +SKIP
    >>> for state in run.steps():                          # doctest: +SKIP
    ...     draw(run.current_skeleton())                   # live preview
    >>> sk = run.result()                                  # doctest: +SKIP
    """

    def __init__(self, V, F, params: SkeletonParams | None = None, progress: Progress | None = None):
        self.params = SkeletonParams() if params is None else params
        if not isinstance(self.params, SkeletonParams):
            raise CurveSkelError(f"params must be a SkeletonParams, got {type(self.params).__name__}")
        check_params(self.params)   # again: fields may have been assigned after construction
        self.progress = progress or (lambda stage, fraction: None)
        self.timings: dict[str, float] = {}
        with self._timed("clean"):
            self.mesh = clean_mesh(V, F, min_component_area=self.params.min_component_area)
            self._input_V = np.asarray(V, dtype=np.float64)
        with self._timed("components"):
            # clean_mesh found them already (None: compute them here)
            self.n_components, self.labels = (self.mesh.components
                                              or components(len(self.mesh.V), self.mesh.F))
        self.problem = self._first_approximation()
        self.energy: list[float] = []
        self._state: SolverState | None = None
        self.postprocess_log: dict | None = None
        self.collapsed: int | None = None
        self.refine_log: dict | None = None

    # -- stages --------------------------------------------------------------------------------
    @contextmanager
    def _timed(self, stage: str):
        t0 = time.perf_counter()
        yield
        self.timings[stage] = self.timings.get(stage, 0.0) + time.perf_counter() - t0

    def _first_approximation(self) -> FitProblem:
        V, F, p = self.mesh.V, self.mesh.F, self.params
        face_label = self.labels[F[:, 0]]
        joints, bones, bone, t = [], [], np.empty(len(V), np.int64), np.empty(len(V))
        comp_meta = []
        nj = nb = 0
        order = np.argsort(self.labels, kind="stable")
        starts = np.searchsorted(self.labels[order], np.arange(self.n_components + 1))
        forder = np.argsort(face_label, kind="stable")
        fstarts = np.searchsorted(face_label[forder], np.arange(self.n_components + 1))
        local = np.empty(len(V), np.int64)
        for c in range(self.n_components):
            vids = order[starts[c]:starts[c + 1]]
            local[vids] = np.arange(len(vids))
            Fc = local[F[forder[fstarts[c]:fstarts[c + 1]]]]
            # Several candidates cost several full first approximations and short solves; on a
            # component larger than the fit subset one candidate is used (recorded in meta).
            if p.candidates > 1 and (not p.max_fit_points or len(vids) <= p.max_fit_points):
                with self._timed("candidates"):
                    fa = best_of_candidates(V[vids], Fc, p, seed=p.seed + c)
            else:
                fa = first_approximation(V[vids], Fc, spacing=p.spacing, seed=p.seed + c)
            for stage, sec in fa.meta.get("timings", {}).items():
                self.timings[stage] = self.timings.get(stage, 0.0) + sec
            joints.append(fa.joints)
            bones.append(fa.bones + nj)
            bone[vids] = fa.bone + nb
            t[vids] = fa.t
            nj += len(fa.joints)
            nb += len(fa.bones)
            comp_meta.append({k: v for k, v in fa.meta.items() if k != "timings"}
                             | {"vertices": int(len(vids)), "joints": int(len(fa.joints)),
                                "bones": int(len(fa.bones))})
            self.progress("first_approximation", (c + 1) / self.n_components)
        with self._timed("weights"):
            w = vertex_areas(V, F) if p.area_weighted else np.ones(len(V))
            if p.area_weighted:
                w = w * (len(V) / max(w.sum(), 1e-300))   # mean weight 1: E stays on the vertex-sum scale
        self.component_meta = comp_meta
        pr = FitProblem(V, w, np.concatenate(joints), np.concatenate(bones), bone, t)
        # Regularisation settings travel with the problem (the "lm" solver reads them).
        pr.meta["regularisation"] = {"smoothness": float(p.smoothness),
                                     "containment": float(p.containment), "surface": (V, F)}
        self.fit_subset = None
        if p.area_weighted and p.max_fit_points and len(V) > p.max_fit_points:
            with self._timed("weights"):
                pr = self._subsample(pr, p.max_fit_points)
        return pr

    def _subsample(self, pr: FitProblem, k: int) -> FitProblem:
        """Fit k random vertices instead of all of them.

        With area weights E is a quadrature of the surface integral (eq. 8); a uniform random
        subset with weights scaled by n/k is an unbiased quadrature of the same integral, so the
        solver's cost stops growing with the mesh while the skeleton stays that of the surface.
        Every vertex is mapped onto the final skeleton in :meth:`_full_mapping`.
        """
        n = len(pr.points)
        rng = np.random.default_rng(self.params.seed)
        idx = np.sort(rng.choice(n, size=k, replace=False))
        self.fit_subset = idx
        sub = FitProblem(pr.points[idx], pr.weights[idx] * (n / k), pr.joints, pr.bones,
                         pr.bone[idx], pr.t[idx], dict(pr.meta))
        return sub

    def _full_mapping(self, joints, bones, bone_sub) -> tuple[np.ndarray, np.ndarray]:
        """Map every working vertex: the bone of its nearest fitted point and that bone's
        neighbours are the candidates; the closest point on them is sigma (eq. 19)."""
        V = self.mesh.V
        _, nn = cKDTree(V[self.fit_subset]).query(V, workers=-1)
        seed_bone = bone_sub[nn]
        table, count = bone_neighbours(bones, len(joints))
        c = count[seed_bone]
        mask = np.arange(table.shape[1])[None, :] < c[:, None]
        ids = table[seed_bone][mask]
        indptr = np.concatenate([[0], np.cumsum(c)])
        bone, t, _ = closest_on_bones(V, joints, bones, (indptr, ids))
        return bone, t

    def steps(self) -> Iterator[SolverState]:
        """Run the solver, yielding its state after every iteration (the first is E0)."""
        p = self.params
        t0 = time.perf_counter()
        try:
            for state in solve_steps(self.problem, solver=p.solver, max_iterations=p.max_iterations,
                                     tolerance=p.tolerance, refit_mapping=p.refit_mapping):
                self._state = state
                self.energy.append(float(state.energy))
                self.progress("optimise", min(state.iteration / max(p.max_iterations, 1), 1.0))
                yield state
        finally:
            self.timings["optimise"] = self.timings.get("optimise", 0.0) + time.perf_counter() - t0

    def current_skeleton(self) -> Skeleton:
        """The skeleton as it stands now (first approximation before any step)."""
        pr, st = self.problem, self._state
        joints = st.joints if st is not None else pr.joints
        bone = st.bone if st is not None else pr.bone
        t = st.t if st is not None else pr.t
        return self._to_skeleton(joints, pr.bones, bone, t)

    def result(self) -> Skeleton:
        """Run any remaining steps, then prune/simplify (once), and return the final Skeleton."""
        if self._state is None or not self._state.done:
            for _ in self.steps():
                pass
        self._postprocess()
        self._refine()
        self._collapse()
        return self.current_skeleton()

    def _collapse(self) -> None:
        """Contract zero-length bones (joints the optimum put on one point), once."""
        st = self._state
        if st is None or self.collapsed is not None:
            return
        V = self.mesh.V
        B = self.problem.bones
        # Per bone: invisible at the mesh's scale, or hidden inside its own end balls.
        tol = np.maximum(COLLAPSE_TOL * float(np.linalg.norm(V.max(axis=0) - V.min(axis=0))),
                         COLLAPSE_RADIUS * np.minimum(st.joints[B[:, 0], 3], st.joints[B[:, 1], 3]))
        J0 = len(st.joints)
        joints, bones, bone, t = collapse_short_bones(st.joints, self.problem.bones, st.bone, st.t, tol)
        self.collapsed = J0 - len(joints)
        if self.collapsed:
            self.problem = FitProblem(self.problem.points, self.problem.weights, joints, bones,
                                      bone, t, self.problem.meta)
            self._state = SolverState(st.iteration, joints, bone, t, st.energy, done=True)

    def _postprocess(self) -> None:
        """Prune noise branches and merge straight-chain joints (``params.prune``/``simplify``),
        re-optimising after each; replaces the problem's bones and the final state."""
        p, st = self.params, self._state
        if self.postprocess_log is not None or not (p.prune > 0 or p.simplify > 0):
            return
        pr = self.problem.copy()
        pr.joints, pr.bone, pr.t = st.joints, st.bone, st.t
        with self._timed("postprocess"):
            out = postprocess(pr, p, self._solve)
        self.postprocess_log = out.meta["postprocess"]
        self.problem = FitProblem(out.points, out.weights, out.joints, out.bones, out.bone, out.t,
                                  dict(pr.meta))
        self._state = SolverState(st.iteration, out.joints, out.bone, out.t,
                                  self.postprocess_log["energy_out"], done=True)

    def _refine(self) -> None:
        """Once: merge away folds (:func:`.postprocess.unfold_chains`), then split the bones
        that leave the mesh and re-solve (``params.refine`` rounds, :mod:`.refine`; its first
        solve serves the unfolded skeleton too), then repair locally."""
        p, st = self.params, self._state
        if self.refine_log is not None or p.refine <= 0 or st is None:
            return
        if len(self.mesh.F) > REFINE_MAX_FACES:
            # Its exact inside tests cost O(faces) per ray direction: on 2M faces more than
            # the whole fit (12 s against 8 s on torus-1M). Said in the meta, not silent.
            self.refine_log = {"skipped": f"{len(self.mesh.F)} faces > {REFINE_MAX_FACES}"}
            return
        pr = self.problem.copy()
        pr.joints, pr.bone, pr.t = st.joints, st.bone, st.t
        with self._timed("refine"):
            # Folds first (a chain doubling back along another part), then the bones that
            # leave the mesh (the last word on containment); the refinement's first solve
            # serves the unfolded skeleton too.
            pr, unfolded = unfold_chains(pr)
            out, self.refine_log = refine(pr, self.mesh.V, self.mesh.F,
                                          lambda q: self._solve(q, REFINE_ITERATIONS),
                                          max_joints=p.max_joints, rounds=p.refine,
                                          solved=not unfolded)
            self.refine_log["unfolded"] = unfolded
        self.problem = FitProblem(out.points, out.weights, out.joints, out.bones, out.bone, out.t,
                                  dict(pr.meta))
        self._state = SolverState(st.iteration, out.joints, out.bone, out.t, energy(out), done=True)

    def _solve(self, pr: FitProblem, max_iterations: int | None = None) -> FitProblem:
        """Re-optimise ``pr`` with the run's solver settings (used after pruning/merging)."""
        p, last = self.params, None
        its = p.max_iterations if max_iterations is None else min(max_iterations, p.max_iterations)
        for last in solve_steps(pr, solver=p.solver, max_iterations=its,
                                tolerance=p.tolerance, refit_mapping=p.refit_mapping):
            pass
        out = pr.copy()
        out.joints, out.bone, out.t = last.joints, last.bone, last.t
        return out

    # -- output --------------------------------------------------------------------------------
    def _to_skeleton(self, joints, bones, bone_w, t_w) -> Skeleton:
        if self.fit_subset is not None:
            bone_w, t_w = self._full_mapping(np.asarray(joints), np.asarray(bones), np.asarray(bone_w))
        wi = self.mesh.work_index
        iso = wi < 0
        if iso.any():
            # Isolated input vertices take the mapping of the nearest working vertex.
            _, nn = cKDTree(self.mesh.V).query(self._input_V[iso])
            wi = wi.copy()
            wi[iso] = nn
        return Skeleton(joints, bones, bone_w[wi], t_w[wi], energy=list(self.energy),
                        timings=dict(self.timings), meta=self._meta())

    def _meta(self) -> dict:
        meta = {"params": self.params.to_dict(), "components": int(self.n_components),
                "component_info": self.component_meta, "input": self.mesh.info,
                "fit_points": int(len(self.fit_subset) if self.fit_subset is not None
                                  else len(self.mesh.V))}
        if self.postprocess_log is not None:
            meta["postprocess"] = self.postprocess_log
        if self.refine_log is not None:
            meta["refine"] = self.refine_log
        if self.collapsed:
            meta["collapsed_joints"] = int(self.collapsed)
        return meta


def skeletonize(V, F, params: SkeletonParams | None = None, progress: Progress | None = None,
                **overrides) -> Skeleton:
    """Curve-skeleton of a triangle mesh.

    Parameters
    ----------
    V : (n, 3) float
        Vertex positions.
    F : (m, 3) int, or polygons
        Faces; polygons are fan-triangulated.
    params : SkeletonParams, optional
        Method parameters; keyword ``overrides`` replace single fields.
    progress : callable(stage, fraction), optional

    Returns
    -------
    Skeleton
        Joints, bones, the mapping of every input vertex (input order), energy history, timings.

    Raises
    ------
    CurveSkelError
        For input that cannot be skeletonized, with a message for the user.

    Examples
    --------
    >>> sk = skeletonize(V, F, solver="paper")             # doctest: +SKIP
    >>> sk.joints.shape[1]                                 # doctest: +SKIP
    4
    """
    if overrides:
        base = (params or SkeletonParams()).to_dict()
        base.update(overrides)
        params = SkeletonParams.from_dict(base)
    return SkeletonRun(V, F, params, progress).result()
