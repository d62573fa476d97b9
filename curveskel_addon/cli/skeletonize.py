#!/usr/bin/env python3
"""Skeletonize mesh files from the command line.

    python scripts/skeletonize.py MESH [--json OUT.json] [--blend OUT.blend] [--render OUT.png]
                                       [method options]

Reads .obj .ply .stl .off, runs the curveskel core and prints vertices, components, joints,
bones, E0 -> E, iterations and the time of every stage. Errors are reported in one line
(exit status 2) — use --debug for a traceback.

No file is ever lost: every output path is checked before the computation (never the input
mesh, a writable folder), each output is written to a temporary file beside it, checked
complete, and renamed over the old one only then; a failed write keeps the old file and exits
non-zero. Ctrl-C prints "interrupted", removes the temporary files and exits with 130.
"""

from __future__ import annotations

import argparse
import os
import shutil
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
    # the artist's settings (the Blender panel shows these)
    "spacing": "detail: distance between cross-sections as a fraction of each part's size "
               "(smaller finds smaller parts, more joints; default %(default)s)",
    "smoothness": "smoothness of the curve along chains: 0 follows the medial axis exactly, "
                  "10 is nearly straight between branchings (default %(default)s)",
    "prune": "remove a leaf branch reaching out of its junction by less than this many of its "
             "own radii: a bump, not a part (0 = keep all; default %(default)s)",
    "max_joints": "simplify chains until the skeleton has at most this many joints "
                  "(0 = no limit; default %(default)s)",
    # advanced
    "solver": "optimiser of the final fit: 'paper' = gradient descent with exact line search "
              "(eqs. 28-31), 'lm' = Levenberg-Marquardt, converges (default %(default)s)",
    "max_iterations": "upper bound on optimiser iterations (default %(default)s)",
    "tolerance": "stop when an iteration lowers E by less than TOLERANCE * E0 (paper: 1e-3; default %(default)s)",
    "seed": "seed of the random first vertex of the pole search (default %(default)s)",
    "area_weighted": "weight vertices by their area: the surface integral of eq. 8 instead of a vertex sum",
    "refit_mapping": "re-fit each vertex's skeleton point to the closest bone point between solver "
                     "steps (lets bones fill the volume; off by default)",
    "centre": "centre the curve on the medial axis and simplify it (off = the paper's first "
              "approximation, as with --paper)",
    "centring": "weight holding each joint to its centred place while E is fitted "
                "(0 = free; default %(default)s)",
    "containment": "weight of a term keeping joints and points along the bones inside the mesh "
                   "with their balls (lm only; 0 = off; default %(default)s)",
    "simplify": "merge chain joints while the chain stays within this fraction of the local "
                "radius (0 = off; default %(default)s)",
    "max_fit_points": "above this many vertices fit an area-weighted random subset of this size "
                      "(0 = all; default %(default)s)",
    "min_component_area": "drop connected parts with less than this share of the total area "
                          "(scan debris; their vertices follow the nearest kept part; "
                          "0 = keep all; default %(default)s)",
}


class _Parser(argparse.ArgumentParser):
    """argparse with the CLI's one-line errors (``error: ...``, exit 2) instead of usage + error."""

    def error(self, message):
        sys.stderr.write(f"error: {message} (see --help)\n")
        sys.exit(2)


