"""The one base class of every error lookfeel raises for a user's input.

A ``LookfeelError`` carries a message for a person: one line that names the file, key or value
and what is wrong. ``lookfeel.cli.main`` catches it once, prints ``lookfeel: <message>`` and
exits 1; anything else is a bug and keeps its traceback. Library code raises a subclass (or this
class) and never prints.
"""

from __future__ import annotations


class LookfeelError(ValueError):
    """A user's data, file, option or config cannot be used; ``str(e)`` says which and why.

    It subclasses ``ValueError`` so code written against the older, separate error classes keeps
    working.
    """


def npz_problem(e: Exception) -> str:
    """Why ``np.load(path, allow_pickle=False)`` failed, for a person. NumPy reads any file that
    is neither an .npz nor an .npy as a pickle and then refuses it, advising to load it
    "unsafely": lookfeel never does, and the file is simply not an .npz archive."""
    text = str(e)
    if "pickled" in text and "allow_pickle" in text:
        return "not an .npz archive"
    return text.splitlines()[0] if text else type(e).__name__
