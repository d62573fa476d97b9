"""One worker process, watched: time limit, memory limit, crashes, restarts.

A :class:`Supervisor` owns at most one worker process (:mod:`.worker`) and runs one asset at a
time in it. The process pool runs one supervisor per worker thread; on a Dask cluster each
worker thread of each Dask worker has its own. While an asset runs, the supervisor looks at the
worker ten times a second:

* past the time limit, or with a resident size above the memory limit: the worker is killed
  (SIGKILL), its temporary files removed, the row says ``timeout`` / ``memory``;
* the worker died by itself (a signal, an exit): the row says ``crashed`` and why (the signal,
  the last line the worker wrote on stderr);
* a new worker is started for the next asset.

The memory limit is checked on the resident size (what the system must give), not the address
space: NumPy's and BLAS's reserved but untouched memory does not count, and a runaway is caught
within a tenth of a second of crossing the limit. A worker that has loaded Blender (rig outputs)
is restarted after every ``restart_every`` assets, as Blender grows over long runs.
"""

from __future__ import annotations

import os
import select
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

from .task import Job, new_row, remove_temps_of
from .worker import read_frames, send

__all__ = ["Supervisor", "Limits", "execute", "rss_bytes", "total_memory"]

#: seconds a worker may take to start (import NumPy, SciPy and the core)
START_TIMEOUT = 300.0
#: seconds between two looks at a running worker
POLL = 0.1
#: worker environment: one BLAS / OpenMP thread each (the workers already fill the cores)
_THREADS = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS",
            "VECLIB_MAXIMUM_THREADS", "NUMEXPR_NUM_THREADS")
_HOST = socket.gethostname()
_BOOT = ("import sys; sys.path.insert(0, {root!r}); "
         "from curveskel_addon.batch.worker import main; main()")


class Limits:
    """A worker's limits.

    Parameters
    ----------
    timeout : float or None
        Seconds one asset may take (None or 0: no limit).
    memory_limit : int or None
        Bytes of resident memory a worker may hold (None or 0: no limit).
    restart_every : int
        Restart a worker that has loaded Blender after this many assets (0: never).
    """

    def __init__(self, timeout=None, memory_limit=None, restart_every: int = 20):
        self.timeout = float(timeout) if timeout else None
        self.memory_limit = int(memory_limit) if memory_limit else None
        self.restart_every = int(restart_every or 0)

    def __repr__(self) -> str:
        return (f"Limits(timeout={self.timeout}, memory_limit={self.memory_limit}, "
                f"restart_every={self.restart_every})")


