"""Embedding every item of a catalog with a trained model: the one path that validation,
``lookfeel embed``, evaluation and the fabric library share.

Embedding a large dataset takes a while: with ``progress`` (``lookfeel embed`` sets it),
`embed_catalog` shows for each modality a progress bar (tqdm) on stderr of its images
decoded, then one of its items embedded."""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass

import numpy as np
import torch
from numpy.typing import NDArray

from lookfeel.config.model import EMBED_BATCH
from lookfeel.data import Catalog, ImageLoader, ImageStore, Item
from lookfeel.data.images import stack_views
from lookfeel.devices import resolve_device
from lookfeel.errors import LookfeelError
from lookfeel.modality import Modality, PressKind
from lookfeel.models import Embedder, add_press_axis, autocast, eval_mode, to_channels_last
from lookfeel.progress import bar as progress_bar
from lookfeel.progress import shown as progress_shown

__all__ = [
    "EmbeddedItems",
    "EmbeddingError",
    "PressPooler",
    "check_finite",
    "embed_catalog",
    "embed_items",
    "press_pooler",
    "raw_pixels",
]


class EmbeddingError(LookfeelError):
    """A model embedded items as NaN or infinity: its weights hold them, or overflow on these
    inputs (a diverged run). Distances, rankings and an index built from such rows would be
    meaningless, so embedding stops and says which items."""


def check_finite(emb: np.ndarray, items: Sequence[Item]) -> np.ndarray:
    """``emb`` itself when every row is finite.

    Args:
        emb: (N, D) embeddings of ``items``, in their order.

    Raises:
        EmbeddingError: naming how many rows are not finite and the first one's file.
    """
    bad = ~np.isfinite(emb).all(axis=1)  # (N, D) -> (N,)
    if bad.any():
        first = items[int(np.flatnonzero(bad)[0])]
        raise EmbeddingError(
            f"the model embeds {int(bad.sum())} of {len(items)} {first.modality.value} items as "
            f"NaN or infinity (first {first.path}): its weights hold NaN or infinity or "
            "overflow on these inputs (a diverged run?)"
        )
    return emb


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
    batch_size: int = EMBED_BATCH,
    device: torch.device | str = "cpu",
    *,
    flip: bool = False,
    store: ImageStore | None = None,
    ready: Iterable[int] | None = None,
    progress: bool = False,
) -> np.ndarray:
    """Embed items of one modality in batches, in eval mode.

    Images travel to the device as the loader keeps them (uint8 for RGB: a quarter of float32's
    bytes), through two alternating pinned buffers on CUDA so a copy overlaps the previous
    batch's network, and become float there; on CUDA the network runs channels-last in the
    precision its config names (`ModelConfig.precision`: bf16 autocast unless ``fp32``).

    A press video whose loader `pools_views` (``data.video_embed: views``) is embedded from
    all its views, their embeddings averaged (`Branch.forward`); the same function therefore
    serves validation, ``embed``, ``cv``, evaluation and the index.

    Args:
        flip: test-time pooling: also embed each image mirrored left to right and return the
            mean of the two embeddings.
        store: images already on the device (`ImageStore` holding ``items``): no copies.
            Ignored for items embedded from several views.
        ready: how many of ``items``, from the first, the loader holds, as decoding goes on
            (`ImageLoader.preload_stream`): each batch is embedded as soon as its images are
            decoded, while the rest decode. ``None``: the loader decodes on demand.
        progress: show a progress bar (tqdm) on stderr of the items embedded.

    Returns:
        (N, D) float32 embeddings, in the order of ``items``.

    Raises:
        EmbeddingError: some embedding holds NaN or infinity (naming the first item).
    """
    if not items:
        return np.zeros((0, model.embed_dim), np.float32)
    dev = resolve_device(device)
    modality = items[0].modality
    stager = _Stager(dev)
    if store is not None and any(loader.pools_views(it) for it in items):
        store = None  # the store holds one image per item
    rows = store.rows(modality, items) if store is not None else None
    stream = iter(ready) if ready is not None else None
    have = 0 if stream is not None else len(items)
    out = []
    bar = progress_bar(total=len(items), desc=f"embed {modality.value}", unit="item", show=progress)
    with bar, eval_mode(model), autocast(dev, precision=model.precision):
        for start in range(0, len(items), batch_size):
            while stream is not None and have < min(start + batch_size, len(items)):
                have = next(stream, len(items))  # exhausted: every item is held
            if store is not None and rows is not None:
                x = store.batch(modality, rows[start : start + batch_size])
            else:
                x = stager.batch(loader, items[start : start + batch_size])
            x = to_channels_last(add_press_axis(x, modality))
            e = model({modality.value: x})[modality.value].float()
            if flip:
                e = 0.5 * (e + model({modality.value: x.flip(-1)})[modality.value].float())
            out.append(e.to("cpu", non_blocking=True))
            bar.update(min(batch_size, len(items) - start))
    for _ in stream or ():  # let the decoding finish (and its workers end) now
        pass
    if dev.type == "cuda":
        torch.cuda.synchronize(dev)  # the non-blocking copies back have landed
    return check_finite(torch.cat(out).numpy(), items)


