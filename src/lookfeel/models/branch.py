"""One modality's branch: backbone, press pooling, optional projection and auxiliary heads."""

from __future__ import annotations

import math

import torch
import torch.nn.functional as F
from torch import Tensor, nn

from lookfeel.modality import Modality
from lookfeel.models.backbone import Backbone

__all__ = ["CLASSES", "CLUSTER", "PROPERTY", "Branch", "BranchEnsemble"]

CLUSTER = "cluster"
"""Name of the cluster-classifier head's output (the paper's Auxiliary Net)."""
PROPERTY = "property"
"""Name of the property-regression head's output."""
CLASSES = "classes"
"""Name of the class heads' output: every head's logits side by side (``model.class_heads``)."""


class Branch(nn.Module):
    """Embeds one modality's inputs: the network G_W of paper section 4.1.

    Touch inputs carry a press axis, (B, P, C, H, W) (C = 3, or 3 per frame with
    ``data.touch_frames``): every press goes through the same
    backbone and the P embeddings are pooled element-wise (max: the paper's Multi-input Net,
    Figure 4c; P = 1 is the plain net). Pooling happens on the backbone's embedding (fc7), then
    the optional projection and L2 normalisation follow.
    """

    def __init__(
        self,
        modality: Modality,
        backbone: Backbone,
        *,
        embed_dim: int | None = None,
        normalize: bool = False,
        press_pool: str = "max",
        num_clusters: int = 0,
        num_properties: int = 0,
        class_sizes: tuple[int, ...] = (),
    ) -> None:
        """Build a branch.

        Args:
            modality: what it embeds; a pooled one's inputs (`Modality.pooled`: touch) have
                a press axis.
            backbone: a `Backbone` with ``in_channels`` fitting the modality.
            embed_dim: size of a linear projection of the backbone's embedding; ``None``: none.
            normalize: L2-normalise the embedding.
            press_pool: ``max`` or ``mean`` over presses.
            num_clusters: classes of a linear cluster head on the embedding; 0: no head.
            num_properties: outputs of a linear property-regression head; 0: no head.
            class_sizes: classes of each linear class head (one per categorical label); the
                heads share one linear layer whose outputs are their logits side by side.
        """
        super().__init__()
        if press_pool not in ("max", "mean"):
            raise ValueError(f"press_pool must be 'max' or 'mean', got {press_pool!r}")
        self.modality = Modality(modality)
        self.pressed = self.modality.pooled
        """Inputs have a press axis, pooled by ``press_pool`` (`Modality.pooled`: touch)."""
        self.backbone = backbone
        self.in_channels = backbone.in_channels
        """Channels of one input image (or press)."""
        self.project: nn.Module = (
            nn.Linear(backbone.embed_dim, embed_dim) if embed_dim is not None else nn.Identity()
        )
        self.embed_dim = embed_dim if embed_dim is not None else backbone.embed_dim
        self.normalize = normalize
        self.press_pool = press_pool
        self.cluster_head = nn.Linear(self.embed_dim, num_clusters) if num_clusters else None
        self.property_head = nn.Linear(self.embed_dim, num_properties) if num_properties else None
        self.class_sizes = tuple(class_sizes)
        self.class_head = nn.Linear(self.embed_dim, sum(class_sizes)) if sum(class_sizes) else None

    def trunk(self, x: Tensor) -> Tensor:
        """The backbone's frozen trunk, applied per image (per press for touch).

        Args:
            x: (B, C, H, W), or (B, P, C, H, W) for touch.

        Returns:
            (B, *F), or (B, P, *F) for touch.
        """
        if not self.pressed:
            return self.backbone.trunk(x)
        b, p = x.shape[:2]
        f = self.backbone.trunk(x.flatten(0, 1))  # (B * P, C, H, W) -> (B * P, *F)
        return f.unflatten(0, (b, p))  # -> (B, P, *F)

    def forward(self, x: Tensor, from_trunk: bool = False) -> Tensor:
        """Embed a batch.

        Args:
            x: images (B, C, H, W), or (B, P, C, H, W) for touch, in [0, 1], or
                (B, P, V, C, H, W) for touch with V views of each press (a press's feature
                is the mean of its views' before the press pooling and projection); with
                ``from_trunk``, the output of `trunk` for those images instead.
            from_trunk: ``x`` holds trunk features (e.g. cached), so skip the trunk.

        Returns:
            (B, D) embeddings.
        """
        lead: tuple[int, ...] = ()
        if self.pressed:
            # (B, P, ...) presses, or (B, P, V, C, H, W): V views of each press.
            views = not from_trunk and x.dim() == 6
            lead = tuple(x.shape[: 3 if views else 2])
            x = x.flatten(0, len(lead) - 1)  # -> (B * P [* V], ...)
        f = x if from_trunk else self.backbone.trunk(x)
        e = self.backbone.head(f)  # (N, D0)
        if self.pressed:
            e = e.unflatten(0, lead)  # -> (B, P [, V], D0)
            if len(lead) == 3:
                e = e.mean(dim=2)  # a press is the mean of its views (before projection)
            e = e.amax(dim=1) if self.press_pool == "max" else e.mean(dim=1)  # -> (B, D0)
        e = self.project(e)  # (B, D0) -> (B, D)
        if self.normalize:
            e = F.normalize(e, dim=-1)
        return e

    def heads(self, e: Tensor) -> dict[str, Tensor]:
        """The auxiliary heads on the embedding.

        Args:
            e: (B, D) embeddings from `forward`.

        Returns:
            ``{"cluster": (B, K) logits, "property": (B, Q) predictions, "classes": (B, sum of
            class_sizes) logits}``, for the heads that exist.
        """
        out = {}
        if self.cluster_head is not None:
            out[CLUSTER] = self.cluster_head(e)
        if self.property_head is not None:
            out[PROPERTY] = self.property_head(e)
        if self.class_head is not None:
            out[CLASSES] = self.class_head(e)
        return out


