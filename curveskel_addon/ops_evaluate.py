"""Evaluate Skeleton and Refine Skeleton (issue 33): any armature against the active mesh.

Thin on purpose: read the mesh and the armature (both taken to world space, so their objects'
transforms may differ), call the core (:func:`.core.evaluate`, :class:`.core.Refinement`), write
the results, report. The armature becomes segments by :mod:`.rig.armature_segments`
(connected bones share a joint, a disconnected child is joined to its parent's tail).

Evaluate writes, on the mesh, the colour attribute ``curveskel_fit`` (the residual as a heat
map: blue where the skeleton explains the surface, red where it does not), the float attribute
``curveskel_residual`` (``|v - sigma(v)| - r(sigma(v))`` in world units) and the report
(``curveskel_fit_report``, JSON, drawn by the panel); and the armature's silhouette beside it
(``<armature>.silhouette`` in the CurveSkel collection). Refine moves the armature's bones to the
refined joints in one undo step, keeping names, parents, deform flags, bone collections and
custom properties; locked and hidden bones do not move. Nothing is written when the input is
refused: the message says why, the armature and the mesh stay as they were.
"""

from __future__ import annotations

import json
import time
import traceback

import bpy
import numpy as np
from bpy.props import BoolProperty, FloatProperty, PointerProperty, StringProperty
from mathutils import Matrix

from . import results
from .armature import local_up
from .core import CurveSkelError, Refinement, evaluate
from .core.config import CONFIG
from .measure.evaluation import HEAT_RANGE, full_report, heat_colours, report_lines
from .mesh_read import mesh_arrays
from .rig.armature_segments import armature_segments, bone_roll_axes
from .silhouette import build_silhouette, update_silhouette

__all__ = ["CURVESKEL_OT_evaluate", "CURVESKEL_OT_refine", "CURVESKEL_PT_evaluate",
           "CurveSkelEvaluateSettings", "LiveRefine", "CLASSES", "type_properties",
           "FIT_ATTRIBUTE", "RESIDUAL_ATTRIBUTE", "REPORT_KEY"]

FIT_ATTRIBUTE = "curveskel_fit"
RESIDUAL_ATTRIBUTE = "curveskel_residual"
REPORT_KEY = "curveskel_fit_report"
#: on an evaluation's silhouette: the armature it shows
FIT_OF_KEY = "curveskel_fit_of"


class CurveSkelEvaluateSettings(bpy.types.PropertyGroup):
    """The panel's choices for Evaluate and Refine (``scene.curveskel_evaluate``)."""

    armature: PointerProperty(
        type=bpy.types.Object, name="Armature",
        description="The armature to evaluate against the active mesh: curveskel's, drawn by "
        "hand, a Rigify metarig or an imported rig",
        poll=lambda self, ob: ob.type == 'ARMATURE')
    heat_range: FloatProperty(
        name="Heat Range", default=HEAT_RANGE, min=1e-4, max=1.0, precision=3, step=0.1,
        description="The residual, as a share of the mesh's size, at which the heat map is "
                    "full red")
    keep_rolls: BoolProperty(
        name="Keep Rolls", default=False,
        description="Refine keeps each bone's roll; off: rolls are recomputed as curveskel's "
                    "own armatures get them")
    interactive: BoolProperty(
        name="Interactive", default=False,
        description="Show the refinement live (Esc keeps the joints reached so far)")


def type_properties():
    """(type, attribute, property) added at registration (``registration.py``)."""
    return ((bpy.types.Scene, "curveskel_evaluate",
             PointerProperty(type=CurveSkelEvaluateSettings, name="CurveSkel Evaluate")),)


# -- reading -----------------------------------------------------------------------------------
def _world(P, matrix) -> np.ndarray:
    M = np.array(matrix, dtype=np.float64)
    return P @ M[:3, :3].T + M[:3, 3]


def mesh_input(ob):
    """(V world (n, 3), F (m, 3)) of the mesh object's own data (no modifiers: the rest shape
    a rig is built on; its vertices are the ones the heat map colours)."""
    V, F = mesh_arrays(ob.data)
    return _world(V, ob.matrix_world), F


