#!/usr/bin/env python
"""Benchmarks of curveskel: speed (issue 2) and quality against peers (issue 5).

Usage (from the repository root, with the project's venv):

    .venv/bin/python scripts/bench.py                 # speed: every shared mesh + 100k / 1M procedural
    .venv/bin/python scripts/bench.py --quality       # quality: curveskel default + paper + peers
                                                      # (+ issue 10's shape measures, skeletons.png)
    .venv/bin/python scripts/bench.py --figures       # only docs/figures/skeletons.png
    .venv/bin/python scripts/bench.py --batch         # batch throughput: 1 and 2 workers, Dask
    .venv/bin/python scripts/bench.py --evaluate      # evaluate / refine outside skeletons (issue 33)

Each measurement runs in a fresh subprocess (one per mesh, or per mesh and method), so the peak
resident memory (``ru_maxrss``) is that run's own and a crash or timeout of one peer does not stop
the rest. Prints a table, writes raw figures as JSON under ``.bench/`` and replaces its own section
of ``docs/benchmarks.md`` (between ``<!-- bench:speed -->`` / ``<!-- bench:quality -->`` markers).
Never asserted in tests: figures depend on the machine.

Peers (``--quality``) are optional: ``pip install -r requirements-bench.txt`` into the same venv.
A missing peer is reported and skipped.
"""

from __future__ import annotations

import argparse
import datetime as _dt
import json
import os
import platform
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: Shared data (meshes, reference skeletons); CURVESKEL_SHARED overrides (e.g. for a copy of the
#: repository checked out elsewhere).
SHARED_DIR = Path(os.environ.get("CURVESKEL_SHARED", ROOT.parent / "shared"))
SHARED = SHARED_DIR / "meshes"
DOC = ROOT / "docs" / "benchmarks.md"
OUT = ROOT / ".bench"
sys.path.insert(0, str(ROOT))

REAL = ["armadillo.obj", "horse.off", "elephant.obj", "hand.off", "homer.obj", "spot.obj",
        "octopus.off", "rocker-arm.obj", "3holes.off", "fertility.off"]
#: procedural meshes: name -> (generator in tests.meshes, kwargs)
PROCEDURAL = {
    "capsule-100k": ("capsule", dict(n_around=256, n_body=380, cap_rings=8)),
    "torus-100k": ("torus", dict(n_major=400, n_minor=250)),
    "capsule-1M": ("capsule", dict(n_around=1024, n_body=970, cap_rings=8)),
    "torus-1M": ("torus", dict(n_major=2000, n_minor=500)),
    "star-87k": ("star", dict(n_around=128, rings=180)),
}
#: CGAL (mean curvature flow skeleton) reference figures: recon_mean, inside, joints.
CGAL = {
    "armadillo": (0.0048, 1.00, 655), "horse": (0.0058, 1.00, 498), "elephant": (0.0233, 0.99, 312),
    "hand": (0.0147, 1.00, 267), "homer": (0.0113, 1.00, 265), "spot": (0.0206, 1.00, 218),
    "octopus": (0.0688, 0.35, 118), "rocker-arm": (0.0343, 0.89, 216), "3holes": (0.0240, 1.00, 258),
    "fertility": (0.0174, 0.99, 390),
}
METHODS = ["curveskel", "curveskel-paper", "curveskel-initial", "skeletor-wavefront",
           "skeletor-clusters", "pygel-msls"]
PEER_PACKAGES = {"skeletor-wavefront": "skeletor", "skeletor-clusters": "skeletor",
                 "pygel-msls": "pygel3d"}
TARGETS = {"inside": 0.98, "joints": 300, "recon_ratio_mean": 0.7}
#: Reference curve skeletons of the shared meshes (issue 10): ../shared/reference/<stem>.json
REFERENCE = SHARED_DIR / "reference"
#: Issue 10's targets (per mesh unless named *_mean / *_median; distances / D).
SHAPE_TARGETS = {"topology": "exact", "inside": 0.98, "joints": 150, "recon_ratio": 1.25,
                 "recon_ratio_mean": 0.8, "zigzag": 0.15, "folds": 0.0, "length": (0.85, 1.25),
                 "to_ref": 0.02, "to_ref_median": 0.012, "from_ref": 0.025}


def shape_marks(r: dict) -> dict:
    """Whether one mesh's row meets each per-mesh target of issue 10 (name -> bool).

    ``r`` holds ``joints, topology_match, inside, zigzag, folds, length_ratio, to_ref_mean,
    from_ref_mean`` and ``recon_ratio`` (or ``recon_mean`` and ``mesh``, for CGAL's figure).
    """
    T = SHAPE_TARGETS
    ratio = r.get("recon_ratio")
    if ratio is None and "recon_mean" in r:
        cg = CGAL.get(stem(str(r.get("mesh", ""))))
        ratio = r["recon_mean"] / cg[0] if cg else None
    lo, hi = T["length"]
    return {"joints": r["joints"] <= T["joints"], "topology": bool(r["topology_match"]),
            "inside": r["inside"] >= T["inside"],
            "recon": ratio is None or ratio <= T["recon_ratio"],
            "zigzag": r["zigzag"] <= T["zigzag"], "folds": r["folds"] <= T["folds"],
            "length": lo <= r["length_ratio"] <= hi, "to_ref": r["to_ref_mean"] <= T["to_ref"],
            "from_ref": r["from_ref_mean"] <= T["from_ref"]}


# ---------------------------------------------------------------------------------------------
# helpers shared by parent and workers
# ---------------------------------------------------------------------------------------------
def load_mesh(spec: str, folder: Path | None = None):
    """(V, F, seconds) of a shared mesh file name (or one in ``folder``) or a procedural mesh
    name."""
    import numpy as np

    t0 = time.perf_counter()
    if spec in PROCEDURAL:
        from tests import meshes

        gen, kw = PROCEDURAL[spec]
        V, F = getattr(meshes, gen)(**kw)
    else:
        import trimesh

        m = trimesh.load(str((folder or SHARED) / spec), process=False, force="mesh",
                         maintain_order=True)
        V, F = np.asarray(m.vertices, np.float64), np.asarray(m.faces, np.int64)
    return V, F, time.perf_counter() - t0


def maxrss_mb() -> float:
    """Peak resident set size of this process so far, MiB (Linux reports KiB)."""
    r = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return r / 1024.0 if sys.platform != "darwin" else r / 2 ** 20


def rss_now_mb() -> float:
    """Current resident set size, MiB (Linux /proc; the peak elsewhere)."""
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    except OSError:
        pass
    return maxrss_mb()


def stem(spec: str) -> str:
    if spec in PROCEDURAL or "." not in spec:
        return spec
    return spec.rsplit(".", 1)[0]


# ---------------------------------------------------------------------------------------------
# workers (run in a subprocess; print one JSON line)
# ---------------------------------------------------------------------------------------------
def _dijkstra_graph(V, F):
    """(seconds to clean, seconds to build, the edge-length graph) of a mesh: the baselines'."""
    from curveskel_addon.core.geometry.mesh_graph import adjacency, edge_lengths, unique_edges
    from curveskel_addon.core.mesh_input import clean_mesh

    t0 = time.perf_counter()
    cm = clean_mesh(V, F)
    t_clean = time.perf_counter() - t0
    t0 = time.perf_counter()
    E = unique_edges(cm.F)
    A = adjacency(len(cm.V), E, edge_lengths(cm.V, E))
    return t_clean, time.perf_counter() - t0, A


def _fastest_dijkstra(A, repeat: int) -> float:
    from scipy.sparse.csgraph import dijkstra

    best = float("inf")
    for _ in range(max(repeat, 1)):
        t0 = time.perf_counter()
        dijkstra(A, directed=False, indices=0)
        best = min(best, time.perf_counter() - t0)
    return best


def worker_dijkstra(spec: str, repeat: int = 1) -> dict:
    """The Dijkstra baseline alone, in a process of its own (its time settles per process)."""
    V, F, _ = load_mesh(spec)
    return {"mesh": spec, "dijkstra_s": _fastest_dijkstra(_dijkstra_graph(V, F)[2], repeat)}


def worker_speed(spec: str, repeat: int = 1) -> dict:
    from curveskel_addon.core import skeletonize
    from curveskel_addon.run_summary import summary

    V, F, t_load = load_mesh(spec)
    import gc

    gc.collect()
    rss_loaded = rss_now_mb()
    t0 = time.perf_counter()
    sk = skeletonize(V, F)
    t_total = time.perf_counter() - t0
    rss_peak = maxrss_mb()
    # repeats (same process, after the memory peak was read): the minimum is the least disturbed
    # by other load on the machine
    all_runs = [(t_total, dict(sk.timings))]
    for _ in range(repeat - 1):
        t0 = time.perf_counter()
        sk2 = skeletonize(V, F)
        all_runs.append((time.perf_counter() - t0, dict(sk2.timings)))
        del sk2
    t_total, timings = min(all_runs, key=lambda x: x[0])
    # baselines, measured in this run on this mesh (after skeletonize: they do not lift its peak)
    t_clean, t_graph, A = _dijkstra_graph(V, F)
    t_dijkstra = _fastest_dijkstra(A, repeat)      # the fastest of as many runs as skeletonize had
    del A
    res = {"mesh": spec, "V": int(len(V)), "F": int(len(F)), "seconds": t_total,
           "all_seconds": [x[0] for x in all_runs], "stages": timings, "joints": sk.n_joints, "bones": sk.n_bones,
           "iterations": summary(sk)["iterations"], "search_stages": summary(sk)["stages"],
           "load_s": t_load, "clean_s": t_clean, "graph_s": t_graph,
           "dijkstra_s": t_dijkstra, "rss_loaded_mb": rss_loaded, "rss_peak_mb": rss_peak}
    try:   # binding weights (rig layout + skin weights), if the rig modules are present
        from curveskel_addon.rig.rig_layout import rig_layout
        from curveskel_addon.rig.skin_weights import skin_weights

        t0 = time.perf_counter()
        layout = rig_layout(sk.joints, sk.bones)
        skin_weights(layout, sk.bone, sk.t)
        res["binding_s"] = time.perf_counter() - t0
    except ImportError as exc:
        res["binding_s"] = None
        res["binding_note"] = f"not timed: {exc}"
    return res


def _peer_radii(V, F, X, owner):
    """Radius per joint: mean distance of the vertices mapped to it; the distance to the
    surface where no vertex is mapped (or no mapping exists)."""
    import numpy as np

    from curveskel_addon.measure.quality import mesh_distance

    r = np.full(len(X), np.nan)
    if owner is not None:
        owner = np.asarray(owner, np.int64)
        ok = (owner >= 0) & (owner < len(X))
        d = np.linalg.norm(V[ok] - X[owner[ok]], axis=1)
        s = np.bincount(owner[ok], weights=d, minlength=len(X))
        c = np.bincount(owner[ok], minlength=len(X))
        r = np.where(c > 0, s / np.maximum(c, 1), np.nan)
    miss = ~np.isfinite(r)
    if miss.any():
        r[miss] = mesh_distance(X[miss], V, F)
    return r


def run_method(method: str, V, F):
    """Skeletonize with one method. Returns (joints (J,4), bones (B,2), skeleton or None, seconds).

    Seconds cover the method's own work from arrays in memory (for peers: building their mesh
    object, their pre-processing and skeletonization), not our radius fill-in or measures.
    """
    import numpy as np

    D = float(np.linalg.norm(np.ptp(V, axis=0)))
    if method.startswith("curveskel"):
        from curveskel_addon.core import SkeletonParams, SkeletonRun, skeletonize
        from curveskel_addon.run_summary import summary

        t0 = time.perf_counter()
        if method == "curveskel-initial":
            # the first approximation (default settings, cut to Max Joints), before the search
            sk = SkeletonRun(V, F, SkeletonParams()).current_skeleton()
        else:
            params = {"curveskel": SkeletonParams(), "curveskel-paper": SkeletonParams.paper()}[method]
            sk = skeletonize(V, F, params)
        s = summary(sk)
        return sk.joints, sk.bones, sk, time.perf_counter() - t0, {
            "iterations": s["iterations"], "stages": s["stages"], "J": s["J"]}
    if method.startswith("skeletor"):
        import skeletor
        import trimesh

        t0 = time.perf_counter()
        m = trimesh.Trimesh(V, F, process=False)
        fixed = skeletor.pre.fix_mesh(m, remove_disconnected=5, inplace=False)
        if method == "skeletor-wavefront":
            s = skeletor.skeletonize.by_wavefront(fixed, waves=1, step_size=1, progress=False)
        else:   # vertex clusters are meant for a contracted mesh (skeletor's documented pipeline)
            cont = skeletor.pre.contract(fixed, progress=False)
            s = skeletor.skeletonize.by_vertex_clusters(cont, sampling_dist=0.02 * D, progress=False)
        sec = time.perf_counter() - t0
        X = np.asarray(s.vertices, np.float64)
        bones = np.asarray(s.edges, np.int64).reshape(-1, 2)
        r = np.asarray(s.radius, np.float64) if s.radius is not None else np.full(len(X), np.nan)
        r = np.where(np.isfinite(r) & (r > 0), r, np.nan)
        if np.isnan(r).any():
            owner = None
            if s.mesh_map is not None and len(fixed.vertices) == len(V):
                owner = np.asarray(s.mesh_map)
            fill = _peer_radii(np.asarray(fixed.vertices), np.asarray(fixed.faces), X, owner)
            r = np.where(np.isnan(r), fill, r)
        note = {"radius": "skeletor's where > 0, else mean distance of mapped vertices"}
        return np.column_stack([X, r]), bones, None, sec, note
    if method == "pygel-msls":
        from pygel3d import graph, hmesh

        t0 = time.perf_counter()
        hm = hmesh.Manifold.from_triangles(V, F)
        g = graph.from_mesh(hm)
        s, mp = graph.MSLS_skeleton_and_map(g)
        sec = time.perf_counter() - t0
        nodes = [int(n) for n in s.nodes()]
        pos = np.asarray(s.positions(), np.float64)
        new = np.full(len(pos), -1, np.int64)
        new[nodes] = np.arange(len(nodes))
        edges = {(min(a, b), max(a, b)) for a in nodes for b in (int(x) for x in s.neighbors(a))}
        bones = new[np.array(sorted(edges), np.int64).reshape(-1, 2)]
        X = pos[nodes]
        # PyGEL renumbers the mesh's vertices: map ours to its graph nodes by position.
        from scipy.spatial import cKDTree

        gnode = cKDTree(np.asarray(g.positions(), np.float64)).query(V)[1]
        owner = np.asarray(mp, np.int64)[gnode]
        owner = np.where(owner >= 0, new[np.clip(owner, 0, len(new) - 1)], -1)
        r = _peer_radii(V, F, X, owner)
        note = {"radius": "mean distance of the mesh vertices PyGEL maps to each node"}
        return np.column_stack([X, r]), bones, None, sec, note
    raise SystemExit(f"unknown method {method}")


def worker_quality(spec: str, method: str, n_samples: int, repeat: int = 1) -> dict:
    from types import SimpleNamespace

    from curveskel_addon.measure.quality import quality

    V, F, _ = load_mesh(spec)
    joints, bones, sk, sec, note = run_method(method, V, F)
    # Repeats of the method alone (same process, every method alike): the fastest is the one
    # least disturbed by other load; the measures are of the first run's skeleton.
    all_seconds = [sec] + [run_method(method, V, F)[3] for _ in range(repeat - 1)]
    sec = min(all_seconds)
    if sk is None:
        sk = SimpleNamespace(joints=joints, bones=bones, bone=None, t=None)
    t0 = time.perf_counter()
    ref = REFERENCE / f"{stem(spec)}.json"
    q = quality(V, F, sk, n_samples=n_samples, seed=0, reference=ref if ref.is_file() else None)
    save_skeleton(joints, bones, spec, method)
    return {"mesh": spec, "method": method, "seconds": sec, "all_seconds": all_seconds,
            "quality_s": time.perf_counter() - t0,
            "rss_peak_mb": maxrss_mb(), "note": note, **q}


#: Keys of ``quality.shape_measures`` reported by the bench (issue 10).
SHAPE_KEYS = ["to_ref_mean", "to_ref_p95", "from_ref_mean", "from_ref_p95", "length_ratio",
              "zigzag", "turn_p90", "folds", "fold_pairs"]


def shape_of(V, F, joints, bones, spec: str) -> dict:
    """Issue 10's shape measures of one skeleton against ``REFERENCE/<mesh>.json`` (the
    reference-free ones only when there is no reference file)."""
    from curveskel_addon.measure.quality import shape_measures

    ref = REFERENCE / f"{stem(spec)}.json"
    m = shape_measures(V, F, (joints, bones), ref if ref.is_file() else None)
    return {k: m[k] for k in SHAPE_KEYS if k in m}


def save_skeleton(joints, bones, spec: str, method: str) -> Path:
    """Write a skeleton (joints, bones; no mapping) to ``.bench/skeletons/<method>/<mesh>.json``
    for the figures."""
    import numpy as np

    path = OUT / "skeletons" / method / f"{stem(spec)}.json"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps({"format": "curveskel-skeleton/1",
                                "joints": np.asarray(joints, float).tolist(),
                                "bones": np.asarray(bones, int).tolist()}))
    return path


