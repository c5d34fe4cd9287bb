"""One scoring path: ordered pairs of modalities scored by one protocol, from embeddings.

Validation during training, cross-validation, `reproduce`, `lookfeel evaluate` and the
benchmarks all score here, so "pick 1 of 10 for a pair of modalities" means one thing:

- `ScoringProtocol`: how a pair is scored (pick k of n, the paper's section 5.1; whole-gallery
  metrics; bootstrap intervals over query fabrics);
- `score_distances`: one (Q, G) distance matrix -> a `PairScore`;
- `pair_distances`: the distance matrix of each wanted `Pair`, each unordered pair's computed
  once (its transpose serves the reverse pair), each same-modality pair with the query's own
  item(s) excluded;
- `score_pairs`: the two together, embeddings in, a `PairScore` per pair out; `flat_metrics`
  turns those into one flat dict keyed ``"{query}_to_{gallery}_{metric}"``
  (``touch_to_depth_top1``).

Metric names of `PairScore.metrics`:

- ``top{k}``: exact pick-k-of-n (`pick_k_of_n_exact`, the paper's Figure 7 and Tables 1-2),
  ``top{k}_chance``; ``top{k}_sampled`` and ``top{k}_sampled_se`` the paper's sampled
  protocol; ``top{k}_released`` and ``top{k}_released_se`` the released code's variant;
- ``map``, ``recall{k}``, ``median_rank`` over the whole gallery (`gallery_metrics`), each with
  ``_chance``;
- ``_ci_low`` / ``_ci_high`` for each of those: a percentile bootstrap over query fabrics;
- ``n_effective`` (candidates per draw), ``n_queries``, ``n_fabrics``.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from lookfeel.metrics._ranking import prepare, scan
from lookfeel.metrics.bootstrap import bootstrap_ci, fabric_weights
from lookfeel.metrics.distances import pairwise_distances
from lookfeel.metrics.gallery import gallery_result_from
from lookfeel.metrics.pick import (
    PickResult,
    n_effective,
    pick_result_from,
    sampled_from,
    warn_if_short,
)
from lookfeel.modality import Modality, Pair

__all__ = [
    "EXACT_PICK",
    "PAPER_PROTOCOL",
    "PairDistances",
    "PairScore",
    "QuerySet",
    "ScoringProtocol",
    "flat_metrics",
    "pair_distances",
    "score_distances",
    "score_pairs",
]


@dataclass(frozen=True)
class ScoringProtocol:
    """How one (query, gallery) pair is scored; the defaults are the paper's (section 5.1).

    A draw shows a query ``n`` candidates: one gallery item of its own fabric and one of each of
    ``n - 1`` other fabrics; ``top{k}`` is the chance its own ranks within k. The exact
    expectation over the draw is always computed.
    """

    n: int = 10
    """Candidates per draw (paper: 10); with fewer gallery fabrics, all of them are offered
    (``n_effective``) and a warning says so."""
    ks: tuple[int, ...] = (1, 3)
    """The k of top-k (paper: top 1 and top 3)."""
    gallery: bool = True
    """Also rank each query against the whole gallery: ``map``, ``recall{k}``, ``median_rank``."""
    recall_ks: tuple[int, ...] = (1, 5, 10)
    """The k of recall@k (with ``gallery``)."""
    sampled: bool = True
    """Also run the paper's sampled protocol: ``top{k}_sampled`` with its standard error."""
    queries_per_fabric: int = 15
    """Sampled protocols: queries drawn per fabric (paper: 15)."""
    repeats: int = 10
    """Sampled protocols: candidate draws per query (paper: 10)."""
    released_variant: bool = False
    """Also run the authors' released code's sampled variant, whose distractor fabrics may be
    the query's own (``top{k}_released``)."""
    n_boot: int = 1000
    """Bootstrap resamples of the query fabrics for the ``_ci_low``/``_ci_high`` keys (0: none)."""
    alpha: float = 0.05
    """Intervals cover 1 - alpha."""
    seed: int = 0
    """Seeds the sampled protocols and the bootstrap."""

    def __post_init__(self) -> None:
        if self.n < 1:
            raise ValueError(f"n must be >= 1; got {self.n}")
        for name, ks in (("ks", self.ks), ("recall_ks", self.recall_ks)):
            if not ks or min(ks) < 1:
                raise ValueError(f"{name} must be positive integers; got {ks!r}")
        if self.queries_per_fabric < 1 or self.repeats < 1:
            raise ValueError("queries_per_fabric and repeats must be >= 1")
        if self.n_boot < 0:
            raise ValueError(f"n_boot must be >= 0; got {self.n_boot}")
        if not 0.0 < self.alpha < 1.0:
            raise ValueError(f"alpha must be in (0, 1); got {self.alpha}")


