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
from .geometry.cluster import cluster_vertices
from .geometry.disc_sections import DiscSections, disc_sections
from .geometry.sections import Sections, cross_sections
from .geometry.meb import size_of

__all__ = ["Mesh"]


@dataclass(frozen=True, eq=False)
class Mesh:
    """A closed triangle mesh.

    Attributes
    ----------
    V : (n, 3) float, read-only
    F : (m, 3) int, read-only
    union : bool
        The solid is the union of the mesh's parts (overlapping parts of one figure): the
        inside test counts the winding number, not the parity (:class:`.geometry.inside.InsideTest`).
    """

    V: np.ndarray
    F: np.ndarray
    union: bool = False

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
    def inside(self) -> InsideTest:
        """Exact inside test (ray parity; the winding number for a union of parts)."""
        return InsideTest(self.V, self.F, union=self.union)

    @cached_property
    def face_tree(self) -> FaceTree:
        """Boxes over the faces, for cross-sections."""
        return FaceTree(self.V, self.F)

    @cached_property
    def _section_cache(self) -> dict:
        return {}

    def sections(self, X, N, reach, *, jacobian=False) -> Sections:
        """:func:`.geometry.sections.cross_sections` of this mesh, each plane's result kept:
        a search asks again and again for the sections of bones that did not move."""
        X = np.ascontiguousarray(X, np.float64).reshape(-1, 3)
        N = np.ascontiguousarray(N, np.float64).reshape(-1, 3)
        reach = np.broadcast_to(np.asarray(reach, np.float64), (len(X),))
        cache = self._section_cache
        rows = np.concatenate([X, N, reach[:, None]], 1)
        keys = [r.tobytes() for r in rows]
        hit = [cache.get(k) for k in keys]
        need = [i for i, h in enumerate(hit) if h is None or (jacobian and h[4] is None)]
        if need:
            idx = np.asarray(need)
            new = cross_sections(self.V, self.F, X[idx], N[idx], reach[idx], tree=self.face_tree,
                                 jacobian=jacobian)
            if len(cache) > 200_000:
                cache.clear()
            for j, i in enumerate(need):
                entry = (new.centroid[j], new.area[j], new.spread[j], new.found[j],
                         None if new.dc_dx is None else new.dc_dx[j],
                         None if new.dc_dn is None else new.dc_dn[j],
                         None if new.ds_dx is None else new.ds_dx[j],
                         None if new.ds_dn is None else new.ds_dn[j],
                         new.extent[j],
                         None if new.de_dx is None else new.de_dx[j],
                         None if new.de_dn is None else new.de_dn[j])
                cache[keys[i]] = entry
                hit[i] = entry
        if not len(X):
            return cross_sections(self.V, self.F, X, N, reach, jacobian=jacobian)
        cols = list(zip(*hit))
        stack = lambda c, shape: (np.array(c).reshape((len(X),) + shape) if c[0] is not None  # noqa: E731
                                  else None)
        return Sections(stack(cols[0], (3,)), np.array(cols[1], np.float64),
                        np.array(cols[2], np.float64), np.array(cols[3], bool),
                        stack(cols[4], (3, 3)) if jacobian else None,
                        stack(cols[5], (3, 3)) if jacobian else None,
                        stack(cols[6], (3,)) if jacobian else None,
                        stack(cols[7], (3,)) if jacobian else None,
                        np.array(cols[8], np.float64),
                        stack(cols[9], (3,)) if jacobian else None,
                        stack(cols[10], (3,)) if jacobian else None)

    def coarsened(self, h: float) -> "Mesh":
        """This mesh with its vertices clustered in cubes of side ``h``
        (:func:`.geometry.cluster.cluster_vertices`), or itself where its edges are already
        about that long: the cross-sections' centroids need no finer a surface than the
        method's resolution."""
        E, _ = self.edges
        if not len(E) or float(np.mean(row_norm(self.V[E[:, 0]] - self.V[E[:, 1]]))) >= 0.5 * h:
            return self
        return Mesh(*cluster_vertices(self.V, self.F, h), union=self.union)

    @cached_property
    def _disc_cache(self) -> dict:
        return {}

    def discs(self, X, N, R, *, jacobian=False) -> DiscSections:
        """:func:`.geometry.disc_sections.disc_sections` of this mesh, each disc's result kept
        (a search asks again and again for the sections of bones that did not move)."""
        X = np.ascontiguousarray(X, np.float64).reshape(-1, 3)
        N = np.ascontiguousarray(N, np.float64).reshape(-1, 3)
        R = np.broadcast_to(np.asarray(R, np.float64), (len(X),))
        k = len(X)
        cache = self._disc_cache
        keys = [r.tobytes() for r in np.concatenate([X, N, R[:, None]], 1)]
        hit = [cache.get(key) for key in keys]
        need = np.asarray([i for i, h in enumerate(hit) if h is None or (jacobian and h[2] is None)],
                          np.int64)
        if len(need):
            new = disc_sections(self.V, self.F, X[need], N[need], R[need], tree=self.face_tree,
                                inside=self.inside, jacobian=jacobian)
            if len(cache) > 200_000:
                cache.clear()
            for j, i in enumerate(need):
                entry = (new.centroid[j], new.area[j],
                         None if new.dc_dx is None else new.dc_dx[j],
                         None if new.dc_dn is None else new.dc_dn[j])
                cache[keys[i]] = entry
                hit[i] = entry
        centroid = np.array([h[0] for h in hit]).reshape(k, 3)
        area = np.array([h[1] for h in hit], np.float64)
        if not jacobian:
            return DiscSections(centroid, area)
        return DiscSections(centroid, area, np.array([h[2] for h in hit]).reshape(k, 3, 3),
                            np.array([h[3] for h in hit]).reshape(k, 3, 3))
