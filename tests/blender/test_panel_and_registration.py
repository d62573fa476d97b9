"""Registration, the sidebar panel's settings and buttons, preferences, and import hygiene."""

import json
import subprocess
import sys
from pathlib import Path

import bpy
import numpy as np
import pytest
from meshes import capsule

import curveskel_addon
from curveskel_addon import panel, registration, results
from curveskel_addon.core import SkeletonParams, skeletonize
from curveskel_addon.properties import (
    ADVANCED_NAMES,
    OPTION_NAMES,
    PARAM_NAMES,
    settings_dict,
    skeleton_params,
)

ROOT = Path(__file__).resolve().parents[2]
CLASS_NAMES = [cls.__name__ for cls in registration.CLASSES]


def _registered() -> bool:
    return all(cls.is_registered for cls in registration.CLASSES)


def test_register_unregister_twice():
    assert _registered() and hasattr(bpy.types.Scene, "curveskel")
    for _ in range(2):
        curveskel_addon.unregister()
        assert not any(cls.is_registered for cls in registration.CLASSES)
        assert not hasattr(bpy.types.Scene, "curveskel")
        assert not hasattr(bpy.types, "CURVESKEL_OT_generate")
        assert panel._menu_entry not in bpy.types.VIEW3D_MT_object._dyn_ui_initialize()
        curveskel_addon.register()
        assert _registered() and hasattr(bpy.types.Scene, "curveskel")
    # the Object menu has our entry exactly once
    draw_funcs = getattr(bpy.types.VIEW3D_MT_object, "_dyn_ui_initialize")()
    assert sum(f is panel._menu_entry for f in draw_funcs) == 1


def test_class_names_and_panel_location():
    assert bpy.types.CURVESKEL_OT_generate.bl_idname == "curveskel.generate"
    assert {'REGISTER', 'UNDO'} <= set(bpy.types.CURVESKEL_OT_generate.bl_options)
    pt = bpy.types.CURVESKEL_PT_main
    assert (pt.bl_space_type, pt.bl_region_type, pt.bl_category) == ('VIEW_3D', 'UI', "CurveSkel")
    assert all(n.startswith(("CURVESKEL_OT_", "CURVESKEL_PT_", "CURVESKEL_AddonPreferences",
                             "CurveSkelSceneSettings", "CurveSkelEvaluateSettings"))
               for n in CLASS_NAMES)
    for name in ("CURVESKEL_OT_evaluate", "CURVESKEL_OT_refine"):
        op = getattr(bpy.types, name)
        assert {'REGISTER', 'UNDO'} <= set(op.bl_options)
    assert bpy.types.CURVESKEL_PT_evaluate.bl_parent_id == "CURVESKEL_PT_main"
    assert hasattr(bpy.types.Scene, "curveskel_evaluate")


def test_poll_message_says_why():
    bpy.context.view_layer.objects.active = None
    assert not bpy.ops.curveskel.generate.poll()
    with pytest.raises(RuntimeError, match="No active object"):
        bpy.ops.curveskel.generate()


def test_settings_defaults_match_the_core():
    d = SkeletonParams()
    s = bpy.context.scene.curveskel
    assert skeleton_params(s) == d      # float32 storage read back as the decimals typed
    assert set(settings_dict(s)) == set(PARAM_NAMES + ADVANCED_NAMES + OPTION_NAMES)
    assert set(PARAM_NAMES + ADVANCED_NAMES) == set(d.to_dict())     # all of the core's parameters
    op_props = bpy.ops.curveskel.generate.get_rna_type().properties
    for name in PARAM_NAMES + ADVANCED_NAMES + OPTION_NAMES:
        assert name in op_props and name in s.bl_rna.properties
    from curveskel_addon.preferences import CURVESKEL_AddonPreferences
    assert CURVESKEL_AddonPreferences.bl_idname == "curveskel_addon"


def test_panel_settings_reach_the_operator(make_mesh, mesh_arrays):
    """What the Generate button does: copy the scene settings into the operator's properties,
    which reach the core: the armature is the core's skeleton for those settings."""
    ob = make_mesh("Cylinder", *capsule())
    assert bpy.context.view_layer.objects.active == ob
    s = bpy.context.scene.curveskel
    s.spacing, s.smoothness, s.prune, s.max_joints = 0.08, 3.0, 0.5, 6
    s.max_iterations, s.make_silhouette = 5, False
    assert bpy.ops.curveskel.generate(**settings_dict(s)) == {'FINISHED'}
    found = results.find_result(ob.name)
    assert found["silhouette"] is None
    arm = found["armature"]
    params = json.loads(arm["curveskel_params"])
    assert {k: params[k] for k in ("spacing", "smoothness", "prune", "max_joints",
                                   "max_iterations")} == {
        "spacing": 0.08, "smoothness": 3.0, "prune": 0.5, "max_joints": 6, "max_iterations": 5}
    ref = skeletonize(*mesh_arrays(ob), SkeletonParams(spacing=0.08, smoothness=3.0, prune=0.5,
                                                       max_joints=6, max_iterations=5))
    assert ref.n_joints <= 6
    np.testing.assert_allclose(np.reshape(arm["curveskel_joints"], (-1, 4)), ref.joints,
                               rtol=1e-7, atol=1e-9)


def test_reset_settings_without_preferences_restores_defaults():
    s = bpy.context.scene.curveskel
    s.spacing, s.seed = 0.2, 7
    assert bpy.ops.curveskel.reset_settings() == {'FINISHED'}
    assert skeleton_params(s) == SkeletonParams()


