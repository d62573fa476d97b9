"""skeletonize() as the search for the minimum of one objective J (work in progress: becomes
pipeline.py)."""

from __future__ import annotations

import time

import numpy as np
from scipy.spatial import cKDTree

from .geometry.samples import face_samples
from .initialise.first import initial_graph
from .mapping import closest_on_bones
from .mesh import Mesh
from .mesh_graph import components
from .mesh_input import clean_mesh
from .objective.objective import Objective, Weights
from .params import SkeletonParams
from .search import SearchLog, search
from .skeleton import Skeleton
from .state import candidates_from_pairs, canonical_subset

__all__ = ["skeletonize"]

MAX_SAMPLES = 30_000


def skeletonize(V, F, params: SkeletonParams | None = None, progress=None, *, weights=None,
                **overrides) -> Skeleton:
    if overrides:
        base = (params or SkeletonParams()).to_dict()
        base.update(overrides)
        params = SkeletonParams.from_dict(base)
    p = params or SkeletonParams()
    t0 = time.perf_counter()
    cm = clean_mesh(V, F, min_component_area=p.min_component_area)
    origin = (cm.V.min(axis=0) + cm.V.max(axis=0)) / 2
    mesh = Mesh(cm.V - origin, cm.F)
    n_comp, labels = cm.components or components(len(mesh.V), mesh.F)
    size_h = p.spacing * mesh.D
    samples = face_samples(mesh.V, mesh.F, size_h / 2)
    one = n_comp == 1
    init = initial_graph(mesh, labels, n_comp, samples, spacing=p.spacing, seed=p.seed,
                         inside=(lambda: mesh.inside) if one else None,
                         edges=cm.edge_table() if one else None)
    sreg = init.sample_region
    if len(samples.points) > MAX_SAMPLES:
        fs = np.einsum("ij,ij->i", samples.bary, init.key[mesh.F[samples.face]])
        idx = canonical_subset(fs, MAX_SAMPLES, p.seed)
        samples = samples.subset(idx, float(samples.weights.sum() / samples.weights[idx].sum()))
        sreg = sreg[idx]
    w = weights or Weights()
    # each sample's thickness: its distance from the first approximation (held in J)
    probe = Objective(mesh, samples, sreg, w, np.ones(len(samples.points)))
    bone0, t0_ = probe.sigma(init.graph)
    Z0 = np.asarray(init.graph.joints)
    ij = init.graph.bones[bone0]
    S0 = t0_[:, None] * Z0[ij[:, 0], :3] + (1 - t0_)[:, None] * Z0[ij[:, 1], :3]
    dist = np.linalg.norm(samples.points - S0, axis=1)
    objective = Objective(mesh, samples, sreg, w, np.maximum(dist, 0.25 * size_h))
    log = SearchLog()
    graph, ev = search(objective, init.graph, log)
    # every working vertex on its region's bones, every input vertex via its working vertex
    n_reg = int(max(init.vertex_region.max(initial=-1), graph.pairs[:, 0].max(initial=-1))) + 1
    cand = candidates_from_pairs(graph.pairs, init.vertex_region, n_reg)
    bone_w, t_w, _ = closest_on_bones(mesh.V, graph.joints, graph.bones, cand)
    wi = cm.work_index.copy()
    iso = wi < 0
    if iso.any():
        _, nn = cKDTree(mesh.V).query(np.asarray(V, np.float64)[iso] - origin)
        wi[iso] = nn
    joints = np.array(graph.joints)
    joints[:, :3] += origin
    meta = {"params": p.to_dict(), "components": int(n_comp), "stages": log.entries,
            "J": float(ev.value), "terms": dict(ev.terms), "input": cm.info,
            "samples": int(len(samples.points))}
    E = [e["terms"]["fit"] for e in log.entries]
    return Skeleton(joints, graph.bones, bone_w[wi], t_w[wi], energy=E,
                    timings={"total": time.perf_counter() - t0}, meta=meta)
