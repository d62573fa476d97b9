"""Issue 14: the armature is the truth once it exists (move / delete / rename / add bones, rename
the mesh, then bind), no weight bleeding between fingers 0.03 apart, mirror names on a symmetric
mesh, the bind UI, and a glTF file the Khronos validator accepts.

Outcomes are asserted with thresholds that hold for any reasonable skeleton: the tests find the
bones they edit by where they are (the arm along +x, ...), never by a joint count of today's
skeletonizer. conftest.py registers the add-on and empties the scene before every test.
"""

from contextlib import contextmanager
from pathlib import Path

import bpy
import numpy as np
import pytest
from mathutils import Matrix, Quaternion

import gltf_validator
import meshes
from curveskel_addon import results
from curveskel_addon.binding import GROUPS_KEY, MODIFIER_NAME, POINTER, bind_mesh
from curveskel_addon.export import export_rig
from curveskel_addon.gltf_layout import read_glb
from test_rigging import evaluated, leaf_and_arm_bone, mesh_object, rigged, rotate, weight_matrix

#: A coarser Detail Size where a test is about the rig's bookkeeping, not the skeleton's detail
#: (the core's search takes seconds a run at the default).
FAST = {"spacing": 0.08}


@contextmanager
def edit_bones(arm):
    """The armature's edit bones, in Edit Mode for the block; back in Object Mode after."""
    vl = bpy.context.view_layer
    prev = vl.objects.active
    vl.objects.active = arm
    bpy.ops.object.mode_set(mode='EDIT')
    assert arm.mode == 'EDIT'
    try:
        yield arm.data.edit_bones
    finally:
        bpy.ops.object.mode_set(mode='OBJECT')
        vl.objects.active = prev


def groups_of(ob):
    return {g.name for g in ob.vertex_groups}


def deform_bones(arm):
    return {b.name for b in arm.data.bones if b.use_deform}


def main_group(ob, names):
    """(n,) index into ``names`` of each vertex's largest weight, and that weight."""
    W = weight_matrix(ob, names)
    return W.argmax(axis=1), W.max(axis=1)


def check_bound(ob, arm):
    """Our groups are exactly the deforming bones, every vertex's weights sum to 1."""
    assert set(ob[GROUPS_KEY]) == deform_bones(arm)
    assert deform_bones(arm) <= groups_of(ob)
    assert not any(g.name.endswith(".001") for g in ob.vertex_groups)
    W = weight_matrix(ob, sorted(deform_bones(arm)))
    assert np.allclose(W.sum(axis=1), 1.0, atol=1e-6)
    assert ob.modifiers[MODIFIER_NAME].object == arm
    assert getattr(ob, POINTER) == arm


