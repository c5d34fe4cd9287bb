"""Worker processes that never outlive the process that started them.

Every pool of worker processes in lookfeel (the synthetic world's renderers, the information
table's feature extractors, the image decoders of `lookfeel.data.decode_pool`, the training
runs of `lookfeel.reproduce`) starts each worker with `die_with_parent`, so a run killed by
Ctrl-C, ``kill`` or ``SIGKILL`` leaves no orphan behind.
"""

from __future__ import annotations

import os
import signal
import sys
import threading
import time

__all__ = ["available_cores", "can_fork", "die_with_parent"]


def die_with_parent(parent: int) -> None:
    """Worker initializer: end this process when ``parent`` (the process that started it) ends.

    On Linux the kernel sends SIGKILL when the parent dies (``prctl(PR_SET_PDEATHSIG)``); a
    daemon thread also checks every second that the parent is still this process's parent
    (it covers other systems and a parent that died before the ``prctl``).
    """
    if sys.platform.startswith("linux"):
        import ctypes

        try:
            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(1, signal.SIGKILL, 0, 0, 0)  # 1 = PR_SET_PDEATHSIG
        except (OSError, AttributeError):
            pass

    def watch() -> None:
        while True:
            if os.getppid() != parent:
                os._exit(1)
            time.sleep(1.0)

    if os.getppid() != parent:
        os._exit(1)
    threading.Thread(target=watch, name="lookfeel-parent-watch", daemon=True).start()


def can_fork() -> bool:
    """Whether worker processes can be forked cheaply and safely here: Linux only (macOS's
    system frameworks are not fork-safe, Windows cannot fork), where a forked worker starts in
    milliseconds instead of the seconds a spawned one takes to import torch."""
    return sys.platform.startswith("linux") and hasattr(os, "fork")


def available_cores() -> int:
    """The CPU cores this process may run on (its affinity on Linux, else the machine's)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)
