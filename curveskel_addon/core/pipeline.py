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

from .errors import CurveSkelError
from .mesh_graph import components
from .mesh_input import clean_mesh
from .params import SOLVERS, SkeletonParams
from .problem import FitProblem, SolverState
from .reeb import first_approximation
from .skeleton import Skeleton
from .solvers import solve_steps
from .vertex_area import vertex_areas

__all__ = ["skeletonize", "SkeletonRun"]

Progress = Callable[[str, float], None]


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
        self.params = params or SkeletonParams()
        _check_params(self.params)
        self.progress = progress or (lambda stage, fraction: None)
        self.timings: dict[str, float] = {}
        with self._timed("clean"):
            self.mesh = clean_mesh(V, F)
            self._input_V = np.asarray(V, dtype=np.float64)
        with self._timed("components"):
            self.n_components, self.labels = components(len(self.mesh.V), self.mesh.F)
        self.problem = self._first_approximation()
        self.energy: list[float] = []
        self._state: SolverState | None = None

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
        return FitProblem(V, w, np.concatenate(joints), np.concatenate(bones), bone, t)

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
        """Run any remaining steps and return the final Skeleton."""
        if self._state is None or not self._state.done:
            for _ in self.steps():
                pass
        return self.current_skeleton()

    # -- output --------------------------------------------------------------------------------
    def _to_skeleton(self, joints, bones, bone_w, t_w) -> Skeleton:
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
        return {"params": self.params.to_dict(), "components": int(self.n_components),
                "component_info": self.component_meta, "input": self.mesh.info}


def _check_params(p: SkeletonParams) -> None:
    if p.solver not in SOLVERS:
        raise CurveSkelError(f"unknown solver {p.solver!r}; choose one of {', '.join(SOLVERS)}")
    if not (0 < p.spacing <= 0.5):
        raise CurveSkelError(f"spacing must be in (0, 0.5] of the mesh size, got {p.spacing}")
    if p.max_iterations < 0:
        raise CurveSkelError("max_iterations must be >= 0")
    if not p.tolerance > 0:
        raise CurveSkelError("tolerance must be > 0")


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
