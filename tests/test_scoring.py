"""The one scoring path: `score_pairs` against brute force, the transpose trick, pooled queries."""

from __future__ import annotations

import itertools
import warnings

import numpy as np
import pytest

from lookfeel.metrics import (
    EXACT_PICK,
    QuerySet,
    ScoringProtocol,
    flat_metrics,
    pair_distances,
    pairwise_distances,
    pick_k_of_n_exact,
    score_distances,
    score_pairs,
)
from lookfeel.modality import Modality, Pair
from tests.test_metrics import brute_gallery, brute_pick, clustered_embeddings

D, C, T = Modality.DEPTH, Modality.COLOR, Modality.TOUCH


def _oracle(q_emb, q_fab, g_emb, g_fab, same, n, ks, recall_ks):
    """Per-query pick top-k, AP, first rank and recall@k by enumeration, on direct distances.

    A same-modality query is scored against the gallery without its own item.
    """
    dist = np.sqrt(((q_emb[:, None, :] - g_emb[None, :, :]) ** 2).sum(-1))
    pick, ap, first, rec = [], [], [], []
    for i in range(len(q_emb)):
        keep = np.arange(len(g_emb)) != i if same else np.ones(len(g_emb), dtype=bool)
        row, gf = dist[i : i + 1, keep], g_fab[keep]
        pick.append(brute_pick(row, q_fab[i : i + 1], gf, n, ks)[0])
        a, f, r = brute_gallery(row, q_fab[i : i + 1], gf, recall_ks)
        ap.append(a[0])
        first.append(f[0])
        rec.append(r[0])
    return np.array(pick), np.array(ap), np.array(first), np.array(rec)


def test_score_pairs_matches_brute_force_on_every_pair():
    rng = np.random.default_rng(3)
    fab = {D: np.repeat(np.arange(5), 2), T: np.repeat(np.arange(5), 3)}
    emb = {m: rng.standard_normal((len(f), 3)) for m, f in fab.items()}
    protocol = ScoringProtocol(n=3, ks=(1, 2), recall_ks=(1, 3), sampled=False, n_boot=0)
    scores = score_pairs(emb, fab, protocol)
    assert list(scores) == ["depth_to_depth", "depth_to_touch", "touch_to_depth", "touch_to_touch"]
    for pair, s in scores.items():
        q, g = pair.query, pair.gallery
        pick, ap, first, rec = _oracle(emb[q], fab[q], emb[g], fab[g], pair.same, 3, (1, 2), (1, 3))
        np.testing.assert_allclose(s.pick.per_query, pick, atol=1e-12, err_msg=pair)
        m = s.metrics
        assert [m["top1"], m["top2"]] == pytest.approx(pick.mean(axis=0), abs=1e-12)
        assert m["map"] == pytest.approx(ap.mean(), abs=1e-12)
        assert m["median_rank"] == pytest.approx(np.median(first))
        assert [m["recall1"], m["recall3"]] == pytest.approx(rec.mean(axis=0), abs=1e-12)
        assert m["top1_chance"] == pytest.approx(1 / 3) and m["n_effective"] == 3
        assert m["n_queries"] == len(emb[q]) and m["n_fabrics"] == 5


def test_exact_pick_protocol_is_the_pick_and_nothing_else():
    emb, fabric = clustered_embeddings(12, 3, seed=4)
    pair = Pair(D, D)
    s = score_pairs({D: emb}, {D: fabric}, EXACT_PICK, [pair])[pair]
    direct = pick_k_of_n_exact(
        pairwise_distances(emb, emb), fabric, fabric, exclude_self=np.arange(len(emb))
    )
    np.testing.assert_array_equal(s.pick.per_query, direct.per_query)
    assert sorted(s.metrics) == sorted(
        ["top1", "top1_chance", "top3", "top3_chance", "n_effective", "n_queries", "n_fabrics"]
    )


def test_reverse_pair_uses_the_transpose_and_pooled_queries_their_own_matrix():
    rng = np.random.default_rng(5)
    fab = {D: np.repeat(np.arange(4), 2), T: np.repeat(np.arange(4), 4)}
    emb = {m: rng.standard_normal((len(f), 6)) for m, f in fab.items()}
    got = {pd.pair: pd for pd in pair_distances(emb, fab, [Pair(T, D), Pair(D, T)])}
    assert list(got) == ["touch_to_depth", "depth_to_touch"]
    assert np.shares_memory(got[Pair(T, D)].dist, got[Pair(D, T)].dist)
    np.testing.assert_allclose(got[Pair(D, T)].dist, pairwise_distances(emb[D], emb[T]))
    # Two presses of one fabric pooled into each touch query: a touch gallery leaves out both.
    members = np.arange(16).reshape(8, 2)
    pooled = QuerySet(emb[T][members].max(axis=1), fab[T][members[:, 0]], members)
    got = {
        pd.pair: pd
        for pd in pair_distances(
            emb, fab, [Pair(T, D), Pair(D, T), Pair(T, T)], queries={T: pooled}
        )
    }
    assert got[Pair(T, D)].dist.shape == (8, 8) and got[Pair(D, T)].dist.shape == (8, 16)
    assert got[Pair(T, T)].exclude.shape == (8, 16) and got[Pair(T, T)].exclude.sum() == 16
    assert got[Pair(T, D)].exclude is None


