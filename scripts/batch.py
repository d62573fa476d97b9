#!/usr/bin/env python3
"""Skeletonize a library of mesh files: ``curveskel batch`` from the source tree.

    python scripts/batch.py IN [IN ...] --out DIR [--workers N | --dask ADDRESS | --dask local:N]
                            [--timeout S] [--memory-limit SIZE] [--glb] [--blend] [--bind] [--quiet]

The same command, flags and behaviour as ``curveskel batch`` once the package is installed
(the code is curveskel_addon/cli/batch.py and curveskel_addon/batch/); ``--help`` explains
every option.
"""

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from curveskel_addon.cli import exit_with  # noqa: E402
from curveskel_addon.cli.batch import main  # noqa: E402

if __name__ == "__main__":
    exit_with(main(prog="batch.py"))
