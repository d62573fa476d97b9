"""Bind a mesh to an armature as it is now: one vertex group per deforming bone + an Armature modifier.

The armature is the truth once it exists: weights are computed for its deforming bones as they
are at bind time (positions, names, parents; bones moved, deleted, renamed or added in Edit Mode
included), never from the skeleton it was generated from. Any armature can be bound to.

Binding is the one change curveskel makes to the user's mesh. What it adds is tracked on the mesh
object (``curveskel_groups``: the vertex groups it made, ``curveskel_modifier``: its modifier, the
pointer property ``curveskel_armature_object``: the armature, ``curveskel_parented``: that the bind
set the mesh's parent), so a re-bind replaces exactly those and leaves the user's other groups and
modifiers alone. Groups of bones that no longer exist are removed; groups Blender renamed with a
bone are taken over.

The mesh is parented to the armature as Blender's own *Parent > Armature Deform* (Ctrl+P) does:
parent type OBJECT, the parent inverse matrix set to the armature's inverse world matrix, so the
mesh keeps its world transform and its own location, rotation and scale (a mesh that had another
parent gets that parent's transform folded into its own, as *Keep Transform* does). It then moves
with the armature object, and the Armature modifier deforms it by the bones (relative to the
armature object, so the two never add up). Parent type ARMATURE is not used: Blender would apply
it as a second, hidden armature deform on top of the modifier. A mesh already parented to the
armature (type OBJECT) is left as it is, whatever its inverse matrix. glTF and FBX exporters want
this hierarchy (Blender's glTF exporter otherwise warns "Armature must be the parent of skinned
mesh" and guesses the armature by name). :func:`unbind_mesh` clears the parent the bind set,
keeping the world transform.

Weights ("SURFACE", the default) come from ``rig.skin_weights.bone_weights`` (closest bone
restricted to its connected patch of the surface, blended at joints, smoothed along the surface)
and are written through a bmesh deform layer (no per-vertex operator call); or from Blender's heat
weights ("HEAT", ``parent_set(type='ARMATURE_AUTO')``, slow on large meshes; its parenting is
replaced by the one above).
"""

from __future__ import annotations

import time

import bmesh
import bpy
import numpy as np
from mathutils import Matrix

from .armature import build_armature
from .core.errors import CurveSkelError
from .core.skeleton import Skeleton
from .rig.skin_weights import bone_weights

__all__ = ["bind_mesh", "unbind_mesh", "parent_to_armature", "write_weights", "armature_bones",
           "METHODS", "GROUPS_KEY", "MODIFIER_KEY", "MODIFIER_NAME", "PARENTED_KEY",
           "HEAT_SLOW_VERTICES", "POINTER"]

METHODS = ("SURFACE", "HEAT")
GROUPS_KEY = "curveskel_groups"
MODIFIER_KEY = "curveskel_modifier"
ARMATURE_KEY = "curveskel_armature"      # legacy string property (name); now a pointer property
POINTER = "curveskel_armature_object"    # Object.curveskel_armature_object (registration.py)
PARENTED_KEY = "curveskel_parented"     # the bind set the mesh's parent (unbind clears it)
MODIFIER_NAME = "CurveSkel Armature"
#: Above this many vertices heat weights take seconds to minutes (about 15 s at 50k).
HEAT_SLOW_VERTICES = 10_000


def _attribute(me, name, domain, data_type):
    a = me.attributes.get(name)
    return a if a is not None and a.domain == domain and a.data_type == data_type else None


def _read(me, attribute, domain, data_type, prop, collection, fallback, width, dtype):
    """(n, width) array of a mesh attribute: the plain attribute copy where the mesh has it
    ("position", ".edge_verts"), else ``collection.foreach_get(fallback)`` (RNA, item by item:
    ``edges.foreach_get("vertices")`` is ~300x slower)."""
    out = np.empty(len(collection) * width, dtype=dtype)
    a = _attribute(me, attribute, domain, data_type)
    if a is not None:
        a.data.foreach_get(prop, out)
    else:
        collection.foreach_get(fallback, out)
    return out.reshape(-1, width)