def test_result_buttons(make_mesh):
    ob = make_mesh("Cylinder", *capsule())
    assert not bpy.ops.curveskel.select_armature.poll()
    bpy.ops.curveskel.generate()
    sil = results.find_result("Cylinder")["silhouette"]
    assert bpy.ops.curveskel.toggle_silhouette() == {'FINISHED'} and sil.hide_get()
    assert bpy.ops.curveskel.toggle_silhouette() == {'FINISHED'} and not sil.hide_get()
    assert bpy.ops.curveskel.select_armature() == {'FINISHED'}
    arm = bpy.context.view_layer.objects.active
    assert arm.name == "Cylinder.skeleton" and arm.select_get() and not ob.select_get()
    # the panel finds the result from the armature too, and shows its figures
    assert results.source_of(arm) == "Cylinder"
    figs = results.figures(arm)
    assert set(figs) == set(results.FIGURE_KEYS)
    with pytest.raises(RuntimeError, match="is armature, not a mesh"):
        bpy.ops.curveskel.generate()


def test_figures_read_the_same_after_save_and_reload(make_mesh, tmp_path):
    """Custom properties survive a .blend round trip (plain ID properties, read with .get)."""
    make_mesh("Cylinder", *capsule())
    bpy.ops.curveskel.generate()
    figs = results.figures(results.find_result("Cylinder")["armature"])
    path = tmp_path / "r.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    bpy.ops.wm.open_mainfile(filepath=str(path))
    again = results.figures(results.find_result("Cylinder")["armature"])
    assert again == pytest.approx(figs)


def test_core_imports_neither_bpy_nor_trimesh_nor_the_layers_above_it():
    """Every module of the core imported: no bpy, no trimesh, and nothing of what sits on top of
    the core (measures, rig, command line, mesh files, the Blender layer)."""
    code = ("import sys, pkgutil, importlib, curveskel_addon.core as c\n"
            "for m in pkgutil.walk_packages(c.__path__, c.__name__ + '.'):\n"
            "    importlib.import_module(m.name)\n"
            "above = ('curveskel_addon.measure', 'curveskel_addon.rig', 'curveskel_addon.cli', "
            "'curveskel_addon.mesh_files', 'curveskel_addon.run_summary', "
            "'curveskel_addon.registration')\n"
            "bad = [m for m in sys.modules if m in ('bpy', 'trimesh') or m.startswith(above)]\n"
            "print(bad); sys.exit(bool(bad))")
    out = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True)
    assert out.returncode == 0, out.stdout + out.stderr


def test_relative_imports_only():
    """Installed extensions are imported as bl_ext.<repo>.curveskel: no absolute self-imports."""
    import ast

    offenders = []
    for p in (ROOT / "curveskel_addon").rglob("*.py"):
        for node in ast.walk(ast.parse(p.read_text())):
            names = ([a.name for a in node.names] if isinstance(node, ast.Import)
                     else [node.module or ""] if isinstance(node, ast.ImportFrom) and node.level == 0 else [])
            offenders += [f"{p.relative_to(ROOT)}:{node.lineno}" for n in names
                          if n.split(".")[0] == "curveskel_addon"]
    assert offenders == []


class _Layout:
    """Stands in for bpy.types.UILayout (there is no UI headless): records what a draw() asks
    for and checks that every property and operator it names exists."""

    def __init__(self, log):
        object.__setattr__(self, "log", log)

    def __setattr__(self, name, value):
        self.log.append(("set", name, value))

    def _child(self, *args, **kw):
        return _Layout(self.log)

    column = row = box = split = grid_flow = _child

    def prop(self, data, name, **kw):
        assert name in data.bl_rna.properties, f"{data!r} has no property {name!r}"
        self.log.append(("prop", name))

    def label(self, text="", **kw):
        self.log.append(("label", text))

    def operator(self, idname, **kw):
        mod, name = idname.split(".")
        op = getattr(getattr(bpy.ops, mod), name)
        props = op.get_rna_type().properties
        log = self.log
        log.append(("operator", idname))

        class _Props:
            def __setattr__(self, key, value):
                assert key in props, f"{idname} has no property {key!r}"
                log.append(("opset", key, value))
        return _Props()


def _draw(panel_cls, context):
    log = []
    fake = type("FakePanel", (), {"layout": _Layout(log)})()
    panel_cls.draw(fake, context)
    return log


def test_panels_draw_parameters_button_and_figures(make_mesh):
    make_mesh("Cylinder", *capsule())
    log = _draw(panel.CURVESKEL_PT_main, bpy.context)
    assert ("operator", "curveskel.generate") in log
    opset = {e[1] for e in log if e[0] == "opset"}
    assert opset == set(settings_dict(bpy.context.scene.curveskel))
    assert {e[1] for e in log if e[0] == "prop"} >= set(PARAM_NAMES)
    advanced = _draw(panel.CURVESKEL_PT_advanced, bpy.context)
    assert {e[1] for e in advanced if e[0] == "prop"} == set(ADVANCED_NAMES)
    assert ("label", "No result for the active object") in _draw(panel.CURVESKEL_PT_result, bpy.context)
    bpy.ops.curveskel.generate()
    log = _draw(panel.CURVESKEL_PT_result, bpy.context)
    labels = [e[1] for e in log if e[0] == "label"]
    arm = results.find_result("Cylinder")["armature"]
    assert "Cylinder" in labels and "Bones" in labels and str(arm["curveskel_n_bones"]) in labels
    assert ("operator", "curveskel.select_armature") in log
    assert ("operator", "curveskel.toggle_silhouette") in log
