"""Metrics: literal truth tables on hand-made distances, brute-force parity, chance, calibration."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

import lookfeel.metrics._ranking as ranking
from lookfeel.metrics import (
    bootstrap_ci,
    chance_average_precision,
    chance_median_rank,
    chance_recall,
    cluster_confusion_matrix,
    confusion_matrix,
    expected_calibration_error,
    fabric_predictions,
    fabric_probabilities,
    fit_temperature,
    gallery_metrics,
    group_queries,
    match_probabilities,
    mean_and_spread,
    order_by_cluster,
    pairwise_distances,
    pick_k_of_n_exact,
    pick_k_of_n_sampled,
    property_probe,
    reliability_curve,
)
from lookfeel.metrics.bootstrap import fabric_weights, percentile_interval
from lookfeel.metrics.properties import (
    knn_neighbours,
    probe_columns,
    resampled_r2,
    resampled_spearman,
)

# ---------------------------------------------------------------- oracles (slow, obvious)


def brute_pick(dist, qf, gf, n, ks, exclude=None):
    """Enumerate every true item, distractor-fabric subset and item choice; ties uniform."""
    dist, qf, gf = np.asarray(dist, float), np.asarray(qf), np.asarray(gf)
    fabrics = np.unique(gf)
    out = []
    for q in range(len(dist)):
        true = [g for g in np.flatnonzero(gf == qf[q]) if exclude is None or exclude[q] != g]
        others = [f for f in fabrics if f != qf[q]]
        m = min(n - 1, len(others))
        per_t = []
        for t in true:
            per_s = []
            for subset in itertools.combinations(others, m):
                items = [np.flatnonzero(gf == f) for f in subset]
                hits = []
                for choice in itertools.product(*items):
                    d = dist[q, list(choice)]
                    lt, eq = int((d < dist[q, t]).sum()), int((d == dist[q, t]).sum())
                    hits.append([np.mean([lt + 1 + x <= k for x in range(eq + 1)]) for k in ks])
                per_s.append(np.mean(hits, axis=0))
            per_t.append(np.mean(per_s, axis=0))
        out.append(np.mean(per_t, axis=0))
    return np.array(out)


def brute_gallery(dist, qf, gf, ks):
    """Average AP, first rank and recall@k over every tie order (permutations within ties)."""
    ap, first, rec = [], [], []
    for q in range(len(dist)):
        rel = gf == qf[q]
        groups = [np.flatnonzero(dist[q] == v) for v in np.unique(dist[q])]
        runs = []
        for parts in itertools.product(*(itertools.permutations(g) for g in groups)):
            r = rel[list(itertools.chain(*parts))]
            hits = np.cumsum(r)
            f = int(np.argmax(r)) + 1
            ap_q = (r * hits / np.arange(1, len(r) + 1)).sum() / r.sum()
            runs.append([ap_q, f] + [f <= k for k in ks])
        mean = np.mean(runs, axis=0)
        ap.append(mean[0])
        first.append(mean[1])
        rec.append(mean[2:])
    return np.array(ap), np.array(first), np.array(rec)


def clustered_embeddings(n_fabrics, per_fabric, dim=16, spread=1.0, seed=0):
    rng = np.random.default_rng(seed)
    fabric = np.repeat(np.arange(n_fabrics), per_fabric)
    centres = rng.standard_normal((n_fabrics, dim))
    return centres[fabric] + spread * rng.standard_normal((len(fabric), dim)), fabric


# ---------------------------------------------------------------- distances


def test_pairwise_distances_match_direct_float64():
    rng = np.random.default_rng(0)
    q, g = rng.standard_normal((7, 5)), rng.standard_normal((4, 5))
    direct = np.sqrt(((q[:, None, :] - g[None, :, :]) ** 2).sum(-1))
    np.testing.assert_allclose(pairwise_distances(q, g), direct, rtol=1e-12, atol=1e-12)
    assert pairwise_distances([[3.0, 4.0]], [[0.0, 0.0], [3.0, 4.0]]).tolist() == [[5.0, 0.0]]
    same = pairwise_distances(q, q)
    assert (same >= 0).all() and np.allclose(np.diag(same), 0.0, atol=1e-7)
    with pytest.raises(ValueError, match="sizes differ"):
        pairwise_distances(q, g[:, :3])


# ---------------------------------------------------------------- pick k of n: truth tables

# Gallery: fabrics A, B, C, D with two items each. One query of fabric A. Its true items are at
# distance 1 (nothing closer) and 5, where both B items (2, 3) are closer, one C item (4) of
# two, and neither D item (7, 8): p_B = 1, p_C = 1/2, p_D = 0.
GALLERY = np.array(["A", "A", "B", "B", "C", "C", "D", "D"])
ROW = np.array([[1.0, 5.0, 2.0, 3.0, 4.0, 6.0, 7.0, 8.0]])


@pytest.mark.parametrize(
    ("n", "ks", "expected"),
    [
        # m = 1 distractor fabric: t=5 survives with 1 - mean(p) = 1/2.
        (2, (1, 2), [(1 + 1 / 2) / 2, 1.0]),
        # m = 2: subsets BC, BD, CD give P(none beats) 0, 0, 1/2 and P(< 2 beat) 1/2, 1, 1.
        (3, (1, 2, 3), [(1 + 1 / 6) / 2, (1 + 5 / 6) / 2, 1.0]),
        # m = 3: B always beats, D never, C half the time.
        (4, (1, 2, 3), [(1 + 0) / 2, (1 + 1 / 2) / 2, 1.0]),
    ],
)
def test_pick_exact_truth_table(n, ks, expected):
    res = pick_k_of_n_exact(ROW, ["A"], GALLERY, n=n, ks=ks)
    np.testing.assert_allclose(res.per_query[0], expected, atol=1e-12)
    np.testing.assert_allclose(res.mean, expected, atol=1e-12)
    assert res.n_effective == n
    np.testing.assert_allclose(res.chance, [min(k, n) / n for k in ks])


def test_pick_ties_broken_uniformly_give_exact_chance():
    # A collapsed embedding: every distance equal. Chance must come out exactly, k / n.
    gf = np.repeat(np.arange(12), 3)
    dist = np.ones((5, len(gf)))
    res = pick_k_of_n_exact(dist, [0, 1, 2, 3, 4], gf, n=10, ks=(1, 3, 10))
    np.testing.assert_allclose(res.per_query, [[0.1, 0.3, 1.0]] * 5, atol=1e-12)
    # One tie: t at 2.0 ties the only distractor item at 2.0 -> it ranks first half the time.
    half = pick_k_of_n_exact([[2.0, 2.0]], ["A"], ["A", "B"], n=2, ks=(1,))
    assert half.per_query[0, 0] == pytest.approx(0.5, abs=1e-12)


def test_pick_exact_equals_brute_force_enumeration():
    rng = np.random.default_rng(1)
    for case in range(8):
        per = rng.integers(1, 4, size=5)
        gf = np.repeat(np.arange(5), per)
        qf = rng.integers(0, 5, size=3)
        # Odd cases: small integer distances, so many ties.
        dist = (
            rng.integers(0, 3, size=(3, len(gf))).astype(float)
            if case % 2
            else rng.random((3, len(gf)))
        )
        for n in (2, 3, 5):
            got = pick_k_of_n_exact(dist, qf, gf, n=n, ks=(1, 2, 3)).per_query
            np.testing.assert_allclose(got, brute_pick(dist, qf, gf, n, (1, 2, 3)), atol=1e-12)


def test_pick_positive_term_path_equals_brute_force(monkeypatch):
    # Large m uses the Poisson-binomial x hypergeometric form; force it on small cases.
    monkeypatch.setattr(ranking, "_MAX_ALTERNATING_M", 0)
    rng = np.random.default_rng(2)
    gf = np.repeat(np.arange(5), [2, 1, 3, 2, 2])
    dist = rng.integers(0, 3, size=(4, len(gf))).astype(float)
    qf = np.array([0, 2, 3, 4])
    for n in (2, 4):
        got = pick_k_of_n_exact(dist, qf, gf, n=n, ks=(1, 3)).per_query
        np.testing.assert_allclose(got, brute_pick(dist, qf, gf, n, (1, 3)), atol=1e-12)


def test_pick_exclude_self_equals_brute_force():
    rng = np.random.default_rng(3)
    gf = np.repeat(np.arange(4), [2, 3, 2, 3])
    emb = rng.integers(0, 3, size=(len(gf), 2)).astype(float)  # duplicates -> ties
    dist = pairwise_distances(emb, emb)
    own = np.arange(len(gf))
    got = pick_k_of_n_exact(dist, gf, gf, n=3, ks=(1, 2), exclude_self=own).per_query
    np.testing.assert_allclose(got, brute_pick(dist, gf, gf, 3, (1, 2), exclude=own), atol=1e-12)
    mask = np.zeros((len(gf), len(gf)), dtype=bool)
    mask[own, own] = True
    masked = pick_k_of_n_exact(dist, gf, gf, n=3, ks=(1, 2), exclude_self=mask).per_query
    np.testing.assert_allclose(masked, got, atol=1e-15)


def test_pick_random_embeddings_give_chance():
    rng = np.random.default_rng(4)
    gf = np.repeat(np.arange(40), 10)
    emb_q, emb_g = rng.standard_normal((400, 8)), rng.standard_normal((400, 8))
    res = pick_k_of_n_exact(pairwise_distances(emb_q, emb_g), gf, gf)
    # Exact over the draw; what remains is the embedding's own noise (sd ~ 0.005 here).
    assert res.mean[0] == pytest.approx(0.1, abs=0.02)
    assert res.mean[1] == pytest.approx(0.3, abs=0.03)


def test_pick_fewer_fabrics_than_n_uses_all_and_says_so():
    gf = np.repeat(np.arange(4), 2)
    with pytest.warns(UserWarning, match="n_effective=4"):
        res = pick_k_of_n_exact(np.ones((2, 8)), [0, 1], gf, n=10, ks=(1, 3))
    assert res.n_effective == 4
    np.testing.assert_allclose(res.chance, [1 / 4, 3 / 4])
    np.testing.assert_allclose(res.mean, [1 / 4, 3 / 4], atol=1e-12)


def test_pick_query_fabric_absent_from_gallery_is_nan_and_left_out():
    res = pick_k_of_n_exact(ROW.repeat(2, axis=0), ["A", "Z"], GALLERY, n=2, ks=(1,))
    assert np.isnan(res.per_query[1, 0]) and res.n_queries == 1
    assert res.mean[0] == pytest.approx(0.75)


def test_pick_rejects_bad_input():
    with pytest.raises(ValueError, match="query_fabric has 2 entries for 1 dist rows"):
        pick_k_of_n_exact(ROW, ["A", "B"], GALLERY)
    with pytest.raises(ValueError, match="NaN"):
        pick_k_of_n_exact([[np.nan, 1.0]], ["A"], ["A", "B"])
    with pytest.raises(ValueError, match="only items of the query's own fabric"):
        pick_k_of_n_exact(ROW, ["A"], GALLERY, exclude_self=np.array([2]))


# ---------------------------------------------------------------- pick k of n: sampled


def test_sampled_agrees_with_exact_within_two_standard_errors():
    emb, fabric = clustered_embeddings(30, 6, spread=1.2, seed=5)
    emb2 = emb + 0.8 * np.random.default_rng(6).standard_normal(emb.shape)
    dist = pairwise_distances(emb, emb2)
    exact = pick_k_of_n_exact(dist, fabric, fabric)
    samp = pick_k_of_n_sampled(dist, fabric, fabric, repeats=40, seed=0)
    assert samp.n_queries == 180 and samp.n_trials == 7200
    assert 0.2 < exact.mean[0] < 0.9  # a case with signal, far from chance and from 1
    assert np.all(np.abs(samp.mean - exact.mean) < 2 * samp.se)
    assert np.all(samp.se < 0.03)


def test_sampled_same_modality_never_offers_the_query_itself():
    # Each query's partner (the other item of its fabric) is farther than every other item;
    # only the query itself (distance 0) would ever win for it.
    fabric = np.array([0, 0, 1, 1, 2, 2])
    dist = 1.0 + 0.1 * np.random.default_rng(0).random((6, 6))
    dist[fabric[:, None] == fabric[None, :]] = 10.0
    np.fill_diagonal(dist, 0.0)
    own = np.arange(6)
    samp = pick_k_of_n_sampled(dist, fabric, fabric, n=3, ks=(1,), exclude_self=own)
    exact = pick_k_of_n_exact(dist, fabric, fabric, n=3, ks=(1,), exclude_self=own)
    assert exact.mean[0] == 0.0 and samp.mean[0] == 0.0
    assert pick_k_of_n_exact(dist, fabric, fabric, n=3, ks=(1,)).mean[0] == pytest.approx(0.5)


def test_sampled_released_variant_may_draw_the_true_fabric():
    # Query of A: A1 at 1, A2 at 2, B1 at 3. The default draw always ranks t first; with the
    # true fabric allowed as a distractor, t = A2 loses to A1 half the time: 1/2 + 1/2 * 1/2.
    dist = np.array([[1.0, 2.0, 3.0]] * 40)
    qf, gf = ["A"] * 40, ["A", "A", "B"]
    default = pick_k_of_n_sampled(dist, qf, gf, n=2, ks=(1,), queries_per_fabric=40, repeats=50)
    assert default.mean[0] == 1.0
    released = pick_k_of_n_sampled(
        dist, qf, gf, n=2, ks=(1,), queries_per_fabric=40, repeats=50, allow_true_distractor=True
    )
    assert abs(released.mean[0] - 0.75) < 2 * released.se[0] + 0.01
    assert released.n_effective == 2


def test_sampled_is_deterministic_given_seed():
    emb, fabric = clustered_embeddings(12, 4, seed=7)
    dist = pairwise_distances(emb, emb[::-1])
    a = pick_k_of_n_sampled(dist, fabric, fabric[::-1], seed=3)
    b = pick_k_of_n_sampled(dist, fabric, fabric[::-1], seed=3)
    np.testing.assert_array_equal(a.mean, b.mean)


# ---------------------------------------------------------------- whole gallery


def test_gallery_truth_table():
    # Relevance in distance order: q0 -> 0 1 0 1 0, q1 -> 1 0 0 0 1 (fabric A relevant).
    gf = np.array(["B", "A", "C", "A", "D"])
    dist = np.array([[1.0, 2.0, 3.0, 4.0, 5.0], [2.0, 1.0, 3.0, 5.0, 4.0]])
    res = gallery_metrics(dist, ["A", "A"], gf, recall_ks=(1, 2, 5))
    # q0: hits at 2 and 4 -> AP (1/2 + 2/4) / 2 = 1/2; q1: hits at 1 and 5 -> (1 + 2/5) / 2.
    np.testing.assert_allclose(res.ap, [0.5, 0.7])
    np.testing.assert_allclose(res.first_rank, [2.0, 1.0])
    np.testing.assert_allclose(res.recall, [[0, 1, 1], [1, 1, 1]])
    assert res.map == pytest.approx(0.6)
    assert res.median_rank == 1.5
    np.testing.assert_allclose(res.recall_mean, [0.5, 1.0, 1.0])


def test_gallery_ties_are_expected_over_random_order():
    # All four tied, one relevant: rank uniform on 1..4.
    res = gallery_metrics([[1.0, 1.0, 1.0, 1.0]], ["A"], ["A", "B", "C", "D"], recall_ks=(1, 2))
    assert res.ap[0] == pytest.approx((1 + 1 / 2 + 1 / 3 + 1 / 4) / 4)
    assert res.first_rank[0] == pytest.approx(2.5)
    np.testing.assert_allclose(res.recall[0], [1 / 4, 1 / 2])


def test_gallery_equals_brute_force_with_ties():
    rng = np.random.default_rng(8)
    for case in range(8):
        gf = np.repeat(np.arange(3), rng.integers(1, 4, size=3))
        qf = rng.integers(0, 3, size=4)
        dist = (
            rng.integers(0, 3, size=(4, len(gf))).astype(float)
            if case % 2
            else rng.random((4, len(gf)))
        )
        res = gallery_metrics(dist, qf, gf, recall_ks=(1, 2, 3))
        ap, first, rec = brute_gallery(dist, qf, gf, (1, 2, 3))
        np.testing.assert_allclose(res.ap, ap, atol=1e-12)
        np.testing.assert_allclose(res.first_rank, first, atol=1e-12)
        np.testing.assert_allclose(res.recall, rec, atol=1e-12)
    # Two relevant items tied with an irrelevant one: the chance AP of G = 3, R = 2.
    tied = gallery_metrics([[1.0, 1.0, 1.0]], ["A"], ["A", "A", "B"])
    assert tied.ap[0] == pytest.approx(29 / 36)


def test_gallery_excludes_self():
    # Same set: without the exclusion every query would find itself first.
    emb = np.array([[0.0], [10.0], [1.0], [11.0]])
    fabric = np.array([0, 0, 1, 1])
    res = gallery_metrics(
        pairwise_distances(emb, emb), fabric, fabric, (1, 3), exclude_self=np.arange(4)
    )
    # q0 at 0 sees 1, 10, 11 (partner 2nd); q1 at 10 sees 11, 1, 0 (partner 3rd); and so on.
    np.testing.assert_allclose(res.first_rank, [2.0, 3.0, 3.0, 2.0])
    np.testing.assert_allclose(res.ap, [1 / 2, 1 / 3, 1 / 3, 1 / 2])
    np.testing.assert_allclose(res.recall, [[0, 1], [0, 1], [0, 1], [0, 1]])
    np.testing.assert_allclose(res.chance_map, chance_average_precision(3, 1))


def test_gallery_chance_levels_truth_table():
    assert chance_average_precision(2, 1) == pytest.approx(0.75)
    # [1,1,0] orders: 110 -> 1, 101 -> 5/6, 011 -> 7/12.
    assert chance_average_precision(3, 2) == pytest.approx(29 / 36)
    assert chance_average_precision(5, 5) == pytest.approx(1.0)
    assert chance_recall(4, 1, 2) == pytest.approx(0.5)
    assert chance_recall(5, 2, 1) == pytest.approx(0.4)
    assert chance_recall(5, 2, 4) == pytest.approx(1.0)
    assert chance_median_rank([4], [1]) == 2.0
    assert chance_median_rank([10, 10], [10, 10]) == 1.0


def test_gallery_random_embeddings_match_chance():
    rng = np.random.default_rng(9)
    gf = np.repeat(np.arange(30), 10)
    res = gallery_metrics(rng.random((600, 300)), rng.integers(0, 30, 600), gf)
    assert res.map == pytest.approx(res.chance_map, rel=0.1)
    np.testing.assert_allclose(res.recall_mean, res.chance_recall, atol=0.04)
    assert abs(res.median_rank - res.chance_median_rank) <= 3


# ---------------------------------------------------------------- multi-press queries


def test_group_queries_max_pools_disjoint_presses_of_one_fabric():
    emb = np.arange(20, dtype=float).reshape(10, 2) * np.array([1.0, -1.0])
    fabric = np.array([7] * 6 + [9] * 4)
    groups = group_queries(emb, fabric, presses=3, seed=0)
    assert groups.emb.shape == (3, 2) and groups.members.shape == (3, 3)
    assert sorted(groups.fabric.tolist()) == [7, 7, 9]  # 6 // 3 + 4 // 3; one press dropped
    for e, f, rows in zip(groups.emb, groups.fabric, groups.members, strict=True):
        assert (fabric[rows] == f).all()
        np.testing.assert_array_equal(e, emb[rows].max(axis=0))
    used = groups.members.ravel()
    assert len(set(used.tolist())) == 9
    again = group_queries(emb, fabric, presses=3, seed=0)
    np.testing.assert_array_equal(again.members, groups.members)


def test_group_queries_is_its_groups_then_the_one_max_pool():
    """Grouping and pooling are apart (QA F18): `group_members` gives `group_queries`' groups,
    `max_pool_groups` its embeddings, and evaluation's `max_pool_presses` is that same pool."""
    from lookfeel.embedding import EmbeddedItems
    from lookfeel.evaluate.core import max_pool_presses, press_queries
    from lookfeel.metrics import group_members, max_pool_groups
    from lookfeel.modality import Modality

    rng = np.random.default_rng(3)
    emb = rng.normal(size=(11, 4)).astype(np.float32)
    fabric = np.array([2, 5, 2, 5, 5, 2, 8, 2, 5, 8, 2])
    groups = group_queries(emb, fabric, presses=2, seed=4)
    members = group_members(fabric, presses=2, seed=4)
    np.testing.assert_array_equal(members, groups.members)
    np.testing.assert_array_equal(max_pool_groups(emb, members), groups.emb)
    touch = EmbeddedItems(Modality.TOUCH, emb, fabric, ())
    np.testing.assert_array_equal(max_pool_presses(touch, members), groups.emb)
    q = press_queries(touch, 2, 4)
    np.testing.assert_array_equal(q.emb, groups.emb)
    np.testing.assert_array_equal(q.members, groups.members)
    assert max_pool_groups(emb, members[:0]).shape == (0, 4)
    with pytest.raises(ValueError, match="presses must be >= 1"):
        group_members(fabric, presses=0)