def worker_skeleton(spec: str) -> dict:
    """The default skeleton of one mesh, saved for the figures (``--figures``)."""
    V, F, _ = load_mesh(spec)
    joints, bones, _, sec, _ = run_method("curveskel", V, F)
    path = save_skeleton(joints, bones, spec, "curveskel")
    return {"mesh": spec, "seconds": sec, "path": str(path), **shape_of(V, F, joints, bones, spec)}


#: Issue 33's cases: (mesh, subdivisions, skeleton). The mesh is refined by midpoint subdivision
#: (its shape unchanged) to about 100k vertices; the skeleton is in the mesh's space.
EVALUATE_CASES = {
    "human-110k+metarig": ("human", 2, "metarig"),
    "hand-76k+cgal": ("hand", 2, "cgal"),
    "human+metarig": ("human", 0, "metarig"),
    "hand+cgal": ("hand", 0, "cgal"),
}
#: Issue 33's targets on a ~100k-vertex mesh, seconds.
EVALUATE_TARGETS = {"evaluate_s": 1.0, "refine_s": 3.0}


def _evaluate_case(case: str):
    """(V, F, skeleton) of one of :data:`EVALUATE_CASES`."""
    import numpy as np
    import trimesh

    from curveskel_addon.core import load_outside_skeleton
    from curveskel_addon.mesh_files import read_mesh
    from curveskel_addon.rig.armature_segments import armature_segments
    from tests.outside_skeletons import blender_to_obj, load_metarig, obj_to_blender, place_metarig

    name, levels, kind = EVALUATE_CASES[case]
    if name == "human":
        V, F = read_mesh(ROOT / "tests" / "data" / "heldout" / "human.obj")
    else:
        V, F = read_mesh(next(SHARED.glob(f"{name}.*")))
    for _ in range(levels):
        V, F = trimesh.remesh.subdivide(V, F)
    if kind == "cgal":
        return np.asarray(V), np.asarray(F), load_outside_skeleton(REFERENCE / f"{name}.json")
    names, parent, connected, H, T = load_metarig()
    scale, offset, H, T = place_metarig(names, parent, H, T, obj_to_blender(V))
    seg = armature_segments(blender_to_obj(scale * H + offset), blender_to_obj(scale * T + offset),
                            parent, connected)
    return np.asarray(V), np.asarray(F), (seg.joints, seg.segments)


def worker_evaluate(case: str, repeat: int = 1) -> dict:
    """Issue 33: ``evaluate`` (the core's report), the full report (+ reconstruction distances)
    and ``refine`` (graph kept) of one case, each the fastest of ``repeat`` runs (wall and CPU
    seconds of that run)."""
    from curveskel_addon.core import evaluate, refine
    from curveskel_addon.measure.evaluation import full_report

    V, F, sk = _evaluate_case(case)

    def fastest(fn):
        best = None
        for _ in range(max(repeat, 1)):
            t0, c0 = time.perf_counter(), time.process_time()
            out = fn()
            run = (time.perf_counter() - t0, time.process_time() - c0, out)
            best = run if best is None or run[0] < best[0] else best
        return best

    t_ev, c_ev, rep = fastest(lambda: evaluate(V, F, sk))
    t_full, c_full, _ = fastest(lambda: full_report(V, F, evaluate(V, F, sk)))
    t_ref, c_ref, res = fastest(lambda: refine(V, F, sk))
    return {"case": case, "V": int(len(V)), "F": int(len(F)), "joints": int(len(rep.joints)),
            "bones": int(len(rep.bones)), "evaluate_s": t_ev, "evaluate_cpu_s": c_ev,
            "evaluate_stages": rep.seconds, "full_report_s": t_full, "full_report_cpu_s": c_full,
            "refine_s": t_ref, "refine_cpu_s": c_ref, "iterations": res.iterations,
            "J_before": res.before.J, "J_after": res.after.J,
            "inside_before": res.before.inside_fraction, "inside_after": res.after.inside_fraction}


