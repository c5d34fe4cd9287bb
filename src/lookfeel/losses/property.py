"""Property regression from the embedding, masked where a fabric's label is unknown."""

from __future__ import annotations

import torch
from torch import Tensor

__all__ = ["masked_mse"]


def masked_mse(pred: Tensor, target: Tensor) -> Tensor:
    """Mean squared error over the known entries of ``target`` (NaN marks unknown).

    Unknown entries contribute neither to the value nor to the gradient (NaN never reaches the
    arithmetic: it is replaced before the difference is taken).

    Args:
        pred: (B, Q) predicted properties.
        target: (B, Q) labels, NaN where unknown; standardise them first, so that properties on
            different scales weigh alike.

    Returns:
        Scalar: the mean over known entries; 0 (with a zero gradient) when none is known.
    """
    known = ~torch.isnan(target)
    safe = torch.where(known, target, pred.detach())
    sq = (pred - safe).pow(2)  # 0 (and a zero gradient) where unknown
    # clamp, not `if known.any()`: a branch on a GPU value would wait for the GPU every step.
    return sq.sum() / known.sum().clamp_min(1)
