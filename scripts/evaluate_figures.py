#!/usr/bin/env python
"""Issue 33's figures: outside skeletons evaluated and refined.

Usage (from the repository root, with the project's venv):

    .venv/bin/python scripts/evaluate_figures.py --cgal       # CGAL's skeletons of the shared
                                                              # meshes + the metarig on the human
    .venv/bin/python scripts/evaluate_figures.py --heatmap    # docs/figures/hand_missing_finger.png

``--cgal`` refines CGAL's reference curve skeleton of every shared mesh with the default
parameters (its graph kept), and Rigify's Basic Human metarig placed on the held-out human
(``tests/outside_skeletons.py``); it prints J, E, the inside fraction and issue 10's shape measures against
the reference before and after, and writes them to ``.bench/evaluate_cgal.json`` and the
``evaluate-cgal`` section of ``docs/benchmarks.md``. ``--heatmap`` builds the hand with CGAL's
skeleton minus one finger as an armature in Blender (bpy), runs *Evaluate Skeleton* on it and
renders the heat map with Cycles.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "scripts"))
sys.path.insert(0, str(ROOT / "tests"))

from bench import OUT, REAL, REFERENCE, SHARED, SHAPE_TARGETS, env_line, md_table, stem, write_section  # noqa: E402

FIGURE = ROOT / "docs" / "figures" / "hand_missing_finger.png"


def _shape(V, F, joints, bones, ref):
    from curveskel_addon.measure.quality import shape_measures

    m = shape_measures(V, F, (np.asarray(joints), np.asarray(bones)), ref)
    return {k: m[k] for k in ("zigzag", "folds", "length_ratio", "to_ref_mean", "from_ref_mean")}


def _held(m) -> list:
    T = SHAPE_TARGETS
    lo, hi = T["length"]
    ok = {"zigzag": m["zigzag"] <= T["zigzag"], "folds": m["folds"] <= T["folds"],
          "length": lo <= m["length_ratio"] <= hi, "to_ref": m["to_ref_mean"] <= T["to_ref"],
          "from_ref": m["from_ref_mean"] <= T["from_ref"]}
    return [k for k, v in ok.items() if v]


def run_cgal(args) -> None:
    from curveskel_addon.core import load_outside_skeleton, refine
    from curveskel_addon.mesh_files import read_mesh
    from curveskel_addon.rig.armature_segments import armature_segments
    from outside_skeletons import load_metarig, obj_to_blender, place_metarig

    rows, out = [], []
    for spec in args.meshes or REAL:
        V, F = read_mesh(SHARED / spec)
        ref = REFERENCE / f"{stem(spec)}.json"
        sk = load_outside_skeleton(ref)
        t0, c0 = time.perf_counter(), time.process_time()
        res = refine(V, F, sk)
        secs, cpu = time.perf_counter() - t0, time.process_time() - c0
        sb, sa = _shape(V, F, sk.joints, sk.bones, ref), _shape(V, F, res.skeleton.joints,
                                                                 res.skeleton.bones, ref)
        lost = sorted(set(_held(sb)) - set(_held(sa)))
        r = {"mesh": stem(spec), "joints": sk.n_joints, "J_before": res.before.J,
             "J_after": res.after.J, "E_before": res.before.E, "E_after": res.after.E,
             "inside_before": res.before.inside_fraction,
             "inside_after": res.after.inside_fraction, "iterations": res.iterations,
             "topology": res.after.topology["match"], "shape_before": sb, "shape_after": sa,
             "targets_lost": lost, "seconds": secs, "cpu_seconds": cpu}
        out.append(r)
        print(f"{r['mesh']}: J {r['J_before']:.4g} -> {r['J_after']:.4g}, inside "
              f"{r['inside_before']:.3f} -> {r['inside_after']:.3f}, lost {lost}, {cpu:.1f} s CPU",
              flush=True)
        rows.append([r["mesh"], r["joints"], f"{r['J_before']:.4g} → {r['J_after']:.4g}",
                     f"{r['E_before']:.3g} → {r['E_after']:.3g}",
                     f"{r['inside_before']:.3f} → {r['inside_after']:.3f}", r["iterations"],
                     "yes" if r["topology"] else "**no**",
                     f"{sa['to_ref_mean']:.4f} / {sa['from_ref_mean']:.4f}",
                     f"{sa['length_ratio']:.3f}", f"{sb['zigzag']:.3f} → {sa['zigzag']:.3f}",
                     f"{sb['folds']:.3f} → {sa['folds']:.3f}",
                     ", ".join(f"**{k}**" for k in lost) or "none", f"{cpu:.1f}"])
    # the metarig on the held-out human (joints only: radii fitted)
    V, F = read_mesh(ROOT / "tests" / "data" / "heldout" / "human.obj")
    Vw = obj_to_blender(V)
    names, parent, connected, H, T = load_metarig()
    scale, offset, H, T = place_metarig(names, parent, H, T, Vw)
    seg = armature_segments(scale * H + offset, scale * T + offset, parent, connected)
    t0, c0 = time.perf_counter(), time.process_time()
    res = refine(Vw, F, (seg.joints, seg.segments))
    cpu = time.process_time() - c0
    out.append({"mesh": "human + Rigify Basic Human metarig", "joints": len(seg.joints),
                "J_before": res.before.J, "J_after": res.after.J,
                "inside_before": res.before.inside_fraction,
                "inside_after": res.after.inside_fraction, "iterations": res.iterations,
                "cpu_seconds": cpu})
    rows.append(["human + metarig", len(seg.joints), f"{res.before.J:.4g} → {res.after.J:.4g}",
                 f"{res.before.E:.3g} → {res.after.E:.3g}",
                 f"{res.before.inside_fraction:.3f} → {res.after.inside_fraction:.3f}",
                 res.iterations, "yes" if res.after.topology["match"] else "**no**",
                 "–", "–", "–", "–", "–", f"{cpu:.1f}"])
    print(f"metarig: J {res.before.J:.4g} -> {res.after.J:.4g}, inside "
          f"{res.before.inside_fraction:.3f} -> {res.after.inside_fraction:.3f}")
    header = ["skeleton", "joints", "J before → after", "E before → after",
              "inside before → after", "steps", "topology", "to / from ref after",
              "length ratio after", "zigzag", "folds", "targets lost", "refine CPU s"]
    table = md_table(header, rows)
    print("\n" + table)
    if not args.no_write:
        OUT.mkdir(exist_ok=True)
        (OUT / "evaluate_cgal.json").write_text(json.dumps({"env": env_line(), "results": out},
                                                           indent=1))
        write_section("evaluate-cgal", f"""## Outside skeletons refined (issue 33)

