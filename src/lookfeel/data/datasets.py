"""Training and evaluation datasets over a `Catalog`.

`TupleDataset` draws the paper's training tuples: one item per slot (a slot is a modality;
the Siamese net has two depth slots), all from one fabric (Y = 0) or each from a different
fabric (Y = 1), at a configured ratio (paper section 4, equation 2). A touch slot holds P
presses of its fabric (the Multi-input Net). Every draw is seeded by (seed, epoch, index), so
a tuple does not depend on worker processes, batch order or a resumed run.

`ItemDataset` yields every item of one modality once, for embedding and evaluation.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
import torch
from torch.utils.data import Dataset

from lookfeel.config import AugmentConfig, DataConfig
from lookfeel.data.augment import Augmenter
from lookfeel.data.catalog import Catalog, Item
from lookfeel.data.images import ImageLoader
from lookfeel.data.problems import DatasetError
from lookfeel.modality import Modality, PressKind, slot_modality, slot_names

__all__ = ["ItemDataset", "TupleDataset"]


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


class TupleDataset(Dataset[dict[str, Any]]):
    """Tuples of slots from one fabric (y = 0) or from different fabrics (y = 1).

    Args:
        catalog: the fabrics to draw from (e.g. a split's training side).
        loader: decodes and caches images; its config supplies touch kinds, presses per touch
            slot, the same-fabric fraction and augmentation.
        views: the modality of each slot, e.g. ``(DEPTH, COLOR, TOUCH)`` for the paper's
            three-branch nets or ``(DEPTH, DEPTH)`` for the Siamese net.
        length: tuples per epoch.
        seed: base seed; tuple ``i`` of epoch ``e`` is drawn from ``(seed, e, i)``.
        augment: apply the configured augmentation (off for validation).

    Each item is a dict:
        ``inputs``: slot name -> (1, S, S) depth, (3, S, S) colour, or (P, 3, S, S) touch.
        ``fabric_ids``: slot name -> int64 scalar.
        ``clusters``: slot name -> int64 scalar (-1 when unknown).
        ``properties``: slot name -> (L,) float32 labels in ``catalog.label_columns`` order,
            standardised (zero mean, unit variance over this dataset's fabrics: see
            ``label_mean`` and ``label_std``), NaN where unknown.
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
        self.epoch = 0
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

    def __len__(self) -> int:
        return self.length

    def set_epoch(self, epoch: int) -> None:
        """Draw a fresh set of tuples for ``epoch`` (call once per epoch)."""
        self.epoch = epoch

    def items(self) -> list[Item]:
        """Every item this dataset may draw (for `ImageLoader.preload`)."""
        return [it for pool in self.pools.values() for items in pool.values() for it in items]

    def pools_items(self, modality: Modality) -> list[Item]:
        """Every item of one modality this dataset may draw."""
        return [it for items in self.pools[modality].values() for it in items]

    def targets(self, fabric_ids: dict[str, list[int]]) -> dict[str, dict[str, torch.Tensor]]:
        """Per-slot targets of a batch from its fabric ids: ``fabric_ids`` (B,), ``clusters``
        (B,) with -1 for unknown, ``properties`` (B, L) with NaN for unknown."""
        out: dict[str, dict[str, torch.Tensor]] = {
            "fabric_ids": {},
            "clusters": {},
            "properties": {},
        }
        for slot, ids in fabric_ids.items():
            fabrics = [self._fabrics[i] for i in ids]
            out["fabric_ids"][slot] = torch.tensor(ids, dtype=torch.int64)
            out["clusters"][slot] = torch.tensor(
                [-1 if f.cluster is None else f.cluster for f in fabrics], dtype=torch.int64
            )
            raw = torch.stack(
                [_labels_vector(dict(f.labels), self.label_columns) for f in fabrics]
            ).reshape(len(ids), len(self.label_columns))
            out["properties"][slot] = (raw - self.label_mean) / self.label_std
        return out

    def _choose(
        self, rng: np.random.Generator, pool: list[Item], k: int, avoid: set[Item]
    ) -> list[Item]:
        fresh = [it for it in pool if it not in avoid]
        source = fresh if len(fresh) >= k else pool
        idx = rng.choice(len(source), size=k, replace=len(source) < k)
        return [source[int(i)] for i in idx]

    def draw(self, index: int) -> tuple[float, list[int], list[list[Item]]]:
        """The tuple at ``index`` as records: (y, fabric per slot, items per slot)."""
        rng = np.random.default_rng([self.seed, self.epoch, index])
        same = bool(rng.random() < self.same_fraction)
        if same:
            fid = self.fabric_ids[int(rng.integers(len(self.fabric_ids)))]
            fabrics = [fid] * len(self.views)
        else:
            idx = rng.choice(len(self.fabric_ids), size=len(self.views), replace=False)
            fabrics = [self.fabric_ids[int(i)] for i in idx]
        used: set[Item] = set()
        chosen = []
        for m, fid in zip(self.views, fabrics, strict=True):
            k = self.presses if m is Modality.TOUCH else 1
            picked = self._choose(rng, self.pools[m][fid], k, used)
            used.update(picked)
            chosen.append(picked)
        return (0.0 if same else 1.0), fabrics, chosen

    def __getitem__(self, index: int) -> dict[str, Any]:
        if not 0 <= index < self.length:
            raise IndexError(index)
        y, fabrics, chosen = self.draw(index)
        gen = torch.Generator().manual_seed(
            int(np.random.default_rng([self.seed, self.epoch, index, 1]).integers(2**62))
        )
        inputs = {}
        for slot, items in zip(self.slots, chosen, strict=True):
            m = slot_modality(slot)
            aug = self.augmenters.get(m)
            xs = [self.loader.load(it) for it in items]
            if aug is not None:
                xs = [aug(x, gen) for x in xs]
            inputs[slot] = torch.stack(xs) if m is Modality.TOUCH else xs[0]
        targets = self.targets({s: [f] for s, f in zip(self.slots, fabrics, strict=True)})
        return {
            "inputs": inputs,
            **{k: {s: v[0] for s, v in per.items()} for k, per in targets.items()},
            "y": torch.tensor(y, dtype=torch.float32),
        }


class ItemDataset(Dataset[dict[str, Any]]):
    """Every item of one modality once, in catalog order (for embedding and evaluation).

    A touch item is one press; its input is (1, 3, S, S), the same press axis as training.

    Each item is a dict: ``input`` (tensor), ``fabric_id`` (int64), ``index`` (int64 row).
    """

    def __init__(
        self,
        catalog: Catalog,
        loader: ImageLoader,
        modality: Modality,
        kinds: Sequence[PressKind] | None = None,
    ) -> None:
        self.loader = loader
        self.modality = modality
        if modality is Modality.TOUCH and kinds is None:
            kinds = loader.config.touch_kinds
        self.item_list = catalog.items(modality, kinds)

    def __len__(self) -> int:
        return len(self.item_list)

    def __getitem__(self, index: int) -> dict[str, Any]:
        it = self.item_list[index]
        x = self.loader.load(it)
        if self.modality is Modality.TOUCH:
            x = x.unsqueeze(0)  # (3, S, S) -> (1, 3, S, S): one press
        return {
            "input": x,
            "fabric_id": torch.tensor(it.fabric_id, dtype=torch.int64),
            "index": torch.tensor(index, dtype=torch.int64),
        }
