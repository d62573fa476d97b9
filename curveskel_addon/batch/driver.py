"""A batch from start to end: find the assets, run them (pool or Dask), write the table.

:func:`run` is the library's entry point (``curveskel_addon.batch.run``) and what ``curveskel
batch`` calls.
"""

from __future__ import annotations

import os
import re
import time
from collections import defaultdict
from pathlib import Path

from ..core import CurveSkelError, SkeletonParams
from .inputs import collect, refuse_url
from .records import STATE_DIR, output_paths, record_path, settings_key
from .report import summary as summary_text
from .report import write_results
from .supervisor import Limits, total_memory
from .task import Job, make_settings

__all__ = ["run", "Results", "BatchInterrupted", "parse_size", "default_workers"]


class Results(list):
    """The results table: a list of row dicts sorted by path (``pandas.DataFrame(results)``
    makes a frame of it).

    Attributes
    ----------
    summary : str
        The end summary (counts per status, slowest assets, refusals grouped by reason).
    out : Path
        The output folder (``results.jsonl`` and ``results.csv`` are there).
    root : Path
        The folder the rows' paths start from.
    total : int
        Assets in the batch.
    seconds : float
        Wall time.
    interrupted : bool
        Stopped before every asset ran (``len(self) < total``).
    workers_started : int
        Worker processes started, restarts included (pool only; 0 on Dask).
    """

    summary = ""
    out = root = None
    total = 0
    seconds = 0.0
    interrupted = False
    workers_started = 0

    def counts(self) -> dict:
        """Rows per status."""
        out: dict = defaultdict(int)
        for r in self:
            out[r["status"]] += 1
        return dict(out)


class BatchInterrupted(KeyboardInterrupt):
    """Ctrl-C (or a stop signal) during a batch: the table of what was done is written and
    in :attr:`results`; what was written stays."""

    def __init__(self, results: Results, signum=None):
        super().__init__("batch interrupted")
        self.results = results
        self.signum = signum


