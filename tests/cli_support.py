"""Running scripts/skeletonize.py in a subprocess from the tests (core and Blender alike)."""

from __future__ import annotations

import signal
import subprocess
import sys
from pathlib import Path

from meshes import capsule

CLI = Path(__file__).resolve().parents[1] / "scripts" / "skeletonize.py"


def run_cli(*args, limit=None, timeout=600, env=None):
    """The command line with ``args``; ``limit`` (bytes) makes the disk fill up there."""
    pre = None
    if limit is not None:
        import resource

        def pre():                     # a file-size limit: a disk that fills up at `limit` bytes
            signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
            resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))
    return subprocess.run([sys.executable, str(CLI), *map(str, args)], capture_output=True,
                          text=True, timeout=timeout, preexec_fn=pre, env=env)


def write_capsule_obj(path: Path) -> Path:
    """A small capsule as a 1-based OBJ file (a mesh the CLI reads quickly)."""
    V, F = capsule(n_around=12, n_body=12)
    with open(path, "w") as fh:
        fh.writelines(f"v {x:.9g} {y:.9g} {z:.9g}\n" for x, y, z in V)
        fh.writelines(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in F)
    return path
