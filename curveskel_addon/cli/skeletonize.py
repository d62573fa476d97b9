"""``curveskel skeletonize``: the curve-skeleton of one mesh file (also ``scripts/skeletonize.py``).

    curveskel skeletonize MESH [--json OUT.json] [--blend OUT.blend] [--render OUT.png]
                               [--bind --glb OUT.glb | --fbx OUT.fbx] [method options]
    curveskel skeletonize MESH --evaluate SKEL.json [--report OUT.json]
    curveskel skeletonize MESH --refine SKEL.json [--json OUT.json] [--report OUT.json]
    curveskel skeletonize MESH --compare A.json B.json [--report OUT.json]

Reads .obj .ply .stl .off, runs the curveskel core, writes the outputs asked for, then prints
vertices, components, joints, bones, J (first -> returned) with its terms, the search's stages,
the paper's E and the time of every stage (stdout; ``--quiet``: nothing). Progress goes to stderr for runs longer than a second. Errors are one
line (exit status 2); ``--debug`` shows a traceback.

No file is ever lost or damaged (:mod:`.outputs`): every output path is checked before the
computation, each output is written to a temporary file beside it and renamed over the old one
only when complete; the summary is printed after the files are written, so a closed stdout
(``... | head -0``) loses nothing and does not change the exit status. Ctrl-C, SIGTERM and
SIGHUP remove the temporary files and exit with 128 + the signal's number (130, 143, 129).
"""

from __future__ import annotations

import argparse
import io
import os
import re
import signal
import sys
import time
from dataclasses import fields
from pathlib import Path

import numpy as np

from .. import __version__
from ..core import SOLVERS, CurveSkelError, Skeleton, SkeletonParams, SkeletonRun
from ..measure.quality import quality
from ..mesh_files import read_mesh
from ..run_summary import energy_text, moves_text, summary, terms_text
from .outputs import Output, check_outputs, commit, kept, remove_temps, temp_path
from . import evaluation
from .progress import Progress

__all__ = ["build_parser", "main", "run", "params_from_args", "print_summary"]

_HELP = {
    # the artist's settings (the Blender panel shows these)
    "spacing": "detail size: the first approximation's spacing, the distance between its "
               "contour levels as a fraction of each part's size (smaller finds smaller parts; "
               "default %(default)s)",
    "smoothness": "smoothness of the curve: the weight of J's smoothness term (how much chains "
                  "turn and radii bend): 0 follows the cross-sections' centres exactly, 10 is "
                  "nearly straight between junctions (default %(default)s)",
    "prune": "branch pruning: the price of a branch (a tip) in J; a branch stays only where it "
             "explains more of the surface than it costs (0 = keep every branch the first "
             "approximation found; default %(default)s)",
    "max_joints": "a hard upper bound on the skeleton's joints (0 = no limit; default "
                  "%(default)s)",
    # advanced
    "solver": "'lm' = the search for the minimum of J (Levenberg-Marquardt on the joints and "
              "radii, topology moves kept only when J falls); 'paper' = the paper's method "
              "(gradient descent on E with the exact line search, eqs. 28-31; --paper also "
              "sets the paper's other settings) (default %(default)s)",
    "max_iterations": "lm: at most this many steps per minimisation of J between the search's "
                      "moves (the last one, to convergence, takes up to 100 at least); paper: "
                      "gradient-descent iterations (default %(default)s)",
    "tolerance": "paper: stop when an iteration lowers E by less than TOLERANCE * E0 (the "
                 "paper's 1e-3; default %(default)s)",
    "seed": "where the pole search starts: 0 (default) starts at the vertex farthest from the "
            "centroid (the same skeleton whatever the mesh's numbering, position or rotation), "
            "any other value at a random vertex drawn from it, as in the paper. It moves the "
            "pole, so it can change which branches the first approximation finds and the "
            "joint count; it also draws the subset of surface samples above the sampling's "
            "budget",
    "min_component_area": "drop connected parts with less than this share of the total area "
                          "(scan debris; their vertices follow the nearest kept part; "
                          "0 = keep all; default %(default)s)",
    "separate_parts": "one skeleton per connected part, as the parts are modelled (by default "
                      "parts that overlap or nearly touch are joined where they meet, and small "
                      "free parts hang from the nearest larger part: one tree)",
}

