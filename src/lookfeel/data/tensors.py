"""Decoded images held once as tensors on the training device, gathered by row per batch.

`ImageStore` takes every item a run may use from an `ImageLoader` (which decodes and
preprocesses each file once) and packs each modality into one tensor: RGB (colour, touch) as
uint8 (N, 3, S, S), exactly the loader's bytes; depth as float32 (N, 1, S, S), the loader's
values (depth is mapped to [0, 1] from millimetres, which 8 bits would quantise). The tensors
live on the GPU when they fit in a quarter of its free memory, else in pinned host memory and
a batch is copied over asynchronously. With ``views``, a press video's other deep frames are
held after its image and a training step draws one of them (`ImageStore.draw_views`); with
``data.depth_wall_drop`` each drape's gaps to the room's walls are held beside it, on the host,
and a training draw drops the cloth near walls moved toward it (`ImageStore.drop_walls`). A
step then costs one gather and one conversion to float on the device: no file decoding.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

import numpy as np
import torch
from torch import Tensor

from lookfeel.data.catalog import Item
from lookfeel.data.images import WALL_GAP_NONE, ImageLoader
from lookfeel.modality import Modality

__all__ = ["ImageStore"]

_GPU_SHARE = 0.25
"""Largest share of the GPU's free memory the store may take before it stays on the host."""