# ---------------------------------------------------------------- bootstrap and spread


def test_bootstrap_interval_contains_estimate_and_shrinks_with_more_fabrics():
    rng = np.random.default_rng(10)

    def interval(n_fabrics):
        fabric = np.repeat(np.arange(n_fabrics), 5)
        values = rng.random(len(fabric)) + 0.3 * rng.standard_normal(n_fabrics)[fabric]
        low, high = bootstrap_ci(values, fabric, n_boot=500, seed=0)
        assert low <= values.mean() <= high
        return high - low

    narrow, wide = interval(200), interval(10)
    assert narrow < wide / 2.5  # width ~ 1 / sqrt(fabrics): sqrt(20) ~ 4.5


def test_bootstrap_literal_cases():
    low, high = bootstrap_ci(np.full(6, 0.4), [0, 0, 1, 1, 2, 2])
    assert low == pytest.approx(0.4) and high == pytest.approx(0.4)
    # One fabric has value 1, two have 0: a resample's mean is (draws of the first) / 3, with
    # P = 8/27, 12/27, 6/27, 1/27 for 0..3 draws: the 5th percentile is 0, the 95th is 2/3.
    low, high = bootstrap_ci([1.0, 0.0, 0.0], [0, 1, 2], n_boot=2000, alpha=0.1)
    assert low == 0.0 and high == pytest.approx(2 / 3)
    med_low, med_high = bootstrap_ci([1.0, 2.0, 3.0], [0, 1, 2], statistic="median")
    assert med_low == 1.0 and med_high == 3.0


