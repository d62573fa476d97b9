"""skeletonize(): the method as the search for the minimum of one objective J.

    mesh arrays -> clean (:mod:`.mesh_input`) -> Mesh, its parts, surface samples
      -> initialise   the paper's first approximation of every part at the spacing's
                      resolution (:mod:`.initialise.first`); parts that overlap or nearly
                      touch joined where they meet, small free parts hung from larger ones,
                      the samples inside another part left out (:mod:`.initialise.parts`;
                      not with ``separate_parts``); cut to the joint budget
      -> search       J minimised: joints and radii fitted (LM), chain joints merged, leaf
                      branches pruned, junctions split or joined, each move kept only when J
                      falls (:mod:`.search`)
      -> Skeleton     every input vertex mapped; ``meta["stages"]`` logs J and its terms after
                      every kept stage, ``meta["J"]`` is the returned skeleton's J

J and its terms: :mod:`.objective` (README: "The objective"). ``SkeletonParams.paper()``
(``solver="paper"``) runs the paper's method exactly instead: its first approximation and
gradient descent on E (eq. 20, the vertex sum) with the exact line search, stopped as in its
eqs. 30-31 (:mod:`.objective.paper`).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Callable, Iterator

import numpy as np
from scipy.spatial import cKDTree

from .config import CONFIG
from .errors import CurveSkelError
from .geometry.rows import col_max, col_min
from .geometry.samples import canonical_subset, face_samples
from .geometry.segments import closest_on_bones
from .graph import SkeletonGraph, candidates_from_pairs
from .initialise.first import initial_graph
from .initialise.contacts import find_figures, part_spacing
from .initialise.parts import join_parts, parts_meta
from .mesh import Mesh
from .mesh_input import clean_mesh
from .objective.objective import Objective, weights_for
from .objective.paper import paper_fit
from .params import SkeletonParams, check_params
from .search import SearchLog, budget, search_steps
from .skeleton import Skeleton

__all__ = ["skeletonize", "SkeletonRun", "RunState"]

Progress = Callable[[str, float], None]


@dataclass
class RunState:
    """What a run reports after every kept stage (the live view draws it)."""

    stage: str
    iteration: int
    energy: float          # J (the paper's mode: E)
    done: bool = False


class SkeletonRun:
    """One skeletonization, stage by stage, so a UI can draw it and stop it.

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
        check_params(self.params)      # again: fields may have been assigned after construction
        self.progress = progress or (lambda stage, fraction: None)
        self.timings: dict[str, float] = {}
        p = self.params
        t0 = time.perf_counter()
        cm = clean_mesh(V, F, min_component_area=p.min_component_area, detail=p.spacing)
        n_comp, labels = cm.components
        self.n_components = n_comp
        paper = p.solver == "paper"
        # parts joined into figures (not the paper's method, not when asked to keep them apart):
        # the solid is their union, and so is the inside test
        join = n_comp > 1 and not paper and not p.separate_parts
        # work about the middle of the bounding box (expanded squares lose digits far from
        # the origin), joints moved back on output
        self.origin = (col_min(cm.V) + col_max(cm.V)) / 2
        self.clean = cm
        self.mesh = Mesh(cm.V - self.origin, cm.F, union=join)
        self._input_V = np.asarray(V, dtype=np.float64) - self.origin
        self.timings["clean"] = time.perf_counter() - t0
        t0 = time.perf_counter()
        cfg = CONFIG.objective
        sample_length = cfg.sample_length * p.spacing * self.mesh.D
        samples = face_samples(self.mesh.V, self.mesh.F, sample_length)
        one = n_comp == 1
        self.parts = None
        spacing = p.spacing
        if join:        # the parts' contacts first; the parts share the mesh's resolution
            figures = find_figures(self.mesh, labels, n_comp, samples, band=sample_length)
            spacing = part_spacing(self.mesh, labels, n_comp, p.spacing)
        self.init = initial_graph(self.mesh, labels, n_comp, samples, spacing=spacing,
                                  seed=p.seed, inside=(lambda: self.mesh.inside) if one else None,
                                  edges=cm.edge_table() if one else None, resolve=not paper)
        sreg = self.init.sample_region
        if join:
            self.parts = join_parts(figures, samples, self.init)
            self.init = self.parts.init
            on_surface = np.flatnonzero(self.parts.visible)     # of the union
            samples, sreg = samples.subset(on_surface), sreg[on_surface]
        self.progress("first_approximation", 1.0)
        self.timings["initialise"] = time.perf_counter() - t0
        self.log = SearchLog()
        if paper:
            self.graph = self.init.graph
            if p.max_joints and self.graph.n_joints > p.max_joints:
                # the budget binds the paper's method too: cut by J's estimates, as below
                obj = Objective.for_first_approximation(self.mesh, samples, sreg, self.graph,
                                                        weights_for(p), p.spacing)
                g0 = self.graph.with_thickness(obj.measure_thickness(self.graph))
                self.graph = budget(obj, g0, p.max_joints)
            self._steps = self._paper_steps()
            return
        if len(samples.points) > cfg.max_samples:
            fs = np.einsum("ij,ij->i", samples.bary, self.init.key[self.mesh.F[samples.face]])
            idx = canonical_subset(fs, cfg.max_samples, p.seed)
            samples = samples.subset(idx, float(samples.weights.sum() / samples.weights[idx].sum()))
            sreg = sreg[idx]
        coarse = self.mesh.coarsened(cfg.sample_length * p.spacing * self.mesh.D)
        self.objective = Objective.for_first_approximation(self.mesh, samples, sreg,
                                                           self.init.graph, weights_for(p),
                                                           p.spacing, sections=coarse)
        t0 = time.perf_counter()
        g0 = self.init.graph
        g0 = g0.with_thickness(self.objective.measure_thickness(g0))
        self.graph = budget(self.objective, g0, p.max_joints)
        self.timings["budget"] = time.perf_counter() - t0
        self._steps = search_steps(self.objective, self.graph, self.log,
                                   max_joints=p.max_joints, max_iterations=p.max_iterations)

    # -- stepping ------------------------------------------------------------------------------
    def steps(self) -> Iterator[RunState]:
        """Run the search, yielding after every kept stage (the last has ``done``)."""
        t0 = time.perf_counter()
        try:
            n = 0
            for graph, entry in self._steps:
                self.graph = graph
                self.progress(entry["stage"], min(n / 20.0, 0.99))
                n += 1
                yield RunState(entry["stage"], n, entry["J"])
            self._done = True
            self.progress("done", 1.0)
            yield RunState("done", n, self.log.entries[-1]["J"] if self.log.entries else 0.0,
                           done=True)
        finally:
            self.timings["search"] = self.timings.get("search", 0.0) + time.perf_counter() - t0

    _done = False
    _finished: Skeleton | None = None

    def current_skeleton(self) -> Skeleton:
        """The skeleton as it stands now."""
        return self._to_skeleton(self.graph)

    def result(self) -> Skeleton:
        """Run the remaining stages and return the Skeleton (the lowest-J graph seen)."""
        if self._finished is None:
            if not self._done:
                for _ in self.steps():
                    pass
            self._finished = self._to_skeleton(self.graph)
        return self._finished

    def _paper_steps(self):
        """The paper's method: E (eq. 20) over the first approximation, gradient descent with
        the exact line search (:mod:`.objective.paper`)."""
        p = self.params
        init = self.init
        V = self.mesh.V
        g = self.graph
        bone, t = init.vertex_bone, init.vertex_t
        if g is not init.graph:
            # the budget merged joints: each vertex on the bones of its own Reeb region, again
            n_reg = int(max(init.vertex_region.max(initial=-1), g.pairs[:, 0].max(initial=-1))) + 1
            cand = candidates_from_pairs(g.pairs, init.vertex_region, n_reg)
            bone, t, _ = closest_on_bones(V, g.joints, g.bones, cand)
        for stage, joints, bone, t, E, it in paper_fit(V, g, bone, t,
                                                       max_iterations=p.max_iterations,
                                                       tolerance=p.tolerance):
            graph = g.with_joints(joints)
            self._paper_mapping = (bone, t)
            entry = self.log.add_value(stage, graph, E, {"E": E}, iterations=it)
            yield graph, entry

    # -- output --------------------------------------------------------------------------------
    def _mapping(self, graph: SkeletonGraph):
        """sigma of every working vertex: the paper's own (its first approximation's, fitted),
        else the closest point on the bones of its Reeb region (or, where the search removed
        them all, on any bone)."""
        if self.params.solver == "paper" and getattr(self, "_paper_mapping", None) is not None:
            return self._paper_mapping
        init = self.init
        n_reg = int(max(init.vertex_region.max(initial=-1), graph.pairs[:, 0].max(initial=-1))) + 1
        cand = candidates_from_pairs(graph.pairs, init.vertex_region, n_reg)
        bone, t, _ = closest_on_bones(self.mesh.V, graph.joints, graph.bones, cand)
        return bone, t

    def _to_skeleton(self, graph: SkeletonGraph) -> Skeleton:
        bone_w, t_w = self._mapping(graph)
        wi = self.clean.work_index.copy()
        iso = wi < 0
        if iso.any():
            # input vertices no face uses: the mapping of the nearest working vertex
            _, nn = cKDTree(self.mesh.V).query(self._input_V[iso])
            wi[iso] = nn
        joints = np.array(graph.joints, dtype=np.float64)
        joints[:, :3] += self.origin
        entries = self.log.entries
        meta = {"params": self.params.to_dict(), "components": int(self.n_components),
                "component_info": self.init.meta, "input": self.clean.info,
                "stages": [dict(e) for e in entries],
                "J": float(entries[-1]["J"]) if entries else None,
                "terms": dict(entries[-1]["terms"]) if entries else {},
                "samples": int(len(self.objective.samples.points)) if hasattr(self, "objective") else 0}
        if self.parts is not None:
            meta["parts"] = parts_meta(self.parts, graph)
        E = [e["terms"].get("E", 0.0) for e in entries]
        return Skeleton(joints, graph.bones, bone_w[wi], t_w[wi], energy=E,
                        timings=dict(self.timings), meta=meta)


def skeletonize(V, F, params: SkeletonParams | None = None, progress: Progress | None = None,
                **overrides) -> Skeleton:
    """Curve-skeleton of a triangle mesh: the minimiser of J found by the search.

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
        Joints, bones, the mapping of every input vertex (input order), the paper's E after
        every stage, timings, and ``meta["stages"]`` (J and its terms after every kept stage;
        ``meta["J"]``: the returned skeleton's J, the lowest in the log).

    Raises
    ------
    CurveSkelError
        For input that cannot be skeletonized, with a message for the user.

    Examples
    --------
    >>> sk = skeletonize(V, F, smoothness=2.0)              # doctest: +SKIP
    >>> sk.meta["J"] == min(s["J"] for s in sk.meta["stages"])   # doctest: +SKIP
    True
    """
    if overrides:
        base = (params or SkeletonParams()).to_dict()
        base.update(overrides)
        params = SkeletonParams.from_dict(base)
    return SkeletonRun(V, F, params, progress).result()
