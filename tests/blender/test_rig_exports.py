"""Issue 31, "rig exports open clean": the bind parents the mesh to its armature (world transform
kept, the Armature modifier still the one deform). conftest.py registers the add-on and empties
the scene before every test.
"""

import bpy
import numpy as np
import pytest
from mathutils import Matrix

from curveskel_addon.armature import build_armature
from curveskel_addon.binding import GROUPS_KEY, MODIFIER_NAME, PARENTED_KEY, bind_mesh, unbind_mesh
from curveskel_addon.core import CurveSkelError, Skeleton
from test_rigging import evaluated, mesh_object, rotate, skeleton_of, weight_matrix

#: the mesh's transform and another one for the armature (rotation, translation, uniform scale)
MESH_M = Matrix.Translation((0.5, -0.2, 1.0)) @ Matrix.Rotation(0.3, 4, 'Z') @ Matrix.Scale(1.5, 4)
ARM_N = Matrix.Translation((-1.0, 2.0, 0.25)) @ Matrix.Rotation(0.7, 4, 'Y')


def star_rig(mesh_matrix=Matrix(), arm_matrix=None):
    """The star mesh at ``mesh_matrix`` and its armature at ``arm_matrix`` (default: the mesh's),
    bones laid where the mesh is in the world; not bound."""
    V, F, sk = skeleton_of("star")
    ob = mesh_object("star", V, F)
    ob.matrix_world = mesh_matrix
    if arm_matrix is None:
        arm_matrix = mesh_matrix
    # the skeleton in the armature's space: x_arm = N^-1 M x (rigid and uniformly scaled)
    A = np.array(arm_matrix.inverted() @ mesh_matrix)
    scale = float(np.cbrt(np.linalg.det(A[:3, :3])))
    J = sk.joints.copy()
    J[:, :3] = J[:, :3] @ A[:3, :3].T + A[:3, 3]
    J[:, 3] *= scale
    arm = build_armature(bpy.context, Skeleton(J, sk.bones, [], []), "star.skeleton",
                         bpy.context.scene.collection, arm_matrix, mirror=False)
    bpy.context.view_layer.update()
    return V, ob, arm


def arm_bone(arm, mesh_m, arm_n, direction):
    """The first bone of the star's arm along ``direction`` (mesh space): the highest ancestor of
    the arm's leaf whose tail is more than 1 (a quarter of the arm) out from the centre."""
    A = np.array(arm_n.inverted() @ mesh_m)
    scale = float(np.cbrt(np.linalg.det(A[:3, :3])))
    u = A[:3, :3] @ np.asarray(direction, float)
    u /= np.linalg.norm(u)
    centre = A[:3, 3]

    def out(b):
        return float(np.dot(np.array(b.tail_local) - centre, u)) / scale
    leaves = [b for b in arm.data.bones if not b.children and b.parent is not None]
    top = max(leaves, key=out)
    while top.parent is not None and top.parent.parent is not None and out(top.parent) > 1.0:
        top = top.parent
    return top


def world_vertices(ob):
    """Evaluated (deformed) vertices in world space."""
    P = evaluated(ob)
    M = np.array(ob.matrix_world)
    return P @ M[:3, :3].T + M[:3, 3]


def same_matrix(a, b, tol=1e-5):
    return np.abs(np.array(a) - np.array(b)).max() <= tol


# -- bind parents the mesh -----------------------------------------------------------------------
@pytest.mark.parametrize("mesh_m, arm_n", [(Matrix(), None), (MESH_M, None), (MESH_M, ARM_N)],
                         ids=["identity", "mesh-moved", "mesh-and-armature-moved"])
def test_bind_parents_the_mesh_keeping_its_world_transform(mesh_m, arm_n):
    V, ob, arm = star_rig(mesh_m, arm_n)
    basis = ob.matrix_basis.copy()
    world = world_vertices(ob)
    bind_mesh(ob, arm)
    bpy.context.view_layer.update()
    assert ob.parent is arm and ob.parent_type == 'OBJECT' and ob.parent_bone == ""
    assert same_matrix(ob.matrix_world, mesh_m)
    assert same_matrix(ob.matrix_basis, basis, 0)              # its own loc/rot/scale untouched
    assert same_matrix(ob.matrix_parent_inverse, arm.matrix_world.inverted())
    assert ob[PARENTED_KEY]
    assert np.abs(world_vertices(ob) - world).max() < 1e-5     # the rest pose is the input
    # moving the armature object carries the mesh once (the parent), not twice (the modifier too)
    shift = np.array([0.3, -0.4, 0.5])
    arm.location = (np.array(arm.location) + shift).tolist()
    bpy.context.view_layer.update()
    assert np.abs(world_vertices(ob) - (world + shift)).max() < 1e-5