def test_percentile_interval_of_replicates_skips_undefined_ones():
    assert percentile_interval(np.arange(101.0)) == pytest.approx((2.5, 97.5))
    assert percentile_interval([np.nan, *np.arange(101.0), np.nan]) == pytest.approx((2.5, 97.5))
    assert percentile_interval(np.arange(11.0), alpha=0.2) == pytest.approx((1.0, 9.0))
    assert all(math.isnan(v) for v in percentile_interval([np.nan, np.nan]))
    with pytest.raises(ValueError, match="alpha"):
        percentile_interval([1.0], alpha=1.0)


def test_mean_and_spread():
    out = mean_and_spread([1.0, 2.0, 3.0, np.nan])
    assert out["mean"] == 2.0 and out["std"] == 1.0 and out["n"] == 3.0
    assert out["sem"] == pytest.approx(1 / math.sqrt(3))
    assert (out["min"], out["max"]) == (1.0, 3.0)
    assert math.isnan(mean_and_spread([0.5])["std"])


# ---------------------------------------------------------------- confusion and calibration


def test_match_probabilities_follow_the_paper_and_are_stable():
    d = np.array([[0.0, 1.0, 2.0]])
    p = match_probabilities(d, c=0.085)
    expected = np.exp(-0.085 * d**2) / np.exp(-0.085 * d**2).sum()
    np.testing.assert_allclose(p, expected)
    far = match_probabilities(np.array([[1000.0, 1001.0]]), c=1.0)  # exp(-1e6) underflows
    np.testing.assert_allclose(far, [[1.0, 0.0]], atol=1e-300)
    own = match_probabilities(np.zeros((2, 2)), exclude_self=np.array([0, 1]))
    np.testing.assert_allclose(own, [[0.0, 1.0], [1.0, 0.0]])


