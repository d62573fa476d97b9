"""curveskel.generate in headless Blender: results, parity with the core, replacing, undo,
the source left untouched, and every bad input reported without changing anything."""

import json
import re

import bpy
import numpy as np
import pytest
from meshes import capsule, torus, two_capsules
from modal_support import FakeContext, fake_event, modal_operator
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from curveskel_addon import results
from curveskel_addon.core import SkeletonParams, skeletonize
from curveskel_addon.run_summary import summary

#: A coarser Detail Size than the default: the same operator, a few times faster (the core's
#: search takes seconds per mesh); the default settings run in the first test.
FAST = {"spacing": 0.08}


def _graph(n, E):
    """(number of parts, degree of each joint) of a skeleton graph."""
    E = np.asarray(E).reshape(-1, 2)
    G = coo_matrix((np.ones(len(E)), (E[:, 0], E[:, 1])), shape=(n, n))
    parts, _ = connected_components(G, directed=False)
    return parts, np.bincount(E.ravel(), minlength=n)


def _silhouette_arrays(sil):
    me = sil.data
    co = np.empty(len(me.vertices) * 3, np.float32)
    me.vertices.foreach_get("co", co)
    ed = np.empty(len(me.edges) * 2, np.int32)
    me.edges.foreach_get("vertices", ed)
    sv = me.skin_vertices[0].data
    rad = np.empty(len(sv) * 2, np.float32)
    sv.foreach_get("radius", rad)
    root = np.empty(len(sv), bool)
    sv.foreach_get("use_root", root)
    return co.reshape(-1, 3), ed.reshape(-1, 2), rad.reshape(-1, 2), root


def _generate(ob, **props):
    bpy.context.view_layer.objects.active = ob
    assert bpy.ops.curveskel.generate(**props) == {'FINISHED'}
    return results.find_result(ob.name)


def _check_parity(ob, found, mesh_arrays, params=None):
    """The operator's objects hold exactly the core's skeleton for the same V, F and params."""
    V, F = mesh_arrays(ob)
    sk = skeletonize(V, F, params or SkeletonParams())
    arm, sil = found["armature"], found["silhouette"]
    co, ed, rad, root = _silhouette_arrays(sil)
    scale = float(np.ptp(V, axis=0).max())
    np.testing.assert_array_equal(ed, sk.bones)
    np.testing.assert_allclose(co, sk.joints[:, :3], atol=1e-5 * scale, rtol=0)
    np.testing.assert_allclose(rad, np.repeat(sk.joints[:, 3:], 2, axis=1), atol=1e-5 * scale, rtol=0)
    # the armature keeps the skeleton itself (teammate's contract) and the figures
    np.testing.assert_allclose(np.reshape(arm["curveskel_joints"], (-1, 4)), sk.joints,
                               rtol=1e-7, atol=1e-9 * scale)
    np.testing.assert_array_equal(np.reshape(arm["curveskel_bones"], (-1, 2)), sk.bones)
    s = summary(sk)
    assert s["stages"] >= 1 and s["J"] <= s["J0"]
    for ob_ in (arm, sil):
        assert ob_["curveskel_n_joints"] == s["joints"]
        assert ob_["curveskel_n_bones"] == s["bones"]
        assert ob_["curveskel_components"] == s["components"]
        assert ob_["curveskel_stages"] == s["stages"]
        assert ob_["curveskel_iterations"] == s["iterations"]
        for key in ("J0", "J", "E0", "E"):
            assert ob_[f"curveskel_{key}"] == pytest.approx(s[key], rel=1e-6), key
        assert ob_["curveskel_seconds"] >= 0
    parts, _ = _graph(len(sk.joints), sk.bones)
    assert root.sum() == parts            # one Skin root per connected part
    return sk


def test_cylinder_gives_one_chain(make_mesh, mesh_arrays):
    ob = make_mesh("Cylinder", *capsule())
    found = _generate(ob)
    sk = _check_parity(ob, found, mesh_arrays)
    parts, deg = _graph(sk.n_joints, sk.bones)
    assert parts == 1 and sk.n_bones == sk.n_joints - 1 and deg.max() <= 2
    arm = found["armature"]
    assert arm.type == 'ARMATURE' and arm.name == "Cylinder.skeleton" and len(arm.data.bones) >= sk.n_bones
    assert found["silhouette"].name == "Cylinder.silhouette"
    coll = bpy.data.collections["CurveSkel"]
    assert {o.name for o in coll.objects} == {"Cylinder.skeleton", "Cylinder.silhouette"}
    assert bpy.context.view_layer.objects.active == ob      # the source stays active