# -- the armature as edited ------------------------------------------------------------------------
def test_moved_joint_moves_the_weights():
    V, sk, ob, arm, _ = rigged("star")

    def pairs_along():
        return [b for b in arm.data.bones if b.parent is not None and b.use_connect
                and b.parent.head_local.x > 0.3 and abs(b.head_local.y) < 0.3
                and b.tail_local.x > b.head_local.x > b.parent.head_local.x]

    # two connected bones along the +x arm (the longest such pair); a straight arm may be one
    # long bone (J prices every joint): the rigger subdivides it first, in three
    if max((min(b.length, b.parent.length) for b in pairs_along()), default=0.0) < 0.8:
        whole = max((b for b in arm.data.bones if b.tail_local.x > 0.3 and abs(b.tail_local.y) < 0.3
                     and b.tail_local.x > b.head_local.x), key=lambda b: b.length)
        with edit_bones(arm) as ebs:
            eb = ebs[whole.name]
            head, tail = eb.head.copy(), eb.tail.copy()
            cuts = [head.lerp(tail, 1 / 3), head.lerp(tail, 2 / 3), tail]
            children = list(eb.children)
            eb.tail, last = cuts[0], eb                 # in three: the outer two are the pair
            for n, end in enumerate(cuts[1:], 1):
                part = ebs.new(f"{eb.name}_sub{n}")
                part.head, part.tail, part.roll = last.tail.copy(), end, eb.roll
                part.parent, part.use_connect, part.use_deform = last, True, eb.use_deform
                last = part
            for c in children:
                c.parent = last
        bind_mesh(ob, arm)
    along = pairs_along()
    leaf = max(along, key=lambda b: min(b.length, b.parent.length))
    parent = leaf.parent
    lo, hi = float(parent.head_local.x), float(leaf.tail_local.x)
    assert hi - lo > 0.8, (lo, hi)
    old = float(leaf.head_local.x)
    # the joint between the two bones moves along the arm, well away from where it was
    cands = [lo + 0.3 * (hi - lo), lo + 0.7 * (hi - lo)]
    new = max(cands, key=lambda x: abs(x - old))
    name = leaf.name
    before = weight_matrix(ob, [name])[:, 0]
    with edit_bones(arm) as ebs:
        eb = ebs[name]
        assert eb.use_connect                       # moving its head moves the parent's tail
        eb.head = (new, eb.head.y, eb.head.z)
    fig = bind_mesh(ob, arm)
    check_bound(ob, arm)
    assert fig["mapping"] == "bones" and fig["unweighted"] == 0
    w = weight_matrix(ob, [name])[:, 0]
    on_arm = (np.abs(V[:, 1]) < 0.6) & (np.abs(V[:, 2]) < 0.6)
    beyond = on_arm & (V[:, 0] > new + 0.3 * (hi - new)) & (V[:, 0] < hi - 0.3 * (hi - new))
    before_joint = on_arm & (V[:, 0] > lo + 0.2 * (new - lo)) & (V[:, 0] < new - 0.5 * (new - lo))
    assert beyond.sum() > 5 and before_joint.sum() > 5
    assert w[beyond].min() > 0.5
    assert w[before_joint].max() < 0.02
    assert np.abs(w - before).max() > 0.25              # the weights followed the edit
    assert np.abs(evaluated(ob) - V).max() < 1e-5       # rest pose is still the input


def test_deleted_bone_loses_its_group_and_its_vertices_follow_the_parent():
    V, sk, ob, arm, _ = rigged("star")
    u = np.array([0.0, 1.0, 0.0])
    leaf, _ = leaf_and_arm_bone(arm, u)
    name, parent = leaf.name, leaf.parent.name
    assert name in groups_of(ob)
    with edit_bones(arm) as ebs:
        ebs.remove(ebs[name])
    bind_mesh(ob, arm)
    check_bound(ob, arm)
    assert name not in groups_of(ob)
    tip = V @ u > 3.8
    names = sorted(deform_bones(arm))
    k, w = main_group(ob, names)
    assert tip.sum() > 10 and {names[i] for i in k[tip]} == {parent}
    # posing the parent carries the tip
    rotate(arm, parent)
    assert np.linalg.norm(evaluated(ob) - V, axis=1)[tip].max() > 0.05


def test_renamed_bone_renamed_objects_then_bind_operator():
    V, sk, ob, arm, _ = rigged("star")
    leaf, _ = leaf_and_arm_bone(arm, np.array([-1.0, 0.0, 0.0]))
    old = leaf.name
    before = weight_matrix(ob, [old])[:, 0]
    arm.data.bones[old].name = "my_finger"             # Blender renames the bound group too
    ob.name, arm.name = "Starfish", "Starfish rig"
    user = ob.vertex_groups.new(name="user_paint")      # the user's own group: kept
    user.add([0, 1, 2], 0.5, 'REPLACE')
    for o in bpy.context.view_layer.objects:
        o.select_set(False)
    ob.select_set(True)
    bpy.context.view_layer.objects.active = ob
    assert bpy.ops.curveskel.bind.poll()
    assert bpy.ops.curveskel.bind() == {'FINISHED'}
    check_bound(ob, arm)
    assert old not in groups_of(ob) and "my_finger" in groups_of(ob) and "user_paint" in groups_of(ob)
    after = weight_matrix(ob, ["my_finger"])[:, 0]
    assert np.abs(after - before).max() < 1e-6            # same bone, same weights, new name
    assert np.allclose(weight_matrix(ob, ["user_paint"])[:3, 0], 0.5)