def _vertices(me) -> np.ndarray:
    return _read(me, "position", 'POINT', 'FLOAT_VECTOR', "vector", me.vertices, "co", 3,
                 np.float32).astype(np.float64)


def _edges(me) -> np.ndarray:
    # ".edge_verts": Blender 4.0+
    return _read(me, ".edge_verts", 'EDGE', 'INT32_2D', "value", me.edges, "vertices", 2,
                 np.int32).astype(np.int64)


def armature_bones(arm_obj) -> dict:
    """The bones of ``arm_obj`` as they are now (edit-mode changes included), armature space.

    Returns ``{"names": [...], "heads": (R, 3), "tails": (R, 3), "parent": (R,), "deform": (R,)}``.
    """
    if arm_obj.mode == 'EDIT':
        arm_obj.update_from_editmode()
    bones = arm_obj.data.bones
    R = len(bones)
    H = np.empty(R * 3, np.float32)
    T = np.empty(R * 3, np.float32)
    D = np.empty(R, bool)
    bones.foreach_get("head_local", H)
    bones.foreach_get("tail_local", T)
    bones.foreach_get("use_deform", D)
    # names in one call; the parent is a pointer (no foreach_get): one look-up per bone, by
    # the bone itself (bpy structs hash and compare by their data pointer: no name read)
    names = bones.keys()
    structs = bones.values()
    index = {b: k for k, b in enumerate(structs)}
    parent = np.array([index.get(b.parent, -1) for b in structs], np.int64)
    return {"names": names, "heads": H.reshape(-1, 3).astype(np.float64),
            "tails": T.reshape(-1, 3).astype(np.float64), "parent": parent, "deform": D}


def _bound_armature(mesh_obj):
    arm = getattr(mesh_obj, POINTER, None)
    if arm is not None:
        return arm
    mod = mesh_obj.modifiers.get(mesh_obj.get(MODIFIER_KEY) or MODIFIER_NAME)
    return mod.object if mod is not None and mod.type == 'ARMATURE' else None


def unbind_mesh(mesh_obj, keep=(), *, unparent: bool = True) -> int:
    """Remove the vertex groups and the modifier a previous bind made, and (``unparent``) clear
    the parent it set, keeping the mesh's world transform; return the modifier's index in the
    stack (0 when there was none). The user's own groups and modifiers are not touched, nor a
    parent the user set; groups named in ``keep`` are left for the caller to replace. A parent the
    mesh had before its first bind is not restored (as Blender's *Clear Parent and Keep
    Transform*)."""
    bound = _bound_armature(mesh_obj)
    if unparent and mesh_obj.get(PARENTED_KEY) and bound is not None and mesh_obj.parent == bound:
        mw = mesh_obj.matrix_world.copy()
        mesh_obj.parent = None
        mesh_obj.matrix_parent_inverse = Matrix.Identity(4)
        mesh_obj.matrix_world = mw
    index = 0
    mod_name = mesh_obj.get(MODIFIER_KEY)
    if mod_name:
        mod = mesh_obj.modifiers.get(mod_name)
        if mod is not None and mod.type == 'ARMATURE':
            index = list(mesh_obj.modifiers).index(mod)
            mesh_obj.modifiers.remove(mod)
    groups = mesh_obj.vertex_groups
    for g in set(mesh_obj.get(GROUPS_KEY, [])).difference(keep).intersection(groups.keys()):
        groups.remove(groups[g])
    for key in (GROUPS_KEY, MODIFIER_KEY, ARMATURE_KEY) + ((PARENTED_KEY,) if unparent else ()):
        if key in mesh_obj.keys():
            del mesh_obj[key]
    if hasattr(mesh_obj, POINTER):
        setattr(mesh_obj, POINTER, None)
    return index


def _influences(index) -> np.ndarray:
    """Influences (entries >= 0) per row of an (n, k) index array, column by column (a per-row
    sum over 4 columns costs more than the k additions)."""
    count = np.zeros(len(index), np.int64)
    for c in range(index.shape[1]):
        count += index[:, c] >= 0
    return count


