"""What a batch keeps per asset so a rerun can skip it: hashes, settings, records.

The output folder holds, besides the outputs that mirror the input tree,

* ``.curveskel-batch/records/<rel>.json``: the asset's record, written by the worker *before*
  its skeleton JSON is renamed into place (and after every other output): its results row, the
  input's SHA-256, the settings and the SHA-256 of every output. The skeleton JSON is committed
  last, so a skeleton JSON on disk always has its record; a rerun reuses an asset when the
  record's input hash and settings are this run's and every output it names is there with its
  hash. Anything else (no record, a changed input, other settings, a missing or edited output)
  is computed again.
* ``.curveskel-batch/lock``: held while a batch runs (a second batch into the same folder is
  refused).

Refusals are recorded too (the same file refused again is not recomputed); time-outs and
crashes are not: a rerun tries them again, perhaps with other limits.
"""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

__all__ = ["STATE_DIR", "file_sha256", "settings_key", "output_paths", "record_path",
           "read_record", "reusable", "skeleton_digest", "OUTPUT_SUFFIXES"]

#: the batch's own files inside the output folder
STATE_DIR = ".curveskel-batch"
#: output kind -> suffix appended to the input's file name (``a.obj`` -> ``a.obj.json``)
OUTPUT_SUFFIXES = {"json": ".json", "glb": ".glb", "fbx": ".fbx", "blend": ".blend"}
_CHUNK = 1 << 20


def file_sha256(path) -> str:
    """SHA-256 (hex) of a file's bytes, read in 1 MiB pieces."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for piece in iter(lambda: fh.read(_CHUNK), b""):
            h.update(piece)
    return h.hexdigest()


def settings_key(settings: dict) -> str:
    """A short hash of the settings that shape an asset's outputs (method parameters, output
    kinds, --bind, --quality, the curveskel version): equal settings, equal key."""
    text = json.dumps(settings, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()[:16]


def output_paths(out_dir, rel: str, kinds) -> dict[str, Path]:
    """Where an asset's outputs go: ``out_dir/<rel><suffix>`` for each kind (json first)."""
    base = Path(out_dir) / rel
    return {k: base.with_name(base.name + OUTPUT_SUFFIXES[k]) for k in kinds}


def record_path(out_dir, rel: str) -> Path:
    """The asset's record: ``out_dir/.curveskel-batch/records/<rel>.json``."""
    base = Path(out_dir) / STATE_DIR / "records" / rel
    return base.with_name(base.name + ".json")


def read_record(path) -> dict | None:
    """A record, or None when there is none or it cannot be read (then the asset runs again)."""
    try:
        rec = json.loads(Path(path).read_text())
    except (OSError, ValueError):
        return None
    return rec if isinstance(rec, dict) and isinstance(rec.get("row"), dict) else None


def reusable(record: dict | None, sha256: str | None, key: str, out_dir, rel: str) -> bool:
    """Whether a record still describes this asset: the same input bytes and settings, and
    every output it names (kind -> SHA-256) on disk under ``out_dir`` with the bytes it had (an
    output edited or removed since means: compute again)."""
    if not record or sha256 is None or record.get("sha256") != sha256 or record.get("settings_key") != key:
        return False
    if record["row"].get("status") not in ("ok", "refused"):
        return False
    digests = record.get("outputs") or {}
    try:
        paths = output_paths(out_dir, rel, digests)
    except KeyError:                             # an output kind this version does not know
        return False
    for kind, digest in digests.items():
        try:
            if file_sha256(paths[kind]) != digest:
                return False
        except OSError:
            return False
    return True


#: keys of a skeleton JSON's ``meta`` that hold wall-clock times (they differ run to run);
#: and any key ending in ``_seconds`` (the quality measures' ``measure_seconds``)
_CLOCK_KEYS = ("timings", "seconds")


def skeleton_digest(doc: dict) -> str:
    """SHA-256 of a skeleton JSON document without its wall-clock times (``meta.timings``,
    every ``seconds`` and ``*_seconds`` inside meta): two runs that computed the same skeleton
    have the same digest, whichever machine, worker or order."""
    doc = dict(doc)
    doc["meta"] = _drop_clock(doc.get("meta", {}))
    text = json.dumps(doc, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()


def _drop_clock(x):
    if isinstance(x, dict):
        return {k: _drop_clock(v) for k, v in x.items()
                if k not in _CLOCK_KEYS and not k.endswith("_seconds")}
    if isinstance(x, list):
        return [_drop_clock(v) for v in x]
    return x