def test_added_bones_deforming_and_not():
    V, sk, ob, arm, _ = rigged("star")
    u = np.array([1.0, 0.0, 0.0])
    leaf, _ = leaf_and_arm_bone(arm, u)
    # read before Edit Mode: leaving it rebuilds the bones, and a Bone reference taken before
    # then reads freed memory (the cap below came out empty in one run of four on bpy 5.2.3)
    name, leaf_end = leaf.name, float(np.array(leaf.tail_local) @ u)
    with edit_bones(arm) as ebs:
        tip = ebs.new("extruded")
        tip.head = ebs[name].tail.copy()
        tip.tail = ebs[name].tail + (ebs[name].tail - ebs[name].head).normalized() * 0.6
        tip.parent = ebs[name]
        tip.use_connect = True
        ctrl = ebs.new("control")
        ctrl.head, ctrl.tail = (0.0, 0.0, 2.0), (0.0, 0.0, 3.0)
        ctrl.use_deform = False
    fig = bind_mesh(ob, arm)
    check_bound(ob, arm)
    assert "extruded" in groups_of(ob) and "control" not in groups_of(ob)
    assert fig["groups"] == len(deform_bones(arm))
    w = weight_matrix(ob, ["extruded"])[:, 0]
    cap = V @ u > leaf_end + 0.1
    assert cap.sum() > 5 and w[cap].max() > 0.5
    # posing the new bone moves the cap only
    rotate(arm, "extruded")
    d = np.linalg.norm(evaluated(ob) - V, axis=1)
    assert d[cap].max() > 0.05 and d[V @ u < 2.0].max() < 1e-6


def test_rename_mesh_then_bind_and_regenerate_gives_one_rig():
    V, F = meshes.bent_capsule()
    ob = mesh_object("L", V, F)
    assert bpy.ops.curveskel.generate('EXEC_DEFAULT', bind=True, **FAST) == {'FINISHED'}
    arm = bpy.data.objects["L.skeleton"]
    ob.name = "Leg"
    arm.name = "my rig"
    assert results.find_result("Leg")["armature"] == arm          # pointers, not names
    assert results.source_object(arm) == ob and results.source_of(arm) == "Leg"
    assert results.find_result(ob)["silhouette"] == bpy.data.objects["L.silhouette"]
    bpy.context.view_layer.objects.active = ob
    assert bpy.ops.curveskel.bind.poll()
    assert bpy.ops.curveskel.bind() == {'FINISHED'}
    check_bound(ob, arm)
    assert bpy.ops.curveskel.generate('EXEC_DEFAULT', bind=True, **FAST) == {'FINISHED'}
    arms = [o for o in bpy.data.objects if o.type == 'ARMATURE']
    sils = [o for o in bpy.data.objects if o.name.endswith(".silhouette")]
    assert [a.name for a in arms] == ["Leg.skeleton"] and [s.name for s in sils] == ["Leg.silhouette"]
    found = results.find_result("Leg")
    assert found["armature"] == arms[0] and found["silhouette"] == sils[0]
    assert [m.name for m in ob.modifiers] == [MODIFIER_NAME]
    check_bound(ob, arms[0])
    assert np.abs(evaluated(ob) - V).max() < 1e-5


# -- no bleeding between fingers 0.03 apart ------------------------------------------------------
GAP, FR = 0.03, 0.1                       # gap between the finger surfaces, finger radius
FX = FR + GAP / 2                         # finger axes at x = +-FX


def two_finger_mesh():
    """A palm (capsule along z, radius 0.25, top at z = 0) and two fingers (radius 0.1, from
    z = -0.05 to 1.0) whose surfaces are 0.03 apart, united into one closed mesh."""
    from meshes import _manifold_from, _to_arrays, tube_along

    union = _manifold_from(*tube_along(np.array([[0.0, 0.0, -0.4], [0.0, 0.0, 0.0]]), 0.25, 32))
    for sx in (-FX, FX):
        path = np.stack([np.full(40, sx), np.zeros(40), np.linspace(-0.05, 1.0, 40)], 1)
        union = union + _manifold_from(*tube_along(path, FR, 24))
    return _to_arrays(union)


def armature_from(name, bones):
    """Armature object from ``[(name, head, tail, parent or None, connect), ...]``."""
    arm = bpy.data.objects.new(name, bpy.data.armatures.new(name))
    bpy.context.scene.collection.objects.link(arm)
    with edit_bones(arm) as ebs:
        for nm, h, t, p, c in bones:
            eb = ebs.new(nm)
            eb.head, eb.tail = h, t
            if p is not None:
                eb.parent = ebs[p]
                eb.use_connect = c
    return arm


