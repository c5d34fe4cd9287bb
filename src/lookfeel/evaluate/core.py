"""Score embeddings by every protocol of the paper's section 5, from one distance matrix per pair.

`evaluate_embeddings` takes per-modality embeddings (ours, a baseline's, a user's) and returns
an `EvalResult`; it knows nothing of models except through the optional press pooler. The pick
and gallery metrics come from the one scoring path (`lookfeel.metrics.score_distances` over
`lookfeel.metrics.pair_distances`, with `scoring_protocol` of the `EvalConfig`); calibration,
confusion matrices, examples, the press curve and the probes are added around it.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable, Hashable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import replace
from typing import Any

import numpy as np
from numpy.typing import NDArray

from lookfeel.config import ConfigError, DataConfig, EvalConfig
from lookfeel.embedding import EmbeddedItems, PressPooler
from lookfeel.metrics import (
    PAPER_C,
    PairDistances,
    QuerySet,
    ScoringProtocol,
    bootstrap_ci,
    cluster_confusion_matrix,
    confusion_matrix,
    fabric_probabilities,
    fit_temperature,
    group_members,
    max_pool_groups,
    n_effective,
    order_by_cluster,
    pair_distances,
    pairwise_distances,
    property_probe,
    reliability_curve,
    score_distances,
)
from lookfeel.metrics.cross_map import CrossMap, fit_cross_map
from lookfeel.metrics.label_space import fit_label_spaces
from lookfeel.metrics.properties import knn_neighbours
from lookfeel.modality import Modality, Pair

from .result import CalibrationResult, EvalResult, GlanceExample, GlanceGallery, PickExample

__all__ = [
    "PressPooler",
    "evaluate_embeddings",
    "exact_protocol",
    "keep_pick",
    "max_pool_presses",
    "no_query_scored",
    "press_queries",
    "project_to_labels",
    "scoring_protocol",
]

UNCLUSTERED = -1
"""Cluster shown for fabrics whose cluster is unknown."""


def max_pool_presses(touch: EmbeddedItems, members: NDArray[np.int64]) -> NDArray[np.float64]:
    """Element-wise max of the presses' embeddings (the Multi-input Net, paper section 4.1):
    `lookfeel.metrics.max_pool_groups` as a `PressPooler`, the default of `press_queries`.

    Equals the model's own multi-press embedding when it pools its final embedding (the
    paper's nets: max over fc7, no projection or normalisation after it).

    Args:
        touch: per-press embeddings (N, D).
        members: (M, P) rows of each group.

    Returns:
        (M, D): ``e[members].max(axis=1)  # (M, P, D) -> (M, D)``.
    """
    return max_pool_groups(touch.embeddings, members)


def scoring_protocol(config: EvalConfig) -> ScoringProtocol:
    """The pick and gallery protocol an `EvalConfig` asks for."""
    return ScoringProtocol(
        n=config.n,
        ks=config.ks,
        recall_ks=config.recall_ks,
        sampled=config.sampled,
        queries_per_fabric=config.queries_per_fabric,
        repeats=config.repeats,
        released_variant=config.released_variant,
        n_boot=config.n_boot,
        alpha=config.alpha,
        seed=config.seed,
    )


def press_queries(
    e: EmbeddedItems, presses: int, seed: int, pool: PressPooler = max_pool_presses
) -> QuerySet:
    """One modality's queries: every item alone (``presses`` 1), or each fabric's presses in
    seeded disjoint groups of ``presses`` (`group_members`), each group embedded by ``pool``."""
    emb = np.asarray(e.embeddings, dtype=np.float64)
    fab = np.asarray(e.fabric_ids, dtype=np.int64)
    if presses == 1:
        return QuerySet.single(emb, fab)
    members = group_members(fab, presses=presses, seed=seed).astype(np.int64)
    pooled = pool(e, members)
    return QuerySet(np.asarray(pooled, dtype=np.float64), fab[members[:, 0]], members)


def no_query_scored(
    pair: Pair,
    presses: int,
    *,
    fabrics: str = "test",
    kinds: Sequence[str] = (),
    option: str = "presses=",
) -> str:
    """Why no query of ``pair`` could be scored: none has an item of its own fabric among
    what it picks from (every per-query pick is NaN).

    The usual cause is touch to touch with pooled queries: a query's own presses are never its
    candidates, so a fabric with exactly ``presses`` presses leaves none of its own to find.

    Args:
        pair: the pair none of whose queries was scored.
        presses: presses pooled into each touch query.
        fabrics: what the scored fabrics are called (``"test"``, ``"held-out"``).
        kinds: the press kinds counted (``("fold",)``), named in the text when given.
        option: how the user sets ``presses``, followed by the number (``"--presses "``).

    Returns:
        One sentence without the pair's name, e.g. ``"no test fabric has more than 3 touch
        presses, so ..."``.
    """
    q, g = pair.query.value, pair.gallery.value
    if pair.same and pair.query is Modality.TOUCH and presses > 1:
        kind = f" ({', '.join(kinds)})" if kinds else ""
        fewer = presses - 1
        return (
            f"no {fabrics} fabric has more than {presses} touch presses{kind}, so each query "
            f"pools every press of its fabric and leaves none to find among the single presses "
            f"it picks from; use {option}{fewer}" + (" or fewer" if fewer > 1 else "")
        )
    if pair.same:
        return f"no {fabrics} fabric has a second {q} item for a query to find"
    return f"no {fabrics} fabric that makes a {q} query has a {g} candidate to find"


class _Notes:
    """Collects what was skipped or approximated, once each, and the warnings raised."""

    def __init__(self) -> None:
        self.items: list[str] = []

    def add(self, text: str) -> None:
        if text not in self.items:
            self.items.append(text)

    @contextmanager
    def catching(self, where: str) -> Iterator[None]:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            yield
        for w in caught:  # the same warning from many pairs is noted once
            text = str(w.message)
            self.add(text if text.startswith("pick ") else f"{where}: {text}")


def _figure_pairs(config: EvalConfig, pairs: Sequence[Pair]) -> list[Pair]:
    wanted = [p for p in config.figure_pairs if p in pairs]
    if wanted:
        return wanted
    cross = [p for p in pairs if not p.same]
    return (cross or list(pairs))[:1]


def _curve_keys(config: EvalConfig) -> list[str]:
    """The keys of one point of the press curve (a subset of the main pick keys)."""
    keys = []
    for k in config.ks:
        keys += [f"top{k}", f"top{k}_chance"]
        if config.n_boot > 0:
            keys += [f"top{k}_ci_low", f"top{k}_ci_high"]
    return [*keys, "n_queries", "n_fabrics", "n_effective"]


def _fit_c(
    rq: QuerySet,
    gallery: QuerySet,
    q: Modality,
    g: Modality,
    notes: _Notes,
) -> float | None:
    """Maximum-likelihood c of one pair on the reference fabrics; None when it cannot be fit.

    Args:
        rq: the reference fabrics' queries of modality ``q``.
        gallery: the reference fabrics' candidates of modality ``g`` (items, or pooled sets).
    """
    gf = np.asarray(gallery.fabric)
    if len(rq.fabric) == 0 or len(np.unique(gf)) < 2:
        return None
    dist = pairwise_distances(rq.emb, gallery.emb)
    pair = Pair(q, g)
    try:
        with notes.catching(f"fitting c for {pair}"):
            return fit_temperature(
                dist, rq.fabric, gf, rq.exclusion(len(gf)) if pair.same else None
            )
    except ValueError as e:
        notes.add(f"c for {pair} not fitted ({e}); the paper's c is used")
        return None


def exact_protocol(config: EvalConfig) -> ScoringProtocol:
    """The exact pick k of n with intervals, nothing else: what the controls and the
    cross-modal map are scored by."""
    return ScoringProtocol(
        n=config.n,
        ks=config.ks,
        gallery=False,
        sampled=False,
        n_boot=config.n_boot,
        alpha=config.alpha,
        seed=config.seed,
    )


def keep_pick(
    out: dict[str, float], score: Mapping[str, float], ks: Sequence[int], key: str
) -> None:
    """Copy ``top{k}`` (and its interval) of ``score`` into ``out`` under ``key`` (a format
    string with ``{k}`` and ``{suffix}``)."""
    for k in ks:
        for suffix in ("", "_ci_low", "_ci_high"):
            if f"top{k}{suffix}" in score:
                out[key.format(k=k, suffix=suffix)] = score[f"top{k}{suffix}"]


def _mapped(
    pairs: Sequence[Pair],
    queries: Mapping[Modality, QuerySet],
    candidates: Callable[[Modality], QuerySet],
    reference_queries: Callable[[Modality], QuerySet],
    reference_gallery: Callable[[Modality], QuerySet],
    reference: Mapping[Modality, EmbeddedItems],
    config: EvalConfig,
    notes: _Notes,
) -> tuple[dict[str, float], dict[Pair, CrossMap], dict[Pair, NDArray[np.float64]]]:
    """Every pair of two modalities scored through its cross-modal map (`EvalConfig.cross_map`),
    the map fitted on the reference fabrics' queries and candidates (pooled as the test ones
    are, ``candidates``); keys ``{pair}_top{k}_mapped``. Returns the keys, the maps and each
    pair's (queries, gallery) distances through its map."""
    out: dict[str, float] = {}
    maps: dict[Pair, CrossMap] = {}
    dists: dict[Pair, NDArray[np.float64]] = {}
    protocol = exact_protocol(config)
    for pair in pairs:
        q, g = pair.query, pair.gallery
        if pair.same or q not in reference or g not in reference:
            continue
        rq, rg = reference_queries(q), reference_gallery(g)
        try:
            maps[pair] = fit_cross_map(rq.emb, rq.fabric, rg.emb, rg.fabric)
        except ValueError as e:
            notes.add(f"{pair}: no cross-modal map ({e})")
            continue
        cand = candidates(g)
        dist = dists[pair] = maps[pair].distances(queries[q].emb, cand.emb)
        with notes.catching(f"{pair} through the cross-modal map"):
            scored = score_distances(dist, queries[q].fabric, cand.fabric, protocol)
        keep_pick(out, scored.metrics, config.ks, f"{pair}_top{{k}}_mapped{{suffix}}")
    return out, maps, dists


