"""Problems found in a dataset, reported all at once with the path (and line) they concern."""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

from lookfeel.errors import LookfeelError
from lookfeel.shell import set_flag

__all__ = ["FEW_LACKING", "DatasetError", "Problem", "lacking_lines", "leave_out"]


@dataclass(frozen=True)
class Problem:
    """One thing wrong (``error``) or worth knowing (``warning``) about a dataset.

    Attributes:
        path: the file or folder concerned (``None`` for the dataset as a whole).
        message: what is wrong, in words a user can act on.
        severity: ``"error"`` (the file or fabric cannot be used) or ``"warning"``.
        line: 1-based line in ``path`` (labels.csv), when it applies.
    """

    path: Path | None
    message: str
    severity: str = "error"
    line: int | None = None

    def __str__(self) -> str:
        where = "" if self.path is None else str(self.path)
        if self.line is not None:
            where += f":{self.line}"
        return f"{where}: {self.message}" if where else self.message

    def to_dict(self) -> dict[str, object]:
        return {
            "path": None if self.path is None else str(self.path),
            "line": self.line,
            "severity": self.severity,
            "message": self.message,
        }


class DatasetError(LookfeelError):
    """A dataset cannot be used as asked; ``problems`` lists every reason, not the first only.

    One problem reads as one line (``path: what is wrong``); several as a count and one line
    each.
    """

    def __init__(self, problems: Iterable[Problem] | str, root: Path | None = None) -> None:
        if isinstance(problems, str):
            problems = [Problem(root, problems)]
        self.problems = tuple(problems)
        self.root = root
        if len(self.problems) == 1:
            only = self.problems[0]
            super().__init__(
                str(only) if only.path is not None or root is None else f"{root}: {only}"
            )
            return
        head = f"{len(self.problems)} problem(s)" + (f" in {root}" if root is not None else "")
        lines = [f"  {p}" for p in self.problems[:50]]
        if len(self.problems) > 50:
            lines.append(f"  ... and {len(self.problems) - 50} more (run `lookfeel data check`)")
        super().__init__("\n".join([head + ":", *lines]))


FEW_LACKING = 3
"""Fabrics lacking an item that `lacking_lines` names on a line each; where more lack it, one
line counts them and names this many."""


def lacking_lines(who: Sequence[str], total: int, noun: str, what: str) -> tuple[list[str], bool]:
    """The lines saying that the fabrics (or objects) ``who`` (``"12"``, ``"'sponge'"``), of
    ``total`` in the dataset, have no ``what`` item, and whether they are grouped into one.

    Up to `FEW_LACKING` of them, while others do have it, get a line each (``"fabric 12 has no
    depth item"``); more, or all, one line that counts them and names the first few (``"none
    of the 12 fabrics (1, 2, 3 and 9 more) has a depth item"``), so a dataset without a sense
    is one line, not one per fabric. Callers add what follows (a reason, a fix)."""
    if len(who) <= FEW_LACKING and len(who) < total:
        return [f"{noun} {w} has no {what} item" for w in who], False
    named = list(who) if len(who) <= FEW_LACKING + 1 else list(who[:FEW_LACKING])
    shown = ", ".join(named)
    if len(who) > len(named):
        shown += f" and {len(who) - len(named)} more"
    if len(who) == total:
        return [f"none of the {total} {noun}s ({shown}) has a {what} item"], True
    return [f"{len(who)} of the {total} {noun}s ({shown}) have no {what} item"], True


def leave_out(what: str, held: Sequence[str], noun: str, one: bool) -> str:
    """What follows a line of `lacking_lines` for a sense ``what`` (``"color"``) that some
    fabrics (``one``: a single one) lack: the ``--set`` of ``train.views`` that trains on the
    senses every fabric has (``held``: ``depth`` and ``touch``; one sense twice, as a Siamese
    run pairs two of its items), or that the missing items be added; ``noun`` is ``fabric`` or
    ``object``."""
    theirs = "its" if one else "their"
    if not held:
        return f"; add {theirs} {what} items (no sense is held by every {noun})"
    views = list(held) if len(held) > 1 else [held[0], held[0]]
    fix = set_flag(f"train.views=[{','.join(views)}]")
    return (
        f"; every {noun} has {' and '.join(held)}: {fix} "
        f"trains without {what}, or add {theirs} {what} items"
    )