PAPER_PROTOCOL = ScoringProtocol()
"""Every metric: exact and sampled pick 1 of 10, top 1 and 3, gallery metrics, 95% intervals."""

EXACT_PICK = ScoringProtocol(gallery=False, sampled=False, n_boot=0)
"""Only the exact pick 1 of 10, top 1 and top 3: what validation and cross-validation report."""


@dataclass(frozen=True)
class PairScore:
    """What one pair scored."""

    pick: PickResult
    """Exact pick k of n: (Q, K) per-query values, their mean and chance."""
    metrics: dict[str, float]
    """Every number, by metric name (``top1``, ``map_ci_low``, ...; see the module docstring)."""


def score_distances(
    dist: ArrayLike,
    query_fabric: ArrayLike,
    gallery_fabric: ArrayLike,
    protocol: ScoringProtocol = PAPER_PROTOCOL,
    *,
    exclude: ArrayLike | None = None,
) -> PairScore:
    """Score one (Q, G) distance matrix by ``protocol``.

    One row sort serves the exact pick-k-of-n and the gallery metrics; the bootstrap draws
    query fabrics once (seeded) and reuses the draw for every metric.

    Args:
        dist: (Q, G) distances from each query to each gallery item.
        query_fabric: (Q,) fabric id of each query.
        gallery_fabric: (G,) fabric id of each gallery item.
        protocol: what to compute.
        exclude: items a query must never see (a same-modality pair): the (Q,) gallery index
            of each query's own item, or a (Q, G) mask (a pooled query's own presses).

    Returns:
        `PairScore`.
    """
    p = protocol
    prep = prepare(dist, query_fabric, gallery_fabric, exclude)
    n_f = len(prep.fabrics)
    n_eff = n_effective(p.n, n_f)
    warn_if_short(p.n, n_eff, n_f)
    recall_ks = p.recall_ks if p.gallery else ()
    res = scan(prep, m=n_eff - 1, ks=p.ks, recall_ks=recall_ks, gallery=p.gallery)
    pick = pick_result_from(res.pick, p.ks, n_eff)
    out: dict[str, float] = {}
    for c, k in enumerate(p.ks):
        out[f"top{k}"] = float(pick.mean[c])
        out[f"top{k}_chance"] = float(pick.chance[c])
    if p.sampled:
        s = sampled_from(prep, p.n, p.ks, p.queries_per_fabric, p.repeats, p.seed, False)
        for c, k in enumerate(p.ks):
            out[f"top{k}_sampled"] = float(s.mean[c])
            out[f"top{k}_sampled_se"] = float(s.se[c])
    n_queries = pick.n_queries
    if p.gallery:
        gal = gallery_result_from(res, recall_ks)
        out["map"] = gal.map
        out["map_chance"] = gal.chance_map
        for c, k in enumerate(recall_ks):
            out[f"recall{k}"] = float(gal.recall_mean[c])
            out[f"recall{k}_chance"] = float(gal.chance_recall[c])
        out["median_rank"] = gal.median_rank
        out["median_rank_chance"] = gal.chance_median_rank
        n_queries = gal.n_queries
    out["n_effective"] = float(n_eff)
    out["n_queries"] = float(n_queries)
    ok = res.n_relevant > 0
    q_fab = prep.qidx[ok]
    out["n_fabrics"] = float(len(np.unique(q_fab)))
    if p.n_boot > 0 and ok.any():
        w = fabric_weights(len(np.unique(q_fab)), p.n_boot, p.seed)
        names = [f"top{k}" for k in p.ks]
        parts = [res.pick[ok]]
        if p.gallery:
            names += ["map"] + [f"recall{k}" for k in recall_ks]
            parts += [res.ap[ok][:, None], res.recall[ok]]
        vals: NDArray[np.float64] = np.concatenate(parts, axis=1)
        low, high = bootstrap_ci(vals, q_fab, alpha=p.alpha, weights=w)
        for j, name in enumerate(names):
            out[f"{name}_ci_low"] = float(low[j])
            out[f"{name}_ci_high"] = float(high[j])
        if p.gallery:
            lo, hi = bootstrap_ci(
                res.first_rank[ok], q_fab, alpha=p.alpha, weights=w, statistic="median"
            )
            out["median_rank_ci_low"] = float(lo)
            out["median_rank_ci_high"] = float(hi)
    if p.released_variant:
        s = sampled_from(prep, p.n, p.ks, p.queries_per_fabric, p.repeats, p.seed, True)
        for c, k in enumerate(p.ks):
            out[f"top{k}_released"] = float(s.mean[c])
            out[f"top{k}_released_se"] = float(s.se[c])
    return PairScore(pick, out)


