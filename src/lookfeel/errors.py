"""The one base class of every error lookfeel raises for a user's input.

A ``LookfeelError`` carries a message for a person: one line that names the file, key or value
and what is wrong. ``lookfeel.cli.main`` catches it once, prints ``lookfeel: <message>`` and
exits 1 (as it does for an ``OSError`` naming a file the system refused, and Ctrl-C, which
exits 130); anything else is a bug and keeps its traceback. Library code raises a subclass (or
this class) and never prints.
"""

from __future__ import annotations

import os
import re
import sys
import types

__all__ = ["LookfeelError", "caller_stacklevel", "error_line", "load_problem"]


class LookfeelError(ValueError):
    """A user's data, file, option or config cannot be used; ``str(e)`` says which and why.

    It subclasses ``ValueError`` so code written against the older, separate error classes keeps
    working.
    """


def load_problem(e: Exception, path: str | os.PathLike[str] | None = None) -> str:
    """Why ``torch.load(path, weights_only=True)`` or ``np.load(path, allow_pickle=False)``
    failed, in one line for a person. Both refuse a file that is not theirs with paragraphs
    advising to load it unsafely (``weights_only=False``, ``allow_pickle=True``: running code
    from the file), which lookfeel never does: keep the reason alone, else the error's first
    sentence. Given the file's ``path``, a file that begins as neither a zip archive (what
    ``torch.save`` and ``np.savez`` write) nor a pickle is said to be so: torch's own error for
    it (a text file gives ``KeyError: '101'``) says nothing."""
    if path is not None:
        try:
            with open(path, "rb") as f:
                head = f.read(4)
        except OSError:
            head = b"PK\x03\x04"  # unreadable now: leave it to the error itself
        if head and not head.startswith((b"PK\x03\x04", b"\x80", b"\x93NUMPY")):
            return (
                "not a file torch.save or NumPy wrote: it begins as neither a zip archive nor "
                "a pickle"
            )
    text = " ".join(line.strip() for line in str(e).splitlines() if line.strip())
    if text.startswith("Weights only load failed"):  # torch
        _, _, reason = text.partition("WeightsUnpickler error:")
        reason = reason.split(" Check the documentation")[0].strip().split(". ")[0]
        return "not a file torch.save wrote of tensors and plain values" + (
            f": {reason[:200]}" if reason else ""
        )
    if "pickled" in text and "allow_pickle" in text:  # NumPy read it as a pickle
        return "not an .npz archive"
    return error_line(e)


_SENTENCE_END = re.compile(r"(?<!e\.g)(?<!i\.e)\. ")
"""Where a sentence ends: a full stop and a space, not that of ``e.g.`` or ``i.e.``."""


def error_line(e: BaseException, limit: int = 200) -> str:
    """Another library's error in one line for a person: its type and its first sentence (at
    most ``limit`` characters), without the paragraphs, graph dumps and advice that follow it
    (``[Caused by ...]``)."""
    text = " ".join(line.strip() for line in str(e).splitlines() if line.strip())
    first = _SENTENCE_END.split(text)[0].split(" [Caused by")[0] if text else "no reason given"
    return f"{type(e).__name__}: {first[:limit]}"


_PACKAGE = os.path.dirname(os.path.abspath(__file__)) + os.sep


def caller_stacklevel() -> int:
    """The ``stacklevel`` that makes a `warnings.warn` in the calling function name the first
    line outside lookfeel's own code: the user's call, however deep in lookfeel the warning is
    raised (``warnings.warn(msg, stacklevel=caller_stacklevel())``; Python 3.12's
    ``skip_file_prefixes`` does this, and lookfeel supports 3.11)."""
    frame: types.FrameType | None = sys._getframe(1)  # the function about to warn: level 1
    level = 1
    while frame is not None and frame.f_code.co_filename.startswith(_PACKAGE):
        frame = frame.f_back
        level += 1
    return level
