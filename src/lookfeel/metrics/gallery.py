"""Whole-gallery retrieval: mAP, recall@k and median rank, with fabric-level relevance.

A gallery item is relevant to a query when it shows the query's fabric. Every query is ranked
against the whole gallery (minus its own item for same-modality pairs). Ties are broken
uniformly at random and every value is the exact expectation over that tie-break (see
``_ranking``); the chance levels are exact expectations over uniformly random rankings.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray
from scipy.special import digamma

from lookfeel.metrics._ranking import (
    IntArray,
    ScanResult,
    none_first_probability,
    prepare,
    scan,
)

__all__ = [
    "GalleryResult",
    "chance_average_precision",
    "chance_median_rank",
    "chance_recall",
    "gallery_metrics",
    "gallery_result_from",
]


@dataclass(frozen=True)
class GalleryResult:
    """Per-query whole-gallery metrics, their summaries and chance levels."""

    recall_ks: tuple[int, ...]
    ap: NDArray[np.float64]
    """(Q,) average precision; NaN for queries with no relevant item."""
    first_rank: NDArray[np.float64]
    """(Q,) 1-based rank of the first relevant item (expected over tie-breaks)."""
    recall: NDArray[np.float64]
    """(Q, K) 1 when the first relevant item ranks within k (expected over tie-breaks)."""
    map: float
    recall_mean: NDArray[np.float64]
    """(K,) recall@k: fraction of queries whose first relevant item ranks within k."""
    median_rank: float
    """Median over queries of ``first_rank``."""
    chance_map: float
    chance_recall: NDArray[np.float64]
    chance_median_rank: float
    n_queries: int


def chance_average_precision(n_gallery: ArrayLike, n_relevant: ArrayLike) -> NDArray[np.float64]:
    """Expected AP of a uniformly random ranking of G items of which R are relevant.

    ``E[AP] = (H_G + (R - 1) / (G - 1) (G - H_G)) / G`` with ``H_G = sum_{i<=G} 1/i``, from
    ``E[rel_i rel_j] = R (R - 1) / (G (G - 1))`` for i != j.
    """
    g = np.asarray(n_gallery, dtype=np.float64)
    r = np.asarray(n_relevant, dtype=np.float64)
    h = digamma(g + 1.0) + np.euler_gamma
    frac = np.where(g > 1, (r - 1.0) / np.maximum(g - 1.0, 1.0), 0.0)
    return np.asarray((h + frac * (g - h)) / g, dtype=np.float64)


def chance_recall(n_gallery: ArrayLike, n_relevant: ArrayLike, k: int) -> NDArray[np.float64]:
    """P(a random ranking puts a relevant item within the first k): ``1 - C(G-R, k)/C(G, k)``."""
    g = np.asarray(n_gallery, dtype=np.float64)
    r = np.asarray(n_relevant, dtype=np.float64)
    return 1.0 - none_first_probability(g - r, r, k)


def chance_median_rank(n_gallery: ArrayLike, n_relevant: ArrayLike) -> float:
    """Median of the first relevant rank under random rankings, pooled over the queries.

    The rank of query q exceeds j with probability ``C(G_q - R_q, j) / C(G_q, j)``; the result is
    the smallest j at which the average of these CDFs reaches 1/2 (the limit of the median
    over many queries).
    """
    g = np.asarray(n_gallery, dtype=np.int64).reshape(-1)
    r = np.asarray(n_relevant, dtype=np.int64).reshape(-1)
    if len(g) == 0:
        return float("nan")
    pairs, weight = np.unique(np.stack([g, r], axis=1), axis=0, return_counts=True)
    j = np.arange(1, int(g.max()) + 1)
    survive = np.zeros(len(j))
    for (gg, rr), w in zip(pairs, weight, strict=True):
        survive += w * none_first_probability(gg - rr, rr, j)
    cdf = 1.0 - survive / weight.sum()
    return float(j[np.argmax(cdf >= 0.5 - 1e-12)])


def gallery_metrics(
    dist: ArrayLike,
    query_fabric: ArrayLike,
    gallery_fabric: ArrayLike,
    recall_ks: tuple[int, ...] = (1, 5, 10),
    exclude_self: ArrayLike | None = None,
) -> GalleryResult:
    """mAP, recall@k and median first-relevant rank of each query against the whole gallery.

    Args:
        dist: (Q, G) distances.
        query_fabric: (Q,) fabric id of each query.
        gallery_fabric: (G,) fabric id of each gallery item; items of the query's fabric are
            relevant.
        recall_ks: the k of recall@k.
        exclude_self: (Q,) gallery index of each query's own item, or a (Q, G) mask: dropped
            from the ranking (same-modality pairs).

    Returns:
        `GalleryResult`; queries whose fabric has no gallery item are NaN and left out.
    """
    ks = tuple(int(k) for k in recall_ks)
    if any(k < 1 for k in ks):
        raise ValueError(f"recall_ks must be positive; got {recall_ks!r}")
    prep = prepare(dist, query_fabric, gallery_fabric, exclude_self)
    res = scan(prep, m=0, ks=(1,), recall_ks=ks, pick=False)
    return gallery_result_from(res, ks)


def gallery_result_from(res: ScanResult, recall_ks: tuple[int, ...]) -> GalleryResult:
    """Summaries and chance levels of a scan's per-query gallery values."""
    ok = res.n_relevant > 0
    g: IntArray = res.n_gallery[ok]
    r: IntArray = res.n_relevant[ok]
    if not ok.any():
        nan = float("nan")
        k_nan = np.full(len(recall_ks), np.nan)
        return GalleryResult(
            recall_ks, res.ap, res.first_rank, res.recall, nan, k_nan, nan, nan, k_nan, nan, 0
        )
    return GalleryResult(
        recall_ks=recall_ks,
        ap=res.ap,
        first_rank=res.first_rank,
        recall=res.recall,
        map=float(res.ap[ok].mean()),
        recall_mean=res.recall[ok].mean(axis=0),
        median_rank=float(np.median(res.first_rank[ok])),
        chance_map=float(chance_average_precision(g, r).mean()),
        chance_recall=np.array([float(chance_recall(g, r, k).mean()) for k in recall_ks]),
        chance_median_rank=chance_median_rank(g, r),
        n_queries=int(ok.sum()),
    )