class BranchEnsemble(Branch):
    """N separately trained branches of one modality, used as one (``model.members``).

    Each member is a whole `Branch` (backbone, projection, heads). The ensemble's embedding is
    the members' embeddings side by side, divided by sqrt(N), so its squared Euclidean
    distances and dot products are the members' averaged (and with L2-normalised members it is
    a unit vector). Its heads average the members' head outputs (class logits, cluster logits,
    property predictions), each member reading its own part of the embedding, exactly as it
    did in training. To everything that embeds (``embed``, ``evaluate``, ``cv``, ``predict``,
    the index, export) it is a `Branch`.

    The members are trained one by one as ordinary runs (`lookfeel.train.train` with
    ``model.members`` > 1: deep ensembles, Lakshminarayanan et al. 2017), each with its own
    seed, and then assembled; the ensemble itself is never trained, so it has no one trunk.
    """

    def __init__(self, members: list[Branch]) -> None:
        """Assemble members of one modality, embedding size and normalisation (at least two).

        Raises:
            ValueError: fewer than two members, or members that differ in modality, size or
                normalisation.
        """
        nn.Module.__init__(self)
        if len(members) < 2:
            raise ValueError(f"an ensemble needs at least two members, got {len(members)}")
        first = members[0]
        if any(
            m.modality is not first.modality
            or m.embed_dim != first.embed_dim
            or m.normalize != first.normalize
            for m in members
        ):
            raise ValueError(
                "ensemble members must share one modality, embedding size and normalisation"
            )
        self.members = nn.ModuleList(members)
        self.modality = first.modality
        self.pressed = first.pressed
        self.in_channels = first.in_channels
        self.embed_dim = first.embed_dim * len(members)
        self.normalize = first.normalize
        self.press_pool = first.press_pool
        self.class_sizes = first.class_sizes

    def member_branches(self) -> list[Branch]:
        """The members, in order."""
        return [m for m in self.members if isinstance(m, Branch)]

    def trunk(self, x: Tensor) -> Tensor:
        """Not available: the members are trained separately, each with its own trunk."""
        raise NotImplementedError(
            "an ensemble (model.members > 1) has no one trunk: its members are trained as "
            "separate runs"
        )

    def forward(self, x: Tensor, from_trunk: bool = False) -> Tensor:
        """The members' embeddings side by side, over sqrt(N): (B, N * D).

        Raises:
            NotImplementedError: ``from_trunk`` (see `trunk`).
        """
        if from_trunk:
            raise NotImplementedError("an ensemble has no one trunk: embed its inputs whole")
        parts = [m(x) for m in self.member_branches()]
        return torch.cat(parts, dim=-1) / math.sqrt(len(parts))

    def split(self, e: Tensor) -> list[Tensor]:
        """Each member's own embedding from an ensemble embedding (the inverse of `forward`'s
        concatenation)."""
        n = len(self.members)
        return [part * math.sqrt(n) for part in e.split(self.embed_dim // n, dim=-1)]

    def heads(self, e: Tensor) -> dict[str, Tensor]:
        """The members' heads, each on its own part of ``e``, averaged."""
        parts = self.split(e)
        outs = [m.heads(p) for m, p in zip(self.member_branches(), parts, strict=True)]
        return {k: torch.stack([o[k] for o in outs]).mean(0) for k in outs[0]}
