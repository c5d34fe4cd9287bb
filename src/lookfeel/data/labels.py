"""Reading ``labels.csv``: one row per fabric or object, every column but the key optional.

The key is ``fabric_id`` (GelFabric: ``12`` or ``F0012``) or ``object`` (a name, as in a folder
of recordings: ``videos/<object>_<n>.mov``). Columns (README, *Data*): ``cluster8`` (or any
``cluster*``), ``thickness_mm``, ``density``, ``stiffness``, ``stretchiness``, ``paper_split``
(``train``, ``test``, ``excluded``), and any further column. A column whose cells are mostly
numbers is numeric (a regression target; a bad cell is reported); a column whose cells are
mostly words (``material``: ``fabric``, ``metal`` ...) is a text column, usable as classes.
A numeric column whose every value is a whole number from 0 to `MAX_RANK` is a column of ranks
(``hardness``: 0, 1, 2): numbers and classes both (`is_rank_column`, the one rule that ``lookfeel
data info``, ``data check``, training's class heads and so ``predict`` follow). One odd value
(``1.5`` among 0, 1, 2) makes the column numbers only, and the reader warns naming its cell.
Every known cell is also kept as text (a rank's class is its text, ``"2"``).

A number is a cell a spreadsheet writes as one (``0.7``, ``-3``, ``1e-3``): ``1_000``, which
Python reads, is not. A cell that is a number but for how it is written (``0,7`` with a
decimal comma, ``0.7 mm`` with a unit, ``1 000`` with grouped digits) counts as a number when
telling numeric columns from text ones, so a column of them is numeric, not classes, and is
reported: one error per column naming a cell and what to write (`_miswritten`).

Empty cells mean unknown, and so do ``NA``, ``N/A``, ``nan``, ``null`` and ``none`` (any case),
as pandas reads them. In a text column ``none`` may be a class (a coating of "none"): it is
still unknown, and the reader warns naming the column and how many rows, so that it is written
as another word or left empty (`_missing_words`). Names and cells are read in Unicode's
composed form (NFC), as object names are taken from file names: an accented letter typed on
macOS (``crème``) is one name however it was saved.
"""

from __future__ import annotations

import csv
import math
import re
import unicodedata
from collections.abc import Iterable
from dataclasses import dataclass, field, replace
from pathlib import Path

from lookfeel.data.problems import Problem

__all__ = [
    "KEY_COLUMNS",
    "MAX_RANK",
    "PAPER_SPLITS",
    "PHYSICAL_LABELS",
    "LabelRow",
    "LabelTable",
    "class_of",
    "is_rank",
    "is_rank_column",
    "read_labels",
]

PHYSICAL_LABELS = ("thickness_mm", "density", "stiffness", "stretchiness")
"""The paper's four human/physical labels (section 3), in its order."""

KEY_COLUMNS = ("fabric_id", "object")
"""The key column of labels.csv, by preference: fabric ids, or object names."""

PAPER_SPLITS = ("train", "test", "excluded")
_MISSING = {"", "na", "n/a", "nan", "none", "null"}
_WORD_MISSING = {"none"}
"""Spellings of unknown (`_MISSING`) that are also a plain word a class may be named: in a text
column each is still unknown, with a warning (`_missing_words`)."""
_ID = re.compile(r"^[Ff]?0*(\d+)$")

MAX_RANK = 10
"""The largest rank: a numeric column whose values are all whole numbers from 0 to this is a
column of ranks (``hardness`` 0/1/2), whose values are classes as well as numbers."""


def is_rank(value: float) -> bool:
    """Whether a label value is a rank: a whole number from 0 to `MAX_RANK`."""
    return float(value).is_integer() and 0 <= value <= MAX_RANK


def is_rank_column(values: Iterable[float]) -> bool:
    """Whether a numeric column with these known values is a column of ranks: it has a value,
    and every one is a rank (`is_rank`). Its values are then classes too: ``lookfeel data info``
    counts them, and a class head (``model.class_heads``) may learn them; any other numeric
    column is numbers only (a regression target), in every command."""
    values = list(values)
    return bool(values) and all(is_rank(v) for v in values)


