"""The objective J of a skeleton, and the Gauss-Newton model the solver steps with.

    J = fit + w_centre centre + w_smooth smooth + w_contain contain
          + w_joint (number of joints) + w_branch (number of tips)

(the terms: :mod:`.terms`). The mapping sigma of every surface sample is the closest point on
the bones its Reeb region may use (:attr:`..graph.SkeletonGraph.pairs`), so J is a function of
the skeleton alone. The two counts price the topology: a joint or a branch stays only where it
explains the surface better than it costs (minimum description length; *Branch Pruning* sets
``w_branch``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree

from ..mapping import closest_on_bones
from ..state import candidates_from_pairs
from . import terms as T

__all__ = ["Weights", "Evaluation", "Objective"]


@dataclass(frozen=True)
class Weights:
    """J's weights (each term is already in units of D; see :mod:`.terms`)."""

    centre: float = 1.0
    smooth: float = 0.01
    contain: float = 100.0
    joint: float = 1e-6
    branch: float = 0.0


@dataclass(frozen=True)
class Evaluation:
    """J of one skeleton: its value, each term's (unweighted) value and sigma."""

    value: float
    terms: dict
    bone: np.ndarray = field(repr=False)
    t: np.ndarray = field(repr=False)


class Objective:
    """J on one mesh.

    Parameters
    ----------
    mesh : Mesh
    samples : Samples
        Surface quadrature points.
    region : (s,) int
        Reeb region of every sample.
    weights : Weights
    scale : (s,) float
        The thickness of the part each sample lies on (its distance from the first
        approximation: a property of the mesh and the first approximation, held through the
        search): the fit's unit of length there, and, averaged over a bone's samples, the
        centring's unit for that bone.
    """

    def __init__(self, mesh, samples, region, weights: Weights, scale):
        self.mesh, self.samples, self.weights = mesh, samples, weights
        self.scale = np.asarray(scale, np.float64)
        self.region = np.asarray(region, np.int64)
        self.n_regions = int(self.region.max(initial=-1)) + 1
        self.area = float(samples.weights.sum())
        self.D = mesh.D
        self.tree = cKDTree(samples.points)

    def sigma(self, graph):
        """(bone, t) of every sample: closest point on its region's bones."""
        n_reg = max(self.n_regions, int(graph.pairs[:, 0].max(initial=-1)) + 1)
        cand = candidates_from_pairs(graph.pairs, self.region, n_reg)
        bone, t, _ = closest_on_bones(self.samples.points, graph.joints, graph.bones, cand)
        return bone, t

    def thickness(self, graph, bone) -> np.ndarray:
        """(B,) the thickness of each bone's part: the area-weighted mean thickness of the
        samples mapped to it (``bone``: each sample's bone); the median where none is."""
        B = len(graph.bones)
        w = self.samples.weights
        W = np.bincount(bone, w, B)
        t = np.bincount(bone, w * self.scale, B)
        return np.where(W > 0, t / np.maximum(W, 1e-300), float(np.median(self.scale)))

    def _blocks(self, Z, bones, bone, t, jacobian):
        w, s, D = self.weights, self.samples, self.D
        out = {"fit": (1.0, T.fit_term(Z, s, bones, bone, t, self.area, self.scale,
                                       jacobian=jacobian))}
        if w.centre:
            out["centre"] = (w.centre, T.centre_term(Z, bones, self.mesh, D, self._thick,
                                                     jacobian=jacobian))
        if w.smooth:
            out["smooth"] = (w.smooth, T.smooth_term(Z, bones, D, jacobian=jacobian))
        if w.contain:
            out["contain"] = (w.contain, T.contain_term(Z, bones, self.mesh.inside, self.tree,
                                                        s.points, s.normal, D, jacobian=jacobian))
        return out

    def evaluate(self, graph, sigma=None) -> Evaluation:
        bone, t = self.sigma(graph) if sigma is None else sigma
        self._thick = self.thickness(graph, bone)
        blocks = self._blocks(np.asarray(graph.joints), graph.bones, bone, t, False)
        terms = {k: float(np.dot(r, r)) for k, (_, (r, _)) in blocks.items()}
        rE = blocks["fit"][1][0] * (self.scale / self.D) ** 2
        terms["E"] = float(np.dot(rE, rE))            # the paper's E, in units of D
        terms["joints"] = float(graph.n_joints)
        terms["tips"] = float(graph.n_leaves)
        value = sum(wt * terms[k] for k, (wt, _) in blocks.items())  # (E: not a term of J)
        value += self.weights.joint * terms["joints"] + self.weights.branch * terms["tips"]
        return Evaluation(float(value), terms, bone, t)

    def model(self, graph, sigma):
        """Gauss-Newton model at ``graph`` with sigma held: (H (4J, 4J), g (4J,)), with
        ``g`` the exact gradient of the continuous part of J and ``H`` its Gauss-Newton
        matrix."""
        Z = np.asarray(graph.joints)
        self._thick = self.thickness(graph, sigma[0])
        n = 4 * len(Z)
        H = sp.csr_matrix((n, n))
        g = np.zeros(n)
        for wt, (r, Jm) in self._blocks(Z, graph.bones, *sigma, True).values():
            if Jm is None or not Jm.nnz:
                continue
            H = H + (2.0 * wt) * (Jm.T @ Jm)
            g += 2.0 * wt * (Jm.T @ r)
        return H.tocsc(), g
