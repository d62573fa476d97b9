"""Output files of the command line: checked before the run, written whole or not at all.

Every output path is checked before any work (never the input mesh, never two options naming
one file, a regular file or nothing, a writable folder). Each output is written to a temporary
file beside the file it replaces, checked complete, flushed to disk and renamed over the old
file only then: the path holds the old file or the new one, never a part.

Policies (the README and ``--help`` say the same):

* a path that exists and is not a regular file (a directory, a FIFO, a device such as
  /dev/null, a socket) is refused: renaming over it would replace the device or hang on the
  FIFO's reader;
* a symbolic link is followed: the file it points to is replaced (in its own folder), the link
  stays a link; a link to something that is not a regular file is refused as above;
* the replaced file keeps its permission bits (a 600 file stays 600);
* a read-only file (no write permission bit, or one this user may not write) is refused, not
  replaced: read-only says "keep this".

A SIGINT, SIGTERM or SIGHUP removes the temporary files (:func:`remove_temps`) before the
process leaves.
"""

from __future__ import annotations

import os
import shutil
import stat
import tempfile
from dataclasses import dataclass
from pathlib import Path

from ..core import CurveSkelError

__all__ = ["Output", "check_outputs", "temp_path", "commit", "remove_temps", "incomplete",
           "OUTPUT_FLAGS"]

