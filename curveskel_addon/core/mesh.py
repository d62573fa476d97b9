"""The working mesh as an immutable value: vertices, faces and what is derived from them once.

A :class:`Mesh` is built from the cleaned working copy (:mod:`.mesh_input`); its arrays are
read-only, and the derived structures (size, area, adjacency, the inside test) are computed on
first use and kept, so every stage shares one of each.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from .geometry.face_tree import FaceTree
from .geometry.inside import InsideTest
from .geometry.mesh_graph import edge_table, faces_around
from .geometry.rows import col_max, col_min, row_cross, row_norm
from .geometry.sections import vertex_edges
from .meb import size_of

__all__ = ["Mesh"]


@dataclass(frozen=True, eq=False)
class Mesh:
    """A closed triangle mesh.

    Attributes
    ----------
    V : (n, 3) float, read-only
    F : (m, 3) int, read-only
    """

    V: np.ndarray
    F: np.ndarray

    def __post_init__(self):
        V = np.array(self.V, dtype=np.float64)
        F = np.array(self.F, dtype=np.int64).reshape(-1, 3)
        V.flags.writeable = False
        F.flags.writeable = False
        object.__setattr__(self, "V", V)
        object.__setattr__(self, "F", F)

    @cached_property
    def D(self) -> float:
        """The unit of length: the diameter of the vertices' minimum enclosing ball (no
        rotation, move or renumbering changes it)."""
        return float(size_of(self.V)) if len(self.V) else 1.0

    @cached_property
    def face_cross(self) -> np.ndarray:
        """(m, 3) twice each face's area times its unit normal."""
        V, F = self.V, self.F
        return row_cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])

    @cached_property
    def area(self) -> float:
        return float(row_norm(self.face_cross).sum() / 2.0)

    @cached_property
    def bbox(self) -> tuple:
        return col_min(self.V), col_max(self.V)

    @cached_property
    def edges(self) -> tuple:
        """(E (e, 2), count (e,)): :func:`.geometry.mesh_graph.edge_table`."""
        return edge_table(self.F, len(self.V))

    @cached_property
    def face_of(self) -> tuple:
        """(indptr, faces): the faces round each vertex."""
        return faces_around(self.F, len(self.V))

    @cached_property
    def vertex_edge(self) -> np.ndarray:
        """(n,) the longest side of the faces round each vertex."""
        return vertex_edges(self.V, self.F, self.face_of)

    @cached_property
    def inside(self) -> InsideTest:
        """Exact inside test (ray parity)."""
        return InsideTest(self.V, self.F)

    @cached_property
    def face_tree(self) -> FaceTree:
        """Boxes over the faces, for cross-sections."""
        return FaceTree(self.V, self.F)
