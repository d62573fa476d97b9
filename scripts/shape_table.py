#!/usr/bin/env python
"""Fast developer table of the issue-10 measures: skeletonize the ten shared meshes, one row each.

Usage (from the repository root):

    .venv/bin/python scripts/shape_table.py                                  # default parameters
    .venv/bin/python scripts/shape_table.py --set smoothness=2 --set prune=0.5
    .venv/bin/python scripts/shape_table.py --paper --meshes horse spot --json out.json
    .venv/bin/python scripts/shape_table.py --ref-only     # the reference curves themselves
    .venv/bin/python scripts/shape_table.py --save-dir out/sk   # keep the skeletons (JSON)
    .venv/bin/python scripts/shape_table.py --heldout --save-dir out/sk --figure out/heldout.png

``--set NAME=VALUE`` overrides a field of ``SkeletonParams`` (value parsed to the type of the
field's default; booleans as 1/0/true/false). Meshes run in a process pool (``--jobs``, default
2). Each row: joints, topology (✓/✗), inside, recon_mean and its ratio to CGAL's (issue 5's
figures), zig-zag, folds, crossings (no target: bone pairs within 0.3 of their radius of
each other and far apart along the skeleton, per bone), pinches (no target: chain joints whose radius is
below 0.4 of both neighbours', ``quality.radius_pinches``), length ratio, to_ref, from_ref (all / D, against
``../shared/reference/<mesh>.json``), off (no target: the median distance of the skeleton's
points every D/400 from the centroids of the mesh's cross-sections across their bones, / D,
``quality.section_offsets``: how centred the curve is, whatever the reference), mirror (no
target: on a mirror-symmetric mesh, how far the
skeleton is from its own mirror image, / D, ``quality.mirror_asymmetry``) and the seconds of
``skeletonize`` alone. A ``*`` marks a
value that misses its issue-10 target. The summary counts the meshes meeting each target, the
median to_ref and the mean recon ratio.

``--heldout [DIR]``: the same table on the meshes of DIR (default ``tests/data/heldout``: meshes not in
shared/, for issue 10's "also checked on meshes not in shared/"), against ``DIR/reference`` (CGAL
mean-curvature-flow skeletons made as shared/reference's, see the folder's README.md). CGAL's
recon figure of such a mesh is that of CGAL's skeleton (the reference, or ``reference/cgal/`` where
the reference is another method's, as for the octopus in shared/), from the same samples: the
shared meshes' figures in ``bench.CGAL`` are those of CGAL's skeletons too. ``--figure PNG`` (with
``--save-dir``) draws the skeletons over the references like docs/figures/skeletons.png.

Speed: recon is ``|silhouette_sdf|`` of ``--samples`` (default 5000) area-uniform surface samples
(the same estimator as ``quality()``'s recon_mean, which the bench runs with 20000 samples: a
few per cent of sampling noise); the reverse recon and the energies of ``quality()`` are skipped.
inside: 10 points per bone, ray parity, as in ``quality()``.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "scripts"))

from bench import CGAL, REAL, REFERENCE, SHAPE_TARGETS, load_mesh, shape_marks, stem  # noqa: E402

#: Largest first: the pool then finishes about together.
ORDER = ["armadillo.obj", "horse.off", "fertility.off", "octopus.off", "rocker-arm.obj",
         "3holes.off", "elephant.obj", "homer.obj", "spot.obj", "hand.off"]
#: Meshes not in shared/ (``--heldout``) and their reference curves in ``HELDOUT / "reference"``.
HELDOUT = ROOT / "tests" / "data" / "heldout"


def heldout_order(folder) -> list[str]:
    """The held-out meshes' file names in ``folder``, largest file first."""
    files = [p for p in Path(folder).iterdir()
             if p.suffix.lower() in (".obj", ".off", ".ply", ".stl")]
    return [p.name for p in sorted(files, key=lambda p: (-p.stat().st_size, p.name))]