#: temporary files of this run still on disk (removed on any failure or interrupt)
_TEMPS: set[Path] = set()
#: the output options, in the order they are written
OUTPUT_FLAGS = ("json", "glb", "fbx", "blend", "render", "report")
_SUFFIX_NEEDED = {"glb": ".glb", "fbx": ".fbx"}
_KINDS = ((stat.S_ISDIR, "a directory"), (stat.S_ISFIFO, "a FIFO (named pipe)"),
          (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"),
          (stat.S_ISSOCK, "a socket"))


@dataclass(frozen=True)
class Output:
    """One output file.

    Attributes
    ----------
    flag : str
        The option's name without dashes ("json").
    given : Path
        The path as the user gave it (for messages).
    target : Path
        The file actually replaced: ``given``, or the file a symbolic link points to.
    """

    flag: str
    given: Path
    target: Path

    @property
    def opt(self) -> str:
        return "--" + self.flag


def check_outputs(args) -> dict[str, Output]:
    """The output paths given in ``args``, each checked before anything runs.

    Parameters
    ----------
    args : argparse.Namespace
        With ``mesh`` and the attributes named in :data:`OUTPUT_FLAGS` (None when not given).

    Returns
    -------
    dict flag -> Output, in the order of :data:`OUTPUT_FLAGS`.

    Raises
    ------
    CurveSkelError
        One line: the path is the input mesh, two options name one file, a wrong suffix, not
        a regular file, read-only, or in a folder that cannot be written.
    """
    mesh = Path(args.mesh).resolve()
    outs: dict[str, Output] = {}
    for flag in OUTPUT_FLAGS:
        path = getattr(args, flag, None)
        if path is None:
            continue
        path = Path(path)
        opt = "--" + flag
        res = Path(os.path.realpath(path))
        if res == mesh or (path.exists() and mesh.exists() and os.path.samefile(path, mesh)):
            raise CurveSkelError(f"{opt} {path} is the input mesh: refusing to overwrite it")
        for other in outs.values():
            if other.target == res:
                raise CurveSkelError(f"{other.opt} and {opt} name the same file {path}")
        need = _SUFFIX_NEEDED.get(flag)
        if need and path.suffix.lower() != need:
            raise CurveSkelError(f"{opt} {path}: the file name must end in {need}")
        _check_existing(path, opt)
        folder = res.parent
        while not folder.exists():
            folder = folder.parent
        if not folder.is_dir():
            raise CurveSkelError(f"cannot write {opt} {path}: {folder} is a file, not a folder")
        if not os.access(folder, os.W_OK | os.X_OK):
            raise CurveSkelError(f"cannot write {opt} {path}: the folder {folder} is not writable")
        if folder == res.parent:
            _probe(folder, opt, path)
        outs[flag] = Output(flag, path, res)
    return outs


def _check_existing(path: Path, opt: str) -> None:
    """Refuse an existing path that is not a regular file, or a read-only one (a symbolic link
    is judged by what it points to; a link to nothing yet is fine: the file is created)."""
    try:
        st = os.stat(path)                       # follows symbolic links
    except (FileNotFoundError, NotADirectoryError):
        return                 # nothing there, a link to nothing yet (or a file as a folder:
                               # said by the folder check)
    except OSError as exc:                       # a link loop, a folder we may not search
        raise CurveSkelError(f"cannot write {opt} {path}: {exc.strerror or exc}") from None
    link = " (through a symbolic link)" if path.is_symlink() else ""
    for test, kind in _KINDS:
        if test(st.st_mode):
            raise CurveSkelError(f"cannot write {opt} {path}: it is {kind}{link}, not a regular file")
    if not stat.S_ISREG(st.st_mode):
        raise CurveSkelError(f"cannot write {opt} {path}: it is not a regular file{link}")
    if not st.st_mode & 0o222 or not os.access(path, os.W_OK):
        raise CurveSkelError(f"cannot write {opt} {path}: the file is read-only (mode "
                             f"{stat.S_IMODE(st.st_mode):03o}){link}: refusing to replace it "
                             "(make it writable, or choose another name)")


def _probe(folder: Path, opt: str, path: Path) -> None:
    """Create and remove a file in ``folder`` (a read-only file system passes os.access)."""
    try:
        fd, name = tempfile.mkstemp(prefix=".curveskel-probe-", dir=folder)
    except OSError as exc:
        raise CurveSkelError(f"cannot write {opt} {path}: cannot create a file in {folder} "
                             f"({exc.strerror or exc})") from None
    os.close(fd)
    os.unlink(name)


def temp_path(out: Output) -> Path:
    """A new temporary file name beside ``out.target``, with its suffix (exporters go by it);
    the folder is created if needed. Registered until committed or removed."""
    target = out.target
    target.parent.mkdir(parents=True, exist_ok=True)
    tmp = target.with_name(f".{target.name}.tmp-{os.getpid()}{target.suffix}")
    _TEMPS.add(tmp)
    return tmp


def remove_temps() -> None:
    """Remove every temporary file of this run still on disk (safe to call from a handler)."""
    for tmp in list(_TEMPS):
        for p in (tmp, Path(str(tmp) + "@")):         # Blender writes "<name>@" then renames
            try:
                p.unlink()
            except OSError:
                pass
        _TEMPS.discard(tmp)


def pending_temps() -> list[Path]:
    """The temporary files not yet committed or removed (for tests)."""
    return sorted(_TEMPS)


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


def kept(out: Output) -> str:
    """What is left at the path after a failed write, in words."""
    return "the previous file is kept" if out.target.exists() else "nothing was written"


def commit(tmp: Path, out: Output, *, backup: bool = False) -> None:
    """Check the temporary file ``tmp`` is complete, give it the mode of the file it replaces,
    flush it to disk and rename it to ``out.target`` (atomic: the old file or the new one,
    never a part). Otherwise remove it, keep the old file and raise CurveSkelError."""
    why = incomplete(tmp)
    target = out.target
    try:
        if why is None:
            try:
                mode = stat.S_IMODE(os.stat(target).st_mode)
            except FileNotFoundError:
                mode = None
            if mode is not None:
                os.chmod(tmp, mode)              # the replaced file's permissions, not umask's
            fd = os.open(tmp, os.O_RDONLY)
            try:
                os.fsync(fd)
            finally:
                os.close(fd)
            if backup and target.exists():
                shutil.copy2(target, target.with_name(target.name + "1"))
            os.replace(tmp, target)
            _TEMPS.discard(tmp)
            return
    except OSError as exc:
        why = exc.strerror or str(exc)
    remove_temps()
    raise CurveSkelError(f"could not write {out.opt} {out.given}: {why} (disk full?); {kept(out)}")
