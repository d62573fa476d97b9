"""The mesh a user sees (modifiers applied) as arrays, in the object's local space."""

from __future__ import annotations

import numpy as np

__all__ = ["evaluated_triangles", "mesh_arrays"]


def evaluated_triangles(obj, depsgraph) -> tuple[np.ndarray, np.ndarray]:
    """Vertices and loop triangles of the evaluated mesh of ``obj`` (modifiers, shape keys applied).

    Reads with ``foreach_get`` from a temporary mesh (``to_mesh`` / ``to_mesh_clear``): the
    object and its mesh data-block are never written.

    Parameters
    ----------
    obj : bpy.types.Object
        A mesh object.
    depsgraph : bpy.types.Depsgraph
        ``context.evaluated_depsgraph_get()``.

    Returns
    -------
    V : (n, 3) float64
        Vertex positions in the object's local space, in the evaluated mesh's vertex order.
    F : (m, 3) int64
        Triangles (polygons split by Blender's loop triangulation).
    """
    ob_eval = obj.evaluated_get(depsgraph)
    me = ob_eval.to_mesh()
    try:
        return mesh_arrays(me)
    finally:
        ob_eval.to_mesh_clear()


def mesh_arrays(me) -> tuple[np.ndarray, np.ndarray]:
    """(V, F) of a mesh data-block: vertex positions and loop-triangle vertex indices."""
    me.calc_loop_triangles()
    V = np.empty(len(me.vertices) * 3, dtype=np.float32)
    me.vertices.foreach_get("co", V)
    F = np.empty(len(me.loop_triangles) * 3, dtype=np.int32)
    me.loop_triangles.foreach_get("vertices", F)
    return V.reshape(-1, 3).astype(np.float64), F.reshape(-1, 3).astype(np.int64)
