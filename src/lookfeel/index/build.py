"""Building a fabric library: embed every item of a dataset, calibrate, index; resumable.

The job is a list of shards (``shard_size`` items of one modality each, in catalog order).
A shard already on disk with the right key is kept, so a killed build, run again with the same
arguments, embeds only what is missing, and rebuilding after adding a few files re-embeds only
the shards whose files changed. Memory is bounded by one shard's preprocessed images (a fresh
`ImageLoader` per shard) plus the embeddings.

Nothing finished is lost: the build writes into the work folder ``OUT.building/``
(`lookfeel.index.library.work_folder`), where a killed build resumes, and only a complete
library replaces the one at ``OUT``, swapped in by two renames (the old one aside to
``OUT.replaced/``, the new one in, then the old one removed; a build killed between them is
finished by the next). A shard the finished library already holds (same key) is hard-linked
into the work folder, not embedded again, so a rebuild with unchanged inputs gives the same
files, byte for byte. A finished library built from another checkpoint (by content) or another
dataset folder is replaced only with ``replace=True`` (``--replace``). Calibration, the slow
step after the shards, is reused from the finished library when every shard was reused and its
manifest's ``calibration_key`` says it was made from the same shards with the same settings and
the same calibration code (`_calibration_key`). The manifest also records what the shard keys
were made from (``shard_key``: the checkpoint, the preprocessing digest, the touch frame; and
each shard's ``files``), so that a rebuild which embeds a finished library's shards again says
why (`_why_embedded`). While it runs a build
holds ``OUT.lock`` (``fcntl.flock``, released by the system when the process ends, however it
ends), so a second build to the same ``OUT`` is refused, naming the first one's PID.

When `MIN_MAP_FABRICS` or more of the library's fabrics have two modalities, a cross-modal map
between them is fitted on the library's own fabrics (`lookfeel.metrics.cross_map`: the fabrics
pair the two embedding spaces, no labels needed), and calibration keeps, per pair, whichever
of the map and the embedding's own distances matches held-out queries better (the map refitted
without each fold's fabrics, `lookfeel.index.calibrate`).
"""

from __future__ import annotations

import contextlib
import fnmatch
import hashlib
import json
import os
import shutil
import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import torch

from lookfeel.atomic import atomic_write_bytes, atomic_write_text, replace_path
from lookfeel.checkpoint import LoadedModel, checkpoint_file, load_model
from lookfeel.config import to_dict
from lookfeel.data import DatasetError, ImageLoader, Item, scan
from lookfeel.data.images import PreprocessSettings
from lookfeel.data.paths import lies_within
from lookfeel.data.recordings import drop_unpressed
from lookfeel.devices import resolve_device
from lookfeel.embedding import embed_items
from lookfeel.index.calibrate import (
    CALIBRATION_VERSION,
    Calibration,
    CalibrationError,
    calibrate,
)
from lookfeel.index.library import (
    CROSS_MAPS,
    LIBRARY_FORMAT,
    LIBRARY_VERSION,
    MANIFEST,
    LibraryError,
    aside_folder,
    file_sha256,
    manifest_status,
    read_shard,
    work_folder,
    write_cross_maps,
    write_shard,
)
from lookfeel.index.match import EMBED_BATCH, check_touch_dataset
from lookfeel.index.query import shape_record
from lookfeel.index.search import FaissSearch, choose_backend
from lookfeel.locks import exclusive
from lookfeel.metrics.cross_map import CrossMap, fit_cross_maps
from lookfeel.modality import Modality, Pair, PressKind
from lookfeel.provenance import software_versions

__all__ = ["MIN_MAP_FABRICS", "BuildResult", "build_library"]

MIN_MAP_FABRICS = 10
"""Fabrics with both modalities a library must hold to fit a cross-modal map between them."""


@dataclass(frozen=True)
class BuildResult:
    """What a build did.

    Attributes:
        root: the library folder.
        items: items per modality.
        shards_embedded: shards embedded by this run.
        shards_reused: shards kept from an earlier (killed or previous) run.
        backend: the search backend chosen (``numpy`` or ``faiss``).
        calibration: the library's calibration.
        seconds: wall time.
        redo_reason: why shards of the finished library at ``out`` were embedded again, as
            a clause in parentheses (``(another checkpoint)``, ``(the files changed)``);
            None when there was no library there or none of its shards was embedded again.
    """

    root: Path
    items: dict[Modality, int]
    shards_embedded: int
    shards_reused: int
    backend: str
    calibration: Calibration
    seconds: float
    redo_reason: str | None = None


