"""``curveskel skeletonize MESH --evaluate / --refine / --compare``: judge outside skeletons by J
(issue 33).

    skeletonize MESH --evaluate SKEL.json [--report OUT.json]
    skeletonize MESH --refine SKEL.json [--json OUT.json] [--fixed I,J,...] [--edit-topology]
                     [--report OUT.json]
    skeletonize MESH --compare A.json B.json [--report OUT.json]

A skeleton file is curveskel's JSON or a plain ``{"joints": [[x, y, z(, r)], ...], "bones":
[[i, j], ...]}`` in the mesh's coordinates. ``--evaluate`` prints J and its terms, the paper's E,
the inside fraction, the reconstruction distances, the topology against the mesh's genus and the
bones that fit worst; ``--report`` also writes it all as JSON (per bone and per vertex
included). ``--refine`` moves the joints to J's minimum with the bones kept (``--json``: the
refined skeleton) and prints the report before and after. ``--compare`` puts two skeletons side
by side on one ruler and says which fits better by J. The method's options (``--smoothness``,
``--prune``, ``--spacing``...) set J's weights and sampling as for a skeletonization.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from ..core import CurveSkelError, compare, evaluate, load_outside_skeleton, refine
from ..measure.evaluation import compare_lines, full_report, report_lines
from ..mesh_files import read_mesh
from .outputs import commit, kept, remove_temps, temp_path

__all__ = ["add_arguments", "requested", "check", "run"]

#: options that make a skeletonization's outputs, which an evaluation does not make
_NOT_WITH = ("paper", "quality", "bind", "glb", "fbx", "blend", "render")


def add_arguments(ap) -> None:
    """The evaluation's options, in a group of their own."""
    g = ap.add_argument_group("evaluate an outside skeleton (instead of skeletonizing)")
    one = g.add_mutually_exclusive_group()
    one.add_argument("--evaluate", type=Path, metavar="SKEL.json",
                     help="print how well this skeleton explains the mesh by J (its terms, E, "
                          "inside fraction, reconstruction, topology, worst bones)")
    one.add_argument("--refine", type=Path, metavar="SKEL.json",
                     help="move this skeleton's joints to J's minimum with its bones kept; "
                          "--json OUT.json writes the refined skeleton")
    one.add_argument("--compare", type=Path, nargs=2, metavar=("A.json", "B.json"),
                     help="the reports of two skeletons side by side, and which fits better by J")
    g.add_argument("--report", type=Path, metavar="OUT.json",
                   help="also write the report as JSON (J, terms, E, inside_fraction, "
                        "recon_mean, per_bone, vertex_residual, ...)")
    g.add_argument("--fixed", type=_indices, metavar="I,J,...",
                   help="--refine: joints (indices in SKEL.json) that keep their positions")
    g.add_argument("--edit-topology", action="store_true",
                   help="--refine: also merge, prune, split and join joints where J falls (the "
                        "bones may change)")


def _indices(text):
    try:
        return [int(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"joint indices separated by commas, got {text!r}") from None


def requested(args) -> bool:
    return any(getattr(args, k, None) for k in ("evaluate", "refine", "compare"))


def check(args) -> None:
    """Refuse combinations that would do nothing or contradict each other, before any work."""
    if not requested(args):
        for flag in ("report", "fixed", "edit_topology"):
            if getattr(args, flag, None):
                raise CurveSkelError(f"--{flag.replace('_', '-')} goes with --evaluate, --refine "
                                     "or --compare")
        return
    mode = next(k for k in ("evaluate", "refine", "compare") if getattr(args, k, None))
    for flag in _NOT_WITH:
        if getattr(args, flag, None):
            raise CurveSkelError(f"--{mode} judges a given skeleton: it cannot be combined with "
                                 f"--{flag}")
    if args.json is not None and mode != "refine":
        raise CurveSkelError(f"--json writes a skeleton: --{mode} makes none (--report writes "
                             "the report)")
    if (args.fixed or args.edit_topology) and mode != "refine":
        raise CurveSkelError("--fixed and --edit-topology go with --refine")


def _write_json(doc: dict, out) -> None:
    tmp = temp_path(out)
    try:
        tmp.write_text(json.dumps(doc))
    except OSError as exc:
        remove_temps()
        raise CurveSkelError(f"could not write {out.opt} {out.given}: {exc.strerror or exc}; "
                             f"{kept(out)}") from None
    commit(tmp, out)


def run(args, outs: dict, params, report, progress) -> int:
    """Evaluate, refine or compare; the files first, the text into ``report``."""
    # the skeleton files first: a bad one is refused before the mesh is read
    given = [args.evaluate or args.refine] if not args.compare else list(args.compare)
    loaded = [load_outside_skeleton(p) for p in given]
    progress("read", 0.0)
    V, F = read_mesh(args.mesh)
    if args.evaluate:
        sk = loaded[0]
        progress("evaluate", 0.0)
        rep = full_report(V, F, evaluate(V, F, sk, params), vertices=True)
        lines = [f"skeleton    {args.evaluate}: {len(rep['joints'])} joints, "
                 f"{len(rep['bones'])} bones"] + report_lines(rep)
        doc = rep
    elif args.refine:
        sk = loaded[0]
        progress("refine", 0.0)
        res = refine(V, F, sk, fixed=args.fixed, edit_topology=args.edit_topology, params=params,
                     progress=progress)
        before = full_report(V, F, res.before)
        after = full_report(V, F, res.after, vertices=True)
        lines = [f"skeleton    {args.refine}: {len(before['joints'])} joints, "
                 f"{len(before['bones'])} bones"]
        lines += ["before      " + x for x in report_lines(before, worst=0)]
        lines += [f"refined     {res.iterations} minimisation steps"
                  + (f", {len(after['joints'])} joints" if args.edit_topology else "")]
        lines += ["after       " + x for x in report_lines(after)]
        doc = {"before": before, "after": after, "iterations": res.iterations}
        if "json" in outs:
            _write_json(res.skeleton.to_dict(), outs["json"])
            lines.append(f"wrote       {args.json}")
    else:
        names = [str(p) for p in args.compare]
        sks = loaded
        progress("compare", 0.0)
        reps = [full_report(V, F, r) for r in compare(V, F, sks, params)]
        lines = compare_lines(names, reps)
        doc = {"skeletons": names, "reports": reps,
               "best": names[min(range(len(reps)), key=lambda k: reps[k]["J"])]}
    if "report" in outs:
        _write_json(doc, outs["report"])
        lines.append(f"wrote       {args.report}")
    print(f"mesh        {args.mesh}: {len(V)} vertices, {len(F)} triangles", file=report)
    for line in lines:
        print(line, file=report)
    return 0
