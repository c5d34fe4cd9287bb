"""A fabric library on disk: every item's embedding and metadata, its calibration and its model.

::

    LIB/manifest.json            format, status, checkpoint (path, sha256), run config, modalities
                                 and their shards, fabrics (labels, cluster, name, text labels),
                                 the label columns of words, calibration, backend
    LIB/shards/depth-00000.npz   one chunk of one modality: embeddings (N, D) float32, fabric ids,
                                 paths, the frame embedded, press kind and id, and its key
    LIB/index-depth.faiss        a faiss index per modality (faiss backend only)
    LIB/cross_maps.npz           the cross-modal maps between modalities, fitted on the
                                 library's fabrics (when enough have two modalities)

Every file is written atomically. A shard's key is a digest of the checkpoint, the
preprocessing and the chunk's files (path, size, modification time), so a build that is killed
continues where it stopped and an unchanged shard is never embedded twice. The manifest is
written first with status ``building`` and last with ``complete``; only a complete library opens.

A finished library is never modified in place. `lookfeel index build` writes into a work folder
beside it, ``LIB.building/`` (`work_folder`: also what a killed build resumes from), and swaps
it in when it is complete: the old library is renamed to ``LIB.replaced/`` (`aside_folder`),
the new one to ``LIB``, then the old one is removed. ``LIB.lock`` (`lock_file`) is held while
a build runs. A build killed between the two renames leaves both libraries whole; the next build
finishes the swap, and `Library.open` says what to do until then. A library opened while a build
swaps it in is read whole, old or new: `Library.open` waits for a swap a running build is making
(`SWAP_WAIT` seconds at most), and reads again when the library was replaced while it read.

The library refers to its checkpoint by path and SHA-256 (queries are embedded with that model);
`Library.load_model` refuses a checkpoint that has changed since the build.

Each fabric's name (``sponge``, for data that names its objects) and its label cells as written
(``material: metal``) are recorded in the manifest; a library built before they were opens
without them (its fabrics are then shown by id, and only its numeric labels are known).
"""

from __future__ import annotations

import hashlib
import io
import json
import os
import time
import zipfile
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch
from numpy.typing import NDArray

from lookfeel.atomic import atomic_write
from lookfeel.checkpoint import RUN_CHECKPOINT, LoadedModel, checkpoint_file, load_model
from lookfeel.config import ConfigError, RunConfig, from_dict
from lookfeel.config.loss import unregistered_loss_kinds_allowed
from lookfeel.data.catalog import Catalog, Fabric
from lookfeel.data.labels import is_rank_column
from lookfeel.errors import LookfeelError, load_problem
from lookfeel.index.calibrate import Calibration, CalibrationError
from lookfeel.index.search import ExactSearch, FaissSearch, Search
from lookfeel.locks import is_held, lock_path
from lookfeel.metrics.cross_map import CrossMap
from lookfeel.modality import Modality, Pair

__all__ = [
    "CROSS_MAPS",
    "LIBRARY_FORMAT",
    "LIBRARY_VERSION",
    "MANIFEST",
    "SWAP_WAIT",
    "FabricRecord",
    "Library",
    "LibraryError",
    "LibraryItem",
    "ModalityTable",
    "aside_folder",
    "file_sha256",
    "folder_identity",
    "lock_file",
    "manifest_status",
    "read_cross_maps",
    "read_shard",
    "work_folder",
    "write_cross_maps",
    "write_shard",
]

LIBRARY_FORMAT = "lookfeel-library"
LIBRARY_VERSION = 2
"""2: pairs may be matched through a cross-modal map (``cross_maps.npz``); 1 is still read."""
MANIFEST = "manifest.json"
CROSS_MAPS = "cross_maps.npz"
SWAP_WAIT = 5.0
"""Seconds `Library.open` waits for a running build to finish swapping a library in."""
_SWAP_POLL = 0.02
_OPEN_TRIES = 4
"""Times `Library.open` reads a library that another is swapped in for while it reads, before
what it read stands (an error, or a library read while one build after another swapped)."""


class LibraryError(LookfeelError):
    """A library cannot be built, opened or queried; the message names the file or value."""


