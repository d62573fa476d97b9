"""skeletonize(): the stages of the method in order over one :class:`.state.PipelineState`.

    mesh arrays -> clean_mesh -> components
      -> initialise  first approximation per component (Reeb graph of the geodesic distance,
                     contours' enclosing balls; :mod:`.reeb`)
      -> centre      the curve moved onto the medial points, smooth along chains (:mod:`.centreline`)
      -> edit        bumps removed, straight chain joints and zig-zags merged, joint budget (:mod:`.edit`)
      -> fit         E minimised (LM or the paper's gradient descent) with every joint held to its
                     centred place and kept inside; sigma stays on the bones of its Reeb region
      -> radii       chains smoothed, radii fitted to the surface with the curve fixed
                     (:func:`.centreline.fit_radii_surface`)
      -> contain     tips trimmed, bones that leave the mesh split at medial points (:mod:`.edit`)
      -> polish      two loops' sides through one web zipped, a bridge across a web made the
                     loops' shared rung (:mod:`.edit`), a chain's end bent into a flat part's
                     corner cut back (:mod:`.flat_corners`), a flap's chain (an ear) laid into
                     the flap's middle (:mod:`.flaps`), other chain joints towards the
                     centroids of the mesh's cross-sections through them (:mod:`.cross_section`;
                     two passes, the radii refitted between them), bones
                     shorter than a tenth of their radius and kinks inside their joint's ball
                     merged, radii refitted
      -> Skeleton    every input vertex mapped; the reported E is that of the returned skeleton

Why this order (issue 10): the *shape* of the curve comes from the mesh's structure (Reeb
graph: one branch per part, the genus, no fold) and its medial axis; E decides the radii and
the fine placement within that shape. Letting E also choose sigma freely and split bones where
it is worst (the earlier default) made bones zig-zag through the volume: E is low for any curve
whose balls fill the shape. ``SkeletonParams.paper()`` skips centre, edit, radii and contain:
the method as published.
"""

from __future__ import annotations

import time
from contextlib import contextmanager
from typing import Callable, Iterator

import numpy as np
from scipy.spatial import cKDTree

from .centreline import SURFACE_RADII_ROUNDS, centre_stage, fit_radii_surface, smooth_chains
from .cross_section import ROUNDS, STEP, polish_chains, section_loops, shared_sections_many
from .edit import (EDIT_CONSTANTS, apply_edit, beside_junctions, bridges_to_rungs, contain_stage,
                   edit_stage,
                   merge_short_bones, outside_worse, point_polyline_distance, put_back, turn_worse,
                   remove_kinks, zip_parallel_chains)
from .errors import CurveSkelError
from .flaps import lay_flaps
from .flat_corners import trim_flat_corners
from .junctions import onto_trunks
from .mapping import closest_on_bones
from .mesh_graph import components
from .mesh_input import clean_mesh
from .params import SkeletonParams, check_params
from .problem import FitProblem, SolverState
from .reeb import first_approximation
from .rows import col_max, col_min
from .skeleton import Skeleton
from .solvers import solve_steps
from .state import PipelineState, canonical_subset
from .vertex_area import face_cross, vertex_areas

__all__ = ["skeletonize", "SkeletonRun"]

Progress = Callable[[str, float], None]

