"""Refine any curve-skeleton of a mesh: J minimised over its joints, its graph kept (issue 33).

A rigger's armature, a metarig scaled onto a character, CGAL's curve: :class:`Refinement`
moves their joints to where J is lowest and fits their radii, keeping every bone (so a Blender
armature keeps its bones' names, parents and order; no bone shrinks below J's resolution).
Joints in ``fixed`` keep their positions exactly (their radii still fit). With ``edit_topology`` the search's topology moves run too
(chain joints merged, branches pruned, junctions split or joined: :mod:`.search`), each kept
only when J falls; the graph may then change, so ``fixed`` cannot be combined with it.

J is the given skeleton's (:mod:`.evaluation`): its unit of length at each surface sample is the
sample's distance from the skeleton as given, held through the refinement, so J before and
after are values of one function. The result's mapping (every input vertex's bone and ``t``) is
the pipeline's kind: each vertex on the bones of its region, the bone nearest to it on the given
skeleton.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Callable, Iterator

import numpy as np
from scipy.spatial import cKDTree

from .config import CONFIG
from .errors import CurveSkelError
from .evaluation import SkeletonReport, prepare, report_of
from .geometry.rows import row_norm
from .geometry.segments import closest_on_bones
from .graph import candidates_from_pairs
from .objective.minimise import minimise
from .params import SkeletonParams
from .pipeline import RunState
from .search import SearchLog, search_steps
from .skeleton import Skeleton

__all__ = ["Refinement", "RefineResult", "refine"]

Progress = Callable[[str, float], None]


@dataclass
class RefineResult:
    """A refined skeleton and the reports before and after.

    Attributes
    ----------
    skeleton : Skeleton
        Joints (J, 4) in the caller's indices (with the graph kept), bones, the mapping of
        every input vertex, ``meta["J"]``, ``meta["J_before"]``, ``meta["stages"]``.
    before, after : SkeletonReport
        On one J (the given skeleton's), so ``after.J <= before.J``.
    iterations : int
    """

    skeleton: Skeleton
    before: SkeletonReport
    after: SkeletonReport
    iterations: int


class Refinement:
    """One refinement, step by step, so a UI can draw it and stop it (as
    :class:`.pipeline.SkeletonRun`).

    Parameters
    ----------
    V : (n, 3) float
    F : (m, 3) int, or polygons
    skeleton : Skeleton, dict, (joints, bones) or OutsideSkeleton
    fixed : (J,) bool or sequence of joint indices, optional
        Joints that keep their positions (the caller's indices).
    edit_topology : bool
        Also run the topology moves (the graph may change).
    params : SkeletonParams, optional
        As for :func:`.evaluate.prepare`; ``max_iterations`` bounds each minimisation and
        ``max_joints`` the topology moves.
    progress : callable(stage, fraction), optional
    step_iterations : int, optional
        Minimisation steps between two yields of :meth:`steps` (a live view); by default the
        search's refit steps.

    Examples
    --------
    >>> run = Refinement(V, F, skeleton, fixed=[0])          # doctest: +SKIP
    >>> for state in run.steps():                            # doctest: +SKIP
    ...     draw(run.current_skeleton())
    >>> result = run.result()                                # doctest: +SKIP
    >>> result.after.J < result.before.J                     # doctest: +SKIP
    True
    """

    def __init__(self, V, F, skeleton, *, fixed=None, edit_topology=False,
                 params: SkeletonParams | None = None, progress: Progress | None = None,
                 step_iterations: int | None = None):
        self.step_iterations = step_iterations
        self.params = SkeletonParams() if params is None else params
        self.progress = progress or (lambda stage, fraction: None)
        self.edit_topology = bool(edit_topology)
        t0 = time.perf_counter()
        self.fit = fit = prepare(V, F, skeleton, self.params)
        self._started = False
        self.fix(fixed)
        self.graph = fit.graph
        Z = np.asarray(fit.graph.joints)
        given = row_norm(Z[fit.graph.bones[:, 0], :3] - Z[fit.graph.bones[:, 1], :3])
        # the least length of a bone: what the first approximation contracts (half a spacing),
        # or half its given length if shorter (a dense curve's bones are below J's resolution
        # and slide along their chains; none may become a point)
        self.min_length = CONFIG.initial.contract * np.minimum(
            given, self.params.spacing * fit.objective.D)
        self.held = np.zeros(fit.graph.n_joints, bool)     # joints the length guard holds
        self.evaluation = fit.objective.evaluate(self.graph)
        self.before = report_of(fit, self.graph, self.evaluation)
        self.log = SearchLog(fit.objective)
        self.iterations = 0
        self.seconds = {"prepare": time.perf_counter() - t0}
        self.progress("prepare", 1.0)
        self._done = False
        self._finished = None

    def fix(self, fixed) -> None:
        """Set the joints that keep their positions (as ``fixed`` of the constructor), before
        the first step (Blender reads some of them, locked bones, only once the input is
        known to be good)."""
        if self._started:
            raise CurveSkelError("the fixed joints are set before the refinement starts")
        self.fixed = self._fixed_mask(fixed)
        if self.edit_topology and self.fixed.any():
            raise CurveSkelError("fixed joints can only be kept with the skeleton's bones kept "
                                 "(no topology edits)")

    def _fixed_mask(self, fixed) -> np.ndarray:
        """(k,) bool over the graph's joints."""
        n = self.fit.skeleton.n_joints
        mask = np.zeros(n, bool)
        if fixed is not None:
            f = np.asarray(fixed)
            if f.dtype == bool:
                if f.shape != (n,):
                    raise CurveSkelError(f"fixed must have one entry per joint ({n}), got {f.shape}")
                mask = f.copy()
            else:
                f = f.astype(np.int64).ravel()
                if len(f) and (f.min() < 0 or f.max() >= n):
                    raise CurveSkelError(f"a fixed joint index is out of range (0 to {n - 1})")
                mask[f] = True
        return mask[self.fit.used]

    # -- stepping ------------------------------------------------------------------------------
    def steps(self) -> Iterator[RunState]:
        """Refine, yielding after every kept step (the last has ``done``)."""
        t0 = time.perf_counter()
        self._started = True
        try:
            n = 0
            steps = self._topology_steps() if self.edit_topology else self._continuous_steps()
            for stage, value in steps:
                n += 1
                self.progress(stage, min(n / 20.0, 0.99))
                yield RunState(stage, n, value)
            self._done = True
            self.progress("done", 1.0)
            yield RunState("done", n, self.evaluation.value, done=True)
        finally:
            self.seconds["refine"] = self.seconds.get("refine", 0.0) + time.perf_counter() - t0

    def _continuous_steps(self):
        """J minimised over the positions of the free joints and every radius, the graph held,
        in rounds of a few steps (``step_iterations``, else the search's refit steps), until a
        round no longer lowers J by the final tolerance (as the search's last fit) or
        ``max_iterations`` steps are spent.

        The graph is kept, so no bone may shrink to a point: J cannot see a bone shorter than
        its resolution (half a spacing, where the first approximation contracts bones), and a
        turn at a joint costs nothing once one of its bones has no length (a rig's foot bone
        collapses so that shin and toe run straight, a chest bone so that the shoulders start
        at the neck). When a round would make a bone shorter than that (or than half its given
        length, if that is shorter), the joints go only as far along the round's way as keeps
        every bone long enough (if J is lower there), and the bone that stopped them is held
        from then on."""
        p = self.params
        tol = CONFIG.search.final_tolerance
        obj = self.fit.objective
        self.log.add("initialise", self.graph, self.evaluation)
        budget = max(p.max_iterations, 1)
        size = self.step_iterations or CONFIG.search.refit_steps
        while self.iterations < budget:
            n = min(size, budget - self.iterations)
            g, ev, it = minimise(obj, self.graph, max_iterations=n, tolerance=tol,
                                 fixed=self.fixed | self.held, evaluation=self.evaluation)
            self.iterations += it
            stop, binding = self._length_guard(self.graph, g)
            if len(binding):
                self.held[np.unique(self.graph.bones[binding])] = True
                g = self.graph.with_joints((1.0 - stop) * np.asarray(self.graph.joints)
                                           + stop * np.asarray(g.joints))
                ev = obj.evaluate(g)
            drop = self.evaluation.value - ev.value
            if drop > 0:
                self.graph, self.evaluation = g, ev
                self.log.add("fit", g, ev, iterations=int(it))
                yield "fit", ev.value
            if not len(binding) and (drop <= tol * self.evaluation.value or it < n):
                break

    def _length_guard(self, before, after):
        """How far (``lam`` in [0, 1]) the joints may go from ``before`` towards ``after``, on
        the straight way, with every bone at least its least length; and the bones that stop
        them there (none: all the way)."""
        X0, X1 = np.asarray(before.joints)[:, :3], np.asarray(after.joints)[:, :3]
        i, j = before.bones[:, 0], before.bones[:, 1]
        d0 = X0[i] - X0[j]
        e = (X1[i] - X1[j]) - d0
        m2 = self.min_length ** 2
        # |d0 + lam e|^2 = m^2: a lam^2 + b lam + c = 0, c >= 0 where the bone starts long enough
        qa = np.einsum("ij,ij->i", e, e)
        qb = 2.0 * np.einsum("ij,ij->i", d0, e)
        qc = np.einsum("ij,ij->i", d0, d0) - m2
        disc = qb * qb - 4.0 * qa * qc
        with np.errstate(divide="ignore", invalid="ignore"):
            first = np.where(qc <= 0, 0.0, (-qb - np.sqrt(np.maximum(disc, 0.0))) / (2.0 * qa))
        # a bone long enough at the start is stopped where it first reaches its least length
        # (only when it shrinks: qb < 0); one at it already, as soon as it shrinks at all
        hits = (qb < 0) & (qa > 0) & (disc >= 0) & (first <= 1)
        if not hits.any():
            return 1.0, np.zeros(0, np.int64)
        lam = float(first[hits].min())
        return lam, np.flatnonzero(hits & (first <= lam))

    def _topology_steps(self):
        """The search from the given skeleton: minimisation and topology moves, each kept only
        when J falls (:func:`.search.search_steps`)."""
        p = self.params
        for graph, entry in search_steps(self.fit.objective, self.graph, self.log,
                                         max_joints=max(p.max_joints, self.graph.n_joints),
                                         max_iterations=p.max_iterations):
            self.graph = graph
            self.iterations += int(entry.get("iterations", 0))
            yield entry["stage"], entry["J"]
        self.evaluation = self.fit.objective.evaluate(self.graph)

    # -- output --------------------------------------------------------------------------------
    def current_skeleton(self) -> Skeleton:
        """The skeleton as it stands now."""
        return self._to_skeleton(self.graph)

    def stop(self) -> None:
        """No more steps: :meth:`result` gives the skeleton reached so far (a live view's Esc;
        J never rose, so it is the lowest seen)."""
        self._done = True
        self.evaluation = self.fit.objective.evaluate(self.graph) if self.edit_topology else \
            self.evaluation

    def result(self) -> RefineResult:
        """Run the remaining steps; the refined skeleton and the reports before and after."""
        if self._finished is None:
            if not self._done:
                for _ in self.steps():
                    pass
            after = report_of(self.fit, self.graph, self.evaluation)
            self._finished = RefineResult(self._to_skeleton(self.graph), self.before, after,
                                          self.iterations)
        return self._finished

    def _mapping(self, graph):
        """Every working vertex on the bones of its region (the bone nearest to it on the given
        skeleton), as the pipeline maps its own."""
        fit = self.fit
        V = fit.mesh.V
        region, _, _ = closest_on_bones(V, fit.graph.joints, fit.graph.bones)
        n_reg = int(max(region.max(initial=-1), graph.pairs[:, 0].max(initial=-1))) + 1
        cand = candidates_from_pairs(graph.pairs, region, n_reg)
        bone, t, _ = closest_on_bones(V, graph.joints, graph.bones, cand)
        return bone, t

    def _to_skeleton(self, graph) -> Skeleton:
        fit = self.fit
        bone_w, t_w = self._mapping(graph)
        wi = fit.clean.work_index.copy()
        iso = wi < 0
        if iso.any():
            _, nn = cKDTree(fit.mesh.V).query(fit.input_vertices[iso])
            wi[iso] = nn
        joints, bones = fit.joints_out(graph), fit.bones_out(graph)
        if fit.keeps_graph(graph):
            # a fixed joint keeps its given coordinates to the last bit (not moved to the
            # working space and back)
            keep = fit.used[self.fixed]
            joints[keep, :3] = fit.skeleton.joints[keep]
        entries = self.log.entries
        meta = {"params": self.params.to_dict(), "refined": True,
                "edit_topology": self.edit_topology,
                "J_before": float(self.before.J), "J": float(self.evaluation.value),
                "terms": dict(self.evaluation.terms),
                "stages": [dict(e) for e in entries], "fixed": int(self.fixed.sum()),
                "held": int(self.held.sum()),
                "samples": int(len(fit.objective.samples.points))}
        E = [float(e["terms"].get("E", 0.0)) for e in entries]
        return Skeleton(joints, bones, bone_w[wi], t_w[wi], energy=E,
                        timings=dict(self.seconds), meta=meta)


def refine(V, F, skeleton, *, fixed=None, edit_topology=False,
           params: SkeletonParams | None = None, progress: Progress | None = None) -> RefineResult:
    """J minimised over the joints of ``skeleton`` on the mesh (V, F) (module doc).

    Parameters
    ----------
    V : (n, 3) float
    F : (m, 3) int, or polygons
    skeleton : Skeleton, dict, (joints, bones) or OutsideSkeleton
    fixed : (J,) bool or sequence of joint indices, optional
        Joints that keep their positions.
    edit_topology : bool
        Also run the topology moves.
    params : SkeletonParams, optional
    progress : callable(stage, fraction), optional

    Returns
    -------
    RefineResult

    Raises
    ------
    CurveSkelError
        Bad mesh, bad skeleton, a skeleton entirely outside the mesh, a fixed index out of
        range, or fixed joints with ``edit_topology``.
    """
    return Refinement(V, F, skeleton, fixed=fixed, edit_topology=edit_topology, params=params,
                      progress=progress).result()
