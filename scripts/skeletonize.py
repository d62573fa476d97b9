#!/usr/bin/env python3
"""Skeletonize a mesh file from the command line: ``curveskel skeletonize`` from the source tree.

    python scripts/skeletonize.py MESH [--json OUT.json] [--blend OUT.blend] [--render OUT.png]
                                       [method options]

The same command, flags and behaviour as ``curveskel skeletonize`` once the package is installed
(the code is curveskel_addon/cli/skeletonize.py); ``--help`` explains every option.
"""

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from curveskel_addon.cli import exit_with  # noqa: E402
from curveskel_addon.cli.skeletonize import main  # noqa: E402

if __name__ == "__main__":
    exit_with(main(prog="skeletonize.py"))