Command: `.venv/bin/python scripts/evaluate_figures.py --cgal` — {env_line()}.

CGAL's reference curve skeleton of each shared mesh (`../shared/reference`, radii as given:
CGAL's estimates) refined by `core.refine` with the default parameters, its graph kept; and
Rigify's Basic Human metarig placed on the T-posed held-out human (`tests/outside_skeletons.py`: scaled to
its height, moved onto its hips, arms raised), radii fitted. J before and after are values of
one function (its unit of length at each surface sample is the sample's distance from the
skeleton as given). Shape measures against the same reference (issue 10's targets): *targets
lost* lists those that held before and fail after.

{table}
""")


# -- the heat map picture ----------------------------------------------------------------------
def _armature_from_segments(name, joints, bones, root):
    """A Blender armature with one bone per segment, parents towards ``root`` (connected)."""
    import bpy

    nbrs = [[] for _ in range(len(joints))]
    for b, (i, j) in enumerate(bones.tolist()):
        nbrs[i].append((j, b))
        nbrs[j].append((i, b))
    arm = bpy.data.armatures.new(name)
    ob = bpy.data.objects.new(name, arm)
    bpy.context.scene.collection.objects.link(ob)
    bpy.context.view_layer.objects.active = ob
    bpy.ops.object.mode_set(mode='EDIT')
    made = {}
    todo = [(root, None)]
    seen = {root}
    while todo:                                   # breadth first from the root
        v, parent = todo.pop(0)
        for w, b in nbrs[v]:
            if w in seen:
                continue
            seen.add(w)
            eb = arm.edit_bones.new(f"bone.{b:03d}")
            eb.head, eb.tail = joints[v], joints[w]
            if parent is not None:
                eb.parent = parent
                eb.use_connect = True
            made[b] = eb
            todo.append((w, eb))
    bpy.ops.object.mode_set(mode='OBJECT')
    return ob


def _face_on(cam, V, scene) -> None:
    """The camera looking at the hand's palm (along its thinnest principal axis, from the side
    it points to), its longest axis across the picture,
    tilted 20 degrees so that the fingers' sides show; moved back until all of it is in frame."""
    from mathutils import Matrix

    from curveskel_addon import framing

    P = np.asarray(V, float)
    _, _, Vt = np.linalg.svd(P - P.mean(0), full_matrices=False)
    x, z = Vt[0], Vt[2]                      # longest axis across, thinnest towards the camera
    if z[2] < 0:
        z = -z
    y = np.cross(z, x)
    R = np.array(Matrix.Rotation(np.radians(20.0), 3, x.tolist()) @ Matrix(np.c_[x, y, z].tolist()))
    cam.rotation_euler = Matrix(R.tolist()).to_euler()
    tan_x, tan_y = framing.half_fov(cam.data.lens, cam.data.sensor_width,
                                    scene.render.resolution_x, scene.render.resolution_y)
    fit = framing.fit_camera(P, np.array(cam.rotation_euler.to_matrix()), tan_x, tan_y)
    cam.location = fit.location.tolist()
    cam.data.clip_start, cam.data.clip_end = fit.clip_start, fit.clip_end


