"""Armature, binding and export in headless Blender, on the L (bent capsule) and the 4-arm star.

Skeletons come from the real ``skeletonize``; the armature from ``build_armature``; weights from
``bind_mesh``. Deformed positions are read from the evaluated mesh. conftest.py sets
BLENDER_USER_RESOURCES, registers the add-on and empties the scene before every test.
"""

import math
import re

import bpy
import numpy as np
import pytest
from mathutils import Matrix, Quaternion

import meshes
from curveskel_addon.armature import build_armature
from curveskel_addon.binding import GROUPS_KEY, MODIFIER_NAME, benchmark_bind, bind_mesh
from curveskel_addon.core import CurveSkelError, skeletonize
from curveskel_addon.export import export_rig


_SKELETONS = {}


def skeleton_of(name):
    if name not in _SKELETONS:
        V, F = getattr(meshes, name)()
        _SKELETONS[name] = (V, F, skeletonize(V, F))
    return _SKELETONS[name]


def mesh_object(name, V, F):
    me = bpy.data.meshes.new(name)
    me.vertices.add(len(V))
    me.vertices.foreach_set("co", np.asarray(V, np.float32).ravel())
    me.loops.add(F.size)
    me.loops.foreach_set("vertex_index", np.asarray(F, np.int32).ravel())
    me.polygons.add(len(F))
    me.polygons.foreach_set("loop_start", np.arange(0, F.size, 3, dtype=np.int32))
    me.update(calc_edges=True)
    ob = bpy.data.objects.new(name, me)
    bpy.context.scene.collection.objects.link(ob)
    bpy.context.view_layer.objects.active = ob
    return ob


def rigged(name, *, matrix=None):
    V, F, sk = skeleton_of(name)
    ob = mesh_object(name, V, F)
    if matrix is not None:
        ob.matrix_world = matrix
    arm = build_armature(bpy.context, sk, f"{name}.skeleton", bpy.context.scene.collection, ob.matrix_world)
    arm["curveskel_source"] = name
    fig = bind_mesh(ob, arm, sk)
    return V, sk, ob, arm, fig


def evaluated(ob):
    dg = bpy.context.evaluated_depsgraph_get()
    dg.update()
    e = ob.evaluated_get(dg)
    me = e.to_mesh()
    P = np.empty(len(me.vertices) * 3)
    me.vertices.foreach_get("co", P)
    e.to_mesh_clear()
    return P.reshape(-1, 3)


def weight_matrix(ob, names):
    """(n, len(names)) weights of the named vertex groups."""
    col = {ob.vertex_groups[nm].index: k for k, nm in enumerate(names)}
    W = np.zeros((len(ob.data.vertices), len(names)))
    for v in ob.data.vertices:
        for g in v.groups:
            if g.group in col:
                W[v.index, col[g.group]] = g.weight
    return W


def arm_directions(name):
    if name == "star":
        return [np.array([math.cos(a), math.sin(a), 0.0]) for a in np.arange(4) * math.pi / 2]
    return [np.array([-1.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.0])]


def leaf_and_arm_bone(arm, u):
    """The leaf bone at the tip of the arm along ``u``, and the ancestor that starts the arm
    (the highest one that reaches out beyond the central part, ``tail . u > 1``: its head may
    lie inside the junction's ball)."""
    leaves = [b for b in arm.data.bones if not b.children and b.parent is not None]
    leaf = max(leaves, key=lambda b: np.dot(np.array(b.tail_local), u))
    top = leaf
    while (top.parent is not None and top.parent.parent is not None
           and np.dot(np.array(top.parent.tail_local), u) > 1.0):
        top = top.parent
    return leaf, top


def rotate(arm, bone_name, degrees=45.0):
    pb = arm.pose.bones[bone_name]
    pb.rotation_mode = 'QUATERNION'
    pb.rotation_quaternion = Quaternion((1.0, 0.0, 0.0), math.radians(degrees))   # about the bone's x