def test_torus_gives_one_loop(make_mesh, mesh_arrays):
    ob = make_mesh("Torus", *torus())
    sk = _check_parity(ob, _generate(ob, **FAST), mesh_arrays, SkeletonParams(**FAST))
    parts, deg = _graph(sk.n_joints, sk.bones)
    assert parts == 1 and sk.n_bones - sk.n_joints + parts == 1     # exactly one loop
    assert (deg >= 2).sum() >= 0.8 * sk.n_joints                    # mostly the loop itself


def test_two_components_give_two_trees(make_mesh, mesh_arrays):
    ob = make_mesh("Pair", *two_capsules())
    found = _generate(ob, **FAST)
    sk = _check_parity(ob, found, mesh_arrays, SkeletonParams(**FAST))
    parts, _ = _graph(sk.n_joints, sk.bones)
    assert parts == 2 and sk.n_bones == sk.n_joints - 2
    assert found["armature"]["curveskel_components"] == 2


def test_suzanne_open_mesh(mesh_arrays):
    bpy.ops.mesh.primitive_monkey_add()
    ob = bpy.context.active_object
    found = _generate(ob, **FAST)
    sk = _check_parity(ob, found, mesh_arrays, SkeletonParams(**FAST))
    assert sk.n_bones >= 1 and np.all(np.isfinite(sk.joints))


def test_modifiers_applied_and_transform_copied(make_mesh, mesh_arrays):
    """The evaluated mesh (an Array modifier makes two parts) in the object's local space."""
    ob = make_mesh("Arrayed", *capsule(length=3.0))
    ob.location = (1.0, -2.0, 0.5)
    ob.rotation_euler = (0.3, 0.0, 1.1)
    ob.scale = (2.0, 2.0, 2.0)
    mod = ob.modifiers.new("Array", 'ARRAY')
    mod.count = 2
    mod.relative_offset_displace = (4.0, 0.0, 0.0)   # x is 4 diameters: a separate copy
    found = _generate(ob, **FAST)
    sk = _check_parity(ob, found, mesh_arrays, SkeletonParams(**FAST))
    assert sk.meta["components"] == 2
    for res in found.values():
        np.testing.assert_allclose(np.array(res.matrix_world), np.array(ob.matrix_world), atol=1e-6)


def test_rerun_replaces_previous_result(make_mesh, mesh_arrays):
    ob = make_mesh("Cylinder", *capsule())
    _generate(ob, spacing=0.1)
    arms, meshes = len(bpy.data.armatures), len(bpy.data.meshes)
    found = _generate(ob, spacing=0.08)
    names = sorted(o.name for o in bpy.data.objects)
    assert names == ["Cylinder", "Cylinder.silhouette", "Cylinder.skeleton"]
    assert (len(bpy.data.armatures), len(bpy.data.meshes)) == (arms, meshes)   # no orphans left
    assert found["armature"].data.name == "Cylinder.skeleton"
    assert found["silhouette"].data.name == "Cylinder.silhouette"
    _check_parity(ob, found, mesh_arrays, SkeletonParams(spacing=0.08))
    assert len(bpy.data.collections) == 1
    # a second mesh gets its own result beside the first
    other = make_mesh("Other", *capsule(length=2.0))
    _generate(other, **FAST)
    assert {o.name for o in bpy.data.collections["CurveSkel"].objects} == {
        "Cylinder.skeleton", "Cylinder.silhouette", "Other.skeleton", "Other.silhouette"}


def test_one_undo_restores_the_scene(make_mesh, scene_snapshot):
    """One undo step removes everything the operator made (the armature's edit-mode round trip
    included). Background mode has no undo stack until ed.undo_push() creates one, and
    bpy.ops pushes the operator's own step only when called with undo=True (what the UI does)."""
    make_mesh("Cylinder", *capsule())
    bpy.ops.ed.undo_push(message="before CurveSkel")
    before = scene_snapshot()
    assert bpy.ops.curveskel.generate('EXEC_DEFAULT', True, **FAST) == {'FINISHED'}
    assert scene_snapshot() != before
    assert bpy.ops.ed.undo() == {'FINISHED'}
    assert scene_snapshot() == before
    assert bpy.ops.ed.redo() == {'FINISHED'}
    assert "Cylinder.skeleton" in bpy.data.objects and "Cylinder.silhouette" in bpy.data.objects