def test_confusion_matrix_truth_table():
    # c = 1 and D^2 = ln 3 make exp(-c D^2) = 1/3: probabilities 3/4 and 1/4.
    s = math.sqrt(math.log(3.0))
    dist = np.array([[0.0, s], [s, 0.0], [1.0, 1.0]])
    conf = confusion_matrix(dist, ["A", "A", "B"], ["A", "B"], c=1.0)
    np.testing.assert_allclose(conf.matrix, [[0.5, 0.5], [0.5, 0.5]])
    conf = confusion_matrix(dist[:1], ["A"], ["A", "B"], c=1.0, order=["B", "A"])
    assert conf.rows.tolist() == ["A"] and conf.cols.tolist() == ["B", "A"]
    np.testing.assert_allclose(conf.matrix, [[0.25, 0.75]])
    probs, _ = fabric_probabilities(dist, ["A", "B"], c=1.0)
    np.testing.assert_allclose(probs.sum(axis=1), 1.0)
    pred, confidence, correct = fabric_predictions(dist[:2], ["A", "A"], ["A", "B"], c=1.0)
    assert pred.tolist() == ["A", "B"] and correct.tolist() == [True, False]
    np.testing.assert_allclose(confidence, [0.75, 0.75])


def test_cluster_confusion_and_cluster_order():
    s = math.sqrt(math.log(3.0))
    dist = np.array([[0.0, s, s], [s, 0.0, s]])  # gallery fabrics 1, 2, 3
    clusters = {1: "x", 2: "x", 3: "y"}
    conf = cluster_confusion_matrix(dist, [1, 2], [1, 2, 3], clusters, c=1.0)
    # Each query: own 3/5, the two others 1/5 each -> cluster x gets 4/5, y 1/5.
    assert conf.rows.tolist() == ["x"] and conf.cols.tolist() == ["x", "y"]
    np.testing.assert_allclose(conf.matrix, [[0.8, 0.2]])
    order = order_by_cluster([3, 1, 2, 4], {1: 1, 2: 0, 3: 1, 4: 0}, key={1: 5.0, 2: 1, 3: 2, 4: 0})
    assert order.tolist() == [4, 2, 3, 1]


