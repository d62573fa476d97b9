"""curveskel core: curve-skeletons of triangle meshes by energy minimisation. Pure NumPy/SciPy.

Never imports bpy. Arrays in, a :class:`Skeleton` out.
"""

from .errors import CurveSkelError
from .params import SOLVERS, SkeletonParams
from .pipeline import SkeletonRun, skeletonize
from .skeleton import FORMAT, Skeleton

__all__ = ["CurveSkelError", "SOLVERS", "SkeletonParams", "SkeletonRun", "skeletonize",
           "Skeleton", "FORMAT"]