# ---------------------------------------------------------------------------------------------
# parent: run workers, tabulate, write
# ---------------------------------------------------------------------------------------------
def spawn(args: list[str], timeout: float) -> dict:
    cmd = [sys.executable, str(Path(__file__).resolve()), "--_worker", *args]
    try:
        p = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, cwd=str(ROOT),
                           env={**os.environ, "PYTHONWARNINGS": "ignore"})
    except subprocess.TimeoutExpired:
        return {"error": f"timeout after {timeout:.0f} s"}
    for line in reversed(p.stdout.splitlines()):
        if line.startswith("{"):
            return json.loads(line)
    err = (p.stderr.strip().splitlines() or ["no output"])[-1]
    return {"error": f"exit {p.returncode}: {err[:200]}"}


def peer_available(method: str) -> str | None:
    pkg = PEER_PACKAGES.get(method)
    if pkg is None:
        return None
    import importlib.util

    if importlib.util.find_spec(pkg) is None:
        return f"{method}: package `{pkg}` not installed (pip install -r requirements-bench.txt)"
    return None


def env_line() -> str:
    import numpy
    import scipy

    try:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True,
                                text=True, cwd=str(ROOT)).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"],
                               capture_output=True, text=True, cwd=str(ROOT)).stdout.strip()
        commit += "+local changes" if dirty else ""
    except OSError:
        commit = "?"
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    load = "/".join(f"{x:.1f}" for x in os.getloadavg()) if hasattr(os, "getloadavg") else "?"
    return (f"{_dt.datetime.now(_dt.timezone.utc):%Y-%m-%d %H:%M} UTC, commit {commit}, {cpu}, "
            f"{os.cpu_count()} cores, load average {load} (1/5/15 min) at the end, "
            f"Python {platform.python_version()}, numpy {numpy.__version__}, scipy {scipy.__version__}")


def md_table(header: list[str], rows: list[list]) -> str:
    out = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    out += ["| " + " | ".join(str(c) for c in r) + " |" for r in rows]
    return "\n".join(out)


def write_section(name: str, body: str) -> None:
    begin, end = f"<!-- bench:{name} -->", f"<!-- /bench:{name} -->"
    text = DOC.read_text() if DOC.exists() else "# Benchmarks\n\nGenerated by `scripts/bench.py`.\n"
    block = f"{begin}\n{body.rstrip()}\n{end}"
    if begin in text and end in text:
        pre, rest = text.split(begin, 1)
        post = rest.split(end, 1)[1]
        text = pre + block + post
    else:
        text = text.rstrip() + "\n\n" + block + "\n"
    DOC.parent.mkdir(parents=True, exist_ok=True)
    DOC.write_text(text)


def f3(x, nd=3):
    if x is None:
        return "–"
    if isinstance(x, float):
        return f"{x:.{nd}f}"
    return str(x)


# -- speed ------------------------------------------------------------------------------------
STAGE_ORDER = ["clean", "initialise", "budget", "search"]
#: Issue 11's speed targets: ratio to one Dijkstra for ~100k meshes, seconds for the shared
#: meshes (armadillo and horse get more) and for 1M (with the 2 GB peak).
#: Processes whose Dijkstra baseline is taken (median) for the ratio targets.
DIJKSTRA_PROCESSES = 5
SPEED_TARGETS = {"dijkstra_ratio_100k": 25.0, "shared_s": 1.0, "shared_big_s": 1.5,
                 "shared_big": ("armadillo.obj", "horse.off"), "s_1M": 10.0, "peak_mb_1M": 2048}


def speed_target(r: dict) -> tuple[str, bool | None]:
    """(target text, met) of one speed row (issue 11)."""
    T = SPEED_TARGETS
    n = r["V"]
    if r["mesh"] in REAL:
        lim = T["shared_big_s"] if r["mesh"] in T["shared_big"] else T["shared_s"]
        return f"< {lim:g} s", r["seconds"] < lim
    if n >= 500_000:
        return (f"< {T['s_1M']:g} s, < 2 GB",
                r["seconds"] < T["s_1M"] and r["rss_peak_mb"] < T["peak_mb_1M"])
    if n >= 50_000:
        return f"≤ {T['dijkstra_ratio_100k']:g}× dijkstra", \
            r["seconds"] / r["dijkstra_s"] <= T["dijkstra_ratio_100k"]
    return "", None


def run_speed(args) -> None:
    specs = args.meshes or (REAL + list(PROCEDURAL))
    results = []
    for spec in specs:
        print(f"[speed] {spec} ...", end=" ", flush=True)
        r = spawn(["speed", spec, str(args.repeat)], args.timeout)
        r.setdefault("mesh", spec)
        if "error" not in r and speed_target(r)[0].endswith("dijkstra"):
            # one Dijkstra settles at one of two speeds per process (the star: 31 or 40 ms, ten
            # runs in each of three processes) while the skeleton's time holds: the baseline is
            # the median of the skeleton's process and DIJKSTRA_PROCESSES - 1 more
            more = [spawn(["dijkstra", spec, str(args.repeat)], args.timeout)
                    for _ in range(DIJKSTRA_PROCESSES - 1)]
            r["dijkstra_s_all"] = [r["dijkstra_s"]] + [m["dijkstra_s"] for m in more
                                                       if "dijkstra_s" in m]
            r["dijkstra_s"] = float(statistics.median(r["dijkstra_s_all"]))
        results.append(r)
        print(f"{r.get('seconds', float('nan')):.2f} s" if "error" not in r else r["error"], flush=True)
    if not args.no_write:
        OUT.mkdir(exist_ok=True)
        (OUT / "speed.json").write_text(json.dumps({"env": env_line(), "results": results}, indent=1))

    stages = [s for s in STAGE_ORDER if any(s in r.get("stages", {}) for r in results)]
    stages += sorted({s for r in results for s in r.get("stages", {})} - set(stages))
    rows = []
    for r in results:
        if "error" in r:
            rows.append([stem(r["mesh"]), "–", "–", r["error"]] + [""] * (len(stages) + 7))
            continue
        st = r["stages"]
        n = r["V"]
        text, met = speed_target(r)
        ok = "" if met is None else f"{text}: " + ("yes" if met else "**no**")
        rows.append([stem(r["mesh"]), f"{n:,}", f"{r['F']:,}", f3(r["seconds"], 2)]
                    + [f3(st.get(s), 3) for s in stages]
                    + [f3(r.get("binding_s"), 3), f"{r['rss_peak_mb']:.0f}",
                       f"{r['rss_peak_mb'] - r['rss_loaded_mb']:.0f}",
                       f3(r["seconds"] / r["dijkstra_s"], 1), f3(r["seconds"] / r["clean_s"], 1),
                       r["joints"], ok])
    header = (["mesh", "V", "F", "total s"] + [f"{s} s" for s in stages]
              + ["binding s", "peak MiB", "Δ MiB", "× dijkstra", "× clean", "joints",
                 "target"])
    table = md_table(header, rows)
    cmd = "python scripts/bench.py" + (" --meshes " + " ".join(args.meshes) if args.meshes else "") \
        + (f" --repeat {args.repeat}" if args.repeat != 3 else "")
    body = f"""## Speed (issue 2)

Command: `.venv/bin/{cmd}` — {env_line()}.

One fresh subprocess per mesh. *total s*: `skeletonize(V, F)` with `SkeletonParams()` from
arrays in memory, the fastest of {args.repeat} runs in that subprocess (stage columns are that
run's `Skeleton.timings`; "clean s" there is the pipeline's own
stage). *binding s*: `rig_layout` + `skin_weights` after it. *peak MiB*: `ru_maxrss` of that
subprocess at the end of `skeletonize` (interpreter, imports and the mesh included); *Δ MiB*:
that peak minus the resident size just before `skeletonize` (mesh loaded): the pipeline's own
extra memory (an upper bound if loading the file peaked higher). Baselines and binding run
after it, so they do not raise the peak. Baselines measured in the same run on the same mesh:
*× dijkstra* = total / one `scipy.sparse.csgraph.dijkstra` from one source over the
edge-length graph, the fastest of as many runs as the total (the paper's geodesic approximation; the pipeline needs at least three for
the pole search and f); for the meshes with a ratio target, the median of that over the
skeleton's process and {DIJKSTRA_PROCESSES - 1} fresh ones (one Dijkstra settles at one of two speeds per
process: the star's 31 or 40 ms); *× clean* = total / `clean_mesh` (validation, duplicate merge).
Targets (issue 11, column *target*): the shared meshes < 1 s (armadillo and horse < 1.5 s);
a ~100k-vertex mesh ≤ 25× one Dijkstra over its edge graph; 1M < 10 s and < 2 GB peak.

{table}
"""
    print("\n" + table)
    if not args.no_write:
        fig = plot_speed(results)
        if fig:
            body += f"\n![seconds per stage]({Path(fig).relative_to('docs')})\n"
        write_section("speed", body)
        print(f"\nwrote {DOC.relative_to(ROOT)} (speed) and .bench/speed.json")


