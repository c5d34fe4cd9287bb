"""Metrics: pure functions of distances, fabric ids and labels (they know nothing of models).

- `pairwise_distances`: (Q, D), (G, D) -> (Q, G) Euclidean distances.
- `pick_k_of_n_exact`, `pick_k_of_n_sampled`: the paper's pick-1-of-10 (section 5.1).
- `gallery_metrics`: mAP, recall@k, median rank over the whole gallery, with chance levels.
- `bootstrap_ci`, `mean_and_spread`: intervals over test fabrics, spread over seeds.
- `group_queries`: max-pooled multi-press touch queries (the Multi-input Net): its groups
  (`group_members`) and their pooling (`max_pool_groups`) are also there on their own.
- `match_probabilities`, `fit_temperature`, `confusion_matrix`, `cluster_confusion_matrix`,
  `reliability_curve`: ``P ∝ exp(-c D^2)``, its confusion matrices and calibration (5.2).
- `property_probe`: predict physical labels from embeddings.
- `score_pairs`: the one scoring path: ordered modality pairs (`lookfeel.modality.Pair`)
  scored by a `ScoringProtocol` from embeddings; `score_distances` scores one distance matrix,
  `pair_distances` walks the pairs' matrices, `flat_metrics` flattens the result.
"""

from lookfeel.metrics.bootstrap import bootstrap_ci, fabric_weights, mean_and_spread
from lookfeel.metrics.calibration import (
    PAPER_C,
    ReliabilityCurve,
    expected_calibration_error,
    fabric_predictions,
    fabric_probabilities,
    fit_temperature,
    match_probabilities,
    reliability_curve,
)
from lookfeel.metrics.confusion import (
    Confusion,
    cluster_confusion_matrix,
    confusion_matrix,
    order_by_cluster,
)
from lookfeel.metrics.distances import pairwise_distances
from lookfeel.metrics.gallery import (
    GalleryResult,
    chance_average_precision,
    chance_median_rank,
    chance_recall,
    gallery_metrics,
)
from lookfeel.metrics.grouping import (
    PressGroups,
    group_members,
    group_queries,
    max_pool_groups,
)
from lookfeel.metrics.pick import (
    PickResult,
    SampledPickResult,
    n_effective,
    pick_k_of_n_exact,
    pick_k_of_n_sampled,
)
from lookfeel.metrics.properties import property_probe
from lookfeel.metrics.scoring import (
    EXACT_PICK,
    PAPER_PROTOCOL,
    PairDistances,
    PairScore,
    QuerySet,
    ScoringProtocol,
    flat_metrics,
    pair_distances,
    score_distances,
    score_pairs,
)

__all__ = [
    "EXACT_PICK",
    "PAPER_C",
    "PAPER_PROTOCOL",
    "Confusion",
    "GalleryResult",
    "PairDistances",
    "PairScore",
    "PickResult",
    "PressGroups",
    "QuerySet",
    "ReliabilityCurve",
    "SampledPickResult",
    "ScoringProtocol",
    "bootstrap_ci",
    "chance_average_precision",
    "chance_median_rank",
    "chance_recall",
    "cluster_confusion_matrix",
    "confusion_matrix",
    "expected_calibration_error",
    "fabric_predictions",
    "fabric_probabilities",
    "fabric_weights",
    "fit_temperature",
    "flat_metrics",
    "gallery_metrics",
    "group_members",
    "group_queries",
    "match_probabilities",
    "max_pool_groups",
    "mean_and_spread",
    "n_effective",
    "order_by_cluster",
    "pair_distances",
    "pairwise_distances",
    "pick_k_of_n_exact",
    "pick_k_of_n_sampled",
    "property_probe",
    "reliability_curve",
    "score_distances",
    "score_pairs",
]
