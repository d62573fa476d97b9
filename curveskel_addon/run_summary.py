"""What a run did, in figures and words: the command line's summary, the Blender operator's
report and the figures the panel shows (pure Python: no bpy).

The core logs J and its terms after every kept stage of its search (``Skeleton.meta["stages"]``,
``meta["J"]``, ``meta["terms"]``) and the paper's E after every stage (``Skeleton.energy``);
everything here is read from those. With ``solver="paper"`` the value the run minimises is E
itself (``J`` is E there, its only term ``"E"``).
"""

from __future__ import annotations

import math

from .core.errors import CurveSkelError
from .core.objective.objective import weights_for
from .core.params import SkeletonParams

__all__ = ["summary", "headline", "moves_text", "term_parts", "terms_text", "energy_text",
           "TERMS", "MOVE_STAGES"]

#: J's terms in the order J sums them (``core.objective.objective``); each is weighted by the
#: :class:`core.config.Weights` field of the same name, except ``fit`` (weight 1), ``joints``
#: (``joint``) and ``tips`` (``branch``).
TERMS = ("fit", "centre", "smooth", "contain", "joints", "tips")
_WEIGHT_OF = {"centre": "centre", "smooth": "smooth", "contain": "contain", "joints": "joint",
              "tips": "branch"}
#: The search's topology moves (stage names of ``meta["stages"]``), with the words for what
#: each kept one did (``moved``: joints merged, branches pruned; a split or a contraction is one).
MOVE_STAGES = {"merge": ("joint merged", "joints merged"),
               "prune": ("branch pruned", "branches pruned"),
               "split": ("junction split", "junctions split"),
               "contract": ("junction pair joined", "junction pairs joined")}


def summary(sk) -> dict:
    """Figures of a run from its :class:`core.Skeleton`.

    Returns
    -------
    dict
        ``joints``, ``bones``, ``components``; ``solver``; ``J0`` (J of the first logged stage,
        the first approximation cut to the joint budget) and ``J`` (the returned skeleton's,
        the lowest logged); ``E0`` and ``E`` (the paper's E of the first and the last logged
        stage); ``stages`` (stages logged), ``moves`` (per kept move kind: how many joints
        it merged or branches it pruned, how many splits and contractions), ``iterations``
        (minimisation steps over all stages; the paper's solver: gradient-descent
        iterations); ``seconds`` (the core's time, all stages).
    """
    meta = sk.meta if isinstance(sk.meta, dict) else {}
    stages = meta.get("stages") or []
    nan = float("nan")
    moves: dict[str, int] = {}
    for st in stages:
        kind = st.get("stage")
        if kind in MOVE_STAGES:
            moves[kind] = moves.get(kind, 0) + int(st.get("moved", 1))
    J = meta.get("J")
    return {
        "joints": sk.n_joints,
        "bones": sk.n_bones,
        "components": int(meta.get("components", 1)),
        "solver": str((meta.get("params") or {}).get("solver", "?")),
        "J0": float(stages[0]["J"]) if stages else nan,
        "J": float(J) if J is not None else (float(stages[-1]["J"]) if stages else nan),
        "E0": float(sk.energy[0]) if sk.energy else nan,
        "E": float(sk.energy[-1]) if sk.energy else nan,
        "stages": len(stages),
        "moves": moves,
        "iterations": int(sum(int(st.get("iterations", 0)) for st in stages)),
        "seconds": float(sum(sk.timings.values())),
    }


def headline(s: dict, *, stopped: bool = False) -> str:
    """``J 0.0293 -> 0.0257 in 12 stages`` (the paper's solver: ``E ... in 12 iterations``)."""
    how = "stopped after" if stopped else "in"
    if s["solver"] == "paper":
        return f"E {s['J0']:.4g} -> {s['J']:.4g} {how} {s['iterations']} iterations"
    return f"J {s['J0']:.4g} -> {s['J']:.4g} {how} {s['stages']} stages"


def moves_text(s: dict) -> str:
    """``8 joints merged, 1 branch pruned`` (empty when the search kept no move)."""
    return ", ".join(f"{n} {MOVE_STAGES[k][n != 1]}" for k, n in s["moves"].items())


def term_parts(sk) -> list[tuple[str, float | None, float]]:
    """``(name, weight, value)`` of every term of the returned skeleton's J, in J's order;
    ``weight`` None where it is not known (parameters from another version of curveskel).
    J = the sum of ``weight * value``."""
    meta = sk.meta if isinstance(sk.meta, dict) else {}
    terms = meta.get("terms") or {}
    try:
        w = weights_for(SkeletonParams.from_dict(meta.get("params") or {}))
    except (CurveSkelError, TypeError):
        w = None
    out = []
    for name in TERMS:
        if name in terms:
            weight = 1.0 if name == "fit" else (getattr(w, _WEIGHT_OF[name]) if w else None)
            out.append((name, weight, float(terms[name])))
    return out


def terms_text(sk) -> str:
    """``J = fit 0.0017 + centre 1 x 4.9e-16 + ... + tips 0.01 x 2`` (empty when J has no
    terms: the paper's solver)."""
    parts = term_parts(sk)
    if not parts:
        return ""
    words = []
    for name, weight, value in parts:
        if weight is None:
            words.append(f"{name} {value:.4g}")
        elif weight == 1.0 and name == "fit":
            words.append(f"{name} {value:.4g}")
        else:
            words.append(f"{name} {weight:g} x {value:.4g}")
    J = sk.meta.get("J")
    return (f"J {J:.6g} = " if J is not None else "J = ") + " + ".join(words)


def energy_text(s: dict) -> str:
    """The paper's E of the first and the last stage, and what it measures."""
    if any(math.isnan(s[k]) for k in ("E0", "E")):
        return "E not computed"
    if s["solver"] == "paper":
        return f"E {s['E0']:.6g} -> {s['E']:.6g} (the paper's eq. 20: the vertex sum)"
    return (f"E {s['E0']:.6g} -> {s['E']:.6g} (the paper's eq. 8 over the surface, / area D^4; "
            "not minimised)")