def test_fit_temperature_recovers_the_generating_c():
    rng = np.random.default_rng(11)
    gf = np.repeat(np.arange(20), 3)
    dist = rng.uniform(0.0, 3.0, size=(1500, len(gf)))
    true_c = 0.7
    probs, _ = fabric_probabilities(dist, gf, c=true_c)
    u = rng.random(len(dist))[:, None]
    qf = (probs.cumsum(axis=1) < u).sum(axis=1)  # each query's fabric drawn from the model
    fitted = fit_temperature(dist, qf, gf)
    assert fitted == pytest.approx(true_c, rel=0.12)


def test_reliability_curve_truth_table():
    curve = reliability_curve([0.15, 0.15, 0.85, 0.85], [0, 0, 1, 0], n_bins=10)
    assert curve.count.tolist() == [0, 2, 0, 0, 0, 0, 0, 0, 2, 0]
    assert curve.accuracy[1] == 0.0 and curve.accuracy[8] == 0.5
    assert curve.ece == pytest.approx((2 * 0.15 + 2 * 0.35) / 4)
    assert expected_calibration_error([1.0, 0.5], [1, 1], n_bins=2) == pytest.approx(0.25)


# ---------------------------------------------------------------- physical properties


def test_property_probe_recovers_a_linear_relation():
    rng = np.random.default_rng(12)
    x = rng.standard_normal((240, 6))
    y = np.stack([x @ np.array([1.0, -2.0, 0.5, 0.0, 0.0, 1.0]), rng.standard_normal(240)], 1)
    y[::7, 0] = np.nan  # unknown labels are skipped
    res = property_probe(x[:160], y[:160], x[160:], y[160:], "ridge", names=["stiff", "noise"])
    assert res["stiff"]["r2"] > 0.99 and res["stiff"]["spearman"] > 0.99
    assert res["stiff"]["n_train"] == 160 - len(range(0, 160, 7))
    assert res["noise"]["r2"] < 0.2  # nothing to find: the probe must not invent a relation
    knn = property_probe(x[:160], y[:160], x[160:], y[160:], "knn", k=5)
    assert 0.3 < knn["0"]["r2"] < res["stiff"]["r2"]


