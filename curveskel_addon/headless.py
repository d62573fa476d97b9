"""Blender-side helpers for the command line (``scripts/skeletonize.py --blend/--render``).

Import a mesh file with Blender's own importers, run the SAME operator the UI runs
(``curveskel.generate``), save a .blend, render a Cycles CPU preview. No maths here.
"""

from __future__ import annotations

from pathlib import Path

import bpy
import numpy as np

from . import results
from .core import CurveSkelError

__all__ = ["reset_scene", "ensure_registered", "mesh_object_from_arrays", "import_mesh",
           "generate", "save_blend", "render_preview", "cli_outputs"]

PREVIEW_COLLECTION = "CurveSkel Preview"


def reset_scene() -> None:
    """An empty scene (no default cube, camera or light)."""
    bpy.ops.wm.read_homefile(use_empty=True)


def ensure_registered() -> None:
    """Register the add-on's classes unless they already are (e.g. the extension is enabled)."""
    if not hasattr(bpy.types, "CURVESKEL_OT_generate"):
        from . import registration

        registration.register()


def mesh_object_from_arrays(name: str, V, F, collection=None) -> bpy.types.Object:
    """A new mesh object from vertices (n, 3) and triangles (m, 3), linked to ``collection``
    (default: the scene's collection), made active and selected."""
    V = np.ascontiguousarray(V, dtype=np.float32).reshape(-1, 3)
    F = np.ascontiguousarray(F, dtype=np.int32).reshape(-1, 3)
    me = bpy.data.meshes.new(name)
    me.vertices.add(len(V))
    me.vertices.foreach_set("co", V.ravel())
    me.loops.add(F.size)
    me.loops.foreach_set("vertex_index", F.ravel())
    me.polygons.add(len(F))
    me.polygons.foreach_set("loop_start", np.arange(0, F.size, 3, dtype=np.int32))
    me.update(calc_edges=True)
    ob = bpy.data.objects.new(name, me)
    (collection or bpy.context.scene.collection).objects.link(ob)
    _activate(ob)
    return ob


def import_mesh(path) -> bpy.types.Object:
    """Import a .obj / .ply / .stl (Blender's importers) or .off (read with trimesh) file.

    Returns the mesh object, active and selected; several objects in one file are joined.
    Raises CurveSkelError for a missing file, an unknown suffix or a file with no mesh.
    """
    path = Path(path).resolve()
    if not path.is_file():
        raise CurveSkelError(f"no such mesh file: {path}")
    suffix = path.suffix.lower()
    before = set(bpy.data.objects)
    if suffix == ".obj":
        bpy.ops.wm.obj_import(filepath=str(path))
    elif suffix == ".ply":
        bpy.ops.wm.ply_import(filepath=str(path))
    elif suffix == ".stl":
        bpy.ops.wm.stl_import(filepath=str(path))
    elif suffix == ".off":
        from .core.mesh_io import read_mesh   # trimesh: command line only, never inside Blender

        V, F = read_mesh(path)
        return mesh_object_from_arrays(path.stem, V, F)
    else:
        raise CurveSkelError(f"cannot import {path.name}: use .obj, .ply, .stl or .off")
    new = [ob for ob in bpy.data.objects if ob not in before and ob.type == 'MESH']
    if not new:
        raise CurveSkelError(f"{path.name} contains no mesh")
    for ob in bpy.context.view_layer.objects:
        ob.select_set(ob in new)
    bpy.context.view_layer.objects.active = new[0]
    if len(new) > 1:
        bpy.ops.object.join()
    ob = bpy.context.view_layer.objects.active
    ob.name = path.stem
    return ob


def generate(ob, **properties) -> dict:
    """Run ``curveskel.generate`` on ``ob`` (made active) with operator ``properties``.

    Returns ``{"armature": ..., "silhouette": ...}``. The operator's ERROR report becomes a
    CurveSkelError with its message.
    """
    ensure_registered()
    _activate(ob)
    try:
        bpy.ops.curveskel.generate('EXEC_DEFAULT', **properties)
    except RuntimeError as exc:
        msg = str(exc).strip()
        raise CurveSkelError(msg.removeprefix("Error:").strip()) from None
    return results.find_result(ob.name)


def save_blend(path) -> Path:
    path = Path(path).resolve()
    path.parent.mkdir(parents=True, exist_ok=True)
    bpy.ops.wm.save_as_mainfile(filepath=str(path), check_existing=False, compress=True)
    return path


