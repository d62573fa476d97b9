"""The objective J of a skeleton on a mesh, and the Gauss-Newton model its minimisation uses.

    J = fit + w_centre centre + w_smooth smooth + w_contain contain
          + w_joint (number of joints) + w_branch (number of tips)

The terms (:mod:`.terms`) are scale-free sums of squared residuals; the two counts price the
topology: a joint or a branch stays only where it explains the surface better than it costs
(minimum description length). *Smoothness* scales ``w_smooth`` and *Branch Pruning*
``w_branch`` (:func:`weights_for`); the other weights are the method's (:class:`..config.Weights`).

sigma, each surface sample's point on the skeleton, is its nearest point on the nearest cones
(a soft minimum over the few nearest, :func:`.terms.fit_term`): the fit
then measures the distance from the surface to the silhouette, the union of the bones' round
cones. Held to the Reeb regions instead (the paper's sigma), the balls of different parts
overlap where the fit cannot see it and the silhouette bulges out of the surface (a flat-sided
torso: 2.1x CGAL's reconstruction error, 1.1x with the nearest bone); the centring and
smoothness terms, not sigma, now keep a curve from wandering through the volume. The paper's E
with its own sigma is computed for every stage all the same (``terms["E"]``).

Each sample's unit of length, its part's thickness, is its distance from the first
approximation (:meth:`Objective.for_first_approximation`): a property of the mesh and the first
approximation, held through the search, so a part of any size weighs the same for the same
relative error.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree

from ..config import CONFIG, Weights
from ..geometry.segments import closest_on_bones, nearest_on_silhouette
from ..graph import candidates_from_pairs
from . import terms as T

__all__ = ["Evaluation", "Objective", "weights_for"]


def weights_for(params) -> Weights:
    """J's weights for the user's settings: *Smoothness* and *Branch Pruning* scale their
    terms' units."""
    w = CONFIG.weights
    return replace(w, smooth=w.smooth * params.smoothness, branch=w.branch * params.prune)


@dataclass(frozen=True)
class Evaluation:
    """J of one skeleton: its value, each term's (unweighted) value and sigma (``bone``, ``t``:
    each sample's nearest cone; ``sigma``: its candidates, as :meth:`Objective.sigma`)."""

    value: float
    terms: dict
    bone: np.ndarray = field(repr=False)
    t: np.ndarray = field(repr=False)
    sigma: tuple = field(repr=False, default=None)


