"""Evaluate any curve-skeleton of a mesh by J: the paper's measure as a tool (issue 33).

The paper: "the method provides a strict way to evaluate and compare various 1D skeletons of
the same 3D object". :func:`evaluate` takes a skeleton from anywhere (:mod:`.skeleton_input`:
curveskel's, CGAL's, an armature, a plain JSON) and reports

* J and each of its terms (:mod:`.objective`), and the paper's E (eq. 8);
* the share of the bones' length inside the mesh, and the skeleton's topology against the
  mesh's (components, cycles against the genus);
* per bone, how much of the surface it explains (its share of the area) and how badly (the
  mean misfit of that surface, its share of J's fit, its centring and inside share);
* per input vertex, the residual ``|v - sigma(v)| - r(sigma(v))`` (sigma: the nearest point on
  any bone, J's own), in the mesh's units: positive where the silhouette falls short of the
  surface (a part with no bone), negative where it bulges out.

Missing pieces are made as the pipeline would make them for that graph: sigma is J's (each
sample's nearest bone point), and radii, when the skeleton has none, are J's minimiser with
the positions held (:func:`prepare`). J's unit of length per sample is its distance from the
given skeleton (:mod:`.objective.for_skeleton`), so J here is not the J a curveskel run logs
(whose unit comes from its first approximation); :func:`compare` puts several skeletons on one
ruler. The reconstruction distances, which need the silhouette's exact distance field, are
measured outside the core (``curveskel_addon.measure.evaluate_report``).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from .config import CONFIG
from .errors import CurveSkelError
from .geometry.rows import col_max, col_min, row_norm
from .geometry.samples import canonical_subset, face_samples
from .geometry.segments import closest_on_bones
from .mesh import Mesh
from .mesh_input import clean_mesh
from .objective.for_skeleton import common_scale, objective_for_skeleton, skeleton_graph
from .objective.minimise import minimise
from .objective.terms import BONE_POINTS, bone_centres, fit_term
from .params import SkeletonParams, check_params
from .skeleton_input import OutsideSkeleton, as_outside_skeleton

__all__ = ["SkeletonFit", "SkeletonReport", "prepare", "evaluate", "compare", "report_of"]


@dataclass
class SkeletonFit:
    """A mesh and a given skeleton, ready for J.

    Attributes
    ----------
    skeleton : OutsideSkeleton
        As given (joint indices are the caller's).
    used : (k,) int
        The given joints some bone uses: the graph's joint ``a`` is the given joint ``used[a]``.
    clean : CleanMesh
    origin : (3,) float
        The working space's origin in the mesh's space (J is computed about the middle of the
        mesh's box; joints go back on output).
    mesh : Mesh
    objective : Objective
    graph : SkeletonGraph
        The given skeleton in working space, radii fitted when it had none.
    radii_fitted : bool
    input_vertices : (n, 3) float
        The caller's vertices in working space (every one, used by a face or not).
    seconds : dict
    """

    skeleton: OutsideSkeleton
    used: np.ndarray
    clean: object
    origin: np.ndarray
    mesh: Mesh
    objective: object
    graph: object
    radii_fitted: bool
    input_vertices: np.ndarray
    seconds: dict = field(default_factory=dict)

    def keeps_graph(self, graph) -> bool:
        """Whether ``graph`` has the given skeleton's bones (a topology edit makes another)."""
        return graph.bones.shape == self.graph.bones.shape and \
            bool(np.array_equal(graph.bones, self.graph.bones))

    def joints_out(self, graph) -> np.ndarray:
        """(J, 4) the graph's joints in the mesh's space: with the given skeleton's bones, in
        the caller's indices (joints of no bone keep their place, radius 0 when none was
        given); after a topology edit, the graph's own."""
        Z = np.array(graph.joints)
        if not self.keeps_graph(graph):
            Z[:, :3] += self.origin
            return Z
        sk = self.skeleton
        out = np.zeros((sk.n_joints, 4))
        out[:, :3] = sk.joints
        if sk.radii is not None:
            out[:, 3] = sk.radii
        out[self.used, :3] = Z[:, :3] + self.origin
        out[self.used, 3] = Z[:, 3]
        return out

    def bones_out(self, graph) -> np.ndarray:
        """(B, 2) the graph's bones, in the caller's joint indices when the graph is kept."""
        return self.skeleton.bones if self.keeps_graph(graph) else np.array(graph.bones)


@dataclass
class SkeletonReport:
    """What :func:`evaluate` finds (see the module doc); lengths in the mesh's units unless
    named ``/ D``.

    Attributes
    ----------
    J : float
    terms : dict
        Each term of J unweighted (``fit``, ``centre``, ``smooth``, ``contain``, ``joints``,
        ``tips``); ``weighted`` holds each one's share of J.
    weighted : dict
    E : float
        The paper's E (eq. 8), each sample on the bone nearest to it on the given skeleton.
    inside_fraction : float
        Share of the points along the bones (J's containment points) inside the mesh.
    topology : dict
        ``skeleton_components``, ``skeleton_cycles``, ``mesh_components``, ``mesh_genus``,
        ``match`` (the same components and as many cycles as the genus).
    per_bone : dict of (B,) arrays
        ``area``: share of the surface nearest the bone; ``misfit``: that surface's
        area-weighted mean ``|residual| / D``; ``fit``: its share of J's fit term; ``centre``:
        the bone's centring term; ``inside``: share of its points inside the mesh.
    vertex_residual : (n,) float
        ``|v - sigma(v)| - r(sigma(v))`` for every input vertex, in input order.
    joints : (J, 4) float
        The skeleton evaluated (radii fitted when it had none), in the mesh's space.
    bones : (B, 2) int
    D : float
        The mesh's size (its minimum enclosing ball's diameter).
    radii_fitted : bool
    seconds : dict
    """

    J: float
    terms: dict
    weighted: dict
    E: float
    inside_fraction: float
    topology: dict
    per_bone: dict
    vertex_residual: np.ndarray = field(repr=False)
    joints: np.ndarray = field(repr=False)
    bones: np.ndarray = field(repr=False)
    D: float = 1.0
    radii_fitted: bool = False
    seconds: dict = field(default_factory=dict)

    def worst_bones(self, k) -> np.ndarray:
        """The ``k`` bones whose surface fits worst (largest ``misfit``), worst first."""
        return np.argsort(-self.per_bone["misfit"], kind="stable")[:k]

    def to_dict(self, *, vertices=False) -> dict:
        """A JSON-ready dict (``vertex_residual`` only with ``vertices``)."""
        nb = len(self.bones)
        per_bone = [{"bone": [int(i), int(j)], **{k: float(v[b]) for k, v in self.per_bone.items()}}
                    for b, (i, j) in zip(range(nb), self.bones.tolist())]
        out = {"J": self.J, "terms": dict(self.terms), "weighted": dict(self.weighted),
               "E": self.E, "inside_fraction": self.inside_fraction,
               "topology": dict(self.topology), "per_bone": per_bone,
               "joints": self.joints.tolist(), "bones": self.bones.tolist(), "D": self.D,
               "radii_fitted": self.radii_fitted, "seconds": dict(self.seconds)}
        if vertices:
            out["vertex_residual"] = self.vertex_residual.tolist()
        return out


# -- the setup ---------------------------------------------------------------------------------
def _samples(mesh, params):
    """J's surface samples, as the pipeline takes them; above the budget a uniform subset
    keyed by the distance from the surface's centroid (the pipeline keys by geodesic distance,
    which needs the first approximation): a rotated or renumbered mesh gets the same points."""
    cfg = CONFIG.objective
    s = face_samples(mesh.V, mesh.F, cfg.sample_length * params.spacing * mesh.D)
    if len(s.points) > cfg.max_samples:
        centre = (s.weights @ s.points) / s.weights.sum()
        idx = canonical_subset(row_norm(s.points - centre), cfg.max_samples, params.seed)
        s = s.subset(idx, float(s.weights.sum() / s.weights[idx].sum()))
    return s


def bone_points(Z, bones) -> np.ndarray:
    """(B * m, 3) J's containment points along every bone (``BONE_POINTS``), bone by bone."""
    X = np.asarray(Z)[:, :3]
    i, j = bones[:, 0], bones[:, 1]
    u = BONE_POINTS
    return (u[None, :, None] * X[i][:, None, :]
            + (1 - u)[None, :, None] * X[j][:, None, :]).reshape(-1, 3)


def _initial_radii(objective, graph) -> np.ndarray:
    """(J,) each joint's radius to start from: the mean thickness of its bones."""
    bones = graph.bones
    thick = np.asarray(graph.thick)
    J = graph.n_joints
    s = np.bincount(bones.ravel(), np.repeat(thick, 2), J)
    n = np.bincount(bones.ravel(), minlength=J)
    return s / np.maximum(n, 1)


def prepare(V, F, skeleton, params: SkeletonParams | None = None, *, fit_radii=None,
            scale_with=()) -> SkeletonFit:
    """The mesh cleaned, J built for the skeleton, its radii fitted when missing.

    Parameters
    ----------
    V : (n, 3) float
    F : (m, 3) int, or polygons
    skeleton : any form :func:`.skeleton_input.as_outside_skeleton` accepts
    params : SkeletonParams, optional
        *Detail Size* (J's sampling and thickness floor), *Smoothness*, *Branch Pruning* (J's
        weights), ``max_iterations`` (the radii's fit), ``seed`` (the samples' subset),
        ``min_component_area`` (the mesh's cleaning).
    fit_radii : bool, optional
        Fit the radii (positions held) even when the skeleton has them; by default only when
        it has none.
    scale_with : sequence of skeletons
        Other skeletons of the mesh whose distances join this one's in J's unit of length
        (:func:`.objective.for_skeleton.common_scale`): for comparing them.

    Raises
    ------
    CurveSkelError
        Bad mesh, bad skeleton, or a skeleton none of whose bones passes through the mesh.
    """
    params = SkeletonParams() if params is None else params
    if not isinstance(params, SkeletonParams):
        raise CurveSkelError(f"params must be a SkeletonParams, got {type(params).__name__}")
    check_params(params)
    seconds = {}
    t0 = time.perf_counter()
    sk = as_outside_skeleton(skeleton)
    cm = clean_mesh(V, F, min_component_area=params.min_component_area)
    origin = (col_min(cm.V) + col_max(cm.V)) / 2
    mesh = Mesh(cm.V - origin, cm.F)
    samples = _samples(mesh, params)
    seconds["mesh"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    used = np.flatnonzero(sk.used)
    local = np.full(sk.n_joints, -1, np.int64)
    local[used] = np.arange(len(used))
    bones = local[sk.bones]
    Z = np.zeros((len(used), 4))
    Z[:, :3] = sk.joints[used] - origin
    if sk.radii is not None:
        Z[:, 3] = sk.radii[used]
    inside = mesh.inside(bone_points(Z, bones))
    if not inside.any():
        raise CurveSkelError("the skeleton lies outside the mesh: no bone passes through its "
                             "inside (are the skeleton and the mesh in the same space?)")
    graph = skeleton_graph(Z, bones)
    others = [_working_graph(as_outside_skeleton(o), origin) for o in scale_with]
    scale = common_scale(mesh, samples, [graph] + others, params.spacing) if others else None
    objective, graph = objective_for_skeleton(mesh, samples, graph, params, scale)
    fitted = sk.radii is None if fit_radii is None else bool(fit_radii)
    if sk.radii is None:
        Z[:, 3] = _initial_radii(objective, graph)
        graph = graph.with_joints(Z)
    if fitted:
        # to the search's round tolerance: the report's J to three digits (a refinement goes
        # on from here to the final tolerance)
        graph, _, _ = minimise(objective, graph, max_iterations=params.max_iterations,
                               tolerance=CONFIG.search.round_tolerance,
                               fixed=np.ones(graph.n_joints, bool))
    seconds["objective"] = time.perf_counter() - t0
    V_in = np.asarray(V, np.float64).reshape(-1, 3) - origin
    return SkeletonFit(sk, used, cm, origin, mesh, objective, graph, fitted, V_in, seconds)


def _working_graph(sk: OutsideSkeleton, origin):
    Z = np.zeros((sk.n_joints, 4))
    Z[:, :3] = sk.joints - origin
    return skeleton_graph(Z, sk.bones)


# -- the report --------------------------------------------------------------------------------
def _topology(clean, mesh, graph) -> dict:
    """Components and cycles of the skeleton; components and genus of the (closed, cleaned)
    mesh, ``g = (2 - chi) / 2`` per component."""
    J = graph.n_joints
    bones = graph.bones
    A = coo_matrix((np.ones(len(bones)), (bones[:, 0], bones[:, 1])), shape=(J, J))
    n_sk, _ = connected_components(A, directed=False)
    cycles = len(bones) - J + n_sk
    k, labels = clean.components if clean.components is not None else (1, np.zeros(len(mesh.V), int))
    E = mesh.edges[0]
    chi = (np.bincount(labels, minlength=k) - np.bincount(labels[E[:, 0]], minlength=k)
           + np.bincount(labels[mesh.F[:, 0]], minlength=k))
    genus = int(np.sum((2 - chi) // 2))
    return {"skeleton_components": int(n_sk), "skeleton_cycles": int(cycles),
            "mesh_components": int(k), "mesh_genus": genus,
            "match": bool(n_sk == k and cycles == genus)}


def vertex_residuals(points, graph) -> np.ndarray:
    """(n,) ``|p - sigma(p)| - r(sigma(p))`` for each point, sigma its nearest bone point."""
    bone, t, d2 = closest_on_bones(points, graph.joints, graph.bones)
    Z = np.asarray(graph.joints)
    ij = graph.bones[bone]
    r = t * Z[ij[:, 0], 3] + (1.0 - t) * Z[ij[:, 1], 3]
    return np.sqrt(d2) - r


def _per_bone(fit, graph, ev, inside) -> dict:
    obj = fit.objective
    s = obj.samples
    Z = np.asarray(graph.joints)
    B = len(graph.bones)
    ij = graph.bones[ev.bone]
    S = ev.t[:, None] * Z[ij[:, 0]] + (1.0 - ev.t)[:, None] * Z[ij[:, 1]]
    res = np.abs(row_norm(s.points - S[:, :3]) - S[:, 3]) / obj.D
    W = np.bincount(ev.bone, s.weights, B)
    misfit = np.bincount(ev.bone, s.weights * res, B) / np.maximum(W, 1e-300)
    # each sample's fit as J has it (the soft minimum over its candidate bones), given to its
    # nearest bone: the shares add up to J's fit term
    r = fit_term(Z, s, graph.bones, ev.sigma[0], obj.area, obj.scale,
                 softness=CONFIG.objective.fit_softness, jacobian=False)[0]
    share = np.bincount(ev.bone, r * r, B)
    X = Z[:, :3]
    centre = (bone_centres(X[graph.bones[:, 0]], X[graph.bones[:, 1]], graph.bones, obj.mesh,
                           obj.D, obj.thickness(graph), graph.n_joints, jacobian=None)
              if obj.weights.centre else np.zeros(B))
    return {"area": W / obj.area, "misfit": misfit, "fit": share, "centre": centre,
            "inside": inside.reshape(B, -1).mean(1)}


def report_of(fit: SkeletonFit, graph=None, evaluation=None) -> SkeletonReport:
    """The report of ``graph`` (by default the fit's own) on the fit's J."""
    t0 = time.perf_counter()
    graph = fit.graph if graph is None else graph
    obj = fit.objective
    ev = obj.evaluate(graph) if evaluation is None else evaluation
    w = obj.weights
    weight = {"fit": 1.0, "centre": w.centre, "smooth": w.smooth, "contain": w.contain,
              "joints": w.joint, "tips": w.branch}
    weighted = {k: weight[k] * v for k, v in ev.terms.items() if k in weight}
    inside = obj.mesh.inside(bone_points(graph.joints, graph.bones))
    per_bone = _per_bone(fit, graph, ev, inside)
    residual = vertex_residuals(fit.input_vertices, graph)
    seconds = dict(fit.seconds)
    seconds["report"] = time.perf_counter() - t0
    return SkeletonReport(J=float(ev.value), terms=dict(ev.terms), weighted=weighted,
                          E=float(obj.paper_energy(graph)), inside_fraction=float(inside.mean()),
                          topology=_topology(fit.clean, obj.mesh, graph), per_bone=per_bone,
                          vertex_residual=residual, joints=fit.joints_out(graph),
                          bones=fit.bones_out(graph), D=float(obj.D),
                          radii_fitted=fit.radii_fitted, seconds=seconds)


def evaluate(V, F, skeleton, params: SkeletonParams | None = None, *,
             fit_radii=None) -> SkeletonReport:
    """How well ``skeleton`` explains the mesh (V, F), by J (module doc).

    Parameters
    ----------
    V : (n, 3) float
    F : (m, 3) int, or polygons
    skeleton : Skeleton, dict, (joints, bones) or OutsideSkeleton
        In the mesh's own space; joints with or without radii.
    params : SkeletonParams, optional
    fit_radii : bool, optional
        See :func:`prepare`.

    Returns
    -------
    SkeletonReport

    Raises
    ------
    CurveSkelError
        Bad mesh, bad skeleton, or a skeleton entirely outside the mesh.

    Examples
    --------
    >>> rep = evaluate(V, F, {"joints": [[0, 0, -1], [0, 0, 1]], "bones": [[0, 1]]})  # doctest: +SKIP
    >>> rep.J, rep.terms["fit"], rep.per_bone["misfit"]                                # doctest: +SKIP
    """
    return report_of(prepare(V, F, skeleton, params, fit_radii=fit_radii))


def compare(V, F, skeletons, params: SkeletonParams | None = None) -> list:
    """Reports of several skeletons of one mesh on one ruler: J's unit of length at every sample
    is its distance from the nearest of them (:func:`.objective.for_skeleton.common_scale`), so
    the lowest J is the skeleton that explains the mesh best (the paper's "choose the best one
    among others"). Radii are fitted for every skeleton (given radii are estimates of unknown
    kind; the comparison is of the curves).

    Returns
    -------
    list of SkeletonReport, in the order given
    """
    skeletons = [as_outside_skeleton(s) for s in skeletons]
    out = []
    for k, sk in enumerate(skeletons):
        others = skeletons[:k] + skeletons[k + 1:]
        out.append(report_of(prepare(V, F, sk, params, fit_radii=True, scale_with=others)))
    return out