def _calibrate(
    pair: Pair,
    dist: NDArray[np.float64],
    q: QuerySet,
    gallery_fabric: NDArray[np.int64],
    exclude: NDArray[np.int64] | NDArray[np.bool_] | None,
    c: float,
    c_source: str,
    config: EvalConfig,
    clusters: Mapping[Hashable, Hashable] | None,
    figure: bool,
    scorable: bool = True,
) -> CalibrationResult:
    """The calibration of one pair; ``scorable`` False (no query has an item of its own
    fabric to find: `no_query_scored`) leaves its accuracy, confidence, ECE and NLL NaN."""
    probs, fabrics = fabric_probabilities(dist, gallery_fabric, c, exclude)  # (Q, F)
    rows = np.arange(len(probs))
    best = np.argmax(probs, axis=1) if len(probs) else np.zeros(0, dtype=np.int64)
    own = np.searchsorted(fabrics, q.fabric).clip(0, max(len(fabrics) - 1, 0))
    has = fabrics[own] == q.fabric if len(fabrics) else np.zeros(len(q.fabric), dtype=bool)
    has &= scorable
    conf = np.clip(probs[rows, best][has], 0.0, 1.0)  # sums of P may round just past 1
    correct = (best == own)[has]
    p_own = probs[rows, own][has]
    nll_own = -np.log(np.maximum(p_own, 1e-300))  # each scored query's
    rel = reliability_curve(conf, correct, config.n_bins)
    nan = float("nan")
    if not has.any():  # nothing to be calibrated on: no error either
        rel = replace(rel, ece=nan)
    confusion = cluster_conf = None
    if figure:
        order = None
        if clusters is not None:
            order = order_by_cluster(np.concatenate([q.fabric, gallery_fabric]), clusters)
        confusion = confusion_matrix(dist, q.fabric, gallery_fabric, c, exclude, order=order)
        if clusters is not None:
            cluster_conf = cluster_confusion_matrix(
                dist, q.fabric, gallery_fabric, clusters, c, exclude
            )
    return CalibrationResult(
        pair=pair,
        c=c,
        c_source=c_source,
        reliability=rel,
        accuracy=float(correct.mean()) if has.any() else nan,
        confidence=float(conf.mean()) if has.any() else nan,
        nll=float(nll_own.mean()) if has.any() else nan,
        nll_se=_se_over_fabrics(nll_own, np.asarray(q.fabric[has], np.int64)),
        accuracy_ci=_accuracy_ci(correct, np.asarray(q.fabric[has], np.int64), config),
        n_fabrics=len(fabrics),
        confusion=confusion,
        cluster_confusion=cluster_conf,
    )


