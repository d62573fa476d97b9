"""The fitting problem the solvers work on, shared by the first approximation and the solvers."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["FitProblem", "SolverState"]


@dataclass
class FitProblem:
    """Points to explain and the skeleton that explains them.

    Attributes
    ----------
    points : (n, 3) float   sample points (the working mesh's vertices)
    weights : (n,) float    weight of each point in E (1 for the paper's vertex sum; area otherwise)
    joints : (J, 4) float   x, y, z, r
    bones : (B, 2) int      joint indices
    bone : (n,) int         sigma: bone of each point
    t : (n,) float          sigma: parameter on that bone, sigma = t*x_i + (1-t)*x_j (eq. 19)
    """

    points: np.ndarray
    weights: np.ndarray
    joints: np.ndarray
    bones: np.ndarray
    bone: np.ndarray
    t: np.ndarray
    meta: dict = field(default_factory=dict)

    def copy(self) -> "FitProblem":
        return FitProblem(self.points, self.weights, self.joints.copy(), self.bones.copy(),
                          self.bone.copy(), self.t.copy(), dict(self.meta))


@dataclass
class SolverState:
    """What a solver reports after each iteration (iteration 0 is the start, E0)."""

    iteration: int
    joints: np.ndarray
    bone: np.ndarray
    t: np.ndarray
    energy: float
    done: bool = False
