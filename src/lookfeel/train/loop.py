"""`train`: one entry point for one process or many (``torchrun``), from config to checkpoints.

A run directory holds ``config.yaml`` (the resolved config), ``split.json`` (the fabrics on
each side), ``metrics.jsonl`` (one JSON object per logged step or validation) and
``checkpoints/last.pt`` and ``best.pt``. The trainer knows nothing of which loss or how many
modalities: it logs every term the loss returns and back-propagates ``"loss"``.

Step ``s``'s global batch of B tuples, its augmentations and its choice of cached copies are
drawn from ``(seed, s)`` alone (each process takes a contiguous share), so a resumed run, or a
run on N processes with the same global batch, sees exactly the batches of an unbroken single
run; with the torch RNG (dropout) saved in every checkpoint, a resumed run is bit-identical.

The loop is short: `_Batches` builds step ``s``'s batch on the device (pixels from the
`ImageStore`, augmented in one pass, or trunk features from the `FeatureTable` when the trunk
is cached; the same draws either way) and `train_step` runs one optimisation step. On CUDA the
forward pass runs with channels-last images under bf16 autocast (``model.precision=fp32``: full
fp32); on CPU everything is fp32.

A run whose loss or weights stop being finite (a learning rate far too high) stops with one
line, `TrainingDiverged`, at the first log step, validation or checkpoint after it; the
checkpoints written before are kept, and none of non-finite weights is ever written
(`lookfeel.train.divergence`). ``metrics.jsonl`` writes a non-finite number as ``null``.
"""

from __future__ import annotations

import json
import math
import os
import time
import warnings
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from contextlib import contextmanager, suppress
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import torch
import yaml
from torch import Tensor

from lookfeel.atomic import atomic_write_text, check_writable, remove_stale_temps
from lookfeel.checkpoint import (
    grey_presses_of,
    init_from_checkpoint,
    non_finite_tensors,
    read_checkpoint,
    save_checkpoint,
    touch_input_of,
)
from lookfeel.config import ConfigError, RunConfig, from_dict, save_config, to_dict
from lookfeel.config.model import Precision
from lookfeel.data import (
    Catalog,
    DatasetError,
    ImageLoader,
    ImageStore,
    Item,
    TupleDataset,
    kmeans_clusters,
    paper_split,
    scan,
    seen_fabric_split,
    stratified_fabric_folds,
    stratified_fabric_split,
)
from lookfeel.data.labels import MAX_RANK, is_rank
from lookfeel.data.problems import Problem
from lookfeel.data.recordings import drop_unpressed
from lookfeel.data.video import is_video
from lookfeel.embedding import EmbeddingError
from lookfeel.errors import caller_stacklevel
from lookfeel.index.query import shape_record
from lookfeel.locks import exclusive
from lookfeel.losses import CombinedLoss, create_loss
from lookfeel.modality import REPRINTS, Modality, slot_modality
from lookfeel.models import (
    BACKBONES,
    BranchEnsemble,
    Embedder,
    autocast,
    create_model,
    to_channels_last,
)
from lookfeel.plugins import trained_with_hint
from lookfeel.progress import bar, shown
from lookfeel.provenance import plugin_modules_of, software_versions
from lookfeel.shell import set_flag
from lookfeel.train.distributed import Distributed
from lookfeel.train.divergence import TrainingDiverged, diverged
from lookfeel.train.features import FeatureTable
from lookfeel.train.validate import validate

__all__ = [
    "MEMBERS",
    "TrainResult",
    "TrainRun",
    "as_trained",
    "config_changes",
    "member_config",
    "resolve_classes",
    "resume_checkpoint",
    "run_started",
    "select_split",
    "train",
    "train_step",
    "views_problem",
]

StepCallback = Callable[[int, Mapping[str, float]], None]


@dataclass(frozen=True)
class TrainResult:
    """What a finished run left behind."""

    run_dir: Path
    steps: int
    last_checkpoint: Path
    best_checkpoint: Path | None
    validation: dict[str, float | str]
    """The last validation's metrics (empty without validation): ``{pair}_top1``, ``_top3``
    and ``_chance`` per scored pair, ``{pair}_not_scored`` (the reason) per pair that held-out
    items cannot score (`lookfeel.train.validate.validate`)."""


# ---------------------------------------------------------------------------------------------
# Splits and data


def select_split(
    catalog: Catalog, config: RunConfig
) -> tuple[Catalog, Catalog | None, dict[str, Any]]:
    """The training and validation catalogs of a run, and a record of the split for split.json.

    The paper's test fabrics (`paper_split`: labels.csv's ``paper_split=test``, or GelFabric's
    built-in list on the authors' own folders) are never trained on; every other split is made
    of the rest. A dataset without a paper split (a user's own) splits all its fabrics.
    """
    t = config.train
    if t.split == "none":
        return catalog, None, {"kind": "none", "train": catalog.ids, "val": []}
    paper = paper_split(catalog)
    pool = list(paper.train) or catalog.ids  # never train on the paper's test fabrics
    if t.split == "seen":
        # Table 4: 80% of each training fabric's items train and 20% validate ("seen"); the
        # paper's test fabrics, or else `val_fabrics` held-out fabrics, are the "novel" ones.
        novel = list(paper.test)
        if not novel and t.val_fabrics:
            held = stratified_fabric_split(
                pool, catalog.clusters(), n_test=t.val_fabrics, seed=t.split_seed
            )
            pool, novel = list(held.train), list(held.test)
        train, val = seen_fabric_split(catalog.subset(pool), 0.8, seed=t.split_seed)
        val_items = sorted(str(it.path) for m in val.modalities for it in val.items(m))
        info = {"kind": "seen", "seed": t.split_seed, "train": train.ids, "val": val.ids}
        return train, val, info | {"novel": novel, "val_items": val_items}
    if t.split == "paper":
        if not paper.test:
            why = (
                "none of the paper's test fabrics is in this dataset (the shared real data "
                "holds them back)"
                if paper.source is not None
                else "no fabric of this dataset is marked paper_split=test in labels.csv"
            )
            raise DatasetError(
                f"train.split=paper: {why}; use train.split=stratified to hold out training "
                "fabrics",
                catalog.root,
            )
        return (
            catalog.subset(paper.train),
            catalog.subset(paper.test),
            {"kind": "paper", "train": list(paper.train), "val": list(paper.test)},
        )
    clusters = catalog.clusters()
    if t.split == "fold":
        split = stratified_fabric_folds(
            pool,
            clusters,
            t.folds,
            seed=t.split_seed,
            fold_size=t.fold_size,
            excluded=len(paper.test),
            excluded_by=paper.source or "labels",
        )[t.fold]
        info = {"kind": "fold", "fold": t.fold, "folds": t.folds, "fold_size": t.fold_size}
        info["seed"] = t.split_seed
    else:
        split = stratified_fabric_split(
            pool,
            clusters,
            n_test=t.val_fabrics,
            seed=t.split_seed,
            excluded=len(paper.test),
            excluded_by=paper.source or "labels",
        )
        info = {"kind": "stratified", "seed": t.split_seed}
    info |= {"train": list(split.train), "val": list(split.test)}
    return catalog.subset(split.train), catalog.subset(split.test), info


def resolve_classes(catalog: Catalog, config: RunConfig) -> RunConfig:
    """The config with ``model.classes`` filled in: each class head's classes, as the whole
    dataset's labels name them (ranks in numeric order, words in alphabetical order).

    A class head learns a column of classes (`Catalog.class_columns`: words, or ranks such as
    hardness 0/1/2), the columns ``lookfeel data info`` counts as classes; a numeric column
    that is not ranks (``1.5`` among 0, 1, 2; a thickness) is refused, naming a value that is
    not a rank.

    Raises:
        ConfigError: a ``model.class_heads`` column is not in labels.csv, is numbers and not
            classes, or has < 2 classes.
    """
    model = config.model
    if not model.class_heads:
        return config
    known = [*catalog.label_columns, *catalog.text_columns]
    absent = [col for col in model.class_heads if col not in known]
    if absent:
        some = len(absent) > 1
        raise ConfigError(
            f"model.class_heads: {' and '.join(map(repr, absent))} "
            f"{'are not columns' if some else 'is not a column'} of labels.csv (have: "
            f"{', '.join(known) or 'none'}); {_heads_fix(catalog, model.class_heads)}"
        )
    classes: dict[str, tuple[str, ...]] = {}
    for col in model.class_heads:
        if col not in catalog.class_columns:
            everyone = [*catalog.fabrics, *catalog.labelled_only.values()]
            odd = next(
                (f for f in everyone if col in f.labels and not is_rank(f.labels[col])), None
            )
            what = (
                f"numbers, not classes: {odd.display_name} has {odd.class_of(col)}, not a "
                f"whole number 0-{MAX_RANK} (a rank)"
                if odd is not None
                else "empty"
            )
            raise ConfigError(
                f"model.class_heads: column {col!r} of labels.csv is {what}; a class head "
                "needs words or ranks"
            )
        if col in model.classes:
            classes[col] = model.classes[col]  # a resumed or fine-tuned run keeps its order
            continue
        names = {k for f in catalog.fabrics if (k := f.class_of(col)) is not None}
        numeric = col in catalog.label_columns
        classes[col] = tuple(sorted(names, key=float if numeric else str))
        if len(classes[col]) < 2:
            raise ConfigError(
                f"model.class_heads: column {col!r} has {len(names)} class(es) in labels.csv; "
                "a class head needs two or more"
            )
    return replace(config, model=replace(model, classes=classes))


