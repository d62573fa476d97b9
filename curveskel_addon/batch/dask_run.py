"""The batch on a Dask cluster: the same jobs, the same supervised workers, the same rows.

Each asset is one Dask task (:func:`dask_task`), submitted with ``Client.map`` and collected
with ``as_completed`` (progress). Inside a Dask worker a task runs exactly as in the process
pool: :func:`.supervisor.execute` with a :class:`.supervisor.Supervisor` kept per worker thread
(so time and memory limits, crash rows and Blender restarts are the pool's). A Dask worker that
dies mid-task (killed, its machine lost) has its tasks moved to another worker by the scheduler;
the outputs are written with temporary files and renames, so a task run twice writes the same
files once, and the client keeps one row per asset.

Paths: the client, the scheduler and every worker must see the inputs and the output folder
under the same local paths (one machine, or a network file system mounted at the same place
everywhere). fsspec URLs (``s3://``, ``gs://``, ...) are not supported: object stores have no
atomic rename; mount them (s3fs, gcsfuse, rclone mount) at the same path on every machine.

dask and distributed are imported here only, when a batch runs on Dask (``pip install
"curveskel[batch]"``); the core, the command line and the Blender extension never need them.
"""

from __future__ import annotations

import os
import threading
import uuid

from ..core import CurveSkelError
from .supervisor import Limits, Supervisor, execute, total_memory
from .task import new_row

__all__ = ["connect", "run_dask", "dask_task"]

#: inside a Dask worker process, per batch (its token; two batches may share a cluster): one
#: supervisor per worker thread, and the batch's stop event
_SUPERVISORS: dict[tuple[str, int], Supervisor] = {}
_LOCK = threading.Lock()
_STOP: dict[str, threading.Event] = {}


def connect(address, *, memory_limit=None):
    """A Dask client for ``address``.

    Parameters
    ----------
    address : str or distributed.Client
        A client (used as it is), ``"local:N"`` (a LocalCluster of N single-threaded worker
        processes on this machine, closed with the client) or a scheduler address
        (``tcp://host:8786``).

    Returns
    -------
    (client, owned) : the client, and whether the caller must close it (and its cluster).

    Raises
    ------
    CurveSkelError
        dask/distributed not installed, a bad ``local:N``, or no scheduler at the address.
    """
    try:
        from distributed import Client, LocalCluster
    except ImportError:
        raise CurveSkelError("--dask needs dask and distributed: pip install \"curveskel[batch]\" "
                             "(or: pip install dask==2025.9.1 distributed==2025.9.1)") from None
    if not isinstance(address, str):
        return address, False
    if address.startswith("local:"):
        try:
            n = int(address[6:])
        except ValueError:
            n = 0
        if n < 1:
            raise CurveSkelError(f"--dask {address}: local:N needs a number of workers N >= 1")
        # single-threaded workers: one asset per worker at a time, as in the pool; no dashboard
        # (a second batch on the same machine would fight over its port)
        cluster = LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                               dashboard_address=None)
        return Client(cluster), True
    try:
        return Client(address, timeout=30), True
    except (OSError, TimeoutError) as exc:
        raise CurveSkelError(f"--dask {address}: cannot reach a Dask scheduler there ({exc})") from None


def run_dask(jobs, client, *, limits: Limits, out: str, on_row) -> int:
    """Run ``jobs`` on the Dask cluster behind ``client``; rows go to ``on_row`` as they come.

    Returns
    -------
    int : the cluster's worker count when the batch started.

    Raises
    ------
    CurveSkelError
        A worker cannot import curveskel or does not see the output folder.
    KeyboardInterrupt
        After the running tasks' worker processes are killed and the tasks cancelled; the
        rows of the tasks that had finished (their files are written) go to ``on_row`` first.
    """
    from distributed import as_completed

    _check_workers(client, out)
    token = uuid.uuid4().hex[:8]
    keys = [f"curveskel-asset-{token}-{i}" for i in range(len(jobs))]
    by_key = dict(zip(keys, jobs))
    # retries: a task that raised (the batch's own fault, e.g. a worker that could not start);
    # a worker lost mid-task is the scheduler's to reschedule (allowed-failures)
    futures = client.map(dask_task, jobs, limits=limits, token=token, key=keys, pure=False,
                         retries=1)
    n_workers = len(client.scheduler_info().get("workers", {}))
    reported: set = set()
    try:
        for fut in as_completed(futures):
            reported.add(fut.key)
            job = by_key[fut.key]
            try:
                row = fut.result()
            except Exception as exc:   # lost too many workers (KilledWorker), cancelled, ...
                row = new_row(job)
                row.update(status="crashed", reason=_one_line(f"the Dask task failed: "
                                                              f"{type(exc).__name__}: {exc}"))
            fut.release()
            if row is not None:
                on_row(row)
    except BaseException:
        try:
            client.run(_stop_batch, token)       # running tasks: kill their worker processes
        except Exception:
            pass
        _drain(futures, reported, on_row)
        client.cancel(futures)
        raise
    finally:
        try:
            client.run(_close_supervisors, token)
        except Exception:
            pass
    return n_workers