@dataclass(frozen=True)
class LabelRow:
    """One fabric's row: known values only (unknown cells are absent).

    ``fabric_id`` is 0 in a table keyed by ``object`` until `LabelTable.with_ids` numbers the
    names; ``name`` is the object's name there (None in a ``fabric_id`` table).
    """

    fabric_id: int
    line: int
    values: dict[str, float] = field(default_factory=dict)
    cluster: int | None = None
    paper_split: str | None = None
    name: str | None = None
    text: dict[str, str] = field(default_factory=dict)
    """Every known cell of every label column as written (numeric ones too)."""


@dataclass(frozen=True)
class LabelTable:
    """The parsed file: its label columns, the cluster column used, and rows by fabric id.

    A table keyed by ``object`` holds its rows in ``named`` (by name) and none in ``rows``
    until `with_ids` gives each name its id.
    """

    path: Path
    columns: tuple[str, ...]
    cluster_column: str | None
    rows: dict[int, LabelRow]
    text_columns: tuple[str, ...] = ()
    """Columns of words rather than numbers (e.g. ``material``): classes, never regressed."""
    key: str = "fabric_id"
    named: dict[str, LabelRow] = field(default_factory=dict)
    rank_columns: tuple[str, ...] = ()
    """The numeric columns of ranks (`is_rank_column` over every row): classes as well."""
    keyed: bool = True
    """Whether the file's keys were read. False when it cannot be read, is empty, or its header
    names no key column: it then says nothing of which fabrics or objects it holds, so no
    fabric is reported as missing from it (its one error says why)."""

    def with_ids(self, ids: dict[str, int]) -> LabelTable:
        """The table with each named row under its id (``ids``: object name -> fabric id)."""
        rows = {ids[n]: replace(r, fabric_id=ids[n]) for n, r in self.named.items() if n in ids}
        return replace(self, rows=rows)


