"""A compact CNN for small inputs (64-112 px) that trains on a CPU in minutes."""

from __future__ import annotations

from typing import ClassVar

from torch import nn

from lookfeel.models.backbone import Backbone
from lookfeel.models.dropout import FastDropout

__all__ = ["CompactCNN"]


def _block(cin: int, cout: int) -> nn.Sequential:
    """3x3 conv, BatchNorm, ReLU, then a 2x2 max pool: halves the side."""
    return nn.Sequential(
        nn.Conv2d(cin, cout, kernel_size=3, padding=1, bias=False),
        nn.BatchNorm2d(cout),
        nn.ReLU(inplace=True),
        nn.MaxPool2d(2),
    )


class CompactCNN(Backbone):
    """Four conv blocks (width w, 2w, 4w, 8w), global average pool, one fc layer (the embedding).

    At 64 px and w = 32 a forward pass costs about 60 MMAC per image (AlexNet at 227 px: 715).
    Like AlexNet's fc7, the embedding is the ReLU of a fully connected layer, D = 8w.
    Freeze points: ``none``, ``to_block4`` (all conv blocks), ``all``.
    Arguments: ``freeze`` ``None`` trains everything; ``dropout`` is the probability before the
    fc layer; ``width`` is w, the channels of the first block (default 32).
    """

    name = "compact"
    freeze_points: ClassVar[dict[str, int]] = {"none": 0, "to_block4": 5, "all": 6}
    min_size = 16

    def _build(self, freeze: str | None, dropout: float, width: int | None) -> None:
        """Build the layers."""
        w = width or 32
        self.features = nn.Sequential(
            _block(self.stem_channels, w),
            _block(w, 2 * w),
            _block(2 * w, 4 * w),
            _block(4 * w, 8 * w),
        )
        self.pool = nn.Sequential(nn.AdaptiveAvgPool2d(1), nn.Flatten(1))
        self.fc = nn.Sequential(
            FastDropout(dropout), nn.Linear(8 * w, 8 * w), nn.ReLU(inplace=True)
        )
        for m in self.modules():
            if isinstance(m, nn.Conv2d):
                nn.init.kaiming_normal_(m.weight, mode="fan_out", nonlinearity="relu")
        stages = [
            *self.features,  # (N, C, H, W) -> (N, 8w, H/16, W/16)
            self.pool,  # -> (N, 8w)
            self.fc,  # -> (N, 8w), the embedding
        ]
        self._set_stages(stages, freeze or "none", embed_dim=8 * w)