def test_property_probe_per_fabric_and_disjoint_fabrics():
    rng = np.random.default_rng(13)
    fabric = np.repeat(np.arange(40), 3)
    centre = rng.standard_normal((40, 4))
    label = centre[:, 0] * 2.0 + 1.0
    emb = centre[fabric] + 0.05 * rng.standard_normal((120, 4))
    tr, te = fabric < 30, fabric >= 30
    res = property_probe(
        emb[tr],
        label[fabric][tr],
        emb[te],
        label[fabric][te],
        "ridge",
        train_fabric=fabric[tr],
        test_fabric=fabric[te],
    )
    assert res["0"]["n_train"] == 30 and res["0"]["n_test"] == 10  # one row per fabric
    assert res["0"]["r2"] > 0.98 and res["0"]["mae"] < 0.2
    with pytest.raises(ValueError, match="in both train and test"):
        property_probe(
            emb, label[fabric], emb, label[fabric], train_fabric=fabric, test_fabric=fabric
        )


def test_knn_probe_never_averages_every_training_fabric():
    # With k >= the training fabrics the "nearest k" are all of them: every test fabric would
    # get the training mean, and the probe's MAE would equal chance's exactly.
    # At most half, at least one; k = 5 unchanged from 10 fabrics up (the demo's 100).
    sizes = (1, 2, 3, 5, 9, 10, 11, 100)
    assert [knn_neighbours(5, n) for n in sizes] == [1, 1, 1, 2, 4, 5, 5, 5]
    assert knn_neighbours(1, 100) == 1
    fabric = np.repeat(np.arange(10), 2)
    centre = np.arange(10, dtype=float)[:, None] * np.array([[1.0, 0.0]])
    emb = centre[fabric]
    label = np.arange(10, dtype=float)[fabric]
    tr, te = fabric < 5, fabric >= 5
    res = property_probe(
        emb[tr], label[tr], emb[te], label[te], "knn",
        train_fabric=fabric[tr], test_fabric=fabric[te], k=5,
    )["0"]  # fmt: skip
    assert res["k"] == 2 and res["n_train"] == 5
    # The nearest 2 of training fabrics 0-4 to each of 5-9 are 3 and 4: mean 3.5, not 2.
    assert res["mae"] == pytest.approx(np.mean(np.arange(5, 10) - 3.5))
    chance = np.mean(np.arange(5, 10) - 2.0)  # always answering the training mean
    assert res["mae"] < chance
    many = property_probe(emb, label, emb, label, "knn", k=5)["0"]  # 20 rows: k stays 5
    assert many["k"] == 5
    assert "k" not in property_probe(emb, label, emb, label, "ridge")["0"]
    one = property_probe(emb[:1], label[:1], emb, label, "knn")["0"]  # too few to fit
    assert math.isnan(one["k"]) and math.isnan(one["mae"])


