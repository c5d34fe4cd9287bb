"""Embed and evaluate a trained checkpoint on a dataset, or evaluate an embeddings file.

Which items are "test" (``split``):

- ``val``: the run's held-out items, from the checkpoint's split (the fabrics in
  ``split["val"]``; for a ``seen`` run, its held-out 20% of each training fabric's items). The
  run's training items are the reference: c and the property probes are fitted on them. A
  run's ``best.pt`` was chosen on these (the best validation top-1): scored here (or on any
  split that holds them), the result says its scores are optimistic (``selected_on_split``,
  a note; `_chosen_on`); ``last.pt`` was not chosen on them.
- ``train``: the run's training items (the paper's Figure 8b shows these); no reference.
- ``novel``: a ``seen`` run's held-out fabrics (Table 4's novel fabrics); reference: training.
- ``paper``: the paper's 18 test fabrics (labels.csv's ``paper_split``, else the built-in list);
  reference: the paper's training fabrics. The shared real data holds the test fabrics back.
- ``all``: every item of the dataset that the model embeds (its modalities, the run's press
  kinds; the description names what is left out); no reference (the paper's c, no probes).

Beside the model's scores, `evaluate_checkpoint` scores the same queries on **raw pixels** (every
same-modality pair, ``{pair}_raw_pixels_top{k}``) and, as `lookfeel cv` does, under the controls
that expose a shortcut (`lookfeel.evaluate.controls`): for a model with a depth branch the
**background control** (``EvalConfig.background_control``, on by default): each test depth
image's background replaced by another fabric's, the cloth kept, every pair with depth scored
again (``{pair}_top{k}_swapped``, raw pixels ``depth_to_depth_raw_pixels_top{k}_swapped``; for
registered depth also the room control, ``..._room``); for touch recorded as press videos the
**untouched control** (always): each press replaced by a moment of its video without contact,
every pair with touch scored again (``{pair}_top{k}_untouched``, raw pixels
``touch_to_touch_raw_pixels_top{k}_untouched``). Touch queries pool the same presses there as
in the main scores. Pairs scored through a cross-modal map are scored through the same map
under each control too (``{pair}_top{k}_mapped_swapped``, ``..._mapped_untouched``).
`evaluate_embedding_file` scores raw pixels too when it is given the dataset.
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from dataclasses import replace
from pathlib import Path, PurePosixPath
from typing import Any

from torch import nn

from lookfeel.checkpoint import CheckpointError, LoadedModel, load_model
from lookfeel.config import DataConfig, EvalConfig, from_dict, to_dict
from lookfeel.config.model import EMBED_BATCH
from lookfeel.data import Catalog, DatasetError, ImageLoader, kmeans_clusters, paper_split
from lookfeel.data import scan as scan_dataset
from lookfeel.data.recordings import drop_unpressed
from lookfeel.data.touch_control import UntouchedControl
from lookfeel.embedding import (
    EmbeddedItems,
    EmbeddingError,
    PressPooler,
    embed_catalog,
    press_pooler,
)
from lookfeel.errors import LookfeelError
from lookfeel.index.match import check_touch_dataset
from lookfeel.metrics.label_space import LabelSpace, fit_label_spaces
from lookfeel.modality import Modality, PressKind
from lookfeel.models import BranchEnsemble, Embedder
from lookfeel.provenance import software_versions

from .controls import background_control, raw_pixel_baseline, untouched_control
from .core import evaluate_embeddings
from .embeddings_file import EmbeddingSet, load_embeddings
from .result import EvalResult

__all__ = [
    "BEST_CHECKPOINT",
    "SPLITS",
    "embed_checkpoint",
    "evaluate_checkpoint",
    "evaluate_embedding_file",
    "pools_final_embedding",
]

SPLITS = ("val", "train", "novel", "paper", "all")
"""The ``split`` values of `evaluate_checkpoint` and `embed_checkpoint`."""

BEST_CHECKPOINT = "best.pt"
"""The name training gives the checkpoint it chose by validation (`lookfeel.train.loop`: the
one of the best validation top-1 so far, beside ``last.pt``, the run's last step)."""


def _scan(data_root: str | os.PathLike[str]) -> Catalog:
    """The dataset, refusing it whole if any file is unusable: embedding or scoring a dataset
    with files silently left out would report on data the user did not ask for."""
    return scan_dataset(Path(data_root), require=(), strict=True)


def pools_final_embedding(model: Embedder) -> bool:
    """Whether the model's multi-press touch embedding is the max of its per-press embeddings.

    True for the paper's nets (max over fc7, nothing after it); False when a projection or an
    L2 normalisation follows the pooling, or the pooling is a mean. An ensemble pools its
    final embedding when every member does (side by side, the maxima are the members').
    """
    if Modality.TOUCH not in model.modalities:
        return True
    b = model.branch(Modality.TOUCH.value)
    parts = b.member_branches() if isinstance(b, BranchEnsemble) else [b]
    return all(
        p.press_pool == "max" and isinstance(p.project, nn.Identity) and not p.normalize
        for p in parts
    )


def _item_key(path: str | Path) -> tuple[str, str]:
    """(folder, file name) of an item's path as a run's ``split.json`` records it: how a held-out
    item is found again wherever the dataset now lies, on whichever system the run was trained
    (a path written on Windows has backslashes)."""
    p = PurePosixPath(str(path).replace("\\", "/"))
    return p.parent.name, p.name


def _unit(catalog: Catalog) -> str:
    return "objects" if any(f.name is not None for f in catalog.fabrics) else "fabrics"


def _every_item(catalog: Catalog, left_out: list[str]) -> str:
    """What ``--split all`` embeds: every item of the dataset, or, when the model leaves some
    out (`_left_out`), every item it embeds, naming what it leaves out."""
    unit = _unit(catalog)
    if not left_out:
        return f"every item of the dataset (training {unit} included)"
    return (
        f"every item of the dataset the model embeds (training {unit} included; left out: "
        f"{'; '.join(left_out)})"
    )


def _left_out(
    catalog: Catalog, kept: Catalog, modalities: list[Modality], kinds: tuple[PressKind, ...]
) -> list[str]:
    """What of ``catalog`` is not embedded, one phrase a reason: the modalities the model does
    not embed, touch presses of no kind in the run's ``data.touch_kinds`` (as
    `embed_catalog` takes them) and, of the rest, videos that hold no press (dropped from
    ``kept``)."""
    out = []
    for m in catalog.modalities:
        if m not in modalities:
            n = len(catalog.items(m))
            what = "presses" if m is Modality.TOUCH else "images"
            out.append(f"{n} {m.value} {what} (the model does not embed {m.value})")
    if Modality.TOUCH not in modalities:
        return out
    taken = set(catalog.items(Modality.TOUCH, kinds))
    other: dict[str, int] = {}
    for it in catalog.items(Modality.TOUCH):
        if it not in taken and it.kind is not None:
            other[it.kind.value] = other.get(it.kind.value, 0) + 1
    if other:
        counts = ", ".join(f"{n} {k}" for k, n in sorted(other.items()))
        run_kinds = "/".join(sorted(k.value for k in kinds))
        out.append(f"{counts} presses (the run's data.touch_kinds: {run_kinds})")
    pressed = set(kept.items(Modality.TOUCH))
    unpressed = sum(1 for it in taken if it not in pressed)
    if unpressed:
        out.append(f"{unpressed} touch video{'s' if unpressed != 1 else ''} with no press")
    return out


def _select(
    loaded: LoadedModel, catalog: Catalog, split: str
) -> tuple[Catalog, Catalog | None, str]:
    """(test items, reference items or None, a description) of ``split`` (module docstring)."""
    if split not in SPLITS:
        raise ValueError(f"split must be one of {', '.join(SPLITS)}; got {split!r}")
    s = loaded.split
    kind = s.get("kind", "")
    unit = _unit(catalog)
    if split == "all":
        return catalog, None, _every_item(catalog, [])
    if (
        split in ("val", "train", "novel")
        and loaded.data_fingerprint is not None
        and not catalog.matches_fingerprint(loaded.data_fingerprint)
    ):
        warnings.warn(
            f"{loaded.path} was trained on another dataset than {catalog.root}, or on this one "
            f"before its files or labels changed: --split {split} takes the run's fabric ids, "
            "which may name other fabrics here",
            stacklevel=2,
        )
    if split == "paper":
        ps = paper_split(catalog)
        if not ps.test:
            other = (
                "--split val for the run's held-out fabrics, or --split all"
                if s.get("val") or s.get("val_items")
                else "--split all (the run held out no fabrics)"
            )
            raise DatasetError(
                "--split paper: no fabric of this dataset is one of the paper's test fabrics "
                "(labels.csv paper_split=test; the shared GelFabric data holds its 18 back); "
                f"use {other}",
                catalog.root,
            )
        ref = catalog.subset(ps.train) if ps.train else None
        return catalog.subset(ps.test), ref, f"the paper's test fabrics ({len(ps.test)})"
    train_ids = [int(i) for i in s.get("train", [])]
    if kind == "seen" and split in ("val", "train"):
        held = {_item_key(p) for p in s.get("val_items", [])}
        pool = catalog.subset(train_ids)
        items = [it for m in pool.modalities for it in pool.items(m)]
        val = [it for it in items if _item_key(it.path) in held]
        if not val:
            raise DatasetError(
                f"{loaded.path}: none of the run's held-out items is in this dataset; is it the "
                "dataset the run was trained on?",
                catalog.root,
            )
        train = [it for it in items if _item_key(it.path) not in held]
        if split == "val":
            return (
                pool.with_items(val),
                pool.with_items(train),
                f"the run's held-out items of its {len(pool.fabrics)} training {unit} (seen)",
            )
        return pool.with_items(train), None, "the run's training items"
    if split == "train":
        return catalog.subset(train_ids), None, f"the run's training {unit} ({len(train_ids)})"
    key = "novel" if split == "novel" else "val"
    ids = [int(i) for i in s.get(key, [])]
    if not ids:
        why = (
            "it is not a seen run"
            if split == "novel"
            else "it trained on every fabric (train.split=none)"
        )
        other = "--split paper or --split all" if paper_split(catalog).test else "--split all"
        raise DatasetError(
            f"{loaded.path}: the run held out no {'novel ' if split == 'novel' else ''}fabrics "
            f"({why}); use {other}",
            catalog.root,
        )
    ref = catalog.subset(train_ids) if train_ids else None
    if ref is not None and kind == "seen":  # training items only, not the held-out 20%
        held = {_item_key(p) for p in s.get("val_items", [])}
        ref = ref.with_items(
            it for m in ref.modalities for it in ref.items(m) if _item_key(it.path) not in held
        )
    what = "held-out novel" if split == "novel" else "held-out"
    return catalog.subset(ids), ref, f"the run's {what} {unit} ({len(ids)})"


def _chosen_on(
    loaded: LoadedModel, catalog: Catalog, test: Catalog, split: str
) -> dict[str, Any] | None:
    """What of ``test`` the checkpoint was chosen on, when it is a run's `BEST_CHECKPOINT`:
    ``{"shared": n, "of": m, "unit": ..., "step": ...}``, ``n`` of the ``m`` test fabrics
    (``unit`` ``fabrics`` or ``objects``) being the run's validation fabrics, or, for a
    ``seen`` run, ``n`` of the ``m`` test items its held-out items (``unit`` ``items``);
    None when it shares none of them or is not a best checkpoint.

    Since session 54 training records in ``best.pt`` the score it was chosen by
    (`LoadedModel.chosen_by`), so a renamed copy is known too; an older one is known by the
    name training gave it. Either needs the run's split to hold validation fabrics or items (a
    run that validated on none, ``train.split=none``, or an ensemble of members, writes no
    ``best.pt``). On another dataset than the run's (its fingerprint), the run's ids name
    other fabrics: only ``--split val``, which takes the run's ids as the test set, counts.
    """
    s = loaded.split
    chosen = loaded.chosen_by is not None or loaded.path.name == BEST_CHECKPOINT
    if not chosen or not (s.get("val") or s.get("val_items")):
        return None
    recorded = loaded.data_fingerprint
    if split != "val" and recorded is not None and not catalog.matches_fingerprint(recorded):
        return None
    if s.get("kind") == "seen":
        held = {_item_key(p) for p in s.get("val_items", [])}
        items = [it for m in test.modalities for it in test.items(m)]
        shared, of, unit = sum(_item_key(it.path) in held for it in items), len(items), "items"
    else:
        val = {int(i) for i in s.get("val", [])}
        shared, of, unit = sum(i in val for i in test.ids), len(test.ids), _unit(catalog)
    if not shared:
        return None
    return {"shared": shared, "of": of, "unit": unit, "step": loaded.step}


def _load(checkpoint: str | os.PathLike[str] | LoadedModel, device: str) -> LoadedModel:
    return checkpoint if isinstance(checkpoint, LoadedModel) else load_model(checkpoint, device)


@contextmanager
def _naming(loaded: LoadedModel) -> Iterator[None]:
    """Turn an `EmbeddingError` (the model embeds NaN or infinity) into a `CheckpointError`
    naming the checkpoint: the weights are at fault, and the user knows the file."""
    try:
        yield
    except EmbeddingError as e:
        raise CheckpointError(f"{loaded.path}: {e}") from None


def _drop_unpressed(
    catalog: Catalog, test: Catalog, ref: Catalog | None, loader: ImageLoader
) -> tuple[Catalog, Catalog | None]:
    """``test`` and ``ref`` without their touch videos that hold no press (`drop_unpressed`,
    one warning naming them all): only the videos of these two are decoded."""
    parts = [c for c in (test, ref) if c is not None]
    wanted = [it for c in parts for m in c.modalities for it in c.items(m)]
    both = catalog.with_items(wanted)
    kept = drop_unpressed(both, loader)
    if kept is both:  # every press held one
        return test, ref
    keep = {it for m in kept.modalities for it in kept.items(m)}

    def only_kept(c: Catalog) -> Catalog:
        return c.with_items(it for m in c.modalities for it in c.items(m) if it in keep)

    return only_kept(test), None if ref is None else only_kept(ref)


def _embed(
    loaded: LoadedModel,
    catalog: Catalog,
    split: str,
    reference: bool,
    batch_size: int,
    device: str,
    progress: bool = False,
) -> tuple[EmbeddingSet, ImageLoader]:
    # Everything that can refuse the split is asked of the checkpoint and the catalog first:
    # the videos are decoded only once the items to embed are known (minutes on hundreds).
    test, ref, description = _select(loaded, catalog, split)
    mods = [m for m in loaded.model.modalities if m in catalog.modalities]
    if not mods:
        have = ", ".join(m.value for m in catalog.modalities) or "none"
        raise DatasetError(
            f"the model embeds {', '.join(m.value for m in loaded.model.modalities)}; the "
            f"dataset has {have}",
            catalog.root,
        )
    if Modality.TOUCH in mods:  # what `lookfeel match` refuses, before any video is decoded
        kinds = tuple(loaded.config.data.touch_kinds)
        parts = [test, ref] if reference and ref is not None else [test]
        presses = [it.path for c in parts for it in c.items(Modality.TOUCH, kinds)]
        check_touch_dataset(presses, loaded.touch_input, loaded.config.data, catalog.root)
    loader = ImageLoader(loaded.config.data)
    selected = test
    test, ref = _drop_unpressed(catalog, test, ref if reference else None, loader)
    if split == "all":  # say so when "every item" is not every item of the dataset
        left = _left_out(selected, test, mods, tuple(loaded.config.data.touch_kinds))
        description = _every_item(catalog, left)

    def run(cat: Catalog) -> dict[Modality, EmbeddedItems]:
        return embed_catalog(
            loaded.model,
            cat,
            loader,
            modalities=mods,
            batch_size=batch_size,
            device=device,
            progress=progress,
        )

    embedded = run(test)
    if not embedded:
        raise DatasetError(f"--split {split}: no items to embed", catalog.root)
    meta = {
        "split": split,
        "split_description": description,
        "checkpoint": str(loaded.path),
        "step": loaded.step,
        "data_root": str(catalog.root),
        "data_fingerprint": catalog.fingerprint(),  # the folder as scanned (`Catalog`)
        "software": software_versions(),
        "data_config": to_dict(loaded.config.data),
        "presses": loaded.config.data.presses,
        "pool_exact": pools_final_embedding(loaded.model),
        # what of the test items the checkpoint was chosen on (None: nothing): see `_chosen_on`
        "selected_on": _chosen_on(loaded, catalog, test, split),
    }
    ref_emb = run(ref) if ref is not None and ref.fabrics else None
    return EmbeddingSet(embedded, ref_emb or None, meta), loader


def embed_checkpoint(
    checkpoint: str | os.PathLike[str] | LoadedModel,
    data_root: str | os.PathLike[str],
    split: str = "all",
    *,
    reference: bool = True,
    batch_size: int = EMBED_BATCH,
    device: str = "cpu",
    progress: bool = False,
) -> EmbeddingSet:
    """Embed a dataset's items with a trained model (``lookfeel embed``).

    Args:
        checkpoint: a checkpoint path, or a model loaded by `lookfeel.checkpoint.load_model`.
        data_root: the dataset folder.
        split: which items (see the module docstring); default every item.
        reference: also embed the split's reference (training) items, when it has any.
        batch_size: images per forward pass.
        device: where the model runs.
        progress: show progress bars on stderr, per modality, of the images decoded and the
            items embedded (`lookfeel.embedding.embed_catalog`'s; ``lookfeel embed`` shows
            them unless ``--quiet``).

    Returns:
        `EmbeddingSet` (write it with `save_embeddings`).

    Raises:
        CheckpointError, DatasetError: naming the file or fabric ids at fault (a checkpoint
            whose model embeds NaN or infinity among them).
        ImageError: touch presses the model cannot take, as ``lookfeel match`` would refuse
            each (`lookfeel.index.match.check_touch_dataset`), before any is embedded.
    """
    loaded = _load(checkpoint, device)
    with _naming(loaded):
        emb, _ = _embed(
            loaded,
            _scan(data_root),
            split,
            reference,
            batch_size,
            device,
            progress,
        )
    return emb


def _clusters_and_labels(
    catalog: Catalog,
) -> tuple[dict[int, int | None], dict[int, list[float]] | None, list[str], list[str]]:
    """Clusters (labels.csv's, else k-means on the labels as the paper), labels and notes."""
    notes = []
    clusters = catalog.clusters()
    if all(c is None for c in clusters.values()) and catalog.label_columns:
        try:
            clusters = kmeans_clusters(catalog, k=8)
            notes.append("clusters: k-means (k = 8) on the fabrics' labels, as the paper")
        except DatasetError as e:
            notes.append(f"clusters: none in labels.csv and no k-means ({e})")
    cols = list(catalog.label_columns)
    labels = catalog.label_matrix(cols) if cols else None
    return clusters, labels, cols, notes


def _evaluate_set(
    emb: EmbeddingSet,
    config: EvalConfig | None,
    catalog: Catalog | None,
    pool: PressPooler | None,
    data_config: DataConfig | None,
    extra_notes: list[str],
) -> EvalResult:
    config = config or EvalConfig()
    if config.presses is None:
        config = replace(config, presses=int(emb.meta.get("presses", 1)))
    clusters: Mapping[int, int | None] | None = None
    labels: dict[int, list[float]] | None = None
    label_names: list[str] = []
    objects: dict[int, str] = {}  # the data's object names, shown in place of fabric ids
    notes = list(extra_notes)
    chosen: dict[str, float] = {}
    if "selected_on" in emb.meta:  # a checkpoint's embeddings (not an older file's); the
        # note itself is said from the result's info (`selection_note`), above its scores
        chosen["selected_on_split"] = 1.0 if emb.meta["selected_on"] else 0.0
    if catalog is not None:
        clusters, labels, label_names, more = _clusters_and_labels(catalog)
        notes += more
        objects = {f.id: f.name for f in catalog.fabrics if f.name is not None}
    result = evaluate_embeddings(
        emb.embedded,
        config,
        clusters,
        labels,
        label_names=label_names or None,
        reference=emb.reference,
        pool_presses=pool,
        info=emb.meta,
        data_config=data_config,
    )
    return replace(
        result,
        metrics={**result.metrics, **chosen},
        notes=tuple(notes) + result.notes,
        names=objects,
    )


def evaluate_checkpoint(
    checkpoint: str | os.PathLike[str] | LoadedModel,
    data_root: str | os.PathLike[str],
    split: str = "val",
    config: EvalConfig | None = None,
    *,
    batch_size: int = EMBED_BATCH,
    device: str = "cpu",
) -> EvalResult:
    """Embed a split of a dataset with a trained model and score it (``lookfeel evaluate``).

    Clusters come from labels.csv (else k-means on the labels, as the paper), labels from
    labels.csv. Multi-press touch queries are embedded by the model itself when it pools
    before a projection or normalisation (`pools_final_embedding`), else by the max of the
    per-press embeddings (identical, and what an embeddings file allows).

    Args:
        checkpoint: a checkpoint path or a loaded model.
        data_root: the dataset folder.
        split: which items are "test" (see the module docstring): ``val`` (default),
            ``train``, ``novel``, ``paper`` or ``all``.
        config: the protocol; ``presses`` defaults to the run's ``data.presses``.
        batch_size, device: for embedding.

    Returns:
        `EvalResult`, with ``info`` naming the checkpoint, step, split and data.

    Raises:
        ImageError: touch presses the model cannot take, as `embed_checkpoint`.
    """
    loaded = _load(checkpoint, device)
    catalog = _scan(data_root)
    with _naming(loaded):
        emb, loader = _embed(loaded, catalog, split, True, batch_size, device)
        exact = bool(emb.meta["pool_exact"])
        pool = None if exact else press_pooler(loaded.model, loader, batch_size, device)
        result = _evaluate_set(emb, config, catalog, pool, loaded.config.data, [])
        extra = raw_pixel_baseline(result, loader)
        notes: list[str] = []
        spaces = _label_spaces(emb, catalog, result.config)
        model, data = loaded.model, loaded.config.data
        if result.config.background_control and Modality.DEPTH in emb.embedded:
            more, why = background_control(
                model, data, emb.embedded, result, batch_size, device, spaces
            )
            extra, notes = extra | more, notes + why
        more, why = untouched_control(
            model, data, emb.embedded, result, exact, batch_size, device, spaces
        )
        extra, notes = extra | more, notes + why
    return replace(result, metrics={**result.metrics, **extra}, notes=result.notes + tuple(notes))


def _label_spaces(
    emb: EmbeddingSet, catalog: Catalog, config: EvalConfig
) -> dict[Modality, LabelSpace] | None:
    """In label space (``eval.space: labels``), the maps onto the labels the pairs were scored
    through (fitted on the reference items, as `lookfeel.evaluate.core.project_to_labels`
    fits them), for the controls' embeddings; else None."""
    if config.space != "labels" or emb.reference is None:
        return None
    names = list(catalog.label_columns)
    labels = catalog.label_matrix(names) if names else {}
    ref = emb.reference
    return fit_label_spaces(
        {m: (ref[m].embeddings, ref[m].fabric_ids) for m in emb.embedded if m in ref},
        labels,
        names,
    )


def evaluate_embedding_file(
    path: str | os.PathLike[str],
    config: EvalConfig | None = None,
    data_root: str | os.PathLike[str] | None = None,
) -> EvalResult:
    """Score an embeddings file (``lookfeel evaluate --embeddings``).

    Clusters and labels come from ``data_root`` when given (else none: fabric-id order, no
    probes). Multi-press touch queries max-pool the stored per-press embeddings; when the file
    says the model pools differently (``pool_exact`` false), a note says these differ from
    the model's own.

    Args:
        path: an npz written by ``lookfeel embed`` (or with the same keys).
        config: the protocol; ``presses`` defaults to the file's ``presses`` (else 1).
        data_root: the dataset the embeddings came from.
    """
    catalog = _scan(data_root) if data_root is not None else None
    emb = load_embeddings(path, catalog)
    notes = []
    if not emb.meta.get("pool_exact", True):
        notes.append(
            "multi-press touch queries max-pool the stored embeddings, but the model pools "
            "before its projection or normalisation: evaluate the checkpoint for its own "
            "multi-press embeddings"
        )
    data_config = None
    if "data_config" in emb.meta:
        data_config = from_dict(DataConfig, emb.meta["data_config"])
    meta: dict[str, Any] = {**emb.meta, "embeddings_file": str(path)}
    result = _evaluate_set(replace(emb, meta=meta), config, catalog, None, data_config, notes)
    touch = emb.embedded[Modality.TOUCH].items if Modality.TOUCH in emb.embedded else ()
    after = []
    if Modality.DEPTH in emb.embedded or UntouchedControl.applies(touch):
        after.append(
            "no background or untouched control: each embeds altered images, which needs the "
            "model (lookfeel evaluate --checkpoint)"
        )
    pixels: dict[str, float] = {}
    if catalog is None or data_config is None:
        why = "the dataset (--data)" if catalog is None else "the run's preprocessing"
        after.append(f"no raw-pixel baseline: it reads the images, and needs {why}")
    else:
        try:
            pixels = raw_pixel_baseline(result, ImageLoader(data_config))
        except LookfeelError as e:
            after.append(f"no raw-pixel baseline: {e}")
    return replace(result, metrics={**result.metrics, **pixels}, notes=(*result.notes, *after))
