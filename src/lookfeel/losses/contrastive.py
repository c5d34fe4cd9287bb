"""The paper's contrastive loss on the tuple distance D3 (section 4.1, equations 1-2).

For one tuple of embeddings E_1 ... E_n of n >= 2 slots (paper: depth, colour, touch),
D3 = sum over slot pairs i < j of D(E_i, E_j), and

    L = 1/2 (1 - Y) D3^2 + 1/2 Y max(0, m - D3)^2,

with Y = 0 when the tuple comes from one fabric, Y = 1 when not, and margin m = 2 (Chopra,
Hadsell & LeCun 2005). With two slots this is the classic contrastive loss.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence

import torch
import torch.nn.functional as F
from torch import Tensor, nn

from lookfeel.losses._naming import slot_pairs, term_name
from lookfeel.losses.distance import euclidean_distance

__all__ = ["ContrastiveD3Loss", "contrastive_d3", "tuple_distance", "tuple_label"]

DistanceFn = Callable[[Tensor, Tensor], Tensor]


def tuple_distance(
    embeddings: Sequence[Tensor], distance: DistanceFn = euclidean_distance
) -> Tensor:
    """D3: the sum of the distances of every pair of a tuple's embeddings (paper equation 1).

    Args:
        embeddings: n >= 2 tensors (B, D), one per slot; row b of each is tuple b.
        distance: row-wise distance, (B, D), (B, D) -> (B,).

    Returns:
        (B,) D3 per tuple.
    """
    if len(embeddings) < 2:
        raise ValueError(f"a tuple distance needs at least 2 embeddings, got {len(embeddings)}")
    n = len(embeddings)
    return torch.stack(
        [distance(embeddings[i], embeddings[j]) for i in range(n) for j in range(i + 1, n)]
    ).sum(dim=0)  # (pairs, B) -> (B,)


def contrastive_d3(
    embeddings: Sequence[Tensor],
    y: Tensor,
    margin: float = 2.0,
    distance: DistanceFn = euclidean_distance,
) -> Tensor:
    """The paper's contrastive loss on D3 (equation 2), averaged over the batch.

    Args:
        embeddings: n >= 2 tensors (B, D), one per slot.
        y: (B,) 0 where the tuple is of one fabric, 1 where not (bool, int or float).
        margin: m; tuples of different fabrics stop contributing once D3 >= m.
        distance: row-wise distance (paper: Euclidean; authors' code: mean squared).

    Returns:
        Scalar loss.
    """
    d = tuple_distance(embeddings, distance)  # (B,)
    y = y.to(d.dtype)
    loss = 0.5 * (1 - y) * d.pow(2) + 0.5 * y * F.relu(margin - d).pow(2)
    return loss.mean()


def tuple_label(fabric: Mapping[str, Tensor], slots: Sequence[str]) -> Tensor:
    """Y per tuple from per-slot fabric ids: 0 when every slot shows one fabric, else 1.

    Args:
        fabric: slot -> (B,) fabric ids.
        slots: the tuple's slots.

    Returns:
        (B,) float labels.
    """
    ids = torch.stack([fabric[s] for s in slots])  # (n, B)
    return (ids != ids[:1]).any(dim=0).float()


class ContrastiveD3Loss(nn.Module):
    """Contrastive loss over a batch of tuples, on D3 or per slot pair.

    Returns one term named after all slots (``depth_color_touch_loss``) on D3, or with
    ``per_pair`` one term per slot pair (``depth_touch_loss`` ...).
    """

    def __init__(
        self, margin: float = 2.0, distance: DistanceFn = euclidean_distance, per_pair: bool = False
    ) -> None:
        """Configure the loss.

        Args:
            margin: m (paper: 2).
            distance: row-wise distance between two embeddings.
            per_pair: one contrastive term per slot pair instead of one on D3.
        """
        super().__init__()
        self.margin = margin
        self.distance = distance
        self.per_pair = per_pair

    def forward(
        self,
        embeddings: Mapping[str, Tensor],
        y: Tensor | None = None,
        fabric: Mapping[str, Tensor] | None = None,
    ) -> dict[str, Tensor]:
        """Compute the terms.

        Args:
            embeddings: slot -> (B, D), at least two slots.
            y: (B,) tuple labels (0 same fabric, 1 different). When ``None`` they come from
                ``fabric``. Per pair, a pair's own label comes from its two fabric ids when
                ``fabric`` is given, else from ``y``.
            fabric: slot -> (B,) fabric ids.

        Returns:
            Term name -> scalar loss.
        """
        slots = list(embeddings)
        if len(slots) < 2:
            raise ValueError(f"the contrastive loss needs at least 2 slots, got {slots}")
        if y is None and fabric is None:
            raise ValueError("the contrastive loss needs y (0 same fabric, 1 not) or fabric ids")
        if not self.per_pair:
            label = y if y is not None else tuple_label(fabric or {}, slots)
            e = [embeddings[s] for s in slots]
            return {term_name(*slots): contrastive_d3(e, label, self.margin, self.distance)}
        terms = {}
        for a, b in slot_pairs(slots):
            pair_y = tuple_label(fabric, (a, b)) if fabric is not None else y
            assert pair_y is not None
            terms[term_name(a, b)] = contrastive_d3(
                [embeddings[a], embeddings[b]], pair_y, self.margin, self.distance
            )
        return terms