_OUTPUT_POLICY = (
    "Outputs: each is written to a temporary file beside it and renamed over the old file "
    "only when complete. A path that exists must be a regular file (a directory, FIFO or "
    "device such as /dev/null is refused); a symbolic link is followed and the file it points "
    "to is replaced (the link stays); the replaced file keeps its permissions; a read-only "
    "file is refused. Ctrl-C, SIGTERM and SIGHUP leave no temporary file behind.")


class _Parser(argparse.ArgumentParser):
    """argparse with the CLI's one-line errors (``error: ...``, exit 2) instead of usage + error."""

    def error(self, message):
        _say(sys.stderr, f"error: {message} (see --help)\n")
        sys.exit(2)


def build_parser(prog: str = "curveskel skeletonize") -> argparse.ArgumentParser:
    """The command's argument parser (``prog``: the name shown in usage and errors)."""
    ap = _Parser(
        prog=prog,
        description="Curve-skeleton of a mesh file (curveskel). Writes the outputs asked for, "
                    "then prints a summary; writes the skeleton as curveskel-skeleton/1 JSON "
                    "with --json.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog=_OUTPUT_POLICY + "\n\nProgress (stage and bar) goes to stderr once a run takes "
               "more than a second: redrawn in place on a terminal, one line per stage "
               "otherwise; --quiet prints nothing but errors.\n\n"
               f"Example: {prog} examples/spot.obj --json out/spot.json")
    ap.add_argument("mesh", type=Path, help="mesh file: .obj, .ply, .stl or .off")
    ap.add_argument("--json", type=Path, metavar="OUT.json", help="write the skeleton as JSON")
    ap.add_argument("--paper", action="store_true",
                    help="the paper's method exactly: its first approximation, then gradient "
                         "descent on E (eq. 20, the vertex sum) with the exact line search, "
                         "stopped as in eqs. 30-31 (SkeletonParams.paper(); options given "
                         "replace its fields)")
    ap.add_argument("--quality", action="store_true",
                    help="compute the quality measures (energy, reconstruction distance, inside "
                         "fraction, topology) and store them in the JSON meta")
    ap.add_argument("--quiet", "-q", action="store_true",
                    help="print nothing but errors (no progress, no summary)")
    ap.add_argument("--version", action="version", version=f"curveskel {__version__}")
    ap.add_argument("--debug", action="store_true", help="show a traceback on errors")
    r = ap.add_argument_group("rigging (needs Blender as a Python module, bpy)")
    r.add_argument("--bind", action="store_true",
                   help="build the armature in Blender and skin the mesh to it (skeleton-mapping "
                        "weights); needs an output that takes the rig: --glb, --fbx or --blend")
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
    b.add_argument("--blend-backup", action="store_true",
                   help="keep the .blend being replaced as OUT.blend1 (Blender's backup); "
                        "by default no backup file is left")
    evaluation.add_arguments(ap)
    g_art = ap.add_argument_group("skeleton settings (the Blender panel's)")
    g_adv = ap.add_argument_group("advanced method parameters (the Blender panel's Advanced)")
    defaults = SkeletonParams()
    for f in fields(SkeletonParams):
        g = g_art if f.name in SkeletonParams.ARTIST else g_adv
        flag = "--" + f.name.replace("_", "-")
        val = getattr(defaults, f.name)
        if isinstance(val, bool):
            g.add_argument(flag, dest=f.name, action=argparse.BooleanOptionalAction, default=None,
                           help=_HELP.get(f.name, "") + f" (default {'on' if val else 'off'})")
        elif f.name == "solver":
            g.add_argument(flag, dest=f.name, choices=SOLVERS, default=None,
                           help=_HELP[f.name] % {"default": val})
        else:
            g.add_argument(flag, dest=f.name, type=type(val), default=None,
                           help=_HELP.get(f.name, "") % {"default": val})
    return ap