def armature_input(arm):
    """The armature's bones in world space and as segments.

    Returns
    -------
    dict
        ``names``, ``parent`` (nb,), ``connected`` (nb,), ``heads``/``tails`` (nb, 3) in the
        armature's space, ``segments`` (:class:`.rig.armature_segments.ArmatureSegments` in
        world space), ``hidden`` (nb,) bool.

    Raises
    ------
    CurveSkelError
        An armature with no bones.
    """
    bones = list(arm.data.bones)
    if not bones:
        raise CurveSkelError(f"armature '{arm.name}' has no bones: nothing to evaluate")
    index = {b.name: i for i, b in enumerate(bones)}
    nb = len(bones)
    H = np.empty(nb * 3)
    T = np.empty(nb * 3)
    arm.data.bones.foreach_get("head_local", H)
    arm.data.bones.foreach_get("tail_local", T)
    H, T = H.reshape(-1, 3), T.reshape(-1, 3)
    parent = np.array([index[b.parent.name] if b.parent else -1 for b in bones])
    connected = np.array([bool(b.use_connect) for b in bones])
    hidden = np.array([bool(b.hide) or (len(b.collections) > 0
                                        and not any(c.is_visible for c in b.collections))
                       for b in bones])
    seg = armature_segments(_world(H, arm.matrix_world), _world(T, arm.matrix_world), parent,
                            connected)
    return {"names": [b.name for b in bones], "parent": parent, "connected": connected,
            "heads": H, "tails": T, "segments": seg, "hidden": hidden}


def _locked(context, arm, names) -> np.ndarray:
    """(nb,) bool: the bones locked in Edit Mode (the flag lives on edit bones only)."""
    with _edit_mode(context, arm):
        ebs = arm.data.edit_bones
        return np.array([bool(ebs[n].lock) for n in names])


class _edit_mode:
    """Edit Mode on ``arm`` for the block; the active object and mode as they were after."""

    def __init__(self, context, arm):
        self.context, self.arm = context, arm

    def __enter__(self):
        vl = self.context.view_layer
        self.prev = vl.objects.active
        if self.arm.name not in vl.objects:
            raise CurveSkelError(f"armature '{self.arm.name}' is not in the view layer: its "
                                 "bones cannot be edited")
        if self.prev is not None and self.prev.mode != 'OBJECT':
            bpy.ops.object.mode_set(mode='OBJECT')
        vl.objects.active = self.arm
        bpy.ops.object.mode_set(mode='EDIT')
        if self.arm.mode != 'EDIT':
            raise CurveSkelError(f"could not enter Edit Mode on '{self.arm.name}'")
        return self

    def __exit__(self, *exc):
        if self.arm.mode != 'OBJECT':
            bpy.ops.object.mode_set(mode='OBJECT')
        vl = self.context.view_layer
        if self.prev is not None and self.prev.name in vl.objects:
            vl.objects.active = self.prev
        return False


# -- writing -----------------------------------------------------------------------------------
def write_heat_map(ob, residual, D, heat_range) -> None:
    """The residual on the mesh: ``curveskel_fit`` (colours, made the active colour attribute)
    and ``curveskel_residual`` (values)."""
    me = ob.data
    for name in (FIT_ATTRIBUTE, RESIDUAL_ATTRIBUTE):
        old = me.attributes.get(name)
        if old is not None:
            me.attributes.remove(old)
    col = me.color_attributes.new(FIT_ATTRIBUTE, 'FLOAT_COLOR', 'POINT')
    col.data.foreach_set("color", heat_colours(residual, D, heat_range).ravel())
    res = me.attributes.new(RESIDUAL_ATTRIBUTE, 'FLOAT', 'POINT')
    res.data.foreach_set("value", np.asarray(residual, np.float32))
    me.color_attributes.active_color = me.color_attributes[FIT_ATTRIBUTE]
    me.update()


class _Shown:
    """What a silhouette build reads: joints (J, 4) and bones (B, 2)."""

    def __init__(self, joints, bones):
        self.joints, self.bones = np.asarray(joints), np.asarray(bones)


def fit_silhouette(context, arm, joints, bones):
    """The armature's silhouette (world space) beside it, replacing the previous one."""
    name = f"{arm.name}.silhouette"
    old = [ob for ob in bpy.data.objects if ob.get(FIT_OF_KEY) == arm.name]
    for ob in old:
        ob.name = ob.name + ".previous"
    sil = build_silhouette(_Shown(joints, bones), name, results.collection(context),
                           Matrix.Identity(4), roots=[int(np.asarray(bones)[0, 0])])
    sil[FIT_OF_KEY] = arm.name
    results.remove_objects(old)
    results.adopt_names(sil, name)
    return sil