# -- armature ----------------------------------------------------------------------------------------
NAME = re.compile(r"^(root(\.\d{2})?|(spine|limb|chain)\d*(\.[LR])?\.\d{2,})$")


@pytest.mark.parametrize("name", ["bent_capsule", "star"])
def test_armature_layout(name):
    V, sk, ob, arm, fig = rigged(name)
    bones = arm.data.bones
    diag = float(np.linalg.norm(np.ptp(V, axis=0)))
    roots = [b for b in bones if b.parent is None]
    assert [b.name for b in roots] == ["root"]
    assert all(NAME.match(b.name) for b in bones), [b.name for b in bones]
    assert len(bones) >= 3
    assert list(arm["curveskel_bone_names"]) and len(arm["curveskel_bone_names"]) == sk.n_bones
    assert all(nm in bones for nm in arm["curveskel_bone_names"])
    assert len(arm["curveskel_joints"]) == 4 * sk.n_joints and len(arm["curveskel_bones"]) == 2 * sk.n_bones
    assert arm["curveskel_source"] == name
    for b in bones:
        assert b.length > 0
        if b.use_connect:
            assert (b.head_local - b.parent.tail_local).length < 1e-5
        if b.parent is not None and b.parent.parent is not None and b.use_connect:
            # rolls: no flip between consecutive bones (Bone.z_axis is parent-relative: use
            # the armature-space matrix)
            z, zp = b.matrix_local.to_3x3().col[2], b.parent.matrix_local.to_3x3().col[2]
            assert z.dot(zp) > 0, (b.name, b.parent.name)
    # the root bone sits on (or, projected onto the mirror plane, next to) the most central joint
    from curveskel_addon.rig.graph_root import central_joints

    c = central_joints(sk.joints, sk.bones)[0]
    assert np.linalg.norm(np.array(roots[0].head_local) - sk.joints[c, :3]) < 0.02 * diag


def test_armature_follows_object_matrix():
    M = Matrix.Translation((1.0, 2.0, 3.0)) @ Matrix.Rotation(math.pi / 2, 4, 'X')
    V, sk, ob, arm, fig = rigged("bent_capsule", matrix=M)
    assert np.allclose(np.array(arm.matrix_world), np.array(M), atol=1e-6)
    # the root bone points up in the world, whatever the object's rotation
    root = arm.data.bones["root"]
    world_dir = (arm.matrix_world.to_3x3() @ (root.tail_local - root.head_local)).normalized()
    assert world_dir.z > 0.999
    assert np.abs(evaluated(ob) - V).max() < 1e-5


# -- weights -----------------------------------------------------------------------------------------
@pytest.mark.parametrize("name", ["bent_capsule", "star"])
def test_weights_cover_and_sum_to_one(name):
    V, sk, ob, arm, fig = rigged(name)
    names = list(ob[GROUPS_KEY])
    assert set(names) <= {b.name for b in arm.data.bones if b.use_deform}
    W = weight_matrix(ob, names)
    assert np.allclose(W.sum(axis=1), 1.0, atol=1e-6)
    assert np.all((W > 0).sum(axis=1) >= 1)
    assert np.all((W > 0).sum(axis=1) <= 4)
    assert fig["unweighted"] == 0 and fig["max_influences"] <= 4 and fig["mapping"] == "bones"
    assert sorted(names) == sorted(b.name for b in arm.data.bones if b.use_deform)   # one per bone
    mod = ob.modifiers[MODIFIER_NAME]
    assert mod.type == 'ARMATURE' and mod.object == arm and mod.use_vertex_groups


@pytest.mark.parametrize("name", ["bent_capsule", "star"])
def test_rest_pose_is_the_input(name):
    V, sk, ob, arm, fig = rigged(name)
    assert np.abs(evaluated(ob) - V).max() < 1e-5