# -- preview render ------------------------------------------------------------------------------
def render_preview(path, ob, *, resolution=(640, 480), samples: int = 16) -> Path:
    """A Cycles CPU picture of ``ob`` (semi-transparent) with its silhouette and skeleton.

    The skeleton (armatures do not render) is drawn by a temporary copy of the silhouette's
    edges as thin tubes with a ball at every joint. Camera, light and materials are added to the
    scene; the temporary objects are removed afterwards.
    """
    path = Path(path).resolve()
    path.parent.mkdir(parents=True, exist_ok=True)
    scene = bpy.context.scene
    found = results.find_result(ob.name)
    sil = found["silhouette"]
    made = []
    coll = bpy.data.collections.new(PREVIEW_COLLECTION)
    scene.collection.children.link(coll)
    try:
        _assign(ob, _material("CurveSkel Preview Mesh", (0.78, 0.84, 0.92), alpha=0.2,
                              roughness=0.35))
        size = max(ob.dimensions) or 1.0
        hidden_render = None
        if sil is not None:
            hidden_render = sil.hide_render
            sil.hide_render = False
            _assign(sil, _material("CurveSkel Preview Silhouette", (1.0, 0.42, 0.08), alpha=0.38,
                                   roughness=0.5))
            made += _skeleton_lines(sil, coll, size)
        cam = _camera(coll, ob)
        made.append(cam)
        made += _lights(coll)
        _setup_render(scene, path, resolution, samples)
        bpy.ops.render.render(write_still=True)
    finally:
        if sil is not None and hidden_render is not None:
            sil.hide_render = hidden_render
        results.remove_objects(made)
        bpy.data.collections.remove(coll)
    return path


def _activate(ob) -> None:
    vl = bpy.context.view_layer
    if vl.objects.active is not None and vl.objects.active.mode != 'OBJECT':
        bpy.ops.object.mode_set(mode='OBJECT')
    for other in vl.objects:
        other.select_set(False)
    ob.select_set(True)
    vl.objects.active = ob


def _material(name, color, *, alpha=1.0, roughness=0.5, emission=0.0):
    mat = bpy.data.materials.new(name)
    if hasattr(mat, "use_nodes") and not mat.use_nodes:   # always on (and deprecated) in 5.0
        mat.use_nodes = True
    bsdf = next(n for n in mat.node_tree.nodes if n.type == 'BSDF_PRINCIPLED')
    bsdf.inputs["Base Color"].default_value = (*color, 1.0)
    bsdf.inputs["Alpha"].default_value = alpha
    bsdf.inputs["Roughness"].default_value = roughness
    if emission:
        bsdf.inputs["Emission Color"].default_value = (*color, 1.0)
        bsdf.inputs["Emission Strength"].default_value = emission
    mat.diffuse_color = (*color, alpha)
    return mat


def _assign(ob, mat) -> None:
    ob.data.materials.clear()
    ob.data.materials.append(mat)