# -- evaluate and refine (issue 33) ----------------------------------------------------------------
def run_evaluate(args) -> None:
    cases = args.meshes or list(EVALUATE_CASES)
    results = []
    for case in cases:
        print(f"[evaluate] {case} ...", end=" ", flush=True)
        r = spawn(["evaluate", case, str(args.repeat)], args.timeout)
        r.setdefault("case", case)
        results.append(r)
        print(f"evaluate {r['evaluate_s']:.2f} s, refine {r['refine_s']:.2f} s"
              if "error" not in r else r["error"], flush=True)
    if not args.no_write:
        OUT.mkdir(exist_ok=True)
        (OUT / "evaluate.json").write_text(json.dumps({"env": env_line(), "results": results}, indent=1))
    T = EVALUATE_TARGETS
    rows = []
    for r in results:
        if "error" in r:
            rows.append([r["case"], r["error"]] + [""] * 9)
            continue
        big = r["V"] >= 50_000
        mark = lambda key: (" " + ("(yes)" if r[key] < T[key] else "(**no**)")) if big else ""  # noqa: E731
        rows.append([r["case"], f"{r['V']:,}", f"{r['joints']}/{r['bones']}",
                     f"{r['evaluate_s']:.2f} / {r['evaluate_cpu_s']:.2f}{mark('evaluate_s')}",
                     f"{r['full_report_s']:.2f}",
                     f"{r['refine_s']:.2f} / {r['refine_cpu_s']:.2f}{mark('refine_s')}",
                     r["iterations"], f"{r['J_before']:.4g} → {r['J_after']:.4g}",
                     f"{r['inside_before']:.3f} → {r['inside_after']:.3f}"])
    header = ["case", "V", "joints/bones", "evaluate s (wall / CPU)", "full report s",
              "refine s (wall / CPU)", "iterations", "J", "inside"]
    table = md_table(header, rows)
    cmd = "python scripts/bench.py --evaluate" + (" --meshes " + " ".join(args.meshes) if args.meshes else "") \
        + (f" --repeat {args.repeat}" if args.repeat != 3 else "")
    body = f"""## Evaluate and refine an outside skeleton (issue 33)

Command: `.venv/bin/{cmd}` — {env_line()}.

One fresh subprocess per case; each figure the fastest of {args.repeat} runs there, wall-clock
and CPU seconds of that run (CPU time is what the machine's other load lengthens least; the
core runs mostly on one thread). *evaluate*: `core.evaluate(V, F, skeleton)` from arrays in memory: the
mesh cleaned, J's samples, the radii fitted (the metarig has none; CGAL's given radii are used),
J, E, per bone, per vertex. *full report*: the same plus the reconstruction distances both ways
(`measure.evaluation.full_report`, 10,000 samples each way). *refine*: `core.refine(V, F,
skeleton)`, the graph kept, to the final tolerance or `max_iterations` (30). The ~100k meshes
are `tests/data/heldout/human.obj` and `../shared/meshes/hand.off` refined twice by midpoint
subdivision (the same surface, 16× the triangles); the metarig is Rigify's Basic Human
(`tests/data/rigify_basic_human.json`) placed on the human by `tests/outside_skeletons.py`, CGAL's is the
reference curve skeleton in `../shared/reference`. Targets on ~100k vertices: evaluate < {T['evaluate_s']:g} s,
refine < {T['refine_s']:g} s (marked).

{table}
"""
    print("\n" + table)
    if not args.no_write:
        write_section("evaluate", body)
        print(f"\nwrote {DOC.relative_to(ROOT)} (evaluate) and .bench/evaluate.json")


# -- quality ----------------------------------------------------------------------------------
QCOLS = ["seconds", "recon_mean", "recon_p95", "recon_rev_mean", "recon_rev_p95", "inside",
         "energy_vertex", "energy_area", "joints", "bones", "leaves", "branch_points",
         "skeleton_components", "skeleton_cycles"]


def run_quality(args) -> None:
    specs = args.meshes or REAL
    methods = args.methods or METHODS
    notes = []
    runnable = []
    for m in methods:
        miss = peer_available(m)
        if miss:
            notes.append(miss)
            print("note:", miss)
        else:
            runnable.append(m)
    results = []
    for spec in specs:
        for m in runnable:
            print(f"[quality] {spec} {m} ...", end=" ", flush=True)
            r = spawn(["quality", spec, m, str(args.samples), str(args.quality_repeat)],
                      args.timeout)
            r.setdefault("mesh", spec)
            r.setdefault("method", m)
            results.append(r)
            print(f"{r['seconds']:.2f} s, recon {r['recon_mean']:.4f}, inside {r['inside']:.2f}, "
                  f"joints {r['joints']}, to_ref {r.get('to_ref_mean', float('nan')):.4f}, "
                  f"zig-zag {r['zigzag']:.2f}, folds {r['folds']:.3f}"
                  if "error" not in r else r["error"], flush=True)
    if not args.no_write:
        OUT.mkdir(exist_ok=True)
        (OUT / "quality.json").write_text(json.dumps({"env": env_line(), "notes": notes,
                                                      "results": results}, indent=1))
    body = quality_markdown(results, specs, runnable, notes, args)
    print("\n" + body)
    if not args.no_write:
        fig = plot_quality(results, specs, runnable)
        if fig:
            body += f"\n![recon and inside per mesh and method]({Path(fig).relative_to('docs')})\n"
        if "curveskel" in runnable:
            fig = plot_skeletons([sp for sp in specs if sp in REAL])
            if fig:
                body += (f"\n![default skeleton (blue) over the reference curve (orange), two "
                         f"views per mesh]({Path(fig).relative_to('docs')})\n")
        write_section("quality", body)
        print(f"\nwrote {DOC.relative_to(ROOT)} (quality) and .bench/quality.json")


def meets_quality(r: dict, cg) -> bool:
    """Topology, inside and recon points (the three quality points of issue 5)."""
    return bool("error" not in r and r["topology_match"] and r["inside"] >= TARGETS["inside"]
                and (cg is None or r["recon_mean"] <= cg[0]))


def quality_markdown(results, specs, methods, notes, args) -> str:
    by = {(r["mesh"], r["method"]): r for r in results}
    rows = []
    for spec in specs:
        s = stem(spec)
        cg = CGAL.get(s)
        if cg:
            rows.append([s, "CGAL (reference)", "–", f"{cg[0]:.4f}", "–", "–", "–", f"{cg[1]:.2f}",
                         "–", "–", cg[2], "–", "–", "–", "–"])
        for m in methods:
            r = by.get((spec, m))
            if r is None:
                continue
            if "error" in r:
                rows.append([s, m, r["error"]] + ["–"] * 12)
                continue
            topo = (f"{r['skeleton_components']}c/{r['skeleton_cycles']}g vs "
                    f"{r['mesh_components']}c/{r['mesh_genus']}g"
                    + ("" if r["topology_match"] else " ✗"))
            rows.append([s, m, f3(r["seconds"], 2), f"{r['recon_mean']:.4f}", f"{r['recon_p95']:.4f}",
                         f"{r['recon_rev_mean']:.4f}", f"{r['recon_rev_p95']:.4f}",
                         f"{r['inside']:.2f}", f"{r['energy_vertex']:.2e}", f"{r['energy_area']:.2e}",
                         r["joints"], r["bones"], r["leaves"], r["branch_points"], topo])
    header = ["mesh", "method", "seconds", "recon mean", "recon p95", "rev mean", "rev p95",
              "inside", "E/(nD⁴)", "E_A/(AD⁴)", "joints", "bones", "leaves", "branch", "topology"]
    table = md_table(header, rows)

    # targets for curveskel's default
    trows = []
    ratios = []
    for spec in specs:
        s = stem(spec)
        cg = CGAL.get(s)
        r = by.get((spec, "curveskel"))
        if r is None or "error" in r:
            trows.append([s] + ["–"] * 6 + [r["error"] if r else "not run"])
            continue
        ratio = r["recon_mean"] / cg[0] if cg else None
        if ratio is not None:
            ratios.append(ratio)
        rivals = [m for m in methods if m != "curveskel" and not m.startswith("curveskel")
                  and meets_quality(by.get((spec, m), {"error": 1}), cg)]
        slower_than = [m for m in rivals if by[(spec, m)]["seconds"] <= r["seconds"]]
        marks = {
            "topology": r["topology_match"],
            "inside": r["inside"] >= TARGETS["inside"],
            "recon": ratio is None or ratio <= 1.0,
            "joints": r["joints"] <= TARGETS["joints"],
            "speed": not slower_than,
        }
        yes = lambda b: "yes" if b else "**no**"  # noqa: E731
        missed = [k for k, v in marks.items() if not v]
        trows.append([s, yes(marks["topology"]), f"{yes(marks['inside'])} ({r['inside']:.2f})",
                      f"{yes(marks['recon'])} ({f3(ratio, 2)}× CGAL)",
                      f"{yes(marks['joints'])} ({r['joints']})",
                      f"{yes(marks['speed'])} ({r['seconds']:.2f} s"
                      + (f"; rivals: {', '.join(rivals)}" if rivals else "; no rival meets quality")
                      + ")",
                      "none" if not missed else ", ".join(missed), ""])
    mean_ratio = sum(ratios) / len(ratios) if ratios else float("nan")
    ttable = md_table(["mesh", "topology", "inside ≥ 0.98", "recon ≤ CGAL", "joints ≤ 300",
                       "faster than rivals", "misses", "error"], trows)
    cmd = "python scripts/bench.py --quality" + (" --meshes " + " ".join(args.meshes) if args.meshes else "") \
        + (" --methods " + " ".join(args.methods) if args.methods else "") \
        + (f" --samples {args.samples}" if args.samples != 20000 else "") \
        + (f" --quality-repeat {args.quality_repeat}" if args.quality_repeat != 1 else "")
    note_txt = "\n".join(f"- {n}" for n in notes) or "- every peer was installed."
    shape_txt = shape_markdown(by, specs, methods)
    return f"""## Quality (issue 5)

Command: `.venv/bin/{cmd}` — {env_line()}.

Measures from `curveskel_addon.measure.quality.quality(V, F, skeleton, n_samples={args.samples}, seed=0)`
(definitions in its module docstring); distances are divided by the bounding-box diagonal D.
*recon*: mesh surface samples → silhouette boundary (union of round cones, exact sdRoundCone);
*rev*: silhouette boundary samples → mesh surface (exact point-to-triangle), penalises bulges;
*inside*: fraction of 10 points per bone inside the mesh (ray parity, 3 random directions);
*E/(nD⁴)*: eq. 20 per vertex, *E_A/(AD⁴)*: area-weighted (eq. 8 / area); peers have no mapping,
so their energies use the closest-point mapping; *topology*: skeleton components c / cycles g vs
mesh components / genus (✗ = mismatch). *seconds*: the method alone, from arrays in memory
(peers: building their mesh object + their pre-processing + skeletonization), one fresh
subprocess per mesh and method; with `--quality-repeat N` the fastest of N runs in it.

Methods: `curveskel` = `SkeletonParams()`; `curveskel-paper` = `SkeletonParams.paper()`;
`curveskel-initial` = the first approximation of `SkeletonParams()` cut to *Max Joints*, before
the search (`SkeletonRun(V, F).current_skeleton()`: shows what the search adds or loses);
`skeletor-wavefront` = `skeletor.pre.fix_mesh` + `by_wavefront(waves=1, step_size=1)`, radii from
skeletor (mean distance of mapped vertices where it gives 0); `skeletor-clusters` = `fix_mesh` +
`contract()` (defaults) + `by_vertex_clusters(sampling_dist=0.02 D)`, radii = mean distance of
the (uncontracted) mesh vertices mapped to each node;
`pygel-msls` = PyGEL3D `graph.MSLS_skeleton_and_map(graph.from_mesh(m))` (multi-scale local
separators; the single-scale `LS_skeleton` took 79 s on elephant alone, so it is not run), radii =
mean distance of the vertices mapped to each node. CGAL rows are the reference figures given in
issue 5 (not measured here).

Peers:
{note_txt}

{table}

### Targets for curveskel's default

Per mesh: topology matches; inside ≥ 0.98; recon mean ≤ CGAL's; joints ≤ 300; faster than every
peer ("rival") that meets the three quality points (topology, inside, recon ≤ CGAL).
Average recon ratio to CGAL over these meshes: **{mean_ratio:.2f}** (target ≤ {TARGETS['recon_ratio_mean']}:
{"met" if mean_ratio <= TARGETS['recon_ratio_mean'] else "**not met**"}).

{ttable}

{shape_txt}
"""


