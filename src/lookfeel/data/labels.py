"""Reading ``labels.csv``: one row per fabric, ``fabric_id`` required, every other column optional.

Columns (shared/DATASET.md): ``cluster8`` (or any ``cluster*``), ``thickness_mm``, ``density``,
``stiffness``, ``stretchiness``, ``paper_split`` (``train``, ``test``, ``excluded``), and any
further numeric column, which becomes an extra regression target. Empty cells mean unknown.
"""

from __future__ import annotations

import csv
import math
import re
from dataclasses import dataclass, field
from pathlib import Path

from lookfeel.data.problems import Problem

__all__ = ["PAPER_SPLITS", "LabelRow", "LabelTable", "read_labels"]

PAPER_SPLITS = ("train", "test", "excluded")
_MISSING = {"", "na", "n/a", "nan", "none", "null"}
_ID = re.compile(r"^[Ff]?0*(\d+)$")


@dataclass(frozen=True)
class LabelRow:
    """One fabric's row: known values only (unknown cells are absent)."""

    fabric_id: int
    line: int
    values: dict[str, float] = field(default_factory=dict)
    cluster: int | None = None
    paper_split: str | None = None


@dataclass(frozen=True)
class LabelTable:
    """The parsed file: its label columns, the cluster column used, and rows by fabric id."""

    path: Path
    columns: tuple[str, ...]
    cluster_column: str | None
    rows: dict[int, LabelRow]


def parse_fabric_id(text: str) -> int | None:
    """``"12"``, ``"0012"`` or ``"F0012"`` -> 12; anything else -> None."""
    m = _ID.match(text.strip())
    return int(m.group(1)) if m else None


def read_labels(path: Path) -> tuple[LabelTable, list[Problem]]:
    """Parse a labels.csv, collecting every problem instead of stopping at the first.

    Rows with an unusable ``fabric_id`` are dropped; a bad cell is reported and left unknown.

    Returns:
        The table (possibly partial) and the problems, each naming the file and line.
    """
    problems: list[Problem] = []
    try:
        text = path.read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as e:
        return LabelTable(path, (), None, {}), [Problem(path, f"cannot read labels file: {e}")]
    reader = csv.reader(text.splitlines())
    header = next(reader, None)
    if header is None:
        return LabelTable(path, (), None, {}), [Problem(path, "labels file is empty")]
    header = [h.strip() for h in header]
    if "fabric_id" not in header:
        return LabelTable(path, (), None, {}), [
            Problem(
                path,
                "no 'fabric_id' column in the header (first line); found: " + ", ".join(header),
                line=1,
            )
        ]
    dupes = sorted({h for h in header if header.count(h) > 1})
    if dupes:
        problems.append(Problem(path, f"duplicate column(s) {', '.join(dupes)}", line=1))
    empty_cols = [i + 1 for i, h in enumerate(header) if not h]
    if empty_cols:
        problems.append(Problem(path, f"column(s) {empty_cols} have no name", line=1))
    cluster_cols = [h for h in header if h.lower().startswith("cluster")]
    cluster_column = "cluster8" if "cluster8" in cluster_cols else next(iter(cluster_cols), None)
    value_cols = tuple(
        h for h in header if h and h != "fabric_id" and h != "paper_split" and h not in cluster_cols
    )
    rows: dict[int, LabelRow] = {}
    for lineno, cells in enumerate(reader, start=2):
        if not cells or all(not c.strip() for c in cells):
            continue
        if len(cells) != len(header):
            problems.append(
                Problem(path, f"{len(cells)} cells but the header has {len(header)}", line=lineno)
            )
            continue
        record = {h: c.strip() for h, c in zip(header, cells, strict=True)}
        fid = parse_fabric_id(record["fabric_id"])
        if fid is None:
            problems.append(
                Problem(
                    path,
                    f"fabric_id {record['fabric_id']!r} is not an integer id (e.g. 12 or F0012)",
                    line=lineno,
                )
            )
            continue
        if fid in rows:
            problems.append(
                Problem(
                    path,
                    f"fabric {fid} appears again (first at line {rows[fid].line})",
                    line=lineno,
                )
            )
            continue
        values: dict[str, float] = {}
        for col in value_cols:
            raw = record[col]
            if raw.lower() in _MISSING:
                continue
            try:
                v = float(raw)
            except ValueError:
                problems.append(
                    Problem(path, f"column {col!r}: {raw!r} is not a number", line=lineno)
                )
                continue
            if not math.isfinite(v):
                problems.append(
                    Problem(path, f"column {col!r}: {raw!r} is not finite", line=lineno)
                )
                continue
            values[col] = v
        cluster = None
        if cluster_column is not None:
            raw = record[cluster_column]
            if raw.lower() not in _MISSING:
                try:
                    c = float(raw)
                    if not c.is_integer() or c < 0:
                        raise ValueError
                    cluster = int(c)
                except ValueError:
                    problems.append(
                        Problem(
                            path,
                            f"column {cluster_column!r}: {raw!r} is not a cluster number "
                            "(0, 1, ...)",
                            line=lineno,
                        )
                    )
        split = None
        if "paper_split" in record:
            raw = record["paper_split"].lower()
            if raw in PAPER_SPLITS:
                split = raw
            elif raw not in _MISSING:
                problems.append(
                    Problem(
                        path,
                        f"column 'paper_split': {record['paper_split']!r} is not one of "
                        + ", ".join(PAPER_SPLITS),
                        line=lineno,
                    )
                )
        rows[fid] = LabelRow(fid, lineno, values, cluster, split)
    return LabelTable(path, value_cols, cluster_column, rows), problems
