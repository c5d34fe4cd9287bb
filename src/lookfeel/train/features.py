"""The frozen-trunk cache: run the frozen part of every branch once per image, train the heads.

With the paper's AlexNet frozen up to fc6, a training step that starts from cached fc6
features costs one 4096x4096 layer per image instead of a whole AlexNet (ARCHITECTURE.md,
"What makes it fast"). Augmented modalities are cached as ``copies`` augmented versions of
each image, drawn once with fixed seeds; each training draw picks one of them. That trades
augmentation variety (``copies`` views instead of a fresh one per step) for speed; set
``train.augment_copies: 0`` to send augmented modalities through the full network instead.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import torch
from torch import Tensor

from lookfeel.config import AugmentConfig
from lookfeel.data import Augmenter, ImageLoader, Item
from lookfeel.modality import Modality
from lookfeel.models import Embedder

__all__ = ["FeatureTable"]


def _copy_seed(seed: int, row: int, copy: int) -> int:
    return int(np.random.default_rng([seed, row, copy, 3]).integers(2**62))


class FeatureTable:
    """Trunk features of every item, plain and (for augmented modalities) augmented copies.

    Args:
        model: the embedder whose frozen trunks are run (in eval mode; no gradient).
        loader: decodes and preprocesses images.
        items: per modality, every item training or validation may use.
        augment: per modality, the augmentation to cache copies of.
        copies: augmented copies per image (0: none cached).
        seed: seeds the augmented copies (copy ``k`` of item row ``i`` uses ``(seed, i, k)``).
        batch_size: images per trunk forward pass.
        device: where the trunk runs; the table is stored on this device.
        rank, world: fill only every ``world``-th row here and sum across processes, so
            ``world`` processes share the work (rows of other ranks stay 0 before the sum).
    """

    def __init__(
        self,
        model: Embedder,
        loader: ImageLoader,
        items: Mapping[Modality, Sequence[Item]],
        augment: Mapping[Modality, AugmentConfig],
        copies: int,
        seed: int,
        batch_size: int = 64,
        device: torch.device | str = "cpu",
        rank: int = 0,
        world: int = 1,
    ) -> None:
        self.rows: dict[Modality, dict[Item, int]] = {}
        self.plain: dict[Modality, Tensor] = {}
        self.augmented: dict[Modality, Tensor] = {}
        self.copies = copies
        self.device = torch.device(device)
        for m, its in items.items():
            unique = list(dict.fromkeys(its))
            self.rows[m] = {it: i for i, it in enumerate(unique)}
            aug = Augmenter(augment[m]) if m in augment else None
            self.plain[m] = self._run(
                model, loader, m, unique, None, 0, seed, batch_size, rank, world
            )
            if aug is not None and aug.active and copies > 0:
                per_copy = [
                    self._run(model, loader, m, unique, aug, k, seed, batch_size, rank, world)
                    for k in range(copies)
                ]
                self.augmented[m] = torch.stack(per_copy, dim=1)  # K x (N, *F) -> (N, K, *F)
        if world > 1:
            import torch.distributed as dist

            for table in (self.plain, self.augmented):
                for t in table.values():
                    dist.all_reduce(t)  # each row was filled by exactly one rank

    @torch.inference_mode()
    def _run(
        self,
        model: Embedder,
        loader: ImageLoader,
        modality: Modality,
        items: list[Item],
        aug: Augmenter | None,
        copy: int,
        seed: int,
        batch_size: int,
        rank: int,
        world: int,
    ) -> Tensor:
        was_training = model.training
        model.eval()
        mine = [i for i in range(len(items)) if i % world == rank]
        out: Tensor | None = None
        try:
            for start in range(0, len(mine), batch_size):
                rows = mine[start : start + batch_size]
                xs = []
                for i in rows:
                    x = loader.load(items[i])
                    if aug is not None:
                        g = torch.Generator().manual_seed(_copy_seed(seed, i, copy))
                        x = aug(x, g)
                    xs.append(x)
                x = torch.stack(xs).to(self.device)
                if modality is Modality.TOUCH:
                    x = x.unsqueeze(1)  # (B, 3, S, S) -> (B, P=1, 3, S, S)
                f = model.trunk({modality.value: x})[modality.value]
                if modality is Modality.TOUCH:
                    f = f.squeeze(1)  # (B, 1, *F) -> (B, *F)
                if out is None:
                    out = torch.zeros((len(items), *f.shape[1:]), dtype=f.dtype, device=self.device)
                out[rows] = f
        finally:
            model.train(was_training)
        if out is None:  # this rank had no row: learn the feature shape from one image
            probe = self._run(model, loader, modality, items[:1], None, 0, seed, 1, 0, 1)
            out = torch.zeros((len(items), *probe.shape[1:]), dtype=probe.dtype, device=self.device)
        return out.clone()  # a normal tensor, usable outside inference mode

    def has_copies(self, modality: Modality) -> bool:
        """Whether augmented copies are cached for ``modality``."""
        return modality in self.augmented

    def gather(
        self, modality: Modality, items: Sequence[Item], copies: Sequence[int] | None = None
    ) -> Tensor:
        """Features of ``items`` (augmented copy ``copies[j]`` for item ``j`` when given).

        Returns:
            (len(items), *F).
        """
        rows = torch.tensor([self.rows[modality][it] for it in items], device=self.device)
        if copies is None or modality not in self.augmented:
            return self.plain[modality][rows]
        k = torch.tensor(list(copies), device=self.device)
        return self.augmented[modality][rows, k]

    def nbytes(self) -> int:
        """Memory held by the table."""
        tensors = [*self.plain.values(), *self.augmented.values()]
        return sum(t.numel() * t.element_size() for t in tensors)