def test_source_mesh_unchanged(make_mesh, mesh_digest):
    ob = make_mesh("Cylinder", *capsule())
    ob.modifiers.new("Subsurf", 'SUBSURF').levels = 1
    before = mesh_digest(ob)
    _generate(ob, **FAST)
    after = mesh_digest(ob)
    assert after["sha256"] == before["sha256"]
    for k in before:
        if isinstance(before[k], np.ndarray):
            np.testing.assert_array_equal(after[k], before[k])
        else:
            assert after[k] == before[k], k


def test_silhouette_display_and_toggles(make_mesh):
    ob = make_mesh("Cylinder", *capsule())
    sil = _generate(ob, **FAST)["silhouette"]
    assert sil.display_type == 'WIRE' and sil.hide_render
    assert [m.type for m in sil.modifiers][0] == 'SKIN'
    sil = _generate(ob, silhouette_in_render=True, make_armature=False, **FAST)["silhouette"]
    assert not sil.hide_render
    assert results.find_result("Cylinder")["armature"] is None
    assert "curveskel_n_bones" in sil          # figures also on the silhouette
    found = _generate(ob, make_silhouette=False, **FAST)
    assert found["silhouette"] is None and found["armature"] is not None


def test_bind_option_binds_the_mesh(make_mesh):
    ob = make_mesh("Cylinder", *capsule())
    arm = _generate(ob, bind=True, **FAST)["armature"]
    mods = [m for m in ob.modifiers if m.type == 'ARMATURE']
    assert len(mods) == 1 and mods[0].object == arm
    assert len(ob.vertex_groups) >= 1
    arm = _generate(ob, bind=True, **FAST)["armature"]      # re-run: still one modifier, on the new armature
    mods = [m for m in ob.modifiers if m.type == 'ARMATURE']
    assert len(mods) == 1 and mods[0].object == arm


def test_interactive_flag_runs_plain_execute_headless(make_mesh):
    make_mesh("Cylinder", *capsule())
    assert bpy.ops.curveskel.generate('INVOKE_DEFAULT', interactive=True, **FAST) == {'FINISHED'}
    assert results.find_result("Cylinder")["armature"] is not None


def test_success_is_reported(make_mesh, capsys):
    _generate(make_mesh("Cylinder", *capsule()), **FAST)
    out = capsys.readouterr().out
    assert "CurveSkel 'Cylinder':" in out and "joints" in out and " stages, " in out
    assert re.search(r"J [0-9.e+-]+ -> [0-9.e+-]+ in \d+ stages", out), out
    _generate(bpy.data.objects["Cylinder"], solver="paper")       # the paper's method: E
    out = capsys.readouterr().out
    assert re.search(r"E [0-9.e+-]+ -> [0-9.e+-]+ in \d+ iterations", out), out


# -- bad input: an ERROR report (RuntimeError in background mode), CANCELLED, nothing changed ----
def _no_active(make_mesh):
    make_mesh("Cylinder", *capsule())
    bpy.context.view_layer.objects.active = None


def _not_a_mesh(make_mesh):
    make_mesh("Cylinder", *capsule())
    bpy.ops.object.empty_add()


def _edit_mode(make_mesh):
    make_mesh("Cylinder", *capsule())
    bpy.ops.object.mode_set(mode='EDIT')


def _empty_mesh(make_mesh):
    make_mesh("Empty", np.zeros((0, 3)), np.zeros((0, 3), int))


def _no_faces(make_mesh):
    me = bpy.data.meshes.new("Edges")
    me.from_pydata([(0, 0, 0), (1, 0, 0), (1, 1, 0)], [(0, 1), (1, 2)], [])
    ob = bpy.data.objects.new("Edges", me)
    bpy.context.scene.collection.objects.link(ob)
    bpy.context.view_layer.objects.active = ob


def _nan(make_mesh):
    V, F = capsule()
    V[5] = np.nan
    make_mesh("Broken", V, F)


def _zero_area(make_mesh):     # a core error: every face degenerate
    make_mesh("Flat", [[0, 0, 0], [1, 0, 0], [2, 0, 0]], [[0, 1, 2]])


def _nothing_to_create(make_mesh):
    make_mesh("Cylinder", *capsule())
    return {"make_armature": False, "make_silhouette": False}


BAD = [
    (_no_active, "No active object"),
    (_not_a_mesh, "not a mesh"),
    (_edit_mode, "Object Mode"),
    (_empty_mesh, "no vertices"),
    (_no_faces, "no faces"),
    (_nan, "NaN"),
    (_zero_area, "zero area"),
    (_nothing_to_create, "Nothing to create"),
]


