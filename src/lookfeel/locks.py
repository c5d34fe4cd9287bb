"""One lookfeel process at a time per output: an exclusive lock beside what a command writes.

Two commands writing one output at once leave it made of both (two trainings into one run
folder: one's config, the other's checkpoint, both logs interleaved; two `synth` runs: one
world's labels over the other's images). `exclusive` holds ``OUT.lock`` beside the output
(``fcntl.flock``, which the system releases when the process ends, however it ends): a second
process is refused in one line naming the first's PID. ``index build``, ``train`` (and so every
run ``cv`` and ``reproduce`` train), ``synth`` and ``reproduce`` hold one. On a system without
``fcntl`` (not Linux or macOS) nothing is locked.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator
from pathlib import Path

from lookfeel.errors import LookfeelError

__all__ = ["BusyError", "exclusive", "is_held", "lock_path"]


class BusyError(LookfeelError):
    """Another process is writing the output, or its lock's name is taken by a file of the
    user's."""


def lock_path(target: str | os.PathLike[str]) -> Path:
    """``TARGET.lock``: the lock beside ``target`` (``.`` and ``..`` by the folder's own name)."""
    root = Path(target)
    if root.name in ("", ".", ".."):
        root = Path(os.path.abspath(root))
    return root.with_name(root.name + ".lock")


@contextlib.contextmanager
def exclusive(
    target: str | os.PathLike[str],
    command: str,
    what: str,
    error: type[LookfeelError] = BusyError,
) -> Iterator[None]:
    """Hold ``TARGET.lock`` (`lock_path`) exclusively while writing ``target``.

    The lock file holds the holder's PID and is removed on a normal end; one left by a killed
    process is taken over, and any other file of that name is refused, never removed.

    Args:
        target: the output (a folder or a file; it need not exist yet).
        command: the command, as messages name it (``"train"``, ``"index build"``).
        what: what it writes, for the message (``"this run"``).
        error: the error class to raise.

    Raises:
        error: another process holds the lock (naming ``target``, the command and the holder's
            PID), or ``TARGET.lock`` is a file of the user's or a folder.
    """
    try:
        import fcntl
    except ImportError:  # not on Linux or macOS: no lock
        yield
        return
    target = Path(target)
    path = lock_path(target)
    path.parent.mkdir(parents=True, exist_ok=True)
    if path.exists() or path.is_symlink():  # a lock holds a PID, or nothing yet
        held = path.read_bytes()[:64] if path.is_file() and not path.is_symlink() else None
        if held is None or not (held.strip().isdigit() or not held.strip()):
            raise error(
                f"{target}: {path} is in the way of the {_noun(command)}'s lock and is not one "
                "(a lock holds a process id); it is kept: move it, or choose another --out"
            )
    while True:
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o666)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            pid = os.pread(fd, 32, 0).decode("ascii", "replace").strip() or "unknown"
            os.close(fd)
            raise error(
                f"{target}: another `lookfeel {command}` is writing {what} (PID {pid}, lock "
                f"{path}); wait for it to end, or stop it"
            ) from None
        try:  # its last holder may have removed the file between our open and our lock
            same = os.path.samestat(os.fstat(fd), os.stat(path))
        except FileNotFoundError:
            same = False
        if same:
            break
        os.close(fd)
    try:
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"{os.getpid()}\n".encode("ascii"), 0)
        yield
    finally:
        path.unlink(missing_ok=True)  # while still held: no other process holds this file
        os.close(fd)


def is_held(lock: Path) -> bool:
    """Whether a live process holds the lock file ``lock`` (`exclusive`'s, `lock_path`): one
    that can be taken at once (shared, and released at once) is held by none; no file, no
    holder."""
    try:
        import fcntl
    except ImportError:  # not on Linux or macOS: nothing is locked
        return False
    try:
        fd = os.open(lock, os.O_RDONLY)
    except OSError:
        return False
    try:
        fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
    except OSError:
        return True
    else:
        fcntl.flock(fd, fcntl.LOCK_UN)
        return False
    finally:
        os.close(fd)


def _noun(command: str) -> str:
    """What the message calls the command's process: ``index build`` -> ``build``."""
    return command.split()[-1]
