"""Blender-side helpers for the command line (``scripts/skeletonize.py --blend/--render``).

Import a mesh file with Blender's own importers, run the SAME operator the UI runs
(``curveskel.generate``), save a .blend, render a Cycles CPU preview (framed and judged by
``framing``). No maths here.
"""

from __future__ import annotations

import os
import time
from math import radians
from pathlib import Path

import bpy
import numpy as np

from . import framing, registration, results
from .core import CurveSkelError
from .mesh_files import read_mesh   # .off only: trimesh is imported there when a file needs it

__all__ = ["reset_scene", "ensure_registered", "mesh_object_from_arrays", "import_mesh",
           "generate", "save_blend", "render_preview", "cli_outputs"]

PREVIEW_COLLECTION = "CurveSkel Preview"
_VISIBILITY = ("visible_shadow", "visible_diffuse", "visible_glossy", "visible_transmission")


def reset_scene() -> None:
    """An empty scene (no default cube, camera or light)."""
    bpy.ops.wm.read_homefile(use_empty=True)


def ensure_registered() -> None:
    """Register the add-on's classes unless they already are (e.g. the extension is enabled)."""
    if not hasattr(bpy.types, "CURVESKEL_OT_generate"):
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
    """Import a .obj / .ply / .stl (Blender's importers) or .off (read by :mod:`.mesh_files`) file.

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
def render_preview(path, ob, *, resolution=(640, 480), samples: int = 8) -> Path:
    """A Cycles CPU picture of ``ob`` (semi-transparent) with its silhouette and skeleton.

    Armatures do not render: temporary copies of the silhouette's joints and bones draw the
    silhouette (balls of the joint radii joined by cones) and the skeleton (thin tubes, a red
    ball per joint), ``ob`` is drawn see-through, a camera frames it all at any size (its place
    and clip distances from the mesh's vertices and the silhouette's balls:
    ``framing.fit_camera``), two suns and a light world light it. Afterwards the temporary
    objects and materials are removed and ``ob`` is as it was (the scene keeps the Cycles
    settings and the world).

    The picture is rendered into a temporary file beside ``path`` and moved there only when it
    is not blank (``framing.picture_coverage``); a picture that cannot be read back (a full
    disk) is moved as it is, for the caller's check of the file.

    Raises
    ------
    CurveSkelError
        A blank picture (nothing written), or nothing to frame.
    """
    path = Path(path).resolve()
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.stem}.render-{os.getpid()}{path.suffix}")
    scene = bpy.context.scene
    found = results.find_result(ob.name)
    sil = found["silhouette"]
    made = []
    coll = bpy.data.collections.new(PREVIEW_COLLECTION)
    scene.collection.children.link(coll)
    materials_before = set(bpy.data.materials)
    ob_materials = list(ob.data.materials)
    ob_visibility = {k: getattr(ob, k) for k in _VISIBILITY}
    try:
        _assign(ob, _xray_material("CurveSkel Preview Mesh", (0.32, 0.42, 0.58), edge=0.9))
        size = max(ob.dimensions) or 1.0
        hidden_render = None
        if sil is not None:
            # The Skin modifier's hull breaks into flat shards where bones are short next to the
            # radii; the picture draws the same balls and cones with geometry nodes instead.
            hidden_render = sil.hide_render
            sil.hide_render = True
            scale = max(sil.matrix_world.to_scale()) or 1.0
            r = _skin_radii(sil)
            orange = _xray_material("CurveSkel Preview Silhouette", (1.0, 0.45, 0.1), edge=0.75)
            made.append(_sweep_object("CurveSkel Preview Silhouette", sil, coll, r, r, orange, orange,
                                      union=True))
            made.append(_sweep_object(
                "CurveSkel Preview Skeleton", sil, coll, 0.005 * size / scale, 0.013 * size / scale,
                _material("CurveSkel Preview Bones", (0.02, 0.08, 0.45), roughness=0.3, emission=0.5),
                _material("CurveSkel Preview Joints", (0.85, 0.05, 0.1), roughness=0.3, emission=0.3)))
        for o in (ob, made[0] if made else None):
            if o is not None:      # transparent layers: seen by the camera only (much faster)
                for k in _VISIBILITY:
                    setattr(o, k, False)
        _setup_render(scene, tmp, resolution, samples)      # before framing: the aspect ratio
        cam, fit = _camera(coll, ob, sil)
        made.append(cam)
        made += _lights(coll)
        bpy.ops.render.render(write_still=True)
        cover = _coverage(tmp)
        if cover is not None and cover["fraction"] < framing.BLANK_FRACTION:
            hint = ""
            if fit.clip_start < cam.data.clip_start:
                hint = (f" (Blender's camera clips no nearer than {cam.data.clip_start:.3g}: scale the "
                        "mesh up for its preview)")
            raise CurveSkelError(
                f"the preview render of '{ob.name}' is blank ({cover['fraction']:.2%} of the pixels "
                f"differ from the background), so no picture was written; the mesh is "
                f"{max(ob.dimensions):.3g} units across, the camera {fit.distance:.3g} away, "
                f"clipping at {fit.clip_start:.3g} .. {fit.clip_end:.3g}{hint}")
        os.replace(tmp, path)
    finally:
        for leftover in (tmp, Path(str(tmp) + "@")):      # Blender writes "<name>@", then renames
            if leftover.exists():
                leftover.unlink()
        if sil is not None and hidden_render is not None:
            sil.hide_render = hidden_render
        for o in made:
            if o.type == 'MESH' and o.modifiers and o.modifiers[0].type == 'NODES':
                bpy.data.node_groups.remove(o.modifiers[0].node_group)
        results.remove_objects(made)
        bpy.data.collections.remove(coll)
        # the source object as it was: its materials and ray visibility
        ob.data.materials.clear()
        for mat in ob_materials:
            ob.data.materials.append(mat)
        for k, v in ob_visibility.items():
            setattr(ob, k, v)
        for mat in set(bpy.data.materials) - materials_before:
            bpy.data.materials.remove(mat)
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
    if bpy.app.version < (5, 0, 0) and not mat.use_nodes:   # always on (and deprecated) since 5.0
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


def _xray_material(name, color, *, edge: float = 1.0, blend: float = 0.35):
    """See-through, self-lit surface: transparent where it faces the camera, ``color`` towards its
    outline (Layer Weight "Facing"). No light sampling, so a few samples render it without noise."""
    mat = bpy.data.materials.new(name)
    if bpy.app.version < (5, 0, 0) and not mat.use_nodes:
        mat.use_nodes = True
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    for n in list(nodes):
        if n.type != 'OUTPUT_MATERIAL':
            nodes.remove(n)
    out = next(n for n in nodes if n.type == 'OUTPUT_MATERIAL')
    weight = nodes.new('ShaderNodeLayerWeight')
    weight.inputs["Blend"].default_value = blend
    scale = nodes.new('ShaderNodeMath')
    scale.operation = 'MULTIPLY'
    scale.inputs[1].default_value = edge
    links.new(weight.outputs["Facing"], scale.inputs[0])
    clear = nodes.new('ShaderNodeBsdfTransparent')
    glow = nodes.new('ShaderNodeEmission')
    glow.inputs["Color"].default_value = (*color, 1.0)
    glow.inputs["Strength"].default_value = 1.0
    mix = nodes.new('ShaderNodeMixShader')
    links.new(scale.outputs[0], mix.inputs["Fac"])
    links.new(clear.outputs[0], mix.inputs[1])
    links.new(glow.outputs[0], mix.inputs[2])
    links.new(mix.outputs[0], out.inputs["Surface"])
    mat.diffuse_color = (*color, 0.5)
    return mat


def _assign(ob, mat) -> None:
    ob.data.materials.clear()
    ob.data.materials.append(mat)


def _sweep_tree(name, tube_material, ball_material, union=False):
    """Geometry nodes: every edge becomes a cone of radius attribute "radius" at its ends, every
    vertex a ball of radius "ball" (a sphere-swept skeleton, drawn without Python maths)."""
    tree = bpy.data.node_groups.new(name, 'GeometryNodeTree')
    tree.interface.new_socket("Geometry", in_out='INPUT', socket_type='NodeSocketGeometry')
    tree.interface.new_socket("Geometry", in_out='OUTPUT', socket_type='NodeSocketGeometry')
    N, L = tree.nodes, tree.links
    gin, gout = N.new('NodeGroupInput'), N.new('NodeGroupOutput')

    def attr(attr_name):
        node = N.new('GeometryNodeInputNamedAttribute')
        node.data_type = 'FLOAT'
        node.inputs["Name"].default_value = attr_name
        return node.outputs["Attribute"]

    to_curve = N.new('GeometryNodeMeshToCurve')
    L.new(gin.outputs[0], to_curve.inputs["Mesh"])
    circle = N.new('GeometryNodeCurvePrimitiveCircle')
    circle.inputs["Resolution"].default_value = 24
    circle.inputs["Radius"].default_value = 1.0
    sweep = N.new('GeometryNodeCurveToMesh')
    sweep.inputs["Fill Caps"].default_value = True
    L.new(circle.outputs["Curve"], sweep.inputs["Profile Curve"])
    if "Scale" in sweep.inputs:                      # Blender 4.4+: explicit profile scale
        L.new(to_curve.outputs["Curve"], sweep.inputs["Curve"])
        L.new(attr("radius"), sweep.inputs["Scale"])
    else:                                            # 4.2: the curve radius scales the profile
        set_r = N.new('GeometryNodeSetCurveRadius')
        L.new(to_curve.outputs["Curve"], set_r.inputs["Curve"])
        L.new(attr("radius"), set_r.inputs["Radius"])
        L.new(set_r.outputs["Curve"], sweep.inputs["Curve"])
    points = N.new('GeometryNodeMeshToPoints')
    L.new(gin.outputs[0], points.inputs["Mesh"])
    sphere = N.new('GeometryNodeMeshUVSphere')
    sphere.inputs["Segments"].default_value = 24
    sphere.inputs["Rings"].default_value = 12
    sphere.inputs["Radius"].default_value = 1.0
    inst = N.new('GeometryNodeInstanceOnPoints')
    L.new(points.outputs["Points"], inst.inputs["Points"])
    L.new(sphere.outputs["Mesh"], inst.inputs["Instance"])
    L.new(attr("ball"), inst.inputs["Scale"])
    real = N.new('GeometryNodeRealizeInstances')
    L.new(inst.outputs["Instances"], real.inputs["Geometry"])
    join = N.new('GeometryNodeJoinGeometry')
    if union:
        # One outer surface (a voxel remesh of balls and cones): two transparent layers per
        # pixel instead of one per overlapping piece - cleaner and several times faster.
        for sock in (real.outputs["Geometry"], sweep.outputs["Mesh"]):
            L.new(sock, join.inputs[0])
        to_vol = N.new('GeometryNodeMeshToVolume')
        if "Resolution Mode" in to_vol.inputs:          # 5.0: a menu socket; 4.2: a property
            to_vol.inputs["Resolution Mode"].default_value = 'Amount'
        else:
            to_vol.resolution_mode = 'VOXEL_AMOUNT'
        to_vol.inputs["Voxel Amount"].default_value = 128
        L.new(join.outputs[0], to_vol.inputs["Mesh"])
        to_mesh = N.new('GeometryNodeVolumeToMesh')
        L.new(to_vol.outputs[0], to_mesh.inputs["Volume"])
        set_mat = N.new('GeometryNodeSetMaterial')
        set_mat.inputs["Material"].default_value = tube_material
        L.new(to_mesh.outputs[0], set_mat.inputs[0])
        last = set_mat.outputs[0]
    else:
        for sock, mat in ((real.outputs["Geometry"], ball_material), (sweep.outputs["Mesh"], tube_material)):
            set_mat = N.new('GeometryNodeSetMaterial')
            set_mat.inputs["Material"].default_value = mat
            L.new(sock, set_mat.inputs[0])
            L.new(set_mat.outputs[0], join.inputs[0])
        last = join.outputs[0]
    smooth = N.new('GeometryNodeSetShadeSmooth')
    L.new(last, smooth.inputs[0])
    L.new(smooth.outputs[0], gout.inputs[0])
    return tree


def _sweep_object(name, sil, coll, radius, ball, tube_material, ball_material, union=False):
    """A render-only copy of the silhouette's joints and bones, drawn by ``_sweep_tree``."""
    src = sil.data
    n = len(src.vertices)
    co = np.empty(n * 3, np.float32)
    src.vertices.foreach_get("co", co)
    ed = np.empty(len(src.edges) * 2, np.int32)
    src.edges.foreach_get("vertices", ed)
    me = bpy.data.meshes.new(name)
    me.vertices.add(n)
    me.vertices.foreach_set("co", co)
    me.edges.add(len(ed) // 2)
    me.edges.foreach_set("vertices", ed)
    me.update()
    for attr_name, values in (("radius", radius), ("ball", ball)):
        me.attributes.new(attr_name, 'FLOAT', 'POINT').data.foreach_set(
            "value", np.broadcast_to(np.asarray(values, np.float32), (n,)).copy())
    ob = bpy.data.objects.new(name, me)
    coll.objects.link(ob)
    ob.matrix_world = sil.matrix_world
    mod = ob.modifiers.new("Sweep", 'NODES')
    mod.node_group = _sweep_tree(name, tube_material, ball_material, union)
    return ob


def _skin_radii(sil) -> np.ndarray:
    sv = sil.data.skin_vertices[0].data
    r = np.empty(len(sv) * 2, np.float32)
    sv.foreach_get("radius", r)
    return r[0::2]


def _world_vertices(ob) -> np.ndarray:
    co = np.empty(len(ob.data.vertices) * 3, np.float32)
    ob.data.vertices.foreach_get("co", co)
    M = np.array(ob.matrix_world)
    return co.reshape(-1, 3) @ M[:3, :3].T + M[:3, 3]


def _camera(coll, ob, sil=None):
    """A camera framing ``ob``'s vertices and the silhouette ``sil``'s balls (joints and radii),
    its clip distances set from them. Returns (camera object, framing.CameraFit)."""
    scene = bpy.context.scene
    cam = bpy.data.objects.new("CurveSkel Preview Camera", bpy.data.cameras.new("CurveSkel Preview Camera"))
    coll.objects.link(cam)
    points = _world_vertices(ob)
    radii = np.zeros(len(points))
    if sil is not None:
        points = np.concatenate([points, _world_vertices(sil)])
        radii = np.concatenate([radii, _skin_radii(sil) * max(abs(c) for c in sil.matrix_world.to_scale())])
    cam.rotation_euler = framing.view_angles(points)
    cam.data.lens = 50.0
    tan_x, tan_y = framing.half_fov(cam.data.lens, cam.data.sensor_width, scene.render.resolution_x,
                                    scene.render.resolution_y)
    fit = framing.fit_camera(points, np.array(cam.rotation_euler.to_matrix()), tan_x, tan_y, radii=radii)
    cam.location = fit.location.tolist()
    cam.data.clip_start = fit.clip_start
    cam.data.clip_end = fit.clip_end
    scene.camera = cam
    return cam, fit


def _coverage(path) -> dict | None:
    """``framing.picture_coverage`` of the picture file at ``path``; None when it cannot be read."""
    try:
        img = bpy.data.images.load(str(path), check_existing=False)
    except RuntimeError:
        return None
    try:
        w, h = img.size
        if not (w and h and img.has_data):
            return None
        px = np.empty(w * h * 4, np.float32)
        img.pixels.foreach_get(px)
        return framing.picture_coverage(px.reshape(h, w, 4))
    finally:
        bpy.data.images.remove(img)


def _lights(coll) -> list:
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
    if bpy.app.version < (5, 0, 0) and not world.use_nodes:   # as Material.use_nodes
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
    scene.cycles.max_bounces = 0             # direct light only: a preview, not a beauty shot
    scene.cycles.transparent_max_bounces = 16
    scene.cycles.min_transparent_bounces = 16    # no random path termination: no grain
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
    reset_scene()
    ensure_registered()
    ob = import_mesh(mesh_path)
    known = {p.identifier for p in bpy.ops.curveskel.generate.get_rna_type().properties}
    dropped = sorted(set(params) - known)
    if dropped:
        print(f"warning: the Blender operator has no parameter {', '.join(dropped)}: left at its default")
    t0 = time.perf_counter()
    found = generate(ob, **{k: v for k, v in params.items() if k in known}, bind=bind)
    out = {"object": ob, **found, "operator_seconds": time.perf_counter() - t0}
    if blend is not None:
        out["blend"] = save_blend(blend)
    if render is not None:
        t0 = time.perf_counter()
        out["render"] = render_preview(render, ob)
        out["render_seconds"] = time.perf_counter() - t0
    return out