@pytest.mark.parametrize("method", ["SURFACE", "HEAT"])
def test_posing_one_finger_leaves_the_other_still(method):
    V, F = two_finger_mesh()
    ob = mesh_object("two_fingers", V, F)
    bones = [("palm", (0, 0, -0.4), (0, 0, 0.2), None, False)]
    for side, x in (("L", FX), ("R", -FX)):
        bones += [(f"finger.{side}.01", (x, 0, 0.2), (x, 0, 0.6), "palm", False),
                  (f"finger.{side}.02", (x, 0, 0.6), (x, 0, 1.0), f"finger.{side}.01", True)]
    arm = armature_from("hand", bones)
    fig = bind_mesh(ob, arm, method=method)
    assert fig["unweighted"] == 0
    diag = float(np.linalg.norm(np.ptp(V, axis=0)))
    other = (V[:, 0] < -GAP / 2) & (V[:, 2] > 0.3)          # the R finger above the palm
    posed = (V[:, 0] > GAP / 2) & (V[:, 2] > 0.8)           # the L finger's tip
    W = weight_matrix(ob, ["finger.L.01", "finger.L.02"]).sum(axis=1)
    rotate(arm, "finger.L.01")
    d = np.linalg.norm(evaluated(ob) - V, axis=1)
    print(method, "largest move of the other finger", d[other].max(), "weight", W[other].max())
    assert d[posed].min() > 0.1                             # the posed finger bends
    if method == "SURFACE":
        assert W[other].max() == 0.0
        assert d[other].max() < 1e-6 * diag
    else:                                                   # heat: recorded, not required
        assert d[other].max() < 0.5 * diag


# -- mirror names ------------------------------------------------------------------------------------
def t_body():
    """A body (capsule along z, radius 0.5, 0..5) with two arms along x (radius 0.35, tips at
    x = +-3, z = 3.5): symmetric about x = 0."""
    from meshes import _manifold_from, _to_arrays, tube_along

    body = _manifold_from(*tube_along(np.stack([np.zeros(40), np.zeros(40), np.linspace(0, 5, 40)], 1),
                                      0.5, 32))
    arms = _manifold_from(*tube_along(np.stack([np.linspace(-3, 3, 60), np.zeros(60), np.full(60, 3.5)], 1),
                                      0.35, 24))
    V, F = _to_arrays(body + arms)
    return V, F


