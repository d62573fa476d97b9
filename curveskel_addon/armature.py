"""Armature object from a Skeleton, laid out by ``core.rig_layout`` (bones, parents, names, rolls).

The armature carries what is needed to bind a mesh to it later without the Skeleton:

``curveskel_joints``      flat (J*4) x, y, z, r of the skeleton joints (the source mesh's local space)
``curveskel_bones``       flat (B*2) joint pairs
``curveskel_bone_names``  Blender bone of each skeleton bone (a zero-length skeleton bone, merged
                          into a joint, names the bone that carries its vertices)
``curveskel_roots``       root joint of each part
``curveskel_up``          direction of the root bones, in the armature's space
``curveskel_source``      name of the source mesh
"""

from __future__ import annotations

import bpy
import numpy as np
from mathutils import Matrix, Vector

from .core.errors import CurveSkelError
from .core.rig_layout import RigLayout, rig_layout

__all__ = ["build_armature", "layout_of", "is_curveskel_armature", "local_up"]

JOINTS_KEY = "curveskel_joints"
BONES_KEY = "curveskel_bones"
NAMES_KEY = "curveskel_bone_names"
ROOTS_KEY = "curveskel_roots"
UP_KEY = "curveskel_up"
SOURCE_KEY = "curveskel_source"


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


def build_armature(context, skeleton, name: str, collection, matrix_world, *, root=None) -> bpy.types.Object:
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
        for r in range(lay.n_bones):
            eb = ebs.new(lay.names[r])
            eb.head = lay.heads[r]
            eb.tail = lay.tails[r]
            eb.use_deform = True
            made.append(eb)
        for r, eb in enumerate(made):
            p = lay.parent[r]
            if p >= 0:
                eb.parent = made[p]
                eb.use_connect = bool(lay.connect[r])
            eb.align_roll(lay.z_axis[r])
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
    if len(arm.bones) != lay.n_bones:
        raise CurveSkelError(f"Blender kept {len(arm.bones)} of {lay.n_bones} bones")

    ob[JOINTS_KEY] = [float(x) for x in skeleton.joints.ravel()]
    ob[BONES_KEY] = [int(x) for x in skeleton.bones.ravel()]
    ob[NAMES_KEY] = [names[r] for r in lay.bone_rig]
    ob[ROOTS_KEY] = [int(x) for x in lay.roots]
    ob[UP_KEY] = [float(x) for x in up]
    src = skeleton.meta.get("source") if isinstance(skeleton.meta, dict) else None
    ob[SOURCE_KEY] = str(src) if src else name.removesuffix(".skeleton")
    return ob
