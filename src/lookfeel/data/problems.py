"""Problems found in a dataset, reported all at once with the path (and line) they concern."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

from lookfeel.errors import LookfeelError

__all__ = ["DatasetError", "Problem"]


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