def _beside(root: Path, suffix: str) -> Path:
    """``root`` with ``suffix`` added to its name (``.`` and ``..`` by the folder's own name)."""
    if root.name in ("", ".."):
        root = Path(os.path.abspath(root))
    return root.with_name(root.name + suffix)


def work_folder(root: Path) -> Path:
    """``LIB.building``: where `lookfeel index build` writes a library before it is complete
    (and what a killed build resumes from), beside ``root``."""
    return _beside(root, ".building")


def aside_folder(root: Path) -> Path:
    """``LIB.replaced``: where the previous library waits while a finished rebuild is moved in,
    beside ``root``; removed once the new one is in place."""
    return _beside(root, ".replaced")


def lock_file(root: Path) -> Path:
    """``LIB.lock``: the lock a build holds while it writes ``root`` (or its work folder;
    `lookfeel.locks.lock_path`)."""
    return lock_path(root)


def file_sha256(path: str | os.PathLike[str]) -> str:
    """SHA-256 of a file's content, read in 1 MiB blocks."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


# ---- shards ------------------------------------------------------------------------------------

_SHARD_ARRAYS = ("embeddings", "fabric_ids", "paths", "images", "kinds", "presses")


def write_shard(
    path: Path,
    key: str,
    embeddings: NDArray[np.floating],
    fabric_ids: Sequence[int],
    paths: Sequence[str],
    images: Sequence[str],
    kinds: Sequence[str],
    presses: Sequence[str],
) -> None:
    """Write one shard atomically (an ``.npz`` of plain arrays: no pickle to read it back)."""
    arrays: dict[str, NDArray[Any]] = {
        "key": np.array(key),
        "embeddings": np.ascontiguousarray(embeddings, dtype=np.float32),
        "fabric_ids": np.asarray(fabric_ids, dtype=np.int64),
        "paths": np.array(list(paths), dtype=str),
        "images": np.array(list(images), dtype=str),
        "kinds": np.array(list(kinds), dtype=str),
        "presses": np.array(list(presses), dtype=str),
    }
    buf = io.BytesIO()
    np.savez(buf, **arrays)  # type: ignore[arg-type]
    atomic_write(path, lambda f: f.write(buf.getvalue()))


def read_shard(path: Path, key: str | None = None) -> dict[str, NDArray[Any]] | None:
    """Read a shard; None when it is missing, damaged, or its key is not ``key``."""
    try:
        with np.load(path, allow_pickle=False) as z:
            if key is not None and str(z["key"]) != key:
                return None
            out = {name: z[name] for name in _SHARD_ARRAYS}
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile):
        return None
    n = len(out["embeddings"])
    if any(len(v) != n for v in out.values()):
        return None
    return out


def write_cross_maps(path: Path, maps: dict[Pair, CrossMap]) -> None:
    """Write the maps atomically: one ``.npz`` of plain arrays, ``{pair}.{array}``."""
    arrays = {f"{p}.{k}": v for p, m in maps.items() for k, v in m.to_arrays().items()}
    buf = io.BytesIO()
    np.savez(buf, **arrays)  # type: ignore[arg-type]
    atomic_write(path, lambda f: f.write(buf.getvalue()))


def read_cross_maps(path: Path, pairs: Sequence[str], width: int) -> dict[Pair, CrossMap]:
    """Read the maps of ``pairs`` that `write_cross_maps` wrote.

    Raises:
        LibraryError: naming the file, when it is missing or damaged or a map is not
            ``width`` wide.
    """
    try:
        with np.load(path, allow_pickle=False) as z:
            arrays = {k: z[k] for k in z.files}
        maps = {}
        for key in pairs:
            pair = Pair.parse(key)
            prefix = f"{key}."
            cmap = CrossMap.from_arrays(
                {k[len(prefix) :]: v for k, v in arrays.items() if k.startswith(prefix)}
            )
            if cmap.forward.coef.shape != (width, width):
                raise ValueError(f"{key} is {cmap.forward.coef.shape}, not ({width}, {width})")
            maps[pair] = cmap
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile) as e:
        raise LibraryError(
            f"{path}: cross-modal maps missing or damaged ({load_problem(e)}); rebuild with "
            "`lookfeel index build` (unchanged shards are reused)"
        ) from None
    return maps


# ---- records -----------------------------------------------------------------------------------


@dataclass(frozen=True)
class LibraryItem:
    """One library row: an item of one fabric in one modality.

    Attributes:
        id: ``"<modality>:<row>"``, how the web app and the JSON API name items.
        modality, row: where it is in the library.
        fabric_id: its fabric.
        path: the item's file (a press's first frame for touch).
        image: the file that was embedded and is shown (for touch: the configured frame).
        kind: the press kind for touch, else None.
        press: the press id for touch, else None.
    """

    id: str
    modality: Modality
    row: int
    fabric_id: int
    path: str
    image: str
    kind: str | None
    press: str | None


@dataclass(frozen=True)
class FabricRecord:
    """A fabric of the library: its known labels and cluster, and its name if it has one.

    Attributes:
        id: the fabric id.
        labels: known numeric label values by column.
        cluster: its cluster, or None when unknown.
        name: the object's name (``sponge``) when the dataset names its objects
            (``videos/<name>_<n>.mov``); None for a numbered fabric, and in a library built
            before names were recorded.
        text_labels: every known label cell as written, text columns (``material``) included;
            empty in a library built before they were recorded.
    """

    id: int
    labels: dict[str, float]
    cluster: int | None
    name: str | None = None
    text_labels: dict[str, str] = field(default_factory=dict)

    @property
    def title(self) -> str:
        """How a person reads the fabric: its name (``sponge``), else ``fabric 7``."""
        return self.name if self.name is not None else f"fabric {self.id}"


class ModalityTable:
    """One modality's rows: embeddings and metadata, plus each fabric's rows.

    Attributes:
        modality: the modality.
        embeddings: (N, D) float32.
        fabric_ids: (N,) int64.
        fabrics: (F,) the distinct fabric ids, sorted.
        fabric_index: (N,) each row's position in ``fabrics``.
    """

    def __init__(self, modality: Modality, arrays: dict[str, NDArray[Any]]) -> None:
        self.modality = modality
        self.embeddings: NDArray[np.float32] = arrays["embeddings"]
        self.fabric_ids: NDArray[np.int64] = arrays["fabric_ids"]
        self._paths = arrays["paths"]
        self._images = arrays["images"]
        self._kinds = arrays["kinds"]
        self._presses = arrays["presses"]
        self.fabrics, self.fabric_index = np.unique(self.fabric_ids, return_inverse=True)
        order = np.argsort(self.fabric_index, kind="stable")
        bounds = np.searchsorted(self.fabric_index[order], np.arange(len(self.fabrics) + 1))
        self._rows = {int(f): order[bounds[i] : bounds[i + 1]] for i, f in enumerate(self.fabrics)}

    def __len__(self) -> int:
        return len(self.embeddings)

    def rows_of(self, fabric_id: int) -> NDArray[np.int64]:
        """Rows of one fabric (empty when it has none in this modality)."""
        return self._rows.get(int(fabric_id), np.zeros(0, dtype=np.int64))

    def item(self, row: int) -> LibraryItem:
        """The metadata of one row.

        Raises:
            KeyError: naming the row when it is out of range.
        """
        if not 0 <= row < len(self):
            raise KeyError(f"{self.modality.value} has no item {row} (rows 0-{len(self) - 1})")
        kind = str(self._kinds[row]) or None
        press = str(self._presses[row]) or None
        return LibraryItem(
            id=f"{self.modality.value}:{row}",
            modality=self.modality,
            row=row,
            fabric_id=int(self.fabric_ids[row]),
            path=str(self._paths[row]),
            image=str(self._images[row]),
            kind=kind,
            press=press,
        )


# ---- the library -------------------------------------------------------------------------------


class Library:
    """A built fabric library, read into memory (use `Library.open`).

    Attributes:
        root: the library folder.
        manifest: the parsed ``manifest.json``.
        tables: modality -> its rows.
        fabrics: fabric id -> labels and cluster.
        label_columns: the numeric label columns, in the dataset's order.
        text_columns: the label columns of words (``material``); empty in a library built
            before they were recorded.
        classes: per label column whose values are classes (words, or ranks such as hardness
            0/1/2), its classes in order (numbers in numeric order, words alphabetical): the
            columns `lookfeel data info` counts as classes, and the model's class heads.
        calibration: c and the unknown threshold per (query, gallery) pair.
        cross_maps: the maps between modalities (`lookfeel.metrics.cross_map`); a pair whose
            calibration says ``mapped`` is matched through its map.
        config: the run config of the model (its DataConfig preprocesses queries).
        backend: ``numpy`` or ``faiss``.
        checkpoint: the checkpoint file queries are embedded with.
    """

    def __init__(
        self,
        root: Path,
        manifest: dict[str, Any],
        tables: dict[Modality, ModalityTable],
        searches: dict[Modality, Search],
        checkpoint: Path,
        cross_maps: dict[Pair, CrossMap] | None = None,
    ) -> None:
        self.root = root
        self.manifest = manifest
        self.tables = tables
        self._searches = searches
        self.checkpoint = checkpoint
        with unregistered_loss_kinds_allowed():  # matching never builds the run's loss
            self.config = from_dict(RunConfig, manifest["config"])
        self.backend: str = manifest["backend"]
        self.label_columns: tuple[str, ...] = tuple(manifest["label_columns"])
        self.text_columns: tuple[str, ...] = tuple(manifest.get("text_columns", ()))
        self.fabrics = {
            int(f["id"]): FabricRecord(
                int(f["id"]),
                {k: float(v) for k, v in f["labels"].items()},
                f["cluster"],
                name=None if f.get("name") is None else str(f["name"]),
                text_labels={str(k): str(v) for k, v in f.get("text_labels", {}).items()},
            )
            for f in manifest["fabrics"]
        }
        self.classes = self._classes()
        self.calibration = Calibration.from_dict(manifest["calibration"])
        self.cross_maps = dict(cross_maps or {})

    def _classes(self) -> dict[str, tuple[str, ...]]:
        """The label columns whose values are classes: those `lookfeel data info` finds
        (`Catalog.class_counts`: text columns, and numeric columns of ranks 0-10; not
        a column whose every cell differs, such as a description), and the model's class heads
        (``model.classes``). Classes in order: numbers in numeric order, words alphabetical."""
        fabrics = tuple(
            Fabric(id=r.id, labels=r.labels, name=r.name, text_labels=r.text_labels)
            for r in self.fabrics.values()
        )
        ranks = self.manifest.get("rank_columns")
        if ranks is None:  # a library built before they were recorded: its fabrics' values
            ranks = [
                c
                for c in self.label_columns
                if is_rank_column(f.labels[c] for f in fabrics if c in f.labels)
            ]
        catalog = Catalog(
            root=self.root,
            fabrics=fabrics,
            label_columns=self.label_columns,
            text_columns=self.text_columns,
            rank_columns=tuple(ranks),
        )
        found = {col: set(counts) for col, counts in catalog.class_counts().items()}
        for col in self.config.model.classes:
            names = {k for f in fabrics if (k := f.class_of(col)) is not None}
            if names:
                found.setdefault(col, names)
        out = {}
        for col in [*self.label_columns, *self.text_columns]:
            if col in found:
                numeric = col in self.label_columns
                out[col] = tuple(sorted(found[col], key=float if numeric else str))
        return out

    @property
    def modalities(self) -> tuple[Modality, ...]:
        """Modalities with items, in enum order."""
        return tuple(m for m in Modality if m in self.tables)

    @property
    def embed_dim(self) -> int:
        return int(self.manifest["embed_dim"])

    def __len__(self) -> int:
        return sum(len(t) for t in self.tables.values())

    def table(self, modality: Modality) -> ModalityTable:
        """One modality's rows.

        Raises:
            LibraryError: naming the modality and those the library has.
        """
        if modality not in self.tables:
            have = ", ".join(m.value for m in self.modalities)
            raise LibraryError(f"the library at {self.root} has no {modality.value} items ({have})")
        return self.tables[modality]

    def search(self, modality: Modality) -> Search:
        """The search backend over one modality's embeddings."""
        self.table(modality)
        return self._searches[modality]

    def item(self, item_id: str) -> LibraryItem:
        """An item by id (``"touch:12"``): the row in ASCII digits, with no sign, space or
        leading zero (``touch:012``, ``touch:+12`` and ``touch: 12`` name no item), so that
        each item has one id.

        Raises:
            KeyError: naming the id when it does not exist.
        """
        mod, _, row = item_id.partition(":")
        modality = next((m for m in Modality if m.value == mod), None)
        digits = (
            row.isascii()
            and row.isdigit()
            and (row == "0" or not row.startswith("0"))
            and len(row) <= 18  # a longer row is no row; int() refuses over 4300 digits
        )
        if modality is None or not digits:
            raise KeyError(f"item id {item_id!r} is not <modality>:<row>")
        index = int(row)
        if modality not in self.tables:
            raise KeyError(f"item {item_id!r}: the library has no {modality.value} items")
        return self.tables[modality].item(index)

    def summary(self) -> dict[str, Any]:
        """What `lookfeel index info` prints and the web app's ``/api/library`` returns."""
        return {
            "root": str(self.root),
            "checkpoint": str(self.checkpoint),
            "model": {
                "backbone": self.config.model.backbone,
                "embed_dim": self.embed_dim,
                "image_size": self.config.data.image_size,
                "color_size": self.config.data.color_size,
                "step": self.manifest["checkpoint"].get("step"),
            },
            "data_root": self.manifest["data_root"],
            # what built it (a library built before session 54 records neither: None)
            "data_fingerprint": self.manifest.get("data_fingerprint"),
            "software": self.manifest.get("software"),
            "backend": self.backend,
            "fabrics": len(self.fabrics),
            "items": {m.value: len(t) for m, t in self.tables.items()},
            "label_columns": list(self.label_columns),
            "calibration": self.calibration.to_dict(),
            "cross_maps": self.manifest.get("cross_maps"),
        }

    def load_model(self, device: torch.device | str = "cpu") -> LoadedModel:
        """The model that embedded the library, to embed queries with.

        Raises:
            LibraryError: the checkpoint is missing or has changed since the build.
        """
        ck = self.checkpoint
        if not ck.is_file():
            raise LibraryError(
                f"{ck}: the library's checkpoint is not there; pass the checkpoint it was built "
                "with (--checkpoint, Library.open's checkpoint) or rebuild the library"
            )
        expected = self.manifest["checkpoint"]["sha256"]
        if file_sha256(ck) != expected:
            raise LibraryError(
                f"{ck}: this checkpoint differs from the one the library was built with "
                f"(sha256 {expected[:12]}...); its embeddings would not match. Rebuild the "
                "library with `lookfeel index build`"
            )
        return load_model(ck, device)

    @classmethod
    def open(
        cls, root: str | os.PathLike[str], checkpoint: str | os.PathLike[str] | None = None
    ) -> Library:
        """Read a complete library.

        Args:
            root: the library folder.
            checkpoint: use this checkpoint file instead of the recorded path (a moved
                library); it must be the same file (same SHA-256).

        Raises:
            LibraryError: naming the file, when the library is missing, unfinished, from a
                newer lookfeel, or damaged.
        """
        root = Path(root)
        deadline = time.monotonic() + SWAP_WAIT
        tries = 1
        while True:
            before = folder_identity(root)
            try:
                library = cls._open_once(root, checkpoint)
            except LibraryError:
                after = folder_identity(root)
                lock = _swap_lock(root) if after is None else None
                if lock is not None:  # a build is moving the new library in
                    if time.monotonic() < deadline:
                        time.sleep(_SWAP_POLL)
                        continue
                    raise LibraryError(
                        f"{root}: not found: a `lookfeel index build` running now is moving a "
                        f"new library in (it holds {lock}) and has not finished in "
                        f"{SWAP_WAIT:g} s; open it again when that build ends"
                    ) from None
                if after != before and tries < _OPEN_TRIES:  # replaced while it was read
                    tries += 1
                    continue
                raise
            if folder_identity(root) == before or tries >= _OPEN_TRIES:
                return library
            tries += 1  # replaced while it was read: read the library now there whole

    @classmethod
    def _open_once(cls, root: Path, checkpoint: str | os.PathLike[str] | None) -> Library:
        """`open`, reading the folder once (what it reads may change under it: `open`)."""
        manifest = read_manifest(root)
        if manifest.get("status") != "complete":
            raise LibraryError(
                f"{root}: the library build did not finish; run `lookfeel index build` again "
                "with the same arguments to resume it"
            )
        try:
            return cls._open(root, manifest, checkpoint)
        except LibraryError:
            raise
        except CalibrationError as e:
            raise LibraryError(
                f"{root / MANIFEST}: {e}; the manifest is damaged: rebuild with "
                "`lookfeel index build`"
            ) from None
        except ConfigError as e:  # a plugin's backbone this process has not loaded, say
            raise LibraryError(
                f"{root / MANIFEST}: its model's config does not load: {e}"
            ) from None
        except KeyError as e:
            raise LibraryError(
                f"{root / MANIFEST}: no {e.args[0]!r} entry; the manifest is damaged or from "
                "another tool; rebuild with `lookfeel index build`"
            ) from None
        except (TypeError, ValueError, AttributeError) as e:
            raise LibraryError(
                f"{root / MANIFEST}: malformed manifest ({type(e).__name__}: {e}); rebuild with "
                "`lookfeel index build`"
            ) from None

    @classmethod
    def _open(
        cls, root: Path, manifest: dict[str, Any], checkpoint: str | os.PathLike[str] | None
    ) -> Library:
        width = int(manifest["embed_dim"])
        tables: dict[Modality, ModalityTable] = {}
        searches: dict[Modality, Search] = {}
        for name, entry in manifest["modalities"].items():
            m = Modality(name)
            parts = []
            for shard in entry["shards"]:
                arrays = read_shard(root / shard["file"], shard["key"])
                if arrays is None:
                    raise LibraryError(
                        f"{root / shard['file']}: shard missing or damaged; rebuild with "
                        "`lookfeel index build` (unchanged shards are reused)"
                    )
                _check_shard(root / shard["file"], arrays, width)
                parts.append(arrays)
            merged = {k: np.concatenate([p[k] for p in parts]) for k in _SHARD_ARRAYS}
            if len(merged["embeddings"]) != entry["rows"]:
                raise LibraryError(
                    f"{root}: {name} has {len(merged['embeddings'])} rows, "
                    f"the manifest says {entry['rows']}"
                )
            tables[m] = ModalityTable(m, merged)
            if manifest["backend"] == "faiss":
                index_file = root / entry["faiss"]
                try:
                    searches[m] = FaissSearch.from_bytes(index_file.read_bytes())
                except (OSError, RuntimeError) as e:
                    raise LibraryError(f"{index_file}: cannot read the faiss index: {e}") from None
            else:
                searches[m] = ExactSearch(tables[m].embeddings)
        built = Path(manifest["checkpoint"]["path"])
        ck = built if checkpoint is None else _checkpoint_for(Path(checkpoint), built)
        maps = {}
        if manifest.get("cross_maps"):
            entry = manifest["cross_maps"]
            maps = read_cross_maps(root / entry["file"], entry["pairs"], width)
        return cls(root, manifest, tables, searches, ck, maps)