def store_report(ob, arm, report: dict) -> None:
    """The report on the mesh (per vertex left out: the attributes hold it)."""
    rep = {k: v for k, v in report.items() if k != "vertex_residual"}
    rep["armature"] = arm.name
    ob[REPORT_KEY] = json.dumps(rep)


def stored_report(ob) -> dict | None:
    text = ob.get(REPORT_KEY) if ob is not None else None
    try:
        return json.loads(text) if text else None
    except (TypeError, ValueError):
        return None


def write_bones(context, arm, data, joints_world, fixed_joints, keep_rolls) -> int:
    """Move the armature's bones onto ``joints_world`` (one Edit Mode pass). A bone end on a
    fixed joint keeps its own coordinates to the last bit; a bone of no length keeps its
    length. Returns the number of bones moved."""
    seg = data["segments"]
    M_inv = np.array(arm.matrix_world.inverted(), dtype=np.float64)
    X = _world(np.asarray(joints_world)[:, :3], M_inv)
    H0, T0 = data["heads"], data["tails"]
    H = np.where(fixed_joints[seg.head][:, None], H0, X[seg.head])
    T = np.where(fixed_joints[seg.tail][:, None], T0, X[seg.tail])
    flat = seg.head == seg.tail
    T[flat] = H[flat] + (T0[flat] - H0[flat])
    z = None if keep_rolls else bone_roll_axes(H, T, data["parent"], local_up(arm.matrix_world))
    moved = 0
    with _edit_mode(context, arm):
        ebs = arm.data.edit_bones
        for b, name in enumerate(data["names"]):
            eb = ebs[name]
            roll = eb.roll
            if np.array_equal(H[b], H0[b]) and np.array_equal(T[b], T0[b]) and keep_rolls:
                continue
            eb.head = H[b]
            eb.tail = T[b]
            if z is None:
                eb.roll = roll
            else:
                eb.align_roll(z[b])
            moved += 1
    return moved


# -- the operators -----------------------------------------------------------------------------
def _targets(context, armature_name: str = ""):
    """(mesh, armature, problem)."""
    ob = context.active_object
    if ob is None or ob.type != 'MESH':
        return None, None, "Make the mesh to evaluate against the active object"
    if context.mode != 'OBJECT':
        return ob, None, "Switch to Object Mode"
    settings = getattr(context.scene, "curveskel_evaluate", None)
    arm = bpy.data.objects.get(armature_name) if armature_name else \
        (settings.armature if settings is not None else None)
    if arm is None or arm.type != 'ARMATURE':
        what = f"'{armature_name}' is not an armature" if armature_name else \
            "Choose an armature in the panel (Evaluate Skeleton)"
        return ob, None, what
    return ob, arm, None


class _Targets:
    armature: StringProperty(name="Armature", default="",
                             description="Armature to use (empty: the one chosen in the panel)")

    @classmethod
    def poll(cls, context):
        # the armature is checked in execute: a script may name one (``armature=``) that the
        # panel has not chosen, and poll cannot see the operator's properties
        ob = context.active_object
        if ob is None or ob.type != 'MESH':
            cls.poll_message_set("Make the mesh to evaluate against the active object")
            return False
        if context.mode != 'OBJECT':
            cls.poll_message_set("Switch to Object Mode")
            return False
        return True

    def _checked(self, context):
        mesh, arm, problem = _targets(context, self.armature)
        if problem is not None:
            self.report({'ERROR'}, problem)
            return None, None
        return mesh, arm

    def _settings(self, context):
        return getattr(context.scene, "curveskel_evaluate", None)


def _fail(op, exc, what):
    if isinstance(exc, CurveSkelError):
        op.report({'ERROR'}, f"CurveSkel {what}: {exc}")
    else:        # a bug, not bad input: the traceback to the console
        traceback.print_exception(exc)
        op.report({'ERROR'}, f"CurveSkel {what}: internal error ({type(exc).__name__}: {exc})")
    return {'CANCELLED'}


def _show(context, mesh, arm, rep, heat_range):
    """Heat map, silhouette and report of an evaluation (all or nothing)."""
    sil = fit_silhouette(context, arm, rep.joints, rep.bones)
    try:
        write_heat_map(mesh, rep.vertex_residual, rep.D, heat_range)
    except BaseException:
        results.remove_objects([sil])
        raise
    return sil