def class_of(values: dict[str, float], text: dict[str, str], column: str) -> str | None:
    """A fabric's class in ``column`` as text: the number written plainly for a numeric column
    (``"2"``, not ``"2.0"``), the cell itself for a text column; None when unknown."""
    if column in values:
        return f"{values[column]:g}"
    return text.get(column)


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
    except OSError as e:
        why = f"cannot read labels file: {e.strerror or e}"
        return LabelTable(path, (), None, {}, keyed=False), [Problem(path, why)]
    except UnicodeDecodeError as e:
        if (utf16 := _utf16_table(path)) is not None:
            return utf16
        why = f"not a text CSV in UTF-8 (byte {e.start}: {e.reason}); save it as UTF-8"
        return LabelTable(path, (), None, {}, keyed=False), [Problem(path, why)]
    # One spelling of each name: macOS and some editors write an accented letter decomposed
    # ("e" and a combining accent), which looks the same as the composed one but compares
    # unequal, to the object names taken from file names (`lookfeel.data.layout`) too.
    text = unicodedata.normalize("NFC", text)
    reader = csv.reader(text.splitlines())
    header = next(reader, None)
    if header is None:
        return LabelTable(path, (), None, {}, keyed=False), [Problem(path, "labels file is empty")]
    header = [h.strip() for h in header]
    key = next((k for k in KEY_COLUMNS if k in header), None)
    if key is None and (other := _other_separator(text)) is not None:
        sep, key = other
        why = (
            f"separated by {_SEPARATORS[sep]}, not commas: lookfeel reads comma-separated "
            "files; save it as CSV with commas"
        )
        return _keys_only(path, text, sep, key, why)
    if key is None:
        near = next((h for h in header if h.casefold() in KEY_COLUMNS), None)
        hint = f" (names are case-sensitive: write {near.casefold()!r})" if near else ""
        why = (
            "no 'fabric_id' or 'object' column in the header (first line); found: "
            + ", ".join(header)
            + hint
        )
        return LabelTable(path, (), None, {}, keyed=False), [Problem(path, why, line=1)]
    dupes = sorted({h for h in header if h and header.count(h) > 1})
    if dupes:
        problems.append(Problem(path, f"duplicate column(s) {', '.join(dupes)}", line=1))
    records = list(enumerate(reader, start=2))
    header, records, unnamed = _unnamed_columns(path, header, records)
    problems.extend(unnamed)
    cluster_cols = [h for h in header if h.lower().startswith("cluster")]
    cluster_column = "cluster8" if "cluster8" in cluster_cols else next(iter(cluster_cols), None)
    value_cols = tuple(
        h
        for h in header
        if h and h not in KEY_COLUMNS and h != "paper_split" and h not in cluster_cols
    )
    text_cols = _text_columns(header, value_cols, [cells for _, cells in records])
    rows: dict[int, LabelRow] = {}
    named: dict[str, LabelRow] = {}
    # (column, way) -> (index in problems of its one error, (line, cell, how) of each cell): the
    # cells of a column that are numbers but for how they are written (`_miswritten`)
    miswritten: dict[tuple[str, str], tuple[int, list[tuple[int, str, _Miswritten]]]] = {}
    for lineno, cells in records:
        if not cells or all(not c.strip() for c in cells):
            continue
        if len(cells) != len(header):
            problems.append(_width_problem(path, cells, len(header), lineno))
            continue
        record = {h: c.strip() for h, c in zip(header, cells, strict=True)}
        name: str | None = None
        fid: int | None = 0
        if key == "object":
            name = record["object"]
            if not name or name.lower() in _MISSING:
                problems.append(Problem(path, "empty 'object' name", line=lineno))
                continue
            if name in named:
                problems.append(
                    Problem(
                        path,
                        f"object {name!r} appears again (first at line {named[name].line})",
                        line=lineno,
                    )
                )
                continue
        else:
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
        if name is None and fid in rows:
            problems.append(
                Problem(
                    path,
                    f"fabric {fid} appears again (first at line {rows[fid].line})",
                    line=lineno,
                )
            )
            continue
        values: dict[str, float] = {}
        cells_text: dict[str, str] = {}
        for col in value_cols:
            raw = record[col]
            if raw.lower() in _MISSING:
                continue
            cells_text[col] = raw
            if col in text_cols:
                continue
            v = _number(raw)
            if v is None and (mis := _miswritten(raw)) is not None:
                how = (col, mis.way)
                if how not in miswritten:  # one error per column and way, here (see below)
                    miswritten[how] = (len(problems), [])
                    problems.append(Problem(path, "", line=lineno))
                miswritten[how][1].append((lineno, raw, mis))
                continue
            if v is None:
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
                    c = _number(raw)
                    if c is None or not c.is_integer() or c < 0:
                        raise ValueError
                    cluster = int(c)
                except (ValueError, OverflowError):
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
        row = LabelRow(fid or 0, lineno, values, cluster, split, name, cells_text)
        if name is not None:
            named[name] = row
        else:
            rows[row.fabric_id] = row
    for (col, _), (at, written) in miswritten.items():
        problems[at] = _miswritten_problem(path, col, written)
    numeric = tuple(c for c in value_cols if c not in text_cols)
    every = [*rows.values(), *named.values()]
    ranks = tuple(c for c in numeric if is_rank_column(r.values[c] for r in every if c in r.values))
    # The paper's physical labels are measurements and ratings, not ranks: GelFabric's
    # stretchiness is 0, 0.5 or 1, and a world of 20 fabrics may well hold one 0.5.
    maybe = [c for c in numeric if c not in ranks and c not in PHYSICAL_LABELS]
    problems.extend(_broken_ranks(path, maybe, every))
    problems.extend(_case_variants(path, text_cols, every))
    problems.extend(_missing_words(path, header, text_cols, records))
    table = LabelTable(path, numeric, cluster_column, rows, text_cols, key, named, ranks)
    return table, problems