def test_property_probe_ignores_columns_constant_in_training():
    # A column (a saturated pixel, a dead unit) that never moves in training but does in test
    # must not swamp the prediction.
    rng = np.random.default_rng(16)
    x = rng.standard_normal((120, 5))
    y = x @ np.array([1.0, 0.5, 0.0, -1.0, 0.0])
    x[:80, 4] = 1e-7 * rng.standard_normal(80)
    x[80:, 4] = 3.0
    res = property_probe(x[:80], y[:80], x[80:], y[80:], "ridge")
    assert res["0"]["r2"] > 0.95


def test_probe_columns_keep_what_property_probe_scores():
    """The same fits as `property_probe`, with each held-out fabric's id, label and
    prediction, and the training fabrics' mean label (what a probe that knows nothing says)."""
    rng = np.random.default_rng(14)
    fabric = np.repeat(np.arange(20), 2)
    centre = rng.standard_normal((20, 3))
    label = np.stack([centre[:, 0] + 2.0, rng.standard_normal(20)], 1)
    label[3, 1] = label[15, 1] = np.nan  # unknown: not held out, not trained on
    emb = centre[fabric] + 0.01 * rng.standard_normal((40, 3))
    tr, te = fabric < 12, fabric >= 12
    args = (emb[tr], label[fabric][tr], emb[te], label[fabric][te])
    for method in ("ridge", "knn"):
        kw = {"names": ["a", "b"], "train_fabric": fabric[tr], "test_fabric": fabric[te]}
        cols = probe_columns(*args, method, **kw)
        scores = property_probe(*args, method, **kw)
        for name in ("a", "b"):
            got, want = cols[name].scores(), scores[name]
            assert got.keys() == want.keys()
            assert all(got[k] == pytest.approx(want[k], nan_ok=True) for k in want), (method, name)
    a, b = cols["a"], cols["b"]
    assert a.rows.tolist() == list(range(12, 20))
    assert b.rows.tolist() == [12, 13, 14, 16, 17, 18, 19]  # fabric 15's label is unknown
    assert a.truth == pytest.approx(label[12:, 0]) and len(b.pred) == 7
    assert a.train_mean == pytest.approx(label[:12, 0].mean())
    assert b.train_mean == pytest.approx(np.delete(label[:12, 1], 3).mean())
    unfitted = probe_columns(emb[:2], label[fabric][:2], emb[te], label[fabric][te], "ridge",
                             train_fabric=fabric[:2], test_fabric=fabric[te])["0"]  # fmt: skip
    assert not unfitted.fitted and unfitted.n_train == 1 and math.isnan(unfitted.scores()["r2"])


