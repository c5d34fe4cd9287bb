"""Progress bars on stderr, drawn where a person watches them.

Long commands show a tqdm bar on stderr (`bar`): ``synth``'s fabrics, training's steps,
``data check``'s files, ``embed``'s items, ``match``'s images. A bar is drawn only where
stderr is a terminal. Redirected into a log file or a pipe, every redraw would add a frame of
its own to the log (a 60-step training run wrote 5.7 KB of them, a long one megabytes), so
none is drawn there; what a command prints line by line (training's validation lines, ``index
build``'s shards) is unchanged. The environment variable ``LOOKFEEL_PROGRESS`` says otherwise:
``always`` draws bars into a log too, ``never`` draws none; unset (or ``auto``), as stderr
is. A command's ``--quiet`` (training's ``train.progress: false``) turns its bars off
whatever the variable says.

Example:
    >>> from lookfeel.progress import bar
    >>> for item in bar(items, desc="embed", unit="item", show=not quiet):
    ...     ...
"""

from __future__ import annotations

import os
import sys
import warnings
from collections.abc import Iterable
from typing import TYPE_CHECKING, Any, TypeVar

if TYPE_CHECKING:
    from tqdm import tqdm

__all__ = ["ENV", "bar", "shown"]

ENV = "LOOKFEEL_PROGRESS"
"""``always``, ``never`` or ``auto`` (the default): where bars are drawn (module doc)."""

_ALWAYS = {"always", "1", "true", "yes", "on"}
_NEVER = {"never", "0", "false", "no", "off"}

T = TypeVar("T")


def shown(wanted: bool = True) -> bool:
    """Whether a bar the caller ``wanted`` is drawn: never when not wanted; else as
    ``LOOKFEEL_PROGRESS`` says, and by default when stderr is a terminal.

    A value of ``LOOKFEEL_PROGRESS`` this module does not know is warned of, naming it, and
    read as ``auto``.
    """
    if not wanted:
        return False
    mode = os.environ.get(ENV, "").strip().lower()
    if mode in _ALWAYS:
        return True
    if mode in _NEVER:
        return False
    if mode not in ("", "auto"):
        warnings.warn(
            f"{ENV}={os.environ[ENV]!r}: expected always, never or auto; read as auto (bars "
            "only where stderr is a terminal)",
            stacklevel=2,
        )
    try:
        return bool(sys.stderr.isatty())
    except (AttributeError, ValueError):  # no stderr, or a closed one
        return False


def bar(iterable: Iterable[T] | None = None, *, show: bool = True, **kwargs: Any) -> tqdm[T]:
    """A tqdm progress bar on stderr, drawn if `shown` (``show``: the caller's own switch,
    e.g. ``not args.quiet``); when not, a silent one that still counts and iterates.
    ``kwargs`` go to tqdm (``total``, ``desc``, ``unit`` ...); ``leave`` defaults to False,
    so a finished bar leaves no line behind.
    """
    from tqdm import tqdm

    kwargs.setdefault("leave", False)
    return tqdm(iterable, disable=not shown(show), **kwargs)
