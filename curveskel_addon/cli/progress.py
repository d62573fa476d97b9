"""Progress of a run on stderr: the stage's name and a bar.

Nothing is shown for the first ``delay`` seconds (1 s; the environment variable
``CURVESKEL_PROGRESS_DELAY`` sets another), so a quick run prints only its summary. Then:

* on a terminal, one line redrawn in place (``\\r``): stage, bar, percent, seconds; cleared at
  the end, so the summary that follows is not mixed with it;
* elsewhere (a log file, CI, a pipe), one plain line per stage as it begins
  (``progress    optimising (2.4 s)``): no redraws to clutter a log; none while the mesh is
  read, so a bad file's error stays the only line.

The reporter never stops a run: a stderr that fails (closed pipe, hung-up terminal) silences it.
"""

from __future__ import annotations

import os
import sys
import time

__all__ = ["Progress", "STAGE_NAMES"]

#: The words shown for the core's stages (``SkeletonRun``'s progress callback) and the CLI's own.
#: The search's stages (a minimisation, then moves, in rounds: ``fit``, ``merge``, ``prune``,
#: ``split``, ``contract``; the paper's solver: ``initialise``, ``fit``) show as one,
#: "optimising", its bar the core's fraction: a log gets one line for the whole search, not one
#: per round.
STAGE_NAMES = {
    "read": "reading the mesh",
    "first_approximation": "first approximation",
    "initialise": "optimising",
    "fit": "optimising",
    "merge": "optimising",
    "prune": "optimising",
    "split": "optimising",
    "contract": "optimising",
    "done": "optimising",
    "quality": "quality measures",
    "write": "writing",
    "blender": "Blender",
}
_BAR = 24
#: Stages with no line of their own in a log: while the mesh is read and checked, an error is
#: still to come as the one line on stderr (a slow start must not put a progress line first).
_NOT_LOGGED = ("read",)


class Progress:
    """A ``progress(stage, fraction)`` callback drawing on a stream.

    Parameters
    ----------
    stream : text file, default sys.stderr
    enabled : bool
        False (``--quiet``): draw nothing.
    tty : bool, optional
        Redraw one line in place; default: whether ``stream`` is a terminal.
    delay : float, optional
        Seconds before anything is shown; default ``CURVESKEL_PROGRESS_DELAY`` or 1.
    clock : callable, optional
        Seconds (``time.monotonic``; tests pass their own).
    """

    def __init__(self, stream=None, *, enabled: bool = True, tty: bool | None = None,
                 delay: float | None = None, clock=time.monotonic):
        self.stream = sys.stderr if stream is None else stream
        self.enabled = enabled and self.stream is not None
        if tty is None:
            try:
                tty = self.stream.isatty()
            except (AttributeError, ValueError, OSError):
                tty = False
        self.tty = tty
        if delay is None:
            try:
                delay = float(os.environ.get("CURVESKEL_PROGRESS_DELAY", "1"))
            except ValueError:
                delay = 1.0
        self.delay = delay
        self.clock = clock
        self.start = clock()
        self.stage = None
        self.fraction = 0.0
        self._drawn_at = None
        self._width = 0
        self.shown = False

    def __call__(self, stage: str, fraction: float = 0.0) -> None:
        """The core's callback: ``stage`` has reached ``fraction`` (0..1)."""
        if not self.enabled:
            return
        new = self.stage is None or _name(stage) != _name(self.stage)
        self.stage, self.fraction = stage, max(0.0, min(float(fraction), 1.0))
        now = self.clock()
        if now - self.start < self.delay:
            return
        if self.tty:
            # a new stage at once, else at most ten redraws a second
            if new or self._drawn_at is None or now - self._drawn_at >= 0.1 or self.fraction >= 1.0:
                self._draw(now)
        elif (new or not self.shown) and stage not in _NOT_LOGGED:
            self._write(f"progress    {_name(stage)} ({now - self.start:.1f} s)\n")

    def _draw(self, now: float) -> None:
        filled = int(round(self.fraction * _BAR))
        name = _name(self.stage)
        line = (f"{name:<20} [{'#' * filled}{'-' * (_BAR - filled)}] "
                f"{100 * self.fraction:3.0f}%  {now - self.start:6.1f} s")
        pad = max(self._width - len(line), 0)
        self._write("\r" + line + " " * pad)
        self._width = len(line)
        self._drawn_at = now

    def _write(self, text: str) -> None:
        try:
            self.stream.write(text)
            self.stream.flush()
            self.shown = True
        except (OSError, ValueError):           # closed or hung up: carry on without
            self.enabled = False

    def close(self) -> None:
        """Clear the redrawn line (terminal), so what is printed next starts clean."""
        if self.enabled and self.tty and self._width:
            self._write("\r" + " " * self._width + "\r")
            self._width = 0


def _name(stage: str) -> str:
    return STAGE_NAMES.get(stage, stage)