def _heads_fix(catalog: Catalog, asked: Sequence[str]) -> str:
    """The ``--set`` of ``model.class_heads`` that fits ``catalog``'s labels, for a config
    whose heads name columns its labels.csv lacks: the asked heads the labels have as classes
    (two or more), else every such column of the labels; ``[]`` (no class head) besides."""
    usable = [
        c
        for c in catalog.class_columns
        if len({k for f in catalog.fabrics if (k := f.class_of(c)) is not None}) >= 2
    ]
    heads = [c for c in asked if c in usable] or usable
    none = set_flag("model.class_heads=[]")
    if not heads:
        return f"no column of labels.csv has two classes or more to learn: {none} for no head"
    setting = set_flag(f"model.class_heads={_flow_list(heads)}")
    return f"give the heads your labels have: {setting}, or {none} for none"


def _flow_list(values: Sequence[str]) -> str:
    """``[hardness,material]``: a YAML list that ``--set`` reads back as these strings (YAML's
    single-quoted strings where a bare word would read as something else: ``true``, ``1e3``,
    ``a: b``; not JSON's double quotes, which a suggested ``--set "..."`` cannot hold)."""
    bare = "[" + ",".join(values) + "]"
    try:
        if yaml.safe_load(bare) == list(values):
            return bare
    except yaml.YAMLError:
        pass
    return "[" + ",".join("'" + v.replace("'", "''") + "'" for v in values) + "]"


def views_problem(catalog: Catalog, config: RunConfig) -> Problem | None:
    """Why the data cannot serve the run's ``train.views``, in one line: the modalities they
    use of which ``catalog`` holds no item at all, what it holds, and the ``--set`` of
    ``train.views`` (and of ``train.val_pairs`` where they name a missing modality) that
    trains on what it holds. None when the data holds every modality the views use, or holds
    nothing (the scan's own error says so)."""
    t = config.train
    have = catalog.modalities
    absent = [m for m in t.modalities if m not in have]
    if not absent or not have:
        return None
    views = [v for v in t.views if v in have]
    if not views:
        views = list(have) if len(have) > 1 else [have[0]]
    if len(views) < 2:
        views = views * 2  # one sense: two presses or images of a fabric (Siamese)
    sets = [f"train.views=[{','.join(v.value for v in views)}]"]
    if t.val_pairs and any(m in absent for p in t.val_pairs for m in (p.query, p.gallery)):
        kept = [str(p) for p in t.val_pairs if p.query in views and p.gallery in views]
        sets.append(f"train.val_pairs=[{','.join(kept)}]")
    asked = "[" + ", ".join(v.value for v in t.views) + "]"
    holds = " and ".join(m.value for m in have) + (" alone" if len(have) == 1 else "")
    fix = " ".join(set_flag(s) for s in sets)
    return Problem(
        catalog.root,
        f"the run's train.views {asked} use {' and '.join(m.value for m in absent)}, of which "
        f"the data holds no item (it holds {holds}): {fix} trains on what it holds",
    )


def _scan_for(data: Path, config: RunConfig) -> Catalog:
    """``scan(data, require=<the run's modalities>, strict=True)``, where a modality the run's
    ``train.views`` use that the data holds no item of is one line (`views_problem`), not one
    per fabric.

    Raises:
        DatasetError: every problem of the scan, the views' first.
    """
    try:
        return scan(data, require=config.train.modalities, strict=True)
    except DatasetError as e:
        held = scan(data)
        problem = views_problem(held, config)
        if problem is None:
            raise
        # The scan's other problems: those of the senses the data does hold (an error path,
        # so scanned once more rather than told apart by their words).
        present = [m for m in config.train.modalities if m in held.modalities]
        try:
            scan(data, require=present, strict=True)
            rest: list[Problem] = []
        except DatasetError as others:
            rest = list(others.problems)
        raise DatasetError([problem, *rest], e.root) from None


def resolve_properties(catalog: Catalog, config: RunConfig) -> RunConfig:
    """The config with ``model.num_properties: auto`` replaced by the number of numeric label
    columns (0, so no property head, for a dataset without labels).

    Raises:
        ConfigError: a number was given that is not the number of numeric label columns.
    """
    model, columns = config.model, catalog.label_columns
    if model.num_properties == "auto":
        return replace(config, model=replace(model, num_properties=len(columns)))
    if model.num_properties and model.num_properties != len(columns):
        raise ConfigError(
            f"model.num_properties={model.num_properties}, but labels.csv has "
            f"{len(columns)} label columns ({', '.join(columns) or 'none'}); "
            "set model.num_properties=auto to follow the labels"
        )
    return config


def as_trained(asked: RunConfig, trained: RunConfig) -> RunConfig:
    """``asked`` with what training resolves from the labels taken from ``trained``: the class
    heads' classes when ``asked`` names none (for the same heads), the property head's size when
    it says ``auto``. Equal to ``trained`` exactly when the run is the one asked for (resume and
    `lookfeel cv` compare them so)."""
    model, done = asked.model, trained.model
    if not model.classes and model.class_heads == done.class_heads:
        model = replace(model, classes=done.classes)
    if model.num_properties == "auto":
        model = replace(model, num_properties=done.num_properties)
    return replace(asked, model=model)


def _with_clusters(catalog: Catalog, config: RunConfig) -> Catalog:
    """Clusters for the auxiliary head: labels.csv's, else k-means on the labels (paper 3).

    Raises:
        ConfigError: labels.csv names a cluster the head has no class for
            (``model.num_clusters``).
    """
    if not config.model.cluster_head:
        return catalog
    k = config.model.num_clusters
    beyond = sorted(
        {f.cluster for f in catalog.fabrics if f.cluster is not None and f.cluster >= k}
    )
    if beyond:
        first = next(f for f in catalog.fabrics if f.cluster == beyond[0])
        raise ConfigError(
            f"{catalog.root / 'labels.csv'}: fabric {first.display_name} is in cluster "
            f"{beyond[0]}, and the cluster head has model.num_clusters={k} (clusters 0-{k - 1}); "
            f"set model.num_clusters={beyond[-1] + 1}"
        )
    if all(f.cluster is not None for f in catalog.fabrics):
        return catalog
    if any(f.cluster is not None for f in catalog.fabrics):
        return catalog  # partly known: unknown ones are masked out of the cluster loss
    warnings.warn(
        f"no cluster column in labels.csv: clustering fabrics into {k} by k-means on their labels",
        stacklevel=caller_stacklevel(),
    )
    return catalog.with_clusters(kmeans_clusters(catalog, k=k, seed=0))


def _say_reprints(
    catalog: Catalog, loader: ImageLoader, config: RunConfig, cached: bool, data: Path
) -> None:
    """Warn when ``data.color_reprints`` asks for re-printed photos that this run cannot read,
    or ``data.depth_wall_drop`` for drops that a frozen trunk's cached run does not make."""
    drop = config.data.depth_wall_drop
    if cached and drop and Modality.DEPTH in config.train.modalities:
        warnings.warn(
            f"data.depth_wall_drop={drop:g} is not used with a frozen trunk (train.cache_trunk): "
            "training reads each drape whole",
            stacklevel=caller_stacklevel(),  # the user's call of train()
        )
    n = config.data.color_reprints
    photos = catalog.items(Modality.COLOR) if Modality.COLOR in config.train.modalities else []
    if not n or not photos:
        return
    if cached:
        warnings.warn(
            f"data.color_reprints={n} is not used with a frozen trunk (train.cache_trunk): "
            "training reads the photos themselves",
            stacklevel=caller_stacklevel(),  # the user's call of train()
        )
    elif not loader.uses_reprints(photos[0].path):
        warnings.warn(
            f"data.color_reprints={n}: {data} has no {REPRINTS}/ folder of re-printed photos "
            "(a synthetic world's: `lookfeel synth --reprints`); training on the photos "
            "themselves",
            stacklevel=caller_stacklevel(),  # the user's call of train()
        )