@pytest.mark.parametrize("setup, message", BAD, ids=[f.__name__.strip("_") for f, _ in BAD])
def test_bad_input_reports_and_changes_nothing(setup, message, make_mesh, scene_snapshot):
    props = setup(make_mesh) or {}
    before = scene_snapshot()
    with pytest.raises(RuntimeError, match=message):
        bpy.ops.curveskel.generate(**props)
    assert scene_snapshot() == before
    assert "CurveSkel" not in bpy.data.collections


# -- the command line's Blender path (curveskel_addon.headless) -------------------------------
@pytest.mark.parametrize("suffix", [".obj", ".ply", ".stl", ".off"])
def test_import_mesh_with_blender_importers(suffix, tmp_path):
    import trimesh

    from curveskel_addon import headless

    V, F = capsule(length=3.0, n_around=16, n_body=12)
    path = tmp_path / f"capsule{suffix}"
    trimesh.Trimesh(V, F, process=False).export(path)
    ob = headless.import_mesh(path)
    assert ob.type == 'MESH' and ob.name == "capsule" and bpy.context.view_layer.objects.active == ob
    assert len(ob.data.polygons) == len(F)
    found = headless.generate(ob, **FAST)
    assert found["armature"] is not None and found["silhouette"] is not None


def test_cli_outputs_blend_and_render(tmp_path):
    """--blend and --render: a .blend with mesh, armature and silhouette; a PNG (tiny here)."""
    import trimesh

    from curveskel_addon import headless

    V, F = capsule(length=3.0, n_around=16, n_body=12)
    mesh = tmp_path / "cap.obj"
    trimesh.Trimesh(V, F, process=False).export(mesh)
    orig = headless.render_preview

    def tiny(path, ob):
        return orig(path, ob, resolution=(96, 72), samples=2)
    headless.render_preview = tiny
    try:
        out = headless.cli_outputs(mesh, {"spacing": 0.08}, blend=tmp_path / "cap.blend",
                                   render=tmp_path / "cap.png")
    finally:
        headless.render_preview = orig
    assert out["armature"].name == "cap.skeleton" and out["silhouette"].name == "cap.silhouette"
    png = (tmp_path / "cap.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 1000
    # the preview's helpers are gone; the silhouette is back to not rendering
    assert not [o.name for o in bpy.data.objects if o.name.startswith("CurveSkel Preview")]
    assert not [m.name for m in bpy.data.materials if m.name.startswith("CurveSkel Preview")]
    assert not [g.name for g in bpy.data.node_groups if g.name.startswith("CurveSkel Preview")]
    assert out["silhouette"].hide_render
    src = out["object"]
    assert len(src.data.materials) == 0 and src.visible_shadow and src.visible_diffuse
    bpy.ops.wm.open_mainfile(filepath=str(tmp_path / "cap.blend"))
    assert {"cap", "cap.skeleton", "cap.silhouette"} <= {o.name for o in bpy.data.objects}
    assert json.loads(bpy.data.objects["cap.skeleton"]["curveskel_params"])["spacing"] == 0.08


# -- interactive mode: what the modal timer drives (timers do not run headless) ---------------
def _shows(sil, sk):
    """The silhouette shows ``sk``: its joints, bones and radii, one Skin root per part."""
    co, ed, rad, root = _silhouette_arrays(sil)
    np.testing.assert_array_equal(ed, sk.bones)
    np.testing.assert_allclose(co, sk.joints[:, :3], atol=1e-5)
    np.testing.assert_allclose(rad, np.repeat(sk.joints[:, 3:], 2, axis=1), atol=1e-5)
    assert root.sum() == _graph(sk.n_joints, sk.bones)[0]


def test_live_run_updates_the_silhouette_and_can_be_stopped(make_mesh, mesh_arrays):
    from curveskel_addon.ops_generate import LiveRun, build_result
    from curveskel_addon.properties import settings_dict

    ob = make_mesh("Cylinder", *capsule())
    _generate(ob, **FAST)                            # a previous result to replace
    live = LiveRun(bpy.context, ob, SkeletonParams(**FAST))
    first = live.run.current_skeleton()
    _shows(live.silhouette, first)                   # the first approximation
    assert live.silhouette.name.startswith("Cylinder.silhouette")
    shown = []
    while not live.advance(1):                       # stage by stage, as the timer does
        sk = live.run.current_skeleton()
        _shows(live.silhouette, sk)                  # the silhouette follows the search ...
        shown.append(sk)
        if len(shown) == 3:
            break
    assert len(shown) == 3, "the search ended before its third stage"
    # ... through merges that change the number of joints (the mesh rebuilt in place)
    assert first.n_joints != shown[-1].n_joints
    sk = live.stop()                                 # what Esc does
    assert live.state.iteration == 3 and len(sk.meta["stages"]) == 3
    assert sk.meta["J"] == min(st["J"] for st in sk.meta["stages"]) <= sk.meta["stages"][0]["J"]
    _shows(live.silhouette, sk)
    options = settings_dict(bpy.context.scene.curveskel)
    found = build_result(bpy.context, ob, sk, options, live_silhouette=live.silhouette, stopped=True)
    assert found["silhouette"] == live.silhouette and found["silhouette"].name == "Cylinder.silhouette"
    names = sorted(o.name for o in bpy.data.objects)
    assert names == ["Cylinder", "Cylinder.silhouette", "Cylinder.skeleton"]
    arm = found["armature"]
    assert arm["curveskel_stopped"] and arm["curveskel_stages"] == 3


def test_live_run_to_the_end_equals_execute(make_mesh, mesh_arrays):
    from curveskel_addon.ops_generate import LiveRun

    ob = make_mesh("Cylinder", *capsule())
    live = LiveRun(bpy.context, ob, SkeletonParams(**FAST))
    while not live.advance(3):
        pass
    sk = live.stop(finished=True)
    _shows(live.silhouette, sk)
    V, F = mesh_arrays(ob)
    ref = skeletonize(V, F, SkeletonParams(**FAST))
    np.testing.assert_array_equal(sk.bones, ref.bones)
    np.testing.assert_allclose(sk.joints, ref.joints, rtol=1e-7, atol=1e-9)
    assert sk.energy == pytest.approx(ref.energy)
    assert sk.meta["J"] == pytest.approx(ref.meta["J"], rel=1e-12)
    live.discard()
    assert "Cylinder.silhouette" not in bpy.data.objects


def test_modal_mode_watch_then_escape(make_mesh):
    ob = make_mesh("Cylinder", *capsule())
    ctx, op = FakeContext(), modal_operator(interactive=True, update_every=1, **FAST)
    assert op._modal_start(ctx) == {'RUNNING_MODAL'}
    assert ctx.window_manager.handlers == [op] and len(ctx.window_manager.timers) == 1
    sil = results.find_result("Cylinder")["silhouette"]
    first = _silhouette_arrays(sil)[0].copy()
    assert op.modal(ctx, fake_event('MOUSEMOVE')) == {'PASS_THROUGH'}      # the view stays usable
    for _ in range(3):
        assert op.modal(ctx, fake_event('TIMER')) == {'RUNNING_MODAL'}
    assert ctx.area.header.startswith("CurveSkel: stage 3 (") and "J = " in ctx.area.header
    moved = _silhouette_arrays(sil)[0]
    assert moved.shape != first.shape or not np.allclose(moved, first)   # the silhouette moved
    assert op.modal(ctx, fake_event('ESC', 'PRESS')) == {'FINISHED'}
    assert ctx.window_manager.timers == [] and ctx.area.header is None
    found = results.find_result("Cylinder")
    assert found["silhouette"] == sil and found["armature"] is not None
    assert found["armature"]["curveskel_stopped"] and found["armature"]["curveskel_stages"] == 3
    assert bpy.context.view_layer.objects.active == ob
    assert any("stopped after 3 stages" in msg for _, msg in op.reports), op.reports


def test_modal_mode_runs_to_the_end_like_execute(make_mesh):
    ob = make_mesh("Cylinder", *capsule())
    bpy.ops.curveskel.generate(**FAST)
    expected = results.figures(results.find_result("Cylinder")["armature"])
    ctx, op = FakeContext(), modal_operator(interactive=True, update_every=4, **FAST)
    assert op._modal_start(ctx) == {'RUNNING_MODAL'}
    for _ in range(1000):
        if op.modal(ctx, fake_event('TIMER')) == {'FINISHED'}:
            break
    found = results.find_result(ob.name)
    figs = results.figures(found["armature"])
    for key in ("curveskel_n_joints", "curveskel_n_bones", "curveskel_stages",
                "curveskel_iterations"):
        assert figs[key] == expected[key]
    for key in ("curveskel_J", "curveskel_E"):
        assert figs[key] == pytest.approx(expected[key], rel=1e-9)
    assert not found["armature"]["curveskel_stopped"]
    names = sorted(o.name for o in bpy.data.objects)
    assert names == ["Cylinder", "Cylinder.silhouette", "Cylinder.skeleton"]
