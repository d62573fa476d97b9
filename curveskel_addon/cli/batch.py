"""``curveskel batch``: skeletonize a library of mesh files (also ``scripts/batch.py``).

    curveskel batch IN [IN ...] --out DIR [--workers N | --dask ADDRESS | --dask local:N]
                    [--timeout S] [--memory-limit SIZE] [--glb] [--fbx] [--blend] [--bind]
                    [--quality] [--quiet] [method options]

The work is :func:`curveskel_addon.batch.run`'s; this module is its command line: the options,
the summary on stdout once the table is written, the exit status (0: every asset ok; 1: some
asset refused, timed out, over the memory limit or crashed, see the table; 2: bad arguments,
nothing run; 130 / 143 / 129: Ctrl-C, SIGTERM, SIGHUP, after the table of the assets done is
written).
"""

from __future__ import annotations

import argparse
import signal
import sys
from dataclasses import fields
from pathlib import Path

from .. import __version__
from ..core import SOLVERS, CurveSkelError, SkeletonParams
from .skeletonize import (_HELP, _Parser, _install_stop_handlers, _say, params_from_args)

__all__ = ["build_parser", "main"]

_EPILOG = """\
Outputs mirror the input tree under DIR: lib/chairs/a.obj -> DIR/chairs/a.obj.json (and
a.obj.glb, .fbx, .blend when asked), each written to a temporary file and renamed when
complete; DIR/results.jsonl and DIR/results.csv hold one row per asset (path, input SHA-256,
status ok / refused / timeout / memory / crashed with its reason, vertices, joints, bones, J,
seconds, peak memory, ...).

Run the same command again to resume: an asset whose input, settings and outputs are unchanged
is not recomputed (its row says reused). Ctrl-C stops at once and keeps every file written.

Examples:
  {prog} assets/ --out skeletons/
  {prog} 'scans/**/*.ply' list.txt --out out/ --workers 8 --timeout 300 --memory-limit 4G
  {prog} assets/ --out out/ --dask local:4
  {prog} /nfs/assets --out /nfs/skeletons --dask tcp://scheduler:8786
"""


def build_parser(prog: str = "curveskel batch") -> argparse.ArgumentParser:
    """The command's argument parser."""
    ap = _Parser(prog=prog, formatter_class=argparse.RawDescriptionHelpFormatter,
                 description="Skeletonize every mesh file (.obj .ply .stl .off) in folders, "
                             "globs or manifests, on this machine's cores or a Dask cluster.",
                 epilog=_EPILOG.format(prog=prog))
    ap.add_argument("inputs", nargs="+", metavar="IN",
                    help="a folder (searched recursively), a glob ('lib/**/*.obj', quoted), a "
                         "manifest (.txt/.lst/.list: one path a line, relative to the manifest) "
                         "or a mesh file")
    ap.add_argument("--out", required=True, metavar="DIR", help="the output folder")   # str: a URL stays one
    ap.add_argument("--root", type=Path, metavar="FOLDER",
                    help="the folder the outputs' paths start from (default: the inputs' "
                         "common folder)")
    run = ap.add_argument_group("where and how it runs")
    run.add_argument("--workers", type=int, metavar="N",
                     help="worker processes on this machine (default: the cores, here "
                          f"{_cores()})")
    run.add_argument("--dask", metavar="ADDRESS",
                     help="run on a Dask cluster: a scheduler address (tcp://host:8786) or "
                          "local:N (a local cluster of N workers); paths must be the same on "
                          "every worker (a shared file system; fsspec URLs are not supported)")
    run.add_argument("--timeout", type=float, default=600.0, metavar="S",
                     help="seconds an asset may take; its worker is then killed and the row "
                          "says timeout (0: no limit; default %(default)g)")
    run.add_argument("--memory-limit", default="auto", metavar="SIZE",
                     help="resident memory a worker may hold, e.g. 4G or 512M; over it the "
                          "worker is killed and the row says memory (0: no limit; default auto: "
                          "the machine's memory over the workers; on Dask each worker's limit "
                          "over its threads)")
    run.add_argument("--restart-every", type=int, default=20, metavar="K",
                     help="restart a worker that loaded Blender (rig outputs) after K assets, "
                          "as Blender grows over long runs (0: never; default %(default)s)")
    run.add_argument("--quiet", "-q", action="store_true",
                     help="print nothing but errors (no progress bar, no summary)")
    run.add_argument("--debug", action="store_true", help="show a traceback on errors")
    run.add_argument("--version", action="version", version=f"curveskel {__version__}")
    out = ap.add_argument_group("outputs beside each skeleton JSON (need Blender as a Python "
                                "module, bpy)")
    out.add_argument("--glb", action="store_true", help="the rigged mesh + armature, glTF")
    out.add_argument("--fbx", action="store_true", help="the rigged mesh + armature, FBX")
    out.add_argument("--blend", action="store_true",
                     help="the Blender scene the add-on's operator makes (mesh, armature, "
                          "silhouette)")
    out.add_argument("--bind", action="store_true",
                     help="bind the mesh in the .blend (.glb and .fbx are always bound)")
    ap.add_argument("--quality", action="store_true",
                    help="quality measures in each JSON's meta and the table")
    ap.add_argument("--paper", action="store_true",
                    help="the paper's method exactly (as curveskel skeletonize --paper)")
    _add_method_options(ap)
    return ap


