"""Losses: the paper's contrastive loss on D3, multi-positive InfoNCE, batch-hard triplet, and
the auxiliary cluster, property and class terms; `create_loss` combines them into one dict of
terms.

Each loss is a pure function tested on its own, wrapped by a thin module that chooses the slot
pairs and names the terms (``depth_touch_loss``); `CombinedLoss` adds ``cluster_loss``,
``property_loss``, ``class_loss`` and the total ``"loss"``. `register_loss` adds an objective
of one's own (``loss.kind``, with its settings under ``loss.options``), `list_losses` names
them all.
"""

from lookfeel.losses._pairwise import FabricPairLoss
from lookfeel.losses.cluster import UNKNOWN_CLUSTER, masked_cross_entropy
from lookfeel.losses.combined import (
    HEAD_TERMS,
    PAIR_LOSSES,
    TARGETS,
    CombinedLoss,
    LossError,
    create_loss,
    list_losses,
    register_loss,
)
from lookfeel.losses.contrastive import (
    ContrastiveD3Loss,
    contrastive_d3,
    tuple_distance,
    tuple_label,
)
from lookfeel.losses.distance import (
    euclidean_distance,
    mean_squared_distance,
    pairwise_euclidean,
    pairwise_mean_squared,
)
from lookfeel.losses.infonce import MultiPositiveInfoNCE, multi_positive_info_nce
from lookfeel.losses.property import masked_mse
from lookfeel.losses.triplet import BatchHardTripletLoss, batch_hard_triplet

__all__ = [
    "HEAD_TERMS",
    "PAIR_LOSSES",
    "TARGETS",
    "UNKNOWN_CLUSTER",
    "BatchHardTripletLoss",
    "CombinedLoss",
    "ContrastiveD3Loss",
    "FabricPairLoss",
    "LossError",
    "MultiPositiveInfoNCE",
    "batch_hard_triplet",
    "contrastive_d3",
    "create_loss",
    "euclidean_distance",
    "list_losses",
    "masked_cross_entropy",
    "masked_mse",
    "mean_squared_distance",
    "multi_positive_info_nce",
    "pairwise_euclidean",
    "pairwise_mean_squared",
    "register_loss",
    "tuple_distance",
    "tuple_label",
]
