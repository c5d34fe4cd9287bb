"""Batch-hard triplet loss between two slots (Hermans, Beyer & Leibe 2017), by fabric id.

Each anchor in one slot is paired with its farthest same-fabric item and its nearest
other-fabric item in the other slot: ``max(0, d(a, p_hard) - d(a, n_hard) + margin)``.
"""

from __future__ import annotations

from collections.abc import Callable

import torch
import torch.nn.functional as F
from torch import Tensor

from lookfeel.losses._pairwise import FabricPairLoss
from lookfeel.losses.distance import pairwise_euclidean

__all__ = ["BatchHardTripletLoss", "batch_hard_triplet"]

PairwiseFn = Callable[[Tensor, Tensor], Tensor]


def batch_hard_triplet(
    anchor: Tensor,
    candidate: Tensor,
    anchor_fabric: Tensor,
    candidate_fabric: Tensor,
    margin: float = 0.2,
    distance: PairwiseFn = pairwise_euclidean,
) -> Tensor:
    """Batch-hard triplet loss from anchors in one slot to candidates in another.

    Args:
        anchor: (N, D).
        candidate: (M, D).
        anchor_fabric: (N,) fabric ids.
        candidate_fabric: (M,) fabric ids.
        margin: the triplet margin.
        distance: (N, D), (M, D) -> (N, M) distances.

    Returns:
        Scalar: the mean over anchors that have both a positive and a negative (0 if none).
    """
    d = distance(anchor, candidate)  # (N, M)
    pos = anchor_fabric[:, None] == candidate_fabric[None, :]  # (N, M)
    valid = pos.any(dim=1) & (~pos).any(dim=1)  # (N,)
    inf = torch.full_like(d, float("inf"))
    hardest_pos = torch.where(pos, d, -inf).amax(dim=1)  # (N,)
    hardest_neg = torch.where(pos, inf, d).amin(dim=1)  # (N,)
    per_anchor = torch.where(valid, F.relu(hardest_pos - hardest_neg + margin), 0.0)
    # A weighted mean, not `[valid].mean()` behind `if valid.any()`: those wait for the GPU.
    return per_anchor.sum() / valid.sum().clamp_min(1)


class BatchHardTripletLoss(FabricPairLoss):
    """Symmetric batch-hard triplet loss over every slot pair."""

    loss_name = "the triplet loss"

    def __init__(self, margin: float = 0.2, distance: PairwiseFn = pairwise_euclidean) -> None:
        """Configure the loss.

        Args:
            margin: the triplet margin, in units of ``distance``.
            distance: pairwise distance, (N, D), (M, D) -> (N, M).
        """
        super().__init__()
        self.margin = margin
        self.distance = distance

    def pair_term(self, ea: Tensor, eb: Tensor, fa: Tensor, fb: Tensor) -> Tensor:
        """The mean of the a-to-b and b-to-a batch-hard triplet losses."""
        return 0.5 * (
            batch_hard_triplet(ea, eb, fa, fb, self.margin, self.distance)
            + batch_hard_triplet(eb, ea, fb, fa, self.margin, self.distance)
        )
