"""Rigging quality and bind time per mesh (issue 14): weight bleeding between chains, flipped
triangles under a pose, bind time of the surface weights next to Blender's heat weights.

    .venv/bin/python scripts/bench_rigging.py [MESH ...] [--methods SURFACE HEAT] [--json OUT]

Default meshes: every mesh in ../shared/meshes (or $CURVESKEL_SHARED_MESHES). For each: skeletonize (default parameters), build
the armature (mirror names), bind with each method, then for every chain C of the armature
(a run of connected bones, each the only child of the previous one):

- pose C: its first bone turns 45 degrees about its own x axis (about its head); C's descendants
  follow, as in Blender. Deformed positions are the Armature modifier's linear blend skinning,
  computed from the weights read back from the vertex groups: v' = v + w_sub(v) (T v - v), with
  w_sub the vertex's weight on C and its descendants;
- *bleed*: the largest displacement of vertices mostly weighted to other chains (w_sub < 0.5),
  as a fraction of the bounding-box diagonal; the worst chain is reported;
- *flipped*: triangles whose normal turns by more than 90 degrees under that pose (worst chain);
- *non-adjacent*: vertices with more than 0.1 weight on each of two chains that are not adjacent
  (adjacent: one starts at the other's end, or both start at the same bone);
- first-bind seconds (the figure that counts): ``bind_mesh`` wall time (weights computed and
  written) of a FIRST bind: each of ``--repeat`` binds per method binds a fresh copy of the mesh
  (its own mesh data, no vertex groups, no modifier) to a fresh copy of the armature (its own
  armature data), so nothing from an earlier bind can be reused; fastest and median reported;
- re-bind seconds: the fastest of ``--repeat`` re-binds of one mesh object to one armature (the
  groups of the previous bind removed first), as the bench measured before;
- in both, the methods take turns (surface, heat, surface, ...), so a burst of load on the shared
  machine hits both alike.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
os.environ.setdefault("BLENDER_USER_RESOURCES", tempfile.mkdtemp(prefix="curveskel-bench-"))

import numpy as np  # noqa: E402

SHARED = Path(os.environ.get("CURVESKEL_SHARED_MESHES", ROOT.parent / "shared" / "meshes"))
MESHES = ["octopus.off", "spot.obj", "hand.off", "3holes.off", "fertility.off", "elephant.obj",
          "homer.obj", "rocker-arm.obj", "armadillo.obj", "horse.off"]


def chains_of(arm):
    """(chain of each bone (R,), first bone of each chain, parent chain of each chain, names)."""
    bones = list(arm.data.bones)
    index = {b.name: k for k, b in enumerate(bones)}
    chain = np.full(len(bones), -1, np.int64)
    first = []
    for k, b in enumerate(bones):                 # parents come before children in data.bones
        p = b.parent
        if p is not None and len(p.children) == 1 and b.use_connect:
            chain[k] = chain[index[p.name]]
        else:
            chain[k] = len(first)
            first.append(k)
    parent_chain = np.array([chain[index[bones[f].parent.name]] if bones[f].parent is not None else -1
                             for f in first], np.int64)
    parent_bone = np.array([index[bones[f].parent.name] if bones[f].parent is not None else -1
                            for f in first], np.int64)
    return chain, np.array(first), parent_chain, parent_bone, [b.name for b in bones]


def weight_matrix(ob, names):
    """(n, len(names)) weights of the vertex groups named like the bones."""
    col = {}
    for k, nm in enumerate(names):
        vg = ob.vertex_groups.get(nm)
        if vg is not None:
            col[vg.index] = k
    n = len(ob.data.vertices)
    rows, cols, vals = [], [], []
    for v in ob.data.vertices:
        for g in v.groups:
            c = col.get(g.group)
            if c is not None and g.weight > 0:
                rows.append(v.index)
                cols.append(c)
                vals.append(g.weight)
    W = np.zeros((n, len(names)))
    np.add.at(W, (np.array(rows, np.int64), np.array(cols, np.int64)), np.array(vals))
    s = W.sum(axis=1, keepdims=True)
    return np.divide(W, s, out=np.zeros_like(W), where=s > 0)     # the modifier normalises


def measure(V, F, arm, W):
    """Bleed, flipped triangles and non-adjacent overlaps of weights W (n, R) on armature ``arm``
    (V in the armature's space)."""
    chain, first, parent_chain, parent_bone, names = chains_of(arm)
    C = len(first)
    R = len(names)
    Wc = np.zeros((len(V), C))
    for r in range(R):
        Wc[:, chain[r]] += W[:, r]
    # chain adjacency
    adj = np.eye(C, dtype=bool)
    for c in range(C):
        p = parent_chain[c]
        if p >= 0:
            adj[c, p] = adj[p, c] = True
        for d in range(C):
            if d != c and parent_bone[c] >= 0 and parent_bone[c] == parent_bone[d]:
                adj[c, d] = True
    big = Wc > 0.1
    non_adj = 0
    if C > 1:
        pairs = big[:, :, None] & big[:, None, :] & ~adj[None]
        non_adj = int(pairs.any(axis=(1, 2)).sum())
    children = [[] for _ in range(C)]
    for c in range(C):
        if parent_chain[c] >= 0:
            children[parent_chain[c]].append(c)
    diag = float(np.linalg.norm(np.ptp(V, axis=0)))
    n0 = np.cross(V[F[:, 1]] - V[F[:, 0]], V[F[:, 2]] - V[F[:, 0]])
    worst = {"bleed": 0.0, "bleed_chain": None, "flipped": 0, "flipped_chain": None}
    for c in range(C):
        b = arm.data.bones[names[first[c]]]
        if b.parent is None and len(b.children) > 1:
            continue                          # the root bone: posing it moves everything
        sub, stack = [], [c]
        while stack:
            x = stack.pop()
            sub.append(x)
            stack += children[x]
        w = Wc[:, sub].sum(axis=1)
        M = np.array(b.matrix_local)          # bone frame in armature space, origin at the head
        x_axis = M[:3, 0] / np.linalg.norm(M[:3, 0])
        a = np.radians(45.0)
        K = np.array([[0, -x_axis[2], x_axis[1]], [x_axis[2], 0, -x_axis[0]], [-x_axis[1], x_axis[0], 0]])
        Rm = np.eye(3) + np.sin(a) * K + (1 - np.cos(a)) * K @ K
        h = np.array(b.head_local)
        moved = (V - h) @ Rm.T + h
        P = V + w[:, None] * (moved - V)
        d = np.linalg.norm(P - V, axis=1)
        others = w < 0.5
        bleed = float(d[others].max() / diag) if others.any() else 0.0
        n1 = np.cross(P[F[:, 1]] - P[F[:, 0]], P[F[:, 2]] - P[F[:, 0]])
        flipped = int(np.sum(np.einsum("ij,ij->i", n0, n1) < 0))
        if bleed > worst["bleed"]:
            worst["bleed"], worst["bleed_chain"] = bleed, names[first[c]]
        if flipped > worst["flipped"]:
            worst["flipped"], worst["flipped_chain"] = flipped, names[first[c]]
    return {**worst, "non_adjacent": non_adj, "chains": C}


def first_bind(ob, arm, method, bind_options):
    """Seconds of ``bind_mesh`` binding a fresh copy of ``ob`` (own mesh data; ``ob`` must be
    unbound) to a fresh copy of ``arm`` (own armature data); the copies are removed after."""
    import bpy

    from curveskel_addon.binding import bind_mesh

    coll = bpy.context.scene.collection
    ob2, arm2 = ob.copy(), arm.copy()
    ob2.data, arm2.data = ob.data.copy(), arm.data.copy()
    coll.objects.link(ob2)
    coll.objects.link(arm2)
    try:
        fig = bind_mesh(ob2, arm2, method=method, **(bind_options if method == "SURFACE" else {}))
    finally:
        me, ad = ob2.data, arm2.data
        bpy.data.objects.remove(ob2)
        bpy.data.objects.remove(arm2)
        bpy.data.meshes.remove(me)
        bpy.data.armatures.remove(ad)
    return fig["seconds"]


def run_mesh(path, methods, skeleton_dir=None, bind_options=None, repeat=3):
    import bpy

    from curveskel_addon import headless
    from curveskel_addon.armature import build_armature
    from curveskel_addon.binding import bind_mesh, unbind_mesh
    from curveskel_addon.core import Skeleton, skeletonize
    from curveskel_addon.mesh_files import read_mesh

    V, F = read_mesh(str(path))
    V = np.asarray(V, np.float64)
    F = np.asarray(F, np.int64)
    t0 = time.perf_counter()
    cache = Path(skeleton_dir) / (Path(path).stem + ".json") if skeleton_dir else None
    if cache is not None and cache.is_file():
        sk = Skeleton.load(str(cache))
    else:
        sk = skeletonize(V, F)
        if cache is not None:
            cache.parent.mkdir(parents=True, exist_ok=True)
            sk.save(str(cache))
    t_sk = time.perf_counter() - t0
    headless.reset_scene()
    from curveskel_addon.headless import mesh_object_from_arrays

    ob = mesh_object_from_arrays(Path(path).stem, V, F)
    t0 = time.perf_counter()
    arm = build_armature(bpy.context, sk, ob.name + ".skeleton", bpy.context.scene.collection,
                         ob.matrix_world, vertices=V)
    t_arm = time.perf_counter() - t0
    names = [b.name for b in arm.data.bones]
    out = {"mesh": Path(path).name, "vertices": len(V), "bones": len(names),
           "pairs": sum(".L." in nm or nm.endswith(".L") for nm in names),
           "mirror": "curveskel_mirror" in arm, "skeleton_seconds": round(t_sk, 2),
           "armature_seconds": round(t_arm, 3)}
    first = {m: [] for m in methods}
    for _ in range(max(repeat, 1)):               # first binds of fresh copies, taking turns
        for method in methods:
            first[method].append(first_bind(ob, arm, method, bind_options))
    figs = {}
    for _ in range(max(repeat, 1)):               # fastest of ``repeat`` re-binds of ``ob``;
        for method in methods:                    # the methods take turns, so load hits both alike
            unbind_mesh(ob)
            for vg in list(ob.vertex_groups):
                ob.vertex_groups.remove(vg)
            fig = bind_mesh(ob, arm, method=method, **(bind_options if method == "SURFACE" else {}))
            if method not in figs or fig["seconds"] < figs[method]["seconds"]:
                figs[method] = fig
    for method in methods:
        unbind_mesh(ob)
        for vg in list(ob.vertex_groups):
            ob.vertex_groups.remove(vg)
        bind_mesh(ob, arm, method=method, **(bind_options if method == "SURFACE" else {}))
        fig = figs[method]
        W = weight_matrix(ob, names)
        m = measure(V, F, arm, W)
        m["seconds"] = round(fig["seconds"], 4)
        m["first_seconds"] = round(min(first[method]), 4)
        m["first_median_seconds"] = round(float(np.median(first[method])), 4)
        # the fastest bind's parts: weights computed (arrays read, core), vertex groups written
        for key in ("mapping_seconds", "weights_seconds"):
            if key in fig:
                m[key] = round(fig[key], 4)
        m["unweighted"] = fig["unweighted"]
        out[method] = m
        print(f"  {method:7s} first bind {m['first_seconds']:7.4f} s "
              f"(median {m['first_median_seconds']:.4f}), re-bind {fig['seconds']:7.4f} s  "
              f"bleed {m['bleed']:.4f} ({m['bleed_chain']})  "
              f"flipped {m['flipped']} ({m['flipped_chain']})  non-adjacent {m['non_adjacent']}  "
              f"unweighted {fig['unweighted']}", flush=True)
    return out


def table(rows, methods) -> str:
    head = ["mesh", "V", "bones", ".L bones"]
    for m in methods:
        head += [f"{m.lower()} first bind s", f"{m.lower()} re-bind s", f"{m.lower()} bleed",
                 f"{m.lower()} flipped", f"{m.lower()} non-adj."]
    ratio = "SURFACE" in methods and "HEAT" in methods
    if ratio:
        head += ["heat / surface first bind", "heat / surface re-bind"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in rows:
        cells = [r["mesh"], f"{r['vertices']:,}", str(r["bones"]), str(r["pairs"])]
        for m in methods:
            x = r.get(m)
            cells += ([f"{x['first_seconds']:.4f}", f"{x['seconds']:.4f}",
                       f"{100 * x['bleed']:.2f} %", str(x["flipped"]), str(x["non_adjacent"])]
                      if x else ["-"] * 5)
        if ratio:
            s, h = r.get("SURFACE"), r.get("HEAT")
            for key in ("first_seconds", "seconds"):
                cells.append(f"{h[key] / s[key]:.1f}x" if s and h and s[key] > 0 else "-")
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("meshes", nargs="*", help="mesh files (default: every shared mesh)")
    ap.add_argument("--methods", nargs="+", default=["SURFACE", "HEAT"], choices=["SURFACE", "HEAT"])
    ap.add_argument("--json", help="write the figures here")
    ap.add_argument("--skeleton-dir", help="reuse / store each mesh's skeleton as JSON here")
    ap.add_argument("--blend", type=float, default=0.25, help="bind blend width (SURFACE)")
    ap.add_argument("--smooth", type=float, default=0.5, help="bind surface smoothing (SURFACE)")
    ap.add_argument("--junction-blend", type=float, default=0.0, help="blend where chains leave a junction (SURFACE)")
    ap.add_argument("--repeat", type=int, default=3,
                    help="first binds (of fresh copies) and re-binds per method; the fastest "
                         "is reported")
    args = ap.parse_args(argv)
    from curveskel_addon import headless

    headless.ensure_registered()
    paths = args.meshes or [str(SHARED / m) for m in MESHES]
    rows = []
    for p in paths:
        print(Path(p).name, flush=True)
        rows.append(run_mesh(p, args.methods, args.skeleton_dir,
                             {"blend": args.blend, "smooth": args.smooth,
                              "junction_blend": args.junction_blend}, args.repeat))
        if args.json:
            Path(args.json).write_text(json.dumps(rows, indent=1))
    print()
    print(table(rows, args.methods))
    return 0


if __name__ == "__main__":
    sys.exit(main())