class Objective:
    """J on one mesh.

    Parameters
    ----------
    mesh : Mesh
    samples : Samples
        Surface quadrature points.
    weights : Weights
    scale : (s,) float
        The thickness of the part each sample lies on: the fit's unit of length there, and,
        averaged over a bone's samples, the centring's unit for that bone.
    paper : (region (s,) int, graph) or None
        The Reeb region of every sample and the first approximation, for the paper's E with
        its own sigma (reported, not minimised).
    sections : Mesh, optional
        The mesh the centring's cross-sections are cut from (a coarser copy at the samples'
        resolution, :meth:`..mesh.Mesh.coarsened`; default ``mesh``).
    resolution : float, optional
        The finest length the method resolves (the first approximation's spacing times D; by
        default the least of ``scale``): containment keeps bones a share of it inside.
    """

    def __init__(self, mesh, samples, weights: Weights, scale, paper=None, sections=None,
                 resolution=None):
        self.mesh, self.samples, self.weights = mesh, samples, weights
        self.section_mesh = mesh if sections is None else sections
        self.scale = np.asarray(scale, np.float64)
        self.area = float(samples.weights.sum())
        self.D = mesh.D
        self.tree = cKDTree(samples.points)
        self.region = None if paper is None else np.asarray(paper, np.int64)
        self.resolution = float(np.min(self.scale, initial=mesh.D) if resolution is None
                                else resolution)

    @classmethod
    def for_first_approximation(cls, mesh, samples, region, graph, weights, spacing, sections=None):
        """J for a mesh whose first approximation is ``graph``: each sample's thickness is its
        distance from the first approximation, on the bones of its Reeb region (at least
        ``CONFIG.objective.thickness_floor`` spacings)."""
        n_reg = int(max(np.max(region, initial=-1), graph.pairs[:, 0].max(initial=-1))) + 1
        cand = candidates_from_pairs(graph.pairs, region, n_reg)
        _, _, d2 = closest_on_bones(samples.points, graph.joints, graph.bones, cand)
        floor = CONFIG.objective.thickness_floor * spacing * mesh.D
        return cls(mesh, samples, weights, np.maximum(np.sqrt(d2), floor), paper=region,
                   sections=sections, resolution=spacing * mesh.D)

    def sigma(self, graph):
        """(bone, t) of every sample, each (s, k): its points on the ``k`` bones whose cones'
        surfaces are nearest, nearest first (:func:`..geometry.segments.nearest_on_silhouette`;
        ``k = CONFIG.objective.soft_bones``, the fit's soft minimum runs over them)."""
        bone, t, _ = nearest_on_silhouette(self.samples.points, graph.joints, graph.bones,
                                           CONFIG.objective.soft_bones)
        return bone.reshape(len(t), -1), t.reshape(len(t), -1)

    def paper_sigma(self, graph):
        """The paper's sigma: each sample on the bones of its own Reeb region."""
        n_reg = int(max(self.region.max(initial=-1), graph.pairs[:, 0].max(initial=-1))) + 1
        cand = candidates_from_pairs(graph.pairs, self.region, n_reg)
        bone, t, _ = closest_on_bones(self.samples.points, graph.joints, graph.bones, cand)
        return bone, t

    def thickness(self, graph) -> np.ndarray:
        """(B,) the thickness of each bone's part: the graph's own (carried from the first
        approximation through every move), else that of the samples nearest each bone now."""
        if graph.thick is not None:
            return np.asarray(graph.thick)
        return self.measure_thickness(graph)

    def margin(self, n_bones) -> np.ndarray:
        """How deep inside each bone must keep (containment): a share of the resolution (of
        a part's thickness, a flap's would be out of reach)."""
        return np.full(n_bones, CONFIG.objective.contain_margin * self.resolution)

    def measure_thickness(self, graph, bone=None) -> np.ndarray:
        """(B,) the area-weighted mean thickness of the samples nearest each bone (``bone``:
        their bones, if known); the median where none is."""
        if bone is None:
            bone = self.sigma(graph)[0][:, 0]
        B = len(graph.bones)
        w = self.samples.weights
        W = np.bincount(bone, w, B)
        t = np.bincount(bone, w * self.scale, B)
        return np.where(W > 0, t / np.maximum(W, 1e-300), float(np.median(self.scale)))

    def _blocks(self, Z, bones, bone, t, jacobian):
        w, s, D = self.weights, self.samples, self.D
        out = {"fit": (1.0, T.fit_term(Z, s, bones, bone, self.area, self.scale,
                                       softness=CONFIG.objective.fit_softness,
                                       jacobian=jacobian))}
        if w.centre:
            out["centre"] = (w.centre, T.centre_term(Z, bones, self.section_mesh, D, self._thick,
                                                     jacobian=jacobian))
        if w.smooth:
            out["smooth"] = (w.smooth, T.smooth_term(Z, bones, D, jacobian=jacobian))
        if w.contain:
            out["contain"] = (w.contain, T.contain_term(Z, bones, self.mesh.inside, self.tree,
                                                        s.points, s.normal, D, self.margin(len(bones)),
                                                        jacobian=jacobian))
        return out

    def evaluate(self, graph, sigma=None) -> Evaluation:
        """J of ``graph`` (sigma: its own nearest points unless given)."""
        bone, t = self.sigma(graph) if sigma is None else sigma
        bone, t = np.asarray(bone).reshape(len(t), -1), np.asarray(t).reshape(len(t), -1)
        self._thick = self.thickness(graph)
        Z = np.asarray(graph.joints)
        blocks = self._blocks(Z, graph.bones, bone, t, False)
        terms = {k: float(np.dot(r, r)) for k, (_, (r, _)) in blocks.items()}
        value = sum(wt * terms[k] for k, (wt, _) in blocks.items())
        terms["joints"] = float(graph.n_joints)
        terms["tips"] = float(graph.n_leaves)
        value += self.weights.joint * terms["joints"] + self.weights.branch * terms["tips"]
        return Evaluation(float(value), terms, bone[:, 0], t[:, 0], (bone, t))

    def per_bone(self, graph, evaluation) -> np.ndarray:
        """(B,) each bone's share of J's continuous terms: the fit of the samples nearest it,
        its centring and containment (weighted as in J)."""
        Z = np.asarray(graph.joints)
        bones, B = graph.bones, len(graph.bones)
        self._thick = self.thickness(graph)
        w, s, D = self.weights, self.samples, self.D
        r = T.fit_term(Z, s, bones, evaluation.sigma[0], self.area, self.scale,
                       softness=CONFIG.objective.fit_softness, jacobian=False)[0]
        out = np.bincount(evaluation.bone, r * r, B)
        X = Z[:, :3]
        if w.centre:
            out += w.centre * T.bone_centres(X[bones[:, 0]], X[bones[:, 1]], bones,
                                             self.section_mesh, D, self._thick, len(Z),
                                             jacobian=None)
        if w.contain:
            out += w.contain * T.bone_contain(X[bones[:, 0]], X[bones[:, 1]], bones,
                                              self.mesh.inside, self.tree, s.points, s.normal,
                                              D, self.margin(B), len(Z), jacobian=None)
        return out

    def paper_energy(self, graph) -> float:
        """The paper's E (eq. 8 over the samples, its own sigma), in units of D: reported."""
        if self.region is None:
            return float("nan")
        bone, t = self.paper_sigma(graph)
        return T.paper_energy(np.asarray(graph.joints), self.samples, graph.bones, bone, t,
                              self.area, self.D)

    def model(self, graph, sigma):
        """Gauss-Newton model at ``graph`` with sigma held: (H (4J, 4J) sparse, g (4J,)), with
        ``g`` the exact gradient of the continuous part of J and ``H`` its Gauss-Newton
        matrix."""
        Z = np.asarray(graph.joints)
        self._thick = self.thickness(graph)
        n = 4 * len(Z)
        H = sp.csr_matrix((n, n))
        g = np.zeros(n)
        for wt, (r, Jm) in self._blocks(Z, graph.bones, *sigma, True).values():
            if Jm is None or not Jm.nnz:
                continue
            H = H + (2.0 * wt) * (Jm.T @ Jm)
            g += 2.0 * wt * (Jm.T @ r)
        return H.tocsc(), g