def _unnamed_columns(
    path: Path, header: list[str], records: list[tuple[int, list[str]]]
) -> tuple[list[str], list[tuple[int, list[str]]], list[Problem]]:
    """The header and rows without the columns that have no name and no value in any row (a
    spreadsheet saves its empty last column as a comma ending every line), with a warning
    naming them; an unnamed column that holds a value is an error (its values are not read).

    A row that lacks the cells of such columns at its end (``egg,2`` under ``object,hardness,``)
    is taken as if it had them empty; a row of another length is an error here, against the
    header as written. Columns are numbered from 1 as a spreadsheet counts them.

    Returns:
        (header, rows by line, problems), the rows' cells in the returned header's columns (a
        blank row as no cells).
    """
    unnamed = [i for i, h in enumerate(header) if not h]
    if not unnamed:
        return header, records, []

    def values(i: int) -> list[tuple[int, str]]:  # in the rows as long as the header
        return [(n, c[i].strip()) for n, c in records if len(c) == len(header) and c[i].strip()]

    empty = [i for i in unnamed if not values(i)]
    last = len(header) - 1
    problems = []
    for i in unnamed:
        if i in empty:
            continue
        line, cell = values(i)[0]
        trailing = " (a trailing comma?)" if i == last else ""
        problems.append(
            Problem(
                path,
                f"column {i + 1} has no name in the header{trailing} but holds values ({cell!r} "
                f"at line {line}): name it, or delete the column",
                line=1,
            )
        )
    if empty:
        cols = ", ".join(str(i + 1) for i in empty)
        which = f"column {cols} has" if len(empty) == 1 else f"columns {cols} have"
        trailing = (
            " (the header ends with a comma, as a spreadsheet saves an empty last column)"
            if last in empty
            else ""
        )
        problems.append(
            Problem(
                path,
                f"{which} no name and no value in any row{trailing}: ignored",
                "warning",
                line=1,
            )
        )
    # The empty columns at the end, which a row may lack altogether.
    tail = len(header)
    while tail > 0 and tail - 1 in empty:
        tail -= 1
    keep = [i for i in range(len(header)) if i not in empty]
    out: list[tuple[int, list[str]]] = []
    for n, cells in records:
        if not any(c.strip() for c in cells):
            out.append((n, []))  # blank: skipped
        elif tail <= len(cells) <= len(header):
            cells = cells + [""] * (len(header) - len(cells))
            out.append((n, [cells[i] for i in keep]))
        else:
            problems.append(_width_problem(path, cells, len(header), n))
    return [header[i] for i in keep], out, problems


def _width_problem(path: Path, cells: list[str], width: int, line: int) -> Problem:
    """A row of ``cells`` under a header of ``width`` cells; a row longer by cells that are
    all empty most likely ends with a comma too many."""
    extra = cells[width:]
    hint = " (a trailing comma?)" if extra and not any(c.strip() for c in extra) else ""
    return Problem(path, f"{len(cells)} cells but the header has {width}{hint}", line=line)


_SEPARATORS = {";": "semicolons (;)", "\t": "tabs"}
_DECIMAL_COMMA = re.compile(r"^-?\d+,\d+$")


def _other_separator(text: str, seps: Iterable[str] = _SEPARATORS) -> tuple[str, str] | None:
    """``(separator, key column)`` when the header, split by a semicolon or a tab instead of
    a comma, has a key column (`KEY_COLUMNS`): a file saved by a spreadsheet set to another
    separator (a European Excel writes ``;``, its "Unicode text" tabs). None otherwise."""
    first = text.splitlines()[0] if text else ""
    for sep in seps:
        cells = [c.strip() for c in next(csv.reader([first], delimiter=sep), [])]
        key = next((k for k in KEY_COLUMNS if k in cells), None)
        if key is not None:
            return sep, key
    return None