def run(paths, out, *, workers: int | None = None, client=None, params=None,
        glb: bool = False, fbx: bool = False, blend: bool = False, bind: bool = False,
        quality: bool = False, timeout: float | None = 600.0, memory_limit="auto",
        restart_every: int = 20, root=None, progress: bool = False, stream=None) -> Results:
    """Skeletonize every mesh file the inputs name; write each one's outputs, mirroring the
    input tree under ``out``, and the results table.

    Parameters
    ----------
    paths : str, Path or list of them
        Folders (recursive), globs, manifest files (``.txt``/``.lst``/``.list``: a path a
        line) or mesh files (.obj .ply .stl .off).
    out : str or Path
        The output folder (created if needed). ``<rel>.json`` per asset (``<rel>.glb``,
        ``.fbx``, ``.blend`` when asked), ``results.jsonl``, ``results.csv``.
    workers : int, optional
        Worker processes on this machine (default: the cores this process may use). Not with
        ``client``.
    client : distributed.Client or str, optional
        Run on Dask: a client, a scheduler address or ``"local:N"`` (a LocalCluster of N
        workers, closed at the end).
    params : SkeletonParams or dict, optional
        Method parameters (default: the defaults).
    glb, fbx, blend, bind, quality : bool
        As the command line's ``--glb`` ... (rig outputs need bpy).
    timeout : float or None
        Seconds one asset may take before its worker is killed (None or 0: no limit).
    memory_limit : "auto", int, str or None
        Resident memory a worker may hold: bytes, or "4G" / "500M"; "auto": the machine's
        memory over the workers (on Dask: each Dask worker's limit over its threads); None or
        0: no limit.
    restart_every : int
        Restart a worker that has loaded Blender after this many assets (0: never).
    root : str or Path, optional
        The folder the outputs' relative paths start from (default: the inputs' common folder).
    progress : bool
        Show progress on ``stream`` (default stderr).

    Returns
    -------
    Results : the rows, sorted by path (also in ``out/results.jsonl`` and ``results.csv``).

    Raises
    ------
    CurveSkelError
        One line, before any work: no inputs, bad settings, an output folder in use by another
        batch or not writable, no Dask.
    BatchInterrupted
        Ctrl-C: its ``results`` are the rows done (also written to the table).
    """
    from .bar import BatchProgress

    t0 = time.monotonic()
    if isinstance(paths, (str, os.PathLike)):
        paths = [paths]
    refuse_url(os.fspath(out))
    out = Path(os.path.abspath(out))
    if out.exists() and not out.is_dir():
        raise CurveSkelError(f"--out {out} is a file, not a folder")
    if bind and not (glb or fbx or blend):
        raise CurveSkelError("--bind needs an output that takes the bound rig: --glb, --fbx or "
                             "--blend (nothing would be written)")
    if client is not None and workers is not None:
        raise CurveSkelError("give the workers of a Dask run with its cluster (--dask local:N), "
                             "not --workers")
    if isinstance(params, dict):
        params = SkeletonParams.from_dict(params)
    params = params or SkeletonParams()
    found = collect(paths, root=root, exclude=out)
    settings = make_settings(params, glb=glb, fbx=fbx, blend=blend, bind=bind, quality=quality)
    key = settings_key(settings)
    jobs = [Job(a.source, a.rel, str(out), settings, key, a.size) for a in found.assets]
    jobs.sort(key=lambda j: (-j.size, j.rel))    # the largest first: the last ones are short
    if timeout is not None and timeout < 0:
        raise CurveSkelError(f"--timeout {timeout:g}: must be positive (0: no limit)")
    if restart_every < 0:
        raise CurveSkelError(f"--restart-every {restart_every}: must be 0 (never) or more")
    workers = default_workers() if workers is None else int(workers)
    if workers < 1:
        raise CurveSkelError(f"--workers {workers}: needs at least 1")
    mem = parse_size(memory_limit)
    if mem == "auto":
        total = total_memory()
        mem = None if client is not None or not total else total // workers
    limits = Limits(timeout, mem, restart_every)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise CurveSkelError(f"cannot create --out {out}: {exc.strerror or exc}") from None
    if not os.access(out, os.W_OK | os.X_OK):
        raise CurveSkelError(f"cannot write in --out {out}: the folder is not writable")
    results = Results()
    results.out, results.root, results.total = out, found.root, len(jobs)
    bar = BatchProgress(len(jobs), enabled=progress, stream=stream)

    def on_row(row: dict) -> None:
        results.append(row)
        bar.update(row)

    with _Lock(out):
        _sweep_temps(out, jobs)                  # left by a batch killed before (SIGKILL)
        how = ""
        started_ns = time.time_ns()
        try:
            if client is None:
                from .pool import run_pool

                how = f"{workers} worker process{'es' if workers > 1 else ''}"
                results.workers_started = run_pool(jobs, workers=workers, limits=limits,
                                                   on_row=on_row)
            else:
                from .dask_run import connect, run_dask

                how = f"Dask {_where(client)}"
                dask_client, owned = connect(client)
                try:
                    n = run_dask(jobs, dask_client, limits=limits, out=str(out), on_row=on_row)
                    how += f": {n} worker{'s' if n != 1 else ''}"
                finally:
                    if owned:
                        _close(dask_client)
        except KeyboardInterrupt as exc:
            results.interrupted = True
            _written_meanwhile(results, jobs, started_ns)
            _finish(results, found, t0, how, bar)
            raise BatchInterrupted(results, getattr(exc, "signum", None)) from None
        finally:
            bar.close()
            _sweep_temps(out, jobs)
        _finish(results, found, t0, how, bar)
    return results


def _written_meanwhile(results: Results, jobs, since_ns: int) -> None:
    """On a stop: an asset whose skeleton JSON this batch wrote but whose row had not come back
    (its worker finished as the stop came, or its Dask task was cancelled with its result) gets
    the row its record holds, so the table names every file the batch wrote."""
    from .records import file_sha256, read_record, record_path, reusable
    from .task import new_row

    have = {r["path"] for r in results}
    for job in jobs:
        if job.rel in have:
            continue
        try:
            if output_paths(job.out, job.rel, ["json"])["json"].stat().st_mtime_ns < since_ns:
                continue                         # not written by this batch (or not at all)
            sha256 = file_sha256(job.source)
        except OSError:
            continue
        rec = read_record(record_path(job.out, job.rel))
        if rec is not None and reusable(rec, sha256, job.key, job.out, job.rel):
            row = new_row(job, sha256)
            row.update(rec["row"])
            row.update(source=job.source)
            results.append(row)


