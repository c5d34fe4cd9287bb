"""Whether one path lies inside a folder, asked of the disk rather than of the spelling.

The guards that keep lookfeel from writing into a dataset (``--out`` inside ``--data``), from
swapping away the shell's current folder (``index build``) or from reading a link that leaves
the dataset compare paths. Comparing the text of two real paths (symbolic links followed) is
not enough: on a disk that ignores case, as macOS and Windows format theirs by default,
``~/Data`` and ``~/data/run`` are one folder and its subfolder, yet the strings differ, and a
folder mounted twice (a bind mount) has two names. `lies_within` also compares the folder's
identity (device and inode, as ``os.path.samefile`` does) with that of the path and of each
folder above it that exists.
"""

from __future__ import annotations

import os
from pathlib import Path

__all__ = ["lies_within"]


def _identity(path: str | os.PathLike[str]) -> tuple[int, int] | None:
    """(device, inode) of what ``path`` names, symbolic links followed; None when it does not
    exist or cannot be looked at."""
    try:
        st = os.stat(path)
    except (OSError, ValueError):  # ValueError: a NUL in the name
        return None
    return st.st_dev, st.st_ino


def lies_within(path: str | os.PathLike[str], folder: str | os.PathLike[str]) -> bool:
    """Whether ``path`` is ``folder`` or lies inside it (``path`` need not exist yet).

    True when the real paths (symbolic links followed) say so as text, or when ``path``, or
    the nearest folder above it that exists or any folder above that, is the same folder on
    disk as ``folder``: another spelling on a disk that ignores case (``~/data/run`` inside
    ``~/Data``), or another mount of the same folder.
    """
    real = Path(os.path.realpath(path))
    real_folder = Path(os.path.realpath(folder))
    if real == real_folder or real.is_relative_to(real_folder):
        return True
    target = _identity(real_folder)
    if target is None or target[1] == 0:  # 0: a file system that numbers no file
        return False
    return any(_identity(above) == target for above in (real, *real.parents))
