"""Parameters of the method, with defaults shared by the core, the CLI and the Blender UI."""

from __future__ import annotations

from dataclasses import asdict, dataclass, fields

__all__ = ["SkeletonParams", "SOLVERS"]

#: "paper": gradient descent with exact line search, stopped as in eqs. 30-31 (reproduces the
#: paper). "lm": Levenberg-Marquardt on the 4-per-joint normal equations (converges).
SOLVERS = ("paper", "lm")


@dataclass
class SkeletonParams:
    """Parameters of :func:`curveskel_addon.core.skeletonize`.

    Attributes
    ----------
    spacing : float
        Contour spacing as a fraction of each component's bounding-box diagonal. Smaller gives
        more joints. Refined automatically where a handle would otherwise be lost.
    solver : str
        One of :data:`SOLVERS`.
    max_iterations : int
        Upper bound on optimisation iterations.
    tolerance : float
        Stop when one iteration lowers E by less than ``tolerance * E0`` (eq. 30-31: 1e-3).
    seed : int
        Seed of the random first vertex of the pole search; results are reproducible.
    area_weighted : bool
        Weight each vertex by its Voronoi area (surface integral of eq. 8 instead of a vertex sum).
    refit_mapping : bool
        Re-fit sigma (each vertex's bone and t) between solver steps.
    prune : float
        Remove a leaf branch whose removal raises E by less than ``prune`` times what the branch
        explains (0 disables).
    simplify : float
        Merge a joint of degree 2 when E barely changes (relative threshold, 0 disables).
    candidates : int
        Number of first approximations (poles / spacings) tried; the one of lowest E is kept.
    smoothness : float
        Weight of a Laplacian term keeping chain joints between their neighbours ("lm" only;
        0 disables). Relative to E; see :mod:`.solvers.lm`.
    containment : float
        Weight of a term keeping each joint, and points along each bone, inside the mesh with
        their balls inside the surface ("lm" only; 0 disables). Stops joints running away while E still falls. Relative to E
        (1: a violation of one median radius at every joint costs E0); default 1.0, measured
        better than 0 on all six reference meshes (bone points inside the mesh and
        reconstruction distance); see :mod:`.solvers.lm`.
    refine : int
        Rounds of splitting the bones that leave the mesh (tested exactly at points along
        every bone) and the 40 % of bones holding most of E, and re-solving, each only while
        more than 2 % of the tested points are outside; then, without re-solving, joints still
        outside are pulled in, bones split again at medial balls of the surface and joints
        relocated (0 disables all of it; skipped above 500k faces, where its exact inside
        tests would cost more than the fit, and ``meta["refine"]["skipped"]`` says so).
        Default 1; each further round lowers E and recon again but costs a solve (0.3-1 s
        on meshes of 5k vertices). Folds (chains doubling back along another part,
        :func:`.postprocess.unfold_chains`) are merged away first. See :mod:`.refine`.
    max_joints : int
        Joint budget of the refinement: no bone is split beyond this many joints.
    max_fit_points : int
        Above this many vertices the solver fits an area-weighted random subset of this size
        (a quadrature of the same surface integral) and maps every vertex at the end.
        0 = always fit every vertex. Needs area_weighted.
    """

    spacing: float = 0.04
    solver: str = "lm"
    max_iterations: int = 100
    tolerance: float = 1e-3
    seed: int = 0
    area_weighted: bool = True
    refit_mapping: bool = True
    prune: float = 0.02
    simplify: float = 0.01
    candidates: int = 3
    smoothness: float = 0.0
    containment: float = 1.0
    max_fit_points: int = 60000
    refine: int = 1
    max_joints: int = 300

    @classmethod
    def paper(cls, **overrides) -> "SkeletonParams":
        """The method exactly as the paper describes it (vertex sum, fixed sigma, gradient descent)."""
        base = dict(solver="paper", area_weighted=False, refit_mapping=False, prune=0.0,
                    simplify=0.0, candidates=1, max_iterations=1000, smoothness=0.0,
                    containment=0.0, max_fit_points=0, refine=0)
        base.update(overrides)
        return cls(**base)

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict) -> "SkeletonParams":
        names = {f.name for f in fields(cls)}
        return cls(**{k: v for k, v in d.items() if k in names})
