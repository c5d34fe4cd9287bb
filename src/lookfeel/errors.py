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
