"""CURVESKEL_OT_bind: skin the active mesh to its curveskel armature (one undo step)."""

from __future__ import annotations

import bpy
from bpy.props import EnumProperty, FloatProperty, StringProperty

from . import results
from .binding import POINTER, bind_mesh
from .core.errors import CurveSkelError

__all__ = ["CURVESKEL_OT_bind", "CLASSES", "bind_targets", "METHOD_ITEMS"]

METHOD_ITEMS = (
    ("SURFACE", "Surface", "Each vertex follows the bone of the body part it lies on (closest bone "
     "restricted to its connected patch of the surface), blended at joints, smoothed along the "
     "surface (fast)"),
    ("HEAT", "Heat (Blender)", "Blender's automatic heat weights (slow on large meshes)"),
)


def bind_targets(context, armature_name: str = ""):
    """(mesh, armature, problem) for binding.

    The mesh is the active object, or the selected mesh when the active object is an armature
    (Blender's usual "select the mesh, then the armature" order). The armature is, in order: the
    one named ``armature_name``, a selected armature, the armature the mesh was bound to, the
    armature generated from it. Pointers only: no scan of all objects (this runs in poll).
    """
    ob = context.active_object
    sel = list(getattr(context, "selected_objects", []) or [])
    mesh = None
    if ob is not None and ob.type == 'MESH':
        mesh = ob
    elif ob is not None and ob.type == 'ARMATURE':
        meshes = [o for o in sel if o.type == 'MESH']
        mesh = meshes[0] if len(meshes) == 1 else None
    if mesh is None:
        return None, None, "Make a mesh active (or select it, then an armature)"
    arm = None
    if armature_name:
        arm = bpy.data.objects.get(armature_name)
        if arm is None or arm.type != 'ARMATURE':
            return mesh, None, f"'{armature_name}' is not an armature"
    if arm is None:
        arms = [o for o in sel if o.type == 'ARMATURE']
        arm = arms[0] if len(arms) == 1 else None
    if arm is None:
        arm = getattr(mesh, POINTER, None)
    if arm is None:
        arm = results.find_result(mesh)["armature"]
    if arm is None:
        return mesh, None, f"No armature for '{mesh.name}': generate one first, or select one"
    return mesh, arm, None


class CURVESKEL_OT_bind(bpy.types.Operator):
    """Bind the mesh to its armature as it is now (edited bones included): an Armature modifier,
    one vertex group per deforming bone, and the armature as the mesh's parent (its world
    transform kept). Re-binding replaces only what curveskel added before"""

    bl_idname = "curveskel.bind"
    bl_label = "Bind Mesh to Skeleton"
    bl_options = {'REGISTER', 'UNDO'}

    armature: StringProperty(
        name="Armature", default="",
        description="Armature to bind to (empty: the selected one, the one the mesh is bound to, "
        "or the mesh's CurveSkel result)")
    method: EnumProperty(name="Weights", default="SURFACE", items=METHOD_ITEMS,
                         description="How the vertex weights are computed")
    blend: FloatProperty(
        name="Blend Width", default=0.25, min=0.0, max=0.5, subtype='FACTOR',
        description="Width of the smooth blend at each joint, as a fraction of the bone's length")

    @classmethod
    def poll(cls, context):
        _, _, problem = bind_targets(context)
        if problem is not None:
            cls.poll_message_set(problem)
            return False
        return True

    smooth: FloatProperty(
        name="Surface Smoothing", default=0.5, min=0.0, soft_max=2.0,
        description="Diffuse the weights along the surface over this fraction of the typical "
        "limb radius (a bone's weights never reach a sibling limb; 0: no diffusion)")

    junction_blend: FloatProperty(
        name="Junction Blend", default=0.0, min=0.0, max=0.5, subtype='FACTOR',
        description="Blend where a limb leaves a junction, as a fraction of its first bone's length "
        "(0: rigid, posing a limb moves no vertex of another limb; more: softer creases)")

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.prop(self, "method")
        col = layout.column()
        col.active = self.method == "SURFACE"
        col.prop(self, "blend")
        col.prop(self, "junction_blend")
        col.prop(self, "smooth")

    def execute(self, context):
        mesh, arm, problem = bind_targets(context, self.armature)
        if problem is not None:
            self.report({'ERROR'}, problem)
            return {'CANCELLED'}
        if context.mode != 'OBJECT':
            bpy.ops.object.mode_set(mode='OBJECT')      # edit-mode bone changes are taken
        try:
            fig = bind_mesh(mesh, arm, None, blend=self.blend, smooth=self.smooth,
                            junction_blend=self.junction_blend, method=self.method)
        except CurveSkelError as exc:
            self.report({'ERROR'}, f"CurveSkel bind '{mesh.name}': {exc}")
            return {'CANCELLED'}
        for w in fig["warnings"]:
            self.report({'WARNING'}, f"CurveSkel bind '{mesh.name}': {w}")
        self.report({'INFO'}, f"CurveSkel: bound '{mesh.name}' to '{arm.name}' "
                              f"({fig['groups']} groups, {fig['vertices']} vertices, "
                              f"{fig['method'].lower()} weights, {fig['seconds']:.2f} s)")
        return {'FINISHED'}


CLASSES = (CURVESKEL_OT_bind,)
