"""The shared shape of the losses that give one term per slot pair, positives by fabric id."""

from __future__ import annotations

from collections.abc import Mapping
from typing import ClassVar

from torch import Tensor, nn

from lookfeel.losses._naming import require_fabric, slot_pairs, term_name

__all__ = ["FabricPairLoss"]


class FabricPairLoss(nn.Module):
    """Base class: checks the slots and fabric ids, then one `pair_term` per slot pair.

    Attributes:
        loss_name: how error messages name the loss (``InfoNCE``, ``the triplet loss``).
    """

    loss_name: ClassVar[str]

    def forward(
        self,
        embeddings: Mapping[str, Tensor],
        y: Tensor | None = None,
        fabric: Mapping[str, Tensor] | None = None,
    ) -> dict[str, Tensor]:
        """One term per slot pair (``depth_touch_loss`` ...).

        Args:
            embeddings: slot -> (B, D), at least two slots.
            y: unused (positives come from fabric ids).
            fabric: slot -> (B,) fabric ids; required.

        Returns:
            Term name -> scalar loss.
        """
        slots = list(embeddings)
        if len(slots) < 2:
            raise ValueError(f"{self.loss_name} needs at least 2 slots, got {slots}")
        fab = require_fabric(fabric, slots, self.loss_name)
        return {
            term_name(a, b): self.pair_term(embeddings[a], embeddings[b], fab[a], fab[b])
            for a, b in slot_pairs(slots)
        }

    def pair_term(self, ea: Tensor, eb: Tensor, fa: Tensor, fb: Tensor) -> Tensor:
        """The scalar loss between slots a and b: embeddings (B, D) and fabric ids (B,)."""
        raise NotImplementedError
