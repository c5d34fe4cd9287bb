"""Dropout whose mask costs a third of PyTorch's on CPU, with identical statistics.

`torch.nn.Dropout` draws one float per element (``bernoulli_``): for the paper's fc7 input,
(640, 4096) per training step, that is ~30 ms of a ~400 ms step on 2 cores. Drawing one random
byte per element and keeping those >= 256 p is exact whenever 256 p is an integer (the paper's
p = 0.5 included), and ~3x cheaper; any other p falls back to `torch.nn.functional.dropout`.
"""

from __future__ import annotations

import torch
import torch.nn.functional as F
from torch import Tensor, nn

__all__ = ["FastDropout"]


class FastDropout(nn.Module):
    """Drop-in replacement for `nn.Dropout` (same state dict: none; same scaling 1/(1-p))."""

    def __init__(self, p: float = 0.5) -> None:
        super().__init__()
        if not 0.0 <= p < 1.0:
            raise ValueError(f"dropout probability must be in [0, 1), got {p}")
        self.p = p
        self._threshold = round(p * 256) if (p * 256).is_integer() else None

    def forward(self, x: Tensor) -> Tensor:
        if not self.training or self.p == 0.0:
            return x
        if self._threshold is None or x.device.type != "cpu":
            return F.dropout(x, self.p, training=True)
        draw = torch.randint(0, 256, x.shape, dtype=torch.uint8, device=x.device)
        keep = draw >= self._threshold  # P(keep) = (256 - 256 p) / 256 = 1 - p exactly
        return x * keep * (1.0 / (1.0 - self.p))

    def extra_repr(self) -> str:
        return f"p={self.p}"