def run_heatmap(args) -> None:
    """Two hands side by side, each coloured by *Evaluate Skeleton*'s heat map: left, CGAL's
    whole skeleton of the hand; right, the same skeleton without one finger (radii fitted by J
    for both: joints only, as an armature has). What is red on both (the flat palm's edges,
    which round radii cannot follow) is the skeleton's own misfit; the finger is red only where
    its bones are missing."""
    import bpy

    from curveskel_addon import headless
    from curveskel_addon.measure.evaluation import HEAT_RANGE
    from curveskel_addon.ops_evaluate import FIT_ATTRIBUTE, stored_report
    from outside_skeletons import hand_without_a_finger

    V, F, (J, B), (Jw, Bw), finger = hand_without_a_finger()
    headless.reset_scene()
    headless.ensure_registered()
    P = np.asarray(V, float)
    _, _, Vt = np.linalg.svd(P - P.mean(0), full_matrices=False)
    shift = 1.1 * np.ptp(P @ Vt[0]) * Vt[0]          # along the hand's longest axis
    mat = bpy.data.materials.new("heat map")
    if bpy.app.version < (5, 0, 0):
        mat.use_nodes = True
    nodes, links = mat.node_tree.nodes, mat.node_tree.links
    bsdf = next(n for n in nodes if n.type == 'BSDF_PRINCIPLED')
    attr = nodes.new('ShaderNodeVertexColor')
    attr.layer_name = FIT_ATTRIBUTE
    links.new(attr.outputs["Color"], bsdf.inputs["Base Color"])
    links.new(attr.outputs["Color"], bsdf.inputs["Emission Color"])
    bsdf.inputs["Emission Strength"].default_value = 0.35
    meshes, everything = [], []
    for label, (Jk, Bk), off in (("whole", (Jw, Bw), -0.5 * shift),
                                 ("without a finger", (J, B), 0.5 * shift)):
        mesh = headless.mesh_object_from_arrays(f"hand ({label})", P + off, F)
        arm = _armature_from_segments(f"hand.rig ({label})", Jk + off, Bk,
                                      root=int(np.argmin(Jk[:, 1])))
        bpy.context.view_layer.objects.active = mesh
        bpy.ops.curveskel.evaluate(armature=arm.name)
        rep = stored_report(mesh)
        res = np.array([a.value for a in mesh.data.attributes["curveskel_residual"].data])
        red = np.abs(res) >= HEAT_RANGE * rep["D"]
        print(f"hand, {label}: J {rep['J']:.4g}, inside {rep['inside_fraction']:.3f}, full red "
              f"(|residual| >= {HEAT_RANGE} D) on the finger {red[finger].mean():.2f}, "
              f"elsewhere {red[~finger].mean():.2f}")
        mesh.data.materials.append(mat)
        meshes.append(mesh)
        everything.append(P + off)
    for ob in bpy.data.objects:           # the armatures and their silhouettes: not in the picture
        if ob not in meshes:
            ob.hide_render = True
    scene = bpy.context.scene
    coll = bpy.data.collections.new("picture")
    scene.collection.children.link(coll)
    headless._setup_render(scene, FIGURE, (1400, 620), 16)
    scene.cycles.max_bounces = 2
    cam, _ = headless._camera(coll, meshes[0])
    _face_on(cam, np.concatenate(everything), scene)
    headless._lights(coll)
    FIGURE.parent.mkdir(parents=True, exist_ok=True)
    bpy.ops.render.render(write_still=True)
    print(f"wrote {FIGURE.relative_to(ROOT)}")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cgal", action="store_true", help="refine CGAL's skeletons and the metarig")
    ap.add_argument("--heatmap", action="store_true", help="render the hand's heat map")
    ap.add_argument("--meshes", nargs="+", help="--cgal: subset of the shared meshes")
    ap.add_argument("--no-write", action="store_true", help="print only")
    args = ap.parse_args(argv)
    if args.cgal:
        run_cgal(args)
    if args.heatmap:
        run_heatmap(args)
    if not (args.cgal or args.heatmap):
        ap.print_help()


if __name__ == "__main__":
    main()
