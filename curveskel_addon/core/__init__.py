"""curveskel core: curve-skeletons of triangle meshes by energy minimisation. Pure NumPy/SciPy.

Never imports bpy. Arrays in, a :class:`Skeleton` out. ``skeletonize`` and ``SkeletonRun`` are
loaded on first use (PEP 562), so importing one stage's module does not import every stage.
"""

from .errors import CurveSkelError
from .params import SOLVERS, SkeletonParams
from .skeleton import FORMAT, Skeleton

__all__ = ["CurveSkelError", "SOLVERS", "SkeletonParams", "SkeletonRun", "skeletonize",
           "Skeleton", "FORMAT"]


def __getattr__(name):
    if name == "skeletonize":
        import os
        if os.environ.get("CURVESKEL_NEW"):            # TEMPORARY: the objective's search
            from . import method
            from .objective.objective import Weights
            w = dict(kv.split("=") for kv in os.environ.get("CURVESKEL_WEIGHTS", "").split(",") if kv)
            weights = Weights(**{k: float(v) for k, v in w.items()})
            return lambda V, F, params=None, progress=None, **kw: method.skeletonize(
                V, F, params, progress, weights=weights, **kw)
    if name in ("skeletonize", "SkeletonRun"):
        from . import pipeline

        return getattr(pipeline, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