@pytest.mark.parametrize("name", ["bent_capsule", "star"])
def test_posing_moves_one_arm_only(name):
    V, sk, ob, arm, fig = rigged(name)
    diag = float(np.linalg.norm(np.ptp(V, axis=0)))
    dirs = arm_directions(name)
    arm_len = 4.0
    report = []
    for k, u in enumerate(dirs):
        leaf, top = leaf_and_arm_bone(arm, u)
        others = np.zeros(len(V), bool)
        for m, w in enumerate(dirs):
            if m != k:
                others |= V @ w > 1.5
        tip = V @ u > arm_len - 0.3
        # The tip bone (the leaf, or its nearest ancestor that carries vertices alone: the
        # skeletonizer can end a branch with a very short bone), then the whole arm: the
        # vertices carried by the bone and its descendants alone turn rigidly about its head.
        groups = set(ob[GROUPS_KEY])

        def subtree_weight(bone):
            sub = [b.name for b in [bone, *bone.children_recursive] if b.name in groups]
            return weight_matrix(ob, sub).sum(axis=1)

        while not (subtree_weight(leaf) > 1 - 1e-6).any():
            leaf = leaf.parent
        for bone, what in ((leaf, "tip"), (top, "arm")):
            rotate(arm, bone.name)
            P = evaluated(ob)
            d = np.linalg.norm(P - V, axis=1)
            W = subtree_weight(bone)
            pb = arm.pose.bones[bone.name]
            R = (pb.matrix @ bone.matrix_local.inverted()).to_3x3()
            head = np.array(bone.head_local)
            rigid = (V - head) @ np.array(R).T + head
            full = W > 1 - 1e-6
            assert full.any()
            assert np.abs(P[full] - rigid[full]).max() < 1e-4, what
            assert d[others].max() < 1e-4 * diag, (what, d[others].max())
            if what == "arm":
                reach = arm_len - float(np.dot(np.array(bone.head_local), u))
                assert d[tip].max() > 0.9 * 2 * math.sin(math.radians(22.5)) * reach
                assert d[tip].max() > 0.25 * arm_len
            report.append((k, what, bone.name, round(float(d[tip].max()), 4), float(d[others].max())))
            pb.rotation_quaternion = (1.0, 0.0, 0.0, 0.0)
    assert np.abs(evaluated(ob) - V).max() < 1e-5                 # back to rest
    print(name, report)


# -- re-binding, heat weights ------------------------------------------------------------------------
def test_rebind_keeps_user_groups_and_modifiers():
    V, sk, ob, arm, fig = rigged("star")
    user = ob.vertex_groups.new(name="user_group")
    user.add(list(range(0, len(V), 3)), 0.3, 'REPLACE')
    ob.modifiers.new("user_subsurf", 'SUBSURF')
    ob.modifiers.new("user_smooth", 'SMOOTH')
    ob.modifiers.move(2, 0)                                # user's smooth first: ours stays in place
    order = [m.name for m in ob.modifiers]
    fig2 = bind_mesh(ob, arm, None, blend=0.1)             # from the armature alone
    assert [m.name for m in ob.modifiers] == order
    # Our groups replaced (none left from the first bind, none doubled), the user's kept. The
    # two mappings may weight different sets of bones: groups exist only for bones with weight.
    ours = list(ob[GROUPS_KEY])
    assert sorted(g.name for g in ob.vertex_groups) == sorted(ours + ["user_group"])
    assert set(ours) <= {b.name for b in arm.data.bones} and len(ours) >= 4     # every arm
    assert not any(g.name.endswith(".001") for g in ob.vertex_groups)
    W = weight_matrix(ob, ["user_group"])[:, 0]
    assert np.allclose(W[::3], 0.3) and np.all(W[np.arange(len(V)) % 3 != 0] == 0)
    assert fig2["mapping"] == "bones"
    Wc = weight_matrix(ob, list(ob[GROUPS_KEY]))
    assert np.allclose(Wc.sum(axis=1), 1.0, atol=1e-6)
    for m in ("user_subsurf", "user_smooth"):
        ob.modifiers[m].show_viewport = False
    assert np.abs(evaluated(ob) - V).max() < 1e-5


