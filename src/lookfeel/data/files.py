"""Reading a data file under one policy: what every image and video read goes through.

`read_image_file` reads a file's bytes only if it is a regular file (a FIFO, device or folder
named like an image is refused at once, never waited on) of at most 512 MB; `ImageError` names
the file and what is wrong; `DEFAULT_MAX_PIXELS` is the largest frame decoded. Images
(`lookfeel.data.images`) and videos (`lookfeel.data.video`) both build on this module.
"""

from __future__ import annotations

import errno
import os
import stat
from pathlib import Path

from lookfeel.errors import LookfeelError

VIDEO_SUFFIXES = (".mov", ".mp4", ".avi", ".mkv", ".webm", ".m4v")
"""File suffixes read as videos (lower-case; the match ignores case): QuickTime and MP4 (``.m4v``
is MP4), AVI, Matroska and WebM (a Matroska subset; VP8, VP9 or AV1 inside)."""

__all__ = ["DEFAULT_MAX_PIXELS", "VIDEO_SUFFIXES", "ImageError", "file_kind", "read_image_file"]


class ImageError(LookfeelError):
    """An image file cannot be used; the message names the file and what is wrong."""

    def __init__(self, path: Path, message: str) -> None:
        self.path = path
        self.reason = message
        super().__init__(f"{path}: {message}")


DEFAULT_MAX_PIXELS = 50_000_000
"""Largest width x height decoded (a 50-megapixel photo; GelSight frames are 0.7 MP, Kinect depth
0.3 MP). Checked from the header, before decoding: 13000 x 13000 declared in a 0.4 MB PNG would
otherwise cost 2 GB."""
_MAX_FILE_BYTES = 512 * 1024 * 1024


def file_kind(mode: int) -> str:
    """What a non-regular file is, in words ("a FIFO (named pipe)"), from its ``st_mode``."""
    if stat.S_ISDIR(mode):
        return "a folder"
    if stat.S_ISFIFO(mode):
        return "a FIFO (named pipe)"
    if stat.S_ISSOCK(mode):
        return "a socket"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "a device"
    return "a special file"


def read_image_file(path: str | os.PathLike[str]) -> bytes:
    """The bytes of an image file, which must be a regular file (symbolic links followed).

    The file is opened without blocking and checked on the open descriptor, so a FIFO named
    like an image is refused at once rather than waited on, and nothing can swap the file
    between the check and the read.

    Raises:
        ImageError: missing, unreadable, not a regular file, or larger than 512 MB.
    """
    p = Path(path)
    try:
        fd = os.open(p, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_NOCTTY", 0))
    except FileNotFoundError:
        raise ImageError(p, "file not found") from None
    except OSError as e:
        if e.errno == errno.EISDIR:
            raise ImageError(p, "is a folder, not an image file") from None
        if e.errno == errno.ENXIO:  # a socket, or a FIFO with no writer on some systems
            raise ImageError(p, "not a regular file") from None
        raise ImageError(p, f"cannot read file: {e.strerror}") from None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            kind = file_kind(st.st_mode)
            raise ImageError(
                p,
                "is a folder, not an image file"
                if kind == "a folder"
                else f"is {kind}, not a regular image file",
            )
        if st.st_size > _MAX_FILE_BYTES:
            raise ImageError(p, f"file of {st.st_size} bytes is larger than {_MAX_FILE_BYTES}")
        chunks = []
        while chunk := os.read(fd, 1 << 20):
            chunks.append(chunk)
        return b"".join(chunks)
    except OSError as e:
        raise ImageError(p, f"cannot read file: {e.strerror}") from None
    finally:
        os.close(fd)