@dataclass(frozen=True)
class QuerySet:
    """The queries of one modality: embeddings, fabrics, and the gallery items each is made of.

    A query is usually one item of the modality (`QuerySet.single`); a multi-press touch query
    pools several presses (the Multi-input Net), all of which a touch gallery must leave out.
    """

    emb: NDArray[np.float64]
    """(Q, D) query embeddings."""
    fabric: NDArray[np.generic]
    """(Q,) fabric id of each query."""
    members: NDArray[np.int64]
    """(Q, P) rows of each query's items in the modality's gallery (P = 1: item i itself)."""

    @classmethod
    def single(cls, emb: ArrayLike, fabric: ArrayLike) -> QuerySet:
        """Every item its own query."""
        e = np.asarray(emb, dtype=np.float64)
        return cls(e, np.asarray(fabric).reshape(-1), np.arange(len(e), dtype=np.int64)[:, None])

    @property
    def pooled(self) -> bool:
        """Queries pool several items."""
        return bool(self.members.shape[1] > 1)

    def exclusion(self, n_gallery: int) -> NDArray[np.int64] | NDArray[np.bool_]:
        """What a gallery of the same items must leave out: each query's own item(s).

        Returns:
            (Q,) the own item's index for single items, else a (Q, G) mask of own items.
        """
        if not self.pooled:
            return self.members[:, 0]
        mask = np.zeros((len(self.members), n_gallery), dtype=bool)
        mask[np.arange(len(self.members))[:, None], self.members] = True
        return mask


@dataclass(frozen=True)
class PairDistances:
    """One pair's distance matrix and what scoring it needs."""

    pair: Pair
    dist: NDArray[np.float64]
    """(Q, G) distances from each query to each gallery item."""
    queries: QuerySet
    gallery_fabric: NDArray[np.generic]
    """(G,) fabric id of each gallery item."""
    exclude: NDArray[np.int64] | NDArray[np.bool_] | None
    """Each query's own item(s) in a same-modality pair, else None."""


def _grouped_pairs(modalities: Sequence[Modality]) -> list[Pair]:
    """Every ordered pair, each pair of two modalities beside its reverse (the order computed)."""
    out = []
    for i, a in enumerate(modalities):
        for b in modalities[i:]:
            out += [Pair(a, b)] if a is b else [Pair(a, b), Pair(b, a)]
    return out


def _inputs(
    embeddings: Mapping[Modality, ArrayLike] | Mapping[str, ArrayLike],
    fabrics: Mapping[Modality, ArrayLike] | Mapping[str, ArrayLike],
) -> tuple[dict[Modality, NDArray[np.float64]], dict[Modality, NDArray[np.generic]]]:
    emb = {Modality(k): np.asarray(v, dtype=np.float64) for k, v in embeddings.items()}
    fab = {Modality(k): np.asarray(v).reshape(-1) for k, v in fabrics.items()}
    if set(emb) != set(fab):
        raise ValueError(
            f"embeddings and fabrics have different modalities: {sorted(emb)} vs {sorted(fab)}"
        )
    for m in emb:
        if len(emb[m]) != len(fab[m]):
            raise ValueError(f"{m}: {len(emb[m])} embeddings but {len(fab[m])} fabric ids")
    return emb, fab