class Supervisor:
    """Runs assets one by one in a worker process it starts, watches and restarts.

    Parameters
    ----------
    limits : Limits
    stop : threading.Event, optional
        Set by the batch on Ctrl-C: a running asset's worker is killed at once.
    """

    def __init__(self, limits: Limits, stop: threading.Event | None = None):
        self.limits = limits
        self.stop = stop or threading.Event()
        self.proc: subprocess.Popen | None = None
        self._log = None
        self._buf = bytearray()
        self._bpy_assets = 0
        self.started = 0                         # workers started (tests, the bench)
        self.busy = False                        # running an asset (its thread owns the worker)

    # -- the worker process ------------------------------------------------------------------
    def _start(self) -> bool:
        """Start a worker and wait until it is ready; False when stopped meanwhile."""
        root = str(Path(__file__).resolve().parents[2])
        env = dict(os.environ)
        for name in _THREADS:
            env.setdefault(name, "1")
        self._log = tempfile.TemporaryFile(prefix="curveskel-worker-")
        self.proc = subprocess.Popen(
            [sys.executable, "-c", _BOOT.format(root=root)], stdin=subprocess.PIPE,
            stdout=subprocess.PIPE, stderr=self._log, env=env, close_fds=True,
            start_new_session=True)              # Ctrl-C in the terminal reaches the batch only
        self._buf = bytearray()
        self._bpy_assets = 0
        self.started += 1
        msg = self._wait(time.monotonic() + START_TIMEOUT, None)
        if msg == "stopped":
            return False
        if not (isinstance(msg, tuple) and msg[0] == "ready"):
            why = msg if isinstance(msg, str) else "it did not start"
            self.kill()
            raise RuntimeError(f"a batch worker could not start: {why}")
        return True

    def _wait(self, deadline: float, job: Job | None):
        """The worker's next message; or a string saying why none came (the worker is then
        killed or dead); or a dict row (the asset's limit was reached)."""
        fd = self.proc.stdout.fileno()
        while True:
            for msg in read_frames(self._buf):
                return msg
            if self.stop.is_set():
                # a row already sent is kept (its outputs are written): read what is there
                while select.select([fd], [], [], 0)[0]:
                    data = os.read(fd, 1 << 16)
                    if not data:
                        break
                    self._buf += data
                for msg in read_frames(self._buf):
                    return msg
                self.kill()
                return "stopped"
            now = time.monotonic()
            if now >= deadline:
                return self._limit(job, "timeout", f"exceeded the time limit of "
                                   f"{self.limits.timeout:g} s: killed") if job else "timed out"
            if job is not None and self.limits.memory_limit:
                rss = rss_bytes(self.proc.pid)
                if rss is not None and rss > self.limits.memory_limit:
                    return self._limit(job, "memory", f"exceeded the memory limit of "
                                       f"{_mib(self.limits.memory_limit)} MiB: killed at "
                                       f"{_mib(rss)} MiB", peak=rss)
            ready, _, _ = select.select([fd], [], [], min(POLL, max(deadline - now, 0.0)))
            if ready:
                data = os.read(fd, 1 << 16)
                if not data:
                    return self._died()
                self._buf += data

    def _limit(self, job: Job, status: str, reason: str, peak: int | None = None) -> dict:
        pid = self.proc.pid
        self.kill()
        remove_temps_of(job, pid)
        row = new_row(job)
        row.update(status=status, reason=reason, worker=f"{_HOST}:{pid}",
                   peak_mb=round(peak / 2 ** 20, 1) if peak else None)
        return row

    def _died(self) -> str:
        """Why the worker died, in one line (and forget it: a new one starts next time)."""
        proc = self.proc
        try:
            rc = proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            rc = proc.wait()
        if rc < 0:
            try:
                what = f"killed by {signal.Signals(-rc).name}"
            except ValueError:
                what = f"killed by signal {-rc}"
        else:
            what = f"exited with status {rc}"
        last = _last_line(self._log)
        self._forget()
        return f"the worker process died ({what})" + (f": {last}" if last else "")

    def kill(self) -> None:
        """Kill the worker now (SIGKILL; nothing it was writing is committed). Called by the
        thread running this supervisor only: another thread sets :attr:`stop` instead."""
        proc = self.proc
        if proc is None:
            return
        try:
            proc.kill()
        except OSError:
            pass
        try:
            proc.wait(timeout=30)
        except subprocess.TimeoutExpired:
            pass
        self._forget()

    def _forget(self) -> None:
        proc, self.proc = self.proc, None
        if proc is not None:
            for fh in (proc.stdin, proc.stdout):
                try:
                    fh.close()
                except OSError:
                    pass
        if self._log is not None:
            self._log.close()
            self._log = None

    def close(self) -> None:
        """Let the worker leave (it finishes nothing: call between assets)."""
        proc = self.proc
        if proc is None:
            return
        try:
            proc.stdin.close()                   # EOF: the worker's loop ends
            proc.wait(timeout=30)
        except (OSError, subprocess.TimeoutExpired):
            pass
        self.kill()

    # -- one asset ---------------------------------------------------------------------------
    def run(self, job: Job, sha256: str | None) -> dict | None:
        """Run one asset in the worker; returns its row, or None when stopped (Ctrl-C)."""
        self.busy = True
        try:
            return self._run(job, sha256)
        finally:
            self.busy = False
            if self.stop.is_set():               # the batch is over: no idle worker left behind
                self.kill()

    def _run(self, job: Job, sha256: str | None) -> dict | None:
        if self.stop.is_set():
            return None
        if self.proc is None and not self._start():
            return None
        pid = self.proc.pid
        try:                                     # the log holds this asset's lines only
            self._log.seek(0)
            self._log.truncate()
        except (OSError, ValueError):
            pass
        t0 = time.monotonic()
        try:
            send(self.proc.stdin, (job, sha256))
            timeout = self.limits.timeout
            msg = self._wait(t0 + timeout if timeout else float("inf"), job)
        except (BrokenPipeError, ValueError):       # died before it read the job
            msg = self._died()
        if msg == "stopped":
            remove_temps_of(job, pid)
            return None
        if isinstance(msg, str):                      # the worker died with the asset
            remove_temps_of(job, pid)
            row = new_row(job, sha256)
            row.update(status="crashed", reason=msg, seconds=round(time.monotonic() - t0, 3),
                       worker=f"{_HOST}:{pid}")
            return row
        if isinstance(msg, dict):                     # a limit: the worker was killed
            msg.update(sha256=sha256, seconds=round(time.monotonic() - t0, 3))
            return msg
        _, row, bpy_loaded = msg
        if bpy_loaded:
            self._bpy_assets += 1
            if self.limits.restart_every and self._bpy_assets >= self.limits.restart_every:
                self.close()                          # Blender grows over long runs
        return row


def execute(job: Job, supervisor: Supervisor) -> dict | None:
    """One asset, the same on the pool and on Dask: its input's hash; its record's row when
    the record still describes it (``reused``: nothing computed); else run in the worker."""
    from .records import file_sha256, read_record, record_path, reusable

    try:
        sha256 = file_sha256(job.source)
    except OSError:
        sha256 = None                            # the worker's reader says what is wrong
    rec = read_record(record_path(job.out, job.rel))
    if reusable(rec, sha256, job.key, job.out, job.rel):
        row = new_row(job, sha256)
        row.update(rec["row"])
        row.update(reused=True, source=job.source)
        return row
    return supervisor.run(job, sha256)


def rss_bytes(pid: int) -> int | None:
    """Resident size of process ``pid`` in bytes (Linux /proc, else psutil), None if unknown."""
    try:
        with open(f"/proc/{pid}/statm") as fh:
            return int(fh.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError, IndexError):
        pass
    try:
        import psutil

        return psutil.Process(pid).memory_info().rss
    except Exception:   # psutil missing, or the process is gone
        return None


def total_memory() -> int | None:
    """This machine's memory in bytes (None if unknown)."""
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):
        try:
            import psutil

            return psutil.virtual_memory().total
        except Exception:
            return None


def _mib(n: int) -> int:
    return int(round(n / 2 ** 20))


def _last_line(log) -> str:
    """The last line the worker wrote on stderr that says something (at most 200 characters)."""
    if log is None:
        return ""
    try:
        log.seek(0, os.SEEK_END)
        size = log.tell()
        log.seek(max(0, size - 8192))
        tail = log.read().decode("utf-8", "replace")
    except (OSError, ValueError):
        return ""
    lines = [ln.strip() for ln in tail.splitlines() if ln.strip()]
    for ln in reversed(lines):
        if "Error" in ln or "error" in ln or "Fatal" in ln:
            return ln[:200]
    return lines[-1][:200] if lines else ""
