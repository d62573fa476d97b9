"""Armature object from a Skeleton, laid out by ``rig.rig_layout`` (bones, parents, rolls) and
named by ``rig.rig_layout.named_rig``: readable names, and when the source mesh is symmetric
(``mirror_plane``) ``.L``/``.R`` pairs with exactly mirrored joints.

Binding reads the bones themselves (the armature is the truth once it exists). The armature also
keeps the skeleton it was made from, for reference:

``curveskel_joints``      flat (J*4) x, y, z, r of the skeleton joints (the source mesh's local space)
``curveskel_bones``       flat (B*2) joint pairs
``curveskel_bone_names``  Blender bone of each skeleton bone (a zero-length skeleton bone, merged
                          into a joint, names the bone that carries its vertices)
``curveskel_roots``       root joint of each part
``curveskel_up``          direction of the root bones, in the armature's space
``curveskel_source``      name of the source mesh
``curveskel_mirror``      the mirror plane (nx, ny, nz, offset) in the armature's space, when found
"""

from __future__ import annotations

import bpy
import numpy as np
from mathutils import Matrix, Vector

from .core.errors import CurveSkelError
from .core.geometry.segments import closest_on_bones
from .mesh_read import evaluated_triangles
from .rig.rig_layout import RigLayout, mirror_plane, named_rig, rig_layout

__all__ = ["build_armature", "layout_of", "is_curveskel_armature", "local_up"]

JOINTS_KEY = "curveskel_joints"
BONES_KEY = "curveskel_bones"
NAMES_KEY = "curveskel_bone_names"
ROOTS_KEY = "curveskel_roots"
UP_KEY = "curveskel_up"
SOURCE_KEY = "curveskel_source"
MIRROR_KEY = "curveskel_mirror"


def local_up(matrix_world) -> np.ndarray:
    """World +Z seen in the local space of an object with ``matrix_world``, (3,) unit."""
    m = Matrix(matrix_world).to_3x3()
    try:
        v = m.inverted() @ Vector((0.0, 0.0, 1.0))
    except ValueError:          # singular (zero scale): keep local +Z
        v = Vector((0.0, 0.0, 1.0))
    v = np.array(v, dtype=np.float64)
    n = np.linalg.norm(v)
    return v / n if n > 0 else np.array([0.0, 0.0, 1.0])


def is_curveskel_armature(ob) -> bool:
    return ob is not None and ob.type == 'ARMATURE' and JOINTS_KEY in ob and BONES_KEY in ob


def layout_of(arm_obj) -> RigLayout:
    """The RigLayout an armature was built from, rebuilt from its custom properties."""
    if not is_curveskel_armature(arm_obj):
        raise CurveSkelError(f"'{getattr(arm_obj, 'name', arm_obj)}' is not a curveskel armature")
    joints = np.asarray(arm_obj[JOINTS_KEY], dtype=np.float64).reshape(-1, 4)
    bones = np.asarray(arm_obj[BONES_KEY], dtype=np.int64).reshape(-1, 2)
    roots = np.asarray(arm_obj.get(ROOTS_KEY, []), dtype=np.int64)
    up = np.asarray(arm_obj.get(UP_KEY, (0.0, 0.0, 1.0)), dtype=np.float64)
    return rig_layout(joints, bones, root=roots if len(roots) else None, up=up)


def _source_vertices(context, source):
    """Vertices of the evaluated ``source`` mesh in its local space, or None."""
    if source is None or source.type != 'MESH':
        return None
    try:
        V, _ = evaluated_triangles(source, context.evaluated_depsgraph_get())
    except Exception:          # a mesh Blender cannot evaluate: no mirror plane, nothing else lost
        return None
    return V


