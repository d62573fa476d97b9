"""Where results live and how they are found again: the "CurveSkel" collection, the names
"<mesh>.skeleton" / "<mesh>.silhouette", replacing a previous result, figures as custom properties.

Results and their source are linked by pointer properties (registered on ``bpy.types.Object``
by ``registration.py``), so renaming the mesh or a result keeps the link:

``curveskel_source_object``      on a result: the mesh it was made from
``curveskel_result_armature``    on the mesh: its armature
``curveskel_result_silhouette``  on the mesh: its silhouette

Every result object also carries the custom properties ``curveskel_source`` (the source's name
when it was made, read only for files saved before the pointers) and ``curveskel_role``
("armature" or "silhouette"); figures are plain custom properties (``ob["curveskel_..."]``), read
with ``ob.get`` — the same on Blender 4.2 and 5.0. Lookups from the panel and the operators'
``poll`` follow pointers and never scan ``bpy.data.objects``.
"""

from __future__ import annotations

import json

import bpy
from mathutils import Matrix

from .binding import POINTER
from .core.errors import CurveSkelError
from .rig.graph_root import central_joints
from .rig.rig_layout import rig_layout
from .run_summary import summary

__all__ = ["COLLECTION_NAME", "FIGURE_KEYS", "collection", "result_names", "find_result",
           "source_of", "source_object", "previous_results", "remove_objects", "adopt_names", "tag",
           "store_figures", "figures", "root_joints", "pointer_properties", "SOURCE_POINTER",
           "ARMATURE_POINTER", "SILHOUETTE_POINTER"]

COLLECTION_NAME = "CurveSkel"
SOURCE_KEY = "curveskel_source"
ROLE_KEY = "curveskel_role"
SOURCE_POINTER = "curveskel_source_object"
ARMATURE_POINTER = "curveskel_result_armature"
SILHOUETTE_POINTER = "curveskel_result_silhouette"
_ROLE_POINTER = {"armature": ARMATURE_POINTER, "silhouette": SILHOUETTE_POINTER}
#: Custom-property keys of the figures, with their labels in the panel.
#: J0 and J: the objective of the first stage of the search and of the result (the paper's
#: solver: its E); E: the paper's E of the result; Stages: the search's kept stages; Steps: its
#: minimisation steps (the paper's solver: gradient-descent iterations).
FIGURE_KEYS = {
    "curveskel_n_joints": "Joints",
    "curveskel_n_bones": "Bones",
    "curveskel_components": "Parts",
    "curveskel_J0": "J0",
    "curveskel_J": "J",
    "curveskel_E0": "E0",
    "curveskel_E": "E",
    "curveskel_stages": "Stages",
    "curveskel_iterations": "Steps",
    "curveskel_seconds": "Seconds",
}


def pointer_properties():
    """(type, attribute, property) of the Object pointers above and the binding's armature
    pointer (``binding.POINTER``), for ``registration.py``."""
    P = bpy.props.PointerProperty
    O = bpy.types.Object
    return ((O, SOURCE_POINTER, P(type=O, name="CurveSkel Source",
                                  description="Mesh this CurveSkel result was made from")),
            (O, ARMATURE_POINTER, P(type=O, name="CurveSkel Armature",
                                    description="Armature CurveSkel made from this mesh")),
            (O, SILHOUETTE_POINTER, P(type=O, name="CurveSkel Silhouette",
                                      description="Silhouette CurveSkel made from this mesh")),
            (O, POINTER, P(type=O, name="CurveSkel Bound Armature",
                           description="Armature this mesh was bound to by CurveSkel")))


def _pointer(ob, attr):
    return getattr(ob, attr, None) if ob is not None else None


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


def source_object(ob):
    """The source mesh of a result object (by pointer), or ``ob`` itself when it is not a result."""
    if ob is None:
        return None
    src = _pointer(ob, SOURCE_POINTER)
    if src is not None:
        return src
    legacy = ob.get(SOURCE_KEY)
    if legacy:
        return bpy.data.objects.get(legacy)
    return ob