#: After the fit of E, refit the radii to the surface (least absolute deviations of each
#: vertex's distance to its nearest bone; :func:`.centreline.fit_radii_surface`).
SURFACE_RADII = True
#: Chain smoothing after the fit of E (weight of the second difference; see smooth_chains).
FIT_SMOOTHING = 0.3
#: Joints that the fit of E (or the smoothing after it) moved into a fold go back to where the
#: edit stage left them (see undo_new_folds).
FOLD_GUARD = True
#: ... and so do joints it moved into a crossing (two bones within 0.3 of their radius of each
#: other, far apart along the skeleton: quality.crossing_pairs).
CROSSING_GUARD = True
#: Last, chain joints move towards the centroids of the mesh's cross-sections through them
#: (:mod:`.cross_section`), radii refitted.
POLISH = True
#: The polish's passes, (rounds, step) each, the radii refitted to the surface between them (a
#: section beyond a few radii is not the part's own, so its reach depends on them). One pass of
#: two half steps left the plate's loops 0.02-0.06 inside its rings (0.0085 D; re-polished
#: from its final skeleton: 0.0062 after two more rounds, 0.0049 after six); a second pass of
#: two full steps: 0.0048, every mesh's curve nearer its sections' centres (3holes' median
#: offset 0.0058 -> 0.0033 D, rocker-arm's 0.0145 -> 0.0070) and armadillo's recon 1.58 ->
#: 1.23x CGAL. Full steps from the first, they zig-zagged 3holes, rocker-arm and spot: the
#: first pass's half steps settle the planes. The second's moves that make a new zig-zag beside
#: a junction are put back (the cat's hip came to turn by 81 and 141 degrees there; elsewhere
#: the kink merge after the polish takes a knot, and a guard everywhere put back one of homer's
#: shoulders at 62 degrees and not its mirror image at 59: mirror asymmetry 0.0070 -> 0.0084 D).
POLISH_PASSES = ((ROUNDS, STEP), (2, 1.0))
#: ... and junctions move onto the straight line of their trunk (:mod:`.junctions`).
TRUNK_JUNCTIONS = True
#: Before it, two loops joined by a bridge across one web (the Reeb graph's link along f through
#: a web wider across than along f) share a rung across the web instead
#: (:func:`.edit.bridges_to_rungs`: the plate with three holes).
RUNGS = True
#: ... and a chain's end bent into a corner of a flat part (the Reeb graph's pole in a board's
#: or a plate's corner) is cut back to where the part's sections stop holding it
#: (:mod:`.flat_corners`).
FLAT_CORNERS = True
#: After the polish, a chain joint turning sharply inside its own ball (its two bones together
#: shorter than its radius) is merged away (:func:`.edit.remove_kinks`): a knot the silhouette
#: does not see (the hand's palm, spot's back).
KINKS = True
#: ... in at most this many rounds, the radii refitted after each that merged one.
KINK_ROUNDS = 3
#: ... but a chain into a flap (an ear: flat sections) is laid from its junction into the
#: flap's middle first, and stays there (:mod:`.flaps`).
FLAPS = True
#: ... and the polish's moves that take a bone further out of the mesh are put back
#: (:func:`.edit.outside_worse`).
INSIDE_GUARD = True
#: Before the polish, two loops' sides running through one part (the web between two holes)
#: are zipped into one strand where they share cross-sections (:func:`.edit.zip_parallel_chains`
#: with :func:`.cross_section.shared_sections`): 3holes' left web held two strands 0.045 D apart
#: across the web's depth, which the polish would pull together and its fold guard then put back.
SHEET_ZIP = True
#: Sections are looked for within this many of the two paths' largest radius: where a web meets
#: the band round a hole its section is the band's, ~0.6 of 3holes' width from the joint (2
#: radii found the web's own sections only, and no zip; 4 and 8 zip the same).
SHEET_ZIP_REACH = 4.0
#: The final radii are refined on the silhouette (the union of round cones) against the surface
#: (:mod:`.silhouette_radii`), after the nearest-bone fit.
SILHOUETTE_RADII = True


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
            # Work about the centre of the bounding box, joints moved back on output: far from
            # the origin, expanded squares (|a|^2 - 2ab + |b|^2) lose the digits that decide an
            # edit (a horse moved by 1e6 of its size changed by 0.006 of it; issue 12).
            self.origin = (col_min(self.mesh.V) + col_max(self.mesh.V)) / 2
            self.mesh.V = self.mesh.V - self.origin
            self._input_V = np.asarray(V, dtype=np.float64) - self.origin
        with self._timed("components"):
            # clean_mesh found them already (None: compute them here)
            self.n_components, self.labels = (self.mesh.components
                                              or components(len(self.mesh.V), self.mesh.F))
        self.state = self._initialise()
        if self.params.centre:
            self._centre_and_edit()
        self.state.face_cross = None              # (the centring's normals took it, if any)
        self.energy: list[float] = []
        self._solver_state: SolverState | None = None
        self._fit = self._fit_problem()
        self._finished: Skeleton | None = None

    # -- stages --------------------------------------------------------------------------------
    @contextmanager
    def _timed(self, stage: str):
        t0 = time.perf_counter()
        yield
        self.timings[stage] = self.timings.get(stage, 0.0) + time.perf_counter() - t0

    _inside = None

    def _inside_test(self):
        """The working mesh's exact inside test, built once (the state's, later)."""
        if self._inside is None:
            from .quality import InsideTest
            self._inside = InsideTest(self.mesh.V, self.mesh.F)
        return self._inside

    def _initialise(self) -> PipelineState:
        """First approximation of every component, in one graph (regions numbered globally)."""
        V, F, p = self.mesh.V, self.mesh.F, self.params
        face_label = self.labels[F[:, 0]]
        order = np.argsort(self.labels, kind="stable")
        starts = np.searchsorted(self.labels[order], np.arange(self.n_components + 1))
        forder = np.argsort(face_label, kind="stable")
        fstarts = np.searchsorted(face_label[forder], np.arange(self.n_components + 1))
        local = np.empty(len(V), np.int64)
        joints, bones, pairs, spacing = [], [], [], []
        bone = np.empty(len(V), np.int64)
        t = np.empty(len(V))
        region = np.empty(len(V), np.int64)
        key = np.zeros(len(V))
        nj = nb = nr = 0
        comp_meta = []
        one = self.n_components == 1
        # one component: its first approximation takes the cleaning's edge census as its edge
        # table (Fc is F, the census's triangles); the census is let go first (memory at 1M)
        edges = self.mesh.edge_table() if one else None
        self.mesh.edge_matrix = None
        for c in range(self.n_components):
            vids = order[starts[c]:starts[c + 1]]
            if one:                # the whole working mesh, in order: no renumbered copy
                Vc, Fc = V, F
            else:
                local[vids] = np.arange(len(vids))
                Vc, Fc = V[vids], local[F[forder[fstarts[c]:fstarts[c + 1]]]]
            # one seed for every component: seed 0 starts each pole search at the vertex farthest from its
            # centroid, so the skeleton does not depend on how the components are numbered
            # one component: the whole working mesh, whose exact inside test the later stages
            # build anyway (the first approximation may use it)
            fa = first_approximation(Vc, Fc, spacing=p.spacing, seed=p.seed,
                                     inside=self._inside_test if one else None, edges=edges)
            edges = None
            for stage, sec in fa.meta.get("timings", {}).items():
                self.timings[stage] = self.timings.get(stage, 0.0) + sec
            if fa.region is None:             # one bone for the whole component
                reg_c = np.zeros(len(vids), np.int64)
                breg_c = np.zeros(len(fa.bones), np.int64)
            else:
                reg_c, breg_c = fa.region, fa.bone_region
            joints.append(fa.joints)
            bones.append(fa.bones + nj)
            bone[vids] = fa.bone + nb
            t[vids] = fa.t
            region[vids] = reg_c + nr
            key[vids] = fa.f if fa.f is not None else 0.0
            pairs.append(np.stack([breg_c + nr, np.arange(len(fa.bones)) + nb], axis=1))
            spacing.append(np.full(len(fa.bones), fa.meta.get("spacing_used", p.spacing)
                                   * fa.meta["size"]))
            nj += len(fa.joints)
            nb += len(fa.bones)
            nr += int(max(reg_c.max(initial=-1), breg_c.max(initial=-1))) + 1
            comp_meta.append({k: v for k, v in fa.meta.items() if k != "timings"}
                             | {"vertices": int(len(vids)), "joints": int(len(fa.joints)),
                                "bones": int(len(fa.bones))})
            self.progress("first_approximation", (c + 1) / self.n_components)
        self.component_meta = comp_meta
        self._bone_spacing = np.concatenate(spacing)
        areas = fn = None
        with self._timed("weights"):
            if p.area_weighted:
                fn = face_cross(V, F)           # the centring's surface normals use it too
                areas = vertex_areas(V, F, fn)
                # mean 1: E stays on the vertex-sum scale
                w = areas * (len(V) / max(areas.sum(), 1e-300))
            else:
                w = np.ones(len(V))
        st = PipelineState(V, F, w, np.concatenate(joints), np.concatenate(bones), bone, t, region,
                           np.unique(np.concatenate(pairs), axis=0))
        st.areas = areas
        if self.n_components == 1 and "size" in comp_meta[0]:
            # the one component is the working mesh, its vertices in order: the size its first
            # approximation measured is the state's (the same minimum enclosing ball)
            st._size = float(comp_meta[0]["size"])
        st.face_cross = fn
        st._inside = self._inside
        st.key = np.where(np.isfinite(key), key, 0.0)
        st.record("initialise", sum(self.timings.get(k, 0.0) for k in
                                    ("pole", "contours", "reeb", "meb", "mapping")))
        return st

    def _centre_and_edit(self) -> None:
        p, st = self.params, self.state
        t0 = time.perf_counter()
        with self._timed("centre"):
            centre_stage(st, self._bone_spacing, smooth=p.smoothness, seed=p.seed)
        st.record("centre", time.perf_counter() - t0, medial_points=st.medial_points)
        self.progress("centre", 1.0)
        t0 = time.perf_counter()
        with self._timed("edit"):
            self.edit_log = edit_stage(st, prune=p.prune, simplify=p.simplify,
                                       max_joints=p.max_joints, diag=st.size)
        st.record("edit", time.perf_counter() - t0)
        self.progress("edit", 1.0)

    def _fit_problem(self) -> FitProblem:
        """The final fit's problem: all vertices, or an area-weighted subset above
        ``max_fit_points`` (an unbiased quadrature of the same surface integral)."""
        p, st = self.params, self.state
        pr = st.problem().copy()
        pr.meta["regularisation"] = {"smoothness": 0.0, "containment": float(p.containment),
                                     "surface": (st.V, st.F), "anchor": float(p.centring),
                                     "anchor_points": st.joints[:, :3].copy()}
        self.fit_subset = None
        n = len(pr.points)
        if p.area_weighted and p.max_fit_points and n > p.max_fit_points:
            idx = canonical_subset(st.key, p.max_fit_points, p.seed)
            self.fit_subset = idx
            pr = FitProblem(pr.points[idx], pr.weights[idx] * (n / p.max_fit_points), pr.joints,
                            pr.bones, pr.bone[idx], pr.t[idx], pr.meta)
        return pr

    def steps(self) -> Iterator[SolverState]:
        """Run the final fit, yielding its state after every iteration (the first is E0)."""
        p = self.params
        t0 = time.perf_counter()
        try:
            for s in solve_steps(self._fit, solver=p.solver, max_iterations=p.max_iterations,
                                 tolerance=p.tolerance, refit_mapping=p.refit_mapping):
                self._solver_state = s
                self.energy.append(float(s.energy))
                self.progress("optimise", min(s.iteration / max(p.max_iterations, 1), 1.0))
                yield s
        finally:
            self.timings["optimise"] = self.timings.get("optimise", 0.0) + time.perf_counter() - t0

    def current_skeleton(self) -> Skeleton:
        """The skeleton as it stands now (before the fit: the centred, edited curve)."""
        s = self._solver_state
        if s is None:
            joints, bone, t = self.state.joints, self.state.bone, self.state.t
        else:
            joints = _flip_radii(s.joints)
            bone, t = self._mapping(joints, s)
        return self._to_skeleton(joints, self.state.bones, bone, t, self.energy)

    def result(self) -> Skeleton:
        """Run any remaining steps and return the final Skeleton; its ``energy[-1]`` is the E
        of the returned skeleton with its returned mapping."""
        if self._finished is not None:
            return self._finished
        if self._solver_state is None or not self._solver_state.done:
            for _ in self.steps():
                pass
        st, s = self.state, self._solver_state
        before_fit = st.joints.copy()
        t0 = time.perf_counter()
        with self._timed("finish"):
            st.joints = _flip_radii(s.joints)
            _into_box(st)
            st.bone, st.t = self._mapping(st.joints, s)
        st.record("fit", self.timings.get("optimise", 0.0) + time.perf_counter() - t0,
                  iterations=int(s.iteration))
        if self.params.centre and st.medial is not None:
            t0 = time.perf_counter()
            with self._timed("radii"):
                if FIT_SMOOTHING > 0:
                    # the fit of E moves joints a little each; a wiggle of neighbours in
                    # opposite directions reads as a zig-zag: smooth it out along the chains
                    st.joints[:, :3] = smooth_chains(st.joints, st.bones, FIT_SMOOTHING)
                if FOLD_GUARD:
                    # positions only (crossings measured with the edit stage's radii), so the
                    # radii are fitted once, after
                    undo_new_folds(st.joints, st.bones, before_fit, st.diag)
                if SURFACE_RADII:
                    # with the polish to come these radii only gauge the sections' reach
                    # (and its fold guard's crossings): least squares, no reweighting
                    st.joints[:, 3], st.bone, st.t = fit_radii_surface(
                        st.V, st.weights, st.joints, st.bones, rounds=0 if POLISH else
                        SURFACE_RADII_ROUNDS)
            st.record("radii", time.perf_counter() - t0)
            t0 = time.perf_counter()
            with self._timed("contain"):
                self.contain_log = contain_stage(st, st.inside, st.medial, diag=st.size,
                                                 max_joints=self.params.max_joints)
                _into_box(st)
            st.record("contain", time.perf_counter() - t0)
            if POLISH:
                t0 = time.perf_counter()
                with self._timed("polish"):
                    moved = self._polish()
                st.record("polish", time.perf_counter() - t0, moved=moved)
        # E after every stage (all vertices, each stage's own mapping); the last is the E of
        # the returned skeleton with its returned mapping. The fit's iterations are in meta.
        E = [x["energy"] for x in st.log]
        self._finished = self._to_skeleton(st.joints, st.bones, st.bone, st.t, E)
        return self._finished

    def _polish(self) -> int:
        """The polish stage: two loops' sides in one part zipped into one strand where they
        share cross-sections (``SHEET_ZIP``), two loops joined by a bridge across one web given
        a shared rung across it (``RUNGS``), chain ends bent into a flat part's corner cut back
        (``FLAT_CORNERS``), a flap's chain laid into the flap's middle (:mod:`.flaps`), then in
        ``POLISH_PASSES`` passes other chain joints and tips towards their cross-sections'
        centroids (:func:`.cross_section.polish_chains`), junctions onto their trunks
        (:func:`.junctions.onto_trunks`), joints moved into a new fold or crossing (after the
        first pass, also a new zig-zag), or taking a bone further out of the mesh, put back;
        last, bones shorter than ``short_bone_fraction`` of their radius and kinks merged, radii
        refitted to the surface. Returns the number of chain joints that moved in the last
        pass."""
        st = self.state
        if SHEET_ZIP:
            apply_edit(st, *zip_parallel_chains(st.joints, st.bones,
                                                EDIT_CONSTANTS["zip_radius_fraction"],
                                                loops=True, sections=self._shared_sections))
        if RUNGS:
            apply_edit(st, *bridges_to_rungs(st.joints, st.bones, self._section,
                                             inside=st.inside))
        if FLAT_CORNERS:
            apply_edit(st, *trim_flat_corners(st.V, st.F, st.joints, st.bones, inside=st.inside,
                                              face_of=st.faces_around,
                                              vertex_edge=st.vertex_edges))
        before = st.joints.copy()
        laid = np.zeros(0, np.int64)
        if FLAPS:
            laid, Y = lay_flaps(st.V, st.F, st.weights, st.joints, st.bones, st.inside,
                                st.medial[0], face_of=st.faces_around,
                                vertex_edge=st.vertex_edges)
            st.joints[laid, :3] = Y
        for k, (rounds, step) in enumerate(POLISH_PASSES):
            if k > 0:
                # the sections' reach is counted in radii: refitted to the surface (one
                # reweighting) now that the joints sit nearer their sections' centres
                before = st.joints.copy()
                st.joints[:, 3], st.bone, st.t = fit_radii_surface(st.V, st.weights, st.joints,
                                                                   st.bones, rounds=1)
            moved = self._polish_pass(before, laid, rounds, step, turn_guard=k > 0)
        # short bones merged with the radii the polish had, then again with the fitted ones
        # (the fitted radius can be much larger: the hand kept a bone of 0.057 r)
        short = EDIT_CONSTANTS["short_bone_fraction"]
        merge = (lambda: merge_short_bones(st.joints, st.bones, short)) if short > 0 else None
        self._take_merge(merge)
        self._fit_final_radii()
        # again with the fitted radii, and the kinks inside their joint's ball (both merges:
        # sigma follows, the radii are fitted once more if either took a joint)
        changed = self._take_merge(merge)
        for k in range(KINK_ROUNDS if KINKS else 0):
            # again after a refit: a merge can leave its neighbour a kink, or the refitted
            # radius make one (the hand's palm: a joint turning by 100 degrees merged, the next
            # then turned by 96 on bones summing to 0.95 of its refitted radius); between the
            # rounds the radii by the nearest-bone fit alone (the silhouette's, 10x its cost,
            # once after)
            if not self._take_merge(lambda: remove_kinks(
                    st.joints, st.bones, EDIT_CONSTANTS["sharp_turn"], inside=st.inside)):
                break
            changed = True
            if k + 1 < KINK_ROUNDS:
                st.joints[:, 3], st.bone, st.t = fit_radii_surface(st.V, st.weights, st.joints,
                                                                   st.bones, rounds=1)
        if changed:
            self._fit_final_radii()
        return moved

    def _polish_pass(self, before, laid, rounds, step, turn_guard=False) -> int:
        """``rounds`` of :func:`.cross_section.polish_chains` with ``step`` (joints ``laid``
        held), junctions onto their trunks, then the moves that made a new fold or crossing, or took a bone
        further out of the mesh than at ``before`` (with ``turn_guard``, or a new zig-zag), put
        back. Returns the joints that moved."""
        st = self.state
        X, moved = polish_chains(st.V, st.F, st.joints, st.bones, st.inside,
                                 face_of=st.faces_around, vertex_edge=st.vertex_edges,
                                 fixed=laid, rounds=rounds, step=step)
        if TRUNK_JUNCTIONS:
            # (a junction whose trunk line leaves the mesh stays where it was)
            Y = onto_trunks(X, st.joints[:, 3], st.bones)
            out = ~st.inside(Y)
            Y[out] = X[out]
            X = Y
        st.joints[:, :3] = X
        # joints whose moves made a new fold or crossing, or took a bone further out of the mesh
        # (each move was checked for its joint only: a bone can cut a corner out), put back;
        # both tests in one loop: a joint put back for one may make the other's defect
        guards = []
        if FOLD_GUARD:
            # positions only (crossings measured with the radii before): one radius fit after
            guards.append(fold_worse(st.bones, before, st.diag))
        if INSIDE_GUARD:
            guards.append(outside_worse(st.bones, before, st.inside))
        if turn_guard:
            # beside a junction: the kink merge after the polish leaves those alone
            guards.append(turn_worse(st.bones, before, EDIT_CONSTANTS["sharp_turn"],
                                     beside_junctions(len(st.joints), st.bones)))
        if guards:
            put_back(st.joints, st.bones, before,
                     lambda X: np.unique(np.concatenate([g(X) for g in guards])))
        return moved

    def _take_merge(self, merge) -> bool:
        """A merge of the polish's end (``merge()`` -> joints, bones, bone_map; None: none) into
        the state, sigma following its bone map, the radii as they are; whether it took a joint."""
        st = self.state
        if merge is None:
            return False
        J2, B2, bone_map = merge()
        if len(J2) == len(st.joints):
            return False
        st.joints, st.bones = J2, B2
        st.apply_bone_map(bone_map)
        return True

    def _fit_final_radii(self) -> None:
        """The returned radii: fitted to the surface, then to the silhouette; sigma mapped."""
        st = self.state
        if SURFACE_RADII:
            # one reweighting is start enough for the silhouette's fit (the five of the
            # nearest-bone fit alone: the same mean recon, 0.73-0.75x over 1-5)
            st.joints[:, 3], st.bone, st.t = fit_radii_surface(
                st.V, st.weights, st.joints, st.bones,
                rounds=1 if SILHOUETTE_RADII else SURFACE_RADII_ROUNDS)
            if SILHOUETTE_RADII:
                st.joints[:, 3] = self._silhouette_radii()
        else:
            st.remap()

    def _section(self, X, T, reach):
        """(centroid, extent) of the mesh's cross-section through the point X across T within
        ``reach`` (:func:`.cross_section.section_loops`; extent inf: none)."""
        st = self.state
        C, extent, _ = section_loops(st.V, st.F, X[None], T[None], [reach],
                                     face_of=st.faces_around, vertex_edge=st.vertex_edges)
        return C[0], extent[0]

    def _shared_sections(self, pairs) -> list:
        """For each path pair ``(JP, JQ)`` (joint rows x, y, z, r), which joints of ``JP`` share
        their cross-section with ``JQ``, looked for within ``SHEET_ZIP_REACH`` of the pair's
        largest radius (:func:`.cross_section.shared_sections_many`). The zip goes only as far
        as the first joint past the junction that shares neither its section nor the distance
        rule's half radius, and most pairs part at once: their first joint is tested alone,
        then the rest of the pairs that pass it."""
        st = self.state
        frac = EDIT_CONSTANTS["zip_radius_fraction"]
        geo = dict(face_of=st.faces_around, vertex_edge=st.vertex_edges)
        reach, near, close = [], [], []
        for JP, JQ in pairs:
            reach.append(SHEET_ZIP_REACH * float(max(np.abs(JP[:, 3]).max(),
                                                     np.abs(JQ[:, 3]).max())))
            d = point_polyline_distance(JP[:, :3], JQ[:, :3])
            near.append(d <= reach[-1])         # farther: no loop within the reach holds both
            close.append(d <= frac * JP[:, 3])  # the distance rule passes anyway
        one = [np.arange(len(JP)) == 1 for JP, _ in pairs]
        got = shared_sections_many(st.V, st.F, [(JP[:, :3], JQ[:, :3], r, t & m)
                                                for (JP, JQ), r, t, m in zip(pairs, reach, one, near)],
                                   **geo)
        rest = []
        for n, (JP, _) in enumerate(pairs):
            if len(JP) > 2 and (got[n][1] or close[n][1]):
                rest.append(n)
        if rest:
            more = shared_sections_many(
                st.V, st.F, [(pairs[n][0][:, :3], pairs[n][1][:, :3], reach[n],
                              (np.arange(len(pairs[n][0])) >= 2) & near[n]) for n in rest], **geo)
            for n, g in zip(rest, more):
                got[n] = got[n] | g
        return got

    def _silhouette_radii(self) -> np.ndarray:
        """The radii refined on the silhouette itself (:mod:`.silhouette_radii`): every vertex
        with its area, or above ``SAMPLES`` vertices a uniform draw of them with their areas."""
        from .silhouette_radii import SAMPLES, fit_radii_silhouette
        st = self.state
        n = len(st.V)
        if n > SAMPLES:
            # a uniform draw, each vertex with its area: an unbiased estimate of the area-weighted
            # sum whatever the share drawn (a draw with probabilities by area is not one when it
            # takes most of the vertices)
            idx = canonical_subset(st.key, SAMPLES, self.params.seed + 2)
        else:
            idx = np.arange(n)
        w = st.weights[idx]
        return fit_radii_silhouette(st.V[idx], w, st.joints, st.bones)[0]

    def _mapping(self, joints, s: SolverState):
        """sigma of every working vertex: the solver's own when it fitted every vertex,
        else the closest point on the bones of the vertex's region."""
        if self.fit_subset is None:
            return s.bone, s.t
        bone, t, _ = closest_on_bones(self.state.V, joints, self.state.bones,
                                      self.state.candidates())
        return bone, t

    # -- output --------------------------------------------------------------------------------
    def _to_skeleton(self, joints, bones, bone_w, t_w, E) -> Skeleton:
        wi = self.mesh.work_index
        iso = wi < 0
        if iso.any():
            # Isolated input vertices take the mapping of the nearest working vertex.
            _, nn = cKDTree(self.mesh.V).query(self._input_V[iso])
            wi = wi.copy()
            wi[iso] = nn
        joints = np.array(joints, dtype=np.float64)
        joints[:, :3] += self.origin
        return Skeleton(joints, bones, bone_w[wi], t_w[wi], energy=list(E),
                        timings=dict(self.timings), meta=self._meta())

    def _meta(self) -> dict:
        meta = {"params": self.params.to_dict(), "components": int(self.n_components),
                "component_info": self.component_meta, "input": self.mesh.info,
                "fit_points": int(len(self.fit_subset) if self.fit_subset is not None
                                  else len(self.mesh.V)),
                "stages": [dict(x) for x in self.state.log],
                "fit_energy": [float(e) for e in self.energy],
                "fit_points_subset": self.fit_subset is not None,
                # above MEDIAL_TREE_POINTS vertices the medial balls shrink against an
                # area-weighted subsample of the surface (said here, as the fit's subset)
                "medial_points": int(self.state.medial_points),
                "medial_points_subset": bool(0 < self.state.medial_points < len(self.mesh.V))}
        if getattr(self, "edit_log", None) is not None:
            meta["edit"] = self.edit_log
        if getattr(self, "contain_log", None) is not None:
            meta["contain"] = self.contain_log
        return meta