def test_bind_refuses_user_group_named_like_a_bone():
    V, F, sk = skeleton_of("bent_capsule")
    ob = mesh_object("L", V, F)
    arm = build_armature(bpy.context, sk, "L.skeleton", bpy.context.scene.collection, ob.matrix_world)
    ob.vertex_groups.new(name=arm.data.bones[1].name)
    with pytest.raises(CurveSkelError):
        bind_mesh(ob, arm, sk)
    assert [m.type for m in ob.modifiers] == []


def test_heat_weights_for_comparison():
    V, sk, ob, arm, fig = rigged("bent_capsule")
    fig = bind_mesh(ob, arm, method="HEAT")
    assert fig["method"] == "HEAT" and fig["groups"] > 0
    assert ob.parent is arm and ob.parent_type == 'OBJECT'     # parented as by Ctrl+P > Armature
    assert [m.name for m in ob.modifiers] == [MODIFIER_NAME]
    assert np.abs(evaluated(ob) - V).max() < 1e-5
    assert not any("slow" in w for w in fig["warnings"])   # 1.9k vertices: no warning


# -- operator --------------------------------------------------------------------------------------------
def test_bind_operator_finds_the_armature():
    V, F, sk = skeleton_of("bent_capsule")
    ob = mesh_object("L", V, F)
    assert not bpy.ops.curveskel.bind.poll()               # no armature yet
    arm = build_armature(bpy.context, sk, "L.skeleton", bpy.context.scene.collection, ob.matrix_world)
    arm["curveskel_source"] = "L"
    assert "UNDO" in bpy.types.CURVESKEL_OT_bind.bl_options
    assert bpy.ops.curveskel.bind.poll()
    assert bpy.ops.curveskel.bind(blend=0.2) == {'FINISHED'}
    assert ob.modifiers[MODIFIER_NAME].object == arm
    assert len(ob[GROUPS_KEY]) > 0
    assert bpy.ops.curveskel.bind() == {'FINISHED'}         # again: replaced, not doubled
    assert [m.name for m in ob.modifiers] == [MODIFIER_NAME]


# -- export ------------------------------------------------------------------------------------------------
def _skinned_vertex_count(ob):
    return sum(1 for v in ob.data.vertices if any(g.weight > 0 for g in v.groups))


def world_positions(ob):
    P = evaluated(ob)
    M = np.array(ob.matrix_world)
    return P @ M[:3, :3].T + M[:3, 3]


def test_glb_export_reimports(tmp_path):
    M = Matrix.Translation((0.5, 0.0, 1.0)) @ Matrix.Rotation(0.3, 4, 'Z')
    V, sk, ob, arm, fig = rigged("star", matrix=M)
    ob.data.polygons.foreach_set("use_smooth", np.ones(len(ob.data.polygons), bool))  # no normal splits
    n_bones = len(arm.data.bones)
    before = world_positions(ob)
    out = export_rig(bpy.context, ob, arm, tmp_path / "star.glb")
    assert ob.parent is arm and np.allclose(np.array(ob.matrix_world), np.array(M), atol=1e-6)
    assert out["format"] == "GLB" and (tmp_path / "star.glb").stat().st_size > 0
    bpy.ops.wm.read_homefile(use_empty=True)
    bpy.ops.import_scene.gltf(filepath=str(tmp_path / "star.glb"))
    arms = [o for o in bpy.data.objects if o.type == 'ARMATURE']
    # (the importer may add an "Icosphere" bone-shape mesh: keep the skinned one)
    mes = [o for o in bpy.data.objects if o.type == 'MESH' and len(o.vertex_groups)]
    assert len(arms) == 1 and len(mes) == 1
    assert len(arms[0].data.bones) == n_bones
    assert len(mes[0].data.vertices) == len(V)
    assert _skinned_vertex_count(mes[0]) == len(V)
    assert any(m.type == 'ARMATURE' for m in mes[0].modifiers)
    assert np.abs(world_positions(mes[0]) - before).max() < 1e-4   # same rest shape, same place