def write_weights(mesh_obj, group_names, index, weight) -> None:
    """Write (n, k) weights into vertex groups ``group_names`` through a bmesh deform layer.

    Parameters
    ----------
    mesh_obj : bpy.types.Object
        A mesh object in object mode.
    group_names : list of str
        One per column value of ``index``; groups are created in this order (a group of that
        name already there is emptied and reused).
    index : (n, k) int
        Position in ``group_names`` of each influence, -1 for none.
    weight : (n, k) float
    """
    me = mesh_obj.data
    groups = mesh_obj.vertex_groups
    # remove first, then create: removing a group renumbers the groups after it. Names are
    # matched against ``keys()`` (one call): ``get`` per name searches the groups one by one
    # (0.3 ms for 106 groups)
    for g in set(groups.keys()).intersection(group_names):
        groups.remove(groups[g])
    new = groups.new
    for g in group_names:
        new(name=g)
    # the new groups are the last ones, in order: their indices follow, and a name Blender had
    # to change (taken, or too long) shows in keys()
    names = groups.keys()
    base = len(names) - len(group_names)
    for g, got in zip(group_names, names[base:]):
        if got != g:
            raise CurveSkelError(f"vertex group name '{g}' is taken")
    n = len(index)
    k = int(_influences(index).max()) if n else 0
    if k and int(index[:, :k].max()) >= len(group_names):
        raise CurveSkelError("write_weights: an influence refers to no group")
    gidx = np.where(index[:, :k] >= 0, index[:, :k] + base, -1)
    bm = bmesh.new()
    try:
        # no normals: only the deform layer is written back (the mesh recomputes its normals)
        bm.from_mesh(me, face_normals=False, vertex_normals=False)
        dl = bm.verts.layers.deform.verify()
        # the first two columns (a bind's: each vertex's bone, then its neighbour across a
        # joint, if any) in one loop step per vertex, no per-subset lists; further columns
        # (other callers) after, column by column
        g0, g1 = (gidx[:, c] if c < k else np.full(n, -1, np.int64) for c in (0, 1))
        w0, w1 = (weight[:, c] if c < k else np.zeros(n) for c in (0, 1))
        for v, a, x, b, y in zip(bm.verts, g0.tolist(), w0.tolist(), g1.tolist(), w1.tolist()):
            d = v[dl]
            if a >= 0:
                d[a] = x
            if b >= 0:
                d[b] = y
        if k > 2:
            verts = list(bm.verts)
            for c in range(2, k):
                rows = np.flatnonzero(gidx[:, c] >= 0)
                for r, g, w in zip(rows.tolist(), gidx[rows, c].tolist(), weight[rows, c].tolist()):
                    verts[r][dl][g] = w
        bm.to_mesh(me)
    finally:
        bm.free()
    me.update()


