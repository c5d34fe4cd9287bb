"""Fabric and cluster confusion matrices of match probabilities (paper section 5.2, Figure 8).

Entry (a, b) of the fabric matrix is the mean, over the query items of fabric a, of the
probability (`fabric_probabilities`, ``P ∝ exp(-c D^2)``) given to gallery fabric b: the
paper's "possibility of mismatching the touch data from the current fabric to the other
fabrics". Rows sum to 1. The figure orders fabrics so that similar ones sit together;
`order_by_cluster` gives that order from the clusters.
"""

from __future__ import annotations

from collections.abc import Hashable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from lookfeel.metrics.calibration import PAPER_C, fabric_probabilities

__all__ = ["Confusion", "cluster_confusion_matrix", "confusion_matrix", "order_by_cluster"]


@dataclass(frozen=True)
class Confusion:
    """A confusion matrix with its row (query) and column (gallery) labels."""

    matrix: NDArray[np.float64]
    """(rows, cols) mean probability; rows sum to 1 when every column is present."""
    rows: NDArray[np.generic]
    """Query fabric (or cluster) of each row."""
    cols: NDArray[np.generic]
    """Gallery fabric (or cluster) of each column."""


def confusion_matrix(
    dist: ArrayLike,
    query_fabric: ArrayLike,
    gallery_fabric: ArrayLike,
    c: float = PAPER_C,
    exclude_self: ArrayLike | None = None,
    order: Sequence[Hashable] | ArrayLike | None = None,
) -> Confusion:
    """Fabric-level confusion: rows query fabrics, columns gallery fabrics (paper Figure 8).

    Args:
        dist: (Q, G) distances.
        query_fabric: (Q,) fabric id of each query.
        gallery_fabric: (G,) fabric id of each gallery item.
        c: the coefficient in ``P ∝ exp(-c D^2)``.
        exclude_self: (Q,) own gallery index of each query (or a (Q, G) mask), given
            probability 0.
        order: fabric ids in the order wanted for rows and columns (e.g. `order_by_cluster`);
            fabrics missing from it are dropped, ids absent from the data are skipped.
            Default: sorted ids.

    Returns:
        `Confusion` of shape (query fabrics, gallery fabrics).
    """
    probs, g_fabrics = fabric_probabilities(dist, gallery_fabric, c, exclude_self)
    q_fabrics, qi = np.unique(np.asarray(query_fabric).reshape(-1), return_inverse=True)
    if len(qi) != len(probs):
        raise ValueError(f"query_fabric has {len(qi)} entries for {len(probs)} dist rows")
    sums = np.zeros((len(q_fabrics), len(g_fabrics)))
    np.add.at(sums, qi, probs)
    matrix = sums / np.bincount(qi, minlength=len(q_fabrics))[:, None]
    if order is not None:
        wanted = list(np.asarray(order).reshape(-1))
        r = [int(np.flatnonzero(q_fabrics == f)[0]) for f in wanted if (q_fabrics == f).any()]
        k = [int(np.flatnonzero(g_fabrics == f)[0]) for f in wanted if (g_fabrics == f).any()]
        return Confusion(matrix[np.ix_(r, k)], q_fabrics[r], g_fabrics[k])
    return Confusion(matrix, q_fabrics, g_fabrics)


def _clusters_of(
    fabrics: NDArray[np.generic], fabric_cluster: Mapping[Hashable, Hashable]
) -> list[Hashable]:
    missing = [f for f in fabrics.tolist() if f not in fabric_cluster]
    if missing:
        raise ValueError(f"fabric_cluster has no cluster for fabric(s) {missing[:5]}")
    return [fabric_cluster[f] for f in fabrics.tolist()]


def cluster_confusion_matrix(
    dist: ArrayLike,
    query_fabric: ArrayLike,
    gallery_fabric: ArrayLike,
    fabric_cluster: Mapping[Hashable, Hashable],
    c: float = PAPER_C,
    exclude_self: ArrayLike | None = None,
) -> Confusion:
    """Cluster-level confusion (Figure 8b): probability mass per gallery cluster.

    Entry (A, B) is the mean, over query items whose fabric is in cluster A, of the summed
    probability of the gallery fabrics in cluster B.

    Args:
        fabric_cluster: cluster of every fabric id (query and gallery).
    """
    probs, g_fabrics = fabric_probabilities(dist, gallery_fabric, c, exclude_self)
    qf = np.asarray(query_fabric).reshape(-1)
    if len(qf) != len(probs):
        raise ValueError(f"query_fabric has {len(qf)} entries for {len(probs)} dist rows")
    g_cl = np.asarray(_clusters_of(g_fabrics, fabric_cluster))
    q_cl = np.asarray(_clusters_of(qf, fabric_cluster))
    clusters = np.unique(np.concatenate([g_cl, q_cl]))
    gi = np.searchsorted(clusters, g_cl)
    qi = np.searchsorted(clusters, q_cl)
    onehot = np.zeros((len(g_fabrics), len(clusters)))
    onehot[np.arange(len(g_fabrics)), gi] = 1.0
    per_query = probs @ onehot  # (Q, F) @ (F, C) -> (Q, C)
    sums = np.zeros((len(clusters), len(clusters)))
    np.add.at(sums, qi, per_query)
    counts = np.bincount(qi, minlength=len(clusters))
    present = counts > 0
    col_present = np.isin(clusters, g_cl)
    matrix = sums[present][:, col_present] / counts[present][:, None]
    return Confusion(matrix, clusters[present], clusters[col_present])


def order_by_cluster(
    fabrics: ArrayLike,
    fabric_cluster: Mapping[Hashable, Hashable],
    key: Mapping[Hashable, float] | None = None,
) -> NDArray[np.generic]:
    """Fabric ids ordered by cluster, then by ``key`` (e.g. a property) or id within a cluster.

    Puts fabrics that humans group together next to each other, as in the paper's Figure 8,
    so confusion between similar fabrics shows as bright blocks near the diagonal.
    """
    f = np.unique(np.asarray(fabrics).reshape(-1))
    clusters = _clusters_of(f, fabric_cluster)
    within = [key[x] if key is not None else 0.0 for x in f.tolist()]
    order = sorted(range(len(f)), key=lambda i: (clusters[i], within[i], f[i]))
    return f[np.asarray(order, dtype=np.int64)]
