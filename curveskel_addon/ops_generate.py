"""CURVESKEL_OT_generate: the active mesh -> core -> armature + silhouette in "CurveSkel".

Thin on purpose: read properties and the evaluated mesh, call the core, build objects, report.
"""

from __future__ import annotations

import time
import traceback

import bpy

from . import results
from .armature import build_armature
from .binding import bind_mesh
from .core import CurveSkelError, SkeletonRun
from .mesh_read import evaluated_triangles
from .preferences import get_preferences
from .properties import (
    ADVANCED_NAMES,
    OPTION_NAMES,
    PARAM_NAMES,
    GenerateSettings,
    draw_settings,
    settings_dict,
    skeleton_params,
)
from .run_summary import headline, summary
from .silhouette import build_silhouette, update_silhouette

__all__ = ["CURVESKEL_OT_generate", "LiveRun", "input_problem", "build_result", "CLASSES"]

# Share of the progress bar (0..100) each core stage fills: the first approximation, then the
# search (every other stage the core reports: its minimisations and moves, "done").
_PROGRESS_SPAN = {"first_approximation": (0.0, 20.0)}
_SEARCH_SPAN = (20.0, 100.0)


def input_problem(context) -> str | None:
    """Why the operator cannot run in ``context`` (None when it can)."""
    ob = context.active_object
    if ob is None:
        return "No active object: select a mesh object to skeletonize"
    if ob.type != 'MESH':
        return f"Active object '{ob.name}' is {ob.type.lower()}, not a mesh: select a mesh object"
    if context.mode != 'OBJECT':
        return "Switch to Object Mode to generate a curve-skeleton"
    return None


def _progress(wm):
    def progress(stage: str, fraction: float) -> None:
        lo, hi = _PROGRESS_SPAN.get(stage, _SEARCH_SPAN)
        wm.progress_update(lo + (hi - lo) * min(max(fraction, 0.0), 1.0))
    return progress


def _describe(name: str, skeleton, seconds: float, stopped: bool = False) -> str:
    s = summary(skeleton)
    return (f"CurveSkel '{name}': {s['joints']} joints, {s['bones']} bones, "
            f"{headline(s, stopped=stopped)}, {seconds:.2f} s")


def build_result(context, src, skeleton, options: dict, *, live_silhouette=None,
                 stopped: bool = False) -> dict:
    """Create the armature and/or silhouette of ``skeleton`` for ``src``; replace its previous result.

    On any failure everything made here is removed again and the exception propagates, so the
    scene is left as it was. Returns ``{"armature": ob or None, "silhouette": ob or None}``.
    """
    arm_name, sil_name = results.result_names(src.name)
    made = []
    # The previous result steps aside (renamed) so the new objects get the exact names; it is
    # deleted once the new result is complete, or renamed back if anything fails.
    previous = {ob: ob.name for ob in results.previous_results(src, keep=(live_silhouette,))}
    for ob, name in previous.items():
        ob.name = name + ".previous"
    try:
        coll = results.collection(context)
        roots = results.root_joints(skeleton)
        mw = src.matrix_world.copy()
        arm = sil = None
        if options["make_armature"]:
            arm = build_armature(context, skeleton, arm_name, coll, mw, source=src)
            made.append(arm)
            results.tag(arm, src, "armature")
        if live_silhouette is not None:
            sil = live_silhouette
            update_silhouette(sil, skeleton, roots=roots)
            sil.hide_render = not options["silhouette_in_render"]
            results.adopt_names(sil, sil_name)
        elif options["make_silhouette"]:
            sil = build_silhouette(skeleton, sil_name, coll, mw, roots=roots,
                                   in_render=options["silhouette_in_render"])
            made.append(sil)
            results.tag(sil, src, "silhouette")
        params = {k: options[k] for k in PARAM_NAMES + ADVANCED_NAMES if k in options}
        for ob in (arm, sil):
            if ob is not None:
                results.store_figures(ob, skeleton, params=params, stopped=stopped)
        if options["bind"] and arm is not None:
            bind_mesh(src, arm, skeleton)   # uses the mapping when it matches the mesh's vertices
    except BaseException:
        results.remove_objects(made)
        for ob, name in previous.items():
            ob.name = name
        raise
    finally:
        _make_active(context, src)
    results.remove_objects(previous)
    for ob, name in ((arm, arm_name), (sil, sil_name)):
        if ob is not None:
            results.adopt_names(ob, name)     # data names too, now the old data are gone
    return {"armature": arm, "silhouette": sil}