def parse_sets(sets: list[str], paper: bool) -> dict:
    """``["name=value", ...]`` -> SkeletonParams field overrides, typed like each default."""
    from dataclasses import fields

    from curveskel_addon.core import SkeletonParams

    base = SkeletonParams.paper() if paper else SkeletonParams()
    known = {f.name: getattr(base, f.name) for f in fields(base)}
    out = {}
    for s in sets:
        if "=" not in s:
            raise SystemExit(f"--set wants NAME=VALUE, got {s!r}")
        k, v = s.split("=", 1)
        k = k.strip().replace("-", "_")
        if k not in known:
            raise SystemExit(f"unknown parameter {k!r}; known: {', '.join(known)}")
        d = known[k]
        if isinstance(d, bool):
            if v.lower() not in ("1", "0", "true", "false", "yes", "no", "on", "off"):
                raise SystemExit(f"{k} is a boolean: use 1/0/true/false, got {v!r}")
            out[k] = v.lower() in ("1", "true", "yes", "on")
        elif isinstance(d, int):
            out[k] = int(float(v)) if float(v).is_integer() else float(v)
        elif isinstance(d, float):
            out[k] = float(v)
        else:
            out[k] = type(d)(v) if d is not None else v
    return out


def measure(spec: str, overrides: dict, paper: bool, n_samples: int, ref_only: bool,
            save_dir: str | None = None, heldout: str | None = None) -> dict:
    """One mesh: skeletonize (or take the reference), fast volumetric measures, shape measures.
    ``heldout``: a folder of held-out meshes (``--heldout``): the mesh from there, against its
    reference in the folder's ``reference/``."""
    import numpy as np

    from curveskel_addon.core import SkeletonParams, skeletonize
    from curveskel_addon.core.geometry.inside import inside_mesh
    from curveskel_addon.measure.quality import (
        bbox_diagonal, bone_points, curve_arrays, mesh_topology, sample_surface, section_offsets,
        shape_measures, silhouette_sdf, skeleton_topology)
    from curveskel_addon.run_summary import summary

    name = stem(spec)
    try:
        V, F, _ = load_mesh(spec, Path(heldout) if heldout else None)
        ref_path = (Path(heldout) / "reference" if heldout else REFERENCE) / f"{name}.json"
        ref = curve_arrays(ref_path)
        with open(ref_path) as fh:
            ref_r = np.asarray(json.load(fh)["joints"], float)[:, 3]
        t0 = time.perf_counter()
        if ref_only:
            X, B = ref
            joints = np.column_stack([X, ref_r])
            bones = B
            meta = {}
        else:
            base = SkeletonParams.paper() if paper else SkeletonParams()
            params = SkeletonParams.from_dict({**base.to_dict(), **overrides})
            sk = skeletonize(V, F, params)
            joints, bones = np.asarray(sk.joints), np.asarray(sk.bones)
            s = summary(sk)
            meta = {"iterations": s["iterations"], "stages": s["stages"], "J": s["J"]}
        sec = time.perf_counter() - t0
        if save_dir and not ref_only:
            Path(save_dir).mkdir(parents=True, exist_ok=True)
            sk.save(str(Path(save_dir) / f"{name}.json"))
        D = bbox_diagonal(V, F)
        rng = np.random.default_rng(0)
        S = sample_surface(V, F, n_samples, rng)
        recon = float(np.mean(np.abs(silhouette_sdf(S, joints, bones)))) / D
        inside = float(inside_mesh(bone_points(joints, bones, 10), V, F, seed=0).mean())
        st = skeleton_topology(len(joints), bones)
        mt = mesh_topology(V, F)
        topo = bool(st["skeleton_components"] == mt["mesh_components"]
                    and st["skeleton_cycles"] == mt["mesh_genus"])
        sm = shape_measures(V, F, (joints, bones), ref, D=D)
        sm["centre_offset"] = float(np.median(section_offsets(V, F, (joints[:, :3], bones), D)[1]))
        cg = CGAL.get(name)
        if heldout:  # CGAL's recon: of its skeleton (the reference, or reference/cgal/<mesh>.json
            cg_path = Path(heldout) / "reference" / "cgal" / f"{name}.json"  # if another's)
            with open(cg_path if cg_path.is_file() else ref_path) as fh:
                cg_sk = json.load(fh)
            cg_J = np.asarray(cg_sk["joints"], float)
            cg_B = np.asarray(cg_sk["bones"], np.int64).reshape(-1, 2)
            cg = (float(np.mean(np.abs(silhouette_sdf(S, cg_J, cg_B)))) / D,)
        res = {"mesh": name, "seconds": sec, "joints": int(len(joints)), "bones": int(len(bones)),
               "topology_match": topo, "cycles": st["skeleton_cycles"], "genus": mt["mesh_genus"],
               "components": st["skeleton_components"], "mesh_components": mt["mesh_components"],
               "inside": inside, "recon_mean": recon,
               "recon_ratio": recon / cg[0] if cg else None, "recon_samples": n_samples,
               **{k: v for k, v in sm.items() if k != "D"}, "D": D, **meta}
        res["measure_seconds"] = time.perf_counter() - t0 - sec
        return res
    except Exception as exc:  # one mesh failing must not stop the table
        import traceback

        return {"mesh": name, "error": f"{type(exc).__name__}: {exc}",
                "traceback": traceback.format_exc(limit=4)}