@dataclass(frozen=True)
class _Shard:
    modality: Modality
    index: int
    items: tuple[Item, ...]
    key: str
    files: str
    """A digest of the shard's items and their files (name, size, modification time): the
    part of ``key`` that is not `_key_parts`."""

    @property
    def file(self) -> str:
        return f"shards/{self.modality.value}-{self.index:05d}.npz"


def _file_stamp(path: Path) -> list[Any]:
    st = path.stat()
    return [str(path.resolve()), st.st_size, st.st_mtime_ns]


def _key_parts(loader: ImageLoader, checkpoint_sha: str) -> dict[str, Any]:
    """What every shard's key is made from besides its items (the manifest's ``shard_key``):
    the checkpoint's SHA-256, the preprocessing digest and the touch frame."""
    return {
        "checkpoint": checkpoint_sha,
        "preprocess": PreprocessSettings.of(loader.config).digest(),
        "touch_frame": loader.config.touch_frame,
    }


def _plan(
    items: dict[Modality, list[Item]],
    loader: ImageLoader,
    shard_size: int,
    base: dict[str, Any],
) -> list[_Shard]:
    shards = []
    for m, its in items.items():
        for i, start in enumerate(range(0, len(its), shard_size)):
            chunk = tuple(its[start : start + shard_size])
            stamps = [
                [it.fabric_id, *(v for f in loader.source_files(it) for v in _file_stamp(f))]
                for it in chunk
            ]
            blob = {**base, "modality": m.value, "items": stamps}
            key = hashlib.sha1(json.dumps(blob, sort_keys=True).encode()).hexdigest()
            files = hashlib.sha1(json.dumps(stamps).encode()).hexdigest()
            shards.append(_Shard(m, i, chunk, key, files))
    return shards


def _check_out(out: Path) -> None:
    """Refuse an ``out`` that is a file, or a folder holding anything but a lookfeel library,
    and a work folder beside it that is not a build's."""
    if out.exists():
        if not out.is_dir():
            raise LibraryError(f"{out}: exists and is not a folder")
        if manifest_status(out) is None and any(out.iterdir()):
            raise LibraryError(
                f"{out}: folder exists and is not a lookfeel library; choose a new or empty folder"
            )
        if theirs := _not_the_library_s(out):
            n = len(theirs)
            more = f" and {n - 3} more" if n > 3 else ""
            raise LibraryError(
                f"{out}: the library holds {'a file' if n == 1 else 'files'} it did not write "
                f"({', '.join(theirs[:3])}{more}); a rebuild replaces the whole folder, so move "
                f"{'it' if n == 1 else 'them'} out first (nothing was changed)"
            )
    work = work_folder(out)
    if work.exists() and not _ours(work):
        raise LibraryError(
            f"{work}: in the way of building {out} there (lookfeel's work folder for it), and "
            "not a library build; move it away or choose another --out"
        )


LIBRARY_NAMES = (MANIFEST, CROSS_MAPS, "shards", "index-*.faiss", ".*.tmp")
"""What a build writes at a library's top level (and the temp files of its writes)."""


def _not_the_library_s(folder: Path) -> list[str]:
    """Names at the top of a library ``folder`` that no build writes (a user's notes): sorted."""
    return sorted(
        p.name
        for p in folder.iterdir()
        if not any(fnmatch.fnmatch(p.name, pattern) for pattern in LIBRARY_NAMES)
    )


def _check_not_here(out: Path) -> None:
    """Refuse an ``out`` that is the current folder or holds it: the swap would leave the
    shell in the old library's removed folder. Asked of the disk as well as of the spelling
    (`lies_within`): ``cd ~/Lib`` then ``--out ~/lib`` is that folder on a disk that ignores
    case."""
    try:
        here = Path.cwd().resolve()
    except OSError:  # the current folder is gone: it is not ``out``
        return
    folder = out.resolve()
    if lies_within(here, folder):
        raise LibraryError(
            f"{out}: is the current folder or holds it, which a build swaps for the new library "
            f"when complete; run it from another folder (cd {folder.parent}; --out {folder.name})"
        )


def _ours(folder: Path) -> bool:
    """Whether ``folder`` is a library or a build's work folder (it has a lookfeel library
    manifest), or holds nothing but temp files a killed write left."""
    if not folder.is_dir():
        return False
    if manifest_status(folder) is not None:
        return True
    return all(p.name.startswith(".") and p.name.endswith(".tmp") for p in folder.iterdir())


