"""curveskel core: a curve-skeleton as the minimiser of one objective J. Pure NumPy/SciPy.

Never imports bpy. Arrays in, a :class:`Skeleton` out. The package follows the method:

==========================  ==================================================================
``mesh_input``              the input checked and cleaned: one :class:`CurveSkelError` per bad
                            mesh, a working copy (duplicates merged, parts turned outwards...)
``mesh``, ``graph``         the values the stages pass: the immutable :class:`Mesh` (V, F, D,
                            its inside test, adjacency, cross-sections) and the search's
                            :class:`SkeletonGraph` (joints, bones, Reeb regions' bones)
``geometry/``               the kernel, importing nothing above it: closest points on bones,
                            inside test, cross-sections and their derivatives, surface
                            quadrature, enclosing balls, mesh graph
``initialise/``             the paper's first approximation: pole, Reeb graph of the geodesic
                            distance, contours' enclosing balls, at the spacing's resolution;
                            separate parts joined into figures where they overlap or nearly
                            touch, small free parts hung from larger ones (``parts``)
``objective/``              J: its terms with exact Jacobians, its evaluation, the
                            minimisation over joints and radii; and the paper's E and solver
``moves/``                  topology moves as pure functions (graph -> graph, bone map), and
                            estimates of what each would change in J
``search``                  the search: minimisation and moves, each kept only when J falls
``pipeline``                :func:`skeletonize`, :class:`SkeletonRun`: the stages in order
``config``, ``params``      every constant of the method; the user's settings
``skeleton``, ``errors``    the result and its JSON; the one exception type
``skeleton_input``,         any skeleton from outside (CGAL's, an armature, a plain JSON):
``evaluation``,             checked, judged by J (terms, E, per bone, per vertex), its joints
``refinement``              moved to J's minimum with its graph kept (:func:`evaluate`,
                            :func:`refine`)
==========================  ==================================================================

The measures (``curveskel_addon.measure``) and the rig (``curveskel_addon.rig``) sit outside:
they import the core, the core never imports them.
"""

from .errors import CurveSkelError
from .evaluation import SkeletonReport, compare, evaluate
from .params import SOLVERS, SkeletonParams
from .pipeline import RunState, SkeletonRun, skeletonize
from .refinement import Refinement, RefineResult, refine
from .skeleton import FORMAT, Skeleton
from .skeleton_input import OutsideSkeleton, load_outside_skeleton

__all__ = ["CurveSkelError", "SOLVERS", "SkeletonParams", "SkeletonRun", "RunState",
           "skeletonize", "Skeleton", "FORMAT", "evaluate", "compare", "refine", "Refinement",
           "RefineResult", "SkeletonReport", "OutsideSkeleton", "load_outside_skeleton"]
