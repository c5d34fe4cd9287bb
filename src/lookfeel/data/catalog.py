"""The dataset as plain records: fabrics, their labels and clusters, and per modality its items.

A `Catalog` is what `scan` builds from files on disk and what splits, samplers and datasets
take. It is immutable and cheap: it holds paths and labels, never pixels.
"""

from __future__ import annotations

import functools
import hashlib
import json
import math
import os
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path, PurePath

from lookfeel.data.files import VIDEO_SUFFIXES
from lookfeel.data.labels import PHYSICAL_LABELS, class_of
from lookfeel.data.problems import DatasetError, Problem, lacking_lines, leave_out
from lookfeel.modality import Modality, PressKind
from lookfeel.shell import set_flag

__all__ = ["PHYSICAL_LABELS", "Catalog", "Fabric", "Item"]


@dataclass(frozen=True)
class Item:
    """One sample of one fabric in one modality.

    A depth or colour item is one image (``frames`` has one path). A touch item is one press:
    its frames in order of the integer frame number in their names.

    Attributes:
        modality: which sensor made it.
        fabric_id: the fabric's integer id (``F<id>_`` in the file name).
        frames: the image file(s), ordered.
        kind: the press kind for touch items, ``None`` otherwise (and for a touch video whose
            kind is not stated: an object's press in ``videos/``).
        press: the press id for touch items (``<press>`` in the name), ``None`` otherwise.
    """

    modality: Modality
    fabric_id: int
    frames: tuple[Path, ...]
    kind: PressKind | None = None
    press: str | None = None

    @property
    def path(self) -> Path:
        """The first frame: the item's file for depth and colour, a press's first frame."""
        return self.frames[0]

    def frame(self, index: int) -> Path:
        """Frame ``index`` of the press (negative counts from the end), clamped to exist."""
        n = len(self.frames)
        i = index if index >= 0 else n + index
        return self.frames[min(max(i, 0), n - 1)]


@dataclass(frozen=True)
class Fabric:
    """One fabric: its labels, cluster and items per modality.

    Attributes:
        id: the fabric id.
        labels: known label values by column (``thickness_mm``, ``density`` ...); unknown
            (empty) cells are absent, never NaN.
        cluster: the fabric's cluster (labels.csv ``cluster8`` or another ``cluster*`` column),
            or ``None`` when unknown.
        paper_split: ``"train"``, ``"test"`` or ``"excluded"`` when labels.csv says, else None.
        items: per modality, the fabric's items in file-name order.
        name: the object's name when the data names objects (``videos/<name>_<n>.mov``).
        text_labels: every known label cell as written, text columns (``material``) included.
    """

    id: int
    labels: Mapping[str, float] = field(default_factory=dict)
    cluster: int | None = None
    paper_split: str | None = None
    items: Mapping[Modality, tuple[Item, ...]] = field(default_factory=dict)
    name: str | None = None
    text_labels: Mapping[str, str] = field(default_factory=dict)

    @property
    def display_name(self) -> str:
        """``sponge`` for a named object, ``F0012`` for a numbered fabric."""
        return self.name if self.name is not None else f"F{self.id:04d}"

    def class_of(self, column: str) -> str | None:
        """The fabric's class in a label column as text (``"2"``, ``"metal"``), None if unknown."""
        return class_of(dict(self.labels), dict(self.text_labels), column)

    def items_of(self, modality: Modality, kinds: Iterable[PressKind] | None = None) -> list[Item]:
        """Items of one modality; for touch, only presses of ``kinds`` when given (a press of
        no stated kind, such as an object's video in ``videos/``, is of every kind)."""
        items = list(self.items.get(modality, ()))
        if kinds is not None and modality is Modality.TOUCH:
            wanted = set(kinds)
            items = [it for it in items if it.kind is None or it.kind in wanted]
        return items

    @property
    def has_physical_labels(self) -> bool:
        """Whether at least one of the paper's four physical labels is known."""
        return any(k in self.labels for k in PHYSICAL_LABELS)


