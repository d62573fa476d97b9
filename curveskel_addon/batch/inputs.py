"""The assets of a batch: mesh files found in folders, globs, manifest files or named one by one.

Each asset has a *relative path* under the batch's root folder; its outputs mirror it under the
output folder (``lib/chairs/a.obj`` -> ``OUT/chairs/a.obj.json`` with root ``lib``). The root is
the deepest folder holding every input as given (a folder, a named file's folder, a glob's folder
before its first wildcard, a manifest entry's folder), or ``root=`` when given.

Everything here is sorted, so the list of assets (and so the results table) does not depend on
the order the file system lists folders in.
"""

from __future__ import annotations

import glob
import os
import re
from dataclasses import dataclass
from pathlib import Path

from ..core import CurveSkelError

__all__ = ["Asset", "Collected", "collect", "refuse_url", "MESH_SUFFIXES", "MANIFEST_SUFFIXES"]

#: the formats the command line reads (curveskel_addon.core.mesh_io says the same; a test checks)
MESH_SUFFIXES = (".obj", ".ply", ".stl", ".off")
#: a file with one of these suffixes, given as an input, lists paths (one a line)
MANIFEST_SUFFIXES = (".txt", ".lst", ".list")
_MAGIC = set("*?[")


@dataclass(frozen=True)
class Asset:
    """One mesh file of the batch.

    Attributes
    ----------
    source : str
        Absolute path of the file (symbolic links not resolved: the name the user sees).
    rel : str
        Its path under the root, with forward slashes; names its outputs.
    size : int
        Bytes, or -1 if the file does not exist (a manifest may list missing files: they get a
        row saying so).
    """

    source: str
    rel: str
    size: int


@dataclass
class Collected:
    """What :func:`collect` found.

    Attributes
    ----------
    assets : list of Asset
        Sorted by ``rel``; one per file, however many inputs named it.
    root : Path
        The folder the relative paths start from.
    ignored : int
        Files in the folders given whose suffix is no mesh format (not assets).
    """

    assets: list
    root: Path
    ignored: int = 0


def collect(inputs, *, root=None, exclude=None) -> Collected:
    """The mesh files the inputs name.

    Parameters
    ----------
    inputs : iterable of str or Path
        A folder (searched recursively; hidden folders and files skipped, other suffixes
        ignored), a glob (``lib/**/*.obj``; ``**`` crosses folders), a manifest (a ``.txt``,
        ``.lst`` or ``.list`` file: one path a line, relative to the manifest's folder, ``#``
        comments and blank lines skipped), or a file (any suffix: one that is no mesh format
        gets a row saying so).
    root : str or Path, optional
        The folder relative paths start from; every asset must lie inside it.
    exclude : str or Path, optional
        A folder never searched (the output folder, when it lies inside an input folder).

    Returns
    -------
    Collected

    Raises
    ------
    CurveSkelError
        One line: an input that does not exist, a glob that matches nothing, an unreadable
        manifest, an asset outside ``root``, or no mesh file at all.
    """
    skip = os.path.abspath(exclude) if exclude is not None else None
    found: list[tuple[str, str]] = []          # (absolute path, base folder)
    ignored = 0
    for given in inputs:
        text = os.fspath(given)
        refuse_url(text)
        path = os.path.abspath(os.path.expanduser(text))
        if os.path.isdir(path):
            files, n = _walk(path, skip)
            found += [(f, path) for f in files]
            ignored += n
        elif os.path.isfile(path):
            if Path(path).suffix.lower() in MANIFEST_SUFFIXES:
                found += _manifest(path)
            else:
                found.append((path, os.path.dirname(path)))
        elif _MAGIC & set(text):
            hits = sorted(glob.glob(os.path.expanduser(text), recursive=True))
            if not hits:
                raise CurveSkelError(f"{text} matches no file")
            base = _glob_base(path)
            for hit in map(os.path.abspath, hits):
                if os.path.isdir(hit):
                    files, n = _walk(hit, skip)
                    found += [(f, base) for f in files]
                    ignored += n
                elif Path(hit).suffix.lower() in MESH_SUFFIXES:
                    found.append((hit, base))
                else:
                    ignored += 1
        else:
            raise CurveSkelError(f"no such file or folder: {text}")
    if not found:
        raise CurveSkelError("no mesh files (" + " ".join(MESH_SUFFIXES) + ") in "
                             + ", ".join(map(os.fspath, inputs)))
    if root is None:
        try:
            base = os.path.commonpath([b for _, b in found])
        except ValueError:                       # different drives (Windows)
            raise CurveSkelError("the inputs share no folder: give --root") from None
    else:
        base = os.path.abspath(root)
    assets: dict[str, Asset] = {}
    seen: set[str] = set()
    for path, _ in sorted(found):
        rel = os.path.relpath(path, base)
        if rel == os.pardir or rel.startswith(os.pardir + os.sep):
            raise CurveSkelError(f"{path} is not inside the root {base}")
        real = os.path.realpath(path)
        if real in seen:                         # one file named twice (a folder and a glob)
            continue
        seen.add(real)
        try:
            size = os.stat(path).st_size
        except OSError:
            size = -1
        rel = Path(rel).as_posix()
        assets.setdefault(rel, Asset(path, rel, size))
    return Collected(sorted(assets.values(), key=lambda a: a.rel), Path(base), ignored)


_URL = re.compile(r"^[A-Za-z][A-Za-z0-9+.-]+://")


def refuse_url(text: str) -> None:
    """Local paths only (a network file system mounted at the same path everywhere counts):
    an fsspec URL (s3://, gs://, http://, ...) is refused with what to do instead. Object
    stores cannot rename a file atomically, which the batch's outputs rely on."""
    if _URL.match(text):
        raise CurveSkelError(f"{text}: URLs are not supported, only paths (on a shared file "
                             "system for Dask); mount the bucket (s3fs, gcsfuse, rclone mount) "
                             "at the same path on every machine")


def _walk(folder: str, skip: str | None) -> tuple[list[str], int]:
    """Mesh files under ``folder`` (sorted) and the number of other files."""
    files, other = [], 0
    for top, dirs, names in os.walk(folder):
        dirs[:] = sorted(d for d in dirs if not d.startswith(".")
                         and os.path.join(top, d) != skip)
        for name in sorted(names):
            if name.startswith("."):
                continue
            if Path(name).suffix.lower() in MESH_SUFFIXES:
                files.append(os.path.join(top, name))
            else:
                other += 1
    return files, other


def _manifest(path: str) -> list[tuple[str, str]]:
    """The paths a manifest lists, each with its folder."""
    try:
        text = Path(path).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise CurveSkelError(f"cannot read the manifest {path}: "
                             f"{getattr(exc, 'strerror', None) or exc}") from None
    here = os.path.dirname(path)
    out = []
    for line in text.splitlines():
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        p = os.path.normpath(os.path.join(here, os.path.expanduser(line)))
        out.append((p, os.path.dirname(p)))
    return out


def _glob_base(pattern: str) -> str:
    """The folder of a glob before its first wildcard (``/lib/a/*/x.obj`` -> ``/lib/a``)."""
    parts = Path(pattern).parts
    keep = []
    for part in parts:
        if _MAGIC & set(part):
            break
        keep.append(part)
    return os.path.join(*keep) if keep else os.getcwd()