def params_from_args(args) -> SkeletonParams:
    """The method parameters the arguments ask for (``--paper``'s, else the defaults, with
    each option given replacing its field)."""
    base = SkeletonParams.paper() if args.paper else SkeletonParams()
    d = base.to_dict()
    for f in fields(SkeletonParams):
        v = getattr(args, f.name, None)
        if v is not None:
            d[f.name] = v
    return SkeletonParams.from_dict(d)


def print_summary(path, V, sk, seconds: float, out=sys.stdout) -> None:
    """The run's summary on ``out``: mesh, repairs, skeleton, J and its terms (issue 30), the
    search's stages, the paper's E, times (and quality)."""
    s = summary(sk)
    info = sk.meta.get("input", {})
    print(f"mesh        {path}: {len(V)} vertices, {info.get('input_faces', '?')} triangles, "
          f"{s['components']} component(s)", file=out)
    repaired = {k: v for k, v in info.items()
                if k in _REPAIRS and v}
    if repaired:
        print("repaired    " + ", ".join(f"{_REPAIRS[k]}: {v}" for k, v in repaired.items()), file=out)
    if info.get("small_components_dropped"):
        if info.get("min_component_area"):
            rule = f"under {100 * info['min_component_area']:g} % of the area each"
        else:
            rule = "smaller than the Detail Size against their nearest neighbour"
        print(f"dropped     {info['small_components_dropped']} small part(s) {rule} "
              f"({100 * info['small_components_area_share']:.2g} % in all, "
              f"{info['small_components_vertices']} vertices, mapped to the nearest kept part)",
              file=out)
    print(f"skeleton    {s['joints']} joints, {s['bones']} bones", file=out)
    if s["solver"] == "paper":
        print(f"objective   E {s['J0']:.6g} -> {s['J']:.6g} in {s['iterations']} iterations "
              "(solver paper: the paper's gradient descent on E, eq. 20, the vertex sum)", file=out)
    else:
        moves = moves_text(s)
        samples = sk.meta.get("samples")
        print(f"objective   J {s['J0']:.6g} -> {s['J']:.6g} in {s['stages']} stages"
              + (f" ({moves})" if moves else "")
              + f", {s['iterations']} minimisation steps"
              + (f", over {samples:,} surface samples" if samples else "")
              + " (solver lm)", file=out)
        text = terms_text(sk)
        if text:
            print(f"terms       {text}", file=out)
        print(f"energy      {energy_text(s)}", file=out)
    stages = " | ".join(f"{k} {v:.3f}" for k, v in sk.timings.items())
    print(f"time (s)    {stages}", file=out)
    print(f"total       {seconds:.3f} s", file=out)
    q = sk.meta.get("quality")
    if q:
        print("quality     " + ", ".join(f"{k} {v:.4g}" if isinstance(v, float) else f"{k} {v}"
                                         for k, v in _flat(q).items()), file=out)


#: meta["input"] counts printed on the "repaired" line, with their wording.
_REPAIRS = {
    "merged_duplicates": "merged duplicate vertices",
    "merged_within_tolerance": "of them within the tolerance",
    "degenerate_faces_dropped": "degenerate faces dropped",
    "isolated_vertices": "isolated vertices",
    "flipped_faces": "faces turned outwards",
    "flat_components_dropped": "flat parts left out",
    "open_fragments_dropped": "loose triangles/strips left out",
}


def _flat(d, prefix=""):
    out = {}
    for k, v in d.items():
        if isinstance(v, dict):
            out.update(_flat(v, prefix + k + "."))
        elif isinstance(v, (int, float, str, bool)):
            out[prefix + k] = v
    return out