def build_parser() -> argparse.ArgumentParser:
    ap = _Parser(
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
    b.add_argument("--blend-backup", action="store_true",
                   help="keep the .blend being replaced as OUT.blend1 (Blender's backup); "
                        "by default no backup file is left")
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
                if k in _REPAIRS and v}
    if repaired:
        print("repaired    " + ", ".join(f"{_REPAIRS[k]}: {v}" for k, v in repaired.items()), file=out)
    if info.get("small_components_dropped"):
        print(f"dropped     {info['small_components_dropped']} small part(s) under "
              f"{100 * info['min_component_area']:g} % of the area each "
              f"({100 * info['small_components_area_share']:.2g} % in all, "
              f"{info['small_components_vertices']} vertices, mapped to the nearest kept part); "
              "--min-component-area 0 keeps them", file=out)
    print(f"skeleton    {s['joints']} joints, {s['bones']} bones", file=out)
    meta = sk.meta
    sampled = []
    if meta.get("fit_points_subset"):
        sampled.append(f"fit on {meta['fit_points']:,} area-weighted vertices (--max-fit-points)")
    if meta.get("medial_points_subset"):
        sampled.append(f"medial balls against {meta['medial_points']:,} area-weighted surface points")
    if sampled:
        print(f"sampled     {'; '.join(sampled)} of {len(V):,}", file=out)
    print(f"energy      E0 {s['E0']:.6g} -> E {s['E_fit']:.6g} in {s['iterations']} iterations "
          f"(solver {sk.meta.get('params', {}).get('solver', '?')})"
          + (f"; E {s['E']:.6g} for the returned skeleton (radii fitted to the silhouette, "
             "joints to their sections' centres)" if s["E"] != s["E_fit"] else ""), file=out)
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


# -- outputs: checked before the run, written to a temporary file, renamed when complete --------
#: temporary files of this run still on disk (removed on any failure or interrupt)
_TEMPS: set[Path] = set()
#: the output options, in the order they are written
OUTPUT_FLAGS = ("json", "glb", "fbx", "blend", "render")
_SUFFIX_NEEDED = {"glb": ".glb", "fbx": ".fbx"}


def check_outputs(args) -> dict[str, Path]:
    """The output paths given, each checked before anything runs: not the input mesh, not
    two options naming one file, not a directory, in a folder that exists or can be created
    and can be written. Raises CurveSkelError with one clear line."""
    mesh = Path(args.mesh).resolve()
    outs: dict[str, Path] = {}
    for flag in OUTPUT_FLAGS:
        path = getattr(args, flag, None)
        if path is None:
            continue
        path = Path(path)
        opt = "--" + flag
        res = path.resolve()
        if res == mesh or (path.exists() and mesh.exists() and os.path.samefile(path, mesh)):
            raise CurveSkelError(f"{opt} {path} is the input mesh: refusing to overwrite it")
        for other, p in outs.items():
            if p.resolve() == res:
                raise CurveSkelError(f"--{other} and {opt} name the same file {path}")
        need = _SUFFIX_NEEDED.get(flag)
        if need and path.suffix.lower() != need:
            raise CurveSkelError(f"{opt} {path}: the file name must end in {need}")
        if path.is_dir():
            raise CurveSkelError(f"cannot write {opt} {path}: it is a directory")
        folder = res.parent
        while not folder.exists():
            folder = folder.parent
        if not folder.is_dir():
            raise CurveSkelError(f"cannot write {opt} {path}: {folder} is a file, not a folder")
        if not os.access(folder, os.W_OK | os.X_OK):
            raise CurveSkelError(f"cannot write {opt} {path}: the folder {folder} is not writable")
        if folder == res.parent:
            _probe(folder, opt, path)
        outs[flag] = path
    return outs


def _probe(folder: Path, opt: str, path: Path) -> None:
    """Create and remove a file in ``folder`` (a read-only file system passes os.access)."""
    import tempfile

    try:
        fd, name = tempfile.mkstemp(prefix=".curveskel-probe-", dir=folder)
    except OSError as exc:
        raise CurveSkelError(f"cannot write {opt} {path}: cannot create a file in {folder} ({exc.strerror or exc})") from None
    os.close(fd)
    os.unlink(name)


