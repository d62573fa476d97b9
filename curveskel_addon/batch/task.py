"""One asset's work, inside a worker process: read, skeletonize, write its outputs and record.

The same steps as ``curveskel skeletonize MESH --json OUT`` (the command line's reader, the
core's ``skeletonize``, ``Skeleton.save``; the rig outputs through the command line's own
``rig_outputs`` / ``blender_outputs``), with the command line's output checks and atomic writes
(:mod:`curveskel_addon.cli.outputs`). The order of the writes is what makes a batch resumable
(:mod:`.records`): every other output first, then the record, then the skeleton JSON.

Every outcome is a row (:func:`new_row`): an error in the input or the settings is ``refused``
with the command line's one-line message; an unexpected exception is ``crashed`` with its type
and message (the worker carries on). A worker that dies, runs past the time limit or over the
memory limit is the supervisor's to record (:mod:`.supervisor`).
"""

from __future__ import annotations

import argparse
import io
import json
import os
import re
import time
from dataclasses import dataclass
from pathlib import Path

from ..core import CurveSkelError

__all__ = ["Job", "make_settings", "new_row", "process", "remove_temps_of", "ROW_KEYS",
           "TEST_HOOKS_ENV"]

#: the results table's first columns, in order (other keys follow, sorted)
ROW_KEYS = ("path", "status", "reason", "sha256", "reused", "vertices", "faces", "components",
            "joints", "bones", "J0", "J", "E0", "E", "stages", "iterations", "seconds", "peak_mb",
            "skeleton_sha256", "outputs", "worker", "source")
#: set to 1 in a worker's environment, a mesh file whose first line is
#: ``# curveskel-batch-test: crash|hang|memory`` makes the worker die by SIGSEGV, sleep, or
#: take memory until it is killed (the tests' bad inputs; ignored otherwise)
TEST_HOOKS_ENV = "CURVESKEL_BATCH_TEST_HOOKS"


@dataclass(frozen=True)
class Job:
    """One asset's work, as sent to a worker (pickled; plain values only).

    Attributes
    ----------
    source : str
        The mesh file (absolute).
    rel : str
        Its path under the batch's root: names the outputs and the row.
    out : str
        The output folder (absolute).
    settings : dict
        From :func:`make_settings`.
    key : str
        ``records.settings_key(settings)``.
    size : int
        The file's size in bytes (-1: missing); larger files are started first.
    """

    source: str
    rel: str
    out: str
    settings: dict
    key: str
    size: int = -1


def make_settings(params, *, glb: bool = False, fbx: bool = False, blend: bool = False,
                  bind: bool = False, quality: bool = False) -> dict:
    """What shapes an asset's outputs (a change in any of them recomputes the asset).

    Parameters
    ----------
    params : SkeletonParams
    glb, fbx, blend : bool
        Rig outputs beside the skeleton JSON (``.glb`` / ``.fbx``: rigged mesh and armature;
        ``.blend``: the scene the Blender operator makes).
    bind : bool
        Bind the mesh in the .blend (the .glb and .fbx are always bound).
    quality : bool
        The quality measures in the JSON's meta and the row.

    Returns
    -------
    dict with ``params`` (dict), ``outputs`` (kinds, json first), ``bind``, ``quality``,
    ``version``.
    """
    from .. import __version__

    outputs = ["json"] + [k for k, on in (("glb", glb), ("fbx", fbx), ("blend", blend)) if on]
    return {"params": params.to_dict(), "outputs": outputs, "bind": bool(bind or glb or fbx),
            "quality": bool(quality), "version": __version__}


def new_row(job: Job, sha256: str | None = None) -> dict:
    """A row with every column of :data:`ROW_KEYS` (empty where not known)."""
    row = dict.fromkeys(ROW_KEYS)
    row.update(path=job.rel, source=job.source, sha256=sha256, reason="", reused=False)
    return row


