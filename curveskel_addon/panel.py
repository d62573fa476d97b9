"""View3D > Sidebar > CurveSkel: parameters, Generate, the active object's last result.

Also the small operators behind the panel's buttons (select the armature, toggle the silhouette,
reset the parameters to the preferences).
"""

from __future__ import annotations

import bpy

from . import results
from .ops_bind import METHOD_ITEMS, bind_targets
from .preferences import get_preferences
from .properties import ADVANCED_NAMES, OPTION_NAMES, PARAM_NAMES, draw_settings, settings_dict

__all__ = ["CURVESKEL_PT_main", "CURVESKEL_PT_advanced", "CURVESKEL_PT_result", "CURVESKEL_PT_bind",
           "CLASSES"]


def _active_result(context) -> tuple[str | None, dict]:
    name = results.source_of(context.active_object)
    return name, (results.find_result(name) if name else {"armature": None, "silhouette": None})


class CURVESKEL_OT_select_armature(bpy.types.Operator):
    """Select the armature made from the active object and make it active"""

    bl_idname = "curveskel.select_armature"
    bl_label = "Select Armature"
    bl_options = {'REGISTER', 'UNDO'}

    @classmethod
    def poll(cls, context):
        if context.mode != 'OBJECT':
            cls.poll_message_set("Switch to Object Mode")
            return False
        if _active_result(context)[1]["armature"] is None:
            cls.poll_message_set("The active object has no CurveSkel armature")
            return False
        return True

    def execute(self, context):
        arm = _active_result(context)[1]["armature"]
        if arm.name not in context.view_layer.objects:
            self.report({'ERROR'}, f"'{arm.name}' is not in the current view layer")
            return {'CANCELLED'}
        for ob in context.selected_objects:
            ob.select_set(False)
        arm.hide_set(False)
        arm.select_set(True)
        context.view_layer.objects.active = arm
        return {'FINISHED'}


class CURVESKEL_OT_toggle_silhouette(bpy.types.Operator):
    """Show or hide the silhouette made from the active object"""

    bl_idname = "curveskel.toggle_silhouette"
    bl_label = "Toggle Silhouette"
    bl_options = {'REGISTER', 'UNDO'}

    @classmethod
    def poll(cls, context):
        if _active_result(context)[1]["silhouette"] is None:
            cls.poll_message_set("The active object has no CurveSkel silhouette")
            return False
        return True

    def execute(self, context):
        sil = _active_result(context)[1]["silhouette"]
        if sil.name not in context.view_layer.objects:
            self.report({'ERROR'}, f"'{sil.name}' is not in the current view layer")
            return {'CANCELLED'}
        sil.hide_set(not sil.hide_get())
        return {'FINISHED'}


class CURVESKEL_OT_reset_settings(bpy.types.Operator):
    """Set the sidebar's parameters to the defaults of the add-on preferences"""

    bl_idname = "curveskel.reset_settings"
    bl_label = "Reset to Defaults"
    bl_options = {'REGISTER', 'UNDO'}

    def execute(self, context):
        prefs = get_preferences(context)
        settings = context.scene.curveskel
        for name in PARAM_NAMES + ADVANCED_NAMES + OPTION_NAMES:
            if prefs is not None:
                setattr(settings, name, getattr(prefs, name))
            else:
                settings.property_unset(name)
        return {'FINISHED'}


class _SidebarPanel:
    """Where every CurveSkel panel lives: the 3D View's sidebar, its CurveSkel tab."""

    bl_space_type = 'VIEW_3D'
    bl_region_type = 'UI'
    bl_category = "CurveSkel"


class _SubPanel(_SidebarPanel):
    bl_parent_id = "CURVESKEL_PT_main"


class CURVESKEL_PT_main(_SidebarPanel, bpy.types.Panel):
    bl_label = "Curve-Skeleton"

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        settings = context.scene.curveskel
        draw_settings(layout, settings, advanced=False)
        row = layout.row()
        row.scale_y = 1.5
        op = row.operator("curveskel.generate", text="Generate", icon='ARMATURE_DATA')
        for name, value in settings_dict(settings).items():
            setattr(op, name, value)
        layout.operator("curveskel.reset_settings", icon='LOOP_BACK')


class CURVESKEL_PT_advanced(_SubPanel, bpy.types.Panel):
    bl_label = "Advanced"
    bl_options = {'DEFAULT_CLOSED'}

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        col = layout.column()
        for name in ADVANCED_NAMES:
            col.prop(context.scene.curveskel, name)


class CURVESKEL_PT_result(_SubPanel, bpy.types.Panel):
    bl_label = "Last Result"

    def draw(self, context):
        layout = self.layout
        name, found = _active_result(context)
        holder = found["armature"] or found["silhouette"]
        if holder is None:
            layout.label(text="No result for the active object", icon='INFO')
            return
        layout.label(text=name, icon='MESH_DATA')
        figs = results.figures(holder)
        grid = layout.grid_flow(row_major=True, columns=2, even_columns=True, align=True)
        for key, label in results.FIGURE_KEYS.items():
            if key in figs:
                value = figs[key]
                grid.label(text=label)
                grid.label(text=f"{value:.4g}" if isinstance(value, float) else str(value))
        if holder.get("curveskel_stopped"):
            layout.label(text="Stopped before convergence", icon='PAUSE')
        row = layout.row(align=True)
        row.operator("curveskel.select_armature", icon='RESTRICT_SELECT_OFF')
        sil = found["silhouette"]
        hidden = sil is not None and sil.name in context.view_layer.objects and sil.hide_get()
        row.operator("curveskel.toggle_silhouette", text="Silhouette",
                     icon='HIDE_ON' if hidden else 'HIDE_OFF', depress=not hidden)
        if sil is not None:
            layout.prop(sil, "display_type", text="Silhouette Display")


class CURVESKEL_PT_bind(_SubPanel, bpy.types.Panel):
    """Bind the active mesh to its armature as it is now, with a choice of weights."""

    bl_label = "Bind Mesh"

    def draw(self, context):
        layout = self.layout
        mesh, arm, problem = bind_targets(context)      # pointers only: cheap at every redraw
        if problem is not None:
            layout.label(text=problem, icon='INFO')
        else:
            layout.label(text=f"{mesh.name} \u2192 {arm.name}", icon='ARMATURE_DATA')
        col = layout.column(align=True)
        col.enabled = problem is None
        for ident, label, _ in METHOD_ITEMS:
            op = col.operator("curveskel.bind", text=f"Bind: {label} Weights",
                              icon='MOD_ARMATURE' if ident == "SURFACE" else 'LIGHT_POINT')
            op.method = ident


def _menu_entry(self, context):
    self.layout.operator("curveskel.generate", icon='ARMATURE_DATA')
    self.layout.operator_menu_enum("curveskel.bind", "method", text="CurveSkel: Bind Mesh",
                                   icon='MOD_ARMATURE')
    self.layout.operator("curveskel.evaluate", text="CurveSkel: Evaluate Skeleton", icon='VIEWZOOM')
    self.layout.operator("curveskel.refine", text="CurveSkel: Refine Skeleton", icon='MOD_ARMATURE')


MENU_ENTRIES = ((bpy.types.VIEW3D_MT_object, _menu_entry),)
CLASSES = (CURVESKEL_OT_select_armature, CURVESKEL_OT_toggle_silhouette,
           CURVESKEL_OT_reset_settings, CURVESKEL_PT_main, CURVESKEL_PT_advanced, CURVESKEL_PT_result,
           CURVESKEL_PT_bind)
