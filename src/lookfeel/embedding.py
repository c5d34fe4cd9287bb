"""Embedding every item of a catalog with a trained model: the one path that validation,
``lookfeel embed``, evaluation and the fabric library share."""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np
import torch

from lookfeel.data import Catalog, ImageLoader, Item
from lookfeel.modality import Modality, PressKind
from lookfeel.models import Embedder

__all__ = ["EmbeddedItems", "embed_catalog", "embed_items", "raw_pixels"]


@dataclass(frozen=True)
class EmbeddedItems:
    """One modality's embeddings, one row per item (per press for touch).

    Attributes:
        modality: the modality.
        embeddings: (N, D) float32.
        fabric_ids: (N,) int64.
        items: the N items, in row order.
    """

    modality: Modality
    embeddings: np.ndarray
    fabric_ids: np.ndarray
    items: tuple[Item, ...]

    @property
    def paths(self) -> list[str]:
        """The file each row was read from (a press's first frame for touch)."""
        return [str(it.path) for it in self.items]


@torch.inference_mode()
def embed_items(
    model: Embedder,
    items: Sequence[Item],
    loader: ImageLoader,
    batch_size: int = 64,
    device: torch.device | str = "cpu",
    *,
    flip: bool = False,
) -> np.ndarray:
    """Embed items of one modality in batches, in eval mode.

    Args:
        flip: test-time pooling: also embed each image mirrored left to right and return the
            mean of the two embeddings.

    Returns:
        (N, D) float32 embeddings, in the order of ``items``.
    """
    if not items:
        return np.zeros((0, model.embed_dim), np.float32)
    modality = items[0].modality
    was_training = model.training
    model.eval()
    out = []
    try:
        for start in range(0, len(items), batch_size):
            chunk = items[start : start + batch_size]
            x = torch.stack([loader.load(it) for it in chunk]).to(device)
            if modality is Modality.TOUCH:
                x = x.unsqueeze(1)  # (B, 3, S, S) -> (B, P=1, 3, S, S)
            x = x.contiguous(memory_format=torch.channels_last) if x.dim() == 4 else x
            e = model({modality.value: x})[modality.value].float()
            if flip:
                e = 0.5 * (e + model({modality.value: x.flip(-1)})[modality.value].float())
            out.append(e.cpu())
    finally:
        model.train(was_training)
    return torch.cat(out).numpy()


def raw_pixels(items: Sequence[Item], loader: ImageLoader) -> np.ndarray:
    """The raw-pixel baseline's "embedding": each preprocessed image (the network's input, at
    the config's size) flattened, as (N, C * S * S) float32."""
    if not items:
        return np.zeros((0, 0), np.float32)
    return torch.stack([loader.load(it).reshape(-1) for it in items]).float().numpy()


def embed_catalog(
    model: Embedder,
    catalog: Catalog,
    loader: ImageLoader,
    modalities: Iterable[Modality] | None = None,
    kinds: Sequence[PressKind] | None = None,
    batch_size: int = 64,
    device: torch.device | str = "cpu",
) -> dict[Modality, EmbeddedItems]:
    """Embed every item of each modality the model has (touch: presses of ``kinds``).

    Args:
        model: a trained embedder.
        catalog: the items to embed.
        loader: decodes images with the run's preprocessing.
        modalities: default: the model's modalities that the catalog has.
        kinds: touch press kinds; default ``loader.config.touch_kinds``.
    """
    mods = list(modalities) if modalities is not None else list(model.modalities)
    kinds = tuple(kinds) if kinds is not None else loader.config.touch_kinds
    out = {}
    for m in mods:
        items = catalog.items(m, kinds)
        if not items:
            continue
        loader.preload(items)
        emb = embed_items(model, items, loader, batch_size, device)
        fids = np.array([it.fabric_id for it in items], dtype=np.int64)
        out[m] = EmbeddedItems(m, emb, fids, tuple(items))
    return out