def _here() -> str:
    """``host:pid`` of this process (the row's ``worker``: which machine, which process)."""
    import socket

    return f"{socket.gethostname()}:{os.getpid()}"


def process(job: Job, sha256: str | None, *, peak_mb=lambda: None) -> dict:
    """Compute one asset and write its outputs; never raises for the asset's own faults.

    Parameters
    ----------
    job : Job
    sha256 : str or None
        The input's hash, taken by the supervisor (None: the file could not be read).
    peak_mb : callable
        Returns this process's peak memory so far in MiB (the worker resets it per asset).

    Returns
    -------
    dict : the row (status ok, refused or crashed).
    """
    from .records import record_path

    t0 = time.perf_counter()
    row = new_row(job, sha256)
    row["worker"] = _here()
    try:
        _test_hook(job.source)
        outs = _check_outputs(job)
        _compute_and_write(job, outs, row, t0, peak_mb)
    except CurveSkelError as exc:
        row.update(status="refused", reason=_one_line(str(exc), job))
        row.update(seconds=time.perf_counter() - t0, peak_mb=peak_mb())
        try:
            _write_record(record_path(job.out, job.rel), job, row, {})
        except (OSError, CurveSkelError):
            pass                                 # no record: the refusal is simply found again
    except MemoryError:
        row.update(status="memory", reason="out of memory (an allocation failed)")
    except Exception as exc:  # a fault of the program, not of the input: say which, carry on
        row.update(status="crashed", reason=_one_line(f"unexpected {type(exc).__name__}: {exc}", job))
    finally:
        from ..cli.outputs import remove_temps

        remove_temps()
    if row["seconds"] is None:
        row.update(seconds=time.perf_counter() - t0, peak_mb=peak_mb())
    return row


def _compute_and_write(job: Job, outs: dict, row: dict, t0: float, peak_mb) -> None:
    from ..cli.outputs import commit, temp_path
    from ..core import SkeletonParams, skeletonize
    # the command line's reader (the one place the batch reads mesh files)
    from ..mesh_files import read_mesh
    from .records import file_sha256, record_path, skeleton_digest

    s = job.settings
    V, F = read_mesh(job.source)
    row.update(vertices=int(len(V)), faces=int(len(F)))
    params = SkeletonParams.from_dict(s["params"])
    sk = skeletonize(V, F, params)
    if s.get("quality"):
        from ..measure.quality import quality

        sk.meta["quality"] = quality(V, F, sk)
    _fill_row(row, sk)
    doc = sk.to_dict()
    row["skeleton_sha256"] = skeleton_digest(doc)
    import numpy as np

    for name in ("joints", "t"):
        if not np.all(np.isfinite(np.asarray(getattr(sk, name), dtype=float))):
            raise CurveSkelError(f"the result has non-finite {name} (a bug; please report it): "
                                 "no JSON written")
    tmp = temp_path(outs["json"])
    sk.save(tmp)                                 # what the command line writes
    digests = {"json": file_sha256(tmp)}
    rig = [k for k in ("glb", "fbx", "blend") if k in outs]
    if rig:
        _rig_outputs(job, outs, V, sk, params)
        digests.update({k: file_sha256(outs[k].target) for k in rig})
    row["outputs"] = [os.path.relpath(outs[k].target, job.out).replace(os.sep, "/")
                      for k in ["json", *rig]]
    row.update(status="ok", seconds=time.perf_counter() - t0, peak_mb=peak_mb())
    _write_record(record_path(job.out, job.rel), job, row, digests)
    commit(tmp, outs["json"])                    # last: a JSON on disk always has its record


def _fill_row(row: dict, sk) -> None:
    """The skeleton's figures as the command line's summary reports them
    (:func:`curveskel_addon.run_summary.summary`): joints, bones, components, J0 and J (the
    objective the search minimises; ``meta['J']``), E0 and E (the paper's E, not minimised),
    stages, iterations; quality measures."""
    from ..run_summary import summary

    for k, v in summary(sk).items():
        if k != "seconds" and isinstance(v, (int, float)) and not isinstance(v, bool):
            row[k] = v if v == v else None          # NaN (not computed) -> empty
    q = sk.meta.get("quality")
    if isinstance(q, dict):
        row["quality"] = json.loads(json.dumps(q))   # plain JSON values


