"""Training and evaluation datasets over a `Catalog`.

`TupleDataset` draws the paper's training tuples: one item per slot (a slot is a modality;
the Siamese net has two depth slots), all from one fabric (Y = 0) or each from a different
fabric (Y = 1), at a configured ratio (paper section 4, equation 2). A touch slot holds P
presses of its fabric (the Multi-input Net). Every draw is seeded by (seed, index), so a tuple
does not depend on worker processes, batch order or a resumed run.

Training draws a step's tuples at once with `TupleDataset.draw_batch` (a few vectorised numpy
calls) and builds the batch on the device (`lookfeel.train.loop`); ``ds[i]`` builds one
tuple's tensors on the CPU (tuple ``i`` is a batch of one drawn from ``(seed, i)``).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch
from torch.utils.data import Dataset

from lookfeel.config import AugmentConfig, DataConfig
from lookfeel.data.augment import Augmenter
from lookfeel.data.catalog import Catalog, Fabric, Item
from lookfeel.data.images import ImageLoader
from lookfeel.data.problems import DatasetError
from lookfeel.losses.cluster import UNKNOWN_CLUSTER
from lookfeel.modality import Modality, PressKind, slot_modality, slot_names

__all__ = ["TupleBatch", "TupleDataset", "class_matrix"]


def class_matrix(fabrics: Sequence[Fabric], classes: Mapping[str, Sequence[str]]) -> np.ndarray:
    """(F, H) int64: each fabric's class index in each ``classes`` column, -1 where unknown
    (or a class the list does not name)."""
    out = np.full((len(fabrics), len(classes)), -1, np.int64)
    for h, (col, names) in enumerate(classes.items()):
        index = {n: i for i, n in enumerate(names)}
        for r, f in enumerate(fabrics):
            k = f.class_of(col)
            if k is not None:
                out[r, h] = index.get(k, -1)
    return out


def _labels_vector(values: dict[str, float], columns: Sequence[str]) -> torch.Tensor:
    return torch.tensor([values.get(c, math.nan) for c in columns], dtype=torch.float32)


def _nan_mean_std(values: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
    """Per-column mean and standard deviation of (N, L) values over the non-NaN entries; a
    column with fewer than two values or no spread gets mean 0 and std 1 (left as it is)."""
    known = ~torch.isnan(values)
    n = known.sum(dim=0)
    filled = torch.where(known, values, torch.zeros_like(values))
    mean = filled.sum(dim=0) / n.clamp_min(1)
    var = torch.where(known, (values - mean) ** 2, torch.zeros_like(values)).sum(dim=0)
    std = (var / (n - 1).clamp_min(1)).sqrt()
    usable = (n >= 2) & (std > 0)
    return torch.where(usable, mean, 0.0), torch.where(usable, std, 1.0)


@dataclass(frozen=True)
class TupleBatch:
    """A batch of drawn tuples (`TupleDataset.draw_batch`)."""

    y: np.ndarray
    """(B,) float32: 0 for one fabric, 1 for different fabrics."""
    fabrics: np.ndarray
    """(B, V) int64 positions in ``TupleDataset.fabric_ids`` of each slot's fabric."""
    items: list[np.ndarray]
    """Per slot, (B, k) int64 indices into ``TupleDataset.pool_items[modality]`` (k = 1, or
    ``presses`` for touch)."""