def temp_path(path: Path) -> Path:
    """A new temporary file name beside ``path``, with its suffix (exporters go by it); the
    folder is created if needed. Registered in _TEMPS until committed or removed."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}{path.suffix}")
    _TEMPS.add(tmp)
    return tmp


def remove_temps() -> None:
    for tmp in list(_TEMPS):
        for p in (tmp, Path(str(tmp) + "@")):         # Blender writes "<name>@" then renames
            try:
                p.unlink()
            except OSError:
                pass
        _TEMPS.discard(tmp)


_PNG_END = b"IEND\xaeB`\x82"
_FBX_END = bytes.fromhex("f85a8c6adef5d97eece90ce3758f290b")
_ZSTD_SEEKABLE_END = bytes.fromhex("b1ea928f")


def incomplete(path: Path) -> str | None:
    """Why the file a writer left at ``path`` is not complete (None when it is). Blender's
    writers ignore a full disk and leave a truncated file: each format's end is checked."""
    try:
        size = path.stat().st_size
    except OSError:
        return "no file was written"
    if size == 0:
        return "the file is empty"
    kind = path.suffix.lower()
    with open(path, "rb") as fh:
        head = fh.read(16)
        fh.seek(max(0, size - 64))
        tail = fh.read()
    if kind == ".blend":
        if not (tail.endswith(_ZSTD_SEEKABLE_END) or b"ENDB" in tail):
            return "the .blend file is truncated"
    elif kind == ".png":
        if not tail.endswith(_PNG_END):
            return "the PNG file is truncated"
    elif kind == ".glb":
        if head[:4] != b"glTF" or int.from_bytes(head[8:12], "little") != size:
            return "the .glb file is truncated"
    elif kind == ".fbx":
        if head.startswith(b"Kaydara FBX Binary") and not tail.endswith(_FBX_END):
            return "the .fbx file is truncated"
    return None


def commit(tmp: Path, path: Path, opt: str, *, backup: bool = False) -> None:
    """Check the temporary file ``tmp`` is complete, flush it to disk and rename it to ``path``
    (atomic: ``path`` is the old file or the new one, never a part). Otherwise remove it,
    keep the old file and raise CurveSkelError."""
    why = incomplete(tmp)
    try:
        if why is None:
            fd = os.open(tmp, os.O_RDONLY)
            try:
                os.fsync(fd)
            finally:
                os.close(fd)
            if backup and path.exists():
                shutil.copy2(path, path.with_name(path.name + "1"))
            os.replace(tmp, path)
            _TEMPS.discard(tmp)
            return
    except OSError as exc:
        why = exc.strerror or str(exc)
    remove_temps()
    kept = "the previous file is kept" if path.exists() else "nothing was written"
    raise CurveSkelError(f"could not write {opt} {path}: {why} (disk full?); {kept}")


def _last_error(exc) -> str:
    """The line that says what went wrong in a message holding a Blender traceback."""
    import re

    lines = [ln.strip() for ln in str(exc).strip().splitlines() if ln.strip()]
    errors = [ln for ln in lines if re.match(r"^[A-Za-z_.]*(Error|Exception): ", ln)]
    return errors[-1] if errors else (lines[0] if lines else type(exc).__name__)


def write_json(sk, path: Path) -> None:
    """The skeleton as JSON, written whole or not at all."""
    import numpy as np

    for name in ("joints", "t"):
        if not np.all(np.isfinite(np.asarray(getattr(sk, name), dtype=float))):
            raise CurveSkelError(f"the result has non-finite {name} (a bug; please report it): "
                                 "no JSON written")
    tmp = temp_path(path)
    try:
        sk.save(tmp)
    except OSError as exc:
        remove_temps()
        kept = "the previous file is kept" if path.exists() else "nothing was written"
        raise CurveSkelError(f"could not write --json {path}: {exc.strerror or exc}; {kept}") from None
    commit(tmp, path, "--json")


def run(args) -> int:
    check_outputs(args)
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
        write_json(sk, args.json)
        print(f"wrote       {args.json}", flush=True)
    if args.bind or args.glb or args.fbx or args.blend or args.render:
        print("blender     loading Blender (bpy) ...", flush=True)
        _import_bpy()
    # --bind with --blend / --render: the operator binds the mesh it saves (one import, one rig);
    # a rig of its own only for the exports, or for --bind alone (a check)
    if args.glb or args.fbx or (args.bind and not (args.blend or args.render)):
        rig_outputs(args, V, sk)
    if args.blend or args.render:
        blender_outputs(args, params)
    return 0