def test_pooled_gallery_is_what_other_senses_pick_among_and_keeps_the_transpose():
    rng = np.random.default_rng(6)
    fab = {D: np.repeat(np.arange(4), 2), T: np.repeat(np.arange(4), 4)}
    emb = {m: rng.standard_normal((len(f), 6)) for m, f in fab.items()}
    members = np.arange(16).reshape(8, 2)
    pooled = QuerySet(emb[T][members].max(axis=1), fab[T][members[:, 0]], members)
    pairs = [Pair(T, D), Pair(D, T), Pair(T, T)]
    got = {
        pd.pair: pd
        for pd in pair_distances(emb, fab, pairs, queries={T: pooled}, galleries={T: pooled})
    }
    # Depth picks among the 8 pooled sets (their fabrics), on the transpose of touch to depth.
    d2t = got[Pair(D, T)]
    assert d2t.dist.shape == (8, 8)
    np.testing.assert_array_equal(d2t.gallery_fabric, fab[T][members[:, 0]])
    np.testing.assert_allclose(d2t.dist, pairwise_distances(emb[D], pooled.emb))
    assert np.shares_memory(d2t.dist, got[Pair(T, D)].dist)
    # Touch to touch still picks among single presses, leaving out the query's own two.
    t2t = got[Pair(T, T)]
    assert t2t.dist.shape == (8, 16) and t2t.exclude.sum() == 16
    # A pooled gallery without pooled queries: its own matrix, not a transpose.
    got = {pd.pair: pd for pd in pair_distances(emb, fab, pairs[:2], galleries={T: pooled})}
    np.testing.assert_allclose(got[Pair(T, D)].dist, pairwise_distances(emb[T], emb[D]))
    np.testing.assert_allclose(got[Pair(D, T)].dist, pairwise_distances(emb[D], pooled.emb))
    # Scored: the per-query pick equals the pick on the pooled matrix itself (pick 1 of 3).
    protocol = ScoringProtocol(n=3, ks=(1,), gallery=False, sampled=False, n_boot=0)
    s = score_pairs(emb, fab, protocol, [Pair(D, T)], galleries={T: pooled})[Pair(D, T)]
    direct = pick_k_of_n_exact(
        pairwise_distances(emb[D], pooled.emb), fab[D], pooled.fabric, n=3, ks=(1,)
    )
    np.testing.assert_array_equal(s.pick.per_query, direct.per_query)


def test_missing_modality_and_bad_pair_name_the_problem():
    emb = {D: np.zeros((4, 2))}
    fab = {D: np.arange(4)}
    with pytest.raises(ValueError, match="touch_to_depth: no touch embeddings"):
        score_pairs(emb, fab, EXACT_PICK, ["touch_to_depth"])
    with pytest.raises(ValueError, match="'depth-depth' is not a modality pair"):
        score_pairs(emb, fab, EXACT_PICK, ["depth-depth"])
    with pytest.raises(ValueError, match="ks must be positive"):
        ScoringProtocol(ks=())


def test_evaluate_pair_keys_and_consistency():
    emb, fabric = clustered_embeddings(12, 5, seed=14)
    touch = emb + 0.5 * np.random.default_rng(15).standard_normal(emb.shape)
    out = flat_metrics(
        score_pairs(
            {T: touch, D: emb}, {T: fabric, D: fabric}, ScoringProtocol(n_boot=200), [Pair(T, D)]
        )
    )
    exact = pick_k_of_n_exact(pairwise_distances(touch, emb), fabric, fabric)
    assert out["touch_to_depth_top1"] == pytest.approx(exact.mean[0], abs=1e-12)
    assert out["touch_to_depth_top1_chance"] == pytest.approx(0.1)
    for name in ("top1", "top3", "map", "recall1", "recall5", "recall10", "median_rank"):
        low, high = out[f"touch_to_depth_{name}_ci_low"], out[f"touch_to_depth_{name}_ci_high"]
        assert low <= out[f"touch_to_depth_{name}"] <= high, name
    assert out["touch_to_depth_n_queries"] == 60 and out["touch_to_depth_n_fabrics"] == 12
    assert abs(out["touch_to_depth_top1"] - out["touch_to_depth_top1_sampled"]) < (
        2 * out["touch_to_depth_top1_sampled_se"] + 0.02
    )


def test_all_pairs_covers_nine_pairs_and_excludes_self():
    rng = np.random.default_rng(16)
    fabric = np.repeat(np.arange(11), 4)
    embs = {m: rng.standard_normal((44, 8)) for m in Modality}
    fabs = {m: fabric for m in Modality}
    protocol = ScoringProtocol(n_boot=50, sampled=False)
    out = flat_metrics(score_pairs(embs, fabs, protocol))
    for q, g in itertools.product(Modality, Modality):
        assert f"{q.value}_to_{g.value}_top1" in out
        assert f"{q.value}_to_{g.value}_top1_ci_high" in out
    # Random embeddings: a same-modality pair that saw the query itself would score ~1.
    assert out["depth_to_depth_top1"] < 0.3
    assert out["depth_to_depth_n_queries"] == 44
    scored = score_distances(
        pairwise_distances(embs[Modality.COLOR], embs[Modality.TOUCH]), fabric, fabric, protocol
    )
    direct = {f"x_{k}": v for k, v in scored.metrics.items()}
    assert out["color_to_touch_map"] == pytest.approx(direct["x_map"], abs=1e-12)
    assert out["color_to_touch_top1_ci_low"] == pytest.approx(direct["x_top1_ci_low"])


def test_no_warnings_on_normal_use():
    emb, fabric = clustered_embeddings(10, 3, seed=17)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        score_pairs({"touch": emb}, {"touch": fabric}, ScoringProtocol(n_boot=20))


def test_released_variant_keys_follow_the_rest():
    emb, fabric = clustered_embeddings(10, 3, seed=18)
    s = score_distances(
        pairwise_distances(emb, emb),
        fabric,
        fabric,
        ScoringProtocol(n_boot=0, released_variant=True),
        exclude=np.arange(len(emb)),
    )
    assert list(s.metrics)[-4:] == [
        "top1_released",
        "top1_released_se",
        "top3_released",
        "top3_released_se",
    ]