def test_symmetric_mesh_gets_mirrored_left_right_pairs():
    V, F = t_body()
    ob = mesh_object("T", V, F)
    assert bpy.ops.curveskel.generate('EXEC_DEFAULT', bind=True) == {'FINISHED'}
    arm = bpy.data.objects["T.skeleton"]
    assert np.allclose(arm["curveskel_mirror"], [1.0, 0.0, 0.0, 0.0], atol=1e-3)
    bones = arm.data.bones
    names = [b.name for b in bones]
    left = [nm for nm in names if ".L." in nm or nm.endswith(".L")]
    assert len(left) >= 1 and not any(nm.startswith("branch") for nm in names)
    diag = float(np.linalg.norm(np.ptp(V, axis=0)))
    S = np.diag([-1.0, 1.0, 1.0])
    for nm in left:
        flipped = bpy.utils.flip_name(nm)
        assert flipped != nm and flipped in bones, (nm, flipped)      # Blender pairs them
        bl, br = bones[nm], bones[flipped]
        assert np.abs(S @ np.array(bl.head_local) - np.array(br.head_local)).max() < 1e-5 * diag
        assert np.abs(S @ np.array(bl.tail_local) - np.array(br.tail_local)).max() < 1e-5 * diag
        assert bl.head_local.x > 0 or bl.tail_local.x > 0               # .L on +x
        # rolls mirrored as Blender mirrors a bone: z-axis reflected
        zl = np.array(bl.matrix_local.to_3x3().col[2])
        zr = np.array(br.matrix_local.to_3x3().col[2])
        assert np.abs(S @ zl - zr).max() < 1e-4
    # the arms are the pairs: a .L chain reaches the +x hand
    assert max(bones[nm].tail_local.x for nm in left) > 2.0
    assert sum(bones[nm].length for nm in left) > 2.0
    # central chains lie on the plane (a skeleton may also have unpaired side chains: "chainK")
    spine = [b for b in bones if b.name.startswith(("spine", "root"))]
    assert spine
    for b in spine:
        assert abs(b.head_local.x) < 1e-6 * diag and abs(b.tail_local.x) < 1e-6 * diag, b.name
    # pose flipping: a pose of a .L bone pasted flipped onto its .R twin deforms the mesh
    # mirrored wherever the vertices belong to paired bones only
    from scipy.spatial import cKDTree

    paired = [n for n in names if bpy.utils.flip_name(n) != n]
    Wp = weight_matrix(ob, paired)
    _, mirror_of = cKDTree(V).query(V @ S)
    assert np.abs(V[mirror_of] - V @ S).max() < 1e-6 * diag        # the mesh is symmetric
    flip = [paired.index(bpy.utils.flip_name(n)) for n in paired]
    on_pairs = Wp.sum(axis=1) > 1 - 1e-6
    # the weights are mirrored on the arms up to the surface smoothing, which follows the
    # triangulation (not mirror-symmetric: the tubes' quads are split the same way along +x);
    # away from the junction, where a skeleton may branch differently left and right. Where
    # the bones' blend zones fall on the hands, the smoothing leaves up to 0.15 of a weight
    # unmirrored on 6 % of the arms' vertices (the skeleton of today: 6 bones an arm)
    dw = np.abs(Wp[mirror_of][:, flip] - Wp).max(axis=1)
    mirrored = dw < 0.02
    arms = on_pairs & (np.abs(V[:, 0]) > 1.5)
    assert mirrored[arms].mean() > 0.9 and dw[arms].max() < 0.25
    # without the smoothing, the weights of mirrored bones are mirrored exactly
    bind_mesh(ob, arm, smooth=0.0)
    W0 = weight_matrix(ob, paired)
    assert np.abs(W0[mirror_of][:, flip] - W0)[arms].max() < 1e-6
    bind_mesh(ob, arm)
    assert np.array_equal(weight_matrix(ob, paired), Wp)
    both = on_pairs & mirrored
    assert both.sum() > 100
    first = min(left, key=lambda nm: bones[nm].head_local.x)         # the chain's first .L bone
    vl = bpy.context.view_layer
    vl.objects.active = arm
    bpy.ops.object.mode_set(mode='POSE')

    def select(pb, state):
        (pb if hasattr(pb, "select") else pb.bone).select = state   # 5.0: on the pose bone

    for pb in arm.pose.bones:
        select(pb, False)
    pl, pr = arm.pose.bones[first], arm.pose.bones[bpy.utils.flip_name(first)]
    pl.rotation_mode = pr.rotation_mode = 'QUATERNION'
    pl.rotation_quaternion = Quaternion((0.3, 0.5, 0.2), 0.8)
    select(pl, True)
    arm.data.bones.active = pl.bone
    assert bpy.ops.pose.copy() == {'FINISHED'}
    select(pl, False)
    select(pr, True)
    arm.data.bones.active = pr.bone
    assert bpy.ops.pose.paste(flipped=True) == {'FINISHED'}
    # the flipped pose is the mirror image of the pose, in the armature's space
    S4 = np.diag([-1.0, 1.0, 1.0, 1.0])
    assert np.abs(S4 @ np.array(pl.matrix) @ S4 - np.array(pr.matrix))[:3].max() < 1e-5 * diag
    bpy.ops.object.mode_set(mode='OBJECT')
    P = evaluated(ob)
    moved = np.linalg.norm(P - V, axis=1)
    assert moved[both].max() > 0.2 * diag / 6
    asym = np.linalg.norm(P[mirror_of][both] @ S - P[both], axis=1).max()
    assert asym < 0.05 * moved[both].max(), (asym, moved[both].max())