def bind_mesh(mesh_obj, arm_obj, skeleton=None, *, blend: float = 0.25, smooth: float = 0.5,
              junction_blend: float = 0.0, method: str = "SURFACE") -> dict:
    """Skin ``mesh_obj`` to the armature ``arm_obj`` as it is now, and parent it to the armature
    (keeping its world transform; see the module's notes).

    Parameters
    ----------
    mesh_obj : bpy.types.Object
        Mesh object in object mode.
    arm_obj : bpy.types.Object
        Any armature object (a curveskel result or not; edited or not).
    skeleton : Skeleton, optional
        Not used (kept for callers of the old signature): the weights always come from the
        armature's current bones, which are as fast to use as the skeleton's mapping.
    blend : float in [0, 0.5]
        Blend width at joints, as a fraction of bone length (SURFACE only).
    smooth : float >= 0
        Diffusion of the weights along the surface, as a fraction of the median vertex-to-bone
        distance (at most 12 steps); 0 keeps the blended weights (SURFACE only).
    junction_blend : float in [0, 0.5]
        Blend width where a chain leaves a junction, as a fraction of its first bone's length;
        0 keeps chain boundaries rigid (posing a limb moves no vertex of another limb).
    method : {"SURFACE", "HEAT"}
        Surface-respecting weights from the bones (default), or Blender's heat weights (slow on
        large meshes). "MAPPING" is accepted as the old name of "SURFACE".

    Returns
    -------
    dict
        ``method``, ``vertices``, ``groups``, ``bones``, ``mapping`` ("bones" or "heat"),
        ``relabelled``, ``max_influences``, ``unweighted`` (vertices with no weight), ``seconds``,
        ``weights_seconds``, ``warnings`` (list of str).

    Raises
    ------
    CurveSkelError
        Wrong object types, the mesh in edit mode, no deforming bone, a vertex group named like a
        bone that the user made before the first bind, an armature of zero scale or one that is a
        child of the mesh (these before anything changes), or heat weighting failing.
    """
    t0 = time.perf_counter()
    method = method.upper()
    if method == "MAPPING":
        method = "SURFACE"
    if method not in METHODS:
        raise CurveSkelError(f"unknown weight method {method!r}; choose one of {', '.join(METHODS)}")
    if mesh_obj is None or mesh_obj.type != 'MESH':
        raise CurveSkelError("bind: the object to bind must be a mesh")
    if arm_obj is None or arm_obj.type != 'ARMATURE':
        raise CurveSkelError(f"bind: '{getattr(arm_obj, 'name', arm_obj)}' is not an armature")
    if not smooth >= 0:
        raise CurveSkelError(f"bind: smooth must be >= 0, got {smooth}")
    if mesh_obj.mode != 'OBJECT':
        raise CurveSkelError(f"bind: '{mesh_obj.name}' must be in object mode")
    _check_parenting(mesh_obj, arm_obj)
    me = mesh_obj.data
    n = len(me.vertices)
    warnings: list[str] = []

    bones = armature_bones(arm_obj)
    deform_names = [nm for nm, d in zip(bones["names"], bones["deform"]) if d]
    if not deform_names:
        raise CurveSkelError(f"bind: armature '{arm_obj.name}' has no deforming bone")
    own = set(mesh_obj.get(GROUPS_KEY, []))
    rebind = _bound_armature(mesh_obj) is not None or bool(own)
    deform_set = set(deform_names)
    if not rebind:
        clash = [g for g in mesh_obj.vertex_groups.keys() if g in deform_set]
        if clash:
            raise CurveSkelError(f"bind: the mesh already has vertex group(s) named like bones "
                                 f"({', '.join(clash[:5])}); rename them first")
    # bound before: groups named like the current bones are ours (Blender renames a bone's
    # group with the bone), groups of bones that no longer exist go
    stack_index = unbind_mesh(mesh_obj, keep=deform_set, unparent=False)
    if rebind:
        groups = mesh_obj.vertex_groups
        for nm in deform_set.intersection(groups.keys()):
            groups.remove(groups[nm])

    fig = {"method": method, "vertices": n, "armature": arm_obj.name, "warnings": warnings,
           "bones": len(deform_names)}
    if method == "SURFACE":
        tw = time.perf_counter()
        # vertices into the armature's space
        M = np.array(arm_obj.matrix_world.inverted() @ mesh_obj.matrix_world)
        P = _vertices(me) @ M[:3, :3].T + M[:3, 3]
        index, weight, info = bone_weights(P, None, bones["heads"], bones["tails"], bones["parent"],
                                           bones["deform"], blend=blend, smooth=smooth,
                                           junction_blend=junction_blend, edges=_edges(me))
        fig.update(info)
        fig["mapping"] = "bones"
        # one group per deforming bone, named as the bone, in armature order
        # bone -> group (the deforming bones' rank), -1 (the last entry) for none
        remap = np.full(len(bones["names"]) + 1, -1, np.int64)
        deform_ids = np.flatnonzero(bones["deform"])
        remap[deform_ids] = np.arange(len(deform_ids))
        col = remap[index]
        fig["mapping_seconds"] = time.perf_counter() - tw
        tw = time.perf_counter()
        write_weights(mesh_obj, deform_names, col, weight)
        groups = deform_names
        fig["weights_seconds"] = time.perf_counter() - tw
        fig["max_influences"] = int(_influences(index).max()) if n else 0
        # rows sorted by decreasing weight: a vertex without weight has none in its first column
        fig["unweighted"] = int(np.count_nonzero(weight[:, 0] <= 0)) if n else 0
        fig["blend"] = float(blend)
        fig["smooth"] = float(smooth)
        fig["junction_blend"] = float(junction_blend)
        mod = mesh_obj.modifiers.new(MODIFIER_NAME, 'ARMATURE')
    else:
        groups, mod = _heat_weights(mesh_obj, arm_obj, deform_names, warnings)
        fig["mapping"] = "heat"
        fig["weights_seconds"] = time.perf_counter() - t0
        if n > HEAT_SLOW_VERTICES:
            warnings.append(f"heat weights are slow on large meshes ({n} vertices); "
                            "the surface method is much faster")
        fig["max_influences"], fig["unweighted"] = _influence_counts(mesh_obj, set(groups))
        if fig["unweighted"]:
            warnings.append("Blender's heat weighting found no solution for some bones (common on "
                            "very small, thin or self-intersecting meshes): use the surface method")

    mod.object = arm_obj
    mod.use_vertex_groups = True
    mod.use_bone_envelopes = False
    idx = list(mesh_obj.modifiers).index(mod)
    if idx != stack_index:
        mesh_obj.modifiers.move(idx, min(stack_index, len(mesh_obj.modifiers) - 1))
    mesh_obj[GROUPS_KEY] = list(groups)
    mesh_obj[MODIFIER_KEY] = mod.name
    if hasattr(mesh_obj, POINTER):
        setattr(mesh_obj, POINTER, arm_obj)
    if parent_to_armature(mesh_obj, arm_obj):
        mesh_obj[PARENTED_KEY] = True
    fig["groups"] = len(groups)
    if fig.get("unweighted"):
        warnings.append(f"{fig['unweighted']} vertices got no weight")
    fig["seconds"] = time.perf_counter() - t0
    return fig