def _drawn(x: np.ndarray, counts: np.ndarray) -> np.ndarray:
    """The rows one resample draws, each as often as it is drawn."""
    return np.repeat(x, counts.astype(int))


def test_resampled_r2_and_spearman_are_those_of_the_drawn_rows():
    """Brute-force parity: each resample's R^2 and Spearman from the weights equal those of
    its drawn rows written out (a row drawn twice is two rows, ties among them ranked as
    scipy ranks them); undefined where the draws hold one value."""
    from scipy.stats import spearmanr

    rng = np.random.default_rng(15)
    truth = np.round(rng.standard_normal(9), 1)
    truth[4] = truth[1]  # a tie in the labels
    pred = truth + rng.standard_normal(9)
    pred[7] = pred[2]  # and in the predictions
    w = fabric_weights(9, n_boot=60, seed=3)
    r2, rho = resampled_r2(truth, pred, w), resampled_spearman(truth, pred, w)
    for b in range(len(w)):
        t, p = _drawn(truth, w[b]), _drawn(pred, w[b])
        want_r2 = 1.0 - ((p - t) ** 2).sum() / ((t - t.mean()) ** 2).sum()
        assert r2[b] == pytest.approx(want_r2), b
        assert rho[b] == pytest.approx(spearmanr(t, p).statistic), b
    assert resampled_r2(truth, pred)[0] == pytest.approx(
        1.0 - ((pred - truth) ** 2).sum() / ((truth - truth.mean()) ** 2).sum()
    )
    assert resampled_spearman(truth, pred)[0] == pytest.approx(spearmanr(truth, pred).statistic)
    assert resampled_r2(truth, truth)[0] == 1.0 and resampled_spearman(truth, -truth)[0] == -1.0
    # Every draw of one row: nothing to explain, nothing to rank.
    one = np.zeros((1, 9))
    one[0, 5] = 9.0
    assert np.isnan(resampled_r2(truth, pred, one)).all()
    assert np.isnan(resampled_spearman(truth, pred, one)).all()
    assert np.isnan(resampled_spearman(truth, np.ones(9))).all()  # one prediction
    with pytest.raises(ValueError, match="must be"):
        resampled_r2(truth, pred[:5])


def test_bootstrap_with_no_resample_gives_nan_intervals_of_the_metrics_shape():
    """QA: `cv --n-boot 0` crashed on the 0-d arrays `bootstrap_ci` returned for (Q, M) values
    with no resample drawn (and numpy warned of an empty slice)."""
    import warnings

    values = np.array([[0.5, 1.0], [0.25, 0.0], [1.0, 0.5]])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        low, high = bootstrap_ci(values, [0, 1, 2], n_boot=0)
        one = bootstrap_ci(values[:, 0], [0, 1, 2], n_boot=0)
    assert low.shape == high.shape == (2,)
    assert np.isnan(low).all() and np.isnan(high).all()
    assert np.isnan(one[0]) and np.isnan(one[1]) and np.ndim(one[0]) == 0