class ImageStore:
    """Every item's preprocessed image, one tensor per modality, indexed by item.

    Args:
        loader: decodes and preprocesses (its memory cache is filled as a side effect).
        items: the items to hold (duplicates are held once).
        device: where batches are needed. On CUDA the store is put on the GPU when it fits
            (see ``on_device``), else pinned in host memory.
        views: also hold each item's other training views (`ImageLoader.views`: the deep
            frames of a press video with ``data.video_views`` > 1, a colour photo's re-printed
            renders with ``data.color_reprints``), drawn by `draw_views`; and with
            ``data.depth_wall_drop`` each drape's gaps to the walls, for `drop_walls`.

    Example:
        >>> store = ImageStore(loader, catalog.items(Modality.TOUCH), device)
        >>> x = store.batch(Modality.TOUCH, store.rows(Modality.TOUCH, items))  # (B, 3, S, S)
    """

    def __init__(
        self,
        loader: ImageLoader,
        items: Iterable[Item],
        device: torch.device | str = "cpu",
        *,
        views: bool = False,
    ) -> None:
        self.device = torch.device(device)
        per: dict[Modality, dict[Item, None]] = {}
        for it in items:
            per.setdefault(it.modality, {})[it] = None
        loader.preload([it for its in per.values() for it in its], views=views)
        self._rows: dict[Modality, dict[Item, int]] = {}
        self._views: dict[Modality, Tensor] = {}
        self._skip_first: set[Modality] = set()
        self._gaps: dict[Modality, np.ndarray] = {}
        c = loader.config
        self._wall = (
            c.depth_wall_drop,
            c.depth_wall_shift_mm,
            c.depth_wall_tilt_mm,
            c.depth_wall_band_mm,
        )
        host: dict[Modality, Tensor] = {}
        for m, its in per.items():
            unique = list(its)
            arrays = [  # (V, ...) each, the image first
                loader.views(it) if views else loader.array(loader.frame_path(it), m)[None]
                for it in unique
            ]
            if views and loader.wall_gaps_follow(m):
                self._gaps[m] = _padded_gaps([a[1:] for a in arrays])
                arrays = [a[:1] for a in arrays]
            counts = np.array([len(a) for a in arrays])
            starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
            self._rows[m] = {it: int(r) for it, r in zip(unique, starts, strict=True)}
            if counts.max() > 1:  # views of row r: rows r .. r + views[r] - 1
                at = np.ones(int(counts.sum()), dtype=np.int64)
                at[starts] = counts
                self._views[m] = torch.from_numpy(at)
                if loader.skips_first_view(m):
                    self._skip_first.add(m)
            stacked = np.concatenate(arrays)
            if stacked.dtype == np.uint8:  # (N, S, S, 3) -> (N, 3, S, S)
                t = torch.from_numpy(stacked).permute(0, 3, 1, 2).contiguous()
            else:  # (N, S, S) float32 depth -> (N, 1, S, S)
                t = torch.from_numpy(stacked.astype(np.float32, copy=False)).unsqueeze(1)
            host[m] = t
        nbytes = sum(t.numel() * t.element_size() for t in host.values())
        self.on_device = self.device.type == "cpu" or (
            self.device.type == "cuda" and nbytes <= _GPU_SHARE * _free_cuda_bytes(self.device)
        )
        if self.device.type == "cpu":
            self._data = host
        elif self.on_device:
            self._data = {m: t.to(self.device) for m, t in host.items()}
        else:
            self._data = {m: t.pin_memory() for m, t in host.items()}

    @property
    def modalities(self) -> tuple[Modality, ...]:
        return tuple(self._data)

    def __contains__(self, item: Item) -> bool:
        return item in self._rows.get(item.modality, {})

    def shape(self, modality: Modality) -> tuple[int, int, int]:
        """(C, S, S) of one image of ``modality``."""
        c, h, w = self._data[modality].shape[1:]
        return int(c), int(h), int(w)

    def nbytes(self) -> int:
        """Memory the store holds."""
        return sum(t.numel() * t.element_size() for t in self._data.values())

    def rows(self, modality: Modality, items: Sequence[Item]) -> list[int]:
        """Row of each item's image (its first view) in ``modality``'s tensor.

        Raises:
            KeyError: an item is not in the store.
        """
        table = self._rows[modality]
        return [table[it] for it in items]

    def draw_views(self, modality: Modality, rows: Tensor, rng: np.random.Generator) -> Tensor:
        """Rows of one training view of each image, drawn uniformly from ``rng`` (`rows`' own
        row is its image, the first view; a re-printed photo's draw leaves its image out:
        `ImageLoader.skips_first_view`); ``rows`` unchanged when no image has several."""
        views = self._views.get(modality)
        u = rng.random(len(rows))  # drawn in every case, so that one stream serves any data
        if views is None:
            return rows
        n = views[rows.cpu()].numpy()
        first = np.where(n > 1, int(modality in self._skip_first), 0)
        pick = torch.from_numpy((first + np.floor(u * (n - first))).astype(np.int64))
        return rows + pick.to(rows.device)

    def drop_walls(
        self, modality: Modality, rows: Tensor, x: Tensor, rng: np.random.Generator, share: slice
    ) -> Tensor:
        """``x`` with, for each image drawn (probability ``data.depth_wall_drop``), the cloth
        near the room's walls dropped as walls moved toward it at random would drop it
        (`lookfeel.data.register.drop_near_walls`), and with ``data.depth_wall_band_mm`` the
        others dropped by walls moved that far (no tilt), as evaluation's images are; ``x``
        unchanged for a modality without gaps (`ImageLoader.wall_gaps_follow`).

        Args:
            modality: the images' modality.
            rows: the global batch's rows (`batch`'s): every process draws alike.
            x: (B, 1, S, S) the images of ``rows[share]``.
            rng: the draws' generator.
            share: this process's part of ``rows``.
        """
        from lookfeel.data.register import drop_near_walls  # needs scipy: training only

        gaps = self._gaps.get(modality)
        if gaps is None:
            return x
        p, shift_mm, tilt_mm, band_mm = self._wall
        chosen = rng.random(len(rows)) < p
        draws = rng.random((len(rows), gaps.shape[1], 3))
        if band_mm:  # the draws left alone drop the fixed band (``data.depth_wall_band_mm``)
            draws[~chosen, :, 0] = band_mm / shift_mm
            draws[~chosen, :, 2] = 0.0
            chosen[:] = True
        picked = np.flatnonzero(chosen[share])
        if not len(picked):
            return x
        at = rows[share].cpu().numpy()[picked]
        idx = torch.from_numpy(picked).to(x.device)
        cloth = x[idx, 0].cpu().numpy() > 0
        keep = drop_near_walls(cloth, gaps[at], draws[share][picked], shift_mm, tilt_mm)
        dropped = torch.from_numpy(cloth & ~keep).to(x.device).unsqueeze(1)
        x = x.clone()
        x[idx] = x[idx].masked_fill(dropped, 0.0)
        return x

    def batch(self, modality: Modality, rows: Sequence[int] | Tensor) -> Tensor:
        """Images of ``rows`` on the device as float32 in the loader's scale ([0, 1]):
        (B, 1, S, S) depth, (B, 3, S, S) RGB; equal to ``loader.load`` image by image."""
        data = self._data[modality]
        if not isinstance(rows, Tensor):
            rows = torch.tensor(list(rows), dtype=torch.int64)
        if self.on_device:
            x = data[rows.to(data.device)]
        else:  # pinned host memory: gather on the host, copy asynchronously
            x = data[rows.cpu()].pin_memory().to(self.device, non_blocking=True)
        if x.dtype == torch.uint8:
            return x.float().div_(255.0)
        return x


def _padded_gaps(gaps: list[np.ndarray]) -> np.ndarray:
    """(N, P, S, S) float32 of each drape's (P_i, S, S) gaps to its walls, padded with
    `WALL_GAP_NONE` (no wall) to the most walls any drape has (at least one)."""
    most = max(1, max(len(g) for g in gaps))
    out = np.full((len(gaps), most, *gaps[0].shape[1:]), WALL_GAP_NONE, np.float32)
    for i, g in enumerate(gaps):
        out[i, : len(g)] = g
    return out


def _free_cuda_bytes(device: torch.device) -> int:
    try:
        free, _ = torch.cuda.mem_get_info(device)
    except (RuntimeError, AssertionError):
        return 0
    return int(free)
