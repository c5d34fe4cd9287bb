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
from lookfeel.data import Augmenter, ImageStore, Item
from lookfeel.modality import Modality
from lookfeel.models import Embedder, add_press_axis, autocast, drop_press_axis, eval_mode

__all__ = ["FeatureTable"]


class FeatureTable:
    """Trunk features of every item, plain and (for augmented modalities) augmented copies.

    Args:
        model: the embedder whose frozen trunks are run (in eval mode; no gradient).
        store: the decoded images (`ImageStore`) on the training device.
        items: per modality, every item training or validation may use.
        augment: per modality, the augmentation to cache copies of.
        copies: augmented copies per image (0: none cached).
        seed: seeds the augmented copies (copy ``k`` of every row is drawn from ``(seed, k)``).
        batch_size: images per trunk forward pass.
        device: where the trunk runs; the table is stored on this device (float32; on CUDA
            the trunk runs in the model's precision, `ModelConfig.precision`).
        rank, world: fill only every ``world``-th row here and sum across processes, so
            ``world`` processes share the work (rows of other ranks stay 0 before the sum).
    """

    def __init__(
        self,
        model: Embedder,
        store: ImageStore,
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
        with eval_mode(model):
            for m, its in items.items():
                unique = list(dict.fromkeys(its))
                self.rows[m] = {it: i for i, it in enumerate(unique)}
                aug = Augmenter(augment[m]) if m in augment else None
                run = (model, store, m, unique, seed, batch_size, rank, world)
                self.plain[m] = self._run(*run, None, 0)
                if aug is not None and aug.active and copies > 0:
                    per_copy = [self._run(*run, aug, k) for k in range(copies)]
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
        store: ImageStore,
        modality: Modality,
        items: list[Item],
        seed: int,
        batch_size: int,
        rank: int,
        world: int,
        aug: Augmenter | None,
        copy: int,
    ) -> Tensor:
        mine = [i for i in range(len(items)) if i % world == rank] or [0]
        rows = store.rows(modality, items)
        draws = None
        if aug is not None:  # every row's draw, so every process draws alike
            rng = np.random.default_rng([seed, copy, 3])
            draws = aug.draw_batch(rng, len(items), *store.shape(modality))
        out: Tensor | None = None
        for start in range(0, len(mine), batch_size):
            chunk = mine[start : start + batch_size]
            x = store.batch(modality, [rows[i] for i in chunk])
            if aug is not None and draws is not None:
                x = aug.apply_batch(x, draws[np.array(chunk)])
            with autocast(self.device, precision=model.precision):
                f = model.trunk({modality.value: add_press_axis(x, modality)})[modality.value]
            f = drop_press_axis(f, modality).float()
            if out is None:
                out = torch.zeros((len(items), *f.shape[1:]), dtype=f.dtype, device=self.device)
            out[chunk] = f
        assert out is not None
        if not any(i % world == rank for i in range(len(items))):
            out.zero_()  # this rank has no row: it ran one image only to learn the shape
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
        rows = torch.tensor([self.rows[modality][it] for it in items])
        k = None if copies is None else torch.tensor(list(copies))
        return self.gather_rows(modality, rows, k)

    def gather_rows(self, modality: Modality, rows: Tensor, copies: Tensor | None = None) -> Tensor:
        """Features of table rows (see ``rows``), of augmented copy ``copies[j]`` for row ``j``
        when given and the modality has copies; (len(rows), *F) on the table's device."""
        rows = rows.to(self.device, non_blocking=True)
        if copies is None or modality not in self.augmented:
            return self.plain[modality][rows]
        return self.augmented[modality][rows, copies.to(self.device, non_blocking=True)]

    def nbytes(self) -> int:
        """Memory held by the table."""
        tensors = [*self.plain.values(), *self.augmented.values()]
        return sum(t.numel() * t.element_size() for t in tensors)