def _move(src: Path, dst: Path) -> None:
    """Rename ``src`` to ``dst`` (one step of the swap) and make the rename durable."""
    replace_path(src, dst)
    with contextlib.suppress(OSError):  # a folder cannot be opened to fsync everywhere
        fd = os.open(dst.parent, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


def _remove_library(folder: Path) -> None:
    """Remove a library folder, its manifest last: what a killed removal leaves is still
    recognised as a library (`_ours`), and removed by the next build."""
    manifest = folder / MANIFEST
    for child in folder.iterdir():
        if child == manifest:
            continue
        if child.is_dir() and not child.is_symlink():
            shutil.rmtree(child)
        else:
            child.unlink()
    manifest.unlink(missing_ok=True)
    folder.rmdir()


def _swap_in(work: Path, out: Path) -> None:
    """Put the complete library in ``work`` at ``out``: the library there (if any) renamed
    aside, the new one renamed in, the old one removed (module docstring)."""
    if out.exists():
        aside = aside_folder(out)
        _move(out, aside)
        _move(work, out)
        _remove_library(aside)
    else:
        _move(work, out)


def _finish_swap(out: Path) -> None:
    """Finish a swap that a killed build left (`_swap_in`): where the previous library still
    lies aside, either the new one is in place (remove the old), or it is complete in the work
    folder (move it in), or neither (put the old one back)."""
    aside = aside_folder(out)
    if not aside.exists():
        return
    if not _ours(aside):
        raise LibraryError(
            f"{aside}: in the way of building {out} there (where the previous library waits "
            "while a new one is moved in), and not a lookfeel library; move it away"
        )
    work = work_folder(out)
    if out.exists():
        _remove_library(aside)
    elif manifest_status(work) == "complete":
        _move(work, out)
        _remove_library(aside)
    else:
        _move(aside, out)


def _finished(out: Path) -> dict[str, Any] | None:
    """The manifest of the complete library at ``out``; None when there is none."""
    if manifest_status(out) != "complete":
        return None
    manifest = json.loads((out / MANIFEST).read_text(encoding="utf-8"))
    return manifest if isinstance(manifest, dict) else None


def _origin(manifest: dict[str, Any]) -> tuple[str, str, str]:
    """(checkpoint path, its SHA-256, data folder) a library manifest records ("?" if not)."""
    ck = manifest.get("checkpoint")
    ck = ck if isinstance(ck, dict) else {}
    return str(ck.get("path", "?")), str(ck.get("sha256", "?")), str(manifest.get("data_root"))


def _check_replace(
    out: Path, checkpoint: Path, checkpoint_sha: str, data_root: Path, allowed: bool
) -> None:
    """Refuse to replace a finished library built from another checkpoint (by content) or
    another dataset folder, unless ``allowed``; then warn what is replaced."""
    old = _finished(out)
    if old is None:
        return
    old_ck, old_sha, old_data = _origin(old)
    was, now = [], []
    if old_sha != checkpoint_sha:
        was.append(f"checkpoint {old_ck} (sha256 {old_sha[:12]})")
        now.append(f"checkpoint {checkpoint} (sha256 {checkpoint_sha[:12]})")
    if old_data != str(data_root):
        was.append(f"data {old_data}")
        now.append(f"data {data_root}")
    if not was:
        return
    if not allowed:
        raise LibraryError(
            f"{out}: holds a finished library built from {' on '.join(was)}; this build is "
            f"from {' on '.join(now)}: pass --replace (replace=True) to replace it once the new "
            "one is complete, or choose another --out"
        )
    warnings.warn(
        f"{out}: replacing the library built from {old_ck} on {old_data} with one from "
        f"{checkpoint} on {data_root} once it is complete",
        stacklevel=3,
    )


def _known_shards(*folders: Path) -> dict[str, list[Path]]:
    """Shard key -> its files, for every shard the manifests in ``folders`` list, in the order
    of ``folders`` (the work folder first). A killed build's work folder lists shards it never
    wrote: the finished library's file of the same key is still found."""
    found: dict[str, list[Path]] = {}
    for folder in folders:
        try:
            manifest = json.loads((folder / MANIFEST).read_text(encoding="utf-8"))
            for entry in manifest["modalities"].values():
                for shard in entry["shards"]:
                    found.setdefault(str(shard["key"]), []).append(folder / str(shard["file"]))
        except (OSError, ValueError, KeyError, TypeError, AttributeError):
            continue  # no manifest, or not one listing shards: nothing to reuse there
    return found


PREPROCESS_CHANGED = "the preprocessing changed: a newer lookfeel or other data.* settings"
EARLIER_MANIFEST = (
    "made by an earlier lookfeel, whose manifest records less of what its shards were made from"
)


def _why_embedded(
    old: dict[str, Any],
    shard: _Shard,
    key_parts: dict[str, Any],
    shard_size: int,
    kinds: list[str],
    data_root: str,
) -> str:
    """Why ``shard`` was embedded again although the finished library whose manifest is
    ``old`` was there: which part of its key differs from the key the library's shard at the
    same place was made with (each part that can be told from ``old``; ``; `` between two),
    or that the library's file of the same key was missing or damaged."""
    try:
        entries = old["modalities"][shard.modality.value]["shards"]
        before = next((e for e in entries if e.get("file") == shard.file), None)
        if any(e.get("key") == shard.key for e in entries):
            return "the library's shard file was missing or damaged"
    except (KeyError, TypeError, AttributeError):
        before = None
    recorded = old.get("shard_key")
    recorded = recorded if isinstance(recorded, dict) else {}
    causes = []
    if _origin(old)[1] != key_parts["checkpoint"]:
        causes.append("another checkpoint")
    if "preprocess" in recorded and recorded["preprocess"] != key_parts["preprocess"]:
        causes.append(PREPROCESS_CHANGED)
    if "touch_frame" in recorded and recorded["touch_frame"] != key_parts["touch_frame"]:
        causes.append(
            f"another data.touch_frame: {key_parts['touch_frame']}, was {recorded['touch_frame']}"
        )
    if (before or {}).get("files") != shard.files:  # other items (or none recorded)
        if old.get("shard_size") != shard_size:
            causes.append(f"another --shard-size: {shard_size}, was {old.get('shard_size')}")
        elif shard.modality is Modality.TOUCH and old.get("touch_kinds", kinds) != kinds:
            was = ",".join(map(str, old["touch_kinds"]))
            causes.append(f"other --kinds: {','.join(kinds)}, was {was}")
        elif old.get("data_root") != data_root:  # the items' paths are in the key
            causes.append("another data folder")
        elif recorded:  # the library recorded its shards' files: they are not these
            causes.append("the files changed")
    if causes:
        return "; ".join(causes)
    return EARLIER_MANIFEST


def _link(src: Path, dst: Path) -> None:
    """Give ``dst`` the content of ``src``: a hard link (shards are never modified in place:
    a write replaces the file), or a copy where links are refused; atomic."""
    dst.parent.mkdir(parents=True, exist_ok=True)
    tmp = dst.with_name(f".{dst.name}.{os.getpid()}.link.tmp")
    tmp.unlink(missing_ok=True)
    try:
        os.link(src, tmp)
    except OSError:
        try:
            shutil.copyfile(src, tmp)
        except OSError as e:  # a full disk: name the shard, leave no temp behind
            tmp.unlink(missing_ok=True)
            raise OSError(e.errno, e.strerror, str(dst)) from None
    os.replace(tmp, dst)


def _remove_temps(work: Path) -> None:
    """Remove the temp files a killed write left in the work folder (no other build writes
    there: the caller holds the lock)."""
    for folder in (work, work / "shards"):
        if folder.is_dir():
            for tmp in folder.glob(".*.tmp"):
                tmp.unlink(missing_ok=True)


def _library_maps(
    tables: dict[Modality, tuple[np.ndarray, np.ndarray]],
) -> tuple[dict[Pair, CrossMap], str | None]:
    """Cross-modal maps fitted on the library's own fabrics, and a note when too few fabrics
    have two modalities to fit any."""
    if len(tables) < 2:
        return {}, None
    common = {m: set(np.unique(f).tolist()) for m, (_, f) in tables.items()}
    pairs = [p for p in Pair.every(list(tables)) if not p.same]
    pairs = [p for p in pairs if len(common[p.query] & common[p.gallery]) >= MIN_MAP_FABRICS]
    maps = fit_cross_maps(tables, pairs)
    if maps:
        return maps, None
    return {}, (
        f"no cross-modal maps: fewer than {MIN_MAP_FABRICS} of the library's fabrics have "
        "two modalities to fit them on"
    )


def _write_manifest(out: Path, manifest: dict[str, Any]) -> None:
    atomic_write_text(out / MANIFEST, json.dumps(manifest, indent=2) + "\n")


def build_library(
    checkpoint: str | os.PathLike[str],
    data: str | os.PathLike[str],
    out: str | os.PathLike[str],
    *,
    backend: str = "auto",
    shard_size: int = 2048,
    batch_size: int = EMBED_BATCH,
    kinds: Sequence[PressKind] | None = None,
    target_false_accept: float = 0.05,
    folds: int = 5,
    seed: int = 0,
    calibration_queries: int = 1000,
    cross_map: bool = True,
    replace: bool = False,
    device: torch.device | str = "cpu",
    on_shard: Callable[[str, int], None] | None = None,
    progress: bool = False,
) -> BuildResult:
    """Embed every item of every modality of a dataset into a library folder.

    Args:
        checkpoint: a trained model's checkpoint (`lookfeel train` writes them); its config's
            data settings preprocess every image exactly as in training.
        data: the dataset folder (the lookfeel layout).
        out: the library folder: new, empty, or a library to update. A library there stays
            as it is until the new one is complete (module docstring); a build killed before
            that resumes when run again with the same arguments.
        backend: ``auto`` (faiss from `AUTO_FAISS_MIN_ROWS` items in a modality, else numpy),
            ``numpy`` (exact) or ``faiss`` (HNSW, approximate).
        shard_size: items per shard (and per resumable unit of work).
        batch_size: images per forward pass.
        kinds: touch press kinds to include; default: the run's ``data.touch_kinds``.
        target_false_accept: false-accept rate the "unknown" threshold is chosen for.
        folds, seed, calibration_queries: leave-fabrics-out calibration settings
            (`lookfeel.index.calibrate`).
        cross_map: fit cross-modal maps on the library's own fabrics and match a pair through
            its map when calibration finds that better (module doc).
        replace: replace a finished library at ``out`` built from another checkpoint (by
            content) or dataset folder; without it such a build is refused before any work.
        device: where to embed: ``cpu``, ``cuda``, ``cuda:1``, a ``torch.device``, or
            ``auto`` (`lookfeel.devices.resolve_device`), checked before anything is written.
        on_shard: called as ``on_shard(file, rows)`` after each shard is written.
        progress: print a line per shard, and one before calibration (or saying it is
            reused).

    Raises:
        LibraryError: ``out`` is another kind of folder, holds a library of another checkpoint
            or dataset (without ``replace``), another build is writing it, or the dataset has
            nothing to embed.
        DeviceError: ``device`` is unknown to torch or not usable here (before any folder or
            lock file is made).
        DatasetError: the dataset has errors (`lookfeel data check` lists them).
        CheckpointError: the checkpoint cannot be read.
        ImageError: touch presses the model cannot take, as ``lookfeel match`` would refuse
            each (still images for a model trained on press videos, videos for one that
            stacks frame images: `lookfeel.index.match.check_touch_dataset`), naming the first,
            before any is embedded.
    """
    started = time.perf_counter()
    out = Path(out)
    if shard_size < 1 or batch_size < 1:
        raise LibraryError(f"shard_size and batch_size must be >= 1 ({shard_size}, {batch_size})")
    if not 0.0 <= target_false_accept < 1.0:
        raise LibraryError(
            f"--false-accept (target_false_accept) must be in [0, 1); got {target_false_accept}"
        )
    if folds < 0:
        raise LibraryError(
            f"--folds (folds) must be 0 or more (below 2: no unknown class); got {folds}"
        )
    if calibration_queries < 1:
        raise LibraryError(
            "--calibration-queries (calibration_queries) must be at least 1; got "
            f"{calibration_queries}"
        )
    try:
        choose_backend(backend, 0)  # validate before any work
    except ValueError as e:
        raise LibraryError(str(e)) from None
    device = resolve_device(device)  # one line, before the lock file and its folder are made
    if out.is_symlink():  # swap the folder it names, keeping the link
        out = out.resolve()
    _check_not_here(out)
    with exclusive(out, "index build", "this library", LibraryError):  # OUT.lock
        _finish_swap(out)
        _check_out(out)
        work = work_folder(out)
        ck = checkpoint_file(checkpoint).resolve()  # a run's folder: its checkpoints/last.pt
        loaded = load_model(ck, device)
        checkpoint_sha = file_sha256(ck)
        _check_replace(out, ck, checkpoint_sha, Path(data).resolve(), replace)
        result = _build(
            started,
            loaded,
            ck,
            checkpoint_sha,
            Path(data),
            out,
            work,
            backend=backend,
            shard_size=shard_size,
            batch_size=batch_size,
            kinds=kinds,
            cross_map=cross_map,
            device=device,
            on_shard=on_shard,
            progress=progress,
            calibration_settings=dict(
                target_false_accept=target_false_accept,
                folds=folds,
                seed=seed,
                max_queries=calibration_queries,
            ),
        )
        _swap_in(work, out)
    return result


def _build(
    started: float,
    loaded: LoadedModel,
    ck: Path,
    checkpoint_sha: str,
    data: Path,
    out: Path,
    work: Path,
    *,
    backend: str,
    shard_size: int,
    batch_size: int,
    kinds: Sequence[PressKind] | None,
    cross_map: bool,
    device: torch.device | str,
    on_shard: Callable[[str, int], None] | None,
    progress: bool,
    calibration_settings: dict[str, Any],
) -> BuildResult:
    """Build the complete library for ``out`` in ``work`` (`build_library`, which holds the
    lock and swaps it in); reuse the shards either already holds."""
    config = loaded.config
    catalog = scan(data, require=())
    if catalog.errors:
        raise DatasetError(catalog.errors, catalog.root)
    kinds = tuple(kinds) if kinds else config.data.touch_kinds
    items = {m: catalog.items(m, kinds) for m in loaded.model.modalities}
    other = catalog.items(Modality.TOUCH) if Modality.TOUCH in loaded.model.modalities else []
    if other and not items.get(Modality.TOUCH):
        found = sorted({it.kind.value for it in other if it.kind is not None})
        warnings.warn(
            f"{catalog.root}: no {'/'.join(k.value for k in kinds)} presses: touch is left out "
            f"of the library (the data holds {', '.join(found)} presses; --kinds chooses)",
            stacklevel=2,
        )
    items = {m: its for m, its in items.items() if its}
    if not items:
        have = ", ".join(m.value for m in loaded.model.modalities)
        raise LibraryError(f"{catalog.root}: no items of the model's modalities ({have})")
    if Modality.TOUCH in items:  # what `lookfeel match` refuses is refused here, before any work
        presses = [it.path for it in items[Modality.TOUCH]]
        check_touch_dataset(presses, loaded.touch_input, config.data, catalog.root)
    data_config = replace(config.data, cache_dir=None)
    loader = ImageLoader(data_config)
    fingerprint = catalog.fingerprint()  # as `train` and `evaluate` take it: before the drop
    catalog = drop_unpressed(catalog, loader)
    items = {m: catalog.items(m, kinds) for m in items}
    key_parts = _key_parts(loader, checkpoint_sha)
    shards = _plan(items, loader, shard_size, key_parts)

    manifest: dict[str, Any] = {
        "format": LIBRARY_FORMAT,
        "version": LIBRARY_VERSION,
        "status": "building",
        "checkpoint": {"path": str(ck), "sha256": checkpoint_sha, "step": loaded.step},
        "config": to_dict(config),
        "data_root": str(catalog.root.resolve()),
        "data_fingerprint": fingerprint,
        "software": software_versions(),
        "touch_kinds": [k.value for k in kinds],
        "embed_dim": loaded.model.embed_dim,
        "shard_size": shard_size,
        "shard_key": key_parts,
        "backend": None,
        "backend_requested": backend,
        "modalities": {
            m.value: {
                "rows": len(its),
                "shards": [
                    {"file": s.file, "key": s.key, "files": s.files}
                    for s in shards
                    if s.modality is m
                ],
            }
            for m, its in items.items()
        },
    }
    for m, its in items.items():  # a query turned against them is warned of (`lookfeel match`)
        shape = shape_record([it.path for it in its], m, data_config)
        if shape is not None:
            manifest["modalities"][m.value]["shape"] = shape
    known = _known_shards(work, out)  # before this build's manifest replaces the work folder's
    old = _finished(out)
    work.mkdir(parents=True, exist_ok=True)
    _remove_temps(work)
    _write_manifest(work, manifest)

    embedded = reused = 0
    redone: dict[str, None] = {}  # why the old library's shards were embedded again, in order
    parts: dict[Modality, list[dict[str, Any]]] = {m: [] for m in items}
    for n, shard in enumerate(shards):
        path = work / shard.file
        arrays = _reuse(shard, path, known.get(shard.key, []))
        again = ""
        if arrays is not None:
            reused += 1
        else:
            if old is not None:
                why = _why_embedded(
                    old,
                    shard,
                    key_parts,
                    shard_size,
                    manifest["touch_kinds"],
                    manifest["data_root"],
                )
                again = " embedded again" + ("" if why in redone else f" ({why})")
                redone[why] = None
            loader.preload(shard.items)  # videos were decoded by drop_unpressed already
            emb = embed_items(loaded.model, shard.items, loader, batch_size, device)
            write_shard(
                path,
                shard.key,
                emb,
                [it.fabric_id for it in shard.items],
                [str(it.path.resolve()) for it in shard.items],
                [str(loader.frame_path(it).resolve()) for it in shard.items],
                [it.kind.value if it.kind else "" for it in shard.items],
                [it.press or "" for it in shard.items],
            )
            arrays = read_shard(path, shard.key)
            assert arrays is not None
            embedded += 1
            if on_shard is not None:
                on_shard(shard.file, len(shard.items))
        loader.forget(shard.items)  # memory: one shard's images at a time
        parts[shard.modality].append(
            {"embeddings": arrays["embeddings"], "fabric_ids": arrays["fabric_ids"]}
        )
        if progress:
            print(f"  shard {n + 1}/{len(shards)} {shard.file} ({len(shard.items)} items){again}")

    keep = {s.file for s in shards}
    for stale in (work / "shards").glob("*.npz"):
        if f"shards/{stale.name}" not in keep:
            stale.unlink()

    tables = {
        m: (
            np.concatenate([p["embeddings"] for p in ps]),
            np.concatenate([p["fabric_ids"] for p in ps]),
        )
        for m, ps in parts.items()
    }
    maps, map_note = _library_maps(tables) if cross_map else ({}, None)
    if maps:
        write_cross_maps(work / CROSS_MAPS, maps)
        manifest["cross_maps"] = {"file": CROSS_MAPS, "pairs": [str(p) for p in maps]}
    else:
        (work / CROSS_MAPS).unlink(missing_ok=True)
        manifest.pop("cross_maps", None)
    calibration_key = _calibration_key(shards, cross_map, calibration_settings)
    manifest["calibration_key"] = calibration_key
    made = _calibration_made(cross_map, calibration_settings)
    manifest["calibration_made"] = made
    calibration = _reused_calibration(old, calibration_key) if not embedded else None
    if calibration is not None:
        if progress:
            print(
                f"  calibration of {len(calibration.pairs)} pairs reused from {out / MANIFEST} "
                "(every shard reused, the same settings)"
            )
    else:
        if progress:
            # Every shard reused, yet calibrated again: say what changed since.
            again = _calibration_changed(old, made) if old is not None and not embedded else ""
            print(f"  calibrating {_calibration_work(tables, maps, calibration_settings)}{again}")
        calibration = calibrate(
            tables, map_pairs=list(maps), map_items=tables, **calibration_settings
        )
        if map_note:
            calibration.notes.append(map_note)
    resolved = choose_backend(backend, max(len(e) for e, _ in tables.values()))
    for old_index in work.glob("index-*.faiss"):
        old_index.unlink()  # another build's (another backend, or modalities)
    for m, (emb, _) in tables.items():
        if resolved == "faiss":
            index_file = work / f"index-{m.value}.faiss"
            atomic_write_bytes(index_file, FaissSearch.build(emb).to_bytes())
            manifest["modalities"][m.value]["faiss"] = index_file.name

    present = {int(f) for _, fids in tables.values() for f in np.unique(fids)}
    manifest.update(
        status="complete",
        backend=resolved,
        label_columns=list(catalog.label_columns),
        text_columns=list(catalog.text_columns),
        rank_columns=list(catalog.rank_columns),
        fabrics=[
            {
                "id": f.id,
                "labels": dict(f.labels),
                "cluster": f.cluster,
                "name": f.name,  # the object's name (``sponge``); None for a numbered fabric
                "text_labels": dict(f.text_labels),  # every label cell as written
            }
            for f in catalog.fabrics
            if f.id in present
        ],
        calibration=calibration.to_dict(),
    )
    _write_manifest(work, manifest)
    return BuildResult(
        root=out,
        items={m: len(its) for m, its in items.items()},
        shards_embedded=embedded,
        shards_reused=reused,
        backend=resolved,
        calibration=calibration,
        seconds=time.perf_counter() - started,
        redo_reason=f"({'; '.join(redone)})" if redone else None,
    )


def _calibration_key(shards: Sequence[_Shard], cross_map: bool, settings: dict[str, Any]) -> str:
    """What a library's calibration is made from, as a digest its manifest records
    (``calibration_key``): every shard's key in order (the items and their embeddings), the
    calibration settings, whether cross-modal maps are fitted, and lookfeel's version and
    `CALIBRATION_VERSION` (the code that made it). A rebuild with the same key reuses the
    calibration."""
    blob = {
        "shards": [[s.modality.value, s.key] for s in shards],
        "cross_map": cross_map,
        "settings": settings,
        "lookfeel": software_versions()["lookfeel"],
        "calibration": CALIBRATION_VERSION,
    }
    return hashlib.sha1(json.dumps(blob, sort_keys=True).encode()).hexdigest()


def _calibration_made(cross_map: bool, settings: dict[str, Any]) -> dict[str, Any]:
    """What a calibration is made with besides the shards (part of `_calibration_key`), kept in
    the manifest as ``calibration_made`` so that a later build can say what changed."""
    return {
        "settings": settings,
        "cross_map": cross_map,
        "lookfeel": software_versions()["lookfeel"],
        "calibration": CALIBRATION_VERSION,
    }


def _calibration_changed(old: dict[str, Any], made: dict[str, Any]) -> str:
    """`` (again: ...)``: why a library whose shards were all reused is calibrated again, from
    its manifest ``old`` and what this build calibrates with (`_calibration_made`): the
    settings that differ (``seed 1, was 0``), the cross-modal maps, lookfeel's version or its
    calibration code; a manifest that does not record them was written by an earlier
    lookfeel."""
    was = old.get("calibration_made")
    if not isinstance(was, dict):
        return " (again: the library was calibrated by an earlier lookfeel)"
    said = []
    recorded = was.get("settings")
    before: dict[str, Any] = recorded if isinstance(recorded, dict) else {}
    for key, value in made["settings"].items():
        if before.get(key) != value:
            said.append(f"{key} {value}, was {before.get(key)}")
    if was.get("cross_map") != made["cross_map"]:
        said.append("cross-modal maps " + ("fitted" if made["cross_map"] else "not fitted"))
    if was.get("lookfeel") != made["lookfeel"]:
        said.append(f"lookfeel {made['lookfeel']}, was {was.get('lookfeel')}")
    if was.get("calibration") != made["calibration"]:
        said.append("the calibration code changed")
    return f" (again: {'; '.join(said)})" if said else ""


def _reused_calibration(old: dict[str, Any] | None, key: str) -> Calibration | None:
    """The calibration of the finished library's manifest ``old`` when it was made from the
    same items with the same settings (its ``calibration_key`` is ``key``); None: calibrate
    (a library built before the key was recorded, or a calibration that cannot be read)."""
    if old is None or old.get("calibration_key") != key:
        return None
    try:
        return Calibration.from_dict(old.get("calibration"))
    except CalibrationError:
        return None


def _calibration_work(
    tables: dict[Modality, tuple[np.ndarray, np.ndarray]],
    maps: dict[Pair, CrossMap],
    settings: dict[str, Any],
) -> str:
    """What calibration is about to do, for the line printed before it: ``4 pairs (depth 300
    items, color 300 items; up to 1000 queries each, 5 folds; 2 also through a cross-modal
    map)``."""
    items = ", ".join(f"{m.value} {len(e)} items" for m, (e, _) in tables.items())
    pairs = len(tables) ** 2
    mapped = f"; {len(maps)} also through a cross-modal map" if maps else ""
    return (
        f"{pairs} pair{'s' if pairs > 1 else ''} ({items}; up to {settings['max_queries']} "
        f"queries each, {settings['folds']} folds{mapped})"
    )


def _reuse(shard: _Shard, path: Path, known: Sequence[Path]) -> dict[str, Any] | None:
    """The arrays of ``shard`` when the work folder holds it at ``path``, or one of the
    ``known`` files of its key elsewhere does (a finished library's shard, linked to
    ``path``); None: embed it."""
    arrays = read_shard(path, shard.key)
    if arrays is not None and len(arrays["embeddings"]) == len(shard.items):
        return arrays
    for file in known:
        if file == path:
            continue
        arrays = read_shard(file, shard.key)
        if arrays is not None and len(arrays["embeddings"]) == len(shard.items):
            _link(file, path)
            return arrays
    return None