@dataclass(frozen=True)
class Catalog:
    """A whole dataset as records, as built by `lookfeel.data.scan`.

    Attributes:
        root: the folder scanned.
        fabrics: every fabric that has at least one usable item, by increasing id.
        label_columns: the numeric label columns of labels.csv beyond the key (in file order),
            other than ``paper_split`` and cluster columns.
        text_columns: the label columns of words (``material``), usable as classes.
        rank_columns: the numeric label columns of ranks (``hardness`` 0/1/2: every value in
            labels.csv a whole number 0-10, `lookfeel.data.labels.is_rank_column`), whose
            values are classes too.
        cluster_column: the labels.csv column the clusters came from, if any.
        labelled_only: fabric ids that are in labels.csv but have no image.
        problems: everything the scan found wrong or worth a warning.
        skipped: files and folders under ``root`` that were not read, and why.
    """

    root: Path
    fabrics: tuple[Fabric, ...]
    label_columns: tuple[str, ...] = ()
    text_columns: tuple[str, ...] = ()
    rank_columns: tuple[str, ...] = ()
    cluster_column: str | None = None
    labelled_only: Mapping[int, Fabric] = field(default_factory=dict)
    problems: tuple[Problem, ...] = ()
    skipped: tuple[Problem, ...] = ()

    # ---- lookups -----------------------------------------------------------------------------

    @property
    def ids(self) -> list[int]:
        """Fabric ids, increasing."""
        return [f.id for f in self.fabrics]

    def fabric(self, fabric_id: int) -> Fabric:
        """The fabric with this id.

        Raises:
            KeyError: naming the id when it is not in the catalog.
        """
        for f in self.fabrics:
            if f.id == fabric_id:
                return f
        raise KeyError(f"fabric {fabric_id} is not in the dataset at {self.root}")

    @property
    def modalities(self) -> tuple[Modality, ...]:
        """Modalities that have at least one item, in enum order."""
        present = {m for f in self.fabrics for m, items in f.items.items() if items}
        return tuple(m for m in Modality if m in present)

    def items(self, modality: Modality, kinds: Iterable[PressKind] | None = None) -> list[Item]:
        """All items of a modality (touch: of ``kinds`` when given), by fabric then name."""
        kinds = None if kinds is None else tuple(kinds)
        return [it for f in self.fabrics for it in f.items_of(modality, kinds)]

    def most_presses(self, kinds: Iterable[PressKind] | None = None) -> int:
        """The most touch presses (of ``kinds`` when given) any one fabric has: how many a
        query can pool (``data.presses``, ``--presses``); 0 without touch."""
        kinds = None if kinds is None else tuple(kinds)
        return max((len(f.items_of(Modality.TOUCH, kinds)) for f in self.fabrics), default=0)

    @property
    def errors(self) -> tuple[Problem, ...]:
        return tuple(p for p in self.problems if p.severity == "error")

    @property
    def warnings(self) -> tuple[Problem, ...]:
        return tuple(p for p in self.problems if p.severity == "warning")

    @property
    def class_columns(self) -> tuple[str, ...]:
        """The label columns whose values are classes: the text columns, then the ranks."""
        return (*self.text_columns, *self.rank_columns)

    def class_counts(self, columns: Iterable[str] | None = None) -> dict[str, dict[str, int]]:
        """Per column of classes (`class_columns` by default) in which some class is shared
        (a column of all-different words is descriptions): fabrics per class, in sorted class
        order."""
        if columns is None:
            columns = self.class_columns
        out: dict[str, dict[str, int]] = {}
        for c in columns:
            counts: dict[str, int] = {}
            for f in self.fabrics:
                k = f.class_of(c)
                if k is not None:
                    counts[k] = counts.get(k, 0) + 1
            if counts and max(counts.values()) >= 2:  # all-unique cells (descriptions) are not
                out[c] = dict(sorted(counts.items()))
        return out

    def clusters(self) -> dict[int, int | None]:
        """Fabric id -> cluster (``None`` where unknown)."""
        return {f.id: f.cluster for f in self.fabrics}

    def label_matrix(self, columns: Iterable[str] = PHYSICAL_LABELS) -> dict[int, list[float]]:
        """Fabric id -> label values in ``columns`` order, NaN where unknown."""
        cols = list(columns)
        return {f.id: [f.labels.get(c, math.nan) for c in cols] for f in self.fabrics}

    # ---- derived catalogs --------------------------------------------------------------------

    def subset(self, fabric_ids: Iterable[int]) -> Catalog:
        """The catalog restricted to these fabrics (a split's train or test side).

        Raises:
            DatasetError: naming the ids that are not in the catalog.
        """
        wanted = list(dict.fromkeys(int(i) for i in fabric_ids))
        have = {f.id: f for f in self.fabrics}
        missing = [i for i in wanted if i not in have]
        if missing:
            raise DatasetError(
                f"fabric id(s) {', '.join(map(str, missing))} are not in the dataset",
                self.root,
            )
        keep = set(wanted)
        return replace(self, fabrics=tuple(f for f in self.fabrics if f.id in keep))

    def with_items(self, keep: Iterable[Item]) -> Catalog:
        """The catalog with only the given items (fabrics left with none are dropped).

        Used by item-level splits such as the paper's "seen fabrics" split (Table 4).
        """
        keep_set = set(keep)
        fabrics = []
        for f in self.fabrics:
            items = {m: tuple(it for it in its if it in keep_set) for m, its in f.items.items()}
            items = {m: its for m, its in items.items() if its}
            if items:
                fabrics.append(replace(f, items=items))
        return replace(self, fabrics=tuple(fabrics))

    def with_clusters(self, clusters: Mapping[int, int | None]) -> Catalog:
        """The catalog with clusters replaced (e.g. from `kmeans_clusters`)."""
        fabrics = tuple(replace(f, cluster=clusters.get(f.id, f.cluster)) for f in self.fabrics)
        return replace(self, fabrics=fabrics, cluster_column=None)

    def require(
        self, modalities: Iterable[Modality], kinds: Iterable[PressKind] | None = None
    ) -> None:
        """Check that every fabric has an item of each modality a run needs.

        Raises:
            DatasetError: listing what each modality lacks (`lacking`).
        """
        problems = self.lacking(modalities, kinds)
        if problems:
            raise DatasetError(problems, self.root)

    def lacking(
        self, modalities: Iterable[Modality], kinds: Iterable[PressKind] | None = None
    ) -> list[Problem]:
        """What `require` refuses: per modality (touch: of ``kinds`` when given), the fabrics
        that have no item of it (`lookfeel.data.problems.lacking_lines`: a few get a line each;
        more, or all, one line that counts them and names the first few). Where the fabrics
        lacking a touch press of ``kinds`` have presses of other kinds, the line gives the
        ``--set data.touch_kinds=[...]`` that trains on them (every kind the data holds)."""
        kinds = None if kinds is None else tuple(kinds)
        problems: list[Problem] = []
        for m in modalities:
            lacking = [f for f in self.fabrics if not f.items_of(m, kinds)]
            if lacking:
                problems += self._lacking(m, kinds, lacking)
        return problems

    def _lacking(
        self, m: Modality, kinds: tuple[PressKind, ...] | None, lacking: list[Fabric]
    ) -> list[Problem]:
        folder = self.root / m.value
        what = m.value
        if m is Modality.TOUCH and kinds is not None:
            what += " (" + "/".join(k.value for k in kinds) + " presses)"

        noun = "object" if any(f.name is not None for f in self.fabrics) else "fabric"

        def fix(fabrics: list[Fabric], whose: str) -> str:
            """What presses ``fabrics`` have instead, and the --set that trains on them; for
            another sense some fabrics have, the --set that leaves it out (`leave_out`)."""
            if m is not Modality.TOUCH or kinds is None:
                if len(lacking) == len(self.fabrics):
                    return ""
                everyone = [
                    s.value for s in self.modalities if all(f.items.get(s) for f in self.fabrics)
                ]
                return leave_out(m.value, everyone, noun, len(fabrics) == 1)
            theirs = _press_kinds(it for f in fabrics for it in f.items.get(m, ()))
            if not theirs:
                return ""
            every = _press_kinds(self.items(m))
            on = "them" if every == theirs else "every kind the data holds"
            use = set_flag(f"data.touch_kinds=[{','.join(every)}]")
            return (
                f"; {whose} presses are {'/'.join(theirs)} (the run's data.touch_kinds asks "
                f"{'/'.join(k.value for k in kinds)}): {use} trains on {on}"
            )

        heads, grouped = lacking_lines([_who(f) for f in lacking], len(self.fabrics), noun, what)
        if grouped:
            return [Problem(folder, heads[0] + fix(lacking, "their"))]
        return [Problem(folder, h + fix([f], "its")) for h, f in zip(heads, lacking, strict=True)]

    # ---- summary -----------------------------------------------------------------------------

    def fingerprint(self) -> str:
        """A digest of what a run learns and is scored on: every fabric's id, name, labels and
        cluster and its items' files, relative to the dataset folder and written with ``/``
        on every system, with each file's size (a moved or copied folder keeps its digest, on
        Linux, macOS or Windows; a file added, removed, renamed or rewritten
        at another size, as a world rendered again at another seed or image size is, or a
        label changed, does not). Runs record it (checkpoints, ``lookfeel cv``'s folders,
        ``lookfeel reproduce``'s runs), so that results on one dataset are never taken for
        another's: compare with `matches_fingerprint`. Taken once per catalog (it reads every
        file's size), as the scan it describes was."""
        return self._sized_digest

    @functools.cached_property
    def _sized_digest(self) -> str:
        return self._digest(sizes=True)

    def matches_fingerprint(self, recorded: str) -> bool:
        """Whether ``recorded`` (a run's `fingerprint`) is this dataset's: its digest now, or
        the one lookfeel recorded before session 53 (without the files' sizes), which older
        checkpoints and cv folders hold; on Windows also those taken before session 57, with
        its ``\\`` between folders."""
        if recorded == self.fingerprint() or recorded == self._digest(sizes=False):
            return True
        return os.sep != "/" and recorded in (
            self._digest(sizes=True, native=True),
            self._digest(sizes=False, native=True),
        )

    def _digest(self, sizes: bool, native: bool = False) -> str:
        def file(p: Path) -> str | list[object]:
            # "/" between folders on every system (unless ``native``): the same dataset has
            # one digest on Linux, macOS and Windows, whose relpath says depth\F0001_1.png
            rel = os.path.relpath(p, self.root)
            rel = rel if native else PurePath(rel).as_posix()
            return [rel, _size(p)] if sizes else rel

        rows = [
            [
                f.id,
                f.name,
                sorted(f.labels.items()),
                sorted(f.text_labels.items()),
                f.cluster,
                [
                    [m.value, [[file(p) for p in it.frames] for it in its]]
                    for m, its in sorted(f.items.items(), key=lambda kv: kv[0].value)
                ],
            ]
            for f in self.fabrics
        ]
        return hashlib.sha256(json.dumps(rows).encode()).hexdigest()[:16]

    def summary(self) -> dict[str, object]:
        """Counts for `lookfeel data info`: fabrics, items per modality and press kind, labels;
        ``data_root`` names the dataset folder (as ``index info`` and ``embed`` do).

        When the data names objects (``videos/<name>_<n>.mov``), two more keys give the names
        behind the ids: ``object_names`` (id as text -> name, of every named object, labelled
        only ones included) and ``labelled_without_images_names`` (the names of the objects
        in labels.csv that have no video; ``labelled_without_images`` keeps their ids).
        """
        items: dict[str, int] = {}
        for m in Modality:
            n = sum(len(f.items.get(m, ())) for f in self.fabrics)
            if n:
                items[m.value] = n
        kinds: dict[str, int] = {}
        frames = 0
        videos = 0
        for it in self.items(Modality.TOUCH):
            kind = it.kind.value if it.kind is not None else "any kind"
            kinds[kind] = kinds.get(kind, 0) + 1
            if it.path.suffix.lower() in VIDEO_SUFFIXES:
                videos += 1
            else:
                frames += len(it.frames)
        clusters: dict[str, int] = {}
        for f in self.fabrics:
            if f.cluster is not None:
                clusters[str(f.cluster)] = clusters.get(str(f.cluster), 0) + 1
        per_fabric = {
            m.value: sorted(len(f.items.get(m, ())) for f in self.fabrics) for m in self.modalities
        }
        out: dict[str, object] = {
            "data_root": str(self.root),
            "fabrics": len(self.fabrics),
            "fabric_ids": self.ids,
            "items": items,
            "items_per_fabric": {
                m: {"min": v[0], "max": v[-1]} for m, v in per_fabric.items() if v
            },
            "touch_presses_by_kind": dict(sorted(kinds.items())),
            "touch_frames": frames,
            "touch_videos": videos,
            "named_objects": sum(f.name is not None for f in self.fabrics),
            "label_columns": list(self.label_columns),
            "text_columns": list(self.text_columns),
            "rank_columns": list(self.rank_columns),
            "classes": self.class_counts(),
            "fabrics_with_physical_labels": sum(f.has_physical_labels for f in self.fabrics),
            "cluster_column": self.cluster_column,
            "fabrics_with_cluster": sum(f.cluster is not None for f in self.fabrics),
            "clusters": dict(sorted(clusters.items(), key=lambda kv: int(kv[0]))),
            "paper_split": {
                s: sum(f.paper_split == s for f in self.fabrics)
                for s in ("train", "test", "excluded")
                if any(f.paper_split == s for f in self.fabrics)
            },
            "labelled_without_images": sorted(self.labelled_only),
            "errors": len(self.errors),
            "warnings": len(self.warnings),
            "skipped": len(self.skipped),
        }
        everyone = sorted([*self.fabrics, *self.labelled_only.values()], key=lambda f: f.id)
        if any(f.name is not None for f in everyone):
            out["object_names"] = {str(f.id): f.name for f in everyone if f.name is not None}
            out["labelled_without_images_names"] = sorted(
                f.name for f in self.labelled_only.values() if f.name is not None
            )
        return out


def _who(fabric: Fabric) -> str:
    """``'sponge'`` for a named object, ``12`` for a numbered fabric."""
    return repr(fabric.name) if fabric.name is not None else str(fabric.id)


def _press_kinds(items: Iterable[Item]) -> list[str]:
    """The stated press kinds of ``items``, sorted (``["flat", "fold"]``)."""
    return sorted({it.kind.value for it in items if it.kind is not None})


def _size(path: Path) -> int:
    """A file's size in bytes, -1 where it cannot be read now (the digest then differs)."""
    try:
        return os.stat(path).st_size
    except OSError:
        return -1