def _make_active(context, ob) -> None:
    if ob is None or ob.name not in context.view_layer.objects:
        return
    if context.view_layer.objects.active is not None and context.view_layer.objects.active.mode != 'OBJECT':
        bpy.ops.object.mode_set(mode='OBJECT')
    context.view_layer.objects.active = ob


class LiveRun:
    """A run the user watches: the search advances a few stages at a time and the silhouette
    follows (the paper's Figure 4; the search's merges and prunes change the joints, the
    silhouette's mesh with them). The operator's modal mode drives it from a timer; nothing
    here needs a window, so it also runs headless.

    Creating it runs the first approximation and creates the live silhouette (tagged as the
    result of ``src``); :meth:`stop` returns the skeleton so far, :meth:`discard` removes the
    silhouette again.
    """

    def __init__(self, context, src, params, *, in_render: bool = False, progress=None):
        V, F = evaluated_triangles(src, context.evaluated_depsgraph_get())
        self.run = SkeletonRun(V, F, params, progress)        # may raise CurveSkelError
        self.source_name = src.name
        first = self.run.current_skeleton()
        _, sil_name = results.result_names(src.name)
        self.silhouette = build_silhouette(first, sil_name, results.collection(context),
                                           src.matrix_world.copy(), roots=results.root_joints(first),
                                           in_render=in_render)
        results.tag(self.silhouette, src, "silhouette")
        self._steps = self.run.steps()
        self.state = None

    def advance(self, stages: int) -> bool:
        """Run up to ``stages`` stages of the search, then redraw the silhouette. Returns True
        once the search has finished."""
        finished = False
        for _ in range(max(int(stages), 1)):
            state = next(self._steps, None)
            if state is not None:
                self.state = state
            if state is None or state.done:
                finished = True
                break
        sk = self.run.current_skeleton()
        update_silhouette(self.silhouette, sk, roots=results.root_joints(sk))
        return finished

    def stop(self, finished: bool = False):
        """End the run: the skeleton of the last stage the search kept (J never rises from one
        kept stage to the next, so it is the lowest-J skeleton so far; a finished search's is
        ``SkeletonRun.result()``)."""
        self._steps.close()
        if finished and self.state is not None and self.state.done:
            return self.run.result()
        return self.run.current_skeleton()

    def discard(self) -> None:
        self._steps.close()
        results.remove_objects([self.silhouette])


