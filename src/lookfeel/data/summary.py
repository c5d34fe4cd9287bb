"""The dataset summary a person reads: `format_summary` of a `Catalog` (``lookfeel data info``,
the demo).
"""

from __future__ import annotations

import csv
from collections.abc import Sequence
from pathlib import Path

from lookfeel.data.catalog import Catalog
from lookfeel.data.labels import PHYSICAL_LABELS
from lookfeel.data.problems import Problem
from lookfeel.modality import REPRINTS, Modality

__all__ = ["format_summary"]


def _ranges(ids: Sequence[int]) -> str:
    """``[1, 2, 3, 7]`` -> ``"1-3, 7"``."""
    out, start, prev = [], None, None
    for i in sorted(ids):
        if start is None:
            start = prev = i
        elif prev is not None and i == prev + 1:
            prev = i
        else:
            out.append(f"{start}-{prev}" if start != prev else f"{start}")
            start = prev = i
    if start is not None:
        out.append(f"{start}-{prev}" if start != prev else f"{start}")
    return ", ".join(out)


def _count(n: object, word: str) -> str:
    """``1 error``, ``0 errors``."""
    return f"{n} {word}" + ("" if n == 1 else "s")


def _relative(problem: Problem, root: Path) -> str:
    """A problem's path under ``root`` (``depth/F0001_1.tif``), else as it is."""
    path = problem.path
    if path is None:
        return str(root)
    return str(path.relative_to(root)) if path.is_relative_to(root) else str(path)


def _listed(names: Sequence[str], most: int = 6) -> str:
    """``a, b, c`` (at most ``most`` names, then ``and N more``)."""
    more = f" and {len(names) - most} more" if len(names) > most else ""
    return ", ".join(names[:most]) + more


def _unread_labels(catalog: Catalog) -> str | None:
    """Why labels.csv exists but none of it could be read (the scan's error about the whole
    file or its header, counted under problems), or None. A file whose columns were read is
    read, whatever else is wrong with its header (an unnamed column holding values): the
    ``labels`` and ``paper split`` rows both follow this one rule."""
    path = catalog.root / "labels.csv"
    if catalog.label_columns or catalog.text_columns:
        return None
    if not (path.exists() or path.is_symlink()):
        return None
    unread = [p for p in catalog.errors if p.path == path and p.line in (None, 1)]
    if unread:
        return unread[0].message.removeprefix("cannot read labels file: ")
    return None if path.is_file() else "not a file"


def _labels_line(catalog: Catalog, s: dict[str, object], named: bool) -> str:
    """The ``labels`` row: the label columns, or why there are none (no labels.csv, or one that
    cannot be read), then how many fabrics or objects are labelled."""
    cols = s["label_columns"]
    assert isinstance(cols, list)
    path = catalog.root / "labels.csv"
    if (why := _unread_labels(catalog)) is not None:
        return f"labels.csv exists but cannot be read: {why} (see `lookfeel data check`)"
    if cols:
        what = ", ".join(cols)
    elif path.exists():
        what = "no numeric label columns in labels.csv"
    else:
        what = "no labels.csv"
    if named:
        n = sum(bool(f.labels or f.text_labels) for f in catalog.fabrics)
        return f"{what}; {n} objects labelled"
    # Any numeric column counts (a dataset's own, such as bend_score); the paper's four keep
    # their name.
    n = sum(bool(f.labels) for f in catalog.fabrics)
    kind = "physical" if cols and set(cols) <= set(PHYSICAL_LABELS) else "numeric"
    return f"{what}; {n} fabrics with {kind} labels"


def _has_split_column(path: Path) -> bool:
    """Whether labels.csv's header (its first line) names a ``paper_split`` column."""
    try:
        with path.open(encoding="utf-8-sig", errors="replace", newline="") as f:
            header = next(csv.reader(f), [])
    except OSError:
        return False
    return "paper_split" in (h.strip() for h in header)


def _paper_split_line(catalog: Catalog, s: dict[str, object], named: bool) -> str:
    """The ``paper split`` row: how many fabrics each side of the paper split holds (labels.csv's
    ``paper_split`` column, or GelFabric's built-in list as ``data info`` fills it in), or
    ``none`` and why: then no fabric is held out as a test set, and a run validates on the
    fabrics its ``train.split`` holds out."""
    split = s["paper_split"]
    assert isinstance(split, dict)
    if split:
        return ", ".join(f"{k} {v}" for k, v in split.items())
    path = catalog.root / "labels.csv"
    if not (path.exists() or path.is_symlink()):
        why = "no labels.csv"
    elif _unread_labels(catalog) is not None:
        why = "labels.csv cannot be read"
    elif not _has_split_column(path):
        why = "labels.csv has no paper_split column"
    else:
        why = "labels.csv's paper_split column marks no " + ("object" if named else "fabric")
    things = "objects" if named else "fabrics"
    return (
        f"none ({why}): no {things[:-1]} is held out as a test set; a run validates on the "
        f"{things} its train.split holds out"
    )


