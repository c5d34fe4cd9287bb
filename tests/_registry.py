"""A backbone and a loss of a researcher's own, as a user's module would write them, and a way
to register them for one test only (the registries are global to the process)."""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from typing import ClassVar

import torch
from torch import Tensor, nn

import lookfeel.config.loss as config_loss
import lookfeel.config.model as config_model
from lookfeel.losses import PAIR_LOSSES, FabricPairLoss
from lookfeel.models import BACKBONES, Backbone


@contextmanager
def restored_registries() -> Iterator[None]:
    """Whatever is registered inside the block (backbones, losses) is forgotten after it."""
    saved = [
        (d, dict(d))
        for d in (
            BACKBONES,
            PAIR_LOSSES,
            config_model._BACKBONE_SPECS,
            config_loss._LOSS_KINDS,
        )
    ]
    try:
        yield
    finally:
        for d, before in saved:
            dict.clear(d)
            dict.update(d, before)


class Patchify(nn.Module):
    """(N, C, H, W) -> (N, T, D): one token per 8x8 patch."""

    def __init__(self, cin: int, dim: int) -> None:
        super().__init__()
        self.proj = nn.Conv2d(cin, dim, 8, stride=8)

    def forward(self, x: Tensor) -> Tensor:
        return self.proj(x).flatten(2).transpose(1, 2)


class MeanTokens(nn.Module):
    """(N, T, D) -> (N, D)."""

    def forward(self, x: Tensor) -> Tensor:
        return x.mean(1)


class TinyViT(Backbone):
    """A tiny transformer: patches, one encoder layer, the mean token. Registered by tests
    only (`restored_registries`)."""

    name = "tinyvit"
    freeze_points: ClassVar[dict[str, int]] = {"none": 0, "to_patches": 1, "all": 3}
    default_freeze = "none"
    min_size = 8

    def _build(self, freeze: str | None, dropout: float, width: int | None) -> None:
        d = width or 16
        self.patch = Patchify(self.stem_channels, d)
        layer = nn.TransformerEncoderLayer(d, 2, 2 * d, dropout=0.0, batch_first=True)
        self.enc = nn.TransformerEncoder(layer, 1, enable_nested_tensor=False)
        self.pool = MeanTokens()
        self._set_stages([self.patch, self.enc, self.pool], freeze or "none", embed_dim=d)


class MeanTripletLoss(FabricPairLoss):
    """Mean triplet margin over every (anchor, positive, negative) of a slot pair."""

    loss_name = "the mean triplet loss"

    def __init__(self, margin: float) -> None:
        super().__init__()
        self.margin = margin

    def pair_term(self, ea: Tensor, eb: Tensor, fa: Tensor, fb: Tensor) -> Tensor:
        d = torch.cdist(ea, eb)
        pos = (fa[:, None] == fb[None, :]).float()
        dp = (d * pos).sum(1) / pos.sum(1).clamp_min(1)
        t = torch.relu(dp[:, None] - d + self.margin) * (1 - pos)
        return (t.sum(1) / (1 - pos).sum(1).clamp_min(1)).mean()


class NaNTermLoss(nn.Module):
    """Two terms: a finite one and one that is NaN from the first step (with a zero gradient,
    so the weights and the other term stay finite)."""

    def forward(
        self,
        embeddings: Mapping[str, Tensor],
        y: Tensor | None = None,
        fabric: Mapping[str, Tensor] | None = None,
    ) -> dict[str, Tensor]:
        first = next(iter(embeddings.values()))
        return {
            "fine_loss": first.pow(2).mean(),
            "broken_loss": first.mean() * 0.0 + float("nan"),  # zero gradient: weights stay finite
        }
