"""``python -m curveskel_addon.cli COMMAND ...``: the ``curveskel`` command without installing."""

from . import run

run()