class TupleDataset(Dataset[dict[str, Any]]):
    """Tuples of slots from one fabric (y = 0) or from different fabrics (y = 1).

    Args:
        catalog: the fabrics to draw from (e.g. a split's training side).
        loader: decodes and caches images; its config supplies touch kinds, presses per touch
            slot, the same-fabric fraction and augmentation.
        views: the modality of each slot, e.g. ``(DEPTH, COLOR, TOUCH)`` for the paper's
            three-branch nets or ``(DEPTH, DEPTH)`` for the Siamese net.
        length: tuples (a run draws ``steps * batch_size``).
        seed: base seed; tuple ``i`` is drawn from ``(seed, i)``.
        augment: apply the configured augmentation (off for validation).
        classes: label column -> its class names, for class-head targets (``classes``).

    Each item is a dict:
        ``inputs``: slot name -> (1, S, S) depth, (3, S, S) colour, or (P, 3, S, S) touch.
        ``fabric_ids``: slot name -> int64 scalar.
        ``clusters``: slot name -> int64 scalar (`UNKNOWN_CLUSTER`, -1, when unknown).
        ``properties``: slot name -> (L,) float32 labels in ``catalog.label_columns`` order,
            standardised (zero mean, unit variance over this dataset's fabrics: see
            ``label_mean`` and ``label_std``), NaN where unknown.
        ``classes``: slot name -> (H,) int64 class index per ``classes`` column, -1 unknown.
        ``y``: float32 scalar, 0 for one fabric and 1 for different fabrics (paper's Y).

    Raises:
        DatasetError: a fabric lacks an item a slot needs, or too few fabrics for y = 1.
    """

    def __init__(
        self,
        catalog: Catalog,
        loader: ImageLoader,
        views: Sequence[Modality],
        length: int,
        seed: int = 0,
        augment: bool = True,
        classes: Mapping[str, Sequence[str]] | None = None,
    ) -> None:
        if not views:
            raise ValueError("views: at least one slot is needed")
        if length < 1:
            raise ValueError(f"length must be >= 1, got {length}")
        cfg: DataConfig = loader.config
        self.catalog = catalog
        self.loader = loader
        self.views = tuple(views)
        self.slots = slot_names(self.views)
        self.length = length
        self.seed = seed
        self.presses = cfg.presses
        self.same_fraction = cfg.same_fraction
        self.kinds: tuple[PressKind, ...] = cfg.touch_kinds
        self.label_columns = catalog.label_columns
        modalities = list(dict.fromkeys(self.views))
        if not catalog.fabrics:
            raise DatasetError("no fabric to draw training tuples from", catalog.root)
        catalog.require(modalities, self.kinds)
        self.fabric_ids = catalog.ids
        self.pools: dict[Modality, dict[int, list[Item]]] = {
            m: {f.id: f.items_of(m, self.kinds) for f in catalog.fabrics} for m in modalities
        }
        self._fabrics = {f.id: f for f in catalog.fabrics}
        known = torch.stack(
            [_labels_vector(dict(f.labels), self.label_columns) for f in catalog.fabrics]
        ).reshape(len(catalog.fabrics), len(self.label_columns))
        self.label_mean, self.label_std = _nan_mean_std(known)
        if self.same_fraction < 1.0 and len(self.fabric_ids) < len(self.views):
            raise DatasetError(
                f"{len(self.views)} slots from different fabrics need at least that many "
                f"fabrics; the dataset has {len(self.fabric_ids)}",
                catalog.root,
            )
        aug: dict[Modality, AugmentConfig] = cfg.augment if augment else {}
        self.augmenters = {m: Augmenter(aug[m]) for m in modalities if m in aug}
        # Vectorised draws: per modality, every pool item once (`pool_items`) and a padded
        # (fabrics, longest pool) matrix of indices into it (-1 past a pool's end).
        self.pool_items: dict[Modality, list[Item]] = {}
        """Per modality, every item this dataset may draw, once, fabric by fabric in id order
        (what `TupleBatch.items` index)."""
        self._pool: dict[Modality, np.ndarray] = {}
        self._pool_len: dict[Modality, np.ndarray] = {}
        for m in modalities:
            pools = [self.pools[m][fid] for fid in self.fabric_ids]
            flat = [it for pool in pools for it in pool]
            self.pool_items[m] = flat
            index = np.full((len(pools), max(len(p) for p in pools)), -1, np.int64)
            start = 0
            for row, pool in enumerate(pools):
                index[row, : len(pool)] = np.arange(start, start + len(pool))
                start += len(pool)
            self._pool[m] = index
            self._pool_len[m] = np.array([len(p) for p in pools], np.int64)
        self._ids = np.array(self.fabric_ids, np.int64)
        self._clusters = np.array(
            [UNKNOWN_CLUSTER if f.cluster is None else f.cluster for f in catalog.fabrics],
            np.int64,
        )
        self._properties = (known - self.label_mean) / self.label_std  # (F, L), NaN unknown
        self._classes = torch.from_numpy(class_matrix(catalog.fabrics, classes or {}))  # (F, H)

    def __len__(self) -> int:
        return self.length

    def items(self) -> list[Item]:
        """Every item this dataset may draw (for `ImageLoader.preload`)."""
        return [it for pool in self.pools.values() for items in pool.values() for it in items]

    def targets(self, fabric_ids: dict[str, list[int]]) -> dict[str, dict[str, torch.Tensor]]:
        """Per-slot targets of a batch from its fabric ids: ``fabric_ids`` (B,), ``clusters``
        (B,) with `UNKNOWN_CLUSTER` (-1) for unknown, ``properties`` (B, L) with NaN for
        unknown."""
        out: dict[str, dict[str, torch.Tensor]] = {
            "fabric_ids": {},
            "clusters": {},
            "properties": {},
            "classes": {},
        }
        position = {fid: i for i, fid in enumerate(self.fabric_ids)}
        for slot, ids in fabric_ids.items():
            fabrics = [self._fabrics[i] for i in ids]
            out["classes"][slot] = self._classes[[position[i] for i in ids]]
            out["fabric_ids"][slot] = torch.tensor(ids, dtype=torch.int64)
            out["clusters"][slot] = torch.tensor(
                [UNKNOWN_CLUSTER if f.cluster is None else f.cluster for f in fabrics],
                dtype=torch.int64,
            )
            raw = torch.stack(
                [_labels_vector(dict(f.labels), self.label_columns) for f in fabrics]
            ).reshape(len(ids), len(self.label_columns))
            out["properties"][slot] = (raw - self.label_mean) / self.label_std
        return out

    def draw_batch(self, rng: np.random.Generator, n: int) -> TupleBatch:
        """``n`` tuples at once from ``rng``: each is all one fabric (y = 0) with probability
        ``same_fraction``, else one distinct fabric per slot (y = 1). A slot takes one item
        (touch: ``presses`` distinct presses, repeated only when its fabric has fewer),
        preferring items not taken by an earlier slot of the tuple (the Siamese net's two
        depth slots from one fabric see two different images)."""
        nf, nv = len(self.fabric_ids), len(self.views)
        same = rng.random(n) < self.same_fraction
        one = rng.integers(nf, size=n)
        if nf >= nv:
            distinct = np.argsort(rng.random((n, nf)), axis=1)[:, :nv]
        else:  # only reachable with same_fraction == 1 (checked in __init__)
            distinct = np.repeat(one[:, None], nv, axis=1)
        fab = np.where(same[:, None], one[:, None], distinct)  # (n, V) fabric positions
        items: list[np.ndarray] = []
        used: dict[Modality, list[np.ndarray]] = {}
        for j, m in enumerate(self.views):
            k = self.presses if m.pooled else 1
            pool, count = self._pool[m][fab[:, j]], self._pool_len[m][fab[:, j]]  # (n, L), (n,)
            keys = rng.random(pool.shape)
            for earlier in used.get(m, []):  # taken items go last
                keys += (pool[:, :, None] == earlier[:, None, :]).any(-1)
            keys[pool < 0] = np.inf
            pos = np.argsort(keys, axis=1, kind="stable")[:, :k]
            if pos.shape[1] < k:
                pos = np.pad(pos, ((0, 0), (0, k - pos.shape[1])), constant_values=pool.shape[1])
            short = pos >= count[:, None]  # fewer items than presses: repeat at random
            if short.any():
                again = (rng.random(pos.shape) * count[:, None]).astype(np.int64)
                pos = np.where(short, again, pos)
            picked = np.take_along_axis(pool, pos, axis=1)  # (n, k) indices into pool_items
            used.setdefault(m, []).append(picked)
            items.append(picked)
        return TupleBatch(y=np.where(same, 0.0, 1.0).astype(np.float32), fabrics=fab, items=items)

    def batch_targets(self, fabrics: np.ndarray) -> dict[str, dict[str, torch.Tensor]]:
        """Per-slot targets from a (B, V) matrix of fabric positions (`TupleBatch.fabrics`):
        ``fabric_ids`` (B,), ``clusters`` (B,) with `UNKNOWN_CLUSTER` (-1) for unknown,
        ``properties`` (B, L) standardised with NaN for unknown."""
        out: dict[str, dict[str, torch.Tensor]] = {
            "fabric_ids": {},
            "clusters": {},
            "properties": {},
            "classes": {},
        }
        for j, slot in enumerate(self.slots):
            pos = fabrics[:, j]
            out["fabric_ids"][slot] = torch.from_numpy(self._ids[pos])
            out["clusters"][slot] = torch.from_numpy(self._clusters[pos])
            out["properties"][slot] = self._properties[torch.from_numpy(pos)]
            out["classes"][slot] = self._classes[torch.from_numpy(pos)]
        return out

    def draw(self, index: int) -> tuple[float, list[int], list[list[Item]]]:
        """The tuple at ``index`` as records: (y, fabric per slot, items per slot)."""
        b = self.draw_batch(np.random.default_rng([self.seed, index]), 1)
        fabrics = [int(self._ids[p]) for p in b.fabrics[0]]
        chosen = [
            [self.pool_items[m][int(i)] for i in picked[0]]
            for m, picked in zip(self.views, b.items, strict=True)
        ]
        return float(b.y[0]), fabrics, chosen

    def augment_rng(self, index: int) -> np.random.Generator:
        """The generator tuple ``index``'s augmentations draw from (`__getitem__`)."""
        return np.random.default_rng([self.seed, index, 1])

    def __getitem__(self, index: int) -> dict[str, Any]:
        if not 0 <= index < self.length:
            raise IndexError(index)
        y, fabrics, chosen = self.draw(index)
        rng = self.augment_rng(index)
        inputs = {}
        for slot, items in zip(self.slots, chosen, strict=True):
            m = slot_modality(slot)
            aug = self.augmenters.get(m)
            x = torch.stack([self.loader.load(it) for it in items])
            if aug is not None and aug.active:
                x = aug.apply_batch(x, aug.draw_batch(rng, *x.shape))
            inputs[slot] = x if m.pooled else x[0]
        targets = self.targets({s: [f] for s, f in zip(self.slots, fabrics, strict=True)})
        return {
            "inputs": inputs,
            **{k: {s: v[0] for s, v in per.items()} for k, per in targets.items()},
            "y": torch.tensor(y, dtype=torch.float32),
        }
