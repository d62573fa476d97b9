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
    if name in ("skeletonize", "SkeletonRun"):
        from . import pipeline

        return getattr(pipeline, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