class CURVESKEL_OT_evaluate(_Targets, bpy.types.Operator):
    """How well an armature explains the active mesh, by the objective J: the report in the
    panel, a heat map on the mesh (red where the skeleton explains the surface badly) and the
    armature's silhouette"""

    bl_idname = "curveskel.evaluate"
    bl_label = "Evaluate Skeleton"
    bl_options = {'REGISTER', 'UNDO'}

    heat_range: FloatProperty(name="Heat Range", default=HEAT_RANGE, min=1e-4, max=1.0,
                              precision=3, description="Share of the mesh's size at which the "
                              "heat map is full red")

    def invoke(self, context, event):
        s = self._settings(context)
        if s is not None and not self.properties.is_property_set("heat_range"):
            self.heat_range = s.heat_range
        return self.execute(context)

    def execute(self, context):
        mesh, arm = self._checked(context)
        if mesh is None:
            return {'CANCELLED'}
        what = f"'{mesh.name}' / '{arm.name}'"
        t0 = time.perf_counter()
        try:
            data = armature_input(arm)
            V, F = mesh_input(mesh)
            seg = data["segments"]
            rep = evaluate(V, F, (seg.joints, seg.segments))
            full = full_report(V, F, rep)
            _show(context, mesh, arm, rep, self.heat_range)
            store_report(mesh, arm, full)
        except BaseException as exc:
            return _fail(self, exc, what)
        self.report({'INFO'}, f"CurveSkel {what}: J {rep.J:.4g}, inside {rep.inside_fraction:.3f}, "
                              f"recon {full['recon_mean']:.4f}, {time.perf_counter() - t0:.2f} s")
        return {'FINISHED'}


class LiveRefine:
    """One refinement of an armature against a mesh; with ``live``, a preview silhouette
    follows the joints a few steps per timer tick (as Generate's live run). Headless-safe.

    The input is checked (the core's refusals) before Edit Mode is entered to read the locked
    bones: a refused armature is never touched.
    """

    def __init__(self, context, mesh, arm, *, live=False):
        self.data = data = armature_input(arm)
        self.V, self.F = mesh_input(mesh)
        seg = data["segments"]
        self.run = Refinement(self.V, self.F, (seg.joints, seg.segments),
                              step_iterations=CONFIG.search.refit_steps if live else None)
        self.fixed = seg.fixed_joints(data["hidden"] | _locked(context, arm, data["names"]))
        self.run.fix(self.fixed)
        self.mesh_name, self.arm_name = mesh.name, arm.name
        self.preview = None
        self._steps = self.run.steps()

    def start_preview(self, context):
        sk = self.run.current_skeleton()
        self.preview = fit_silhouette(context, bpy.data.objects[self.arm_name], sk.joints,
                                      sk.bones)

    def advance(self, n=1) -> bool:
        """Up to ``n`` steps, then the preview follows; True once the refinement is done."""
        done = False
        for _ in range(max(int(n), 1)):
            state = next(self._steps, None)
            if state is None or state.done:
                done = True
                break
        if self.preview is not None:
            sk = self.run.current_skeleton()
            update_silhouette(self.preview, _Shown(sk.joints, sk.bones))
        return done

    def finish(self, *, stopped=False):
        """The refinement's result: run to the end, or (``stopped``) the joints reached."""
        if stopped:
            self._steps.close()
            self.run.stop()
        return self.run.result()