def _accuracy_ci(
    correct: NDArray[np.bool_], fabric: NDArray[np.int64], config: EvalConfig
) -> tuple[float, float]:
    """The 95% bootstrap interval of the fabric accuracy over the query fabrics (resampled as
    the pick scores are: `bootstrap_ci`); NaN without resamples or queries."""
    if config.n_boot <= 0 or not len(correct):
        return (math.nan, math.nan)
    low, high = bootstrap_ci(
        correct.astype(np.float64), fabric, n_boot=config.n_boot, seed=config.seed
    )
    return (float(low), float(high))


def _se_over_fabrics(values: NDArray[np.float64], fabric: NDArray[np.int64]) -> float:
    """The standard error of the mean of per-query ``values`` over their fabrics: the spread
    of the fabrics' own means over the square root of their number (NaN under two)."""
    ids, inverse = np.unique(fabric, return_inverse=True)
    if len(ids) < 2:
        return float("nan")
    means = np.bincount(inverse, weights=values) / np.bincount(inverse)
    return float(means.std(ddof=1) / math.sqrt(len(ids)))


def _draw_examples(
    pair: Pair,
    dist: NDArray[np.float64],
    q: QuerySet,
    gallery_fabric: NDArray[np.int64],
    same: bool,
    config: EvalConfig,
    gallery_rows: NDArray[np.int64] | None = None,
) -> tuple[PickExample, ...]:
    """Draw pick trials as the paper's protocol does; keep half right, half wrong when both occur.

    Distinct query fabrics are preferred, so the figure shows different fabrics.
    ``gallery_rows``: the item row that shows each gallery entry (a pooled set's first press);
    default the entry itself.
    """
    if config.examples == 0 or len(q.fabric) == 0:
        return ()
    rng = np.random.default_rng(config.seed)
    fabrics = np.unique(gallery_fabric)
    rows_of = {int(f): np.flatnonzero(gallery_fabric == f) for f in fabrics}
    m = n_effective(config.n, len(fabrics)) - 1
    right: list[tuple[int, PickExample]] = []
    wrong: list[tuple[int, PickExample]] = []
    for qi in rng.permutation(len(q.fabric))[: max(200, 20 * config.examples)]:
        f = int(q.fabric[qi])
        own = rows_of.get(f, np.zeros(0, dtype=np.int64))
        if same:
            own = own[~np.isin(own, q.members[qi])]
        others = fabrics[fabrics != f]
        if len(own) == 0 or len(others) < m:
            continue
        t = int(rng.choice(own))
        picked = rng.choice(others, size=m, replace=False)
        cands = np.array([t] + [int(rng.choice(rows_of[int(x)])) for x in picked], dtype=np.int64)
        d = dist[qi, cands]
        order = np.argsort(d, kind="stable")
        ex = PickExample(
            pair=pair,
            query_rows=tuple(int(r) for r in q.members[qi]),
            candidates=tuple(
                int(c if gallery_rows is None else gallery_rows[c]) for c in cands[order]
            ),
            distances=tuple(float(x) for x in d[order]),
            true_position=int(np.flatnonzero(order == 0)[0]),
        )
        (right if ex.true_position == 0 else wrong).append((f, ex))

    def take(pool: list[tuple[int, PickExample]], count: int) -> list[PickExample]:
        seen: set[int] = set()
        first: list[PickExample] = []
        rest: list[PickExample] = []
        for f, ex in pool:
            (rest if f in seen else first).append(ex)
            seen.add(f)
        return (first + rest)[:count]

    want_right = (config.examples + 1) // 2
    chosen = take(right, want_right)
    chosen += take(wrong, config.examples - len(chosen))
    if len(chosen) < config.examples:
        chosen += [ex for ex in take(right, config.examples) if ex not in chosen]
    return tuple(chosen[: config.examples])


