"""J for a skeleton that did not come from curveskel's first approximation.

:meth:`.objective.Objective.for_first_approximation` measures each surface sample's unit of
length, its part's thickness, as its distance from the first approximation, on the bones of
its Reeb region. A skeleton from outside (a hand-drawn armature, a metarig, CGAL's curve) has
no Reeb regions. Its own bones stand in for them: every sample's *region* is the bone nearest
to it on the given skeleton, and that bone is the region's only bone (pairs ``(b, b)``). Then

* each sample's thickness is its distance from the given skeleton (floored as for the first
  approximation): the skeleton is judged in the units of the shape it claims to explain;
* the paper's E is computed with its own kind of sigma, each sample held to the bone of its
  region, so E before and after a refinement compare the same mapping;
* the topology moves (:mod:`..moves`) rewrite the pairs like any other graph's.

Several skeletons of one mesh are compared on one ruler (:func:`common_scale`): each sample's
thickness is its distance from the nearest of them, so J's values are in the same units.
"""

from __future__ import annotations

import numpy as np

from ..config import CONFIG
from ..geometry.segments import closest_on_bones
from ..graph import SkeletonGraph
from .objective import Objective, weights_for

__all__ = ["skeleton_graph", "objective_for_skeleton", "common_scale"]


def skeleton_graph(joints, bones) -> SkeletonGraph:
    """The search's graph of a given skeleton: every bone its own region (pairs ``(b, b)``).

    Parameters
    ----------
    joints : (J, 4) float
        x, y, z, r.
    bones : (B, 2) int
    """
    nb = len(np.asarray(bones).reshape(-1, 2))
    pairs = np.stack([np.arange(nb), np.arange(nb)], 1)
    return SkeletonGraph(joints, bones, pairs)


def _distance(samples, graph):
    bone, _, d2 = closest_on_bones(samples.points, graph.joints, graph.bones)
    return bone, np.sqrt(d2)


def common_scale(mesh, samples, graphs, spacing) -> np.ndarray:
    """(s,) each sample's distance from the nearest of ``graphs`` (all skeletons of one mesh),
    at least the thickness floor: one unit of length for comparing them."""
    d = np.min([_distance(samples, g)[1] for g in graphs], axis=0)
    return np.maximum(d, CONFIG.objective.thickness_floor * spacing * mesh.D)


def objective_for_skeleton(mesh, samples, graph, params, scale=None):
    """J on ``mesh`` for the given skeleton ``graph`` (as :func:`skeleton_graph` builds it).

    Parameters
    ----------
    mesh : Mesh
    samples : Samples
    graph : SkeletonGraph
        Pairs ``(b, b)``: each bone its own region.
    params : SkeletonParams
        *Detail Size* (the thickness floor), *Smoothness* and *Branch Pruning* (J's weights).
    scale : (s,) float, optional
        Each sample's thickness (:func:`common_scale`); by default its distance from ``graph``.

    Returns
    -------
    objective : Objective
    graph : SkeletonGraph
        ``graph`` with each bone's thickness (the centring's unit), held from here on.
    """
    region, _ = _distance(samples, graph)
    # the centring's cross-sections cut from a copy at the samples' resolution, as the
    # pipeline's J has them (a 100k-vertex mesh: the same centres, a fraction of the time)
    coarse = mesh.coarsened(CONFIG.objective.sample_length * params.spacing * mesh.D)
    objective = Objective.for_first_approximation(mesh, samples, region, graph,
                                                  weights_for(params), params.spacing,
                                                  sections=coarse)
    if scale is not None:
        objective = Objective(mesh, samples, objective.weights, scale, paper=region,
                              sections=coarse, resolution=objective.resolution)
    return objective, graph.with_thickness(objective.measure_thickness(graph))
