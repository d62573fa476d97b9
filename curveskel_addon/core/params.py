"""Parameters of the method, with defaults shared by the core, the CLI and the Blender UI.

Every parameter is checked here, once, whoever builds it (API, command line, Blender): see
:data:`RULES` and :func:`check_params`. A bad value raises :class:`CurveSkelError` naming it.
"""

from __future__ import annotations

import difflib
import math
import numbers
from dataclasses import asdict, dataclass, fields

from .errors import CurveSkelError

__all__ = ["SkeletonParams", "SOLVERS", "RULES", "check_params"]

#: "lm": the search for the minimum of the objective J (Levenberg-Marquardt on the joints,
#: topology moves kept only when J falls; :mod:`.search`). "paper": the paper's method as
#: published (its first approximation, then gradient descent on E with the exact line search,
#: stopped as in its eqs. 30-31).
SOLVERS = ("lm", "paper")


@dataclass
class SkeletonParams:
    """Parameters of :func:`curveskel_addon.core.skeletonize`.

    The first four are the artist's settings, each mapped to exactly one thing of the method
    (the Blender panel shows only these; the rest sit under *Advanced* and in the command
    line's "advanced" group).

    Attributes
    ----------
    spacing : float
        *Detail Size.* The first approximation's spacing: the distance between the contour
        levels of its Reeb graph, as a fraction of each part's size (the diameter of its
        enclosing ball). Smaller finds smaller parts.
    smoothness : float
        *Smoothness.* The weight of J's smoothness term (how much the chains turn and their
        radii bend), in units of :data:`.config.WEIGHTS` ``.smooth``: 0 lets the curve follow
        the sections' centres exactly, 10 makes chains nearly straight between junctions.
    prune : float
        *Branch Pruning.* The price of a branch (a tip) in J, in units of :data:`.config.WEIGHTS`
        ``.branch``: a branch stays only where it explains more of the surface than it costs
        (0 keeps every branch the first approximation found).
    max_joints : int
        *Max Joints.* A hard upper bound on the joints of the result (0: none).
    solver : str
        One of :data:`SOLVERS`.
    max_iterations : int
        At most this many steps per minimisation ("lm"), or gradient-descent iterations
        ("paper").
    tolerance : float
        "paper": stop when an iteration lowers E by less than ``tolerance * E0`` (eqs. 30-31:
        1e-3).
    seed : int
        Where the pole search starts: 0 at the vertex farthest from the centroid (the same
        skeleton whatever the mesh's numbering or pose), another value at a random vertex, as in
        the paper. Moving the pole can change which branches the first approximation finds.
    min_component_area : float
        Connected parts of the mesh with less than this share of the total surface area are
        dropped before the fit; their vertices are mapped to the nearest kept part. The
        largest part is always kept. 0 (the default) drops none by share: debris is judged per
        part instead, against its nearest neighbour (a part below its neighbour's *Detail
        Size* is dropped: :func:`.mesh_input.clean_mesh`), so 200 equal spheres stay 200 parts.
    separate_parts : bool
        One skeleton per connected part, as the parts are modelled. By default parts that
        overlap or nearly touch are joined where they meet and small free parts hang from the
        nearest larger part, so a figure modelled in pieces gets one tree
        (:mod:`.initialise.parts`).
    """

    spacing: float = 0.025
    smoothness: float = 1.0
    prune: float = 1.0
    max_joints: int = 150
    solver: str = "lm"
    max_iterations: int = 30
    tolerance: float = 1e-3
    seed: int = 0
    min_component_area: float = 0.0
    separate_parts: bool = False

    def __post_init__(self):
        check_params(self)        # one place for every rule: API, command line and Blender

    @classmethod
    def paper(cls, **overrides) -> "SkeletonParams":
        """The method exactly as the paper describes it: its first approximation (Reeb graph of
        the geodesic distance, contours' enclosing balls), then gradient descent on E (eq. 20,
        the vertex sum) with the exact line search, stopped as in eqs. 30-31."""
        base = dict(spacing=0.04, solver="paper", max_iterations=1000, smoothness=0.0,
                    prune=0.0, max_joints=0)
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
    # numbers overflow (a weight of 1e308 broke the linear solves)
    "spacing": ("float", (0.0,), 0.5),
    "smoothness": ("float", 0.0, 1000.0),           # 10 is nearly straight already
    "prune": ("float", 0.0, 1000.0),
    "max_joints": ("int", 0, 100_000),
    "solver": ("choice", SOLVERS, None),
    "max_iterations": ("int", 0, 100_000),
    "tolerance": ("float", (0.0,), 1.0),
    "seed": ("int", 0, 2**32 - 1),                  # NumPy's seed range
    "min_component_area": ("float", 0.0, (1.0,)),
    "separate_parts": ("bool", None, None),
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
    out = []
    for k in unknown:
        close = difflib.get_close_matches(str(k), names, n=1)
        out.append(f"{k!r}" + (f" (did you mean {close[0]!r}?)" if close else ""))
    return f"unknown parameter{'s' if len(out) > 1 else ''} {', '.join(out)}; known: {', '.join(names)}"