def _checkpoint_for(given: Path, built: Path) -> Path:
    """The checkpoint file a ``--checkpoint`` given to a library stands for: a file as it is;
    a training run's folder, the file of that run the library was built with where it is
    there (``best.pt``: the library's manifest names it), else its ``checkpoints/last.pt``
    (`lookfeel.checkpoint.checkpoint_file`), as everywhere else. A library built from a run's
    ``best.pt`` and moved with its run is so opened with the run's folder, not refused as
    built from another checkpoint."""
    if given.is_dir():
        same = given / RUN_CHECKPOINT.parent / built.name
        if built.parent.name == RUN_CHECKPOINT.parent.name and same.is_file():
            return same
    return checkpoint_file(given)


def _check_shard(path: Path, arrays: dict[str, NDArray[Any]], width: int) -> None:
    """A shard's embeddings must be (N, width) finite numbers and its fabric ids integers.

    Raises:
        LibraryError: naming the shard and what is wrong (a wrong width or a NaN would
            otherwise be served as a fabric with no id).
    """
    emb = arrays["embeddings"]
    if emb.ndim != 2 or emb.shape[1] != width or emb.dtype.kind != "f":
        raise LibraryError(
            f"{path}: embeddings are {emb.dtype} of shape {emb.shape}; the manifest says width "
            f"{width}; rebuild with `lookfeel index build`"
        )
    if not np.isfinite(emb).all():
        raise LibraryError(
            f"{path}: embeddings hold NaN or infinite values; rebuild with `lookfeel index build`"
        )
    if arrays["fabric_ids"].dtype.kind not in "iu":
        raise LibraryError(f"{path}: fabric ids are {arrays['fabric_ids'].dtype}, not integers")


