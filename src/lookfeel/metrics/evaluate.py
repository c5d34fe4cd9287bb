"""Every protocol for every (query, gallery) modality pair, from one distance matrix each.

`evaluate_pair` scores one ordered pair; `all_pairs` scores all of them (same-modality pairs
included, each query's own item excluded) and returns one flat dict of JSON-able floats keyed
``"{query}_to_{gallery}_{metric}"`` (e.g. ``touch_to_depth_top1``):

- ``top{k}``: exact pick-k-of-n (`pick_k_of_n_exact`, the paper's Figure 5 and Tables 1-2),
  ``top{k}_sampled`` and ``top{k}_sampled_se`` the paper's sampled protocol, ``top{k}_chance``;
- ``map``, ``recall{k}``, ``median_rank`` over the whole gallery (`gallery_metrics`), each with
  ``_chance``;
- ``_ci_low`` / ``_ci_high`` for each of those: a percentile bootstrap over query fabrics;
- ``n_effective`` (candidates per draw), ``n_queries``, ``n_fabrics``.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
from numpy.typing import ArrayLike, NDArray

from lookfeel.metrics._ranking import Prepared, prepare, scan
from lookfeel.metrics.bootstrap import bootstrap_ci, fabric_weights
from lookfeel.metrics.distances import pairwise_distances
from lookfeel.metrics.gallery import gallery_result_from
from lookfeel.metrics.pick import (
    n_effective,
    pick_result_from,
    sampled_from,
    warn_if_short,
)
from lookfeel.modality import Modality

__all__ = ["all_pairs", "evaluate_distances", "evaluate_pair"]


def evaluate_distances(
    dist: ArrayLike,
    query_fabric: ArrayLike,
    gallery_fabric: ArrayLike,
    *,
    prefix: str = "",
    exclude_self: ArrayLike | None = None,
    n: int = 10,
    ks: tuple[int, ...] = (1, 3),
    recall_ks: tuple[int, ...] = (1, 5, 10),
    sampled: bool = True,
    queries_per_fabric: int = 15,
    repeats: int = 10,
    n_boot: int = 1000,
    alpha: float = 0.05,
    seed: int = 0,
) -> dict[str, float]:
    """All metrics of one (Q, G) distance matrix as a flat dict (keys start with ``prefix``).

    One row sort serves the exact pick-k-of-n and the gallery metrics; the bootstrap draws
    query fabrics once (seeded) and reuses the draw for every metric. ``n_boot=0`` skips the
    intervals, ``sampled=False`` the sampled protocol.
    """
    prep = prepare(dist, query_fabric, gallery_fabric, exclude_self)
    return _evaluate(
        prep, prefix, n, ks, recall_ks, sampled, queries_per_fabric, repeats, n_boot, alpha, seed
    )


def _evaluate(
    prep: Prepared,
    prefix: str,
    n: int,
    ks: tuple[int, ...],
    recall_ks: tuple[int, ...],
    sampled: bool,
    queries_per_fabric: int,
    repeats: int,
    n_boot: int,
    alpha: float,
    seed: int,
) -> dict[str, float]:
    n_f = len(prep.fabrics)
    n_eff = n_effective(n, n_f)
    warn_if_short(n, n_eff, n_f)
    res = scan(prep, m=n_eff - 1, ks=ks, recall_ks=recall_ks)
    pick = pick_result_from(res.pick, ks, n_eff)
    gal = gallery_result_from(res, recall_ks)
    out: dict[str, float] = {}
    for c, k in enumerate(ks):
        out[f"top{k}"] = float(pick.mean[c])
        out[f"top{k}_chance"] = float(pick.chance[c])
    if sampled:
        s = sampled_from(prep, n, ks, queries_per_fabric, repeats, seed, False)
        for c, k in enumerate(ks):
            out[f"top{k}_sampled"] = float(s.mean[c])
            out[f"top{k}_sampled_se"] = float(s.se[c])
    out["map"] = gal.map
    out["map_chance"] = gal.chance_map
    for c, k in enumerate(recall_ks):
        out[f"recall{k}"] = float(gal.recall_mean[c])
        out[f"recall{k}_chance"] = float(gal.chance_recall[c])
    out["median_rank"] = gal.median_rank
    out["median_rank_chance"] = gal.chance_median_rank
    out["n_effective"] = float(n_eff)
    out["n_queries"] = float(gal.n_queries)
    ok = res.n_relevant > 0
    q_fab = prep.qidx[ok]
    out["n_fabrics"] = float(len(np.unique(q_fab)))
    if n_boot > 0 and ok.any():
        w = fabric_weights(len(np.unique(q_fab)), n_boot, seed)
        names = [f"top{k}" for k in ks] + ["map"] + [f"recall{k}" for k in recall_ks]
        vals: NDArray[np.float64] = np.concatenate(
            [res.pick[ok], res.ap[ok][:, None], res.recall[ok]], axis=1
        )
        low, high = bootstrap_ci(vals, q_fab, alpha=alpha, weights=w)
        for j, name in enumerate(names):
            out[f"{name}_ci_low"] = float(low[j])
            out[f"{name}_ci_high"] = float(high[j])
        lo, hi = bootstrap_ci(res.first_rank[ok], q_fab, alpha=alpha, weights=w, statistic="median")
        out["median_rank_ci_low"] = float(lo)
        out["median_rank_ci_high"] = float(hi)
    return {f"{prefix}{k}": v for k, v in out.items()}


def evaluate_pair(
    query_emb: ArrayLike,
    query_fabric: ArrayLike,
    gallery_emb: ArrayLike,
    gallery_fabric: ArrayLike,
    *,
    query: Modality | str,
    gallery: Modality | str,
    same_items: bool = False,
    n: int = 10,
    ks: tuple[int, ...] = (1, 3),
    recall_ks: tuple[int, ...] = (1, 5, 10),
    sampled: bool = True,
    queries_per_fabric: int = 15,
    repeats: int = 10,
    n_boot: int = 1000,
    alpha: float = 0.05,
    seed: int = 0,
) -> dict[str, float]:
    """Score query embeddings of one modality against gallery embeddings of another.

    Args:
        query_emb: (Q, D) query embeddings.
        query_fabric: (Q,) fabric id of each query.
        gallery_emb: (G, D) gallery embeddings.
        gallery_fabric: (G,) fabric id of each gallery item.
        query, gallery: the modalities, used in the keys (``touch_to_depth_top1``).
        same_items: query and gallery are the same items (a same-modality pair): item i is
            excluded from query i's candidates and ranking.
        n, ks, recall_ks, sampled, queries_per_fabric, repeats, n_boot, alpha, seed: as in
            `evaluate_distances`.

    Returns:
        Flat dict of floats (see the module docstring).
    """
    dist = pairwise_distances(query_emb, gallery_emb)
    excl = np.arange(dist.shape[0]) if same_items else None
    if same_items and dist.shape[0] != dist.shape[1]:
        raise ValueError(f"same_items needs Q == G; got {dist.shape}")
    prefix = f"{Modality(query).value}_to_{Modality(gallery).value}_"
    return evaluate_distances(
        dist,
        query_fabric,
        gallery_fabric,
        prefix=prefix,
        exclude_self=excl,
        n=n,
        ks=ks,
        recall_ks=recall_ks,
        sampled=sampled,
        queries_per_fabric=queries_per_fabric,
        repeats=repeats,
        n_boot=n_boot,
        alpha=alpha,
        seed=seed,
    )


def all_pairs(
    embeddings: Mapping[Modality, ArrayLike] | Mapping[str, ArrayLike],
    fabrics: Mapping[Modality, ArrayLike] | Mapping[str, ArrayLike],
    *,
    n: int = 10,
    ks: tuple[int, ...] = (1, 3),
    recall_ks: tuple[int, ...] = (1, 5, 10),
    sampled: bool = True,
    queries_per_fabric: int = 15,
    repeats: int = 10,
    n_boot: int = 1000,
    alpha: float = 0.05,
    seed: int = 0,
) -> dict[str, float]:
    """Every ordered (query, gallery) pair of modalities, same-modality pairs included.

    Each unordered pair's distance matrix is computed once; the reverse pair uses its
    transpose. Same-modality pairs exclude each query's own item.

    Args:
        embeddings: (N_m, D) embeddings per modality.
        fabrics: (N_m,) fabric ids per modality (same keys).
        n, ks, recall_ks, sampled, queries_per_fabric, repeats, n_boot, alpha, seed: as in
            `evaluate_distances`.

    Returns:
        One flat dict for all pairs, keys ``"{query}_to_{gallery}_{metric}"``.
    """
    emb = {Modality(k): np.asarray(v, dtype=np.float64) for k, v in embeddings.items()}
    fab = {Modality(k): np.asarray(v).reshape(-1) for k, v in fabrics.items()}
    if set(emb) != set(fab):
        raise ValueError(
            f"embeddings and fabrics have different modalities: {sorted(emb)} vs {sorted(fab)}"
        )
    for m in emb:
        if len(emb[m]) != len(fab[m]):
            raise ValueError(f"{m}: {len(emb[m])} embeddings but {len(fab[m])} fabric ids")
    mods = list(emb)
    out: dict[str, float] = {}

    def score(
        dist: NDArray[np.float64], q: Modality, g: Modality, excl: NDArray[np.int64] | None
    ) -> None:
        out.update(
            evaluate_distances(
                dist,
                fab[q],
                fab[g],
                prefix=f"{q}_to_{g}_",
                exclude_self=excl,
                n=n,
                ks=ks,
                recall_ks=recall_ks,
                sampled=sampled,
                queries_per_fabric=queries_per_fabric,
                repeats=repeats,
                n_boot=n_boot,
                alpha=alpha,
                seed=seed,
            )
        )

    for i, a in enumerate(mods):
        for b in mods[i:]:
            dist = pairwise_distances(emb[a], emb[b])
            if a == b:
                score(dist, a, a, np.arange(len(dist)))
            else:
                score(dist, a, b, None)
                score(dist.T, b, a, None)
    return out