def pair_distances(
    embeddings: Mapping[Modality, ArrayLike] | Mapping[str, ArrayLike],
    fabrics: Mapping[Modality, ArrayLike] | Mapping[str, ArrayLike],
    pairs: Sequence[Pair | str] | None = None,
    *,
    queries: Mapping[Modality, QuerySet] | None = None,
    galleries: Mapping[Modality, QuerySet] | None = None,
) -> Iterator[PairDistances]:
    """The distance matrix of each wanted pair, one matrix in memory at a time.

    A pair of two modalities is followed by its reverse when that is wanted too, scored on the
    transpose of the same matrix (when each modality is the same set on both sides). Same-modality
    pairs exclude each query's own item(s).

    Args:
        embeddings: (N_m, D) gallery embeddings per modality (every item).
        fabrics: (N_m,) fabric ids per modality (same keys).
        pairs: the pairs; default every ordered pair, same-modality pairs included, each pair
            beside its reverse.
        queries: the queries of a modality when they are not its items one by one (pooled
            multi-press touch queries).
        galleries: the gallery of a modality, when another modality queries it, as pooled
            sets instead of its items one by one (the Multi-input Net's touch candidates are
            three presses each, as its touch queries are). Same-modality pairs keep the items.

    Yields:
        `PairDistances`, in the order computed.

    Raises:
        ValueError: a pair's modality has no embeddings, or the inputs disagree in length.
    """
    emb, fab = _inputs(embeddings, fabrics)
    wanted = [Pair.parse(p) for p in pairs] if pairs is not None else _grouped_pairs(list(emb))
    for p in wanted:
        for m in (p.query, p.gallery):
            if m not in emb:
                raise ValueError(f"{p}: no {m.value} embeddings (have {', '.join(emb)})")
    qs = {m: QuerySet.single(emb[m], fab[m]) for m in emb}
    qs.update(queries or {})
    pooled = dict(galleries or {})

    def gallery(p: Pair) -> tuple[NDArray[np.float64], NDArray[np.generic]]:
        if not p.same and p.gallery in pooled:
            return pooled[p.gallery].emb, pooled[p.gallery].fabric
        return emb[p.gallery], fab[p.gallery]

    def one(p: Pair, dist: NDArray[np.float64]) -> PairDistances:
        q, g = qs[p.query], gallery(p)[1]
        return PairDistances(p, dist, q, g, q.exclusion(len(g)) if p.same else None)

    def symmetric(m: Modality) -> bool:
        """``m`` is the same set as a query and as another modality's gallery."""
        return pooled[m] is qs[m] if m in pooled else not qs[m].pooled

    done: set[Pair] = set()
    for p in wanted:
        if p in done:
            continue
        dist = pairwise_distances(qs[p.query].emb, gallery(p)[0])
        yield one(p, dist)
        done.add(p)
        back = p.reverse()
        if p.same or back not in wanted or back in done:
            continue
        if symmetric(p.query) and symmetric(p.gallery):
            dist = dist.T
        else:
            del dist
            dist = pairwise_distances(qs[back.query].emb, gallery(back)[0])
        yield one(back, dist)
        done.add(back)


def score_pairs(
    embeddings: Mapping[Modality, ArrayLike] | Mapping[str, ArrayLike],
    fabrics: Mapping[Modality, ArrayLike] | Mapping[str, ArrayLike],
    protocol: ScoringProtocol = PAPER_PROTOCOL,
    pairs: Sequence[Pair | str] | None = None,
    *,
    queries: Mapping[Modality, QuerySet] | None = None,
    galleries: Mapping[Modality, QuerySet] | None = None,
) -> dict[Pair, PairScore]:
    """Score ordered pairs of modalities by one protocol: the one entry point from embeddings.

    Example:
        >>> scores = score_pairs({"touch": t, "depth": d}, {"touch": tf, "depth": df})
        >>> scores[Pair.parse("touch_to_depth")].metrics["top1"]

    Args:
        embeddings: (N_m, D) embeddings per modality.
        fabrics: (N_m,) fabric ids per modality (same keys).
        protocol: what to compute (default: everything, the paper's pick 1 of 10).
        pairs: the pairs to score; default every ordered pair, same-modality pairs included.
        queries: pooled queries of a modality (see `pair_distances`).
        galleries: pooled galleries of a modality for the other modalities' queries (see
            `pair_distances`).

    Returns:
        pair -> `PairScore`, in the order of ``pairs`` (default: each pair beside its reverse).
    """
    scores = {
        pd.pair: score_distances(
            pd.dist, pd.queries.fabric, pd.gallery_fabric, protocol, exclude=pd.exclude
        )
        for pd in pair_distances(embeddings, fabrics, pairs, queries=queries, galleries=galleries)
    }
    if pairs is None:
        return scores
    return {p: scores[p] for p in (Pair.parse(x) for x in pairs)}


def flat_metrics(scores: Mapping[Pair, PairScore]) -> dict[str, float]:
    """One flat dict of every pair's metrics, keys ``"{query}_to_{gallery}_{metric}"``."""
    return {f"{pair}_{k}": v for pair, s in scores.items() for k, v in s.metrics.items()}
