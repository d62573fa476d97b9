"""Export a rigged mesh and its armature with Blender's own glTF (.glb) and FBX exporters.

Only the two objects are written (selection export). Both exporters want the skinned mesh to be
a child of its armature, as a bind leaves it (``binding.parent_to_armature``); a mesh that is not
(its parent cleared by hand) is parented for the export, keeping its world transform, and put
back after. In the GLB the skinned mesh's node is then moved to the scene's roots, where glTF
wants it (``gltf_layout``): the file passes the Khronos glTF Validator with no error and no
warning (tests/blender/test_rig_exports.py runs it when node is available). Blender's glTF
*importer* adds a hidden "Icosphere" (its bone display shape, in the collection
"glTF_not_exported") unless imported with ``disable_bone_shape=True``: it is not in the file.
"""

from __future__ import annotations

import time
from pathlib import Path

import bpy

from .core.errors import CurveSkelError
from .gltf_layout import fix_glb_file

__all__ = ["export_rig", "FORMATS"]

#: file suffix -> format
FORMATS = {".glb": "GLB", ".fbx": "FBX"}


def export_rig(context, mesh_obj, arm_obj, filepath, *, fmt: str | None = None) -> dict:
    """Write ``mesh_obj`` (skinned) and ``arm_obj`` to ``filepath``; only these two are exported.

    Parameters
    ----------
    context : bpy.types.Context
    mesh_obj : bpy.types.Object
        A mesh bound to ``arm_obj`` (see :func:`binding.bind_mesh`).
    arm_obj : bpy.types.Object
        Its armature.
    filepath : str or Path
    fmt : {"GLB", "FBX"}, optional
        Default from the suffix (.glb, .fbx).

    Returns
    -------
    dict
        ``path``, ``format``, ``bones``, ``vertices``, ``seconds``, ``moved_to_root`` (GLB: skinned
        mesh nodes moved to the scene's roots).

    Raises
    ------
    CurveSkelError
        Unknown format, or the exporter failing.
    """
    path = Path(filepath)
    fmt = (fmt or FORMATS.get(path.suffix.lower(), "")).upper()
    if fmt not in FORMATS.values():
        raise CurveSkelError(f"cannot export '{path.name}': use a .glb or .fbx file")
    path.parent.mkdir(parents=True, exist_ok=True)
    vl = context.view_layer
    prev_sel = [o for o in vl.objects if o.select_get()]
    prev_active = vl.objects.active
    if prev_active is not None and prev_active.mode != 'OBJECT':
        bpy.ops.object.mode_set(mode='OBJECT')
    t0 = time.perf_counter()
    # Both exporters expect a skinned mesh to be a child of its armature (a bind parents it):
    # a mesh that is not is parented for the export, keeping its world placement, then restored.
    saved = None
    if mesh_obj.parent != arm_obj or mesh_obj.parent_type != 'OBJECT':
        saved = (mesh_obj.parent, mesh_obj.parent_type, mesh_obj.parent_bone,
                 mesh_obj.matrix_parent_inverse.copy(), mesh_obj.matrix_basis.copy())
        mw = mesh_obj.matrix_world.copy()
        mesh_obj.parent = arm_obj
        mesh_obj.parent_type = 'OBJECT'
        mesh_obj.matrix_parent_inverse = arm_obj.matrix_world.inverted()
        mesh_obj.matrix_basis = mw
        context.view_layer.update()
    try:
        for o in prev_sel:
            o.select_set(False)
        for o in (mesh_obj, arm_obj):
            o.select_set(True)
        vl.objects.active = arm_obj
        if fmt == "GLB":
            bpy.ops.export_scene.gltf(filepath=str(path), export_format='GLB', use_selection=True,
                                      export_skins=True, export_animations=False,
                                      export_def_bones=False)
        else:
            bpy.ops.export_scene.fbx(filepath=str(path), use_selection=True,
                                     object_types={'ARMATURE', 'MESH'}, add_leaf_bones=False,
                                     bake_anim=False, use_armature_deform_only=False)
        moved = fix_glb_file(path) if fmt == "GLB" and path.is_file() else 0
    except RuntimeError as exc:
        raise CurveSkelError(f"{fmt} export to '{path}' failed: {exc}") from exc
    except (OSError, ValueError) as exc:       # Blender ignores a full disk: a truncated file
        raise CurveSkelError(f"{fmt} export to '{path}' failed: the file written is incomplete "
                             f"({exc}; disk full?)") from exc
    finally:
        if saved is not None:
            (mesh_obj.parent, mesh_obj.parent_type, mesh_obj.parent_bone,
             mesh_obj.matrix_parent_inverse, mesh_obj.matrix_basis) = saved
            context.view_layer.update()
        for o in vl.objects:
            o.select_set(o in prev_sel)
        vl.objects.active = prev_active
    if not path.is_file():
        raise CurveSkelError(f"{fmt} export wrote no file at '{path}'")
    return {"path": str(path), "format": fmt, "bones": len(arm_obj.data.bones),
            "vertices": len(mesh_obj.data.vertices), "seconds": time.perf_counter() - t0,
            "moved_to_root": moved}
