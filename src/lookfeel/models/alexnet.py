"""AlexNet in torchvision's exact module layout, embedding at fc7 (the paper's E).

The attribute names and indices are torchvision's (``features.0.weight`` ...
``classifier.6.bias``), so a user's local ``alexnet-owt-7be5be79.pth`` loads unchanged (see
`lookfeel.models.pretrained`). The embedding is ReLU(fc7), 4096-d, as in the authors' code;
the ImageNet classifier fc8 (``classifier.6``) is kept for the state dict but never used.
"""

from __future__ import annotations

from typing import ClassVar

from torch import Tensor, nn

from lookfeel.models.backbone import Backbone
from lookfeel.models.dropout import FastDropout

__all__ = ["AlexNet"]


class _PoolTo6(nn.AdaptiveAvgPool2d):
    """torchvision's adaptive average pool to 6x6, passing a map that is 6x6 already (an image
    of 224-231 px) through untouched: the same numbers, and a graph that ONNX can export with
    a dynamic number of presses, where the exporter no longer knows the map's size, which
    adaptive pooling needs."""

    def __init__(self) -> None:
        super().__init__((6, 6))

    def forward(self, x: Tensor) -> Tensor:
        if tuple(x.shape[-2:]) == (6, 6):
            return x
        return super().forward(x)


class AlexNet(Backbone):
    """AlexNet (Krizhevsky et al. 2012, torchvision's single-tower variant) to fc7.

    Stages: conv1-5 with pooling (``features``), avgpool and flatten, fc6 (``classifier.0-2``:
    dropout, linear, ReLU), fc7 (``classifier.3-5``). Freeze points: ``none``; ``to_conv5``;
    ``to_fc6`` (the paper: "parameters of AlexNet before fc7 will be fixed"); ``all``.
    Arguments: ``freeze`` ``None`` is the paper's ``to_fc6``; ``dropout`` is the probability
    before fc6 and fc7 (torchvision: 0.5); ``width`` must be ``None`` (AlexNet's is fixed).
    """

    name = "alexnet"
    freeze_points: ClassVar[dict[str, int]] = {"none": 0, "to_conv5": 2, "to_fc6": 3, "all": 4}
    default_freeze = "to_fc6"
    loads_pretrained = True
    takes_width = False
    min_size = 63  # three stride-2 max pools after a stride-4 conv need 63 px

    def _build(self, freeze: str | None, dropout: float, width: int | None) -> None:
        """Build the layers."""
        if width is not None:
            raise ValueError("alexnet has a fixed width; width must be None")
        self.features = nn.Sequential(
            nn.Conv2d(self.stem_channels, 64, kernel_size=11, stride=4, padding=2),
            nn.ReLU(inplace=True),
            nn.MaxPool2d(kernel_size=3, stride=2),
            nn.Conv2d(64, 192, kernel_size=5, padding=2),
            nn.ReLU(inplace=True),
            nn.MaxPool2d(kernel_size=3, stride=2),
            nn.Conv2d(192, 384, kernel_size=3, padding=1),
            nn.ReLU(inplace=True),
            nn.Conv2d(384, 256, kernel_size=3, padding=1),
            nn.ReLU(inplace=True),
            nn.Conv2d(256, 256, kernel_size=3, padding=1),
            nn.ReLU(inplace=True),
            nn.MaxPool2d(kernel_size=3, stride=2),
        )
        self.avgpool = _PoolTo6()
        self.classifier = nn.Sequential(
            FastDropout(p=dropout),
            nn.Linear(256 * 6 * 6, 4096),
            nn.ReLU(inplace=True),
            FastDropout(p=dropout),
            nn.Linear(4096, 4096),
            nn.ReLU(inplace=True),
            nn.Linear(4096, 1000),
        )
        stages = [
            self.features,  # (N, C, H, W) -> (N, 256, h, w)
            nn.Sequential(self.avgpool, nn.Flatten(1)),  # -> (N, 9216)
            self.classifier[0:3],  # fc6: -> (N, 4096)
            self.classifier[3:6],  # fc7: -> (N, 4096), the embedding E
        ]
        self._set_stages(
            stages, freeze or self.default_freeze, embed_dim=4096, unused=[self.classifier[6]]
        )