def test_fbx_export_reimports(tmp_path):
    V, sk, ob, arm, fig = rigged("bent_capsule")
    n_bones = len(arm.data.bones)
    export_rig(bpy.context, ob, arm, tmp_path / "L.fbx")
    bpy.ops.wm.read_homefile(use_empty=True)
    bpy.ops.import_scene.fbx(filepath=str(tmp_path / "L.fbx"))
    arms = [o for o in bpy.data.objects if o.type == 'ARMATURE']
    mes = [o for o in bpy.data.objects if o.type == 'MESH' and len(o.vertex_groups)]
    assert len(arms) == 1 and len(mes) == 1 and len(arms[0].data.bones) == n_bones
    assert _skinned_vertex_count(mes[0]) == len(mes[0].data.vertices) == len(V)


# -- speed ---------------------------------------------------------------------------------------------------
def test_bind_100k_vertices_weights_every_vertex():
    # its time is measured by scripts/bench.py (Blender row), never asserted here
    fig = benchmark_bind(100_000)
    assert fig["vertices"] >= 99_000
    assert fig["unweighted"] == 0
    assert fig["groups"] == fig["bones"] >= 20               # a group per deforming bone
    assert 1 <= fig["max_influences"] <= 2                  # a bone and its chain neighbour


def test_generate_operator_binds_when_asked():
    V, F, sk = skeleton_of("bent_capsule")
    ob = mesh_object("L", V, F)
    ob.vertex_groups.new(name="user_group")
    assert bpy.ops.curveskel.generate('EXEC_DEFAULT', bind=True, make_silhouette=False,
                                      spacing=0.08) == {'FINISHED'}
    arm = bpy.data.objects["L.skeleton"]
    assert ob.modifiers[MODIFIER_NAME].object == arm
    assert ob[GROUPS_KEY] and "user_group" in ob.vertex_groups
    W = weight_matrix(ob, list(ob[GROUPS_KEY]))
    assert np.allclose(W.sum(axis=1), 1.0, atol=1e-6)
    assert np.abs(evaluated(ob) - V).max() < 1e-5
    # generating again replaces the armature and re-binds in place
    assert bpy.ops.curveskel.generate('EXEC_DEFAULT', bind=True, make_silhouette=False,
                                      spacing=0.08) == {'FINISHED'}
    assert [m.name for m in ob.modifiers] == [MODIFIER_NAME]
    assert ob.modifiers[MODIFIER_NAME].object == bpy.data.objects["L.skeleton"]
    assert len([a for a in bpy.data.objects if a.type == 'ARMATURE']) == 1


def test_command_line_bind_and_export(tmp_path, user_resources):
    import os
    import subprocess
    import sys
    from pathlib import Path

    V, F, sk = skeleton_of("bent_capsule")
    obj = tmp_path / "L.obj"
    with open(obj, "w") as fh:
        fh.writelines(f"v {x:.9g} {y:.9g} {z:.9g}\n" for x, y, z in V)
        fh.writelines(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in F)
    root = Path(__file__).resolve().parents[2]
    env = {**os.environ, "BLENDER_USER_RESOURCES": user_resources}
    res = subprocess.run([sys.executable, str(root / "scripts" / "skeletonize.py"), str(obj), "--bind",
                          "--glb", str(tmp_path / "L.glb"), "--fbx", str(tmp_path / "L.fbx"),
                          "--spacing", "0.08"],
                         capture_output=True, text=True, env=env, timeout=300)
    assert res.returncode == 0, res.stderr[-2000:]
    assert "rig " in res.stdout and (tmp_path / "L.glb").stat().st_size > 0
    assert (tmp_path / "L.fbx").stat().st_size > 0
    bpy.ops.import_scene.gltf(filepath=str(tmp_path / "L.glb"))
    mes = [o for o in bpy.data.objects if o.type == 'MESH' and len(o.vertex_groups)]
    assert len(mes) == 1 and _skinned_vertex_count(mes[0]) == len(mes[0].data.vertices)