# -- the run ----------------------------------------------------------------------------------------
#: The flags that take a bound rig (--bind alone would compute it and write nothing).
_BIND_OUTPUTS = ("glb", "fbx", "blend")


def run(args, report=None, progress=None) -> int:
    """Check the outputs, skeletonize, write every output, then print the summary.

    Parameters
    ----------
    args : argparse.Namespace from :func:`build_parser`
    report : io.StringIO, optional
        Where the summary is gathered; printed to stdout after the last file is written.
    progress : Progress, optional
        The stderr progress reporter (default: one for this run, silent with ``--quiet``).

    Returns
    -------
    int : the exit status (0).
    """
    evaluation.check(args)
    if args.bind and not any(getattr(args, f) for f in _BIND_OUTPUTS):
        raise CurveSkelError("--bind needs an output that takes the bound rig: --glb OUT.glb, "
                             "--fbx OUT.fbx or --blend OUT.blend (nothing would be written)")
    outs = check_outputs(args)
    params = params_from_args(args)
    report = io.StringIO() if report is None else report
    progress = Progress(enabled=not args.quiet) if progress is None else progress
    if evaluation.requested(args):       # an outside skeleton judged by J (issue 33)
        rc = evaluation.run(args, outs, params, report, progress)
        progress.close()
        return rc
    t0 = time.perf_counter()
    progress("read", 0.0)
    V, F = read_mesh(args.mesh)
    sk_run = SkeletonRun(V, F, params, progress)
    sk = sk_run.result()
    if args.quality:
        progress("quality", 0.0)
        sk.meta["quality"] = quality(V, F, sk)
    seconds = time.perf_counter() - t0
    print_summary(args.mesh, V, sk, seconds, out=report)
    if "json" in outs:
        progress("write", 0.0)
        write_json(sk, outs["json"])
        print(f"wrote       {args.json}", file=report)
    if args.bind or args.glb or args.fbx or args.blend or args.render:
        progress("blender", 0.0)
        _import_bpy()
    # --bind with --blend / --render: the operator binds the mesh it saves (one import, one rig);
    # a rig of its own only for the exports
    if args.glb or args.fbx:
        rig_outputs(args, outs, V, sk, report)
    if args.blend or args.render:
        blender_outputs(args, outs, params, report)
    progress.close()
    return 0


def write_json(sk, out: Output) -> None:
    """The skeleton as JSON, written whole or not at all."""
    for name in ("joints", "t"):
        if not np.all(np.isfinite(np.asarray(getattr(sk, name), dtype=float))):
            raise CurveSkelError(f"the result has non-finite {name} (a bug; please report it): "
                                 "no JSON written")
    tmp = temp_path(out)
    try:
        sk.save(tmp)
    except OSError as exc:
        remove_temps()
        raise CurveSkelError(f"could not write --json {out.given}: {exc.strerror or exc}; {kept(out)}") from None
    commit(tmp, out)


def _last_error(exc) -> str:
    """The line that says what went wrong in a message holding a Blender traceback."""
    lines = [ln.strip() for ln in str(exc).strip().splitlines() if ln.strip()]
    errors = [ln for ln in lines if re.match(r"^[A-Za-z_.]*(Error|Exception): ", ln)]
    return errors[-1] if errors else (lines[0] if lines else type(exc).__name__)


