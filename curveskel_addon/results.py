"""Where results live and how they are found again: the "CurveSkel" collection, the names
"<mesh>.skeleton" / "<mesh>.silhouette", replacing a previous result, figures as custom properties.

Every result object carries the custom properties ``curveskel_source`` (source object name) and
``curveskel_role`` ("armature" or "silhouette"); figures are plain custom properties
(``ob["curveskel_..."]``), read with ``ob.get`` — the same on Blender 4.2 and 5.0.
"""

from __future__ import annotations

import json

import bpy

__all__ = ["COLLECTION_NAME", "FIGURE_KEYS", "collection", "result_names", "find_result",
           "source_of", "previous_results", "remove_objects", "adopt_names", "tag", "store_figures",
           "figures", "root_joints"]

COLLECTION_NAME = "CurveSkel"
SOURCE_KEY = "curveskel_source"
ROLE_KEY = "curveskel_role"
#: Custom-property keys of the figures, with their labels in the panel.
FIGURE_KEYS = {
    "curveskel_n_joints": "Joints",
    "curveskel_n_bones": "Bones",
    "curveskel_components": "Parts",
    "curveskel_E0": "E0",
    "curveskel_E": "E",
    "curveskel_iterations": "Iterations",
    "curveskel_seconds": "Seconds",
}


def collection(context) -> bpy.types.Collection:
    """The "CurveSkel" collection, created once and linked to the scene if it is not."""
    coll = bpy.data.collections.get(COLLECTION_NAME)
    if coll is None:
        coll = bpy.data.collections.new(COLLECTION_NAME)
    scene_coll = context.scene.collection
    if coll.name not in scene_coll.children and not _in_tree(scene_coll, coll):
        scene_coll.children.link(coll)
    return coll


def _in_tree(parent, coll) -> bool:
    return any(c == coll or _in_tree(c, coll) for c in parent.children)


def result_names(source_name: str) -> tuple[str, str]:
    """Names of the armature and the silhouette made from ``source_name``."""
    return f"{source_name}.skeleton", f"{source_name}.silhouette"


def source_of(ob) -> str | None:
    """Name of the source mesh of a result object, or the object's own name for a mesh that is
    not a result (so the panel finds the result from the source, the armature or the silhouette)."""
    if ob is None:
        return None
    return ob.get(SOURCE_KEY) or ob.name


def find_result(source_name: str) -> dict:
    """``{"armature": ob or None, "silhouette": ob or None}`` of the result made from ``source_name``."""
    found = {"armature": None, "silhouette": None}
    for ob in bpy.data.objects:
        if ob.get(SOURCE_KEY) != source_name:
            continue
        role = ob.get(ROLE_KEY) or ("armature" if ob.type == 'ARMATURE' else "silhouette")
        if role in found and found[role] is None:
            found[role] = ob
    return found


def previous_results(source_name: str, keep=()) -> list:
    """Every result object made from ``source_name`` except those in ``keep``."""
    keep_ptrs = {k.as_pointer() for k in keep if k is not None}
    return [ob for ob in bpy.data.objects
            if ob.get(SOURCE_KEY) == source_name and ob.as_pointer() not in keep_ptrs]


def remove_objects(objects) -> None:
    """Delete objects and their data-blocks when nothing else uses them."""
    for ob in list(objects):
        if ob is None:
            continue
        data = ob.data
        bpy.data.objects.remove(ob, do_unlink=True)
        if data is not None and data.users == 0:
            if isinstance(data, bpy.types.Mesh):
                bpy.data.meshes.remove(data)
            elif isinstance(data, bpy.types.Armature):
                bpy.data.armatures.remove(data)


def adopt_names(ob, name: str) -> None:
    """Give ``ob`` and its data ``name`` (once the previous holder of the name is gone)."""
    ob.name = name
    if ob.data is not None and ob.data.users == 1:
        ob.data.name = name


def tag(ob, source_name: str, role: str) -> None:
    ob[SOURCE_KEY] = source_name
    ob[ROLE_KEY] = role


def store_figures(ob, skeleton, *, params: dict, stopped: bool = False) -> None:
    """Write the result's figures on ``ob`` as custom properties (see FIGURE_KEYS)."""
    s = skeleton.summary()
    ob["curveskel_n_joints"] = int(s["joints"])
    ob["curveskel_n_bones"] = int(s["bones"])
    ob["curveskel_components"] = int(s["components"])
    ob["curveskel_E0"] = float(s["E0"])
    ob["curveskel_E"] = float(s["E"])
    ob["curveskel_iterations"] = int(s["iterations"])
    ob["curveskel_seconds"] = round(float(s["seconds"]), 3)
    ob["curveskel_stopped"] = bool(stopped)
    ob["curveskel_params"] = json.dumps(params, sort_keys=True)


def figures(ob) -> dict:
    """The figures stored on ``ob`` (empty when it has none)."""
    if ob is None:
        return {}
    return {key: ob[key] for key in FIGURE_KEYS if key in ob}


def root_joints(skeleton):
    """Root joint of every connected part: the joints the armature roots its parts at
    (``core.rig_layout``), i.e. each part's most central joint."""
    from .core.errors import CurveSkelError
    from .core.graph_root import central_joints
    from .core.rig_layout import rig_layout

    if skeleton.n_bones:
        try:
            return rig_layout(skeleton.joints, skeleton.bones).roots
        except CurveSkelError:
            pass
    return central_joints(skeleton.joints, skeleton.bones)