def _check_parenting(mesh_obj, arm_obj) -> None:
    """CurveSkelError when ``mesh_obj`` cannot be parented to ``arm_obj`` (before anything changes)."""
    if abs(arm_obj.matrix_world.determinant()) < 1e-30:
        raise CurveSkelError(f"bind: armature '{arm_obj.name}' has a zero scale: give it a scale "
                             "before binding")
    p = arm_obj
    while p is not None:
        if p == mesh_obj:
            raise CurveSkelError(f"bind: armature '{arm_obj.name}' is a child of '{mesh_obj.name}': "
                                 "clear its parent first (the mesh is parented to the armature)")
        p = p.parent


def parent_to_armature(mesh_obj, arm_obj) -> bool:
    """Parent ``mesh_obj`` to ``arm_obj`` as *Parent > Armature Deform* does (type OBJECT, the
    inverse of the armature's world matrix), keeping the mesh's world transform; a mesh with
    another parent gets that parent's transform folded into its own. Returns whether anything
    changed (a mesh already parented to the armature with type OBJECT is left as it is)."""
    if mesh_obj.parent == arm_obj and mesh_obj.parent_type == 'OBJECT':
        return False
    _check_parenting(mesh_obj, arm_obj)
    had_parent = mesh_obj.parent is not None
    mw = mesh_obj.matrix_world.copy()
    mesh_obj.parent = arm_obj
    mesh_obj.parent_type = 'OBJECT'
    mesh_obj.parent_bone = ""
    mesh_obj.matrix_parent_inverse = arm_obj.matrix_world.inverted()
    if had_parent:
        # without a parent before, world == basis: left as the user set it (no round trip
        # through a decomposition)
        mesh_obj.matrix_world = mw
    return True


def _influence_counts(mesh_obj, groups) -> tuple[int, int]:
    """(most influences on one vertex, vertices without weight) among ``groups`` (slow path, HEAT)."""
    ids = {vg.index for vg in mesh_obj.vertex_groups if vg.name in groups}
    most, none = 0, 0
    for v in mesh_obj.data.vertices:
        k = sum(1 for g in v.groups if g.group in ids and g.weight > 0)
        most = max(most, k)
        none += k == 0
    return most, none