class _Batches:
    """Step ``s``'s batch on the device, drawn from ``(seed, s)``.

    A slot is served from the trunk cache when the table holds its modality (augmented
    modalities: one of the cached copies per image); otherwise its images are gathered from the
    store and augmented on the device, and, in a cached run, sent through the frozen trunk
    without gradient (augmented modalities with ``augment_copies: 0``).
    """

    def __init__(
        self,
        ds: TupleDataset,
        store: ImageStore,
        table: FeatureTable | None,
        model: Embedder,
        config: RunConfig,
        device: torch.device,
        rank: int,
        world: int,
    ) -> None:
        self.ds, self.store, self.table, self.model, self.device = ds, store, table, model, device
        self.seed = config.train.seed
        self.batch = config.train.batch_size
        self.channels_last = config.train.channels_last
        local = self.batch // world
        self.lo, self.hi = rank * local, (rank + 1) * local
        self.augmenters = {m: a for m, a in ds.augmenters.items() if a.active}
        self.cached = {
            m
            for m in ds.pool_items
            if table is not None and not (m in self.augmenters and not table.has_copies(m))
        }
        # Pool index (TupleDataset.pool_items) -> row of the store / of the table.
        self.store_rows = {
            m: torch.tensor(store.rows(m, its))
            for m, its in ds.pool_items.items()
            if m in store.modalities
        }
        self.table_rows = {
            m: torch.tensor([table.rows[m][it] for it in ds.pool_items[m]])
            for m in self.cached
            if table is not None
        }

    def _pixels(
        self,
        m: Modality,
        picked: np.ndarray,
        aug_rng: np.random.Generator,
        view_rng: np.random.Generator,
        wall_rng: np.random.Generator,
    ) -> Tensor:
        """(B*k, C, S, S) images of picked pool indices (B, k), each one of its training views:
        the global batch's draws are made (so every process draws alike), this process's share
        is built."""
        n, k = picked.shape
        rows = self.store.draw_views(
            m, self.store_rows[m][torch.from_numpy(picked.reshape(-1))], view_rng
        )
        share = slice(self.lo * k, self.hi * k)
        x = self.store.drop_walls(m, rows, self.store.batch(m, rows[share]), wall_rng, share)
        aug = self.augmenters.get(m)
        if aug is not None:
            draws = aug.draw_batch(aug_rng, n * k, *self.store.shape(m))
            x = aug.apply_batch(x, draws[self.lo * k : self.hi * k])
        return x

    def __call__(self, step: int) -> dict[str, Any]:
        b = self.ds.draw_batch(np.random.default_rng([self.seed, step]), self.batch)
        aug_rng = np.random.default_rng([self.seed, step, 1])
        copy_rng = np.random.default_rng([self.seed, step, 2])
        view_rng = np.random.default_rng([self.seed, step, 3])
        wall_rng = np.random.default_rng([self.seed, step, 4])
        lo, hi = self.lo, self.hi
        inputs: dict[str, Tensor] = {}
        for j, slot in enumerate(self.ds.slots):
            m = slot_modality(slot)
            picked = b.items[j]  # (B, k) pool indices; k = presses if m.pooled (touch), else 1
            k = picked.shape[1]
            if m in self.cached:
                assert self.table is not None
                rows = self.table_rows[m][torch.from_numpy(picked[lo:hi].reshape(-1))]
                copies = None
                if self.table.has_copies(m):
                    drawn = copy_rng.integers(self.table.copies, size=picked.size)
                    copies = torch.from_numpy(drawn[lo * k : hi * k])
                f = self.table.gather_rows(m, rows, copies).unflatten(0, (hi - lo, k))
                inputs[slot] = f if m.pooled else f[:, 0]
                continue
            x = self._pixels(m, picked, aug_rng, view_rng, wall_rng)
            x = x.unflatten(0, (hi - lo, k)) if m.pooled else x
            if self.table is not None:  # cached run, live augmentation: trunk without grad
                with torch.no_grad(), autocast(self.device, precision=self.model.precision):
                    x = self.model.trunk({m.value: x})[m.value].float()
            elif self.channels_last:
                x = to_channels_last(x)
            inputs[slot] = x
        targets = self.ds.batch_targets(b.fabrics[lo:hi])
        dev = self.device
        return {
            "inputs": inputs,
            "y": torch.from_numpy(b.y[lo:hi]).to(dev, non_blocking=True),
            **{
                key: {s: v.to(dev, non_blocking=True) for s, v in per.items()}
                for key, per in targets.items()
            },
        }


@dataclass
class TrainRun:
    """What one optimisation step needs: the model (``net``: wrapped for DDP), the loss, the
    optimiser and schedule, and how the batch's inputs are to be read."""

    net: torch.nn.Module
    loss_fn: torch.nn.Module
    optimizer: torch.optim.Optimizer
    scheduler: torch.optim.lr_scheduler.LRScheduler
    device: torch.device
    dist: Distributed
    from_trunk: bool
    """The inputs are cached trunk features."""
    heads: bool
    """The model has auxiliary heads (cluster, property, classes) to train."""
    cluster: bool
    properties: bool
    classes: bool = False
    precision: Precision = "auto"
    """How the forward pass computes on CUDA (`ModelConfig.precision`)."""


def train_step(run: TrainRun, batch: Mapping[str, Any]) -> dict[str, Tensor]:
    """One optimisation step on ``batch`` (from `_Batches`, on the device).

    Returns:
        The loss terms, detached, on the device (reading them waits for the GPU: the loop
        reads them only at log steps).
    """
    run.optimizer.zero_grad(set_to_none=True)
    terms = _update(run, batch)
    run.scheduler.step()
    return terms


def _update(run: TrainRun, batch: Mapping[str, Any], cache: bool = True) -> dict[str, Tensor]:
    """Forward, loss, backward and the optimiser's update: what a CUDA graph captures."""
    with autocast(run.device, cache, run.precision):
        outputs = run.net(batch["inputs"], from_trunk=run.from_trunk, heads=run.heads)
    outputs = {k: v.float() for k, v in outputs.items()}  # the loss in fp32
    terms = run.loss_fn(
        outputs,
        y=batch["y"],
        fabric=batch["fabric_ids"],
        cluster=batch["clusters"] if run.cluster else None,
        properties=batch["properties"] if run.properties else None,
        classes=batch["classes"] if run.classes else None,
        # What the objective between slots is given (lookfeel.losses.TARGETS): every target,
        # whether or not the model has the heads above (an objective of one's own may use them).
        targets={
            "cluster": batch["clusters"],
            "properties": batch["properties"],
            "classes": batch["classes"],
        },
    )
    terms["loss"].backward()
    run.dist.reduce_extra_grads(run.loss_fn)
    run.optimizer.step()
    return {k: v.detach() for k, v in terms.items()}


def _tree_map(fn: Callable[..., Any], *trees: Any) -> Any:
    """``fn`` over the tensors of nested dicts of equal structure."""
    if isinstance(trees[0], Mapping):
        return {k: _tree_map(fn, *(t[k] for t in trees)) for k in trees[0]}
    return fn(*trees)


class GraphedStep:
    """`train_step` replayed from a CUDA graph (``train.cuda_graph``).

    The first ``warmup`` steps run eagerly on a side stream (real steps: they also give the
    optimiser its state and cuBLAS its workspaces); the next step is captured once, and from
    then on each step copies its batch into the captured input tensors and replays the graph.
    The batch's shapes must not change (they do not: the batch size and presses are fixed). The
    returned loss terms are the graph's own output tensors, overwritten by the next replay: the
    loop reads or adds them before the next step, in stream order.
    """

    def __init__(self, run: TrainRun, warmup: int = 3) -> None:
        for group in run.optimizer.param_groups:  # a captured step() must keep state on device
            group["capturable"] = True
        self.run = run
        self.warmup = warmup
        self.eager_steps = 0
        self.graph: torch.cuda.CUDAGraph | None = None
        self.inputs: Any = None
        self.outputs: dict[str, Tensor] = {}

    def __call__(self, batch: Mapping[str, Any]) -> dict[str, Tensor]:
        run = self.run
        if self.graph is None and self.eager_steps < self.warmup:
            side = torch.cuda.Stream(run.device)
            side.wait_stream(torch.cuda.current_stream(run.device))
            with torch.cuda.stream(side):
                terms = train_step(run, batch)
            torch.cuda.current_stream(run.device).wait_stream(side)
            self.eager_steps += 1
            return terms
        if self.graph is None:
            self.inputs = _tree_map(lambda x: x.clone(), dict(batch))
            run.optimizer.zero_grad(set_to_none=True)
            graph = torch.cuda.CUDAGraph()
            with torch.cuda.graph(graph):
                self.outputs = _update(run, self.inputs, cache=False)
            self.graph = graph
        else:
            _tree_map(lambda dst, src: dst.copy_(src, non_blocking=True), self.inputs, dict(batch))
        self.graph.replay()
        run.scheduler.step()
        return self.outputs


def _step_function(
    run: TrainRun, config: RunConfig
) -> Callable[[Mapping[str, Any]], dict[str, Tensor]]:
    """`train_step`, or a `GraphedStep` where ``train.cuda_graph`` can apply."""
    t = config.train
    if not t.cuda_graph:
        return lambda batch: train_step(run, batch)
    why = None
    if run.device.type != "cuda":
        why = "it needs CUDA"
    elif run.dist.world > 1:
        why = "it runs in one process only"
    elif t.lr_schedule != "constant" or t.warmup_steps:
        why = "the learning rate must be constant (a captured optimiser step keeps its lr)"
    if why is not None:
        if run.device.type == "cuda":
            warnings.warn(f"train.cuda_graph ignored: {why}", stacklevel=3)
        return lambda batch: train_step(run, batch)
    return GraphedStep(run)


