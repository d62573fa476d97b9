"""Parameters of the method, with defaults shared by the core, the CLI and the Blender UI.

Every parameter is checked here, once, whoever builds it (API, command line, Blender): see
:data:`RULES` and :func:`check_params`. A bad value raises :class:`CurveSkelError` naming it.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import asdict, dataclass, fields

from .errors import CurveSkelError

__all__ = ["SkeletonParams", "SOLVERS", "RULES", "check_params"]

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
    min_component_area : float
        Connected parts of the mesh with less than this share of the total surface area are
        dropped before the fit (scan debris, specks); their vertices are mapped to the nearest
        kept part. The largest part is always kept. 0 keeps every part. Reported in
        ``meta["input"]`` (``small_components_dropped`` ...).
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
    min_component_area: float = 0.01

    def __post_init__(self):
        check_params(self)

    @classmethod
    def paper(cls, **overrides) -> "SkeletonParams":
        """The method exactly as the paper describes it (vertex sum, fixed sigma, gradient descent)."""
        base = dict(solver="paper", area_weighted=False, refit_mapping=False, prune=0.0,
                    simplify=0.0, candidates=1, max_iterations=1000, smoothness=0.0,
                    containment=0.0, max_fit_points=0, refine=0)
        base.update(overrides)
        return cls.from_dict(base)

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def from_dict(cls, d: dict) -> "SkeletonParams":
        """Parameters from a mapping of field names; an unknown name raises CurveSkelError."""
        names = [f.name for f in fields(cls)]
        unknown = [k for k in d if k not in names]
        if unknown:
            raise CurveSkelError(_unknown_message(unknown, names))
        return cls(**dict(d))


# -- validation ---------------------------------------------------------------------------------
#: One rule per field: (kind, low, high) with kind "float" (finite real), "int" (integral),
#: "bool" or "choice"; low/high are inclusive bounds, a bound in a 1-tuple is exclusive
#: ((0,) means "> 0"), None means unbounded; for "choice" low is the tuple of allowed values.
#: A field without a rule is still type-checked from its default's type (finite for floats).
RULES: dict[str, tuple] = {
    "spacing": ("float", (0.0,), 0.5),
    "solver": ("choice", SOLVERS, None),
    "max_iterations": ("int", 0, None),
    "tolerance": ("float", (0.0,), 1.0),
    "seed": ("int", 0, None),
    "area_weighted": ("bool", None, None),
    "refit_mapping": ("bool", None, None),
    "prune": ("float", 0.0, 1.0),
    "simplify": ("float", 0.0, None),
    "candidates": ("int", 1, None),
    "smoothness": ("float", 0.0, None),
    "containment": ("float", 0.0, None),
    "max_fit_points": ("int", 0, None),
    "refine": ("int", 0, None),
    "max_joints": ("int", 2, None),
    "min_component_area": ("float", 0.0, (1.0,)),
}


def check_params(p: "SkeletonParams") -> None:
    """Check every field of ``p`` against :data:`RULES` (or its default's type); normalise
    numbers to plain Python ``float``/``int`` in place. Raises :class:`CurveSkelError` naming
    the parameter."""
    for f in fields(p):
        value = getattr(p, f.name)
        rule = RULES.get(f.name) or _rule_from_default(f)
        if rule is None:
            continue
        setattr(p, f.name, _checked(f.name, value, *rule))


def _rule_from_default(f):
    default = f.default
    if isinstance(default, bool):
        return ("bool", None, None)
    if isinstance(default, numbers.Integral):
        return ("int", None, None)
    if isinstance(default, numbers.Real):
        return ("float", None, None)
    return None


def _checked(name, value, kind, low, high):
    if kind == "choice":
        if not isinstance(value, str) or value not in low:
            raise CurveSkelError(f"unknown {name} {value!r}: {name} must be one of {', '.join(map(repr, low))}")
        return value
    if kind == "bool":
        if isinstance(value, bool) or (type(value).__name__ == "bool_"):
            return bool(value)
        raise CurveSkelError(f"{name} must be True or False, got {value!r}")
    if isinstance(value, (bool, str, bytes)) or not isinstance(value, numbers.Real) \
            or type(value).__name__ == "bool_":
        what = "an integer" if kind == "int" else "a number"
        raise CurveSkelError(f"{name} must be {what}, got {type(value).__name__} {value!r}")
    if not math.isfinite(float(value)):
        raise CurveSkelError(f"{name} must be a finite number, got {value!r}")
    if kind == "int":
        if not isinstance(value, numbers.Integral) and float(value) != math.floor(float(value)):
            raise CurveSkelError(f"{name} must be an integer, got {value!r}")
        value = int(value)
    else:
        value = float(value)
    for bound, is_low in ((low, True), (high, False)):
        if bound is None:
            continue
        strict = isinstance(bound, tuple)
        b = bound[0] if strict else bound
        bad = (value <= b if strict else value < b) if is_low else (value >= b if strict else value > b)
        if bad:
            raise CurveSkelError(f"{name} must be {_range_text(low, high)}, got {value!r}")
    return value


def _range_text(low, high) -> str:
    parts = []
    if low is not None:
        parts.append(f"> {low[0]:g}" if isinstance(low, tuple) else f">= {low:g}")
    if high is not None:
        parts.append(f"< {high[0]:g}" if isinstance(high, tuple) else f"<= {high:g}")
    return " and ".join(parts)


def _unknown_message(unknown, names) -> str:
    import difflib

    out = []
    for k in unknown:
        close = difflib.get_close_matches(str(k), names, n=1)
        out.append(f"{k!r}" + (f" (did you mean {close[0]!r}?)" if close else ""))
    return f"unknown parameter{'s' if len(out) > 1 else ''} {', '.join(out)}; known: {', '.join(names)}"