GLANCE_QUERIES = 3
"""Touch queries in the glance figure (fewer when ``eval.examples`` asks for fewer)."""
GLANCE_SHOWN = 5
"""Nearest fabrics shown per look modality in the glance figure."""
_LOOKS = (Modality.DEPTH, Modality.COLOR)


def _glance_queries(q: QuerySet, count: int, seed: int) -> NDArray[np.int64]:
    """``count`` touch queries of distinct fabrics, drawn with ``seed`` (not chosen by score)."""
    if count <= 0:
        return np.zeros(0, dtype=np.int64)
    rng = np.random.default_rng([seed, 7])
    chosen: list[int] = []
    seen: set[int] = set()
    for qi in rng.permutation(len(q.fabric)):
        f = int(q.fabric[qi])
        if f not in seen:
            seen.add(f)
            chosen.append(int(qi))
        if len(chosen) == count:
            break
    return np.asarray(chosen, dtype=np.int64)


def _rank_fabrics(
    dist: NDArray[np.float64], fabric: NDArray[np.int64]
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Fabrics ordered by their item nearest to a query (one row of distances to ``fabric``'s
    items), and that item's row for each."""
    fabrics, inverse = np.unique(fabric, return_inverse=True)
    order = np.lexsort((dist, inverse))  # by fabric, nearest first within each
    first = order[np.searchsorted(inverse[order], np.arange(len(fabrics)))]
    ranked = np.argsort(dist[first], kind="stable")
    return fabrics[ranked].astype(np.int64), first[ranked].astype(np.int64)


def _nearest_fabrics(
    dist: NDArray[np.float64], gallery_fabric: NDArray[np.int64], own: int, modality: Modality
) -> GlanceGallery:
    """Rank a query's gallery fabrics by their nearest item (one row of distances)."""
    ranked, rows = _rank_fabrics(dist, gallery_fabric)
    hit = np.flatnonzero(ranked == own)
    return GlanceGallery(
        modality=modality,
        rows=tuple(int(r) for r in rows[:GLANCE_SHOWN]),
        fabrics=tuple(int(f) for f in ranked[:GLANCE_SHOWN]),
        true_rank=int(hit[0]) + 1 if hit.size else 0,
        n_fabrics=len(ranked),
    )


def fewer_neighbours(what: str, used: int, n: int, k: int) -> str:
    """The note that ``what`` averaged the nearest ``used`` of ``n`` reference fabrics instead
    of ``eval.probe_k``'s ``k`` (`lookfeel.metrics.properties.knn_neighbours`)."""
    covers = "all of them: their mean, the same for every query" if k >= n else "most of them"
    return (
        f"{what}: the mean of the nearest {used} of the {n} training fabrics, not "
        f"eval.probe_k's {k}: a k-NN averages at most half of them (the nearest {k} of {n} "
        f"would be {covers})"
    )


def _feels_like(
    query_emb: NDArray[np.float64],
    own: int,
    reference: QuerySet,
    labels: Mapping[int, Sequence[float]],
    n_cols: int,
    k: int,
) -> tuple[tuple[float, ...], tuple[int, ...], int]:
    """The mean label of the training fabrics whose touch is nearest (by their nearest query),
    those fabrics and how many there were to choose from; the query's own fabric is never one
    of them. ``k`` of them, but at most half of those with labels (`knn_neighbours`): the
    nearest k of k or fewer would be every one, the same answer for every query."""
    d = pairwise_distances(query_emb[None], reference.emb)[0]
    ranked, _ = _rank_fabrics(d, np.asarray(reference.fabric, dtype=np.int64))
    known = [int(f) for f in ranked if f != own and int(f) in labels]
    nearest = known[: knn_neighbours(k, len(known))]
    if not nearest:
        return tuple([math.nan] * n_cols), (), len(known)
    y = _labels_of(np.asarray(nearest, dtype=np.int64), labels, n_cols)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # a column no neighbour knows: NaN
        mean = np.nanmean(y, axis=0)
    return tuple(float(v) for v in mean), tuple(nearest), len(known)


def project_to_labels(
    embedded: Mapping[Modality, EmbeddedItems],
    reference: Mapping[Modality, EmbeddedItems],
    labels: Mapping[int, Sequence[float]],
    label_names: Sequence[str],
    pool: PressPooler,
) -> tuple[dict[Modality, EmbeddedItems], dict[Modality, EmbeddedItems], PressPooler]:
    """``eval.space: labels``: the test and reference items mapped onto the labels
    (`lookfeel.metrics.label_space.fit_label_spaces`, fitted on the reference items), and a
    press pooler that pools as ``pool`` does, then maps.

    Raises:
        ConfigError: a modality without reference items, or no label column every modality
            can be mapped onto.
    """
    missing = [m.value for m in embedded if m not in reference or not len(reference[m].items)]
    if missing:
        raise ConfigError(
            f"eval.space: labels needs reference (training) items of {', '.join(missing)} to "
            "fit the map on"
        )
    spaces = fit_label_spaces(
        {m: (reference[m].embeddings, reference[m].fabric_ids) for m in embedded},
        labels,
        list(label_names),
    )
    if set(spaces) != set(embedded):
        raise ConfigError(
            "eval.space: labels needs a label column that enough reference fabrics of every "
            f"modality have (labels: {', '.join(label_names) or 'none'})"
        )
    source: dict[int, EmbeddedItems] = {}

    def mapped(e: EmbeddedItems) -> EmbeddedItems:
        out = replace(e, embeddings=spaces[e.modality].project(e.embeddings).astype(np.float32))
        source[id(out)] = e
        return out

    test = {m: mapped(e) for m, e in embedded.items()}
    ref = {m: mapped(reference[m]) for m in embedded}

    def pooled(e: EmbeddedItems, members: NDArray[np.int64]) -> NDArray[np.float64]:
        original = source.get(id(e), e)
        return spaces[e.modality].project(pool(original, members))

    return test, ref, pooled


def _labels_of(
    fabric: NDArray[np.int64], labels: Mapping[int, Sequence[float]], n_cols: int
) -> NDArray[np.float64]:
    missing = [math.nan] * n_cols
    return np.array([list(labels.get(int(f), missing)) for f in fabric], dtype=np.float64).reshape(
        len(fabric), n_cols
    )


def _mae_chance(
    train_y: NDArray[np.float64],
    train_f: NDArray[np.int64],
    test_y: NDArray[np.float64],
    test_f: NDArray[np.int64],
) -> NDArray[np.float64]:
    """MAE of always answering the training fabrics' mean label, per column (per fabric)."""
    _, i_tr = np.unique(train_f, return_index=True)
    _, i_te = np.unique(test_f, return_index=True)
    ytr, yte = train_y[i_tr], test_y[i_te]
    out = np.full(train_y.shape[1], np.nan)
    for j in range(train_y.shape[1]):
        a, b = ytr[:, j], yte[:, j]
        a, b = a[~np.isnan(a)], b[~np.isnan(b)]
        if len(a) and len(b):
            out[j] = float(np.abs(b - a.mean()).mean())
    return out


def _probes(
    embedded: Mapping[Modality, EmbeddedItems],
    reference: Mapping[Modality, EmbeddedItems],
    labels: Mapping[int, Sequence[float]],
    names: list[str],
    config: EvalConfig,
    notes: _Notes,
) -> dict[Modality, dict[str, dict[str, dict[str, float]]]]:
    out: dict[Modality, dict[str, dict[str, dict[str, float]]]] = {}
    for m, te in embedded.items():
        tr = reference.get(m)
        if tr is None or len(tr.embeddings) == 0 or len(te.embeddings) == 0:
            continue
        f_tr = np.asarray(tr.fabric_ids, dtype=np.int64)
        f_te = np.asarray(te.fabric_ids, dtype=np.int64)
        if np.intersect1d(f_tr, f_te).size:
            notes.add(
                "property probes skipped: the reference and test items share fabrics (an "
                "item-level split), and labels belong to fabrics"
            )
            continue
        y_tr = _labels_of(f_tr, labels, len(names))
        y_te = _labels_of(f_te, labels, len(names))
        chance = _mae_chance(y_tr, f_tr, y_te, f_te)
        for method in config.probes:
            with notes.catching(f"{m.value} {method} probe"):
                res = property_probe(
                    tr.embeddings,
                    y_tr,
                    te.embeddings,
                    y_te,
                    "knn" if method == "knn" else "ridge",
                    names=names,
                    train_fabric=f_tr,
                    test_fabric=f_te,
                    k=config.probe_k,
                )
            for j, name in enumerate(names):
                res[name]["mae_chance"] = float(chance[j])
                used, n_fit = res[name].get("k", math.nan), res[name]["n_train"]
                if math.isfinite(used) and used < config.probe_k:
                    what = "k-NN property probe"
                    notes.add(fewer_neighbours(what, int(used), int(n_fit), config.probe_k))
            out.setdefault(m, {})[method] = res
    return out


def _touch_presses(touch: EmbeddedItems, data_config: DataConfig | None) -> str:
    """What a fabric's touch presses are, as the notes count them: ``touch presses (2 at
    most)``; where the presses evaluated have kinds, those kinds, as the run's
    ``data.touch_kinds`` chose them (a dataset's presses of other kinds are not evaluated, so
    not counted): ``fold touch presses (the kind evaluated: the run's data.touch_kinds; 2 at
    most)``."""
    fabrics = np.asarray(touch.fabric_ids, dtype=np.int64)
    most = int(np.unique(fabrics, return_counts=True)[1].max()) if fabrics.size else 0
    kinds = sorted({it.kind.value for it in touch.items if it.kind is not None})
    if not kinds:
        return f"touch presses ({most} at most)"
    which = "kinds" if len(kinds) > 1 else "kind"
    run = ": the run's data.touch_kinds" if data_config is not None else ""
    return f"{'/'.join(kinds)} touch presses (the {which} evaluated{run}; {most} at most)"


def evaluate_embeddings(
    embedded: Mapping[Modality, EmbeddedItems],
    config: EvalConfig | None = None,
    clusters: Mapping[int, int | None] | None = None,
    labels: Mapping[int, Sequence[float]] | None = None,
    *,
    label_names: Sequence[str] | None = None,
    reference: Mapping[Modality, EmbeddedItems] | None = None,
    pool_presses: PressPooler | None = None,
    info: Mapping[str, Any] | None = None,
    data_config: DataConfig | None = None,
) -> EvalResult:
    """Every protocol of the paper's section 5 for every (query, gallery) modality pair.

    For each ordered pair, same-modality pairs included (a query's own item, or for a pooled
    touch query its own presses, is never a candidate), one distance matrix gives:

    - pick k of n (section 5.1, Figure 7, Tables 1-2): exact expectation ``top{k}``, the
      paper's sampled protocol ``top{k}_sampled`` (15 queries x 10 draws per fabric) and, with
      ``config.released_variant``, the released code's ``top{k}_released``;
    - ``map``, ``recall{k}``, ``median_rank`` over the whole gallery;
    - ``_chance`` beside each, ``_ci_low``/``_ci_high`` from a bootstrap over the test fabrics;
    - calibration of ``P ∝ exp(-c D^2)`` (section 5.2): ``c`` (fitted on ``reference`` when
      given, else the paper's 0.085), ``fabric_accuracy`` (most probable gallery fabric is the
      query's), ``confidence``, ``ece``, ``nll``, with chance; confusion matrices (Figure 8)
      for the figure pairs.

    With ``reference`` (and `EvalConfig.cross_map`), every pair of two modalities is also
    matched through a cross-modal map fitted on the reference fabrics (``{pair}_top{k}_mapped``
    with its interval; `EvalResult.cross_maps`), and the glance ranks the looks through it.

    Touch queries pool ``config.presses`` presses of one fabric (element-wise max, the
    Multi-input Net), and so do the touch candidates of another modality's queries (the net
    embeds touch from its presses wherever touch is; touch to touch picks among single
    presses); the curve over P = 1 .. ``config.max_presses`` is in the
    ``touch_to_{gallery}_presses{P}_*`` keys. Physical-property probes (k-NN, ridge) are fitted
    on ``reference`` and scored on the test fabrics when ``labels`` are given:
    ``property_{modality}_{label}_{probe}_{r2|spearman|mae|mae_chance}`` (and ``..._knn_k``;
    ``..._n_test``: the labelled test fabrics they are over);
    a k-NN, the probe's or the glance's feel, averages at most half the reference fabrics
    (`knn_neighbours`), noted where that is fewer than ``config.probe_k``. A calibration row
    says how many reference fabrics c was fitted on (``{pair}_c_fit_fabrics``) and whether its
    NLL is clearly above chance's (`CalibrationResult.overconfident`: by more than twice its
    standard error over the test fabrics, ``{pair}_nll_se``, or twice chance's;
    ``{pair}_overconfident``).

    Args:
        embedded: the test items' embeddings per modality (touch: one row per press).
        config: the protocol; default `EvalConfig()` with ``presses`` 1 when unset.
        clusters: fabric id -> cluster, to order confusion matrices and build the cluster
            matrix (Figure 8b); None or all-None: fabrics in id order, no cluster matrix.
        labels: fabric id -> label values (NaN: unknown), for the probes; must cover the
            reference fabrics too.
        label_names: a name per label column (default ``"0"``, ``"1"``, ...).
        reference: embeddings of other (training) fabrics, to fit c and the probes on.
        pool_presses: embeds pooled touch queries; default `max_pool_presses`. Pass the model
            (see `evaluate_checkpoint`) when it pools before a projection or normalisation.
        info: provenance copied into the result (split, checkpoint ...).
        data_config: the preprocessing of the items' images, for example figures.

    Returns:
        `EvalResult`.

    Raises:
        ValueError: no embeddings, or embeddings and fabric ids of different lengths.
    """
    config = config or EvalConfig()
    presses = config.presses or 1
    config = replace(config, presses=presses)
    pool = pool_presses or max_pool_presses
    mods = [m for m in Modality if m in embedded and len(embedded[m].embeddings)]
    if not mods:
        raise ValueError("no embeddings to evaluate")
    for m in mods:
        e = embedded[m]
        if len(e.embeddings) != len(e.fabric_ids):
            raise ValueError(
                f"{m.value}: {len(e.embeddings)} embeddings but {len(e.fabric_ids)} fabric ids"
            )
    notes = _Notes()
    if config.space == "labels":
        if labels is None or reference is None:
            raise ConfigError(
                "eval.space: labels needs the fabrics' labels and reference (training) fabrics"
            )
        n_cols = len(next(iter(labels.values()), []))
        names = list(label_names) if label_names is not None else [str(j) for j in range(n_cols)]
        embedded, reference, pool = project_to_labels(
            {m: embedded[m] for m in mods}, reference, labels, names, pool
        )
        notes.add(
            "scored in label space: each modality mapped onto the labels' normal scores by a "
            "ridge fitted on the reference (training) fabrics"
        )
    all_fabrics = np.unique(np.concatenate([embedded[m].fabric_ids for m in mods]))
    known = dict(clusters or {})
    cluster_map: dict[Hashable, Hashable] | None = None
    if any(known.get(int(f)) is not None for f in all_fabrics):
        cluster_map = {}
        for f in all_fabrics:
            c = known.get(int(f))
            cluster_map[int(f)] = int(c) if c is not None else UNCLUSTERED
    else:
        notes.add("no clusters known: confusion matrices in fabric-id order, no cluster matrix")

    queries = {
        m: press_queries(embedded[m], presses if m.pooled else 1, config.seed, pool) for m in mods
    }
    if Modality.TOUCH in mods and len(queries[Modality.TOUCH].fabric) == 0:
        notes.add(
            f"no fabric has {presses} {_touch_presses(embedded[Modality.TOUCH], data_config)} "
            "to pool into a query: touch queries are single presses"
        )
        presses = 1
        config = replace(config, presses=1)
        queries[Modality.TOUCH] = press_queries(embedded[Modality.TOUCH], 1, config.seed, pool)
    # The Multi-input Net embeds touch from its presses wherever touch is: pooled touch is also
    # what another sense's queries pick among (touch to touch picks among single presses).
    galleries = {m: q for m, q in queries.items() if q.pooled}
    pairs = Pair.every(mods)
    figure_pairs = _figure_pairs(config, pairs)
    protocol = scoring_protocol(config)
    gallery = {m: np.asarray(embedded[m].embeddings, dtype=np.float64) for m in mods}
    gallery_fabric = {m: np.asarray(embedded[m].fabric_ids, dtype=np.int64) for m in mods}
    per_pair: dict[Pair, dict[str, float]] = {}
    ref_queries: dict[Modality, QuerySet] = {}  # built once per modality, when c is fitted
    calibration: dict[Pair, CalibrationResult] = {}
    examples: dict[Pair, tuple[PickExample, ...]] = {}
    not_scored: dict[Pair, str] = {}  # pairs none of whose queries has its own fabric to find
    glance_q = np.zeros(0, dtype=np.int64)
    if Modality.TOUCH in mods and any(m in mods for m in _LOOKS):
        count = min(GLANCE_QUERIES, config.examples)
        glance_q = _glance_queries(queries[Modality.TOUCH], count, config.seed)
    glance_seen: dict[Modality, list[GlanceGallery]] = {}

    def reference_queries(m: Modality) -> QuerySet:
        """The reference fabrics' queries of modality ``m``, pooled as the test queries are."""
        assert reference is not None
        if m not in ref_queries:
            p = presses if m.pooled else 1
            ref_queries[m] = press_queries(reference[m], p, config.seed, pool)
        return ref_queries[m]

    def reference_gallery(m: Modality, same: bool = False) -> QuerySet:
        """The reference fabrics' candidates of modality ``m``, pooled as the test candidates
        are (for another modality's queries; ``same``: a same-modality pair's, single items)."""
        assert reference is not None
        if m in galleries and not same:
            return reference_queries(m)
        return QuerySet.single(reference[m].embeddings, reference[m].fabric_ids)

    def score(pd: PairDistances) -> None:
        pair, dist, qs, excl = pd.pair, pd.dist, pd.queries, pd.exclude
        gf = np.asarray(pd.gallery_fabric, dtype=np.int64)  # already int64: no copy
        q, g = pair.query, pair.gallery
        if q is Modality.TOUCH and g in _LOOKS and len(glance_q):
            glance_seen[g] = [
                _nearest_fabrics(np.asarray(dist[qi]), gf, int(qs.fabric[qi]), g) for qi in glance_q
            ]
        with notes.catching(pair):
            scored = score_distances(dist, qs.fabric, gf, protocol, exclude=excl)
        out = {f"{pair}_{k}": v for k, v in scored.metrics.items()}
        scorable = scored.pick.n_queries > 0
        if not scorable:  # its numbers are NaN: say why instead
            kinds = [k.value for k in data_config.touch_kinds] if data_config else []
            why = no_query_scored(pair, presses, kinds=kinds, option="--set presses=")
            not_scored[pair] = why
            notes.add(f"{pair} not scored: {why}")
        c_used, source = config.c, "fixed"
        fit_fabrics = 0
        if c_used is None:
            fitted = None
            if (
                scorable
                and reference is not None
                and config.fit_c
                and q in reference
                and g in reference
            ):
                rq, rg = reference_queries(q), reference_gallery(g, pair.same)
                fitted = _fit_c(rq, rg, q, g, notes)
                if fitted is not None:
                    fit_fabrics = len(np.intersect1d(rq.fabric, rg.fabric))
            c_used, source = (fitted, "fitted") if fitted is not None else (PAPER_C, "paper")
        figure = pair in figure_pairs
        cal = _calibrate(
            pair, dist, qs, gf, excl, c_used, source, config, cluster_map, figure, scorable
        )
        cal = calibration[pair] = replace(cal, fit_fabrics=fit_fabrics)
        out[f"{pair}_c"] = cal.c
        out[f"{pair}_c_fitted"] = 1.0 if source == "fitted" else 0.0
        out[f"{pair}_c_fit_fabrics"] = float(fit_fabrics) if fit_fabrics else math.nan
        out[f"{pair}_fabric_accuracy"] = cal.accuracy
        out[f"{pair}_fabric_accuracy_ci_low"], out[f"{pair}_fabric_accuracy_ci_high"] = (
            cal.accuracy_ci
        )
        out[f"{pair}_fabric_accuracy_chance"] = 1.0 / max(cal.n_fabrics, 1)
        out[f"{pair}_confidence"] = cal.confidence
        out[f"{pair}_ece"] = cal.reliability.ece
        out[f"{pair}_nll"] = cal.nll
        out[f"{pair}_nll_chance"] = cal.nll_chance
        out[f"{pair}_nll_se"] = cal.nll_se
        out[f"{pair}_overconfident"] = (
            float(cal.overconfident) if math.isfinite(cal.nll) else math.nan
        )
        per_pair[pair] = out
        if figure:
            rows = None if pair.same or g not in galleries else galleries[g].members[:, 0]
            examples[pair] = _draw_examples(pair, dist, qs, gf, pair.same, config, rows)

    for pd in pair_distances(gallery, gallery_fabric, pairs, queries=queries, galleries=galleries):
        score(pd)
    metrics: dict[str, float] = {}
    for pair in pairs:
        metrics.update(per_pair[pair])
    calibration = {pair: calibration[pair] for pair in pairs}
    maps: dict[Pair, CrossMap] = {}
    if config.cross_map and config.space == "embedding" and reference is not None:
        extra, maps, mapped_dist = _mapped(
            pairs,
            queries,
            lambda m: (
                galleries[m] if m in galleries else QuerySet.single(gallery[m], gallery_fabric[m])
            ),
            reference_queries,
            reference_gallery,
            reference,
            config,
            notes,
        )
        metrics.update(extra)
        for pair, dist in mapped_dist.items():  # the glance shows what the map finds
            if pair.query is Modality.TOUCH and pair.gallery in glance_seen:
                own = queries[Modality.TOUCH].fabric
                glance_seen[pair.gallery] = [
                    replace(
                        _nearest_fabrics(
                            dist[qi], gallery_fabric[pair.gallery], int(own[qi]), pair.gallery
                        ),
                        mapped=True,
                    )
                    for qi in glance_q
                ]

    if Modality.TOUCH in mods:
        # The press curve: exact top-k with intervals of touch queries pooling P presses.
        curve = replace(protocol, gallery=False, sampled=False, released_variant=False)
        touch = embedded[Modality.TOUCH]
        to_every = [Pair(Modality.TOUCH, g) for g in mods]
        for p in range(1, config.max_presses + 1):
            qs = (
                queries[Modality.TOUCH]
                if p == presses
                else press_queries(touch, p, config.seed, pool)
            )
            if len(qs.fabric) == 0:
                what = _touch_presses(touch, data_config)
                notes.add(f"no fabric has {p} {what}: the press curve stops before {p}")
                break
            if p == presses:  # the main keys already hold these
                for pair in to_every:
                    for key in _curve_keys(config):
                        if f"{pair}_{key}" in metrics:
                            metrics[f"{pair}_presses{p}_{key}"] = metrics[f"{pair}_{key}"]
                continue
            touch_queries = {Modality.TOUCH: qs}
            for pd in pair_distances(gallery, gallery_fabric, to_every, queries=touch_queries):
                with notes.catching(f"touch ({p} presses) to {pd.pair.gallery.value}"):
                    point = score_distances(
                        pd.dist, qs.fabric, pd.gallery_fabric, curve, exclude=pd.exclude
                    ).metrics
                for key in _curve_keys(config):
                    metrics[f"{pd.pair}_presses{p}_{key}"] = point.get(key, math.nan)

    properties: dict[Modality, dict[str, dict[str, dict[str, float]]]] = {}
    if labels is None:
        notes.add("no labels: physical-property probes skipped")
    elif reference is None:
        notes.add("no reference (training) fabrics: physical-property probes skipped")
    else:
        n_cols = len(next(iter(labels.values()), []))
        names = list(label_names) if label_names is not None else [str(j) for j in range(n_cols)]
        properties = _probes(
            {m: embedded[m] for m in mods}, reference, labels, names, config, notes
        )
        for m, by_probe in properties.items():
            for probe, by_label in by_probe.items():
                for name, scores in by_label.items():
                    for stat in ("r2", "spearman", "mae", "mae_chance", "k", "n_test"):
                        if stat in scores:  # k: the k-NN's neighbours; n_test: scored over
                            metrics[f"property_{m.value}_{name}_{probe}_{stat}"] = scores[stat]
    full_info = dict(info or {})
    full_info.setdefault("items", {m.value: len(embedded[m].embeddings) for m in mods})
    full_info.setdefault("fabrics", [int(f) for f in all_fabrics])
    glance: list[GlanceExample] = []
    if len(glance_q):
        tq = queries[Modality.TOUCH]
        n_cols = len(next(iter(labels.values()), [])) if labels else 0
        columns = tuple(label_names or [str(j) for j in range(n_cols)])
        ref_touch = None
        if labels and reference is not None and Modality.TOUCH in reference:
            ref_touch = reference_queries(Modality.TOUCH)
        for i, qi in enumerate(glance_q):
            f = int(tq.fabric[qi])
            predicted: tuple[float, ...] = ()
            truth: tuple[float, ...] = ()
            neighbours: tuple[int, ...] = ()
            n_ref = 0
            if labels and ref_touch is not None and len(ref_touch.fabric):
                predicted, neighbours, n_ref = _feels_like(
                    tq.emb[qi], f, ref_touch, labels, n_cols, config.probe_k
                )
                truth = tuple(float(v) for v in _labels_of(np.array([f]), labels, n_cols)[0])
                if neighbours and len(neighbours) < config.probe_k:
                    what = "the glance's feel"
                    notes.add(fewer_neighbours(what, len(neighbours), n_ref, config.probe_k))
            glance.append(
                GlanceExample(
                    query_rows=tuple(int(r) for r in tq.members[qi]),
                    fabric=f,
                    galleries=tuple(glance_seen[m][i] for m in _LOOKS if m in glance_seen),
                    label_names=columns if predicted else (),
                    predicted=predicted,
                    truth=truth,
                    neighbours=neighbours,
                    n_reference=n_ref,
                )
            )

    return EvalResult(
        metrics=metrics,
        config=config,
        pairs=tuple(pairs),
        calibration=calibration,
        examples=examples,
        properties=properties,
        embedded={m: embedded[m] for m in mods},
        clusters={int(f): known.get(int(f)) for f in all_fabrics},
        notes=tuple(notes.items),
        info=full_info,
        data_config=data_config,
        glance=tuple(glance),
        cross_maps=maps,
        not_scored=not_scored,
        pooled_queries=dict(galleries),
    )
