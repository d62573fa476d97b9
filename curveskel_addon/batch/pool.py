"""The batch on this machine: N supervised worker processes (:mod:`.supervisor`).

One thread per worker takes the next job from a shared queue, runs it in its worker process and
hands the row to the calling thread, which reports progress. The calling thread only waits, so
Ctrl-C reaches it at once: it sets the stop event, each thread kills its worker within a tenth
of a second (the asset it was on is not written: its temporary files are removed), and the
rows already received are kept.
"""

from __future__ import annotations

import queue
import threading
from collections import deque

from .supervisor import Limits, Supervisor, execute
from .task import new_row

__all__ = ["run_pool"]


def run_pool(jobs, *, workers: int, limits: Limits, on_row) -> int:
    """Run ``jobs`` on ``workers`` worker processes.

    Parameters
    ----------
    jobs : list of Job
        In the order they should start.
    workers : int
    limits : Limits
    on_row : callable
        Called in the calling thread with each row as it arrives.

    Returns
    -------
    int : worker processes started (restarts included).

    Raises
    ------
    KeyboardInterrupt
        After the workers are stopped (the rows received so far were passed to ``on_row``).
    """
    todo = deque(jobs)
    lock = threading.Lock()
    stop = threading.Event()
    rows: queue.Queue = queue.Queue()
    sups = [Supervisor(limits, stop) for _ in range(max(1, min(workers, len(todo))))]

    def loop(sup: Supervisor) -> None:
        try:
            while not stop.is_set():
                with lock:
                    if not todo:
                        break
                    job = todo.popleft()
                try:
                    row = execute(job, sup)
                except Exception as exc:   # the batch's own fault (cannot start a worker...)
                    row = new_row(job)
                    row.update(status="crashed", reason=f"{type(exc).__name__}: {exc}")
                if row is not None:
                    rows.put(row)
        finally:
            if stop.is_set():
                sup.kill()
            else:
                sup.close()
            rows.put(None)                       # this thread is done

    threads = [threading.Thread(target=loop, args=(s,), name=f"curveskel-batch-{i}", daemon=True)
               for i, s in enumerate(sups)]
    for t in threads:
        t.start()
    running = len(threads)
    try:
        while running:
            try:
                row = rows.get(timeout=0.5)
            except queue.Empty:
                continue
            if row is None:
                running -= 1
            else:
                on_row(row)
    except BaseException:
        stop.set()                               # each thread kills its own worker
        for t in threads:
            t.join()
        while True:                              # rows that arrived meanwhile are kept
            try:
                row = rows.get_nowait()
            except queue.Empty:
                break
            if row is not None:
                on_row(row)
        raise
    for t in threads:
        t.join()
    return sum(s.started for s in sups)
