"""Cluster cross-entropy, the paper's auxiliary task (section 4.1, Auxiliary Net)."""

from __future__ import annotations

import torch.nn.functional as F
from torch import Tensor

__all__ = ["UNKNOWN_CLUSTER", "masked_cross_entropy"]

UNKNOWN_CLUSTER = -1
"""Cluster target of an item whose fabric has no cluster label; it contributes nothing."""


def masked_cross_entropy(logits: Tensor, target: Tensor) -> Tensor:
    """Cross-entropy over the items with a known cluster.

    Args:
        logits: (B, K) cluster logits.
        target: (B,) cluster indices in [0, K), or `UNKNOWN_CLUSTER` (-1) when unknown.

    Returns:
        Scalar: the mean over known items; 0 (with a zero gradient) when none is known.
    """
    # No boolean indexing and no `if known.any()`: either would wait for the GPU every step.
    per_item = F.cross_entropy(logits, target.clamp_min(0), reduction="none")
    known = (target != UNKNOWN_CLUSTER).to(per_item.dtype)
    return (per_item * known).sum() / known.sum().clamp_min(1.0)
