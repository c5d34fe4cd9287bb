"""Worker processes that never outlive the process that started them.

Every pool of worker processes in lookfeel (the synthetic world's renderers, the information
table's feature extractors, the image decoders of `lookfeel.data.decode_pool`, the training
runs of `lookfeel.reproduce`) starts each worker with `die_with_parent`, so a run killed by
Ctrl-C, ``kill`` or ``SIGKILL`` leaves no orphan behind.
"""

from __future__ import annotations

import functools
import multiprocessing
import multiprocessing.connection
import os
import signal
import sys
import threading
import time

__all__ = ["available_cores", "can_fork", "die_with_parent"]


def die_with_parent(parent: int) -> None:
    """Worker initializer: end this process when ``parent`` (the process that started it) ends.

    On Linux the kernel sends SIGKILL when the parent dies (``prctl(PR_SET_PDEATHSIG)``). On
    every system a daemon thread also waits for the parent to end (it covers systems without
    ``prctl`` and a parent that died before it): on the parent's sentinel, which every
    `multiprocessing` child has (`multiprocessing.parent_process`; a pipe that the parent's
    end closes on POSIX, the parent's process handle on Windows); else (a process that
    multiprocessing did not start) by checking every second that the parent is still this
    process's parent, which Windows cannot tell (its ``getppid`` keeps naming a dead parent).
    """
    if sys.platform.startswith("linux"):
        import ctypes

        try:
            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(1, signal.SIGKILL, 0, 0, 0)  # 1 = PR_SET_PDEATHSIG
        except (OSError, AttributeError):
            pass
    if os.getppid() != parent:  # it died before the prctl (where getppid tells)
        os._exit(1)
    sentinel = _parent_sentinel(parent)
    if sentinel is not None:
        watch = functools.partial(_wait_for_sentinel, sentinel, parent)
    else:
        watch = functools.partial(_poll_parent, parent)
    threading.Thread(target=watch, name="lookfeel-parent-watch", daemon=True).start()


def _parent_sentinel(parent: int) -> int | None:
    """The sentinel of ``parent`` (ready once it has ended) where multiprocessing started this
    process from it, else None."""
    process = multiprocessing.parent_process()
    if process is None or process.pid != parent:
        return None
    try:
        return process.sentinel
    except ValueError:  # multiprocessing has no sentinel for it
        return None


def _wait_for_sentinel(sentinel: int, parent: int) -> None:
    """End this process once ``sentinel`` (its parent's) is ready: the parent has ended (if
    the sentinel cannot be waited on, `_poll_parent` instead)."""
    try:
        multiprocessing.connection.wait([sentinel])
    except (OSError, ValueError):
        _poll_parent(parent)
    os._exit(1)


def _poll_parent(parent: int) -> None:
    """End this process once ``parent`` is no longer its parent (checked every second)."""
    while os.getppid() == parent:
        time.sleep(1.0)
    os._exit(1)


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