def read_manifest(root: Path) -> dict[str, Any]:
    """Parse ``root/manifest.json`` and check it is a library this version reads.

    Raises:
        LibraryError: naming the file.
    """
    path = root / MANIFEST
    if root.exists() and not root.is_dir():
        raise LibraryError(
            f"{root}: is a file, not a library folder (give the folder that holds {MANIFEST})"
        )
    if not root.is_dir():
        raise LibraryError(_not_found(root))
    try:
        manifest = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise LibraryError(f"{root}: not a lookfeel library (no {MANIFEST})") from None
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
        raise LibraryError(f"{path}: unreadable library manifest ({e})") from None
    if not isinstance(manifest, dict) or manifest.get("format") != LIBRARY_FORMAT:
        raise LibraryError(f"{path}: not a lookfeel library manifest")
    if int(manifest.get("version", 0)) > LIBRARY_VERSION:
        raise LibraryError(
            f"{path}: written by a newer lookfeel (library version {manifest['version']}); upgrade"
        )
    return manifest


def manifest_status(root: Path) -> str | None:
    """The ``status`` of the lookfeel library manifest in ``root`` (``building``, ``complete``),
    or None when there is none, or it is not a lookfeel library's."""
    try:
        manifest = json.loads((root / MANIFEST).read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError):
        return None
    if not isinstance(manifest, dict) or manifest.get("format") != LIBRARY_FORMAT:
        return None
    status = manifest.get("status")
    return status if isinstance(status, str) else None