def blender_outputs(args, outs: dict, params, report) -> None:
    """--blend/--render: the same operator the Blender UI runs (curveskel_addon.headless)."""
    from .. import headless   # imports bpy: only when a Blender output is asked for

    blend = temp_path(outs["blend"]) if "blend" in outs else None
    render = temp_path(outs["render"]) if "render" in outs else None
    res = headless.cli_outputs(args.mesh, params.to_dict(), blend=blend, render=render,
                               bind=args.bind)
    arm = res["armature"]
    print(f"blender     {arm.name}: {arm['curveskel_n_joints']} joints, {arm['curveskel_n_bones']} bones, "
          f"operator {res['operator_seconds']:.2f} s", file=report)
    if blend is not None:
        commit(blend, outs["blend"], backup=args.blend_backup)
        print(f"wrote       {args.blend}", file=report)
    if render is not None:
        commit(render, outs["render"])
        print(f"wrote       {args.render} (render {res['render_seconds']:.1f} s)", file=report)


def rig_outputs(args, outs: dict, V, sk, report) -> None:
    """--glb/--fbx: import the mesh into Blender, armature + binding from ``sk``, export."""
    # the Blender side only when a rig is asked for: the command line runs without bpy
    import bpy

    from .. import headless
    from ..export import export_rig
    from ..ops_generate import build_result

    headless.reset_scene()
    ob = headless.import_mesh(args.mesh)
    co = np.empty(len(ob.data.vertices) * 3)
    ob.data.vertices.foreach_get("co", co)
    if len(co) != 3 * len(V) or np.abs(co.reshape(-1, 3) - V).max() > 1e-5 * max(float(np.ptp(V)), 1e-12):
        # Blender's importer changed the vertices: bind by closest point on the bones instead.
        sk = Skeleton(sk.joints, sk.bones, [], [], energy=sk.energy, timings=sk.timings, meta=sk.meta)
    options = {**sk.meta.get("params", {}), "make_armature": True, "make_silhouette": False,
               "silhouette_in_render": False, "bind": True}
    found = build_result(bpy.context, ob, sk, options)
    arm = found["armature"]
    print(f"rig         {len(arm.data.bones)} bones, {len(ob.vertex_groups)} vertex groups", file=report)
    for flag in ("glb", "fbx"):
        if flag in outs:
            o = outs[flag]
            tmp = temp_path(o)
            try:
                res = export_rig(bpy.context, ob, arm, tmp)
            except CurveSkelError as exc:    # the exporter's traceback: say what went wrong
                remove_temps()
                raise CurveSkelError(f"could not write --{flag} {o.given}: {_last_error(exc)}; {kept(o)}") from None
            commit(tmp, o)
            print(f"wrote       {o.given} ({res['format']}, {res['seconds']:.2f} s)", file=report)


# -- signals ----------------------------------------------------------------------------------------
#: The signals that stop a run cleanly: temporary files removed, exit 128 + the number.
STOP_SIGNALS = tuple(getattr(signal, n) for n in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, n))
_SAID = {"SIGINT": "interrupted", "SIGTERM": "terminated (SIGTERM)", "SIGHUP": "hung up (SIGHUP)"}


class Interrupted(KeyboardInterrupt):
    """A stop signal arrived (SIGTERM, SIGHUP; SIGINT is Python's own KeyboardInterrupt). A
    KeyboardInterrupt, so nothing that catches Exception swallows it."""

    def __init__(self, signum: int):
        super().__init__(signum)
        self.signum = signum


def _raise_interrupted(signum, frame) -> None:
    raise Interrupted(signum)


def _install_stop_handlers() -> None:
    """SIGTERM and SIGHUP stop the run as Ctrl-C does (the default action would kill the
    process and leave its temporary files)."""
    for s in STOP_SIGNALS:
        if s != signal.SIGINT:
            signal.signal(s, _raise_interrupted)