def _import_bpy() -> None:
    """Import bpy with Ctrl-C handled by :func:`_exit_on_sigint` from here on.

    A KeyboardInterrupt raised inside bpy's start-up, or inside an operator, is caught and
    printed by Blender, which then crashes or carries on; so from the Blender stage on Ctrl-C
    removes the temporary files and leaves at once instead (set again after the import, in
    case Blender installed its own handler)."""
    import signal

    signal.signal(signal.SIGINT, _exit_on_sigint)
    # Blender's start-up installs signal handlers of its own (bpy 5.2 puts SIGINT back to the
    # default action, which kills the process with no clean-up): hold Ctrl-C back while bpy
    # loads, then deliver a pending one to our handler.
    blocked = hasattr(signal, "pthread_sigmask")
    if blocked:
        signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        import bpy  # noqa: F401
    finally:
        signal.signal(signal.SIGINT, _exit_on_sigint)
        if blocked:
            signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})


def _exit_on_sigint(signum, frame) -> None:
    _interrupted()


def blender_outputs(args, params) -> None:
    """--blend/--render: the same operator the Blender UI runs (curveskel_addon.headless)."""
    from curveskel_addon import headless

    blend = temp_path(args.blend) if args.blend else None
    render = temp_path(args.render) if args.render else None
    out = headless.cli_outputs(args.mesh, params.to_dict(), blend=blend, render=render,
                               bind=args.bind)
    arm = out["armature"]
    print(f"blender     {arm.name}: {arm['curveskel_n_joints']} joints, {arm['curveskel_n_bones']} bones, "
          f"operator {out['operator_seconds']:.2f} s", flush=True)
    if blend is not None:
        commit(blend, args.blend, "--blend", backup=args.blend_backup)
        print(f"wrote       {args.blend}", flush=True)
    if render is not None:
        commit(render, args.render, "--render")
        print(f"wrote       {args.render} (render {out['render_seconds']:.1f} s)", flush=True)


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
    for flag, path in (("glb", args.glb), ("fbx", args.fbx)):
        if path is not None:
            tmp = temp_path(path)
            try:
                out = export_rig(bpy.context, ob, arm, tmp)
            except CurveSkelError as exc:    # the exporter's traceback: say what went wrong
                remove_temps()
                kept = "the previous file is kept" if path.exists() else "nothing was written"
                raise CurveSkelError(f"could not write --{flag} {path}: {_last_error(exc)}; {kept}") from None
            commit(tmp, path, "--" + flag)
            print(f"wrote       {path} ({out['format']}, {out['seconds']:.2f} s)", flush=True)


def main(argv=None) -> int:
    ap = build_parser()
    args = ap.parse_args(argv)
    try:
        return _finish(run(args))
    except CurveSkelError as exc:
        remove_temps()
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return _interrupted()
    except Exception as exc:  # never a raw traceback for users; --debug shows it
        remove_temps()
        if args.debug:
            raise
        print(f"error: unexpected {type(exc).__name__}: {exc} (run with --debug for details)", file=sys.stderr)
        return 1


def _finish(rc: int) -> int:
    """Every output is written: a Ctrl-C from here on has nothing left to stop and is ignored.
    (The interpreter's shutdown puts a handled SIGINT back to the default action, so a late
    Ctrl-C would otherwise kill the process by signal after a complete run.)"""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)
    return rc


def _exit(rc: int) -> None:
    """Leave with ``rc``; with bpy loaded at once, as the normal shutdown can crash inside Blender."""
    if "bpy" in sys.modules or "_bpy" in sys.modules:
        try:
            sys.stdout.flush()
            sys.stderr.flush()
        finally:
            os._exit(rc)
    sys.exit(rc)


def _interrupted() -> int:
    """Ctrl-C: remove the temporary files, say so, exit 130. Once bpy is (even partly) loaded
    the interpreter's normal shutdown can crash inside Blender: leave at once instead."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_IGN)      # a second Ctrl-C must not cut the clean-up
    remove_temps()
    print("interrupted", file=sys.stderr)
    if "bpy" in sys.modules or "_bpy" in sys.modules:
        try:
            sys.stdout.flush()
            sys.stderr.flush()
        finally:
            os._exit(130)
    return 130


if __name__ == "__main__":
    _exit(main())