class CURVESKEL_OT_generate(GenerateSettings, bpy.types.Operator):
    """Fit a curve-skeleton to the active mesh: an armature and a Skin-modifier silhouette in the
    "CurveSkel" collection (the mesh itself is not changed)"""

    bl_idname = "curveskel.generate"
    bl_label = "Generate Curve-Skeleton"
    bl_options = {'REGISTER', 'UNDO'}

    @classmethod
    def poll(cls, context):
        problem = input_problem(context)
        if problem is not None:
            cls.poll_message_set(problem)
            return False
        return True

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        draw_settings(layout, self, advanced=True)

    # -- entry points ---------------------------------------------------------------------------
    def invoke(self, context, event):
        self._defaults_from_preferences(context)
        if self.interactive and not bpy.app.background and context.window is not None:
            return self._modal_start(context)
        return self.execute(context)

    def execute(self, context):
        self._defaults_from_preferences(context)
        src = self._checked_source(context)
        if src is None:
            return {'CANCELLED'}
        t0 = time.perf_counter()
        wm = context.window_manager
        wm.progress_begin(0, 100)
        try:
            V, F = evaluated_triangles(src, context.evaluated_depsgraph_get())
            skeleton = SkeletonRun(V, F, skeleton_params(self), _progress(wm)).result()
        except CurveSkelError as exc:
            self.report({'ERROR'}, f"CurveSkel '{src.name}': {exc}")
            return {'CANCELLED'}
        except Exception as exc:      # a bug, not bad input: say so, keep the traceback in the console
            traceback.print_exc()
            self.report({'ERROR'}, f"CurveSkel '{src.name}': internal error ({type(exc).__name__}: {exc})")
            return {'CANCELLED'}
        finally:
            wm.progress_end()
        return self._finish(context, src, skeleton, t0)

    # -- interactive mode: a timer steps the solver, the silhouette follows, Esc stops ----------
    def _modal_start(self, context):
        src = self._checked_source(context)
        if src is None:
            return {'CANCELLED'}
        self._t0 = time.perf_counter()
        self._live = self._timer = None
        wm = context.window_manager
        try:
            self._live = LiveRun(context, src, skeleton_params(self),
                                 in_render=self.silhouette_in_render, progress=_progress(wm))
            wm.progress_begin(0, 100)
            self._timer = wm.event_timer_add(0.02, window=context.window)
            wm.modal_handler_add(self)
            self._status(context, "first approximation (Esc to stop)")
        except BaseException as exc:
            return _modal_failed(self, context, exc, src.name)
        return {'RUNNING_MODAL'}

    def modal(self, context, event):
        # Whatever fails (bad input, a bug, Ctrl-C), the timer, the header text, the progress
        # bar and the live preview go with the run: _modal_failed cleans up and reports.
        try:
            if event.type == 'ESC' and event.value == 'PRESS':
                return self._modal_end(context, stopped=True)
            if event.type != 'TIMER':
                return {'PASS_THROUGH'}       # the view can still be orbited and zoomed
            if self._live.advance(self.update_every):
                return self._modal_end(context, stopped=False)
            st = self._live.state
            if st is not None:
                what = "E" if self._live.run.params.solver == "paper" else "J"
                self._status(context, f"stage {st.iteration} ({st.stage}), {what} = "
                                      f"{st.energy:.4g} (Esc to stop)")
            return {'RUNNING_MODAL'}
        except BaseException as exc:
            return _modal_failed(self, context, exc, getattr(self._live, "source_name", "?"))

    def _modal_end(self, context, *, stopped: bool):
        self._modal_cleanup(context)
        live = self._live
        skeleton = live.stop(finished=not stopped)
        src = bpy.data.objects.get(live.source_name)
        if src is None:
            live.discard()
            self.report({'ERROR'}, f"CurveSkel: the source object '{live.source_name}' is gone")
            return {'CANCELLED'}
        sil = live.silhouette
        if not self.make_silhouette:
            results.remove_objects([sil])
            sil = None
        return self._finish(context, src, skeleton, self._t0, live=sil, stopped=stopped)

    def _modal_cleanup(self, context) -> None:
        """Remove the timer (once), end the progress bar, clear the header; each step runs even
        if another fails."""
        wm = context.window_manager
        timer, self._timer = getattr(self, "_timer", None), None
        try:
            if timer is not None:
                wm.event_timer_remove(timer)
        finally:
            try:
                wm.progress_end()
            finally:
                self._status(context, None)

    def _status(self, context, text) -> None:
        if context.area is not None:
            context.area.header_text_set(None if text is None else f"CurveSkel: {text}")

    # -- shared ---------------------------------------------------------------------------------
    def _defaults_from_preferences(self, context) -> None:
        """Properties the caller did not set take the add-on preferences' values (once: after
        that they count as set, so Adjust Last Operation keeps what the user sees)."""
        prefs = get_preferences(context)
        if prefs is None:
            return
        for name in PARAM_NAMES + ADVANCED_NAMES + OPTION_NAMES:
            if not self.properties.is_property_set(name):
                setattr(self, name, getattr(prefs, name))

    def _checked_source(self, context):
        problem = input_problem(context)
        if problem is None and not (self.make_armature or self.make_silhouette):
            problem = "Nothing to create: enable Armature or Silhouette"
        if problem is not None:
            self.report({'ERROR'}, problem)
            return None
        return context.active_object

    def _finish(self, context, src, skeleton, t0, *, live=None, stopped=False):
        try:
            build_result(context, src, skeleton, settings_dict(self), live_silhouette=live,
                         stopped=stopped)
        except (CurveSkelError, RuntimeError, ValueError) as exc:
            if live is not None:
                results.remove_objects([live])
            self.report({'ERROR'}, f"CurveSkel '{src.name}': could not build the result: {exc}")
            return {'CANCELLED'}
        self.report({'INFO'}, _describe(src.name, skeleton, time.perf_counter() - t0, stopped))
        return {'FINISHED'}


def _modal_failed(op, context, exc: BaseException, name: str) -> set:
    """The interactive run failed: remove its timer, header text, progress bar and live preview
    (whatever of them exists), report why, and cancel. Input problems (CurveSkelError) are
    reported as they are; anything else is a bug: its traceback goes to the console."""
    try:
        op._modal_cleanup(context)
    finally:
        live = getattr(op, "_live", None)
        if live is not None:
            try:
                live.discard()
            except ReferenceError:        # the preview was already removed
                pass
    if isinstance(exc, CurveSkelError):
        op.report({'ERROR'}, f"CurveSkel '{name}': {exc}")
    elif isinstance(exc, KeyboardInterrupt):
        op.report({'WARNING'}, f"CurveSkel '{name}': interrupted")
    else:
        traceback.print_exception(exc)
        op.report({'ERROR'}, f"CurveSkel '{name}': internal error ({type(exc).__name__}: {exc})")
    return {'CANCELLED'}


CLASSES = (CURVESKEL_OT_generate,)
