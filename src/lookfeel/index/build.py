"""Building a fabric library: embed every item of a dataset, calibrate, index; resumable.

The job is a list of shards (``shard_size`` items of one modality each, in catalog order).
A shard already on disk with the right key is kept, so a killed build, run again with the same
arguments, embeds only what is missing, and rebuilding after adding a few files re-embeds only
the shards whose files changed. Memory is bounded by one shard's preprocessed images (a fresh
`ImageLoader` per shard) plus the embeddings.

When `MIN_MAP_FABRICS` or more of the library's fabrics have two modalities, a cross-modal map
between them is fitted on the library's own fabrics (`lookfeel.metrics.cross_map`: the fabrics
pair the two embedding spaces, no labels needed), and calibration keeps, per pair, whichever
of the map and the embedding's own distances matches held-out queries better (the map refitted
without each fold's fabrics, `lookfeel.index.calibrate`).
"""

from __future__ import annotations

import hashlib
import json
import os
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import torch

from lookfeel.atomic import atomic_write_bytes, atomic_write_text
from lookfeel.checkpoint import load_model
from lookfeel.config import to_dict
from lookfeel.data import DatasetError, ImageLoader, Item, scan
from lookfeel.data.images import PreprocessSettings
from lookfeel.data.recordings import drop_unpressed
from lookfeel.embedding import embed_items
from lookfeel.index.calibrate import Calibration, calibrate
from lookfeel.index.library import (
    CROSS_MAPS,
    LIBRARY_FORMAT,
    LIBRARY_VERSION,
    MANIFEST,
    LibraryError,
    file_sha256,
    read_shard,
    write_cross_maps,
    write_shard,
)
from lookfeel.index.search import FaissSearch, choose_backend
from lookfeel.metrics.cross_map import CrossMap, fit_cross_maps
from lookfeel.modality import Modality, Pair, PressKind

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
    """

    root: Path
    items: dict[Modality, int]
    shards_embedded: int
    shards_reused: int
    backend: str
    calibration: Calibration
    seconds: float


@dataclass(frozen=True)
class _Shard:
    modality: Modality
    index: int
    items: tuple[Item, ...]
    key: str

    @property
    def file(self) -> str:
        return f"shards/{self.modality.value}-{self.index:05d}.npz"


def _file_stamp(path: Path) -> list[Any]:
    st = path.stat()
    return [str(path.resolve()), st.st_size, st.st_mtime_ns]


def _plan(
    items: dict[Modality, list[Item]],
    loader: ImageLoader,
    shard_size: int,
    checkpoint_sha: str,
) -> list[_Shard]:
    base = {
        "checkpoint": checkpoint_sha,
        "preprocess": PreprocessSettings.of(loader.config).digest(),
        "touch_frame": loader.config.touch_frame,
    }
    shards = []
    for m, its in items.items():
        for i, start in enumerate(range(0, len(its), shard_size)):
            chunk = tuple(its[start : start + shard_size])
            blob = {
                **base,
                "modality": m.value,
                "items": [
                    [it.fabric_id, *(v for f in loader.source_files(it) for v in _file_stamp(f))]
                    for it in chunk
                ],
            }
            key = hashlib.sha1(json.dumps(blob, sort_keys=True).encode()).hexdigest()
            shards.append(_Shard(m, i, chunk, key))
    return shards


def _check_out(out: Path) -> None:
    if not out.exists():
        return
    if not out.is_dir():
        raise LibraryError(f"{out}: exists and is not a folder")
    manifest = out / MANIFEST
    if manifest.is_file():
        try:
            fmt = json.loads(manifest.read_text(encoding="utf-8")).get("format")
        except (OSError, UnicodeDecodeError, json.JSONDecodeError, AttributeError):
            fmt = None
        if fmt == LIBRARY_FORMAT:
            return
    if any(out.iterdir()):
        raise LibraryError(
            f"{out}: folder exists and is not a lookfeel library; choose a new or empty folder"
        )


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
    batch_size: int = 64,
    kinds: Sequence[PressKind] | None = None,
    target_false_accept: float = 0.05,
    folds: int = 5,
    seed: int = 0,
    calibration_queries: int = 1000,
    cross_map: bool = True,
    device: torch.device | str = "cpu",
    on_shard: Callable[[str, int], None] | None = None,
    progress: bool = False,
) -> BuildResult:
    """Embed every item of every modality of a dataset into a library folder.

    Args:
        checkpoint: a trained model's checkpoint (`lookfeel train` writes them); its config's
            data settings preprocess every image exactly as in training.
        data: the dataset folder (the lookfeel layout).
        out: the library folder: new, empty, or a library to resume or update.
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
        device: where to embed.
        on_shard: called as ``on_shard(file, rows)`` after each shard is written.
        progress: print a line per shard.

    Raises:
        LibraryError: ``out`` is another kind of folder, or the dataset has nothing to embed.
        DatasetError: the dataset has errors (`lookfeel data check` lists them).
        CheckpointError: the checkpoint cannot be read.
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
    _check_out(out)
    ck = Path(checkpoint).resolve()
    loaded = load_model(ck, device)
    checkpoint_sha = file_sha256(ck)
    config = loaded.config
    catalog = scan(Path(data), require=())
    if catalog.errors:
        raise DatasetError(catalog.errors, catalog.root)
    kinds = tuple(kinds) if kinds else config.data.touch_kinds
    items = {m: catalog.items(m, kinds) for m in loaded.model.modalities}
    items = {m: its for m, its in items.items() if its}
    if not items:
        have = ", ".join(m.value for m in loaded.model.modalities)
        raise LibraryError(f"{catalog.root}: no items of the model's modalities ({have})")
    data_config = replace(config.data, cache_dir=None)
    loader = ImageLoader(data_config)
    catalog = drop_unpressed(catalog, loader)
    items = {m: catalog.items(m, kinds) for m in items}
    shards = _plan(items, loader, shard_size, checkpoint_sha)

    manifest: dict[str, Any] = {
        "format": LIBRARY_FORMAT,
        "version": LIBRARY_VERSION,
        "status": "building",
        "checkpoint": {"path": str(ck), "sha256": checkpoint_sha, "step": loaded.step},
        "config": to_dict(config),
        "data_root": str(catalog.root.resolve()),
        "touch_kinds": [k.value for k in kinds],
        "embed_dim": loaded.model.embed_dim,
        "shard_size": shard_size,
        "backend": None,
        "backend_requested": backend,
        "modalities": {
            m.value: {
                "rows": len(its),
                "shards": [{"file": s.file, "key": s.key} for s in shards if s.modality is m],
            }
            for m, its in items.items()
        },
    }
    out.mkdir(parents=True, exist_ok=True)
    _write_manifest(out, manifest)

    embedded = reused = 0
    parts: dict[Modality, list[dict[str, Any]]] = {m: [] for m in items}
    for n, shard in enumerate(shards):
        path = out / shard.file
        arrays = read_shard(path, shard.key)
        if arrays is not None and len(arrays["embeddings"]) == len(shard.items):
            reused += 1
        else:
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
            print(f"  shard {n + 1}/{len(shards)} {shard.file} ({len(shard.items)} items)")

    keep = {s.file for s in shards}
    for stale in (out / "shards").glob("*.npz"):
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
        write_cross_maps(out / CROSS_MAPS, maps)
        manifest["cross_maps"] = {"file": CROSS_MAPS, "pairs": [str(p) for p in maps]}
    else:
        (out / CROSS_MAPS).unlink(missing_ok=True)
        manifest.pop("cross_maps", None)
    calibration = calibrate(
        tables,
        target_false_accept=target_false_accept,
        folds=folds,
        seed=seed,
        max_queries=calibration_queries,
        map_pairs=list(maps),
        map_items=tables,
    )
    if map_note:
        calibration.notes.append(map_note)
    resolved = choose_backend(backend, max(len(e) for e, _ in tables.values()))
    for m, (emb, _) in tables.items():
        index_file = out / f"index-{m.value}.faiss"
        if resolved == "faiss":
            atomic_write_bytes(index_file, FaissSearch.build(emb).to_bytes())
            manifest["modalities"][m.value]["faiss"] = index_file.name
        else:
            index_file.unlink(missing_ok=True)

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
    _write_manifest(out, manifest)
    return BuildResult(
        root=out,
        items={m: len(its) for m, its in items.items()},
        shards_embedded=embedded,
        shards_reused=reused,
        backend=resolved,
        calibration=calibration,
        seconds=time.perf_counter() - started,
    )