COLS = [("mesh", 10), ("J", 4), ("topo", 5), ("inside", 6), ("recon", 7), ("×CGAL", 6),
        ("zigzag", 6), ("folds", 6), ("cross", 5), ("pinch", 5), ("len×", 5), ("to_ref", 6),
        ("from", 6), ("off", 6), ("mirror", 6), ("s", 6)]


def fmt_row(r: dict) -> str:
    if "error" in r:
        return f"{r['mesh']:<10} ERROR {r['error']}"
    m = shape_marks(r)
    star = lambda k: " " if m.get(k, True) else "*"  # noqa: E731
    topo = ("ok" if r["topology_match"] else f"{r['components']}c{r['cycles']}g")
    cells = [f"{r['mesh']:<10}", f"{r['joints']:>3}{star('joints')}", f"{topo:>4}{star('topology')}",
             f"{r['inside']:5.3f}{star('inside')}", f"{r['recon_mean']:7.4f}",
             (f"{r['recon_ratio']:5.2f}" if r["recon_ratio"] is not None else "    –") + star("recon"),
             f"{r['zigzag']:5.2f}{star('zigzag')}", f"{r['folds']:5.3f}{star('folds')}",
             f"{r['crossings']:5.3f}" if r.get("crossings") is not None else "    –",
             f"{r['pinches']:5d}" if r.get("pinches") is not None else "    –",
             f"{r['length_ratio']:4.2f}{star('length')}", f"{r['to_ref_mean']:.4f}{star('to_ref')}",
             f"{r['from_ref_mean']:.4f}{star('from_ref')}",
             f"{r['centre_offset']:.4f}" if r.get("centre_offset") is not None else "     –",
             f"{r['mirror_asymmetry']:.4f}" if r.get("mirror_asymmetry") is not None else "     –",
             f"{r['seconds']:6.2f}"]
    return " ".join(cells)


def header() -> str:
    return " ".join(f"{n:<{w}}" if i == 0 else f"{n:>{w}}" for i, (n, w) in enumerate(COLS))