def folder_identity(root: Path) -> tuple[int, int] | None:
    """Which folder ``root`` is now (device, inode), None when there is none: a library swapped
    in is another folder than the one it replaced."""
    try:
        st = os.stat(root)
    except OSError:
        return None
    return (st.st_dev, st.st_ino)


def _swap_lock(root: Path) -> Path | None:
    """The lock of a build moving a library in at ``root`` now, None when none is: a complete
    library waits in the work folder or the previous one lies aside (module docstring), and a
    live build holds the lock (`_held`)."""
    if root.is_symlink():  # a build swaps the folder a link names (`build_library`)
        root = Path(os.path.realpath(root))
    if not (aside_folder(root).is_dir() or manifest_status(work_folder(root)) == "complete"):
        return None
    lock = lock_file(root)
    return lock if is_held(lock) else None


def _not_found(root: Path) -> str:
    """Why there is no library at ``root``, and what to do when a build left one beside it
    (module docstring: the work folder, the previous library set aside)."""
    work, aside = work_folder(root), aside_folder(root)
    if aside.is_dir() and manifest_status(work) == "complete":
        return (
            f"{root}: not found: a rebuild was stopped while moving the new library in (it is "
            f"complete in {work}, the previous one in {aside}); run `lookfeel index build` again "
            f"with the same arguments to finish, or rename {work} to {root}"
        )
    if aside.is_dir():
        return (
            f"{root}: not found: the previous library is in {aside} (a rebuild was stopped "
            f"while replacing it); rename it to {root}"
        )
    if work.is_dir():
        return (
            f"{root}: the library build did not finish; run `lookfeel index build` again with "
            f"the same arguments to resume it (its work so far is in {work})"
        )
    return f"{root}: library folder not found"