class CURVESKEL_OT_refine(_Targets, bpy.types.Operator):
    """Move the armature's joints to where they explain the active mesh best (the minimum of
    J), keeping its bones, names, hierarchy, deform flags, collections and custom properties;
    locked and hidden bones do not move"""

    bl_idname = "curveskel.refine"
    bl_label = "Refine Skeleton"
    bl_options = {'REGISTER', 'UNDO'}

    keep_rolls: BoolProperty(name="Keep Rolls", default=False,
                             description="Keep each bone's roll (off: recomputed as curveskel's "
                                         "own armatures get them)")
    interactive: BoolProperty(name="Interactive", default=False,
                              description="Show the refinement live (Esc stops)")
    heat_range: FloatProperty(name="Heat Range", default=HEAT_RANGE, min=1e-4, max=1.0,
                              precision=3)

    def invoke(self, context, event):
        s = self._settings(context)
        if s is not None:
            for name in ("keep_rolls", "interactive", "heat_range"):
                if not self.properties.is_property_set(name):
                    setattr(self, name, getattr(s, name))
        if self.interactive and not bpy.app.background and context.window is not None:
            return self._modal_start(context)
        return self.execute(context)

    def execute(self, context):
        mesh, arm = self._checked(context)
        if mesh is None:
            return {'CANCELLED'}
        try:
            live = LiveRefine(context, mesh, arm)
            res = live.finish()
        except BaseException as exc:
            return _fail(self, exc, f"'{mesh.name}' / '{arm.name}'")
        return self._finish(context, mesh, arm, live, res)

    def _finish(self, context, mesh, arm, live, res):
        what = f"'{mesh.name}' / '{arm.name}'"
        try:
            moved = write_bones(context, arm, live.data, res.skeleton.joints, live.fixed,
                                self.keep_rolls)
            if live.preview is not None:
                results.remove_objects([live.preview])
            rep = res.after
            _show(context, mesh, arm, rep, self.heat_range)
            store_report(mesh, arm, full_report(live.V, live.F, rep))
        except BaseException as exc:
            return _fail(self, exc, what)
        self.report({'INFO'}, f"CurveSkel {what}: J {res.before.J:.4g} -> {res.after.J:.4g}, "
                              f"inside {res.before.inside_fraction:.3f} -> "
                              f"{res.after.inside_fraction:.3f}, {moved} bones moved "
                              f"({res.iterations} steps)")
        return {'FINISHED'}

    # -- interactive ---------------------------------------------------------------------------
    def _modal_start(self, context):
        mesh, arm = self._checked(context)
        if mesh is None:
            return {'CANCELLED'}
        try:
            self._run = LiveRefine(context, mesh, arm, live=True)
            self._run.start_preview(context)
        except BaseException as exc:
            return _fail(self, exc, f"'{mesh.name}' / '{arm.name}'")
        wm = context.window_manager
        self._timer = wm.event_timer_add(0.02, window=context.window)
        wm.modal_handler_add(self)
        return {'RUNNING_MODAL'}

    def modal(self, context, event):
        try:
            stop = event.type == 'ESC' and event.value == 'PRESS'
            if not stop and event.type != 'TIMER':
                return {'PASS_THROUGH'}
            done = stop or self._run.advance(1)
            if not done:
                return {'RUNNING_MODAL'}
            context.window_manager.event_timer_remove(self._timer)
            res = self._run.finish(stopped=stop)
            mesh = bpy.data.objects.get(self._run.mesh_name)
            arm = bpy.data.objects.get(self._run.arm_name)
            if mesh is None or arm is None:
                results.remove_objects([self._run.preview])
                self.report({'ERROR'}, "CurveSkel: the mesh or the armature is gone")
                return {'CANCELLED'}
            return self._finish(context, mesh, arm, self._run, res)
        except BaseException as exc:
            try:
                context.window_manager.event_timer_remove(self._timer)
            finally:
                results.remove_objects([getattr(self._run, "preview", None)])
            return _fail(self, exc, "refine")


class CURVESKEL_PT_evaluate(bpy.types.Panel):
    """Evaluate or refine any armature against the active mesh, and the last report."""

    bl_space_type = 'VIEW_3D'
    bl_region_type = 'UI'
    bl_category = "CurveSkel"
    bl_parent_id = "CURVESKEL_PT_main"
    bl_label = "Evaluate Skeleton"

    def draw(self, context):
        layout = self.layout
        s = getattr(context.scene, "curveskel_evaluate", None)
        if s is None:
            return
        col = layout.column()
        col.prop(s, "armature")
        col.prop(s, "heat_range")
        row = layout.row(align=True)
        row.enabled = s.armature is not None
        op = row.operator("curveskel.evaluate", icon='VIEWZOOM')
        op.heat_range = s.heat_range
        op = row.operator("curveskel.refine", icon='MOD_ARMATURE')
        op.keep_rolls, op.interactive, op.heat_range = s.keep_rolls, s.interactive, s.heat_range
        row = layout.row(align=True)
        row.prop(s, "keep_rolls")
        row.prop(s, "interactive")
        rep = stored_report(context.active_object)
        if rep is None:
            return
        box = layout.box()
        box.label(text=f"{context.active_object.name} / {rep.get('armature', '?')}", icon='INFO')
        for line in report_lines(rep):
            box.label(text=line)
        shading = getattr(context.space_data, "shading", None)
        if shading is not None:
            box.prop(shading, "color_type", text="Viewport Colour")


CLASSES = (CurveSkelEvaluateSettings, CURVESKEL_OT_evaluate, CURVESKEL_OT_refine,
           CURVESKEL_PT_evaluate)
