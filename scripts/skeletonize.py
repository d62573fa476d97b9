#!/usr/bin/env python3
"""Skeletonize mesh files from the command line.

    python scripts/skeletonize.py MESH [--json OUT.json] [--blend OUT.blend] [--render OUT.png]
                                       [method options]

Reads .obj .ply .stl .off, runs the curveskel core and prints vertices, components, joints,
bones, E0 -> E, iterations and the time of every stage. Errors are reported in one line
(exit status 2) — use --debug for a traceback.
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import fields
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from curveskel_addon.core import SOLVERS, CurveSkelError, SkeletonParams, skeletonize  # noqa: E402
from curveskel_addon.core.mesh_io import read_mesh  # noqa: E402

_HELP = {
    "spacing": "contour spacing as a fraction of each component's bounding-box diagonal "
               "(smaller = more joints; default %(default)s)",
    "solver": "optimiser: 'paper' = gradient descent with exact line search (eqs. 28-31), "
              "'lm' = Levenberg-Marquardt, converges (default %(default)s)",
    "max_iterations": "upper bound on optimiser iterations (default %(default)s)",
    "tolerance": "stop when an iteration lowers E by less than TOLERANCE * E0 (paper: 1e-3; default %(default)s)",
    "seed": "seed of the random first vertex of the pole search (default %(default)s)",
    "area_weighted": "weight vertices by their area: the surface integral of eq. 8 instead of a vertex sum",
    "refit_mapping": "re-fit each vertex's skeleton point between solver steps",
    "prune": "remove leaf branches that explain less than this share of E (0 = keep all; default %(default)s)",
    "simplify": "merge chain joints when E rises by less than this fraction (0 = off; default %(default)s)",
    "candidates": "first approximations tried (poles/spacings); the lowest E wins (default %(default)s)",
    "smoothness": "weight of a term keeping chain joints between their neighbours (lm only; "
                  "0 = off; default %(default)s)",
    "containment": "weight of a term keeping joints and points along the bones inside the mesh "
                   "with their balls (lm only; 0 = off; default %(default)s)",
    "max_fit_points": "above this many vertices fit an area-weighted random subset of this size "
                      "(0 = all; default %(default)s)",
    "refine": "rounds of splitting bones that leave the mesh and re-solving; then outside "
              "joints are pulled in and bones split without a solve (0 = off; default %(default)s)",
    "max_joints": "joint budget of the refinement (default %(default)s)",
}


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(
        prog="skeletonize.py",
        description="Curve-skeleton of a mesh file (curveskel). Prints a summary; writes the "
                    "skeleton as curveskel-skeleton/1 JSON with --json.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="Example: python scripts/skeletonize.py examples/spot.obj --json out/spot.json")
    ap.add_argument("mesh", type=Path, help="mesh file: .obj, .ply, .stl or .off")
    ap.add_argument("--json", type=Path, metavar="OUT.json", help="write the skeleton as JSON")
    ap.add_argument("--paper", action="store_true",
                    help="the paper's method exactly: vertex sum, fixed mapping, gradient descent "
                         "(solver=paper, no area weights, no re-fit, no pruning/simplification)")
    ap.add_argument("--quality", action="store_true",
                    help="compute the quality measures (energy, reconstruction distance, inside "
                         "fraction, topology) and store them in the JSON meta")
    ap.add_argument("--debug", action="store_true", help="show a traceback on errors")
    r = ap.add_argument_group("rigging (needs Blender as a Python module, bpy)")
    r.add_argument("--bind", action="store_true",
                   help="build the armature in Blender and skin the mesh to it (skeleton-mapping weights)")
    r.add_argument("--glb", type=Path, metavar="OUT.glb",
                   help="export the rigged mesh + armature with Blender's glTF exporter (implies --bind)")
    r.add_argument("--fbx", type=Path, metavar="OUT.fbx",
                   help="export the rigged mesh + armature with Blender's FBX exporter (implies --bind)")
    b = ap.add_argument_group("Blender scene (needs Blender as a Python module, bpy)")
    b.add_argument("--blend", type=Path, metavar="OUT.blend",
                   help="import the mesh with Blender's importer, run the add-on's operator and save "
                        "the scene (mesh, armature, silhouette)")
    b.add_argument("--render", type=Path, metavar="OUT.png",
                   help="render a Cycles CPU preview of the mesh with its silhouette and skeleton")
    g = ap.add_argument_group("method parameters")
    defaults = SkeletonParams()
    for f in fields(SkeletonParams):
        flag = "--" + f.name.replace("_", "-")
        val = getattr(defaults, f.name)
        if isinstance(val, bool):
            g.add_argument(flag, dest=f.name, action=argparse.BooleanOptionalAction, default=None,
                           help=_HELP.get(f.name, "") + f" (default {'on' if val else 'off'})")
        elif f.name == "solver":
            g.add_argument(flag, dest=f.name, choices=SOLVERS, default=None, help=_HELP[f.name] % {"default": val})
        else:
            g.add_argument(flag, dest=f.name, type=type(val), default=None,
                           help=_HELP.get(f.name, "") % {"default": val})
    return ap


def params_from_args(args) -> SkeletonParams:
    base = SkeletonParams.paper() if args.paper else SkeletonParams()
    d = base.to_dict()
    for f in fields(SkeletonParams):
        v = getattr(args, f.name, None)
        if v is not None:
            d[f.name] = v
    return SkeletonParams.from_dict(d)


def print_summary(path, V, sk, seconds: float, out=sys.stdout) -> None:
    s = sk.summary()
    info = sk.meta.get("input", {})
    print(f"mesh        {path}: {len(V)} vertices, {info.get('input_faces', '?')} triangles, "
          f"{s['components']} component(s)", file=out)
    repaired = {k: v for k, v in info.items()
                if k in ("merged_duplicates", "degenerate_faces_dropped", "isolated_vertices") and v}
    if repaired:
        print("repaired    " + ", ".join(f"{k.replace('_', ' ')}: {v}" for k, v in repaired.items()), file=out)
    print(f"skeleton    {s['joints']} joints, {s['bones']} bones", file=out)
    print(f"energy      E0 {s['E0']:.6g} -> E {s['E']:.6g} in {s['iterations']} iterations "
          f"(solver {sk.meta.get('params', {}).get('solver', '?')})", file=out)
    stages = " | ".join(f"{k} {v:.3f}" for k, v in sk.timings.items())
    print(f"time (s)    {stages}", file=out)
    print(f"total       {seconds:.3f} s", file=out)
    q = sk.meta.get("quality")
    if q:
        print("quality     " + ", ".join(f"{k} {v:.4g}" if isinstance(v, float) else f"{k} {v}"
                                         for k, v in _flat(q).items()), file=out)


def _flat(d, prefix=""):
    out = {}
    for k, v in d.items():
        if isinstance(v, dict):
            out.update(_flat(v, prefix + k + "."))
        elif isinstance(v, (int, float, str, bool)):
            out[prefix + k] = v
    return out


def run(args) -> int:
    params = params_from_args(args)
    t0 = time.perf_counter()
    V, F = read_mesh(args.mesh)
    sk = skeletonize(V, F, params)
    if args.quality:
        from curveskel_addon.core.quality import quality

        sk.meta["quality"] = quality(V, F, sk)
    seconds = time.perf_counter() - t0
    print_summary(args.mesh, V, sk, seconds)
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        sk.save(args.json)
        print(f"wrote       {args.json}")
    if args.bind or args.glb or args.fbx:
        rig_outputs(args, V, sk)
    if args.blend or args.render:
        blender_outputs(args, params)
    return 0


def blender_outputs(args, params) -> None:
    """--blend/--render: the same operator the Blender UI runs (curveskel_addon.headless)."""
    from curveskel_addon import headless

    out = headless.cli_outputs(args.mesh, params.to_dict(), blend=args.blend, render=args.render,
                               bind=args.bind)
    arm = out["armature"]
    print(f"blender     {arm.name}: {arm['curveskel_n_joints']} joints, {arm['curveskel_n_bones']} bones, "
          f"operator {out['operator_seconds']:.2f} s", flush=True)
    if "blend" in out:
        print(f"wrote       {out['blend']}")
    if "render" in out:
        print(f"wrote       {out['render']} (render {out['render_seconds']:.1f} s)")


def rig_outputs(args, V, sk) -> None:
    """--bind/--glb/--fbx: import the mesh into Blender, armature + binding from ``sk``, export."""
    import numpy as np

    import bpy
    from curveskel_addon import headless
    from curveskel_addon.export import export_rig
    from curveskel_addon.ops_generate import build_result

    headless.reset_scene()
    ob = headless.import_mesh(args.mesh)
    co = np.empty(len(ob.data.vertices) * 3)
    ob.data.vertices.foreach_get("co", co)
    if len(co) != 3 * len(V) or np.abs(co.reshape(-1, 3) - V).max() > 1e-5 * max(float(np.ptp(V)), 1e-12):
        # Blender's importer changed the vertices: bind by closest point on the bones instead.
        from curveskel_addon.core import Skeleton

        sk = Skeleton(sk.joints, sk.bones, [], [], energy=sk.energy, timings=sk.timings, meta=sk.meta)
    options = {**sk.meta.get("params", {}), "make_armature": True, "make_silhouette": False,
               "silhouette_in_render": False, "bind": True}
    found = build_result(bpy.context, ob, sk, options)
    arm = found["armature"]
    print(f"rig         {len(arm.data.bones)} bones, {len(ob.vertex_groups)} vertex groups", flush=True)
    for path in (args.glb, args.fbx):
        if path is not None:
            out = export_rig(bpy.context, ob, arm, path)
            print(f"wrote       {out['path']} ({out['format']}, {out['seconds']:.2f} s)")


def main(argv=None) -> int:
    ap = build_parser()
    args = ap.parse_args(argv)
    try:
        return run(args)
    except CurveSkelError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    except Exception as exc:  # never a raw traceback for users; --debug shows it
        if args.debug:
            raise
        print(f"error: unexpected {type(exc).__name__}: {exc} (run with --debug for details)", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
