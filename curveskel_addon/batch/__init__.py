"""Batches of mesh files: a process pool on one machine, or a Dask cluster (issue 32).

    from curveskel_addon.batch import run
    rows = run(["library/"], "out/", workers=4)              # or client="local:4" / a Client
    [r for r in rows if r["status"] != "ok"]

``run`` writes each asset's skeleton JSON (and rig outputs when asked) under the output folder,
mirroring the input tree, and the results table (``results.jsonl``, ``results.csv``); it
returns the table. Modules (outside the core; no bpy, no dask at import):

============== ======================================================================
``inputs``     folders, globs, manifests -> assets with their relative paths
``records``    input and output hashes, settings key, the per-asset records (resume)
``task``       one asset's work inside a worker: read, skeletonize, write (atomic)
``worker``     the worker process: jobs in, rows out, one at a time
``supervisor`` one worker process watched: time and memory limits, crashes, restarts
``pool``       N supervised workers on this machine
``dask_run``   the same tasks on a Dask cluster (dask/distributed imported there only)
``report``     results.jsonl / results.csv and the end summary
``bar``        progress on stderr (tqdm on a terminal, plain lines in a log)
``driver``     :func:`run`: all of the above, in order
============== ======================================================================
"""

from .driver import BatchInterrupted, Results, run

__all__ = ["run", "Results", "BatchInterrupted"]