def summary(results: list[dict]) -> str:
    ok = [r for r in results if "error" not in r]
    keys = ["joints", "topology", "inside", "recon", "zigzag", "folds", "length", "to_ref", "from_ref"]
    met = {k: sum(shape_marks(r)[k] for r in ok) for k in keys}
    all_met = sum(all(shape_marks(r).values()) for r in ok)
    n = len(ok)
    ratios = [r["recon_ratio"] for r in ok if r["recon_ratio"] is not None]
    mean_ratio = sum(ratios) / len(ratios) if ratios else float("nan")
    med_to = statistics.median(r["to_ref_mean"] for r in ok) if ok else float("nan")
    T = SHAPE_TARGETS
    lines = [
        "targets met (of %d): " % n + "  ".join(f"{k} {met[k]}" for k in keys)
        + f"   all {all_met}",
        f"median to_ref {med_to:.4f} (target ≤ {T['to_ref_median']})"
        + ("" if med_to <= T["to_ref_median"] else " *")
        + f"   mean recon ratio {mean_ratio:.2f} (target ≤ {T['recon_ratio_mean']})"
        + ("" if mean_ratio <= T["recon_ratio_mean"] else " *")
        + f"   total s {sum(r['seconds'] for r in ok):.1f}",
    ]
    if len(ok) < len(results):
        lines.append(f"{len(results) - len(ok)} mesh(es) failed: "
                     + ", ".join(r["mesh"] for r in results if "error" in r))
    return "\n".join(lines)


SWEEP_HEADER = ("| setting | all targets met (of 10) | inside ≥ 0.98 | recon ≤ 1.25× | mean recon ×CGAL "
                "| zig-zag ≤ 0.15 | folds 0 | length ok | to_ref ≤ 0.02 | median to_ref "
                "| from_ref ≤ 0.025 |\n|---|---|---|---|---|---|---|---|---|---|---|")


def sweep_row(setting: str, results: list[dict]) -> str:
    """One markdown row of the deciding-parameter table in docs/benchmarks.md: how many meshes
    meet each target, the mean recon ratio and the median to_ref."""
    ok = [r for r in results if "error" not in r]
    marks = [shape_marks(r) for r in ok]
    met = {k: sum(m[k] for m in marks) for k in marks[0]} if marks else {}
    ratios = [r["recon_ratio"] for r in ok if r["recon_ratio"] is not None]
    cells = [setting, sum(all(m.values()) for m in marks), met.get("inside", 0),
             met.get("recon", 0), f"{sum(ratios) / max(len(ratios), 1):.2f}", met.get("zigzag", 0),
             met.get("folds", 0), met.get("length", 0), met.get("to_ref", 0),
             f"{statistics.median(r['to_ref_mean'] for r in ok):.4f}" if ok else "–",
             met.get("from_ref", 0)]
    failed = len(results) - len(ok)
    return "| " + " | ".join(str(c) for c in cells) + " |" + (f" ({failed} failed)" if failed else "")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter,
                                 epilog="targets: " + ", ".join(f"{k} {v}" for k, v in SHAPE_TARGETS.items()))
    ap.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                    help="override a SkeletonParams field (repeatable)")
    ap.add_argument("--paper", action="store_true", help="start from SkeletonParams.paper()")
    ap.add_argument("--ref-only", action="store_true",
                    help="measure the reference skeletons themselves (sanity check)")
    ap.add_argument("--meshes", nargs="+", help="subset, by file name or stem (e.g. horse spot)")
    ap.add_argument("--jobs", type=int, default=2, help="process pool size (default 2)")
    ap.add_argument("--samples", type=int, default=5000, help="surface samples for recon")
    ap.add_argument("--json", metavar="OUT", help="also write the rows (and settings) as JSON")
    ap.add_argument("--save-dir", metavar="DIR", help="also save each skeleton as DIR/<mesh>.json")
    ap.add_argument("--heldout", nargs="?", const=str(HELDOUT), metavar="DIR",
                    help="meshes not in shared/ and their references (DIR/reference/); default "
                         "DIR: tests/data/heldout")
    ap.add_argument("--figure", metavar="PNG",
                    help="with --save-dir: draw the skeletons over the references (two views each)")
    ap.add_argument("--sweep", metavar="NAME=V1,V2,...",
                    help="one summary row per value of one parameter (the other --set overrides "
                         "apply to every row), as a markdown table for docs/benchmarks.md")
    args = ap.parse_args(argv)
    if args.figure and (not args.save_dir or args.ref_only):
        raise SystemExit("--figure draws the skeletons saved by --save-dir (not with --ref-only)")
    if args.sweep:
        return sweep(args)

    overrides = parse_sets(args.set, args.paper)
    specs = _specs(args)
    setting = ("reference curves" if args.ref_only else ("paper" if args.paper else "default")
               + (" " + " ".join(args.set) if args.set else ""))
    label = setting + (f"; held-out meshes ({args.heldout})" if args.heldout else "")
    print(f"# shape_table: {label}; recon from {args.samples} samples; * = misses target", flush=True)
    print(header(), flush=True)
    t0 = time.perf_counter()
    results = run(specs, overrides, args, echo=True)
    print(summary(results))
    print(f"wall {time.perf_counter() - t0:.1f} s")
    if args.json:
        Path(args.json).write_text(json.dumps({"settings": label, "overrides": overrides,
                                               "paper": args.paper, "ref_only": args.ref_only,
                                               "samples": args.samples, "targets": SHAPE_TARGETS,
                                               "heldout": args.heldout, "results": results},
                                              indent=1, default=str))
        print(f"wrote {args.json}")
    if args.figure:
        from bench import plot_skeletons

        fig = plot_skeletons(sorted(specs) if args.heldout else specs,
                             folder=Path(args.heldout) if args.heldout else None,
                             ref_dir=Path(args.heldout) / "reference" if args.heldout else None,
                             sk_dir=args.save_dir, path=args.figure, label=f"curveskel ({setting})")
        print(f"wrote {fig}" if fig else "no figure (matplotlib missing, or no skeleton saved)")


