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

    The first four are the artist's settings (the Blender panel shows only these; the rest sit
    under *Advanced* and in the command line's "advanced" group).

    Attributes
    ----------
    spacing : float
        *Detail.* Distance between the cross-sections (Reeb contours) as a fraction of each
        component's size (the diameter of its enclosing ball): smaller finds smaller parts and gives more joints.
        Refined automatically where a handle would otherwise be lost.
    smoothness : float
        *Smoothness* of the centred curve: weight of a chain joint's distance from the midpoint
        of its neighbours against the medial points it explains (scale-free; 0 follows the
        medial points exactly, 10 is nearly straight between branchings). See :mod:`.centreline`.
    prune : float
        *Branch pruning.* A leaf branch reaching out of its junction's ball by less than this
        many of its own radii is a bump of the junction and is removed (0 keeps all).
    max_joints : int
        *Max joints.* Chains are simplified further until the skeleton has at most this many
        joints (0: no limit).
    solver : str
        One of :data:`SOLVERS` ("lm": Levenberg-Marquardt, default; "paper": gradient descent
        with the exact line search, as published).
    max_iterations : int
        Upper bound on optimisation iterations of the final fit.
    tolerance : float
        Stop when one iteration lowers E by less than ``tolerance * E0`` (eq. 30-31: 1e-3).
    seed : int
        Seed of the random first vertex of the pole search and of the fit subsets.
    area_weighted : bool
        Weight each vertex by its Voronoi area (surface integral of eq. 8 instead of a vertex sum).
    refit_mapping : bool
        Re-fit sigma (each vertex's bone and t) to the closest bone point between solver steps.
        Off by default: a free re-fit turns E into a distance to the silhouette, which rewards
        bones that fill the volume (issue 10); sigma stays on the bones of its Reeb region.
    centre : bool
        Centre the Reeb graph's curve on the medial points and simplify it (the rig-ready
        formulation, :mod:`.centreline`, :mod:`.edit`); off in :meth:`paper`.
    centring : float
        Weight holding each joint to its centred position during the final fit of E (relative
        to E: 1 means a displacement of one median radius at every joint costs E0; 0 lets E
        move the joints freely). See :mod:`.solvers.lm`.
    containment : float
        Weight of a term keeping each joint, and points along each bone, inside the mesh with
        their balls inside the surface ("lm" only; 0 disables). Relative to E.
    simplify : float
        Chain joints are merged while the chain stays within this fraction of the local radius
        of the straight bone replacing them (Douglas-Peucker; 0 disables).
    max_fit_points : int
        Above this many vertices the final fit uses an area-weighted random subset of this
        size (a quadrature of the same surface integral) and maps every vertex at the end.
        0 = always fit every vertex.
    min_component_area : float
        Connected parts of the mesh with less than this share of the total surface area are
        dropped before the fit (scan debris, specks); their vertices are mapped to the nearest
        kept part. The largest part is always kept. 0 keeps every part. Reported in
        ``meta["input"]`` (``small_components_dropped`` ...).
    """

    spacing: float = 0.025
    smoothness: float = 0.5
    prune: float = 0.5
    max_joints: int = 150
    solver: str = "lm"
    max_iterations: int = 30
    tolerance: float = 1e-3
    seed: int = 0
    area_weighted: bool = True
    refit_mapping: bool = False
    centre: bool = True
    centring: float = 3.0
    containment: float = 1.0
    simplify: float = 0.25
    max_fit_points: int = 30000
    min_component_area: float = 0.01

    def __post_init__(self):
        check_params(self)        # one place for every rule: API, command line and Blender

    @classmethod
    def paper(cls, **overrides) -> "SkeletonParams":
        """The method exactly as the paper describes it (vertex sum, fixed sigma, gradient descent)."""
        base = dict(spacing=0.04, solver="paper", area_weighted=False, refit_mapping=False,
                    prune=0.0, simplify=0.0, centre=False, centring=0.0, max_iterations=1000,
                    smoothness=0.0, containment=0.0, max_fit_points=0, max_joints=0)
        base.update(overrides)
        return cls.from_dict(base)

    #: The artist's settings, in the order the UI shows them.
    ARTIST = ("spacing", "smoothness", "prune", "max_joints")

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
    # upper bounds: far past any useful value in the setting's own unit, well before the
    # numbers overflow (smoothness or centring at 1e308 broke the linear solves)
    "spacing": ("float", (0.0,), 0.5),
    "solver": ("choice", SOLVERS, None),
    "max_iterations": ("int", 0, 100_000),
    "tolerance": ("float", (0.0,), 1.0),
    "seed": ("int", 0, 2**32 - 1),                  # NumPy's seed range
    "area_weighted": ("bool", None, None),
    "refit_mapping": ("bool", None, None),
    "prune": ("float", 0.0, 100.0),                 # radii (0.5 by default)
    "simplify": ("float", 0.0, 100.0),              # radii (0.25)
    "smoothness": ("float", 0.0, 1000.0),           # 10 is nearly straight already
    "containment": ("float", 0.0, 1000.0),          # relative to E (1)
    "max_fit_points": ("int", 0, 100_000_000),
    "max_joints": ("int", 0, 100_000),
    "centre": ("bool", None, None),
    "centring": ("float", 0.0, 1000.0),             # relative to E (3)
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
