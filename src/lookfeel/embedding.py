"""Embedding every item of a catalog with a trained model: the one path that validation,
``lookfeel embed``, evaluation and the fabric library share."""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np
import torch

from lookfeel.data import Catalog, ImageLoader, Item
from lookfeel.modality import Modality, PressKind
from lookfeel.models import Embedder, add_press_axis, autocast, eval_mode, to_channels_last

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

    Images go to the device as uint8 (RGB) or float32 (depth) from pinned memory and become
    float there; on CUDA the network runs under bf16 autocast, channels-last.

    Args:
        flip: test-time pooling: also embed each image mirrored left to right and return the
            mean of the two embeddings.

    Returns:
        (N, D) float32 embeddings, in the order of ``items``.
    """
    if not items:
        return np.zeros((0, model.embed_dim), np.float32)
    dev = torch.device(device)
    modality = items[0].modality
    out = []
    with eval_mode(model), autocast(dev):
        for start in range(0, len(items), batch_size):
            x = _batch(loader, items[start : start + batch_size], dev)
            x = to_channels_last(add_press_axis(x, modality))
            e = model({modality.value: x})[modality.value].float()
            if flip:
                e = 0.5 * (e + model({modality.value: x.flip(-1)})[modality.value].float())
            out.append(e.to("cpu", non_blocking=True))
    if dev.type == "cuda":
        torch.cuda.synchronize(dev)  # the non-blocking copies back have landed
    return torch.cat(out).numpy()


def _batch(loader: ImageLoader, items: Sequence[Item], device: torch.device) -> torch.Tensor:
    """(B, C, S, S) float images of ``items`` on ``device``, equal to ``loader.load``'s: the
    bytes travel (a quarter of float32's for RGB) and are converted on the device."""
    arrays = [loader.array(loader.frame_path(it), it.modality) for it in items]
    stacked = torch.from_numpy(np.stack(arrays))
    if device.type == "cuda":
        stacked = stacked.pin_memory().to(device, non_blocking=True)
    if stacked.dtype == torch.uint8:  # (B, S, S, 3) -> (B, 3, S, S), channels-last strides
        return stacked.permute(0, 3, 1, 2).float().div_(255.0)
    return stacked.unsqueeze(1)  # (B, S, S) depth -> (B, 1, S, S)


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
