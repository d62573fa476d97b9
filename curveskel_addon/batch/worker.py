"""A batch worker process: takes jobs on stdin, sends rows back, one asset at a time.

Started by :class:`.supervisor.Supervisor` (``python -c ...`` running :func:`main`). The
protocol is frames of a 4-byte big-endian length and a pickle, on the process's standard input
and on a copy of its standard output; the standard output itself is pointed at stderr first, so
whatever the core or Blender prints cannot mix into the frames.

* child -> parent: ``("ready", pid)`` once the core is imported, then ``("row", row, bpy)`` per
  job (``bpy``: whether Blender is loaded in this process now);
* parent -> child: ``(job, sha256)`` per asset, ``None`` to leave.

The worker leaves by itself when its parent dies (its parent process id changes): a batch
killed with SIGKILL leaves no worker computing on.
"""

from __future__ import annotations

import os
import pickle
import resource
import signal
import struct
import sys
import threading
import time

__all__ = ["main", "send", "read_frames", "peak_mb", "reset_peak"]

_HEADER = struct.Struct(">I")


def send(fh, obj) -> None:
    """Write one frame (length + pickle) and flush."""
    data = pickle.dumps(obj, protocol=pickle.HIGHEST_PROTOCOL)
    fh.write(_HEADER.pack(len(data)) + data)
    fh.flush()


def read_frames(buffer: bytearray):
    """Complete frames at the start of ``buffer`` (consumed), unpickled, in order."""
    while len(buffer) >= _HEADER.size:
        (n,) = _HEADER.unpack_from(buffer)
        if len(buffer) < _HEADER.size + n:
            break
        data = bytes(buffer[_HEADER.size:_HEADER.size + n])
        del buffer[:_HEADER.size + n]
        yield pickle.loads(data)


def _recv(fh):
    head = fh.read(_HEADER.size)
    if len(head) < _HEADER.size:
        return None                              # the parent closed the pipe: leave
    (n,) = _HEADER.unpack(head)
    return pickle.loads(fh.read(n))


def reset_peak() -> bool:
    """Reset this process's peak resident size (Linux: /proc/self/clear_refs), so the next
    :func:`peak_mb` is one asset's peak; False where the system cannot."""
    try:
        with open("/proc/self/clear_refs", "w") as fh:
            fh.write("5")
        return True
    except OSError:
        return False


def peak_mb() -> float:
    """Peak resident size of this process, MiB: since the last :func:`reset_peak` on Linux
    (VmHWM), over the process's life elsewhere (ru_maxrss)."""
    try:
        with open("/proc/self/status") as fh:
            for line in fh:
                if line.startswith("VmHWM:"):
                    return round(int(line.split()[1]) / 1024.0, 1)
    except OSError:
        pass
    r = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return round(r / 1024.0 if sys.platform != "darwin" else r / 2 ** 20, 1)


def _watch_parent(interval: float = 0.2) -> None:
    """Leave at once when the parent dies (we are handed to another process then)."""
    parent = os.getppid()

    def watch():
        while True:
            time.sleep(interval)
            if os.getppid() != parent:
                os._exit(3)

    threading.Thread(target=watch, name="curveskel-parent-watch", daemon=True).start()


def main() -> None:
    """The worker's loop (see the module's docstring)."""
    proto_in = sys.stdin.buffer
    proto_out = os.fdopen(os.dup(1), "wb")
    os.dup2(2, 1)                                # prints (core, Blender) go to stderr
    signal.signal(signal.SIGINT, signal.SIG_IGN)     # the batch decides when a worker stops
    import faulthandler

    faulthandler.enable()                        # a crash's "Fatal Python error" for its row
    _watch_parent()
    from .task import process

    send(proto_out, ("ready", os.getpid()))
    while True:
        msg = _recv(proto_in)
        if msg is None:
            break
        job, sha256 = msg
        reset_peak()
        row = process(job, sha256, peak_mb=peak_mb)
        send(proto_out, ("row", row, "bpy" in sys.modules))
    if "bpy" in sys.modules:                     # Blender's shutdown can crash: leave at once
        proto_out.close()
        os._exit(0)