PressPooler = Callable[["EmbeddedItems", NDArray[np.int64]], NDArray[np.float64]]
"""Embeds multi-press touch queries: (touch items, (M, P) rows of each group) -> (M, D)."""


def press_pooler(
    model: Embedder,
    loader: ImageLoader,
    batch_size: int = EMBED_BATCH,
    device: torch.device | str = "cpu",
    *,
    flip: bool = False,
) -> PressPooler:
    """Multi-press touch queries embedded by the model itself, its own press pooling (the
    Multi-input Net's): each group's presses go through the touch branch together (the
    branch of the items' modality: any `Modality.pooled` one).

    ``loader`` reads the items' images (a control's loader gives the control's images);
    ``flip`` averages each group's embedding with its mirror image's, as `embed_items`."""

    @torch.inference_mode()
    def pool(touch: EmbeddedItems, members: NDArray[np.int64]) -> NDArray[np.float64]:
        p = members.shape[1]
        slot = touch.modality.value  # touch, or any other `Modality.pooled` modality
        step = max(1, batch_size // p)
        out = []
        with eval_mode(model):
            for start in range(0, len(members), step):
                rows = members[start : start + step]
                x = stack_views([loader.load_embedded(touch.items[j]) for row in rows for j in row])
                x = x.unflatten(0, (len(rows), p)).to(device)  # (B, P [, V], 3, S, S)
                e = model({slot: x})[slot].double()
                if flip:
                    e = 0.5 * (e + model({slot: x.flip(-1)})[slot])
                out.append(e.cpu())
        if not out:
            return np.zeros((0, model.embed_dim))
        pooled = np.asarray(torch.cat(out).numpy(), dtype=np.float64)  # (M, D)
        return check_finite(pooled, [touch.items[j] for j in members[:, 0]])  # by 1st press

    return pool


class _Stager:
    """Batches of the loader's arrays on a device, equal to ``loader.load_embedded`` item by
    item (a view axis after the batch's when some item has views: `stack_views`).

    On CUDA the arrays are stacked straight into one of two pinned buffers and copied
    asynchronously; a buffer is refilled only after its previous copy has finished.
    """

    def __init__(self, device: torch.device) -> None:
        self.device = device
        self.buffers: list[tuple[torch.Tensor, torch.cuda.Event | None]] = []
        self.turn = 0

    def _pinned(self, shape: tuple[int, ...], dtype: np.dtype) -> torch.Tensor:
        kind = torch.from_numpy(np.empty(0, dtype)).dtype
        have = self.buffers[0][0] if self.buffers else None
        if (
            have is None
            or have.shape[1:] != shape[1:]
            or have.dtype != kind
            or len(have) < shape[0]
        ):
            self.buffers = [(torch.empty(shape, dtype=kind).pin_memory(), None) for _ in range(2)]
        self.turn ^= 1
        buf, event = self.buffers[self.turn]
        if event is not None:
            event.synchronize()  # the copy out of this buffer two batches ago is done
        return buf[: shape[0]]

    def batch(self, loader: ImageLoader, items: Sequence[Item]) -> torch.Tensor:
        arrays = [loader.embed_array(it) for it in items]
        if self.device.type == "cuda":
            shape = (len(arrays), *max((a.shape for a in arrays), key=len))
            buf = self._pinned(shape, arrays[0].dtype)
            if len({a.ndim for a in arrays}) == 1:
                np.stack(arrays, out=buf.numpy())
            else:  # single images among views: repeated as every view
                buf.numpy()[...] = stack_views(arrays)
            stacked = buf.to(self.device, non_blocking=True)
            event = torch.cuda.Event()
            event.record()
            self.buffers[self.turn] = (self.buffers[self.turn][0], event)
        else:
            stacked = torch.from_numpy(np.ascontiguousarray(stack_views(arrays)))
        if stacked.dtype == torch.uint8:  # (B [, V], S, S, 3) -> (B [, V], 3, S, S)
            if stacked.dim() == 5:
                return stacked.permute(0, 1, 4, 2, 3).float().div_(255.0)
            return stacked.permute(0, 3, 1, 2).float().div_(255.0)  # channels-last strides
        return stacked.unsqueeze(1)  # (B, S, S) depth -> (B, 1, S, S)


def raw_pixels(items: Sequence[Item], loader: ImageLoader) -> np.ndarray:
    """The raw-pixel baseline's "embedding": each preprocessed image (the network's input, at
    the config's size) flattened, as (N, C * S * S) float32. An item embedded from several
    views (`ImageLoader.pools_views`) gives the mean of its views' pixels, as the model
    averages their embeddings."""
    if not items:
        return np.zeros((0, 0), np.float32)
    rows = []
    for it in items:
        x = loader.load_embedded(it)
        rows.append((x.mean(0) if x.dim() == 4 else x).reshape(-1))
    return torch.stack(rows).float().numpy()


def embed_catalog(
    model: Embedder,
    catalog: Catalog,
    loader: ImageLoader,
    modalities: Iterable[Modality] | None = None,
    kinds: Sequence[PressKind] | None = None,
    batch_size: int = EMBED_BATCH,
    device: torch.device | str = "cpu",
    *,
    progress: bool = False,
) -> dict[Modality, EmbeddedItems]:
    """Embed every item of each modality the model has (touch: presses of ``kinds``).

    Args:
        model: a trained embedder.
        catalog: the items to embed.
        loader: decodes images with the run's preprocessing.
        modalities: default: the model's modalities that the catalog has.
        kinds: touch press kinds; default ``loader.config.touch_kinds``.
        progress: show progress bars (tqdm) on stderr, per modality: on a CPU the images
            decoded, then the items embedded; on CUDA, which embeds while the rest decode,
            the items embedded. Default: none.
    """
    mods = list(modalities) if modalities is not None else list(model.modalities)
    kinds = tuple(kinds) if kinds is not None else loader.config.touch_kinds

    out = {}
    for m in mods:
        items = catalog.items(m, kinds)
        if not items:
            continue
        ready = None
        if resolve_device(device).type == "cuda":  # the GPU embeds while the cores decode
            ready = loader.preload_stream(items)
        elif progress_shown(progress):  # as below, counting the items as they are decoded
            with progress_bar(total=len(items), desc=f"decode {m.value}", unit="item") as bar:
                for held in loader.preload_stream(items):
                    bar.update(held - bar.n)
        else:  # the same cores would do both: decoding first is 5% faster on 2 cores
            loader.preload(items)
        emb = embed_items(model, items, loader, batch_size, device, ready=ready, progress=progress)
        fids = np.array([it.fabric_id for it in items], dtype=np.int64)
        out[m] = EmbeddedItems(m, emb, fids, tuple(items))
    return out