def shape_markdown(by: dict, specs, methods) -> str:
    """Issue 10: shape measures of every method against the reference curves, and the targets
    of curveskel's default (every target of the issue, recon/inside/topology included)."""
    import statistics

    rows = []
    for spec in specs:
        s = stem(spec)
        for m in methods:
            r = by.get((spec, m))
            if r is None or "error" in r or "zigzag" not in r:
                continue
            rows.append([s, m, f"{r['to_ref_mean']:.4f}" if "to_ref_mean" in r else "–",
                         f"{r['to_ref_p95']:.4f}" if "to_ref_p95" in r else "–",
                         f"{r['from_ref_mean']:.4f}" if "from_ref_mean" in r else "–",
                         f"{r['from_ref_p95']:.4f}" if "from_ref_p95" in r else "–",
                         f"{r['length_ratio']:.2f}" if "length_ratio" in r else "–",
                         f"{r['zigzag']:.2f}", f"{r['turn_p90']:.0f}°", f"{r['folds']:.3f}",
                         r["joints"]])
    table = md_table(["mesh", "method", "to_ref mean", "to_ref p95", "from_ref mean",
                      "from_ref p95", "length ÷ ref", "zig-zag", "turn p90", "folds", "joints"], rows)
    T = SHAPE_TARGETS
    lo, hi = T["length"]
    trows, ratios, to_refs, all_met = [], [], [], 0
    yes = lambda b, v: ("yes" if b else "**no**") + f" ({v})"  # noqa: E731
    for spec in specs:
        s = stem(spec)
        r = by.get((spec, "curveskel"))
        if r is None or "error" in r or "to_ref_mean" not in r:
            continue
        cg = CGAL.get(s)
        ratio = r["recon_mean"] / cg[0] if cg else None
        if ratio is not None:
            ratios.append(ratio)
        to_refs.append(r["to_ref_mean"])
        mk = shape_marks({**r, "recon_ratio": ratio})
        all_met += all(mk.values())
        trows.append([s, yes(mk["topology"], "✓" if r["topology_match"] else
                             f"{r['skeleton_components']}c/{r['skeleton_cycles']}g"),
                      yes(mk["inside"], f"{r['inside']:.3f}"), yes(mk["joints"], r["joints"]),
                      yes(mk["recon"], f"{f3(ratio, 2)}×"), yes(mk["zigzag"], f"{r['zigzag']:.2f}"),
                      yes(mk["folds"], f"{r['folds']:.3f}"), yes(mk["length"], f"{r['length_ratio']:.2f}"),
                      yes(mk["to_ref"], f"{r['to_ref_mean']:.4f}"),
                      yes(mk["from_ref"], f"{r['from_ref_mean']:.4f}"),
                      ", ".join(k for k, v in mk.items() if not v) or "none"])
    if trows:
        med = statistics.median(to_refs)
        mean_ratio = sum(ratios) / len(ratios) if ratios else float("nan")
        ok = lambda b: "met" if b else "**not met**"  # noqa: E731
        summary = (f"Meshes meeting every per-mesh target: **{all_met} of {len(trows)}**. "
                   f"Median to_ref: **{med:.4f}** D (target ≤ {T['to_ref_median']}: "
                   f"{ok(med <= T['to_ref_median'])}); mean recon ratio to CGAL: "
                   f"**{mean_ratio:.2f}** (target ≤ {T['recon_ratio_mean']}: "
                   f"{ok(mean_ratio <= T['recon_ratio_mean'])}).")
        ttable = md_table(["mesh", "topology", "inside ≥ 0.98", f"joints ≤ {T['joints']}",
                           f"recon ≤ {T['recon_ratio']}× CGAL", f"zig-zag ≤ {T['zigzag']}",
                           "folds 0", f"length {lo}–{hi}", f"to_ref ≤ {T['to_ref']}",
                           f"from_ref ≤ {T['from_ref']}", "misses"], trows)
    else:
        summary, ttable = "curveskel's default was not run.", ""
    return f"""### Shape against the reference curves (issue 10)

`curveskel_addon.measure.quality.shape_measures(V, F, skeleton, reference)` against
`../shared/reference/<mesh>.json` (CGAL mean-curvature-flow skeletons; PyGEL3D's for the
octopus); every distance / D. *to_ref*: points every D/400 along the method's bones → nearest of
points every D/2000 along the reference's bones (spurious or off-centre parts); *from_ref*: the
reverse (missed parts); *length ÷ ref*: Σ bone lengths ÷ the reference's; *zig-zag*: fraction of
degree-2 joints where the chain turns by more than 60°; *turn p90*: 90th percentile of those
turns; *folds*: bone pairs within 0.01 D of each other but more than 0.1 D apart along the
skeleton (same connected part), ÷ bones. Skeletons saved in `.bench/skeletons/<method>/`.

{table}

#### Targets of issue 10 for curveskel's default

Per mesh: topology exact; inside ≥ {T['inside']}; joints ≤ {T['joints']}; recon mean ≤
{T['recon_ratio']}× CGAL's; zig-zag ≤ {T['zigzag']}; folds {T['folds']:g}; length ratio {lo}–{hi};
to_ref ≤ {T['to_ref']} D; from_ref ≤ {T['from_ref']} D. Over the meshes: median to_ref ≤
{T['to_ref_median']} D, mean recon ratio ≤ {T['recon_ratio_mean']}.
{summary}

{ttable}
"""


# -- figures (optional: matplotlib from requirements-bench.txt) ---------------------------------
def plot_speed(results) -> str | None:
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return None
    ok = [r for r in results if "error" not in r]
    if not ok:
        return None
    stages = [s for s in STAGE_ORDER if any(s in r["stages"] for r in ok)]
    fig, ax = plt.subplots(figsize=(11, 4.5))
    x = list(range(len(ok)))
    totals = [max(sum(r["stages"].get(s, 0.0) for s in stages), 1e-12) for r in ok]
    bottom = [0.0] * len(ok)
    for s in stages:
        h = [r["stages"].get(s, 0.0) / t for r, t in zip(ok, totals)]
        ax.bar(x, h, bottom=bottom, label=s)
        bottom = [b + v for b, v in zip(bottom, h)]
    for i, r in enumerate(ok):
        ax.text(i, 1.01, f"{r['seconds']:.2g} s", ha="center", va="bottom", fontsize=7)
    ax.set_ylim(0, 1.1)
    ax.set_xticks(x, [f"{stem(r['mesh'])}\n{r['V']:,} V" for r in ok], rotation=45, ha="right",
                  fontsize=8)
    ax.set_ylabel("share of skeletonize() time")
    ax.set_title("skeletonize(): share of each stage (total seconds on top)")
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    fig.tight_layout()
    path = ROOT / "docs" / "figures" / "speed_stages.png"
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return str(path.relative_to(ROOT))


def plot_quality(results, specs, methods) -> str | None:
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return None
    by = {(r["mesh"], r["method"]): r for r in results if "error" not in r}
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.5))
    w = 0.8 / (len(methods) + 1)
    for k, m in enumerate(["CGAL"] + list(methods)):
        ys, ins = [], []
        for spec in specs:
            if m == "CGAL":
                cg = CGAL.get(stem(spec))
                ys.append(cg[0] if cg else float("nan"))
                ins.append(cg[1] if cg else float("nan"))
            else:
                r = by.get((spec, m))
                ys.append(r["recon_mean"] if r else float("nan"))
                ins.append(r["inside"] if r else float("nan"))
        xs = [i + (k - len(methods) / 2) * w for i in range(len(specs))]
        axes[0].bar(xs, ys, width=w, label=m)
        axes[1].bar(xs, ins, width=w, label=m)
    for ax, t in zip(axes, ["recon mean / D (lower is better)", "inside (higher is better)"]):
        ax.set_xticks(range(len(specs)), [stem(s) for s in specs], rotation=45, ha="right", fontsize=8)
        ax.set_title(t)
    axes[1].axhline(TARGETS["inside"], color="k", lw=0.8, ls="--")
    axes[0].legend(fontsize=7)
    fig.tight_layout()
    path = ROOT / "docs" / "figures" / "quality.png"
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return str(path.relative_to(ROOT))


def run_figures(args) -> None:
    """--figures: the default skeleton of each shared mesh (fresh subprocess each), then
    docs/figures/skeletons.png."""
    specs = [sp for sp in (args.meshes or REAL) if sp in REAL]
    for spec in specs:
        print(f"[figures] {spec} ...", end=" ", flush=True)
        r = spawn(["skeleton", spec], args.timeout)
        print(r["error"] if "error" in r else
              f"{r['seconds']:.2f} s, to_ref {r.get('to_ref_mean', float('nan')):.4f}, "
              f"zig-zag {r['zigzag']:.2f}, folds {r['folds']:.3f}", flush=True)
    fig = plot_skeletons(specs)
    print(f"wrote {fig}" if fig else "matplotlib missing: no figure")