def _check_outputs(job: Job) -> dict:
    """The command line's checks of the asset's output paths (regular files, writable, not the
    input), before any work."""
    from ..cli.outputs import check_outputs
    from .records import output_paths

    paths = output_paths(job.out, job.rel, job.settings["outputs"])
    ns = argparse.Namespace(mesh=Path(job.source), render=None,
                            **{k: paths.get(k) for k in ("json", "glb", "fbx", "blend")})
    return check_outputs(ns)


def _rig_outputs(job: Job, outs: dict, V, sk, params) -> None:
    """--glb / --fbx / --blend through the command line's own functions (bpy is imported on
    the first rig asset of a worker; the supervisor restarts such workers every K assets)."""
    from ..cli.skeletonize import blender_outputs, rig_outputs

    s = job.settings
    args = argparse.Namespace(mesh=Path(job.source), bind=s["bind"], blend_backup=False,
                              json=None, render=None,
                              **{k: (outs[k].given if k in outs else None)
                                 for k in ("glb", "fbx", "blend")})
    report = io.StringIO()
    if "glb" in outs or "fbx" in outs:
        rig_outputs(args, outs, V, sk, report)
    if "blend" in outs:
        blender_outputs(args, outs, params, report)


def _write_record(path: Path, job: Job, row: dict, digests: dict) -> None:
    """The asset's record, written whole or not at all (temporary file + rename)."""
    from ..cli.outputs import Output, commit, temp_path

    out = Output("record", path, Path(os.path.realpath(path)))
    tmp = temp_path(out)
    rec = {"format": "curveskel-batch-record/1", "path": job.rel, "sha256": row["sha256"],
           "settings_key": job.key, "settings": job.settings, "outputs": digests, "row": row}
    tmp.write_text(json.dumps(rec))
    commit(tmp, out)


def remove_temps_of(job: Job, pid: int) -> None:
    """Remove the temporary files a worker (process ``pid``) killed while on ``job`` left
    behind (the command line's names: ``.<name>.tmp-<pid><suffix>``, Blender's ``...@``)."""
    from .records import output_paths, record_path

    targets = list(output_paths(job.out, job.rel, job.settings["outputs"]).values())
    targets.append(record_path(job.out, job.rel))
    for t in targets:
        t = Path(os.path.realpath(t))
        tmp = t.with_name(f".{t.name}.tmp-{pid}{t.suffix}")
        for p in (tmp, Path(str(tmp) + "@")):
            try:
                p.unlink()
            except OSError:
                pass


def _one_line(text: str, job: Job) -> str:
    """A message on one line, naming the asset by its path in the batch (not the absolute
    path the worker was given)."""
    text = " ".join(text.split())
    for name in (job.source, os.path.realpath(job.source)):
        text = text.replace(name, job.rel)
    return text


# -- the tests' bad inputs ----------------------------------------------------------------------
_HOOK = re.compile(rb"^# curveskel-batch-test: (\w+)")


def _test_hook(source: str) -> None:
    """Under :data:`TEST_HOOKS_ENV` only: simulate a worker crash, a hang or a runaway."""
    if os.environ.get(TEST_HOOKS_ENV) != "1":
        return
    try:
        with open(source, "rb") as fh:
            m = _HOOK.match(fh.read(64))
    except OSError:
        return
    what = m.group(1).decode() if m else None
    if what == "crash":
        import signal

        os.kill(os.getpid(), signal.SIGSEGV)
        time.sleep(60)
    elif what == "hang":
        time.sleep(3600)
    elif what == "memory":
        hog = []
        while True:                              # 64 MiB a step, every page touched
            hog.append(bytearray(64 << 20))
            time.sleep(0.01)