def build_armature(context, skeleton, name: str, collection, matrix_world, *, root=None,
                   source=None, vertices=None, mirror: bool = True) -> bpy.types.Object:
    """Armature object of ``skeleton``, linked to ``collection`` with ``matrix_world``.

    Parameters
    ----------
    context : bpy.types.Context
    skeleton : Skeleton
        Joints in the local space of the source mesh (the armature gets the same matrix_world).
    name : str
        Name of the object and its armature data.
    collection : bpy.types.Collection
        Must be in the view layer (edit mode needs a visible, linked object).
    matrix_world : (4, 4) matrix
    root : int or sequence of int, optional
        Root joint(s); default the most central joint of each part.
    source : bpy.types.Object, optional
        The source mesh: its vertices give the mirror plane.
    vertices : (n, 3) float, optional
        The source mesh's vertices in the skeleton's space (instead of ``source``).
    mirror : bool
        Look for a mirror plane (names ``.L``/``.R``, mirrored joints).

    Returns
    -------
    bpy.types.Object
        The armature object, in object mode; the previously active object is active again.

    Raises
    ------
    CurveSkelError
        If the skeleton has no bones or edit mode cannot be entered.
    """
    up = local_up(matrix_world)
    lay = rig_layout(skeleton.joints, skeleton.bones, root=root, up=up)
    rig = named_rig(lay, None, up=up)
    if mirror:
        V = vertices if vertices is not None else _source_vertices(context, source)
        planes = mirror_plane(np.asarray(V, dtype=np.float64), all_planes=True) if V is not None else []
        # of the planes that mirror the mesh, the one pairing most chains (ties: the first)
        for plane in planes:
            cand = named_rig(lay, plane, up=up)
            if cand.plane is not None and rig.plane is None or cand.meta["pairs"] > rig.meta["pairs"]:
                rig = cand
    plane = rig.plane

    arm = bpy.data.armatures.new(name)
    arm.display_type = 'OCTAHEDRAL'
    ob = bpy.data.objects.new(name, arm)
    collection.objects.link(ob)
    ob.matrix_world = Matrix(matrix_world)
    ob.show_in_front = True

    vl = context.view_layer
    prev_active = vl.objects.active
    if prev_active is not None and prev_active.mode != 'OBJECT':
        bpy.ops.object.mode_set(mode='OBJECT')
    if ob.name not in vl.objects:
        bpy.data.objects.remove(ob)
        bpy.data.armatures.remove(arm)
        raise CurveSkelError(f"collection '{collection.name}' is not in the view layer: cannot edit bones")
    vl.objects.active = ob
    try:
        bpy.ops.object.mode_set(mode='EDIT')
        if ob.mode != 'EDIT':
            raise CurveSkelError(f"could not enter edit mode on '{ob.name}'")
        ebs = arm.edit_bones
        made = []
        for r in range(rig.n_bones):
            eb = ebs.new(rig.names[r])
            eb.head = rig.heads[r]
            eb.tail = rig.tails[r]
            eb.use_deform = True
            made.append(eb)
        for r, eb in enumerate(made):
            p = rig.parent[r]
            if p >= 0:
                eb.parent = made[p]
                eb.use_connect = bool(rig.connect[r])
            eb.align_roll(rig.z_axis[r])
        names = [eb.name for eb in made]   # as Blender spelled them
    except BaseException:
        if ob.mode == 'EDIT':
            bpy.ops.object.mode_set(mode='OBJECT')
        bpy.data.objects.remove(ob)
        bpy.data.armatures.remove(arm)
        raise
    bpy.ops.object.mode_set(mode='OBJECT')
    if prev_active is not None and prev_active.name in vl.objects:
        vl.objects.active = prev_active
    if len(arm.bones) != rig.n_bones:
        raise CurveSkelError(f"Blender kept {len(arm.bones)} of {rig.n_bones} bones")

    ob[JOINTS_KEY] = [float(x) for x in skeleton.joints.ravel()]
    ob[BONES_KEY] = [int(x) for x in skeleton.bones.ravel()]
    # the bone nearest each skeleton bone's middle (for reference; binding reads the bones)
    X = skeleton.joints[:, :3]
    mid = 0.5 * (X[skeleton.bones[:, 0]] + X[skeleton.bones[:, 1]]) if skeleton.n_bones else np.zeros((0, 3))
    if len(mid):
        P = np.concatenate([rig.heads, rig.tails])
        segs = np.stack([np.arange(rig.n_bones), rig.n_bones + np.arange(rig.n_bones)], 1)
        near, _, _ = closest_on_bones(mid, P, segs)
        ob[NAMES_KEY] = [names[int(r)] for r in near]
    else:
        ob[NAMES_KEY] = []
    ob[ROOTS_KEY] = [int(x) for x in lay.roots]
    ob[UP_KEY] = [float(x) for x in up]
    if plane is not None:
        ob[MIRROR_KEY] = [float(x) for x in (*plane.normal, plane.offset)]
    src = skeleton.meta.get("source") if isinstance(skeleton.meta, dict) else None
    ob[SOURCE_KEY] = str(src) if src else name.removesuffix(".skeleton")
    return ob