def _skeleton_lines(sil, coll, size) -> list:
    """Bones as thin tubes (Skin of constant radius) and joints as balls (vertex instancing)."""
    me = bpy.data.meshes.new("CurveSkel Preview Bones")
    n = len(sil.data.vertices)
    co = np.empty(n * 3, np.float32)
    sil.data.vertices.foreach_get("co", co)
    ed = np.empty(len(sil.data.edges) * 2, np.int32)
    sil.data.edges.foreach_get("vertices", ed)
    me.vertices.add(n)
    me.vertices.foreach_set("co", co)
    me.edges.add(len(ed) // 2)
    me.edges.foreach_set("vertices", ed)
    me.update()
    bones = bpy.data.objects.new("CurveSkel Preview Bones", me)
    coll.objects.link(bones)
    bones.matrix_world = sil.matrix_world
    bones.modifiers.new("Skin", 'SKIN').use_smooth_shade = True
    scale = max(sil.matrix_world.to_scale()) or 1.0
    me.skin_vertices[0].data.foreach_set("radius", np.full(2 * n, 0.006 * size / scale, np.float32))
    _assign(bones, _material("CurveSkel Preview Bones", (0.02, 0.08, 0.45), roughness=0.3, emission=0.6))
    bpy.ops.mesh.primitive_uv_sphere_add(segments=16, ring_count=8, radius=0.016 * size / scale)
    ball = bpy.context.active_object
    for c in list(ball.users_collection):
        c.objects.unlink(ball)
    coll.objects.link(ball)
    ball.name = "CurveSkel Preview Joint"
    ball.data.polygons.foreach_set("use_smooth", np.ones(len(ball.data.polygons), bool))
    _assign(ball, _material("CurveSkel Preview Joints", (0.85, 0.05, 0.1), roughness=0.3))
    ball.parent = bones
    ball.matrix_parent_inverse.identity()
    ball.location = (0.0, 0.0, 0.0)
    bones.instance_type = 'VERTS'
    bones.show_instancer_for_render = True
    return [ball, bones]


def _camera(coll, ob):
    from math import radians

    cam = bpy.data.objects.new("CurveSkel Preview Camera", bpy.data.cameras.new("CurveSkel Preview Camera"))
    coll.objects.link(cam)
    cam.rotation_euler = (radians(72.0), 0.0, radians(32.0))   # front-right, slightly from above
    cam.data.lens = 50.0
    bpy.context.view_layer.update()
    co = np.empty(len(ob.data.vertices) * 3, np.float32)
    ob.data.vertices.foreach_get("co", co)
    M = np.array(ob.matrix_world)
    world = co.reshape(-1, 3) @ M[:3, :3].T + M[:3, 3]
    loc, _scale = cam.camera_fit_coords(bpy.context.evaluated_depsgraph_get(), world.ravel().tolist())
    cam.location = loc
    cam.data.lens = 50.0 * 0.9             # a margin around the framed object
    bpy.context.scene.camera = cam
    return cam


def _lights(coll) -> list:
    from math import radians

    out = []
    for name, energy, rot in (("Key", 3.0, (50.0, 10.0, 30.0)), ("Fill", 1.0, (60.0, -20.0, -120.0))):
        light = bpy.data.lights.new(f"CurveSkel Preview {name}", 'SUN')
        light.energy = energy
        light.angle = radians(10.0)
        ob = bpy.data.objects.new(light.name, light)
        ob.rotation_euler = tuple(radians(a) for a in rot)
        coll.objects.link(ob)
        out.append(ob)
    world = bpy.context.scene.world or bpy.data.worlds.new("CurveSkel Preview World")
    bpy.context.scene.world = world
    if hasattr(world, "use_nodes") and not world.use_nodes:
        world.use_nodes = True
    bg = next(n for n in world.node_tree.nodes if n.type == 'BACKGROUND')
    bg.inputs["Color"].default_value = (0.93, 0.94, 0.96, 1.0)
    bg.inputs["Strength"].default_value = 0.9
    return out


def _setup_render(scene, path, resolution, samples) -> None:
    scene.render.engine = 'CYCLES'
    scene.cycles.device = 'CPU'
    scene.cycles.samples = samples
    scene.cycles.use_adaptive_sampling = True
    scene.cycles.max_bounces = 3
    scene.cycles.diffuse_bounces = 1
    scene.cycles.glossy_bounces = 1
    scene.cycles.transmission_bounces = 0
    scene.cycles.transparent_max_bounces = 16
    # OpenImageDenoise takes longer than the render itself on a small CPU: off.
    scene.cycles.use_denoising = False
    scene.render.resolution_x, scene.render.resolution_y = resolution
    scene.render.resolution_percentage = 100
    scene.render.film_transparent = False
    scene.view_settings.view_transform = 'Standard'
    scene.render.image_settings.file_format = 'PNG'
    scene.render.filepath = str(path)


def cli_outputs(mesh_path, params: dict, *, blend=None, render=None, bind: bool = False) -> dict:
    """What ``skeletonize.py --blend/--render`` does: a fresh scene, the mesh through Blender's
    importer, the ``curveskel.generate`` operator with ``params`` (SkeletonParams fields), then
    the .blend and/or the preview picture. Returns the objects and timings."""
    import time

    reset_scene()
    ensure_registered()
    ob = import_mesh(mesh_path)
    t0 = time.perf_counter()
    found = generate(ob, **params, bind=bind)
    out = {"object": ob, **found, "operator_seconds": time.perf_counter() - t0}
    if blend is not None:
        out["blend"] = save_blend(blend)
    if render is not None:
        t0 = time.perf_counter()
        out["render"] = render_preview(render, ob)
        out["render_seconds"] = time.perf_counter() - t0
    return out