def undo_new_folds(joints, bones, before, D, *, rounds: int | None = None) -> np.ndarray:
    """Put back the joints of bones that fold although they did not in ``before`` (in place).

    Why: E is low wherever the balls explain the surface, so where two chains pass a thin
    place the fit may pull both onto it: a fold (two bones within 0.01 D that are far apart
    along the skeleton; fertility's handles: 0.014 -> 0.056 of its bones). The edit stage's
    curve had no such pair, so its joints are the better place for those bones.

    Parameters
    ----------
    joints : (J, 4) float, changed in place (x, y, z only)
    bones : (B, 2) int
    before : (J, 4) float
        The same joints before the fit.
    D : float
        The mesh's bounding-box diagonal (the unit of the fold measure).

    Returns
    -------
    (J,) bool : the joints put back.
    """
    return put_back(joints, bones, before, fold_worse(bones, before, D), rounds=rounds)


def fold_worse(bones, before, D):
    """``worse(X)`` for :func:`.edit.put_back`: the bones of folds (and crossings, measured
    with ``before``'s radii) at ``X`` that ``before`` does not have."""
    from .quality import crossing_pairs, fold_pairs

    def pairs(X):
        # folds, and crossings measured with the edit stage's radii (the part's thickness),
        # each kind on its own: two bones that crossed before and fold now make a new fold
        Xr = np.column_stack([X[:, :3], before[:, 3]])
        found = [("fold",) + tuple(p) for p in fold_pairs(X, bones, D).tolist()]
        if CROSSING_GUARD:
            found += [("cross",) + tuple(p) for p in crossing_pairs(Xr, bones, D).tolist()]
        return found

    old = set(pairs(before))
    return lambda X: np.unique(np.asarray(
        [b for p in pairs(X) if p not in old for b in p[1:]], np.int64))


def _into_box(st) -> None:
    """Joints outside the mesh's bounding box projected onto it (in place).

    A joint outside the box is outside the shape. On a tiny flat solid (8-40 hull points,
    issue 12's property test) the fit can push one there, and the medial point a bone is split
    at can lie off a shape that has almost no inside."""
    st.joints[:, :3] = np.clip(st.joints[:, :3], *st.bbox)


def _flip_radii(joints) -> np.ndarray:
    """Joints with negative radii flipped (r enters E squared; the paper does the same)."""
    j = np.array(joints, dtype=np.float64)
    j[:, 3] = np.abs(j[:, 3])
    return j


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
        Joints, bones, the mapping of every input vertex (input order), the E of each stage
        (the last is the E of the returned skeleton), timings, and per-stage meta.

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