# -- UI --------------------------------------------------------------------------------------------
def test_bind_panel_and_menu_offer_every_method():
    from curveskel_addon import panel
    from curveskel_addon.ops_bind import METHOD_ITEMS
    from test_panel_and_registration import _draw

    V, F = meshes.bent_capsule()
    ob = mesh_object("L", V, F)
    log = _draw(panel.CURVESKEL_PT_bind, bpy.context)
    assert ("operator", "curveskel.bind") in log and any(e[0] == "label" for e in log)
    assert bpy.ops.curveskel.generate('EXEC_DEFAULT', **FAST) == {'FINISHED'}
    bpy.context.view_layer.objects.active = ob
    log = _draw(panel.CURVESKEL_PT_bind, bpy.context)
    assert {e[2] for e in log if e[0] == "opset" and e[1] == "method"} == {m[0] for m in METHOD_ITEMS}
    assert ("label", "L \u2192 L.skeleton") in log
    draw_funcs = bpy.types.VIEW3D_MT_object._dyn_ui_initialize()
    assert panel._menu_entry in draw_funcs

    class _Menu:
        calls = []

        def operator(self, idname, **kw):
            self.calls.append(idname)

        def operator_menu_enum(self, idname, prop, **kw):
            self.calls.append((idname, prop))

    fake = type("FakeMenu", (), {"layout": _Menu()})()
    panel._menu_entry(fake, bpy.context)
    assert ("curveskel.bind", "method") in _Menu.calls


# -- glTF -------------------------------------------------------------------------------------------
def _glb_json(path):
    return read_glb(Path(path).read_bytes())[0]


def test_glb_passes_the_khronos_validator_and_holds_mesh_and_armature_only(tmp_path):
    M = Matrix.Translation((0.5, 0.0, 1.0)) @ Matrix.Rotation(0.3, 4, 'Z')
    V, sk, ob, arm, _ = rigged("star", matrix=M)
    extra = mesh_object("bystander", *meshes.capsule(length=1.0))    # not exported
    extra.select_set(True)
    path = tmp_path / "star.glb"
    export_rig(bpy.context, ob, arm, path)
    assert ob.parent is arm                                      # as the bind left it
    doc = _glb_json(path)
    assert len(doc["meshes"]) == 1 and len(doc["skins"]) == 1
    assert len(doc["nodes"]) == len(arm.data.bones) + 2            # bones, armature, mesh
    skinned = [n for n in doc["nodes"] if "skin" in n]
    roots = set(doc["scenes"][0]["nodes"])
    assert len(skinned) == 1 and doc["nodes"].index(skinned[0]) in roots   # a root node
    pkg, why = gltf_validator.validator()
    if pkg is None:
        pytest.skip(why)
    issues = gltf_validator.validate(path)["issues"]
    assert issues["numErrors"] == 0 and issues["numWarnings"] == 0, issues["messages"]
    # re-imported (without the importer's own bone-shape helper): the mesh and the armature
    bpy.ops.wm.read_homefile(use_empty=True)
    bpy.ops.import_scene.gltf(filepath=str(path), disable_bone_shape=True)
    assert sorted(o.type for o in bpy.data.objects) == ["ARMATURE", "MESH"]
    me = next(o for o in bpy.data.objects if o.type == 'MESH')
    assert len(me.data.vertices) == len(V)


def test_bind_operator_from_armature_edit_mode_takes_the_edit():
    """Select the mesh, then the armature (active), edit a bone and bind without leaving Edit
    Mode: the operator leaves it and binds to the bones as edited."""
    V, sk, ob, arm, _ = rigged("star")
    leaf, _ = leaf_and_arm_bone(arm, np.array([0.0, -1.0, 0.0]))
    name = leaf.name
    vl = bpy.context.view_layer
    for o in vl.objects:
        o.select_set(False)
    ob.select_set(True)
    arm.select_set(True)
    vl.objects.active = arm
    bpy.ops.object.mode_set(mode='EDIT')
    ebs = arm.data.edit_bones
    ebs.remove(ebs[name])
    extra = ebs.new("fin")
    extra.head, extra.tail = (0.0, 0.0, 0.0), (0.0, 0.0, 0.4)     # inside the centre
    assert bpy.ops.curveskel.bind.poll()
    assert bpy.ops.curveskel.bind(method='SURFACE') == {'FINISHED'}
    assert arm.mode == 'OBJECT'
    check_bound(ob, arm)
    assert name not in groups_of(ob) and "fin" in groups_of(ob)
