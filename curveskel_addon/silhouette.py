"""The silhouette: joints as vertices, bones as edges, a Skin modifier with the joints' radii."""

from __future__ import annotations

import bmesh
import bpy
import numpy as np

from .rig.graph_root import central_joints

__all__ = ["build_silhouette", "update_silhouette", "SKIN_MODIFIER", "SMOOTH_MODIFIER"]

SKIN_MODIFIER = "CurveSkel Skin"
SMOOTH_MODIFIER = "CurveSkel Smooth"


def build_silhouette(skeleton, name: str, collection, matrix_world, *, roots=(),
                     in_render: bool = False) -> bpy.types.Object:
    """A new mesh object showing ``skeleton`` as the Skin modifier's surface.

    Parameters
    ----------
    skeleton : core.Skeleton
        Joints (J, 4) become vertices with Skin radius r; bones (B, 2) become edges.
    name : str
        Name of the object and of its mesh.
    collection : bpy.types.Collection
        Where the object is linked.
    matrix_world : mathutils.Matrix
        The source object's transform (the skeleton is in the source's local space).
    roots : sequence of int
        Joints marked as Skin roots (one per connected part; ``results.root_joints``).
    in_render : bool
        Whether the silhouette shows in renders.

    Returns
    -------
    bpy.types.Object
        Displayed as wire so the source mesh stays visible.
    """
    J = skeleton.joints
    E = skeleton.bones
    me = bpy.data.meshes.new(name)
    me.vertices.add(len(J))
    me.vertices.foreach_set("co", np.ascontiguousarray(J[:, :3], dtype=np.float32).ravel())
    me.edges.add(len(E))
    me.edges.foreach_set("vertices", np.ascontiguousarray(E, dtype=np.int32).ravel())
    me.update()
    ob = bpy.data.objects.new(name, me)
    collection.objects.link(ob)
    ob.matrix_world = matrix_world
    mod = ob.modifiers.new(SKIN_MODIFIER, 'SKIN')     # creates me.skin_vertices[0]
    mod.use_smooth_shade = True
    mod.branch_smoothing = 0.0
    _set_skin(me, J[:, 3], roots)
    smooth = ob.modifiers.new(SMOOTH_MODIFIER, 'SUBSURF')   # the usual partner of Skin: rounds its hull
    smooth.levels = 1
    smooth.render_levels = 2
    ob.display_type = 'WIRE'
    ob.show_in_front = False
    ob.hide_render = not in_render
    return ob


def update_silhouette(ob, skeleton, *, roots=None) -> None:
    """Show ``skeleton`` on the silhouette ``ob``: its vertices and radii moved in place, or,
    when the joints or bones are not the same in number (the search merged joints or pruned a
    branch), the mesh's geometry rebuilt with the skin layer kept (the object, its modifiers and
    its mesh data-block stay)."""
    me = ob.data
    J = skeleton.joints
    if len(me.vertices) != len(J) or len(me.edges) != len(skeleton.bones):
        _rebuild(me, J[:, :3], skeleton.bones)
        if roots is None:           # the new vertices have no root flags: one root per part
            roots = central_joints(J, skeleton.bones)
    else:
        me.vertices.foreach_set("co", np.ascontiguousarray(J[:, :3], dtype=np.float32).ravel())
    _set_skin(me, J[:, 3], roots)
    me.update()


def _rebuild(me, X, bones) -> None:
    """Replace the geometry of ``me`` by vertices ``X`` and edges ``bones``, keeping its skin
    layer (``clear_geometry`` would drop it, and Python cannot add one to a mesh: bmesh can)."""
    bm = bmesh.new()
    try:
        bm.verts.layers.skin.verify()
        verts = [bm.verts.new(p) for p in np.asarray(X, dtype=np.float64).tolist()]
        for i, j in np.asarray(bones, dtype=np.int64).reshape(-1, 2).tolist():
            bm.edges.new((verts[i], verts[j]))
        bm.to_mesh(me)
    finally:
        bm.free()


def _set_skin(me, radius, roots) -> None:
    sv = me.skin_vertices[0].data
    sv.foreach_set("radius", np.repeat(np.asarray(radius, dtype=np.float32), 2))
    if roots is not None:
        mask = np.zeros(len(radius), dtype=bool)
        mask[np.asarray(roots, dtype=np.int64)] = True
        sv.foreach_set("use_root", mask)