def _finish(results: Results, found, t0: float, how: str, bar) -> None:
    bar.close()
    results.sort(key=lambda r: r["path"])
    results.seconds = time.monotonic() - t0
    write_results(results.out, results)
    results.summary = summary_text(results, total=results.total, seconds=results.seconds,
                                   workers=how, interrupted=results.interrupted,
                                   ignored=found.ignored)


def default_workers() -> int:
    """The cores this process may run on."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return max(1, os.cpu_count() or 1)


_UNITS = {"": 1, "B": 1, "K": 2 ** 10, "M": 2 ** 20, "G": 2 ** 30, "T": 2 ** 40}


def parse_size(value):
    """Bytes from ``4G``, ``512M``, ``1.5GiB``, ``2GB`` (powers of 1024) or a number; "auto"
    stays "auto"; None, 0 and "none" mean no limit (None)."""
    if value is None:
        return None
    if isinstance(value, (int, float)):
        if value < 0:
            raise CurveSkelError(f"--memory-limit {value}: must be positive (0: no limit)")
        return int(value) or None
    text = str(value).strip()
    if text.lower() == "auto":
        return "auto"
    if text.lower() in ("none", "0", "off"):
        return None
    m = re.fullmatch(r"(\d+(?:\.\d+)?)\s*([KMGT]?)(?:I?B)?", text.upper())
    if not m:
        raise CurveSkelError(f"--memory-limit {value!r}: use a size such as 4G, 512M or 1.5GiB "
                             "(0: no limit)")
    return int(float(m.group(1)) * _UNITS[m.group(2)]) or None


def _where(client) -> str:
    if isinstance(client, str):
        return client
    try:
        return client.scheduler.address
    except AttributeError:
        return "cluster"


def _close(client) -> None:
    cluster = getattr(client, "cluster", None)
    try:
        client.close()
    finally:
        if cluster is not None:
            cluster.close()


_TEMP = re.compile(r"^\.(?P<name>.+)\.tmp-\d+(\.[^.@]*)?@?$")


def _sweep_temps(out: Path, jobs) -> None:
    """Remove the temporary files a killed batch left beside this batch's outputs (the lock
    says no other batch writes here, so none of them is being written)."""
    names = defaultdict(set)
    for job in jobs:
        for p in [*output_paths(out, job.rel, job.settings["outputs"]).values(),
                  record_path(out, job.rel)]:
            names[p.parent].add(p.name)
    names[out].update(("results.jsonl", "results.csv"))
    for folder, ours in names.items():
        try:
            entries = list(os.scandir(folder))
        except OSError:
            continue
        for e in entries:
            m = _TEMP.match(e.name)
            if m and m.group("name") in ours:
                try:
                    os.unlink(e.path)
                except OSError:
                    pass


class _Lock:
    """``out/.curveskel-batch/lock``, held while the batch runs: two batches writing into one
    folder at once would remove each other's temporary files (POSIX advisory lock; released
    when the process ends, however it ends)."""

    def __init__(self, out: Path):
        self.path = out / STATE_DIR / "lock"
        self.fd = None

    def __enter__(self):
        try:
            import fcntl
        except ImportError:                      # Windows: no lock
            return self
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self.fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
        except OSError as exc:                   # a read-only file system, no permission
            raise CurveSkelError(f"cannot write in --out {self.path.parents[1]}: "
                                 f"{exc.strerror or exc}") from None
        try:
            fcntl.flock(self.fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            other = os.pread(self.fd, 64, 0).decode(errors="replace").strip()
            os.close(self.fd)
            self.fd = None
            raise CurveSkelError(f"another batch is writing into {self.path.parents[1]}"
                                 + (f" (process {other})" if other else "")
                                 + ": wait for it to end, or choose another --out") from None
        os.ftruncate(self.fd, 0)
        os.pwrite(self.fd, str(os.getpid()).encode(), 0)
        return self

    def __exit__(self, *exc):
        if self.fd is not None:
            os.close(self.fd)
            self.fd = None
        return False
