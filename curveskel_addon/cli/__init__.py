"""The ``curveskel`` command: ``curveskel COMMAND [args]``, one module per subcommand.

Adding a subcommand is one module in this package with ``main(argv, prog) -> int`` and one line
in :data:`COMMANDS`. A subcommand's module is imported only when it runs, so ``curveskel
--version`` and ``--help`` are quick. Nothing here imports bpy (the Blender outputs import it
when asked for), and ``curveskel_addon.core`` never imports this package.
"""

from __future__ import annotations

import difflib
import importlib
import os
import sys

from .. import __version__

__all__ = ["COMMANDS", "main", "run", "exit_with"]

#: subcommand -> (module in this package, one line for ``curveskel --help``)
COMMANDS: dict[str, tuple[str, str]] = {
    "skeletonize": ("skeletonize", "curve-skeleton of one mesh file (JSON, .blend, render, rig)"),
}


def _usage() -> str:
    width = max(map(len, COMMANDS))
    lines = [f"usage: curveskel [--version] [--help] COMMAND [args]",
             "",
             f"curveskel {__version__}: curve-skeletons of meshes (armature + Skin-modifier silhouette).",
             "",
             "commands:"]
    lines += [f"  {name:<{width}}  {what}" for name, (_, what) in COMMANDS.items()]
    lines += ["", "'curveskel COMMAND --help' explains a command's options."]
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    """Dispatch ``argv`` (default sys.argv[1:]) to its subcommand; returns the exit status."""
    argv = list(sys.argv[1:] if argv is None else argv)
    if not argv or argv[0] in ("-h", "--help"):
        _write(sys.stdout if argv else sys.stderr, _usage())
        return 0 if argv else 2
    if argv[0] in ("-V", "--version"):
        _write(sys.stdout, f"curveskel {__version__}\n")
        return 0
    name = argv[0]
    if name not in COMMANDS:
        close = difflib.get_close_matches(name, COMMANDS, n=1)
        hint = f" (did you mean '{close[0]}'?)" if close else ""
        _write(sys.stderr, f"error: unknown command {name!r}{hint}; commands: "
                           f"{', '.join(COMMANDS)} (see curveskel --help)\n")
        return 2
    module = importlib.import_module(f".{COMMANDS[name][0]}", __name__)
    return module.main(argv[1:], prog=f"curveskel {name}")


def _write(stream, text: str) -> None:
    try:
        stream.write(text)
        stream.flush()
    except (OSError, ValueError):
        pass


def exit_with(rc: int) -> None:
    """Leave with ``rc``; with bpy loaded at once, as the normal shutdown can crash inside Blender."""
    if "bpy" in sys.modules or "_bpy" in sys.modules:
        for s in (sys.stdout, sys.stderr):
            try:
                s.flush()
            except (OSError, ValueError, AttributeError):
                pass
        os._exit(rc)
    sys.exit(rc)


def run() -> None:
    """The console script ``curveskel`` (pyproject's ``[project.scripts]``)."""
    exit_with(main())