# ---------------------------------------------------------------------------------------------
# Run directory, logs and resume


def _flatten(d: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    out: dict[str, Any] = {}
    for k, v in d.items():
        key = f"{prefix}{k}"
        if isinstance(v, Mapping):
            out |= _flatten(v, key + ".")
        else:
            out[key] = v
    return out


def config_changes(
    trained: RunConfig, asked: RunConfig, free: Iterable[str] = ()
) -> list[tuple[str, Any, Any]]:
    """``(key, trained value, asked value)`` for each setting, by its dotted key, in which
    ``asked`` differs from the run ``trained`` (what the run resolved from its labels counts as
    asked where ``asked`` leaves it to the labels: `as_trained`), the keys ``free`` aside;
    sorted by key. A resume (`_check_resume_config`) and ``lookfeel reproduce``'s reuse of a
    finished run both decide by it."""
    a, b = _flatten(to_dict(trained)), _flatten(to_dict(as_trained(asked, trained)))
    skip = set(free)
    keys = sorted(k for k in a.keys() | b.keys() if a.get(k) != b.get(k) and k not in skip)
    return [(k, a.get(k), b.get(k)) for k in keys]


def _check_resume_config(
    saved: dict[str, Any], given: RunConfig, path: Path, plugins: Iterable[object] = ()
) -> RunConfig:
    """The saved config, with a longer ``train.steps`` allowed, and where images are cached or
    how they are decoded (``data.cache_dir``, ``data.decode``, ``data.workers``: the same
    numbers), ``train.progress`` and ``train.threads`` taken from ``given``; any other change
    is an error (a thread count other than the run's is warned of when the run resumes).
    What the run resolved from its labels counts as given where the config leaves it to the
    labels (`as_trained`). ``model.pretrained`` may differ (the same file named from another
    folder, or no longer there): a resumed run takes every weight from its checkpoint. A saved
    config that does not load names the ``plugins`` it was trained with that are not loaded."""
    try:
        old = from_dict(RunConfig, saved)
    except ConfigError as e:  # a backbone or loss of a plugin this process lacks, say
        hint = trained_with_hint(plugins)
        raise ConfigError(f"{_RESUME}: {path}: the run's config does not load: {e}{hint}") from None
    # What cannot change a number: where images are cached, how they are decoded and by how
    # many workers (bit for bit the same, checked), and the progress bar.
    free = (
        "train.steps",
        "model.pretrained",
        "train.progress",
        "train.threads",
        "data.cache_dir",
        "data.decode",
        "data.workers",
    )
    changed = config_changes(old, given, free)
    if changed:
        raise ConfigError(
            f"{_RESUME}: the config differs from the run's ({path}) in "
            + ", ".join(f"{k} ({was!r} -> {now!r})" for k, was, now in changed[:6])
            + "; resume with the run's own config.yaml or start a new run"
        )
    data = replace(
        old.data,
        cache_dir=given.data.cache_dir,
        decode=given.data.decode,
        workers=given.data.workers,
    )
    train = replace(
        old.train,
        steps=given.train.steps,
        progress=given.train.progress,
        threads=given.train.threads,  # `_check_resume_threads` warns when the count differs
    )
    return replace(old, data=data, train=train)


def _check_resume_threads(state: Mapping[str, Any], device: torch.device, path: Path) -> None:
    """Warn when a CPU run resumes on another number of threads than it trained on: its sums
    round otherwise from there, so it no longer ends where an unbroken run would (the
    numbers of a whole run differ by thread count alike)."""
    saved, now = state.get("threads"), torch.get_num_threads()
    if device.type != "cpu" or saved is None or saved == now:
        return
    warnings.warn(
        f"{path}: the run trained on {saved} CPU thread(s) and resumes on {now}: from here it "
        f"rounds otherwise and will not end where an unbroken run would; for that, resume "
        f"with train.threads={saved} (--set train.threads={saved}) or OMP_NUM_THREADS={saved}",
        stacklevel=3,
    )


def _trim_log(path: Path, step: int) -> None:
    """Drop log lines past ``step`` (written after the checkpoint a resume starts from)."""
    if not path.exists():
        return
    keep = [
        line
        for line in path.read_text(encoding="utf-8").splitlines()
        if line and json.loads(line)["step"] <= step
    ]
    atomic_write_text(path, "".join(line + "\n" for line in keep))


def _say_unscored(val: Mapping[str, Any], key: str, stacklevel: int = 4) -> bool:
    """Warn, in one line, of the pairs a validation could not score and why (fewer than two
    held-out items per fabric), and when the pair that picks ``best.pt`` (``key``: its top-1)
    is one of them, that ``best.pt`` is not written: the run's checkpoint is ``last.pt``, as
    with ``train.split=none``. Returns whether there was anything to say."""
    unscored = {
        k.removesuffix("_not_scored"): v for k, v in val.items() if k.endswith("_not_scored")
    }
    if not unscored:
        return False
    text = "; ".join(f"{pair} not scored: {why}" for pair, why in unscored.items())
    primary = key.removesuffix("_top1")
    if primary in unscored:
        text += f"; best.pt is not written ({primary} picks it): use last.pt"
    warnings.warn(f"validation: {text}", stacklevel=stacklevel)
    return True


class _Log:
    """metrics.jsonl (and TensorBoard when it is installed), written by rank 0 only."""

    def __init__(self, run_dir: Path, enabled: bool) -> None:
        self.path = run_dir / "metrics.jsonl"
        self.enabled = enabled
        self.tb: Any = None
        if enabled:
            try:
                from torch.utils.tensorboard import SummaryWriter

                self.tb = SummaryWriter(str(run_dir / "tensorboard"))
            except Exception:  # tensorboard is optional
                self.tb = None

    def write(self, record: dict[str, Any]) -> None:
        """Append ``record`` as one line of JSON. NaN and infinity (a diverged loss) are written
        as ``null``: JSON has no such numbers, and readers choke on Python's bare ``NaN``."""
        if not self.enabled:
            return
        record = {
            k: None if isinstance(v, float) and not math.isfinite(v) else v
            for k, v in record.items()
        }
        with self.path.open("a", encoding="utf-8") as f:
            f.write(json.dumps(record, allow_nan=False) + "\n")
        if self.tb is not None:
            for k, v in record.items():
                if k != "step" and isinstance(v, (int, float)):
                    self.tb.add_scalar(k, v, record["step"])

    def close(self) -> None:
        if self.tb is not None:
            self.tb.close()


# ---------------------------------------------------------------------------------------------
# The entry point


def _keep_freed_memory() -> None:
    """Ask glibc to keep freed large blocks for reuse instead of returning them to the OS.

    Every step frees and reallocates the same large buffers (the fc7 gradients alone are 3 x 64
    MB); by default glibc unmaps each and the next step page-faults them back in, ~10% of a
    cached step of the paper's Multi-input Net on 2 cores. Peak memory is unchanged. A no-op
    where the C library is not glibc.

    Process-wide and for good: `train` cannot put it back, since glibc has no call that reads
    the setting it replaces (and setting it at all ends glibc's own adjusting of the
    thresholds). A process that trains and then needs its freed memory handed back can call
    ``mallopt`` itself (``M_TRIM_THRESHOLD``, ``M_MMAP_THRESHOLD``; glibc's defaults are
    128 KiB).
    """
    import ctypes
    import ctypes.util

    name = ctypes.util.find_library("c")
    if name is None:
        return
    try:
        mallopt = ctypes.CDLL(name).mallopt
    except (OSError, AttributeError):
        return
    m_trim_threshold, m_mmap_threshold = -1, -3
    mallopt(m_mmap_threshold, 1 << 30)
    mallopt(m_trim_threshold, 1 << 30)


def _adam(
    params: list[torch.nn.Parameter], lr: float, weight_decay: float
) -> torch.optim.Optimizer:
    """Adam (AdamW with weight decay), fused where this torch build has it: on 2 CPU cores the
    fused update of the paper's three fc7 layers (50M weights) is 7x faster than the default."""
    cls = torch.optim.AdamW if weight_decay else torch.optim.Adam
    try:
        return cls(params, lr=lr, weight_decay=weight_decay, fused=True)
    except (RuntimeError, TypeError, ValueError):
        return cls(params, lr=lr, weight_decay=weight_decay)


def _state_like_params(optimizer: torch.optim.Optimizer) -> None:
    """Lay each parameter's optimizer state out in memory as the parameter is (channels-last
    for the convolutions). A fused update walks both tensors' storage in one order, so a state
    saved in another layout (a checkpoint written before training went channels-last on every
    device) would silently update the wrong weights."""
    for p, s in optimizer.state.items():
        for k, v in s.items():
            if isinstance(v, torch.Tensor) and v.shape == p.shape and v.stride() != p.stride():
                s[k] = torch.empty_like(p, dtype=v.dtype).copy_(v)


def _lr_lambda(config: RunConfig) -> Callable[[int], float]:
    t = config.train

    def f(step: int) -> float:
        if t.warmup_steps and step < t.warmup_steps:
            return (step + 1) / t.warmup_steps
        if t.lr_schedule == "cosine":
            span = max(1, t.steps - t.warmup_steps)
            return 0.5 * (1 + math.cos(math.pi * min(1.0, (step - t.warmup_steps) / span)))
        return 1.0

    return f


def train(
    config: RunConfig,
    data: str | Path,
    out: str | Path,
    *,
    resume: bool = False,
    on_step: StepCallback | None = None,
    loader: ImageLoader | None = None,
) -> TrainResult:
    """Train a model on the dataset at ``data``, writing the run to ``out``.

    The caller's torch settings come back as they were when it returns or raises: the torch
    random number generators (the run seeds its own from ``train.seed``: the CPU's, and on
    CUDA its device's), the thread count (``train.threads``) and cuDNN's autotuner flag. One
    setting stays for the rest of the process: glibc is told to serve allocations under 1 GiB
    from its heap and to keep up to 1 GiB of freed memory there for reuse, rather than hand it
    back to the system at once (every step frees and reallocates the same large buffers,
    which would otherwise be unmapped and page-faulted back in: ~10% of a step on 2 cores;
    `_keep_freed_memory`). glibc cannot say what the setting was before, so it is not put
    back. NumPy's and Python's global generators are neither seeded nor drawn from.

    Example:
        >>> from lookfeel import RunConfig, load_config, load_model
        >>> from lookfeel.train import train
        >>> config = load_config(RunConfig, "configs/tiny.yaml", ["train.steps=200"])
        >>> result = train(config, "my_fabrics/", "runs/first")  # resume=True continues it
        >>> result.validation["touch_to_depth_top1"]  # held-out fabrics, as in metrics.jsonl
        >>> loaded = load_model(result.best_checkpoint or result.last_checkpoint)

    Args:
        config: the run's configuration.
        data: a dataset folder in the lookfeel layout.
        out: the run directory; must not hold a run unless ``resume``.
        resume: continue the run in ``out`` from ``checkpoints/last.pt`` (its saved config is
            used; only ``train.steps`` may grow). The result equals an unbroken run's. An
            ensemble (``model.members`` > 1) keeps its finished members and resumes the others.
        on_step: called after every step with (steps done, that step's loss terms); an
            ensemble calls it through each member's run in turn.
        loader: an `ImageLoader` of ``config.data`` whose decoded images to reuse (an
            ensemble's members share one); default: a new one.

    Raises:
        DatasetError: the data cannot serve this run (every problem listed).
        ConfigError: a config key is wrong, or ``resume`` with a different config.
        DeviceError: ``train.device=cuda`` where this PyTorch or machine has no CUDA.
        TrainingDiverged: the loss or the weights became NaN or infinite (the message names
            the steps and the last finite checkpoint, which is kept).
    """
    run_dir = Path(out)
    if loader is not None and loader.config != config.data:
        raise ValueError("train: the loader given must be of this run's data config")
    # Images smaller than the backbone takes are refused here, before any data is read, not
    # after the data are loaded; each backbone class knows its own minimum.
    config.check_input_sizes(BACKBONES[config.model.backbone].min_size)
    with _callers_torch_state(), _run_folder(run_dir):
        if config.model.members > 1:
            return _train_members(config, Path(data), run_dir, resume, on_step, loader)
        last = run_dir / "checkpoints" / "last.pt"
        state: dict[str, Any] | None = None
        if resume:
            # A run stopped while writing its first last.pt may hold best.pt of the same
            # step (written just before): a whole state, resumed from as last.pt would be.
            source = resume_checkpoint(run_dir)
            if source is None:
                raise ConfigError(
                    f"{_RESUME}: no checkpoint at {last} to resume from (the run stopped before "
                    "its first one): start it again without --resume"
                )
            state = read_checkpoint(source)
            config = _check_resume_config(
                state["config"], config, source, state.get("plugins") or ()
            )
            for path in (last, run_dir / "config.yaml"):  # before the work, not at its end
                check_writable(path)
        elif (held := resume_checkpoint(run_dir)) is not None:
            raise ConfigError(f"{run_dir} already holds a run ({held}); {_ELSEWHERE}")
        dist = Distributed.from_env(config.train.device)
        try:
            with _callers_cuda_rng(dist.device):
                result = _train(config, Path(data), run_dir, state, dist, on_step, loader)
        except BaseException:
            dist.close()  # no barrier: the other processes may be gone
            raise
        dist.close(sync=True)
        return result


@contextmanager
def _run_folder(run_dir: Path) -> Iterator[None]:
    """Hold the run folder while a run trains in it, and give it back as found when the run
    fails before it has a checkpoint.

    One training at a time per run folder (`lookfeel.locks.exclusive`: a second process is
    refused, naming the first's PID); under torchrun the first process holds it for all, and
    alone tidies up (it alone writes the run).

    A run that fails (an error, Ctrl-C) while the folder holds no checkpoint (`run_started`)
    has nothing to resume from, yet its config.yaml and split.json would make the folder look
    like a run. So what this call created goes: the run's own files (`_OWN_FILES`) that did
    not exist when it began, then the folders it made (the run folder and the missing ones
    above it, ``checkpoints``, ...) where they are empty. A file that was there before is
    kept, and so is any file of the user's. Once a checkpoint exists, everything is kept, to
    resume from (a run killed during training resumes as before).
    """
    if int(os.environ.get("RANK", "0")) != 0:
        yield
        return
    missing: list[Path] = []  # the run folder and those above it that do not exist: deepest first
    for folder in (run_dir, *run_dir.parents):
        if folder.exists() or folder.is_symlink():
            break
        missing.append(folder)
    made: list[Path] = []  # of ``missing``, to remove once the lock file beside them is gone
    try:
        with exclusive(run_dir, "train", "this run"):
            before = _own_files(run_dir)
            try:
                yield
            except BaseException:
                if not run_started(run_dir):
                    new = _own_files(run_dir) - before
                    made = missing
                    for path in sorted(new, key=lambda p: len(p.parts), reverse=True):
                        _remove_if_own(path)
                raise
    finally:
        for folder in made:  # deepest first; the lock file beside the run folder is gone now
            try:
                folder.rmdir()
            except FileNotFoundError:  # an ensemble member's run removed it already
                continue
            except OSError:  # not empty: someone else's files are in it, so keep it and above
                break


_OWN_FILES = ("config.yaml", "split.json", "metrics.jsonl", "checkpoints", "tensorboard")
"""What a run writes in its folder before its first checkpoint (and the folders its
checkpoints and TensorBoard's event files go into; an ensemble's ``members`` too)."""


def _own_files(run_dir: Path) -> set[Path]:
    """Those of `_OWN_FILES` (and ``members``, TensorBoard's event files) in ``run_dir`` now."""
    paths = [run_dir / name for name in (*_OWN_FILES, MEMBERS)]
    paths += (run_dir / "tensorboard").glob("events.out.tfevents.*")
    return {p for p in paths if p.exists() or p.is_symlink()}


def _remove_if_own(path: Path) -> None:
    """Remove a file this run wrote, or a folder it made once it is empty (one that holds
    anything else is kept)."""
    if path.is_dir() and not path.is_symlink():
        with suppress(OSError):  # not empty: kept
            path.rmdir()
    else:
        path.unlink(missing_ok=True)


_RESUME = "--resume (resume=True)"
"""How the CLI flag and the Python argument that resume a run are named in errors."""
_ELSEWHERE = f"pass {_RESUME} to continue it, or choose another --out (out=...)"
"""What an error about a run already in the out directory suggests."""


@contextmanager
def _callers_torch_state() -> Iterator[None]:
    """Give the caller back the process-wide torch settings a run changes: the CPU random
    generator's state (the run seeds it, draws its initial weights and dropout from it), the
    thread count (``train.threads``) and cuDNN's autotuner flag (on CUDA the run turns it on
    for its fixed shapes; an evaluation's batches of every size, the caller's own code, get
    the caller's setting back)."""
    rng = torch.get_rng_state()
    threads = torch.get_num_threads()
    benchmark = torch.backends.cudnn.benchmark
    try:
        yield
    finally:
        torch.set_rng_state(rng)
        if torch.get_num_threads() != threads:
            torch.set_num_threads(threads)
        torch.backends.cudnn.benchmark = benchmark


@contextmanager
def _callers_cuda_rng(device: torch.device) -> Iterator[None]:
    """On a CUDA ``device``, give the caller back its random generator's state (the run seeds
    it: dropout on the GPU draws from it). Nothing on another device: the run then touches no
    CUDA generator."""
    if device.type != "cuda":
        yield
        return
    rng = torch.cuda.get_rng_state(device)
    try:
        yield
    finally:
        torch.cuda.set_rng_state(rng, device)


def resume_checkpoint(out: str | Path) -> Path | None:
    """The checkpoint a run in ``out`` resumes from: ``checkpoints/last.pt``, or where a run was
    stopped while writing its first one, the ``best.pt`` written just before it (of that
    same step, a whole state); None when it has neither."""
    for name in ("last.pt", "best.pt"):
        if (path := Path(out) / "checkpoints" / name).is_file():
            return path
    return None


def run_started(out: str | Path) -> bool:
    """Whether ``out`` holds a run to resume (`resume_checkpoint`), or an ensemble's member
    does."""
    run_dir = Path(out)
    members = sorted(run_dir.glob(f"{MEMBERS}/*")) if (run_dir / MEMBERS).is_dir() else []
    return any(resume_checkpoint(d) is not None for d in [run_dir, *members])


MEMBERS = "members"
"""Folder of an ensemble run (``model.members`` > 1) that holds one ordinary run per member."""


def member_config(config: RunConfig, k: int) -> RunConfig:
    """The run config of ensemble member ``k``: one network (``model.members: 1``), and its own
    seed (member 0 keeps ``train.seed``; member k > 0 a seed drawn from (seed, k), so members
    of runs with neighbouring seeds never coincide)."""
    t = config.train
    seed = t.seed if k == 0 else int(np.random.SeedSequence([t.seed, k]).generate_state(1)[0] >> 1)
    return replace(config, model=replace(config.model, members=1), train=replace(t, seed=seed))


def _train_members(
    config: RunConfig,
    data: Path,
    run_dir: Path,
    resume: bool,
    on_step: StepCallback | None,
    loader: ImageLoader | None,
) -> TrainResult:
    """Train an ensemble: each member as an ordinary run in ``run_dir/members/k``, one after
    the other (a finished member is kept on resume), then one checkpoint holding them all."""
    n = config.model.members
    if run_started(run_dir) and not resume:
        raise ConfigError(f"{run_dir} already holds a run; {_ELSEWHERE}")
    if resume and not run_started(run_dir):
        raise ConfigError(
            f"{_RESUME}: no run in {run_dir} to resume from: start it without --resume"
        )
    loader = loader if loader is not None else ImageLoader(config.data)  # decoded once for all
    paths = []
    for k in range(n):
        cfg = member_config(config, k)
        member_dir = run_dir / MEMBERS / str(k)
        last = member_dir / "checkpoints" / "last.pt"
        started = last.exists()
        if not (started and int(read_checkpoint(last)["step"]) >= cfg.train.steps):
            train(cfg, data, member_dir, resume=started, on_step=on_step, loader=loader)
        paths.append(last)
    states = [read_checkpoint(p) for p in paths]
    first = from_dict(RunConfig, states[0]["config"])  # as trained: its classes resolved
    merged = replace(
        first,
        model=replace(first.model, members=n),
        train=replace(first.train, seed=config.train.seed),
    )
    modalities = [Modality(m) for m in states[0]["modalities"]]
    channels = first.data.touch_channels
    model = create_model(merged.model, modalities, load_weights=False, touch_channels=channels)
    for k, state in enumerate(states):
        part = create_model(first.model, modalities, load_weights=False, touch_channels=channels)
        part.load_state_dict(state["model"])
        for m in modalities:
            ensemble = model.branch(m.value)
            assert isinstance(ensemble, BranchEnsemble)
            ensemble.member_branches()[k].load_state_dict(part.branch(m.value).state_dict())
    validation: dict[str, Any] = {}
    if merged.train.split != "none":  # the ensemble on the members' validation fabrics
        catalog = drop_unpressed(scan(data, require=modalities, strict=True), loader)
        _, val_cat, _ = select_split(_with_clusters(catalog, merged), merged)
        if val_cat is not None:
            items = {m: val_cat.items(m, merged.data.touch_kinds) for m in modalities}
            device = torch.device("cpu")
            validation = validate(
                model,
                items,
                loader,
                None,
                merged.train.feature_batch,
                device,
                merged.train.val_pairs,
            )
            validation.pop("primary_pair", None)
    last = run_dir / "checkpoints" / "last.pt"
    if int(os.environ.get("RANK", "0")) == 0:  # under torchrun: one process writes
        run_dir.mkdir(parents=True, exist_ok=True)
        save_config(merged, run_dir / "config.yaml")
        atomic_write_text(run_dir / "split.json", json.dumps(states[0]["split"], indent=1) + "\n")
        keep = (
            "step",
            "modalities",
            "label_columns",
            "label_stats",
            "split",
            "touch_input",
            "data_fingerprint",
            "software",
            "plugins",
            "rank_columns",
            "shapes",
            "grey_presses",
        )
        save_checkpoint(
            last,
            {k: states[0][k] for k in keep if k in states[0]}
            | {"config": to_dict(merged), "model": model.state_dict()},
        )
    return TrainResult(
        run_dir=run_dir,
        steps=config.train.steps,
        last_checkpoint=last,
        best_checkpoint=None,
        validation=validation,
    )


@dataclass
class _RunData:
    """What `_prepare_data` read: the run's config (its class and property heads fitted to
    the data), the dataset and its split, the training tuples and the validation items."""

    config: RunConfig
    catalog: Catalog
    """Every fabric the run reads (k-means clusters where labels.csv has none)."""
    train_cat: Catalog
    val_cat: Catalog | None
    split_info: dict[str, Any]
    """What ``split.json`` records."""
    ds: TupleDataset
    val_items: dict[Modality, list[Item]]
    data_fingerprint: str
    """The files as `evaluate` scans them (checked on resume, kept in the checkpoint)."""


def _prepare_data(
    config: RunConfig,
    data: Path,
    state: dict[str, Any] | None,
    loader: ImageLoader,
    cached: bool,
    resumed_from: Path,
) -> _RunData:
    """Scan ``data``, check a resumed run's fingerprint, leave out the videos that hold no
    press, fit the heads to the labels, split off the validation fabrics, and build the
    training tuples; the images they read are decoded here (``loader.preload``)."""
    t = config.train
    modalities = t.modalities
    # A live run trains on the press videos' views: decode them once, while finding the presses.
    scanned = _scan_for(data, config)
    # The files as `evaluate` scans them: before k-means clusters, and before the videos that
    # hold no press are left out (which evaluate finds after it compares the two).
    data_fingerprint = scanned.fingerprint()
    trained_on = state.get("data_fingerprint") if state is not None else None
    other_data = ConfigError(
        f"{_RESUME}: {resumed_from} was trained on another dataset than {data}, or on this "
        "one before its files or labels changed: resume it with the data it trained on, or "
        "start a new run in another --out"
    )
    # Refused before any video is decoded: a checkpoint that records its software (session 53
    # on) took the fingerprint before the drop; an older one after it (checked below).
    if (
        trained_on is not None
        and state is not None
        and "software" in state
        and not scanned.matches_fingerprint(trained_on)
    ):
        raise other_data
    catalog = drop_unpressed(scanned, loader, views=not cached)
    if trained_on is not None and not any(
        c.matches_fingerprint(trained_on) for c in (scanned, catalog)
    ):
        raise other_data
    _say_reprints(catalog, loader, config, cached, data)
    catalog = _with_clusters(catalog, config)
    config = resolve_properties(catalog, resolve_classes(catalog, config))
    train_cat, val_cat, split_info = select_split(catalog, config)
    ds = TupleDataset(
        train_cat,
        loader,
        t.views,
        length=t.steps * t.batch_size,
        seed=t.seed,
        classes=config.model.classes,
    )
    val_items: dict[Modality, list[Item]] = {}
    if val_cat is not None:
        val_items = {m: val_cat.items(m, config.data.touch_kinds) for m in modalities}
    # What the store below reads: each training item's views (its image among them) when it
    # draws views, else its image (with a wall band a registered drape's views hold the
    # unbanded image: its banded one is never read in training, so it is not made);
    # validation embeds images.
    loader.preload(ds.items(), views=not cached)
    loader.preload([it for v in val_items.values() for it in v])
    return _RunData(
        config, catalog, train_cat, val_cat, split_info, ds, val_items, data_fingerprint
    )


def _build_optimisation(
    config: RunConfig, state: dict[str, Any] | None, device: torch.device
) -> tuple[Embedder, CombinedLoss, torch.optim.Optimizer, torch.optim.lr_scheduler.LambdaLR]:
    """Seed the run's generators, then build its model (on ``device``), loss, optimiser and
    learning-rate schedule; a resumed run's weights come from ``state`` later
    (`_resume_from`), so no pretrained file is read for it."""
    t = config.train
    # The generators the run draws from, and no other (`torch.manual_seed` would also seed
    # every CUDA device, or queue that for when CUDA starts, on a CPU run): the CPU's (initial
    # weights; dropout on the CPU) and the training device's (dropout on a GPU).
    torch.default_generator.manual_seed(t.seed)
    if device.type == "cuda":
        with torch.cuda.device(device):
            torch.cuda.manual_seed(t.seed)
    # A resumed run's weights all come from its checkpoint: its pretrained file is not read.
    model = create_model(
        config.model,
        t.modalities,
        load_weights=state is None,
        touch_channels=config.data.touch_channels,
    )
    if state is None and config.model.init_from is not None:
        fresh = init_from_checkpoint(model, config.model.init_from)
        if fresh:
            warnings.warn(
                f"model.init_from: copied {len(model.state_dict()) - len(fresh)} of "
                f"{len(model.state_dict())} tensors from {config.model.init_from}; "
                f"{len(fresh)} start fresh (e.g. {', '.join(fresh[:3])})",
                stacklevel=4,
            )
    model = model.to(device)
    if device.type == "cuda":
        torch.backends.cudnn.benchmark = True  # fixed shapes: let cuDNN pick its fastest
    if t.channels_last:  # on every device (`TrainConfig.channels_last`)
        model = model.to(memory_format=torch.channels_last)  # type: ignore[call-overload, unused-ignore]
    loss_fn = create_loss(config.loss, config.model.class_sizes).to(device)
    params = [*model.trainable_parameters(), *(p for p in loss_fn.parameters() if p.requires_grad)]
    optimizer = _adam(params, t.lr, t.weight_decay)
    scheduler = torch.optim.lr_scheduler.LambdaLR(optimizer, _lr_lambda(config))
    return model, loss_fn, optimizer, scheduler


def _build_inputs(
    config: RunConfig,
    rd: _RunData,
    loader: ImageLoader,
    model: Embedder,
    dist: Distributed,
    cached: bool,
) -> tuple[FeatureTable | None, _Batches]:
    """The images on the device (`ImageStore`), with a frozen trunk its features of them
    (`FeatureTable`, ``cached``), and the batches drawn from them (`_Batches`)."""
    t = config.train
    ds, device = rd.ds, dist.device
    table_items = {
        m: [*dict.fromkeys([*ds.pool_items[m], *rd.val_items.get(m, [])])] for m in t.modalities
    }
    store = ImageStore(
        loader,
        [it for its in table_items.values() for it in its] if cached else ds.items(),
        device,
        views=not cached,
    )
    table: FeatureTable | None = None
    if cached:
        table = FeatureTable(
            model,
            store,
            table_items,
            config.data.augment,
            t.augment_copies,
            seed=t.seed,
            batch_size=t.feature_batch,
            device=device,
            rank=dist.rank,
            world=dist.world,
        )
    batches = _Batches(ds, store, table, model, config, device, dist.rank, dist.world)
    return table, batches


def _resume_from(
    state: dict[str, Any] | None,
    model: Embedder,
    loss_fn: CombinedLoss,
    optimizer: torch.optim.Optimizer,
    scheduler: torch.optim.lr_scheduler.LambdaLR,
) -> tuple[int, float]:
    """Load a resumed run's weights and optimiser state from ``state``: (the step to start
    from, the best validation score so far); a new run's (0, -inf)."""
    if state is None:
        return 0, -math.inf
    model.load_state_dict(state["model"])
    optimizer.load_state_dict(state["optimizer"])
    _state_like_params(optimizer)
    scheduler.load_state_dict(state["scheduler"])
    loss_fn.load_state_dict(state["loss"])
    return int(state["step"]), float(state.get("best", -math.inf))


def _checkpoint_metadata(rd: _RunData, loader: ImageLoader) -> dict[str, Any]:
    """What every checkpoint of the run records beside its weights, for the commands that
    read it (`predict`, `match`, `evaluate`, ``--resume``): read once, before the first step."""
    config = rd.config
    modalities = config.train.modalities
    train_cat, catalog, kinds = rd.train_cat, rd.catalog, config.data.touch_kinds
    # What a touch query must be to be read as training read its presses (predict, match and
    # serve refuse a still frame for a model trained on press videos).
    touch_input = (
        touch_input_of(it.path for it in train_cat.items(Modality.TOUCH, kinds))
        if Modality.TOUCH in modalities
        else None
    )

    # The shape of each modality's training items (their one orientation and most common
    # size, read from file headers once, here): `predict` warns of a query turned against them.
    shapes: dict[str, dict[str, Any]] = {}
    for m in modalities:
        paths = [it.path for it in train_cat.items(m, kinds)]
        if (shape := shape_record(paths, m, config.data)) is not None:
            shapes[m.value] = shape

    # Whether the training press videos were grey (no colour), as the loader read them above
    # (nothing is decoded again): `predict` and `match` warn of a query video of the other kind.
    grey_presses = None
    if Modality.TOUCH in modalities:
        presses = train_cat.items(Modality.TOUCH, kinds)
        videos = dict.fromkeys(p for p in map(loader.frame_path, presses) if is_video(p))
        grey_presses = grey_presses_of(loader.is_grey(p) for p in videos)

    # The ranks each column of ranks holds (hardness 0/1/2): `predict` reads the property
    # head's number for one as the nearest rank.
    rank_columns = {
        c: sorted({int(f.labels[c]) for f in catalog.fabrics if c in f.labels})
        for c in catalog.rank_columns
        if c in catalog.label_columns
    }
    software = software_versions()
    plugins = plugin_modules_of(config.model.backbone, config.loss.kind)
    return {
        "touch_input": touch_input,
        "data_fingerprint": rd.data_fingerprint,
        "software": software,
        "plugins": plugins,
        "config": to_dict(config),
        "modalities": [m.value for m in modalities],
        "label_columns": list(catalog.label_columns),
        "label_stats": {
            c: [float(rd.ds.label_mean[i]), float(rd.ds.label_std[i])]
            for i, c in enumerate(catalog.label_columns)
        },
        "rank_columns": rank_columns,
        "shapes": shapes,
        "grey_presses": grey_presses,
        "split": rd.split_info,
    }


def _train(
    config: RunConfig,
    data: Path,
    run_dir: Path,
    state: dict[str, Any] | None,
    dist: Distributed,
    on_step: StepCallback | None,
    loader: ImageLoader | None = None,
) -> TrainResult:
    """One run (`train`'s steps 1-6, docs/ARCHITECTURE.md): the data (`_prepare_data`), the
    model and its optimiser (`_build_optimisation`), the batches (`_build_inputs`), a resumed
    run's state (`_resume_from`), then the steps, logging, validating and checkpointing."""
    t = config.train
    last = run_dir / "checkpoints" / "last.pt"
    resumed_from = resume_checkpoint(run_dir) or last  # a resume's: where ``state`` was read
    if dist.is_main:  # what a kill mid-write left (one process writes a run's checkpoints)
        for name in ("last.pt", "best.pt"):
            remove_stale_temps(last.parent / name)
    if t.batch_size % dist.world:
        raise ConfigError(
            f"train.batch_size={t.batch_size} must divide evenly over {dist.world} processes"
        )
    if t.threads:
        torch.set_num_threads(t.threads)
    _keep_freed_memory()
    device = dist.device

    loader = loader if loader is not None else ImageLoader(config.data)
    cached = t.cache_trunk and config.model.resolved_freeze != "none"
    rd = _prepare_data(config, data, state, loader, cached, resumed_from)
    config, val_cat, val_items = rd.config, rd.val_cat, rd.val_items
    model, loss_fn, optimizer, scheduler = _build_optimisation(config, state, device)

    started = time.perf_counter()
    table, batches = _build_inputs(config, rd, loader, model, dist, cached)
    cache_s = time.perf_counter() - started
    start_step, best = _resume_from(state, model, loss_fn, optimizer, scheduler)

    log = _Log(run_dir, dist.is_main)
    if dist.is_main:
        run_dir.mkdir(parents=True, exist_ok=True)
        save_config(config, run_dir / "config.yaml")
        atomic_write_text(run_dir / "split.json", json.dumps(rd.split_info, indent=1) + "\n")
        if state is None:
            log.path.unlink(missing_ok=True)
            if cached and table is not None:
                log.write(
                    {
                        "step": 0,
                        "trunk_cache_s": round(cache_s, 2),
                        "trunk_cache_mb": round(table.nbytes() / 2**20, 1),
                    }
                )
        else:
            _trim_log(log.path, start_step)
    if state is not None:  # after every set-up draw: dropout resumes exactly
        _check_resume_threads(state, device, resumed_from)
        torch.set_rng_state(state["rng"])
        if device.type == "cuda" and state.get("cuda_rng") is not None:
            torch.cuda.set_rng_state(state["cuda_rng"], device)
    net = dist.wrap(model)
    run = TrainRun(
        net=net,
        loss_fn=loss_fn,
        optimizer=optimizer,
        scheduler=scheduler,
        device=device,
        dist=dist,
        from_trunk=cached,
        heads=bool(
            config.model.cluster_head or config.model.num_properties or config.model.class_heads
        ),
        cluster=bool(config.model.cluster_head),
        properties=bool(config.model.num_properties),
        classes=bool(config.model.class_heads),
        precision=config.model.precision,
    )
    metadata = _checkpoint_metadata(rd, loader)
    # A plugin's loss (not lookfeel's) is named first when a run diverges in its terms.
    own_loss = None if loss_fn.pair_loss.__module__.startswith("lookfeel.") else config.loss.kind
    loop = _Loop(
        config=config,
        run_dir=run_dir,
        run=run,
        model=model,
        batches=batches,
        log=log,
        loader=loader,
        table=table,
        val_cat=val_cat,
        val_items=val_items,
        metadata=metadata,
        own_loss=own_loss,
        on_step=on_step,
        start_step=start_step,
        best=best,
        resumed_from=resumed_from if state is not None else None,
    )
    model.train()
    step_fn = _step_function(run, config)
    return loop.run(step_fn)


class _Loop:
    """The steps of one run (the end of `_train`) and what they carry from one to the next:
    the loss terms summed over the log window (``sums``), the checkpoints on disk with finite
    weights (``kept``: what a diverged run keeps and names), the last step whose loss was read
    and found finite (``checked``), and the best validation score (``best``, ``best.pt``'s).

    `step` is one step: draw its batch, update, and on the steps the config says, log the
    window's mean loss terms, check they are finite, validate and write checkpoints (`save`);
    `stop` is the `TrainingDiverged` that ends a run whose loss or weights are not finite.
    """

    def __init__(
        self,
        *,
        config: RunConfig,
        run_dir: Path,
        run: TrainRun,
        model: Embedder,
        batches: _Batches,
        log: _Log,
        loader: ImageLoader,
        table: FeatureTable | None,
        val_cat: Catalog | None,
        val_items: dict[Modality, list[Item]],
        metadata: dict[str, Any],
        own_loss: str | None,
        on_step: StepCallback | None,
        start_step: int,
        best: float,
        resumed_from: Path | None,
    ) -> None:
        self.config, self.t, self.run_dir = config, config.train, run_dir
        self.train_run, self.model, self.batches, self.log = run, model, batches, log
        self.dist, self.device = run.dist, run.device
        self.loader, self.table = loader, table
        self.val_cat, self.val_items = val_cat, val_items
        self.metadata, self.own_loss, self.on_step = metadata, own_loss, on_step
        self.start_step, self.best = start_step, best
        self.last = run_dir / "checkpoints" / "last.pt"
        t = self.t
        self.progress = None
        if self.dist.is_main and shown(t.progress):  # on a terminal (`lookfeel.progress`)
            self.progress = bar(
                total=t.steps,
                initial=start_step,
                desc="train",
                unit="step",
                dynamic_ncols=True,
                leave=True,
            )
        self.last_val: dict[str, Any] = {}
        self.said_unscored = False
        self.sums: dict[str, Tensor] = {}  # loss terms summed over the log window, on the device
        self.window_start, self.window_steps = time.perf_counter(), 0
        # Checkpoints on disk with finite weights (what a diverged run keeps), and the last step
        # whose loss was read and found finite.
        self.kept: dict[Path, int] = {}
        if resumed_from is not None:
            self.kept[resumed_from] = start_step
        self.checked = start_step

    def checkpoint_state(self, step: int) -> dict[str, Any]:
        """What a checkpoint of step ``step`` holds: the run's metadata, its weights and every
        state a resume needs to continue as an unbroken run would."""
        run, device = self.train_run, self.device
        return {
            "step": step,
            **self.metadata,
            "model": self.model.state_dict(),
            "optimizer": run.optimizer.state_dict(),
            "scheduler": run.scheduler.state_dict(),
            "loss": run.loss_fn.state_dict(),
            "rng": torch.get_rng_state(),
            "cuda_rng": torch.cuda.get_rng_state(device) if device.type == "cuda" else None,
            "threads": torch.get_num_threads(),  # a CPU run's sums round by its thread count
            "best": self.best,
        }

    def stop(
        self, what: str, value: float, done: int, terms: Sequence[str] = ()
    ) -> TrainingDiverged:
        """The error that ends a diverged run (``what`` became ``value`` by step ``done``),
        naming the checkpoints kept; the progress bar and the log are closed first."""
        if self.progress is not None:
            self.progress.close()
        self.log.close()
        t = self.t
        return diverged(
            what,
            value,
            self.checked + 1,
            done,
            t.lr,
            self.kept,
            t.checkpoint_every,
            terms,
            self.own_loss,
        )

    def save(self, path: Path, done: int, chosen_by: str | None = None) -> None:
        """Write a checkpoint of step ``done``, never one of non-finite weights (at ``last.pt``
        every process checks: their weights are equal, so all stop together); ``chosen_by``:
        the validation score ``best.pt`` was chosen by, recorded in it (`LoadedModel.chosen_by`:
        `lookfeel evaluate` then says when it scores the fabrics it was chosen on)."""
        if non_finite_tensors(self.model.state_dict()):
            raise self.stop("weights", math.nan, done)
        if self.dist.is_main:
            state = self.checkpoint_state(done)
            if chosen_by is not None:
                state["chosen_by"] = chosen_by
            save_checkpoint(path, state)
            self.kept[path] = done

    def run(self, step_fn: Callable[[Mapping[str, Any]], dict[str, Tensor]]) -> TrainResult:
        """Every step from ``start_step`` to ``train.steps`` (`step`), then the run's result."""
        t = self.t
        for step in range(self.start_step, t.steps):
            self.step(step, step_fn)
        if self.progress is not None:
            self.progress.close()
        self.log.close()
        best_path = self.run_dir / "checkpoints" / "best.pt"
        return TrainResult(
            run_dir=self.run_dir,
            steps=t.steps,
            last_checkpoint=self.last,
            best_checkpoint=best_path if best_path.exists() else None,
            validation={k: v for k, v in self.last_val.items() if k != "primary_pair"},
        )

    def step(self, step: int, step_fn: Callable[[Mapping[str, Any]], dict[str, Tensor]]) -> None:
        """Step ``step`` (0-based): update, then log, check, validate and save as due."""
        t, dist, sums = self.t, self.dist, self.sums
        terms = step_fn(self.batches(step))
        for k, v in terms.items():
            sums[k] = sums[k] + v.double() if k in sums else v.double()
        self.window_steps += 1
        done = step + 1
        if self.on_step is not None:  # per-step values: one device sync a step
            self.on_step(done, dist.mean_values({k: float(v) for k, v in terms.items()}))
        if self.progress is not None:
            self.progress.update(1)
            if done % 10 == 0 or done == t.steps:
                self.progress.set_postfix(loss=f"{float(terms['loss']):.4f}")
        is_log = done % max(t.log_every, 1) == 0 or done == t.steps
        is_val = self.val_cat is not None and bool(
            (t.val_every and done % t.val_every == 0) or done == t.steps
        )
        is_save = bool(t.checkpoint_every and done % t.checkpoint_every == 0) or done == t.steps
        loss: float | None = None
        read: Mapping[str, Tensor | float] = {}  # the terms read with the loss
        if is_log:
            means = dist.mean_values({k: float(v) / self.window_steps for k, v in sums.items()})
            elapsed = time.perf_counter() - self.window_start
            record: dict[str, Any] = {"step": done, **means}
            record["lr"] = self.train_run.scheduler.get_last_lr()[0]
            record["steps_per_s"] = self.window_steps / elapsed if elapsed > 0 else None
            self.log.write(record)
            read, self.sums, self.window_start, self.window_steps = (
                means,
                {},
                time.perf_counter(),
                0,
            )
            loss = means["loss"]
        elif is_val or is_save:  # the device syncs here anyway
            loss = dist.mean_values({"loss": float(sums["loss"])})["loss"]
            read = sums
        if loss is not None:
            if not math.isfinite(loss):  # name the terms (read now: the run stops anyway)
                bad = [k for k, v in read.items() if k != "loss" and not math.isfinite(float(v))]
                raise self.stop("loss", loss, done, bad)
            self.checked = done
        if is_val:
            if dist.is_main:
                self.validate(done)
            dist.barrier()
        if is_save:
            self.save(self.last, done)
            dist.barrier()

    def validate(self, done: int) -> None:
        """Validate after step ``done`` (the main process), log it, and write ``best.pt`` when
        the primary pair's top-1 beats the best so far."""
        t, device, model = self.t, self.device, self.model
        with autocast(device, precision=model.precision):
            try:
                self.last_val = validate(
                    model,
                    self.val_items,
                    self.loader,
                    self.table,
                    t.feature_batch,
                    device,
                    t.val_pairs,
                )
            except EmbeddingError:  # a finite loss, but held-out items overflow
                raise self.stop("validation embeddings", math.nan, done) from None
        last_val = self.last_val
        key = f"{last_val.get('primary_pair')}_top1"
        self.log.write(
            {
                "step": done,
                **{f"val/{k}": v for k, v in last_val.items() if k != "primary_pair"},
            }
        )
        if not self.said_unscored:  # the same pairs at every validation: say it once
            # stacklevel: past validate, step, run, _train and train, to train()'s caller
            self.said_unscored = _say_unscored(last_val, key, stacklevel=7)
        if key in last_val and last_val[key] > self.best:
            self.best = last_val[key]
            self.save(self.run_dir / "checkpoints" / "best.pt", done, chosen_by=f"val/{key}")