def _heat_weights(mesh_obj, arm_obj, deform, warnings):
    """Blender's automatic (heat) weights; the parenting it makes is undone (its world transform
    is not kept for a mesh with another parent: bind_mesh parents the mesh itself afterwards).
    Returns (group names, modifier)."""
    ctx = bpy.context
    vl = ctx.view_layer
    prev_sel = [o for o in vl.objects if o.select_get()]
    prev_active = vl.objects.active
    parent, parent_type, parent_bone = mesh_obj.parent, mesh_obj.parent_type, mesh_obj.parent_bone
    pinv, mw = mesh_obj.matrix_parent_inverse.copy(), mesh_obj.matrix_world.copy()
    before = {m.name for m in mesh_obj.modifiers}
    for o in prev_sel:
        o.select_set(False)
    mesh_obj.select_set(True)
    arm_obj.select_set(True)
    vl.objects.active = arm_obj
    try:
        bpy.ops.object.parent_set(type='ARMATURE_AUTO')
    except RuntimeError as exc:
        warnings.append(f"heat weights: {exc}".strip())
    finally:
        mesh_obj.parent = parent
        mesh_obj.parent_type = parent_type
        mesh_obj.parent_bone = parent_bone
        mesh_obj.matrix_parent_inverse = pinv
        mesh_obj.matrix_world = mw
        for o in vl.objects:
            o.select_set(o in prev_sel)
        vl.objects.active = prev_active
    new = [m for m in mesh_obj.modifiers if m.name not in before and m.type == 'ARMATURE']
    if not new:
        raise CurveSkelError("heat weights failed: Blender added no Armature modifier")
    mod = new[0]
    mod.name = MODIFIER_NAME
    groups = [g.name for g in mesh_obj.vertex_groups if g.name in set(deform)]
    return groups, mod


def benchmark_bind(vertices: int = 100_000, *, bones: int = 20, method: str = "SURFACE",
                   use_mapping: bool = True) -> dict:
    """Time :func:`bind_mesh` on a tube of about ``vertices`` vertices with a chain of ``bones``.

    Builds the mesh, its skeleton (a straight chain along the tube, mapping by the vertex's
    height) and armature in the current scene, binds and returns the figures of
    :func:`bind_mesh` plus ``build_seconds``. With ``use_mapping=False`` the mapping is recomputed
    by closest point on the bones (the re-bind path).
    """
    around = 64
    rings = max(vertices // around, 2)
    length, radius = 10.0, 0.5
    z = np.linspace(0.0, length, rings)
    a = 2 * np.pi * np.arange(around) / around
    V = np.stack([np.broadcast_to(radius * np.cos(a), (rings, around)),
                  np.broadcast_to(radius * np.sin(a), (rings, around)),
                  np.broadcast_to(z[:, None], (rings, around))], -1).reshape(-1, 3)
    r = np.arange(rings - 1)[:, None] * around
    k = np.arange(around)[None, :]
    k1 = (k + 1) % around
    q = np.stack([r + k, r + k1, r + around + k1, r + around + k], -1).reshape(-1, 4)
    t0 = time.perf_counter()
    me = bpy.data.meshes.new("curveskel_bench")
    me.vertices.add(len(V))
    me.vertices.foreach_set("co", V.ravel())
    me.loops.add(q.size)
    me.loops.foreach_set("vertex_index", q.ravel())
    me.polygons.add(len(q))
    me.polygons.foreach_set("loop_start", np.arange(0, q.size, 4))
    me.update(calc_edges=True)
    ob = bpy.data.objects.new("curveskel_bench", me)
    bpy.context.scene.collection.objects.link(ob)
    zj = np.linspace(0.0, length, bones + 1)
    joints = np.stack([0 * zj, 0 * zj, zj, np.full_like(zj, radius)], 1)
    chain = np.stack([np.arange(bones), np.arange(1, bones + 1)], 1)
    u = V[:, 2] / length * bones
    b = np.minimum(u.astype(np.int64), bones - 1)
    sk = Skeleton(joints, chain, b, 1.0 - (u - b))
    arm = build_armature(bpy.context, sk, "curveskel_bench.skeleton", bpy.context.scene.collection,
                         ob.matrix_world)
    build = time.perf_counter() - t0
    fig = bind_mesh(ob, arm, sk if use_mapping else None, method=method)
    fig["build_seconds"] = build
    return fig