@pytest.mark.parametrize("mesh_m, arm_n", [(Matrix(), None), (MESH_M, ARM_N)],
                         ids=["identity", "mesh-and-armature-moved"])
def test_posed_bone_deforms_the_parented_mesh(mesh_m, arm_n):
    """Posing a bone turns the vertices it alone carries rigidly about its head, in the world,
    and leaves the other arms where they were."""
    V, ob, arm = star_rig(mesh_m, arm_n)
    bind_mesh(ob, arm)
    rest = world_vertices(ob)
    top = arm_bone(arm, mesh_m, arm_n or mesh_m, [1.0, 0.0, 0.0])
    names = list(ob[GROUPS_KEY])
    carried = [b.name for b in [top, *top.children_recursive] if b.name in names]
    full = weight_matrix(ob, carried).sum(axis=1) > 1 - 1e-6
    untouched = weight_matrix(ob, carried).sum(axis=1) == 0
    assert full.sum() > 20 and untouched.sum() > len(V) / 2
    rotate(arm, top.name, 60.0)
    bpy.context.view_layer.update()
    moved = world_vertices(ob)
    pb = arm.pose.bones[top.name]
    W = np.array(arm.matrix_world @ pb.matrix @ top.matrix_local.inverted() @ arm.matrix_world.inverted())
    want = rest @ W[:3, :3].T + W[:3, 3]
    assert np.abs(moved[full] - want[full]).max() < 1e-4
    assert np.linalg.norm(moved[full] - rest[full], axis=1).max() > 0.5   # it did move
    assert np.abs(moved[untouched] - rest[untouched]).max() < 1e-5


def test_rebind_and_operator_do_not_stack_parents_or_modifiers():
    V, ob, arm = star_rig(MESH_M, ARM_N)
    bind_mesh(ob, arm)
    pinv = ob.matrix_parent_inverse.copy()
    arm.location.x += 1.0                 # the rig moved since: a re-bind keeps the mesh in place
    bpy.context.view_layer.update()
    world = ob.matrix_world.copy()
    bind_mesh(ob, arm, blend=0.1)
    vl = bpy.context.view_layer
    for o in vl.objects:
        o.select_set(False)
    vl.objects.active = ob
    assert bpy.ops.curveskel.bind(armature=arm.name) == {'FINISHED'}
    bpy.context.view_layer.update()
    assert ob.parent is arm and ob.parent_type == 'OBJECT'
    assert same_matrix(ob.matrix_parent_inverse, pinv, 0)      # left as the first bind set it
    assert same_matrix(ob.matrix_world, world)
    assert [m.name for m in ob.modifiers] == [MODIFIER_NAME]
    assert list(arm.children) == [ob]


def test_bind_to_another_armature_moves_the_parent_and_the_modifier():
    V, ob, arm = star_rig(MESH_M)
    other = build_armature(bpy.context, skeleton_of("star")[2], "other", bpy.context.scene.collection,
                           MESH_M, mirror=False)
    other.matrix_world = ARM_N @ MESH_M
    bind_mesh(ob, arm)
    bind_mesh(ob, other)
    bpy.context.view_layer.update()
    assert ob.parent is other and list(arm.children) == []
    assert same_matrix(ob.matrix_world, MESH_M)
    assert [m.name for m in ob.modifiers] == [MODIFIER_NAME] and ob.modifiers[0].object is other


def test_mesh_with_another_parent_keeps_its_place():
    """A mesh under a user's empty: the bind re-parents it to the armature (as Blender's Ctrl+P),
    its world transform kept, the empty's part folded into its own transform."""
    V, ob, arm = star_rig(MESH_M)
    empty = bpy.data.objects.new("character", None)
    bpy.context.scene.collection.objects.link(empty)
    empty.matrix_world = Matrix.Translation((0.0, 0.0, 2.0)) @ Matrix.Rotation(0.4, 4, 'X')
    ob.parent = empty
    ob.matrix_parent_inverse = empty.matrix_world.inverted()
    bpy.context.view_layer.update()
    world = world_vertices(ob)
    bind_mesh(ob, arm)
    bpy.context.view_layer.update()
    assert ob.parent is arm and same_matrix(ob.matrix_world, MESH_M)
    assert np.abs(world_vertices(ob) - world).max() < 1e-5