def _view_axes(X):
    """Two orthographic views of a point set: (horizontal, vertical) unit axes for each.

    View 1 faces the two widest principal axes (the largest silhouette); its vertical is the
    one of them closer to the world's up (+y, the convention of the shared meshes), pointing
    up. View 2 turns view 1 by 65° about that vertical and tilts it by 20° (an oblique view:
    depth of the first one, and more than an edge for a flat part).
    """
    import numpy as np

    C = X - X.mean(axis=0)
    _, _, Vt = np.linalg.svd(C[:: max(1, len(C) // 20000)], full_matrices=False)
    up = np.array([0.0, 1.0, 0.0])
    k = int(np.argmax([abs(Vt[0] @ up), abs(Vt[1] @ up)]))
    vert = Vt[k] * (np.sign(Vt[k] @ up) or 1.0)
    hor = Vt[1 - k]
    depth = np.cross(hor, vert)
    a, t = np.radians(65), np.radians(20)
    h2 = np.cos(a) * hor + np.sin(a) * depth
    d2 = np.cross(h2, vert)
    v2 = np.cos(t) * vert + np.sin(t) * d2
    return [(hor, vert), (h2, v2)]


def plot_skeletons(specs, method: str = "curveskel", folder: Path | None = None,
                   ref_dir: Path | None = None, sk_dir: Path | None = None,
                   path: Path | None = None, label: str | None = None) -> str | None:
    """docs/figures/skeletons.png: each mesh (faint surface samples), its reference curve
    (orange) and the method's skeleton from ``.bench/skeletons/<method>/`` (blue, joints as
    dots), two orthographic views per mesh, measures in the title.

    ``folder``, ``ref_dir``, ``sk_dir``, ``path`` and ``label`` replace the shared meshes, their
    references, the skeletons' folder, the picture and the skeleton's legend (the held-out
    meshes: ``scripts/shape_table.py --heldout --figure``)."""
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return None
    import numpy as np

    from curveskel_addon.measure.quality import curve_arrays, sample_surface, shape_measures

    ref_dir = Path(ref_dir) if ref_dir else REFERENCE
    sk_dir = Path(sk_dir) if sk_dir else OUT / "skeletons" / method
    items = []
    for spec in specs:
        sk_path = sk_dir / f"{stem(spec)}.json"
        ref_path = ref_dir / f"{stem(spec)}.json"
        if sk_path.is_file() and ref_path.is_file():
            items.append((spec, sk_path, ref_path))
    if not items:
        return None
    ncol = 4                                     # two meshes per row, two views each
    nrow = (len(items) + 1) // 2
    fig, axes = plt.subplots(nrow, ncol, figsize=(16, 3.6 * nrow))
    axes = np.atleast_2d(axes)
    for ax in axes.ravel():
        ax.set_axis_off()
    for n, (spec, sk_path, ref_path) in enumerate(items):
        V, F, _ = load_mesh(spec, folder)
        X, B = curve_arrays(sk_path)
        Xr, Br = curve_arrays(ref_path)
        m = shape_measures(V, F, (X, B), (Xr, Br))
        S = sample_surface(V, F, 6000, np.random.default_rng(0))
        for v, (h, u) in enumerate(_view_axes(V[np.unique(F)])):
            ax = axes[n // 2, 2 * (n % 2) + v]
            P = lambda Y: (Y @ h, Y @ u)  # noqa: E731
            ax.scatter(*P(S), s=0.6, c="0.55", alpha=0.18, linewidths=0, rasterized=True)
            for Y, bones, col, lw, z in ((Xr, Br, "#f28e2b", 1.3, 2), (X, B, "#1f4e9c", 1.6, 3)):
                if len(bones):
                    a, b = P(Y[bones[:, 0]]), P(Y[bones[:, 1]])
                    ax.plot(np.stack([a[0], b[0]]), np.stack([a[1], b[1]]), color=col, lw=lw,
                            zorder=z, solid_capstyle="round")
            ax.scatter(*P(X), s=5, c="#1f4e9c", zorder=4, linewidths=0)
            ax.set_aspect("equal")
            if v == 0:
                ax.set_title(f"{stem(spec)}: {len(X)} joints\nto_ref {m['to_ref_mean']:.3f} D, "
                             f"from_ref {m['from_ref_mean']:.3f} D, length ×{m['length_ratio']:.2f}, "
                             f"zig-zag {m['zigzag']:.2f}, folds {m['folds']:.2f}",
                             fontsize=9, loc="left")
    from matplotlib.lines import Line2D

    fig.legend([Line2D([], [], color="#1f4e9c", lw=2), Line2D([], [], color="#f28e2b", lw=2)],
               [label or f"{method} (default parameters)", "reference curve skeleton ("
                + ("shared/reference" if ref_dir == REFERENCE else os.path.relpath(ref_dir, ROOT))
                + ")"],
               loc="upper center", ncol=2, fontsize=10, frameon=False)
    fig.tight_layout(rect=(0, 0, 1, 0.975))
    path = Path(path) if path else ROOT / "docs" / "figures" / "skeletons.png"
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=90)
    plt.close(fig)
    return os.path.relpath(path, ROOT) if path.resolve().is_relative_to(ROOT) else str(path)


# -- the whole command against skeletor's (issue 11) ------------------------------------------------
SKELETOR_COMMAND = """
import sys, trimesh, skeletor
m = trimesh.load(sys.argv[1], process=False, force="mesh")
fixed = skeletor.pre.fix_mesh(m, remove_disconnected=5, inplace=False)
s = skeletor.skeletonize.by_wavefront(fixed, waves=1, step_size=1, progress=False)
print(len(s.vertices))
"""


def run_command(args) -> None:
    """Whole command on a ~90k-vertex OBJ (the 87k-vertex star, four capsules united), each in
    its own process with reading and imports included: ``scripts/skeletonize.py STAR.obj --json
    OUT`` against skeletor's ``fix_mesh`` + ``by_wavefront(waves=1, step_size=1)`` of the same
    file. The two take turns ``--repeat`` times; medians are reported."""
    import subprocess
    import tempfile

    import numpy as np

    V, F, _ = load_mesh("star-87k")
    with tempfile.TemporaryDirectory() as tmp:
        obj = Path(tmp) / "star87k.obj"
        with open(obj, "w") as fh:
            np.savetxt(fh, V, fmt="v %.9g %.9g %.9g")
            np.savetxt(fh, F + 1, fmt="f %d %d %d")
        commands = {
            "curveskel": [sys.executable, str(ROOT / "scripts" / "skeletonize.py"), str(obj),
                          "--json", str(Path(tmp) / "out.json")],
            "skeletor-wavefront": [sys.executable, "-c", SKELETOR_COMMAND, str(obj)],
        }
        seconds = {k: [] for k in commands}
        for _ in range(max(args.repeat, 1)):
            for name, cmd in commands.items():
                t0 = time.perf_counter()
                res = subprocess.run(cmd, capture_output=True, text=True, timeout=args.timeout)
                dt = time.perf_counter() - t0
                if res.returncode != 0:
                    print(f"{name} failed: {res.stderr.strip().splitlines()[-1:]}")
                    return
                seconds[name].append(dt)
    print(f"star-87k: {len(V):,} vertices, {len(F):,} triangles; {max(args.repeat, 1)} runs each, taking turns")
    print("| command | median s | runs s |")
    print("|---|---|---|")
    for name, ts in seconds.items():
        print(f"| {name} | {np.median(ts):.2f} | {', '.join(f'{t:.2f}' for t in ts)} |")
    ratio = np.median(seconds["skeletor-wavefront"]) / np.median(seconds["curveskel"])
    print(f"curveskel is {ratio:.2f}x as fast as skeletor's wavefront (target > 1)")



# -- batch (issue 32) ---------------------------------------------------------------------------
#: tiny tasks for the per-task overhead: empty files, refused as soon as they are read
OVERHEAD_TASKS = 300
#: the throughput library: this many of tests/batch_support's procedural meshes (several shapes,
#: sizes, formats), every configuration on the same files
THROUGHPUT_MESHES = 24
#: the library run's time limit per asset (the hanging input reaches it; the slowest real mesh
#: takes a fraction of it)
LIBRARY_TIMEOUT = 90.0


def _batch_support():
    sys.path.insert(0, str(ROOT / "tests"))
    import batch_support

    return batch_support


def _throughput_library(folder: Path) -> list[Path]:
    """THROUGHPUT_MESHES procedural meshes, every other one of the sorted 54 (all sizes)."""
    bs = _batch_support()
    names = sorted(bs.procedural())[::2][:THROUGHPUT_MESHES]
    return [folder / r for r in bs.make_library(folder, names=names, real=False)]


class OtherLoad:
    """CPU seconds taken by processes outside this one's process tree while it measures
    (/proc sampled twice a second): this machine is shared, the figures say how much of it
    others took. Linux only (elsewhere it reports 0)."""

    def __init__(self, interval: float = 0.5):
        import threading

        self.interval = interval
        self.seconds = 0.0
        self._seen: dict = {}
        self._tick = os.sysconf("SC_CLK_TCK") if hasattr(os, "sysconf") else 100
        self._stop = threading.Event()
        self._start = self._uptime()
        self._sample()
        self._thread = threading.Thread(target=self._loop, daemon=True)
        self._thread.start()

    @staticmethod
    def _uptime() -> float:
        try:
            return float(Path("/proc/uptime").read_text().split()[0])
        except OSError:
            return 0.0

    def _sample(self) -> None:
        procs = {}
        for d in Path("/proc").iterdir() if Path("/proc").is_dir() else []:
            if d.name.isdigit():
                try:
                    f = (d / "stat").read_text().rsplit(")", 1)[1].split()
                except (OSError, IndexError):
                    continue
                procs[int(d.name)] = (int(f[1]), (int(f[11]) + int(f[12])) / self._tick,
                                      int(f[19]) / self._tick)
        ours, todo = {os.getpid()}, [os.getpid()]
        kids: dict = {}
        for pid, (ppid, _, _) in procs.items():
            kids.setdefault(ppid, []).append(pid)
        while todo:
            for k in kids.get(todo.pop(), []):
                ours.add(k)
                todo.append(k)
        for pid, (_, cpu, started) in procs.items():
            if pid in ours:
                continue
            prev = self._seen.get(pid, cpu if started < self._start else 0.0)
            self.seconds += max(cpu - prev, 0.0)
            self._seen[pid] = cpu

    def _loop(self) -> None:
        while not self._stop.wait(self.interval):
            self._sample()

    def stop(self) -> float:
        """Stop sampling; the other processes' CPU seconds meanwhile."""
        self._stop.set()
        self._thread.join()
        self._sample()
        return self.seconds


def _batch_once(paths, out: Path, **kw) -> dict:
    """One batch into a fresh folder: wall seconds, rows, per-worker peaks."""
    import shutil

    from curveskel_addon.batch import run

    shutil.rmtree(out, ignore_errors=True)
    other = OtherLoad()
    t0 = time.perf_counter()
    res = run(paths, out, timeout=900, params=_batch_support().METHOD, **kw)
    wall = time.perf_counter() - t0
    other_s = other.stop()
    peaks: dict = {}
    for r in res:
        if r.get("worker") and r.get("peak_mb") is not None:
            peaks[r["worker"]] = max(peaks.get(r["worker"], 0.0), r["peak_mb"])
    return {"wall_s": wall, "n": len(res), "per_min": 60.0 * len(res) / wall, "other_cpu_s": other_s,
            "statuses": res.counts(), "worker_peak_mb": sorted(peaks.values(), reverse=True),
            "sum_asset_s": sum(r["seconds"] or 0.0 for r in res),
            "digests": {r["path"]: r["skeleton_sha256"] for r in res},
            "not_ok": {r["path"]: f"{r['status']}: {r['reason']}" for r in res if r["status"] != "ok"}}


def _jsons(out: Path) -> dict:
    """{skeleton JSON under out: its mtime_ns} (records and the table left out)."""
    return {p: p.stat().st_mtime_ns for p in out.rglob("*.json") if ".curveskel-batch" not in p.parts}


def _rows(out: Path) -> list[dict]:
    return [json.loads(line) for line in (out / "results.jsonl").read_text().splitlines()]


def _library_run(tmp: Path, client) -> dict:
    """The issue's 60-mesh folder (54 procedural variants, 3 shared, 3 held-out; 4 formats)
    with the three bad inputs: the single-file command line on each mesh; the pool (2 workers,
    scripts/batch.py) stopped by Ctrl-C once half the skeletons are written, then run again;
    a 2-worker Dask LocalCluster; the outputs compared."""
    import signal

    from curveskel_addon.batch import run
    from curveskel_addon.batch.records import skeleton_digest
    from curveskel_addon.batch.task import TEST_HOOKS_ENV

    bs = _batch_support()
    lib = tmp / "library"
    good = [lib / "good" / r for r in bs.make_library(lib / "good")]
    bad = [lib / r for r in bs.make_bad(lib)]
    n = len(good) + len(bad)
    t0 = time.perf_counter()
    ref = {Path(p): d for p, d in bs.reference_digests(good, tmp / "reference").items()}
    ref_s = time.perf_counter() - t0
    print(f"[batch] library: {len(good)} meshes + {len(bad)} bad inputs; single-file command "
          f"line, 2 processes: {ref_s:.0f} s ({sum(d is None for d in ref.values())} refused)", flush=True)
    digest = lambda out, rows: {Path(r["source"]): skeleton_digest(json.loads((out / (r["path"] + ".json")).read_text()))
                                for r in rows if r["status"] == "ok"}
    # the meshes the single-file command line fails on: the batch must fail on the same ones
    failed = sorted(p.relative_to(lib).as_posix() for p, d in ref.items() if d is None)
    ref = {p: d for p, d in ref.items() if d is not None}
    not_ok = lambda rows: sorted(r["path"] for r in rows if r["status"] != "ok" and r["path"] not in bs.BAD)
    # the pool, interrupted halfway (Ctrl-C), then run again
    out = tmp / "library-pool"
    env = {**os.environ, TEST_HOOKS_ENV: "1"}
    cmd = [sys.executable, str(ROOT / "scripts" / "batch.py"), str(lib), "--out", str(out),
           "--workers", "2", "--timeout", str(LIBRARY_TIMEOUT), "--quiet", *bs.METHOD_ARGS]
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    while len(_jsons(out) if out.exists() else {}) < len(good) // 2 and proc.poll() is None:
        time.sleep(0.2)
    proc.send_signal(signal.SIGINT)
    _, err1 = proc.communicate(timeout=300)
    first_s = time.perf_counter() - t0
    written = _jsons(out)
    first_rows = _rows(out)
    t0 = time.perf_counter()
    r2 = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=3600)
    second_s = time.perf_counter() - t0
    rows = _rows(out)
    by = {r["path"]: r for r in rows}
    reused = {out / (r["path"] + ".json") for r in rows if r["reused"] and r["status"] == "ok"}
    computed_again = [r["path"] for r in rows if r["status"] == "ok" and not r["reused"]
                      and out / (r["path"] + ".json") in written]
    pool = {"first_rc": proc.returncode, "first_s": first_s, "written_at_stop": len(written),
            "first_rows": len(first_rows), "second_rc": r2.returncode, "second_s": second_s,
            "rows": len(rows), "statuses": _counts(rows), "reused": len(reused),
            "reused_equals_written": reused == set(written),
            "untouched": {p: p.stat().st_mtime_ns for p in written} == written,
            "computed_twice": computed_again,
            "bad": {k: [by[k]["status"], by[k]["reason"]] for k in bs.BAD},
            "temp_files": bs.temp_files(out),
            "identical_to_cli": digest(out, rows) == ref and not_ok(rows) == failed,
            "not_ok": {r["path"]: [r["status"], r["reason"]] for r in rows
                       if r["status"] != "ok" and r["path"] not in bs.BAD}}
    print(f"[batch] pool: stopped after {first_s:.0f} s with {len(written)} written (rc "
          f"{proc.returncode}), rerun {second_s:.0f} s (rc {r2.returncode}): {pool['statuses']}, "
          f"{len(reused)} reused, computed twice {computed_again}, identical {pool['identical_to_cli']}",
          flush=True)
    # a 2-worker Dask LocalCluster (the same client the throughput runs use)
    dout = tmp / "library-dask"
    t0 = time.perf_counter()        # the hooks: set before the cluster started (run_batch_bench)
    res = run(lib, dout, client=client, timeout=LIBRARY_TIMEOUT, params=bs.METHOD, progress=False)
    dask_s = time.perf_counter() - t0
    dask = {"s": dask_s, "rows": len(res), "statuses": res.counts(),
            "bad": {k: [r["status"], r["reason"]] for r in res for k in bs.BAD if r["path"] == k},
            "identical_to_cli": digest(dout, res) == ref and not_ok(res) == failed,
            "identical_to_pool": [{k: r[k] for k in ("path", "status", "skeleton_sha256")} for r in res]
                                 == [{k: r[k] for k in ("path", "status", "skeleton_sha256")} for r in rows]}
    print(f"[batch] dask local:2: {dask_s:.0f} s, {dask['statuses']}, identical to the command "
          f"line {dask['identical_to_cli']}, to the pool {dask['identical_to_pool']}", flush=True)
    return {"meshes": len(good), "assets": n, "reference_s": ref_s, "pool": pool, "dask": dask,
            "cli_failed": failed,
            "stderr_first": err1[-500:], "stderr_second": r2.stderr[-500:]}


def _counts(rows) -> dict:
    out: dict = {}
    for r in rows:
        out[r["status"]] = out.get(r["status"], 0) + 1
    return out


def run_batch_bench(args) -> None:
    """Throughput: assets per minute with 1 and 2 pool workers and on a 2-worker Dask
    LocalCluster, taking turns ``--repeat`` times (medians); per-worker peak memory; Dask's
    overhead per task against the pool, on meshes and on tiny tasks. Then the issue's 60-mesh
    folder (:func:`_library_run`)."""
    import tempfile

    from distributed import Client, LocalCluster

    from curveskel_addon.batch.task import TEST_HOOKS_ENV

    bs = _batch_support()
    # the library's crash and hang inputs work through the test hooks, in every worker process
    # (the Dask workers' too: set before the cluster starts); other files are not affected
    os.environ[TEST_HOOKS_ENV] = "1"
    runs: dict = {"pool-1": [], "pool-2": [], "dask-2": [], "tiny-pool-2": [], "tiny-dask-2": []}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        lib = _throughput_library(tmp / "lib")
        tiny = []
        (tmp / "tiny").mkdir()
        for i in range(OVERHEAD_TASKS):
            (tmp / "tiny" / f"e{i:03d}.obj").write_text("")
            tiny.append(tmp / "tiny" / f"e{i:03d}.obj")
        turns_n = max(args.repeat, 1)
        print(f"[batch] {len(lib)} meshes, {OVERHEAD_TASKS} tiny tasks; {turns_n} turns", flush=True)
        t0 = time.perf_counter()
        cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                               dashboard_address=None)
        client = Client(cluster)
        start_s = time.perf_counter() - t0
        try:
            for turn in range(turns_n):
                for name, paths, kw in (("pool-1", lib, {"workers": 1}), ("pool-2", lib, {"workers": 2}),
                                        ("dask-2", lib, {"client": client}),
                                        ("tiny-pool-2", tiny, {"workers": 2}),
                                        ("tiny-dask-2", tiny, {"client": client})):
                    r = _batch_once(paths, tmp / "out", **kw)
                    runs[name].append(r)
                    print(f"[batch] turn {turn + 1} {name}: {r['n']} in {r['wall_s']:.1f} s "
                          f"({r['per_min']:.1f}/min) {r['statuses']}; other processes "
                          f"{r['other_cpu_s']:.1f} CPU s", flush=True)
            library = None if args.no_library else _library_run(tmp, client)
            dask_rss = client.run(lambda: __import__("resource").getrusage(
                __import__("resource").RUSAGE_SELF).ru_maxrss / 1024.0)
        finally:
            client.close()
            cluster.close()
    med = {k: statistics.median(r["wall_s"] for r in v) for k, v in runs.items()}
    other = {k: statistics.median(r["other_cpu_s"] / r["wall_s"] for r in v) for k, v in runs.items()}
    n, nt = runs["pool-1"][0]["n"], runs["tiny-pool-2"][0]["n"]
    rate = {k: 60.0 * (nt if k.startswith("tiny") else n) / med[k] for k in med}
    ratio = med["pool-1"] / med["pool-2"]
    turns = [a["wall_s"] / b["wall_s"] for a, b in zip(runs["pool-1"], runs["pool-2"])]
    same = all(r["digests"] == runs["pool-1"][0]["digests"] for k in ("pool-1", "pool-2", "dask-2")
               for r in runs[k])
    over_lib = (med["dask-2"] - med["pool-2"]) / n
    over_tiny = (med["tiny-dask-2"] - med["tiny-pool-2"]) / nt
    peak = {k: max(max(r["worker_peak_mb"]) for r in runs[k]) for k in ("pool-1", "pool-2", "dask-2")}
    work = {k: statistics.median(r["sum_asset_s"] for r in runs[k]) for k in ("pool-1", "pool-2")}
    contention = work["pool-2"] / work["pool-1"]
    result = {"env": env_line(), "assets": n, "tiny": nt, "method": bs.METHOD, "runs": runs,
              "median_s": med, "other_cpu_share": other, "per_min": rate,
              "ratio_2_over_1": ratio, "ratio_per_turn": turns,
              "dask_overhead_per_task_s": over_lib, "dask_overhead_per_tiny_task_s": over_tiny,
              "cluster_start_s": start_s, "dask_worker_process_peak_mb": dask_rss,
              "worker_peak_mb": peak, "identical_outputs": same, "asset_seconds_sum": work,
              "contention": contention, "library": library}
    for v in runs.values():
        for r in v:
            r.pop("digests")
    rows = [["pool, 1 worker", f"{med['pool-1']:.1f}", f"{rate['pool-1']:.1f}", "1.00",
             f"{peak['pool-1']:.0f}", f"{other['pool-1']:.2f}"],
            ["pool, 2 workers", f"{med['pool-2']:.1f}", f"{rate['pool-2']:.1f}", f"{ratio:.2f}",
             f"{peak['pool-2']:.0f}", f"{other['pool-2']:.2f}"],
            ["Dask LocalCluster, 2 workers", f"{med['dask-2']:.1f}", f"{rate['dask-2']:.1f}",
             f"{med['pool-1'] / med['dask-2']:.2f}", f"{peak['dask-2']:.0f}", f"{other['dask-2']:.2f}"]]
    table = md_table(["run", "median wall s", "assets/min", "× 1 worker", "worker peak MiB",
                      "others' cores"], rows)
    target = "met" if ratio >= 1.7 else "**not met**"
    method = ", ".join(f"--{k.replace('_', '-')} {v}" for k, v in bs.METHOD.items())
    body = f"""## Batch (issue 32)

Command: `.venv/bin/python scripts/bench.py --batch --repeat {turns_n}` — {env_line()}.
Method settings: `{method}` (a coarse Detail Size, as the batch tests; the objective-J core
takes several seconds per small mesh at the default 0.025, so the default would make this a
half-hour bench; the batch machinery measured here does not depend on it).

### Throughput

{n} of tests/batch_support.py's procedural meshes (every other one of the 54: capsules, tori,
bent capsules, props, trimesh primitives, moved and scaled copies; four formats), each
configuration into a fresh output folder, the three taking turns ({turns_n} turn{"s" if turns_n > 1 else ""}; medians).
*worker peak MiB*: the largest peak resident size of one batch worker process over the assets
it ran (reset before each asset: VmHWM). *others' cores*: the CPU other processes on this
shared machine took during the run, in cores (from /proc) — the machine was not left to the
bench, and the figures are lower than on an idle machine by about that. The same skeletons in
every run: {"yes" if same else "**no**"}.{_not_ok_text(runs["pool-1"][0]["not_ok"], n)}

{table}

Scaling with 2 workers on this {os.cpu_count()}-core machine: **{ratio:.2f}×** (target ≥ 1.7×:
{target}; per turn {", ".join(f"{t:.2f}" for t in turns)}). The assets' own seconds add up to
{work['pool-1']:.1f} s with one worker and {work['pool-2']:.1f} s with two ({100 * (contention - 1):+.0f} %: two busy
cores, and the other processes, slow each other), so {2 / contention:.2f}× is the most two workers
could give in this run; the rest is the last assets' tail. Dask's overhead per task against the
pool, side by side: {1000 * over_lib:+.0f} ms per asset on these meshes, {1000 * over_tiny:+.1f} ms
per tiny task ({nt} empty files, refused as they are read: pool {rate['tiny-pool-2']:.0f}/min,
Dask {rate['tiny-dask-2']:.0f}/min); starting the LocalCluster took {start_s:.1f} s (not in the
walls). The Dask worker processes themselves (each hands its tasks to a batch worker process
of its own, counted above) peaked at {", ".join(f"{v:.0f}" for v in dask_rss.values())} MiB.
"""
    if library:
        body += _library_markdown(library, bs)
    print("\n" + table)
    print(f"asset seconds {work['pool-1']:.1f} / {work['pool-2']:.1f} (x{contention:.2f}); "
          f"ratio {ratio:.2f}; dask overhead {1000 * over_lib:+.0f} ms/asset, {1000 * over_tiny:+.1f} ms/tiny task")
    if not args.no_write:
        OUT.mkdir(exist_ok=True)
        (OUT / "batch.json").write_text(json.dumps(result, indent=1, default=str))
        write_section("batch", body)
        print(f"\nwrote {DOC} (batch) and {OUT / 'batch.json'}")


def _not_ok_text(not_ok: dict, n: int) -> str:
    if not not_ok:
        return ""
    return (f" {len(not_ok)} of the {n} not ok, in every run (a fault of the core at these "
            "settings, the same with the single-file command line): "
            + "; ".join(f"`{k}` {v}" for k, v in not_ok.items()) + ".")


def _library_markdown(L: dict, bs) -> str:
    p, d = L["pool"], L["dask"]
    yes = lambda ok: "yes" if ok else "**no**"
    st = lambda c: ", ".join(f"{v} {k}" for k, v in sorted(c.items(), key=lambda kv: -kv[1]))
    bad = "; ".join(f"`{k}`: {s} ({reason})" for k, (s, reason) in p["bad"].items())
    failed = ""
    if L["cli_failed"]:
        failed = (f" The single-file command line fails on {len(L['cli_failed'])} of the meshes at "
                  "these settings, and the batch's rows say the same: "
                  + "; ".join(f"`{k}`: {st} ({reason})" for k, (st, reason) in p["not_ok"].items())
                  + " (a fault of the core, not of the batch).")
    return f"""
### The 60-mesh folder

{L['meshes']} meshes (tests/batch_support.py's 54 procedural variants at several sizes, 3 of
../shared/meshes: octopus, spot, hand; 3 held-out: koala, penguin, quadknot; four formats, nested
folders) and the three bad inputs in `bad/` (an empty file; a file that kills its worker by
SIGSEGV and one that sleeps forever, both through the test-hook variable), {L['assets']} assets,
`--timeout {LIBRARY_TIMEOUT:g}`. Reference: the single-file command line's `main` on each mesh
(`curveskel skeletonize MESH --json OUT`, 2 processes): {L['reference_s']:.0f} s.

| run | wall s | rows | statuses | JSONs identical to the single-file command's |
|---|---|---|---|---|
| pool, 2 workers (`scripts/batch.py`), Ctrl-C at half | {p['first_s']:.0f} | {p['first_rows']} | {p['written_at_stop']} skeletons written at the stop, exit {p['first_rc']} | – |
| the same command again | {p['second_s']:.0f} | {p['rows']} | {st(p['statuses'])} ({p['reused']} reused) | {yes(p['identical_to_cli'])} |
| Dask LocalCluster, 2 workers (`run(..., client=)`) | {d['s']:.0f} | {d['rows']} | {st(d['statuses'])} | {yes(d['identical_to_cli'])} (rows as the pool's: {yes(d['identical_to_pool'])}) |

Interrupted and run again: the {p['reused']} skeletons reused are exactly the
{p['written_at_stop']} on disk at the stop ({yes(p['reused_equals_written'])}), none of them
rewritten ({yes(p['untouched'])}), none computed twice ({yes(not p['computed_twice'])}),
no temporary file left ({yes(not p['temp_files'])}). The bad inputs' rows: {bad}.{failed}
"""


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quality", action="store_true", help="quality benchmark against peers (issue 5)")
    ap.add_argument("--command", action="store_true",
                    help="whole command on a ~90k-vertex OBJ against skeletor's wavefront (issue 11)")
    ap.add_argument("--batch", action="store_true",
                    help="batch (issue 32): throughput with 1 and 2 workers and a 2-worker Dask "
                         "LocalCluster, Dask's overhead per task (--repeat turns); then the "
                         "60-mesh folder: pool interrupted and rerun, Dask, against the "
                         "single-file command line")
    ap.add_argument("--no-library", action="store_true",
                    help="--batch: throughput only, not the 60-mesh folder")
    ap.add_argument("--evaluate", action="store_true",
                    help="evaluate and refine outside skeletons on ~100k-vertex meshes (issue 33); "
                         f"--meshes picks cases ({', '.join(EVALUATE_CASES)})")
    ap.add_argument("--figures", action="store_true",
                    help="only docs/figures/skeletons.png: default skeleton of each shared mesh "
                         "over its reference (also drawn by --quality)")
    ap.add_argument("--meshes", nargs="+", help="subset: shared file names or procedural names "
                    f"({', '.join(PROCEDURAL)})")
    ap.add_argument("--methods", nargs="+", choices=METHODS, help="quality: subset of methods")
    ap.add_argument("--samples", type=int, default=20000, help="quality: n_samples")
    ap.add_argument("--repeat", type=int, default=3,
                    help="speed: runs per mesh in its subprocess; the fastest is reported")
    ap.add_argument("--quality-repeat", type=int, default=1,
                    help="quality: runs of each method per mesh (same subprocess); the fastest "
                         "is reported, the measures are of the first")
    ap.add_argument("--timeout", type=float, default=900, help="seconds per subprocess")
    ap.add_argument("--no-write", action="store_true", help="print only; leave docs/ and .bench/")
    ap.add_argument("--_worker", nargs="+", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args._worker:
        kind, *rest = args._worker
        if kind == "speed":
            res = worker_speed(rest[0], int(rest[1]) if len(rest) > 1 else 1)
        elif kind == "dijkstra":
            res = worker_dijkstra(rest[0], int(rest[1]) if len(rest) > 1 else 1)
        elif kind == "skeleton":
            res = worker_skeleton(rest[0])
        elif kind == "evaluate":
            res = worker_evaluate(rest[0], int(rest[1]) if len(rest) > 1 else 1)
        else:
            res = worker_quality(rest[0], rest[1], int(rest[2]), int(rest[3]) if len(rest) > 3 else 1)
        print(json.dumps(res, default=lambda o: o.item() if hasattr(o, "item") else str(o)))
        return
    if args.quality:
        run_quality(args)
    elif args.command:
        run_command(args)
    elif args.evaluate:
        run_evaluate(args)
    elif args.figures:
        run_figures(args)
    elif args.batch:
        run_batch_bench(args)
    else:
        run_speed(args)


if __name__ == "__main__":
    main()