def _specs(args) -> list[str]:
    order = heldout_order(args.heldout) if args.heldout else ORDER
    if not args.meshes:
        return order
    want = {m.rsplit(".", 1)[0] if "." in m and m.rsplit(".", 1)[1] in ("obj", "off", "ply", "stl")
            else m for m in args.meshes}
    specs = [s for s in order if stem(s) in want]
    unknown = want - {stem(s) for s in specs}
    if unknown:
        raise SystemExit(f"unknown mesh(es): {', '.join(sorted(unknown))}; known: "
                         + ", ".join(stem(s) for s in (sorted(order) if args.heldout else REAL)))
    return specs


def run(specs: list[str], overrides: dict, args, echo: bool = False) -> list[dict]:
    """Measure the meshes in a process pool; rows in REAL's order (the held-out ones: by name)."""
    env = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
    for k, v in env.items():         # one BLAS thread per worker: the pool already fills the cores
        os.environ.setdefault(k, v)
    results = []
    with ProcessPoolExecutor(max_workers=max(1, args.jobs)) as pool:
        futs = {pool.submit(measure, s, overrides, args.paper, args.samples, args.ref_only,
                            args.save_dir, args.heldout): s
                for s in specs}
        for f in as_completed(futs):
            r = f.result()
            results.append(r)
            if echo:
                print(fmt_row(r), flush=True)
            if "error" in r:
                print(r["traceback"], file=sys.stderr)
    order = {stem(s): i for i, s in enumerate(sorted(specs) if args.heldout else REAL)}
    results.sort(key=lambda r: order.get(r["mesh"], 99))
    return results


def sweep(args) -> None:
    """``--sweep NAME=V1,V2,...``: the deciding-parameter table, one row per value."""
    from curveskel_addon.core import SkeletonParams

    if "=" not in args.sweep:
        raise SystemExit(f"--sweep wants NAME=V1,V2,..., got {args.sweep!r}")
    name, values = args.sweep.split("=", 1)
    base = parse_sets(args.set, args.paper)
    defaults = SkeletonParams.paper() if args.paper else SkeletonParams()
    print(f"# sweep of {name} ({'paper' if args.paper else 'default'}"
          + (" " + " ".join(args.set) if args.set else "") + f"; recon from {args.samples} samples)",
          flush=True)
    print(SWEEP_HEADER, flush=True)
    for v in values.split(","):
        one = parse_sets([f"{name}={v}"], args.paper)
        (field, value), = one.items()
        label = f"{name} {v.strip()}" + (" (default)" if value == getattr(defaults, field) else "")
        print(sweep_row(label, run(_specs(args), base | one, args)), flush=True)


if __name__ == "__main__":
    main()