def _utf16_table(path: Path) -> tuple[LabelTable, list[Problem]] | None:
    """A labels.csv saved as UTF-16 (it begins with a UTF-16 byte-order mark: Excel's "Unicode
    text"), read for its keys alone with an error saying how to save it; None when the file
    is not UTF-16 text with a key column."""
    try:
        data = path.read_bytes()
        if not data.startswith((b"\xff\xfe", b"\xfe\xff")):
            return None
        text = data.decode("utf-16")
    except (OSError, UnicodeDecodeError):
        return None
    found = _other_separator(text, (",", *_SEPARATORS))
    if found is None:
        return None
    sep, key = found
    how = "" if sep == "," else f", separated by {_SEPARATORS[sep]}"
    why = (
        f'saved as UTF-16 text{how} (a spreadsheet\'s "Unicode text"): lookfeel reads UTF-8 '
        'files separated by commas; save it as "CSV UTF-8 (comma delimited)"'
    )
    return _keys_only(path, text, sep, key, why)


def _keys_only(
    path: Path, text: str, sep: str, key: str, why: str
) -> tuple[LabelTable, list[Problem]]:
    """A labels.csv that cannot be read as it was saved (``why``: one error, at line 1), read
    with ``sep`` for its keys alone (no label is read), so that the scan does not also report
    every fabric as missing from it."""
    records = list(csv.reader(unicodedata.normalize("NFC", text).splitlines(), delimiter=sep))
    header = [h.strip() for h in records[0]]
    i = header.index(key)
    rows: dict[int, LabelRow] = {}
    named: dict[str, LabelRow] = {}
    for lineno, r in enumerate(records[1:], start=2):
        raw = r[i].strip() if i < len(r) else ""
        if key == "object" and raw and raw.lower() not in _MISSING:
            named.setdefault(raw, LabelRow(0, lineno, name=raw))
        elif key == "fabric_id" and (fid := parse_fabric_id(raw)) is not None:
            rows.setdefault(fid, LabelRow(fid, lineno))
    cells = (c.strip() for r in records[1:] for c in r)
    decimal = next((c for c in cells if _DECIMAL_COMMA.match(c)), None)
    if decimal is not None:
        why += f" and a full stop as the decimal mark (it has {decimal!r})"
    table = LabelTable(path, (), None, rows, key=key, named=named)
    return table, [Problem(path, f"{why}; no label was read", line=1)]


def _case_variants(path: Path, columns: Iterable[str], rows: list[LabelRow]) -> list[Problem]:
    """A warning per text column (classes) holding spellings that differ only in case
    or spacing (``Cotton`` and ``cotton``): each spelling is its own class."""
    out = []
    for col in columns:
        seen: dict[str, dict[str, LabelRow]] = {}
        for r in sorted(rows, key=lambda r: r.line):
            if col in r.text:
                key = " ".join(r.text[col].split()).casefold()
                seen.setdefault(key, {}).setdefault(r.text[col], r)
        for spellings in seen.values():
            if len(spellings) < 2:
                continue
            named = [f"{s!r} ({_who(r)}, line {r.line})" for s, r in spellings.items()]
            out.append(
                Problem(
                    path,
                    f"column {col!r}: {' and '.join(named)} differ only in case or spacing, so "
                    f"they are {len(spellings)} classes; write them alike if they are one",
                    "warning",
                    next(iter(spellings.values())).line,
                )
            )
    return out


def _who(r: LabelRow) -> str:
    return f"object {r.name!r}" if r.name is not None else f"fabric {r.fabric_id}"