def _import_bpy() -> None:
    """Import bpy with the stop signals handled by :func:`_exit_on_signal` from here on.

    A KeyboardInterrupt raised inside bpy's start-up, or inside an operator, is caught and
    printed by Blender, which then crashes or carries on; so from the Blender stage on a stop
    signal removes the temporary files and leaves at once instead (set again after the import,
    in case Blender installed handlers of its own)."""
    for s in STOP_SIGNALS:
        signal.signal(s, _exit_on_signal)
    # Blender's start-up installs signal handlers of its own (bpy 5.2 puts SIGINT back to the
    # default action, which kills the process with no clean-up): hold the signals back while
    # bpy loads, then deliver a pending one to our handler.
    blocked = hasattr(signal, "pthread_sigmask")
    if blocked:
        signal.pthread_sigmask(signal.SIG_BLOCK, set(STOP_SIGNALS))
    try:
        import bpy  # noqa: F401
    finally:
        for s in STOP_SIGNALS:
            signal.signal(s, _exit_on_signal)
        if blocked:
            signal.pthread_sigmask(signal.SIG_UNBLOCK, set(STOP_SIGNALS))


def _exit_on_signal(signum, frame) -> None:
    _interrupted(signum)


def _interrupted(signum: int = signal.SIGINT) -> int:
    """A stop signal: remove the temporary files, say so, return 128 + its number. Once bpy is
    (even partly) loaded the interpreter's normal shutdown can crash inside Blender: leave at
    once instead."""
    for s in STOP_SIGNALS:
        signal.signal(s, signal.SIG_IGN)             # a second signal must not cut the clean-up
    remove_temps()
    name = signal.Signals(signum).name
    _say(sys.stderr, _SAID.get(name, f"stopped by {name}") + "\n")
    rc = 128 + int(signum)
    if "bpy" in sys.modules or "_bpy" in sys.modules:
        _flush_all()
        os._exit(rc)
    return rc


# -- entry point ------------------------------------------------------------------------------------
def main(argv=None, prog: str = "curveskel skeletonize") -> int:
    """Run the command with ``argv`` (default sys.argv[1:]); returns the exit status."""
    _install_stop_handlers()
    args = None
    report = io.StringIO()
    progress = Progress(enabled=False)
    try:
        ap = build_parser(prog)
        args = ap.parse_args(argv)
        progress = Progress(enabled=not args.quiet)
        rc = run(args, report, progress)
    except CurveSkelError as exc:
        remove_temps()
        progress.close()
        _say(sys.stderr, f"error: {exc}\n")
        return 2
    except KeyboardInterrupt as exc:
        progress.close()
        return _interrupted(getattr(exc, "signum", signal.SIGINT))
    except Exception as exc:  # never a raw traceback for users; --debug shows it
        remove_temps()
        progress.close()
        if args is not None and args.debug:
            raise
        _say(sys.stderr, f"error: unexpected {type(exc).__name__}: {exc} (run with --debug for details)\n")
        return 1
    _finish()
    if not args.quiet:
        _say(sys.stdout, report.getvalue())
    return rc


def _finish() -> None:
    """Every output is written: a stop signal from here on has nothing left to clean up. A
    Ctrl-C is ignored (the interpreter's shutdown puts a handled SIGINT back to the default
    action, so a late one would kill the process by signal after a complete run); SIGTERM and
    SIGHUP take their default action."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    for s in STOP_SIGNALS:
        if s != signal.SIGINT:
            signal.signal(s, signal.SIG_DFL)


def _say(stream, text: str) -> None:
    """Write ``text`` to ``stream`` and flush; a closed or broken stream (``| head -0``,
    a hung-up terminal) is let go: the files are written, the exit status stays."""
    if stream is None or not text:
        return
    try:
        stream.write(text)
        stream.flush()
    except (OSError, ValueError):
        _silence(stream)


def _silence(stream) -> None:
    """Point a broken stream's descriptor at /dev/null, so the interpreter's final flush does
    not fail again (and turn a written run into exit status 120)."""
    try:
        fd = stream.fileno()
        null = os.open(os.devnull, os.O_WRONLY)
        os.dup2(null, fd)
        os.close(null)
    except (OSError, ValueError, AttributeError):
        pass


def _flush_all() -> None:
    for s in (sys.stdout, sys.stderr):
        try:
            s.flush()
        except (OSError, ValueError, AttributeError):
            _silence(s)