def format_summary(catalog: Catalog, shown: Sequence[Problem] = ()) -> str:
    """A dataset summary a person reads (``lookfeel data info``).

    It reports what the scan saw (names and file headers, no pixels), so its problem count
    covers those only; the catalog's errors about the dataset as a whole (an empty dataset,
    one fabric, which ``lookfeel data info`` adds with `lookfeel.data.check.size_problems`)
    are printed in full, and so is each problem of ``shown`` (``data info``: the errors of
    ``data check`` for files the scan skipped that were meant as data), with its path.
    """
    s = catalog.summary()
    named = s["named_objects"]
    ids = f" (ids {_ranges(catalog.ids)})" if catalog.ids else ""
    rows: list[tuple[str, str]] = [("fabrics", f"{s['fabrics']}{ids}")]
    if named:
        listed = _listed([f.display_name for f in catalog.fabrics])
        rows[0] = ("objects", f"{s['fabrics']} named in labels.csv or videos/: {listed}")
    per = s["items_per_fabric"]
    assert isinstance(per, dict)
    items = s["items"]
    assert isinstance(items, dict)
    for m in Modality:
        if m.value not in items:
            rows.append((m.value, "none"))
            continue
        rng = per[m.value]
        unit = "presses" if m is Modality.TOUCH else "images"
        per_what = "object" if named else "fabric"
        line = f"{items[m.value]} {unit} ({rng['min']}-{rng['max']} per {per_what})"
        if m is Modality.TOUCH:
            kinds = s["touch_presses_by_kind"]
            assert isinstance(kinds, dict)
            line += ": " + ", ".join(f"{k} {v}" for k, v in kinds.items())
            parts = []
            if s["touch_frames"]:
                parts.append(f"{s['touch_frames']} frames")
            if s["touch_videos"]:
                parts.append(f"{s['touch_videos']} videos")
            line += "; " + ", ".join(parts or ["0 frames"])
        if m is Modality.COLOR and (catalog.root / REPRINTS).is_dir():
            n = sum(1 for p in (catalog.root / REPRINTS).iterdir() if not p.name.startswith("."))
            line += f"; {n} re-printed renders in {REPRINTS}/ (training views)"
        rows.append((m.value, line))
    rows.append(("labels", _labels_line(catalog, s, bool(named))))
    texts = s["text_columns"]
    assert isinstance(texts, list)
    if texts:
        rows.append(("text labels", ", ".join(texts)))
    classes = s["classes"]
    assert isinstance(classes, dict)
    for col, counts in classes.items():
        rows.append((f"  {col}", " ".join(f"{k}:{v}" for k, v in counts.items())))
    clusters = s["clusters"]
    assert isinstance(clusters, dict)
    if clusters:
        dist = " ".join(f"{k}:{v}" for k, v in clusters.items())
        rows.append(
            (
                "clusters",
                f"{len(clusters)} from {s['cluster_column'] or 'k-means'}, "
                f"{s['fabrics_with_cluster']} of {s['fabrics']} fabrics ({dist})",
            )
        )
    elif not named:
        rows.append(("clusters", "none (add a cluster8 column, or use k-means on labels)"))
    rows.append(("paper split", _paper_split_line(catalog, s, bool(named))))
    held = s["labelled_without_images"]
    assert isinstance(held, list)
    held_names = s.get("labelled_without_images_names")
    if held_names:  # labels.csv keyed by object: names, and videos are what they lack
        assert isinstance(held_names, list)
        rows.append(("no videos", f"{len(held)} labelled objects: {_listed(held_names)}"))
    elif held:
        rows.append(("no images", f"{len(held)} labelled fabrics: {_ranges(held)}"))
    if catalog.skipped:
        names = ", ".join(p.path.name for p in catalog.skipped[:5] if p.path is not None)
        more = f" and {len(catalog.skipped) - 5} more" if len(catalog.skipped) > 5 else ""
        rows.append(("skipped", f"{len(catalog.skipped)} not in the layout: {names}{more}"))
    # Problems of the dataset as a whole (empty, one fabric: `lookfeel.data.check.size_problems`)
    # are the ones a reader must see here; the rest concern single files, counted below.
    rows.extend(("error", p.message) for p in catalog.errors if p.path == catalog.root)
    rows.extend((p.severity, f"{_relative(p, catalog.root)}: {p.message}") for p in shown)
    # The scan reads names and headers only: say so, or "0 errors" reads as a clean dataset.
    rows.append(
        (
            "problems",
            f"{_count(s['errors'], 'error')}, {_count(s['warnings'], 'warning')} in names and "
            "headers "
            + (
                "(run `lookfeel data check`)"
                if s["errors"] or s["warnings"]
                else "(`lookfeel data check` decodes every file)"
            ),
        )
    )
    width = max(len(k) for k, _ in rows)
    return "\n".join([f"Dataset {catalog.root}"] + [f"  {k:<{width}}  {v}" for k, v in rows])
