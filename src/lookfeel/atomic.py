"""Atomic file writes: a reader sees the old file or the new one, never half of either.

Checkpoints, caches, indexes, configs and reports all go through here, so a run killed at any
moment leaves every file it had written intact (write to a temp file in the same folder, flush,
fsync, then ``os.replace``). The file gets the mode a plain ``open(path, "w")`` would give:
an existing file keeps its own, and one its owner made read-only is refused (`check_writable`);
a new one gets ``0o666`` less the process's umask (a temp file alone would be ``0o600``,
unreadable by a teammate). A write that fails (a full disk, a folder made read-only meanwhile)
raises an `OSError` naming the destination, never the hidden temp file, and leaves the old
file as it was.
"""

from __future__ import annotations

import errno
import glob
import json
import math
import os
import re
import stat
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import IO, Any

__all__ = [
    "atomic_write",
    "atomic_write_bytes",
    "atomic_write_json",
    "atomic_write_text",
    "check_writable",
    "current_umask",
    "file_mode",
    "finite_or_null",
    "remove_stale_temps",
    "remove_stale_temps_in",
    "replace_path",
]

_UMASK_LOCK = threading.Lock()
_UMASK: int | None = None
"""The umask read where ``/proc`` cannot tell it (`current_umask`), once per process."""


def current_umask() -> int:
    """The process's umask. On Linux it is read from ``/proc`` each time, without changing it.
    Elsewhere (macOS) the only way to read it is to set it and set it back, which for that
    instant holds for every thread of the process (a folder another thread made then would be
    ``0o700``): it is read so once, on first use, and remembered (a umask this process sets
    later, after a first atomic write, is not seen there)."""
    try:
        with open("/proc/self/status", encoding="ascii") as f:
            for line in f:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    global _UMASK
    with _UMASK_LOCK:
        if _UMASK is None:
            _UMASK = os.umask(0o077)
            os.umask(_UMASK)
        return _UMASK


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
    for tmp in p.parent.glob(f"{glob.escape(_temp_prefix(p.name))}*.tmp"):
        tmp.unlink(missing_ok=True)
        gone.append(tmp)
    return gone


_TEMP_NAME = re.compile(r"\..+\.[a-z0-9_]{8}\.tmp")
"""What `atomic_write`'s temp files are named: ``.{name}.`` (`_temp_prefix`), the 8 characters
``tempfile.mkstemp`` draws, ``.tmp``."""


def remove_stale_temps_in(folder: str | os.PathLike[str]) -> list[Path]:
    """Remove every temp file `atomic_write` left in ``folder`` (not below it) when its process
    was killed mid-write: a command's own output folder, written again (`remove_stale_temps`
    for one file). Call it only where no other process may be writing in ``folder`` now.

    Returns:
        The files removed.
    """
    root = Path(folder)
    if not root.is_dir():
        return []
    gone = []
    for tmp in root.iterdir():
        if _TEMP_NAME.fullmatch(tmp.name) and tmp.is_file() and not tmp.is_symlink():
            tmp.unlink(missing_ok=True)
            gone.append(tmp)
    return sorted(gone)


_NAME_MAX = 255
"""Bytes a file name may hold on the common file systems (ext4, XFS, btrfs, tmpfs, APFS)."""


def _temp_prefix(name: str) -> str:
    """The temp files' prefix for ``name``: ``.{name}.``, with the name cut short enough
    that the temp name (prefix, 8 random characters, ``.tmp``) fits where ``name`` fits."""
    extra = len("..") + 8 + len(".tmp")  # the dots around the name, mkstemp's characters
    raw = name.encode("utf-8", "surrogateescape")
    if len(raw) + extra <= _NAME_MAX:
        return f".{name}."
    cut = raw[: _NAME_MAX - extra - len("~")].decode("utf-8", "ignore")
    return f".{cut}~."


def check_writable(path: str | os.PathLike[str]) -> None:
    """Refuse what `atomic_write` would refuse, before any work: an existing ``path`` its
    owner made read-only (a plain ``open(path, "w")`` refuses it too), or a folder it would go
    in that exists and cannot be written.

    Raises:
        PermissionError: naming ``path`` (or its folder) and why.
    """
    p = Path(path)
    if p.is_file() and not os.access(p, os.W_OK):
        raise PermissionError(
            errno.EACCES,
            "the file is read-only for this user; lookfeel does not replace it",
            str(p),
        )
    folder = p.parent
    if folder.is_dir() and not os.access(folder, os.W_OK | os.X_OK):
        raise PermissionError(
            errno.EACCES,
            "the folder is read-only for this user; nothing can be written in it",
            str(folder),
        )


def atomic_write(path: str | os.PathLike[str], write: Callable[[IO[bytes]], object]) -> Path:
    """Call ``write(f)`` on a temp file beside ``path``, then move it onto ``path``.

    Args:
        path: destination; its folder is created if missing.
        write: writes the whole content to the binary file object it is given.

    Returns:
        The destination path, of its own mode where it existed, else ``0o666 & ~umask`` (as
        `open` would give).

    Raises:
        PermissionError: ``path`` exists and is read-only for this user (`check_writable`).
        OSError: the write failed (a full disk ...), naming ``path``; the old file is as it
            was and no temp file is left.
    """
    p = Path(path)
    check_writable(p)
    try:
        mode = stat.S_IMODE(os.stat(p).st_mode) if p.is_file() else file_mode()
        p.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=p.parent, prefix=_temp_prefix(p.name), suffix=".tmp")
    except OSError as e:
        raise _naming(e, p) from None
    try:
        with os.fdopen(fd, "wb") as f:
            if hasattr(os, "fchmod"):
                os.fchmod(f.fileno(), mode)
            write(f)
            f.flush()
            os.fsync(f.fileno())
        replace_path(tmp, p)
    except OSError as e:
        Path(tmp).unlink(missing_ok=True)
        raise _naming(e, p) from None
    except RuntimeError as e:  # torch.save's zip writer says a short write so
        Path(tmp).unlink(missing_ok=True)
        if "inline_container" not in str(e) and "unexpected pos" not in str(e):
            raise
        first = str(e).strip().splitlines()[0] if str(e).strip() else "no reason given"
        raise OSError(
            errno.EIO, f"the write stopped short (is the disk full? torch: {first})", str(p)
        ) from None
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return p


_REPLACE_WAITS = (0.05, 0.1, 0.15, 0.2, 0.25, 0.25, 0.25, 0.25, 0.25, 0.25)
"""Seconds `replace_path` waits before each retry on Windows: about 2 s in all."""


def replace_path(tmp: str | Path, dest: Path) -> None:
    """``os.replace(tmp, dest)``. On Windows a destination that another process has open (a
    reader of the checkpoint, an antivirus scan, the search indexer) cannot be replaced for
    as long as it is open (`PermissionError`): there it is retried for about 2 s before the
    error is raised. Elsewhere a `PermissionError` is a real one, raised at once."""
    if sys.platform != "win32":
        os.replace(tmp, dest)
        return
    for wait in _REPLACE_WAITS:
        try:
            os.replace(tmp, dest)
            return
        except PermissionError:
            time.sleep(wait)
    os.replace(tmp, dest)


def _naming(e: OSError, path: Path) -> OSError:
    """``e`` as an error of ``path`` (the destination) where it names the temp file written
    for it or nothing (the command line prints an `OSError` as ``path: reason``); one about
    another file (the folder it could not create) keeps that file's name."""
    name = Path(e.filename).name if e.filename is not None else None
    if name is None or name.startswith(_temp_prefix(path.name)):
        e.filename, e.filename2 = str(path), None
    return e


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