def test_two_parts_get_two_roots():
    V, sk, ob, arm, fig = rigged("two_capsules")
    roots = sorted(b.name for b in arm.data.bones if b.parent is None)
    assert roots == ["root.00", "root.01"]
    assert not any(b.name.startswith("branch") for b in arm.data.bones)
    W = weight_matrix(ob, list(ob[GROUPS_KEY]))
    assert np.allclose(W.sum(axis=1), 1.0, atol=1e-6)
    assert np.abs(evaluated(ob) - V).max() < 1e-5


# -- the bind's Blender side against straightforward references (issue 14's faster bind) -------------
def test_armature_bones_equal_per_bone_reads():
    from curveskel_addon.binding import armature_bones

    V, F, sk = skeleton_of("star")
    ob = mesh_object("star", V, F)
    arm = build_armature(bpy.context, sk, "star.skeleton", bpy.context.scene.collection, ob.matrix_world)
    arm.data.bones[2].use_deform = False
    got = armature_bones(arm)
    bones = list(arm.data.bones)
    names = [b.name for b in bones]
    assert list(got["names"]) == names
    assert got["parent"].tolist() == [names.index(b.parent.name) if b.parent else -1 for b in bones]
    assert got["deform"].tolist() == [b.use_deform for b in bones]
    assert np.allclose(got["heads"], [b.head_local for b in bones])
    assert np.allclose(got["tails"], [b.tail_local for b in bones])


def test_written_groups_are_the_core_weights_named_as_the_bones():
    """bind_mesh writes, per deforming bone in armature order, a group named as the bone holding
    exactly bone_weights' weights (float32 in Blender), beside a user's own group."""
    from curveskel_addon.binding import _edges, _vertices, armature_bones
    from curveskel_addon.rig.skin_weights import bone_weights

    V, F, sk = skeleton_of("star")
    ob = mesh_object("star", V, F)
    ob.vertex_groups.new(name="user").add([0, 1], 0.3, 'REPLACE')
    arm = build_armature(bpy.context, sk, "star.skeleton", bpy.context.scene.collection, ob.matrix_world)
    arm.data.bones[1].use_deform = False
    bind_mesh(ob, arm)
    bones = armature_bones(arm)
    index, weight, _ = bone_weights(_vertices(ob.data), None, bones["heads"], bones["tails"],
                                    bones["parent"], bones["deform"], edges=_edges(ob.data))
    deform = [nm for nm, d in zip(bones["names"], bones["deform"]) if d]
    assert [g.name for g in ob.vertex_groups] == ["user"] + deform
    assert list(ob[GROUPS_KEY]) == deform
    by_index = {g.index: g.name for g in ob.vertex_groups}
    for v in ob.data.vertices:
        got = {by_index[g.group]: g.weight for g in v.groups}
        user = got.pop("user", None)
        assert user == pytest.approx(0.3) if v.index < 2 else user is None
        want = {bones["names"][i]: np.float32(w) for i, w in zip(index[v.index], weight[v.index]) if i >= 0}
        assert got == want


def test_bind_refuses_a_group_name_blender_would_change():
    """A bone whose name is taken by a group the bind must keep: Blender would rename the new
    group, and the bind says so instead of writing weights under another name."""
    from curveskel_addon.binding import write_weights

    V, F, sk = skeleton_of("bent_capsule")
    ob = mesh_object("L", V, F)
    with pytest.raises(CurveSkelError):
        write_weights(ob, ["a", "a"], np.zeros((len(V), 1), np.int64), np.ones((len(V), 1)))