def _broken_ranks(path: Path, columns: Iterable[str], rows: list[LabelRow]) -> list[Problem]:
    """A warning for each cell that alone keeps a column from being ranks: the column's other
    values are ranks (two or more of them, 0 to `MAX_RANK`) and only a few are not (one, or
    one in twenty: a column of 0 and 1 with 15 of 100 at 0.5 is numbers)."""
    out = []
    for col in columns:
        known = [r for r in rows if col in r.values]
        odd = [r for r in known if not is_rank(r.values[col])]
        ranks = sorted({r.values[col] for r in known} - {r.values[col] for r in odd})
        if len(ranks) < 2 or len(odd) > max(1, len(known) // 20):
            continue
        for r in odd:
            who = f"object {r.name!r}" if r.name is not None else f"fabric {r.fabric_id}"
            out.append(
                Problem(
                    path,
                    f"column {col!r}: {who} has {r.text[col]!r}, where the column's other "
                    f"values are whole numbers 0-{MAX_RANK} ({', '.join(f'{v:g}' for v in ranks)}"
                    "): the whole column is read as numbers, not ranks (no classes in `lookfeel "
                    "data info`, no class head); correct the cell if it is a rank",
                    "warning",
                    r.line,
                )
            )
    return out


def _number(text: str) -> float | None:
    """The number a cell holds as a spreadsheet writes one (``0.7``, ``-3``, ``1e-3``, ``inf``),
    else None. Python's float also reads ``1_000`` (digits grouped by underscores), which no
    spreadsheet writes: such a cell is not a number here (`_miswritten` says what to write)."""
    if "_" in text:
        return None
    try:
        return float(text)
    except ValueError:
        return None


_UNITS = (
    "mm|cm|dm|m|km|µm|μm|um|nm|in|inch|inches|ft|g|kg|mg|lb|lbs|oz|gsm|g/m2|g/m²|g/cm3|g/cm³"
    "|kg/m2|kg/m²|kg/m3|kg/m³|n|kn|mn|n/m|n/mm|n/cm|pa|kpa|mpa|gpa|psi|%|°|deg|s|ms|hz|khz"
)
"""Units a measurement may be written with (matched in any case): ``0.7 mm``, ``120gsm``."""
_WITH_UNIT = re.compile(rf"^(?P<number>[+-]?[\d.,]*\d)\s*(?P<unit>{_UNITS})\.?$", re.IGNORECASE)
_COMMA_DECIMAL = re.compile(r"^[+-]?\d*,\d+$")
_THOUSANDS = re.compile(r"^[+-]?[1-9]\d{0,2},\d{3}$")
_GROUP_MARKS = "_ \u00a0\u202f'’"
_GROUPED = re.compile(rf"^[+-]?\d{{1,3}}(?:[{_GROUP_MARKS}]\d{{3}})+(?:\.\d+)?$")


@dataclass(frozen=True)
class _Miswritten:
    """A cell that is a number but for how it is written (`_miswritten`)."""

    number: str
    """What to write instead (``0.7``; ``1.500 or 1500`` where a comma may be either mark)."""
    why: str
    """What is wrong, in words (``a comma as the decimal mark``)."""
    way: str
    """``comma``, ``grouped`` or ``unit``: the cells of a column written one way are one error."""
    unit: str = ""


def _miswritten(cell: str) -> _Miswritten | None:
    """How a cell that is a number but for how it is written should be written, else None:
    ``0,7`` (a comma as the decimal mark) -> ``0.7``; ``1_000`` or ``1 000`` (grouped digits)
    -> ``1000``; ``0.7 mm`` or ``0,7mm`` (a unit, `_UNITS`) -> ``0.7``. A comma before three
    digits (``1,500``) is a decimal mark or a thousands separator: both readings are given."""
    if _number(cell) is not None:
        return None
    if _COMMA_DECIMAL.match(cell):
        number = cell.replace(",", ".")
        if _THOUSANDS.match(cell):
            number += " or " + cell.replace(",", "")
            return _Miswritten(
                number, "a comma as the decimal mark or thousands separator", "comma"
            )
        return _Miswritten(number, "a comma as the decimal mark", "comma")
    if _GROUPED.match(cell):
        mark = next(c for c in cell if c in _GROUP_MARKS)
        by = "spaces" if mark.isspace() else repr(mark)
        digits = "".join(c for c in cell if c not in _GROUP_MARKS)
        return _Miswritten(digits, f"its digits grouped by {by}", "grouped")
    m = _WITH_UNIT.match(cell)
    if m is None:
        return None
    number = m["number"]
    if _number(number) is None:
        if not _COMMA_DECIMAL.match(number):
            return None
        number = number.replace(",", ".")
    return _Miswritten(number, f"a unit, {m['unit']}", "unit", m["unit"])


def _miswritten_problem(path: Path, col: str, cells: list[tuple[int, str, _Miswritten]]) -> Problem:
    """The one error of the cells of a column that are numbers written one way (`_miswritten`):
    the first cell, what to write instead, and the lines of the rest. The cells are read as
    unknown."""
    line, raw, first = cells[0]
    fix = f"write {first.number}"
    if first.way == "unit":
        if col.casefold().endswith(first.unit.casefold()):
            fix += " (the column's name gives the unit)"
        elif first.unit.isalnum():
            fix += f" and give the unit in the column's name ({col}_{first.unit})"
        else:
            fix += " and give the unit in the column's name"
    elif first.way == "comma":
        fix += ", a full stop as the decimal mark"
    else:
        fix += ", its digits together"
    rest = ""
    if len(cells) > 1:
        lines = ", ".join(str(c[0]) for c in cells[1:4])
        more = f" and {len(cells) - 4} more" if len(cells) > 4 else ""
        n = len(cells) - 1
        rest = f"; {n} more of its cells {'are' if n > 1 else 'is'} written so (line {lines}{more})"
    them = "they are" if len(cells) > 1 else "it is"
    return Problem(
        path,
        f"column {col!r}: {raw!r} is not a number ({first.why}){rest}: {fix}; until then {them} "
        "read as unknown",
        line=line,
    )


def _missing_words(
    path: Path, header: list[str], columns: Iterable[str], records: list[tuple[int, list[str]]]
) -> list[Problem]:
    """A warning per text column and spelling of `_WORD_MISSING` (``none``) it holds: read as
    unknown, as every spelling of `_MISSING` is, although it may name a class."""
    out = []
    for col in columns:
        i = header.index(col)
        found: dict[str, list[int]] = {}
        spelt: dict[str, str] = {}
        for n, cells in records:
            cell = cells[i].strip() if len(cells) == len(header) else ""
            if cell.lower() in _WORD_MISSING:
                found.setdefault(cell.lower(), []).append(n)
                spelt.setdefault(cell.lower(), cell)
        for low, lines in found.items():
            word = spelt[low]
            rows = f"{len(lines)} row{'s' if len(lines) > 1 else ''}"
            out.append(
                Problem(
                    path,
                    f"column {col!r}: {word!r} ({rows}) is read as unknown, as an empty cell, NA "
                    f"and N/A are; if it is a class, write it as another word (such as "
                    f"'no_{col}'), else leave its cells empty",
                    "warning",
                    lines[0],
                )
            )
    return out


def _text_columns(
    header: list[str], value_cols: tuple[str, ...], rows: list[list[str]]
) -> tuple[str, ...]:
    """Columns most of whose known cells are not numbers, not even numbers miswritten (so one
    typo in a numeric column is reported as a bad number, not taken for a word, and a column
    of ``0,7`` is reported as numbers written with a comma, not taken for classes)."""
    out = []
    for col in value_cols:
        i = header.index(col)
        cells = [r[i].strip() for r in rows if len(r) == len(header)]
        known = [c for c in cells if c.lower() not in _MISSING]
        # A number written with a decimal comma or a unit counts as a number, so a column of
        # them is numeric (and its cells reported), not a column of classes.
        words = sum(_number(c) is None and _miswritten(c) is None for c in known)
        if known and words * 2 > len(known):
            out.append(col)
    return tuple(out)
