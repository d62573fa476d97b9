"""Progress of a batch on stderr: assets done, rate and ETA.

On a terminal a tqdm bar (``pip install "curveskel[batch]"``), redrawn in place, with the count
of assets that are not ok; elsewhere (a log file, CI) one plain line when another tenth of the
batch is done or a minute has passed, so a log stays readable. ``enabled=False`` (``--quiet``)
draws nothing. The reporter never stops a batch: a stderr that fails silences it.
"""

from __future__ import annotations

import sys
import time

__all__ = ["BatchProgress"]


class BatchProgress:
    """Counts rows as they arrive and shows the batch's progress.

    Parameters
    ----------
    total : int
        Assets in the batch.
    enabled : bool
    stream : text file, default sys.stderr
    tty : bool, optional
        Draw a bar (default: whether ``stream`` is a terminal and tqdm is installed).
    every : float
        Seconds between two plain lines at most (default 60).
    """

    def __init__(self, total: int, *, enabled: bool = True, stream=None, tty=None,
                 every: float = 60.0):
        self.total = total
        self.stream = sys.stderr if stream is None else stream
        self.enabled = enabled and self.stream is not None
        self.done = 0
        self.failed = 0
        self.start = time.monotonic()
        self.every = every
        self._last_line = self.start
        self._last_tenth = 0
        self._bar = None
        if tty is None:
            try:
                tty = self.stream.isatty()
            except (AttributeError, ValueError, OSError):
                tty = False
        if self.enabled and tty:
            try:
                from tqdm import tqdm
            except ImportError:
                tqdm = None
            if tqdm is not None:
                self._bar = tqdm(total=total, unit="asset", file=self.stream, dynamic_ncols=True,
                                 smoothing=0.1, desc="curveskel batch")

    def update(self, row: dict) -> None:
        """One more asset done (``row``: its results row)."""
        self.done += 1
        if row.get("status") != "ok":
            self.failed += 1
        if not self.enabled:
            return
        try:
            if self._bar is not None:
                if self.failed:
                    self._bar.set_postfix_str(f"{self.failed} not ok", refresh=False)
                self._bar.update(1)
                return
            now = time.monotonic()
            tenth = (10 * self.done) // max(self.total, 1)
            if tenth > self._last_tenth or now - self._last_line >= self.every or self.done == self.total:
                self._last_tenth, self._last_line = tenth, now
                self.stream.write(self.line(now) + "\n")
                self.stream.flush()
        except (OSError, ValueError):
            self.enabled = False

    def line(self, now: float | None = None) -> str:
        """``progress    12/60 assets (20 %), 31.4/min, ETA 1.5 min, 1 not ok``."""
        now = time.monotonic() if now is None else now
        dt = max(now - self.start, 1e-9)
        rate = 60.0 * self.done / dt
        left = self.total - self.done
        eta = f"ETA {_duration(left * dt / self.done)}" if self.done and left else "done"
        bad = f", {self.failed} not ok" if self.failed else ""
        return (f"progress    {self.done}/{self.total} assets "
                f"({100 * self.done // max(self.total, 1)} %), {rate:.1f}/min, {eta}{bad}")

    def close(self) -> None:
        if self._bar is not None:
            try:
                self._bar.close()
            except (OSError, ValueError):
                pass
            self._bar = None


def _duration(s: float) -> str:
    if s < 90:
        return f"{s:.0f} s"
    if s < 5400:
        return f"{s / 60:.1f} min"
    return f"{s / 3600:.1f} h"
