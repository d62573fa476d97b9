"""The batch's results table (``results.jsonl``, ``results.csv``) and its end summary.

One row per asset, sorted by path (so the table does not depend on the number of workers or
the order they finished in). ``results.jsonl`` holds the rows as they are (the quality measures
as a nested object, outputs as a list); ``results.csv`` has one column per key (the quality
measures as ``quality.<name>``, outputs joined by ``;``). Both are written whole or not at all.
"""

from __future__ import annotations

import csv
import io
import json
import re
from collections import Counter, defaultdict
from pathlib import Path

from .task import ROW_KEYS

__all__ = ["STATUSES", "write_results", "summary", "csv_columns"]

#: every status a row can have, in the summary's order
STATUSES = ("ok", "refused", "timeout", "memory", "crashed")


def csv_columns(rows) -> list[str]:
    """:data:`ROW_KEYS` first, then every other key (quality measures flattened), sorted."""
    extra = set()
    for r in rows:
        extra.update(_flat(r))
    return [k for k in ROW_KEYS] + sorted(extra - set(ROW_KEYS))


def _flat(row: dict) -> dict:
    out = {}
    for k, v in row.items():
        if isinstance(v, dict):
            out.update({f"{k}.{kk}": vv for kk, vv in _flat(v).items()})
        elif isinstance(v, list):
            out[k] = ";".join(map(str, v))
        else:
            out[k] = v
    return out


def write_results(out_dir, rows) -> tuple[Path, Path]:
    """Write ``results.jsonl`` and ``results.csv`` in ``out_dir`` (rows sorted by path)."""
    from ..cli.outputs import Output, commit, temp_path

    rows = sorted(rows, key=lambda r: r["path"])
    out_dir = Path(out_dir)
    jsonl = "".join(json.dumps(r, sort_keys=False) + "\n" for r in rows)
    cols = csv_columns(rows)
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=cols, extrasaction="ignore", lineterminator="\n")
    w.writeheader()
    for r in rows:
        w.writerow({k: ("" if v is None else v) for k, v in _flat(r).items()})
    paths = []
    for name, text in (("results.jsonl", jsonl), ("results.csv", buf.getvalue())):
        path = out_dir / name
        o = Output(name.split(".")[1], path, path.resolve())
        tmp = temp_path(o)
        tmp.write_text(text)
        commit(tmp, o)
        paths.append(path)
    return paths[0], paths[1]


def summary(rows, *, total: int, seconds: float, workers: str, interrupted: bool = False,
            slowest: int = 5, ignored: int = 0) -> str:
    """The end summary, a few lines.

    Parameters
    ----------
    rows : list of dict
    total : int
        Assets in the batch (more than ``len(rows)`` when interrupted).
    seconds : float
        Wall time.
    workers : str
        How it ran ("2 workers", "Dask tcp://...: 8 workers").
    interrupted : bool
    slowest : int
        How many of the slowest computed assets to name.
    ignored : int
        Files in the input folders that are no mesh.

    Returns
    -------
    str : lines ending in a newline: counts per status, the slowest assets, the refusals
    grouped by reason, the time-outs, memory and crash rows one by one.
    """
    counts = Counter(r["status"] for r in rows)
    reused = sum(1 for r in rows if r.get("reused"))
    computed = [r for r in rows if not r.get("reused")]
    rate = 60.0 * len(computed) / seconds if seconds > 0 else 0.0
    parts = [f"{counts[s]} {s}" + (f" ({reused} reused)" if s == "ok" and reused else "")
             for s in STATUSES if counts[s]]
    lines = [f"batch       {len(rows)} of {total} assets in {seconds:.1f} s, {workers}, "
             f"{rate:.1f} computed/min: " + ", ".join(parts or ["none done"])]
    if interrupted:
        lines.append(f"interrupted {total - len(rows)} assets not run: the same command again "
                     "finishes the batch (assets done are not recomputed)")
    if ignored:
        lines.append(f"ignored     {ignored} files in the folders are no mesh (.obj .ply .stl .off)")
    timed = sorted((r for r in computed if r["status"] == "ok" and r.get("seconds") is not None),
                   key=lambda r: (-r["seconds"], r["path"]))[:slowest]
    if timed:
        lines.append("slowest     " + ", ".join(f"{r['path']} {r['seconds']:.1f} s" for r in timed))
    groups = defaultdict(list)
    for r in rows:
        if r["status"] == "refused":
            groups[_reason_group(r)].append(r["path"])
    for reason, paths in sorted(groups.items(), key=lambda kv: (-len(kv[1]), kv[0])):
        eg = ", ".join(paths[:3]) + (", ..." if len(paths) > 3 else "")
        lines.append(f"refused     {len(paths)} x {reason} ({eg})")
    for s in ("timeout", "memory", "crashed"):
        for r in sorted((r for r in rows if r["status"] == s), key=lambda r: r["path"]):
            lines.append(f"{s:<11} {r['path']}: {r['reason']}")
    return "\n".join(lines) + "\n"


def _reason_group(row: dict) -> str:
    """A refusal's reason with the file's own parts taken out (its name, line numbers,
    sizes), so refusals of the same kind group together."""
    text = row["reason"]
    for name in (row["path"], Path(row["path"]).name):
        text = text.replace(name, "FILE")
    return re.sub(r"\d+(\.\d+)?", "N", text)
