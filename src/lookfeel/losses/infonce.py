"""Multi-positive InfoNCE between two slots (CLIP's loss, with every same-fabric item positive).

In a batch drawn from few fabrics, CLIP's one-positive-per-row targets call other items of the
same fabric negatives ("false negatives"), pushing apart what the paper wants together. Here row
i's target is uniform over every item of its fabric in the other slot (SupCon's L_out, Khosla et
al. 2020), and the loss is the KL divergence from that target to the softmax, so that it is 0
at its optimum whatever the number of positives.
"""

from __future__ import annotations

import math

import torch
import torch.nn.functional as F
from torch import Tensor, nn

from lookfeel.losses._pairwise import FabricPairLoss

__all__ = ["MultiPositiveInfoNCE", "multi_positive_info_nce"]


def _rows(logits: Tensor, pos: Tensor) -> Tensor:
    """Mean over rows with a positive of KL(uniform over the row's positives || softmax)."""
    logp = F.log_softmax(logits, dim=1)  # (N, M)
    n = pos.sum(dim=1)  # (N,) positives per row
    valid = (n > 0).to(logp.dtype)
    n_safe = n.clamp_min(1).to(logp.dtype)
    ce = -torch.where(pos, logp, torch.zeros_like(logp)).sum(dim=1) / n_safe  # (N,)
    # A weighted mean, not `[valid].mean()` behind `if valid.any()`: those wait for the GPU.
    # No positive anywhere: 0, with the graph kept.
    return ((ce - n_safe.log()) * valid).sum() / valid.sum().clamp_min(1.0)


def multi_positive_info_nce(
    a: Tensor,
    b: Tensor,
    fabric_a: Tensor,
    fabric_b: Tensor,
    logit_scale: Tensor | float,
) -> Tensor:
    """Symmetric multi-positive InfoNCE between two sets of embeddings.

    Args:
        a: (N, D) embeddings of one slot.
        b: (M, D) embeddings of another.
        fabric_a: (N,) fabric ids of ``a``.
        fabric_b: (M,) fabric ids of ``b``; every pair with equal ids is a positive.
        logit_scale: inverse temperature; logits are ``logit_scale * cos(a_i, b_j)``.

    Returns:
        Scalar: the mean of the a-to-b and b-to-a losses; each is
        ``-mean_{p in P(i)} log softmax_p - log |P(i)|`` averaged over rows with a positive.
    """
    a = F.normalize(a, dim=-1)
    b = F.normalize(b, dim=-1)
    logits = logit_scale * (a @ b.T)  # (N, M)
    pos = fabric_a[:, None] == fabric_b[None, :]  # (N, M)
    return 0.5 * (_rows(logits, pos) + _rows(logits.T, pos.T))


class MultiPositiveInfoNCE(FabricPairLoss):
    """Multi-positive InfoNCE over every slot pair, with a learnt or fixed temperature.

    With ``learn_temperature`` the module owns a parameter (the log inverse temperature): give
    ``loss.parameters()`` to the optimiser and keep ``loss.state_dict()`` in checkpoints.
    """

    loss_name = "InfoNCE"

    def __init__(
        self,
        temperature: float = 0.07,
        learn_temperature: bool = True,
        max_logit_scale: float = 100.0,
    ) -> None:
        """Configure the loss.

        Args:
            temperature: the (starting) temperature (CLIP: 0.07).
            learn_temperature: learn it.
            max_logit_scale: clamp of the inverse temperature (CLIP: 100).
        """
        super().__init__()
        if temperature <= 0:
            raise ValueError(f"temperature must be > 0, got {temperature}")
        self.max_logit_scale = max_logit_scale
        self.log_logit_scale: nn.Parameter | None = None
        self._fixed_scale = 1.0 / temperature
        if learn_temperature:
            self.log_logit_scale = nn.Parameter(torch.tensor(math.log(1.0 / temperature)))

    def logit_scale(self) -> Tensor | float:
        """The current inverse temperature, clamped to ``max_logit_scale``."""
        if self.log_logit_scale is None:
            return min(self._fixed_scale, self.max_logit_scale)
        return self.log_logit_scale.exp().clamp(max=self.max_logit_scale)

    def pair_term(self, ea: Tensor, eb: Tensor, fa: Tensor, fb: Tensor) -> Tensor:
        """Multi-positive InfoNCE between slots a and b at the current temperature."""
        return multi_positive_info_nce(ea, eb, fa, fb, self.logit_scale())