def source_of(ob) -> str | None:
    """Name of the source mesh of a result object, or the object's own name for a mesh that is
    not a result (so the panel finds the result from the source, the armature or the silhouette)."""
    if ob is None:
        return None
    src = source_object(ob)
    return src.name if src is not None else (ob.get(SOURCE_KEY) or ob.name)


def find_result(source) -> dict:
    """``{"armature": ob or None, "silhouette": ob or None}`` of the result made from ``source``
    (an object, or its name). Follows the source's pointers; results of files saved before them
    are found by their names ("<source>.skeleton", "<source>.silhouette") and tag."""
    src = bpy.data.objects.get(source) if isinstance(source, str) else source
    name = source if isinstance(source, str) else getattr(source, "name", None)
    found = {"armature": None, "silhouette": None}
    for role, attr in _ROLE_POINTER.items():
        ob = _pointer(src, attr)
        if ob is not None and _pointer(ob, SOURCE_POINTER) == src:
            found[role] = ob
    if name:
        # by name: files saved before the pointers, or a source pointer whose reverse was
        # cleared (a cancelled interactive run removes its live silhouette)
        for role, cand in zip(("armature", "silhouette"), result_names(name)):
            ob = bpy.data.objects.get(cand)
            if found[role] is not None or ob is None:
                continue
            ptr = _pointer(ob, SOURCE_POINTER)
            if (ptr is None and ob.get(SOURCE_KEY) == name) or (ptr is not None and ptr == src):
                found[role] = ob
    return found


def previous_results(source, keep=()) -> list:
    """Every result object made from ``source`` (an object or its name) except those in ``keep``
    (scans the objects once: for the operator's execute, not for poll or draw)."""
    src = bpy.data.objects.get(source) if isinstance(source, str) else source
    name = source if isinstance(source, str) else source.name
    keep_ptrs = {k.as_pointer() for k in keep if k is not None}
    out = []
    for ob in bpy.data.objects:
        if ob.as_pointer() in keep_ptrs or ob == src:
            continue
        ptr = _pointer(ob, SOURCE_POINTER)
        if (ptr is not None and ptr == src) or (ptr is None and ob.get(SOURCE_KEY) == name):
            out.append(ob)
    return out


def remove_objects(objects) -> None:
    """Delete objects and their data-blocks when nothing else uses them. Children that stay (a
    mesh bound to a replaced armature) lose their parent but keep their world transform."""
    objects = [ob for ob in objects if ob is not None]
    going = {ob.as_pointer() for ob in objects}
    for ob in objects:
        for child in ob.children:
            if child.as_pointer() not in going:
                mw = child.matrix_world.copy()
                child.parent = None
                child.matrix_parent_inverse = Matrix.Identity(4)
                child.matrix_world = mw
    for ob in objects:
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


def tag(ob, source, role: str) -> None:
    """Mark ``ob`` as the ``role`` result of ``source`` (an object, or its name)."""
    src = bpy.data.objects.get(source) if isinstance(source, str) else source
    ob[SOURCE_KEY] = src.name if src is not None else str(source)
    ob[ROLE_KEY] = role
    if src is not None and hasattr(ob, SOURCE_POINTER):
        setattr(ob, SOURCE_POINTER, src)
        setattr(src, _ROLE_POINTER[role], ob)


def store_figures(ob, skeleton, *, params: dict, stopped: bool = False) -> None:
    """Write the result's figures on ``ob`` as custom properties (see FIGURE_KEYS)."""
    s = summary(skeleton)
    ob["curveskel_n_joints"] = int(s["joints"])
    ob["curveskel_n_bones"] = int(s["bones"])
    ob["curveskel_components"] = int(s["components"])
    ob["curveskel_J0"] = float(s["J0"])
    ob["curveskel_J"] = float(s["J"])
    ob["curveskel_E0"] = float(s["E0"])
    ob["curveskel_E"] = float(s["E"])
    ob["curveskel_stages"] = int(s["stages"])
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
    (``rig.rig_layout``), i.e. each part's most central joint."""
    if skeleton.n_bones:
        try:
            return rig_layout(skeleton.joints, skeleton.bones).roots
        except CurveSkelError:
            pass
    return central_joints(skeleton.joints, skeleton.bones)
