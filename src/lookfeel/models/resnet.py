"""ResNet-18 (He et al. 2016) in plain torch, with torchvision's module layout and keys.

The names match torchvision's ``resnet18`` (``conv1``, ``bn1``, ``layer1.0.conv1`` ...
``fc``), so a user's local ``resnet18-f37072fd.pth`` loads unchanged. The embedding is the
globally pooled output of ``layer4`` (D = 8 * width = 512); the ImageNet classifier ``fc`` is
kept for the state dict but never used.
"""

from __future__ import annotations

from typing import ClassVar

from torch import Tensor, nn

from lookfeel.models.backbone import Backbone

__all__ = ["ResNet18"]


class BasicBlock(nn.Module):
    """Two 3x3 convolutions with a residual connection (torchvision's ``BasicBlock``)."""

    def __init__(self, cin: int, cout: int, stride: int = 1) -> None:
        super().__init__()
        self.conv1 = nn.Conv2d(cin, cout, 3, stride=stride, padding=1, bias=False)
        self.bn1 = nn.BatchNorm2d(cout)
        self.relu = nn.ReLU(inplace=True)
        self.conv2 = nn.Conv2d(cout, cout, 3, padding=1, bias=False)
        self.bn2 = nn.BatchNorm2d(cout)
        self.downsample: nn.Module | None = None
        if stride != 1 or cin != cout:
            self.downsample = nn.Sequential(
                nn.Conv2d(cin, cout, 1, stride=stride, bias=False), nn.BatchNorm2d(cout)
            )

    def forward(self, x: Tensor) -> Tensor:
        """(N, cin, H, W) -> (N, cout, H / stride, W / stride)."""
        identity = x if self.downsample is None else self.downsample(x)
        out = self.relu(self.bn1(self.conv1(x)))
        out = self.bn2(self.conv2(out))
        return self.relu(out + identity)


class ResNet18(Backbone):
    """ResNet-18 to its pooled ``layer4`` features.

    Stages: stem (conv1, bn1, ReLU, max pool), layer1-4, global average pool. Freeze points:
    ``none``, ``to_layer2``, ``to_layer3``, ``all``.
    Arguments: ``freeze`` ``None`` trains everything; ``dropout`` is unused (ResNet-18 has no
    dropout; accepted for a uniform interface); ``width`` is the channels of ``layer1``
    (default 64, torchvision's).
    """

    name = "resnet18"
    freeze_points: ClassVar[dict[str, int]] = {"none": 0, "to_layer2": 3, "to_layer3": 4, "all": 6}
    loads_pretrained = True
    pretrained_width = 64
    min_size = 32

    def _build(self, freeze: str | None, dropout: float, width: int | None) -> None:
        """Build the layers."""
        del dropout
        w = width or 64
        self.conv1 = nn.Conv2d(self.stem_channels, w, 7, stride=2, padding=3, bias=False)
        self.bn1 = nn.BatchNorm2d(w)
        self.relu = nn.ReLU(inplace=True)
        self.maxpool = nn.MaxPool2d(kernel_size=3, stride=2, padding=1)
        self.layer1 = nn.Sequential(BasicBlock(w, w), BasicBlock(w, w))
        self.layer2 = nn.Sequential(BasicBlock(w, 2 * w, 2), BasicBlock(2 * w, 2 * w))
        self.layer3 = nn.Sequential(BasicBlock(2 * w, 4 * w, 2), BasicBlock(4 * w, 4 * w))
        self.layer4 = nn.Sequential(BasicBlock(4 * w, 8 * w, 2), BasicBlock(8 * w, 8 * w))
        self.avgpool = nn.AdaptiveAvgPool2d((1, 1))
        self.fc = nn.Linear(8 * w, 1000)
        for m in self.modules():
            if isinstance(m, nn.Conv2d):
                nn.init.kaiming_normal_(m.weight, mode="fan_out", nonlinearity="relu")
        stages = [
            nn.Sequential(self.conv1, self.bn1, self.relu, self.maxpool),  # -> (N, w, H/4, W/4)
            self.layer1,
            self.layer2,
            self.layer3,
            self.layer4,  # -> (N, 8w, H/32, W/32)
            nn.Sequential(self.avgpool, nn.Flatten(1)),  # -> (N, 8w), the embedding
        ]
        self._set_stages(stages, freeze or "none", embed_dim=8 * w, unused=[self.fc])
