"""Atomic file writes: a reader sees the old file or the new one, never half of either.

Checkpoints, caches, indexes, configs and reports all go through here, so a run killed at any
moment leaves every file it had written intact (write to a temp file in the same folder, flush,
fsync, then ``os.replace``). The file gets the mode a plain ``open(path, "w")`` would give:
``0o666`` less the process's umask (a temp file alone would be ``0o600``, unreadable by a
teammate).
"""

from __future__ import annotations

import json
import math
import os
import tempfile
import threading
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import IO, Any

__all__ = [
    "atomic_write",
    "atomic_write_bytes",
    "atomic_write_json",
    "atomic_write_text",
    "current_umask",
    "file_mode",
    "finite_or_null",
    "remove_stale_temps",
]

_UMASK_LOCK = threading.Lock()


def current_umask() -> int:
    """The process's umask, read without changing it where the system allows (Linux)."""
    try:
        with open("/proc/self/status", encoding="ascii") as f:
            for line in f:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    with _UMASK_LOCK:  # elsewhere: set and restore it at once (briefly process-wide)
        mask = os.umask(0o077)
        os.umask(mask)
    return mask


def file_mode() -> int:
    """Mode of a new file under the current umask: ``0o666 & ~umask``."""
    return 0o666 & ~current_umask()


def remove_stale_temps(path: str | os.PathLike[str]) -> list[Path]:
    """Remove the temp files `atomic_write` left beside ``path`` when its process was killed
    mid-write (``.{name}.*.tmp``; a normal end, or an exception, removes its own). Call it
    only where no other process may be writing ``path`` now (a run's own checkpoints).

    Returns:
        The files removed.
    """
    p = Path(path)
    gone = []
    for tmp in p.parent.glob(f".{p.name}.*.tmp"):
        tmp.unlink(missing_ok=True)
        gone.append(tmp)
    return gone


def atomic_write(path: str | os.PathLike[str], write: Callable[[IO[bytes]], object]) -> Path:
    """Call ``write(f)`` on a temp file beside ``path``, then move it onto ``path``.

    Args:
        path: destination; its folder is created if missing.
        write: writes the whole content to the binary file object it is given.

    Returns:
        The destination path, of mode ``0o666 & ~umask`` (as `open` would create it).
    """
    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=p.parent, prefix=f".{p.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as f:
            if hasattr(os, "fchmod"):
                os.fchmod(f.fileno(), file_mode())
            write(f)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, p)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return p


def atomic_write_bytes(path: str | os.PathLike[str], data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically."""
    return atomic_write(path, lambda f: f.write(data))


def atomic_write_text(path: str | os.PathLike[str], text: str) -> Path:
    """Write UTF-8 ``text`` to ``path`` atomically."""
    return atomic_write_bytes(path, text.encode("utf-8"))


def finite_or_null(obj: Any) -> Any:
    """``obj`` with every NaN or infinite float, at any depth, replaced by None: a number that
    could not be measured is JSON's ``null``, never a bare ``NaN`` that strict parsers refuse."""
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, Mapping):
        return {k: finite_or_null(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [finite_or_null(v) for v in obj]
    return obj


def atomic_write_json(path: str | os.PathLike[str], data: Any, indent: int | None = None) -> Path:
    """Write ``data`` to ``path`` atomically as strict JSON (`finite_or_null`), newline-ended."""
    text = json.dumps(finite_or_null(data), indent=indent, allow_nan=False)
    return atomic_write_text(path, text + "\n")