def _drain(futures, reported: set, on_row, wait_s: float = 2.0) -> None:
    """On a stop: the rows of the tasks that finished but were not reported yet (their outputs
    are written; the table must say so). The batch's stop event is set, so a task still running
    or waiting returns None at once (its worker killed); they are given ``wait_s`` seconds."""
    from distributed import wait

    try:
        wait(futures, timeout=wait_s)
    except BaseException:   # timed out, or a second Ctrl-C: take what has finished
        pass
    for fut in futures:
        if fut.key in reported or fut.status != "finished":
            continue
        try:
            row = fut.result(timeout=1)
        except BaseException:
            continue
        if row is not None:
            on_row(row)


def dask_task(job, limits: Limits, token: str):
    """One asset on a Dask worker (see the module's docstring): this thread's supervisor for
    batch ``token`` runs it."""
    me = (token, threading.get_ident())
    with _LOCK:
        sup = _SUPERVISORS.get(me)
        if sup is None:
            stop = _STOP.setdefault(token, threading.Event())
            sup = _SUPERVISORS[me] = Supervisor(_resolved(limits), stop)
    return execute(job, sup)


def _resolved(limits: Limits) -> Limits:
    """The limits on this worker: with no memory limit given, this Dask worker's own limit
    shared among its threads (the machine's memory over its cores when it has none)."""
    if limits.memory_limit is not None:
        return limits
    mem = None
    try:
        from distributed import get_worker

        w = get_worker()
        mem = (w.memory_manager.memory_limit or 0) // max(1, w.state.nthreads) or None
    except Exception:   # not in a worker (tests), or another distributed layout
        pass
    if mem is None:
        total = total_memory()
        mem = total // max(1, os.cpu_count() or 1) if total else None
    return Limits(limits.timeout, mem, limits.restart_every)


def _check_workers(client, out: str) -> None:
    """The scheduler (it unpickles the tasks) and every worker import this curveskel, and the
    workers see the output folder: said once, before any task, instead of a row per asset."""
    for who, runs, ask in (("scheduler", "runs", client.run_on_scheduler),
                           ("workers", "run", client.run)):
        try:
            seen = ask(_worker_view, out)
        except Exception as exc:   # the remote error comes back as the exception raised there
            if "curveskel_addon" in str(exc):
                raise CurveSkelError(f"the Dask {who} cannot import curveskel_addon: install "
                                     f"curveskel (the same version) where the {who} {runs}"
                                     ) from None
            raise CurveSkelError(f"the Dask {who} did not answer: {_one_line(str(exc))}") from None
    seen = client.run(_worker_view, out)
    if not seen:
        raise CurveSkelError("the Dask cluster has no workers")
    from .. import __version__

    for addr, (version, sees) in sorted(seen.items()):
        if version != __version__:
            raise CurveSkelError(f"the Dask worker {addr} runs curveskel {version}, this is "
                                 f"{__version__}: install the same version everywhere")
        if not sees:
            raise CurveSkelError(f"the Dask worker {addr} does not see the output folder {out}: "
                                 "it must be on a file system every worker mounts at the same path")


def _worker_view(out: str):
    from .. import __version__

    return __version__, os.path.isdir(out)


def _stop_batch(token: str) -> None:
    with _LOCK:
        _STOP.setdefault(token, threading.Event()).set()


def _close_supervisors(token: str) -> None:
    """Let batch ``token``'s worker processes on this Dask worker leave (the batch is over)."""
    with _LOCK:
        sups = [_SUPERVISORS.pop(k) for k in [k for k in _SUPERVISORS if k[0] == token]]
        _STOP.pop(token, None)
    for sup in sups:
        if sup.busy:        # a stopped task still on it: its own thread kills the worker
            continue
        try:
            sup.close()
        except Exception:   # a worker process already gone
            pass


def _one_line(text: str) -> str:
    return " ".join(text.split())[:300]