def _add_method_options(ap) -> None:
    """The method parameters, as ``curveskel skeletonize`` has them (same names, same help)."""
    g_art = ap.add_argument_group("skeleton settings (the Blender panel's)")
    g_adv = ap.add_argument_group("advanced method parameters (as curveskel skeletonize)")
    defaults = SkeletonParams()
    for f in fields(SkeletonParams):
        g = g_art if f.name in SkeletonParams.ARTIST else g_adv
        flag = "--" + f.name.replace("_", "-")
        val = getattr(defaults, f.name)
        text = _HELP.get(f.name, "")
        if isinstance(val, bool):
            g.add_argument(flag, dest=f.name, action=argparse.BooleanOptionalAction, default=None,
                           help=text + f" (default {'on' if val else 'off'})")
        elif f.name == "solver":
            g.add_argument(flag, dest=f.name, choices=SOLVERS, default=None,
                           help=text % {"default": val})
        else:
            g.add_argument(flag, dest=f.name, type=type(val), default=None,
                           help=text % {"default": val})


def _cores() -> int:
    from ..batch.driver import default_workers

    return default_workers()


def main(argv=None, prog: str = "curveskel batch") -> int:
    """Run the command with ``argv`` (default sys.argv[1:]); returns the exit status."""
    from ..batch import BatchInterrupted, run

    _install_stop_handlers()
    args = None
    try:
        args = build_parser(prog).parse_intermixed_args(argv)   # IN... before or after options
        res = run(args.inputs, args.out, workers=args.workers, client=args.dask,
                  params=params_from_args(args), glb=args.glb, fbx=args.fbx, blend=args.blend,
                  bind=args.bind, quality=args.quality, timeout=args.timeout,
                  memory_limit=args.memory_limit, restart_every=args.restart_every,
                  root=args.root, progress=not args.quiet)
    except CurveSkelError as exc:
        _say(sys.stderr, f"error: {exc}\n")
        return 2
    except BatchInterrupted as exc:
        signum = exc.signum or signal.SIGINT
        _report(exc.results, args)
        _say(sys.stderr, f"{_SAID.get(signal.Signals(signum).name, 'stopped')}: the table of "
                         f"the {len(exc.results)} assets done is written\n")
        return 128 + int(signum)
    except KeyboardInterrupt as exc:             # before the batch started
        return 128 + int(getattr(exc, "signum", signal.SIGINT))
    except Exception as exc:  # never a raw traceback for users; --debug shows it
        if args is not None and args.debug:
            raise
        _say(sys.stderr, f"error: unexpected {type(exc).__name__}: {exc} "
                         "(run with --debug for details)\n")
        return 1
    _report(res, args)
    return 0 if all(r["status"] == "ok" for r in res) else 1


_SAID = {"SIGINT": "interrupted", "SIGTERM": "terminated (SIGTERM)", "SIGHUP": "hung up (SIGHUP)"}


def _report(res, args) -> None:
    if args is None or args.quiet:
        return
    _say(sys.stdout, res.summary + f"results     {res.out / 'results.jsonl'}, "
                                   f"{res.out / 'results.csv'}\n")