def test_a_mesh_the_user_parented_to_the_armature_is_left_as_it_is():
    V, ob, arm = star_rig(MESH_M)
    ob.parent = arm                       # Ctrl+P > Object without inverse: the mesh moves there
    ob.matrix_parent_inverse = Matrix()
    bpy.context.view_layer.update()
    world = ob.matrix_world.copy()
    bind_mesh(ob, arm)
    assert ob.parent is arm and same_matrix(ob.matrix_parent_inverse, Matrix(), 0)
    assert same_matrix(ob.matrix_world, world) and PARENTED_KEY not in ob.keys()
    unbind_mesh(ob)                       # the user's parent stays
    assert ob.parent is arm and ob.modifiers.get(MODIFIER_NAME) is None


def test_unbind_clears_the_parent_the_bind_set():
    V, ob, arm = star_rig(MESH_M, ARM_N)
    bind_mesh(ob, arm)
    arm.location.z += 1.0
    bpy.context.view_layer.update()
    world = ob.matrix_world.copy()
    unbind_mesh(ob)
    bpy.context.view_layer.update()
    assert ob.parent is None and same_matrix(ob.matrix_world, world)
    assert not ob.modifiers and not ob.vertex_groups and PARENTED_KEY not in ob.keys()
    assert np.abs(evaluated(ob) - V).max() < 1e-5


def test_bind_with_bone_parent_type_becomes_object_parenting():
    """A mesh parented to one bone of the armature would follow that bone and be deformed on top:
    the bind makes it an OBJECT child, world transform kept."""
    V, ob, arm = star_rig(MESH_M)
    ob.parent = arm
    ob.parent_type = 'BONE'
    ob.parent_bone = arm.data.bones[0].name
    bpy.context.view_layer.update()
    world = ob.matrix_world.copy()
    bind_mesh(ob, arm)
    bpy.context.view_layer.update()
    assert ob.parent_type == 'OBJECT' and ob.parent_bone == "" and same_matrix(ob.matrix_world, world)


@pytest.mark.parametrize("case", ["zero-scale", "armature-child-of-mesh"])
def test_bind_refuses_what_cannot_be_parented_and_changes_nothing(case, mesh_digest):
    V, ob, arm = star_rig(MESH_M)
    if case == "zero-scale":
        arm.scale = (0.0, 0.0, 0.0)
        want = "zero scale"
    else:
        arm.parent = ob
        want = "child of"
    bpy.context.view_layer.update()
    before = mesh_digest(ob)
    with pytest.raises(CurveSkelError, match=want):
        bind_mesh(ob, arm)
    after = mesh_digest(ob)
    assert after["sha256"] == before["sha256"] and after["modifiers"] == before["modifiers"] == []
    assert after["vertex_groups"] == [] and ob.parent is None
    vl = bpy.context.view_layer
    for o in vl.objects:
        o.select_set(False)
    vl.objects.active = ob
    with pytest.raises(RuntimeError, match=want):          # the operator: one ERROR report
        bpy.ops.curveskel.bind(armature=arm.name)
    assert not ob.modifiers and ob.parent is None


def test_generate_again_keeps_the_bound_mesh_in_place():
    """Generating again replaces the armature the mesh is parented to: with --bind the mesh moves
    to the new one, without it the mesh is unparented; either way it stays where it is."""
    V, F, _ = skeleton_of("bent_capsule")
    ob = mesh_object("L", V, F)
    ob.matrix_world = MESH_M
    assert bpy.ops.curveskel.generate('EXEC_DEFAULT', bind=True, make_silhouette=False) == {'FINISHED'}
    arm = bpy.data.objects["L.skeleton"]
    assert ob.parent is arm
    arm.location.x += 2.0                 # the user moves the rig; the mesh follows
    bpy.context.view_layer.update()
    world = ob.matrix_world.copy()
    assert not same_matrix(world, MESH_M)
    for bind in (True, False):
        bpy.context.view_layer.objects.active = ob
        assert bpy.ops.curveskel.generate('EXEC_DEFAULT', bind=bind, make_silhouette=False) == {'FINISHED'}
        bpy.context.view_layer.update()
        new = bpy.data.objects["L.skeleton"]
        assert (ob.parent is new) if bind else (ob.parent is None)
        assert same_matrix(ob.matrix_world, world)
        assert len([o for o in bpy.data.objects if o.type == 'ARMATURE']) == 1
