"""Matching through a cross-modal map: two embeddings of the same fabrics in different spaces,
paired by the training fabrics alone (no labels)."""

from __future__ import annotations

import numpy as np
import pytest

from lookfeel.metrics import pairwise_distances, pick_k_of_n_exact
from lookfeel.metrics.cross_map import (
    CrossMap,
    LinearMap,
    fit_cross_map,
    fit_cross_maps,
    fit_linear_map,
)
from lookfeel.modality import Modality, Pair


def _items(latent: np.ndarray, mix: np.ndarray, rng: np.random.Generator, per: int = 3):
    """Items whose embedding is a fixed linear mix of their fabric's latent, plus noise."""
    fabrics = np.repeat(np.arange(len(latent)), per)
    emb = latent[fabrics] @ mix + 0.1 * rng.standard_normal((len(fabrics), mix.shape[1]))
    return emb, fabrics


def test_two_spaces_of_one_physics_are_matched_through_the_map_and_not_directly():
    """Touch and depth embed the same 3 hidden properties, each in its own 8-d space: their
    distances match a press to its drape at chance, the map fitted on 40 training fabrics at
    nearly 1 on 20 others."""
    rng = np.random.default_rng(0)
    train, test = rng.standard_normal((40, 3)), rng.standard_normal((20, 3))
    mix_t, mix_d = rng.standard_normal((3, 8)), rng.standard_normal((3, 8))
    et, ft = _items(train, mix_t, rng)
    ed, fd = _items(train, mix_d, rng)
    cross = fit_cross_map(et, ft, ed, fd)
    qt, qf = _items(test, mix_t, rng)
    gd, gf = _items(test, mix_d, rng)
    dist = cross.distances(qt, gd)
    assert dist.shape == (len(qt), len(gd)) and (dist >= 0).all()
    mapped = pick_k_of_n_exact(dist, qf, gf, n=10, ks=(1,)).mean[0]
    direct = pick_k_of_n_exact(pairwise_distances(qt, gd), qf, gf, n=10, ks=(1,)).mean[0]
    assert mapped > 0.9 and direct < 0.35
    # Each route is in units of its mean distance among training fabrics.
    assert cross.forward(et).shape == (len(et), 8) and cross.backward(ed).shape == (len(ed), 8)
    assert cross.scale_forward > 0 and cross.scale_backward > 0


def test_linear_map_recovers_an_exact_linear_relation():
    rng = np.random.default_rng(1)
    x = rng.standard_normal((200, 5))
    w, b = rng.standard_normal((5, 4)), rng.standard_normal(4)
    fitted = fit_linear_map(x, x @ w + b)
    assert fitted.coef.shape == (5, 4) and fitted.intercept.shape == (4,)
    assert np.allclose(fitted(x), x @ w + b, atol=0.05)


def test_fitted_on_fabric_means_of_the_fabrics_both_modalities_have():
    """A fabric only one modality has does not move the map; too few in common is an error."""
    rng = np.random.default_rng(2)
    latent = rng.standard_normal((12, 2))
    mix = rng.standard_normal((2, 4))
    ea, fa = _items(latent, mix, rng)
    eb, fb = _items(latent, mix[:, ::-1], rng)
    base = fit_cross_map(ea, fa, eb, fb)
    extra = np.vstack([ea, np.full((3, 4), 50.0)])  # fabric 99, touch only
    more = fit_cross_map(extra, np.concatenate([fa, [99, 99, 99]]), eb, fb)
    assert np.allclose(base.forward.coef, more.forward.coef)
    with pytest.raises(ValueError, match="3 or more training fabrics"):
        fit_cross_map(ea[fa < 2], fa[fa < 2], eb[fb < 2], fb[fb < 2])
    with pytest.raises(ValueError, match="do not match"):
        fit_cross_map(ea, fa[:-1], eb, fb)


def test_arrays_round_trip_exactly_and_a_damaged_map_is_refused():
    rng = np.random.default_rng(3)
    latent = rng.standard_normal((12, 2))
    ea, fa = _items(latent, rng.standard_normal((2, 4)), rng)
    eb, fb = _items(latent, rng.standard_normal((2, 6)), rng)
    cross = fit_cross_map(ea, fa, eb, fb)
    back = CrossMap.from_arrays(cross.to_arrays())
    np.testing.assert_array_equal(back.distances(ea, eb), cross.distances(ea, eb))
    np.testing.assert_array_equal(cross.against(eb)(ea), cross.distances(ea, eb))
    arrays = cross.to_arrays()
    with pytest.raises(ValueError, match="do not fit together"):
        CrossMap.from_arrays(arrays | {"backward_coef": arrays["backward_coef"][:, :3]})
    with pytest.raises(ValueError, match="do not fit together"):
        CrossMap.from_arrays(arrays | {"scales": np.array([1.0, 0.0])})
    with pytest.raises(KeyError):
        CrossMap.from_arrays({k: v for k, v in arrays.items() if k != "scales"})


def test_hub_correction_lowers_each_gallery_item_by_its_crowding_among_training_fabrics():
    """d'(q, g) = d(q, g) - r(g) + c, r(g) the mean distance of g's 10 nearest training
    fabrics (query modality, fabric means), c the largest r among the training fabrics; 0
    neighbours is the plain two-route distance. An item's distance does not depend on what
    else the gallery holds."""
    rng = np.random.default_rng(5)
    latent = rng.standard_normal((30, 2))
    ea, fa = _items(latent, rng.standard_normal((2, 4)), rng)
    eb, fb = _items(latent, rng.standard_normal((2, 6)), rng)
    plain = fit_cross_map(ea, fa, eb, fb, hub_neighbours=0)
    hubbed = fit_cross_map(ea, fa, eb, fb)
    assert plain.hubs is None and hubbed.hubs is not None and hubbed.hubs.shape == (30, 4)
    np.testing.assert_allclose(hubbed.hubs, np.stack([ea[fa == i].mean(0) for i in range(30)]))
    q, g = rng.standard_normal((7, 4)), rng.standard_normal((9, 6))
    base = plain.distances(q, g)
    r = np.sort(plain.distances(hubbed.hubs, g), axis=0)[:10].mean(axis=0)
    mg = np.stack([eb[fb == i].mean(0) for i in range(30)])
    c = np.sort(plain.distances(hubbed.hubs, mg), axis=0)[:10].mean(axis=0).max()
    assert hubbed.hub_offset == pytest.approx(c)
    np.testing.assert_allclose(hubbed.distances(q, g), np.maximum(base - r + c, 0), atol=1e-12)
    assert (hubbed.distances(q, g) >= 0).all()
    np.testing.assert_allclose(hubbed.distances(q, g[:4]), hubbed.distances(q, g)[:, :4])
    old = CrossMap.from_arrays(plain.to_arrays())  # a map saved without hubs: none applied
    assert old.hubs is None and "hubs" not in plain.to_arrays()
    np.testing.assert_array_equal(old.distances(q, g), base)
    back = CrossMap.from_arrays(hubbed.to_arrays())  # the hubs travel with the map
    np.testing.assert_array_equal(back.distances(q, g), hubbed.distances(q, g))
    assert back.hub_neighbours == 10
    with pytest.raises(ValueError, match="hubs"):
        CrossMap.from_arrays(hubbed.to_arrays() | {"hubs": hubbed.hubs[:, :3]})
    with pytest.raises(ValueError, match=">= 0"):
        fit_cross_map(ea, fa, eb, fb, hub_neighbours=-1)


def test_a_gallery_item_near_every_query_is_no_longer_picked_for_all_of_them():
    """A hub: one gallery drape sits where the map sends every press of the training
    fabrics, a little closer to each query than its own drape is. Without the correction it
    is every query's first pick; with it, each query finds its own."""
    centre = np.zeros(2)
    own = np.array([[3.0, 0.0], [-3.0, 0.0], [0.0, 3.0], [0.0, -3.0]])
    queries = 0.48 * own  # a little nearer the hub (the centre) than their own drape
    gallery = np.vstack([own, centre])
    identity = LinearMap(np.eye(2), np.zeros(2))
    hubs = np.vstack([0.1 * own, 0.1 * own[::-1]])  # training fabrics crowd the centre
    plain = CrossMap(identity, identity, 1.0, 1.0)
    hubbed = CrossMap(identity, identity, 1.0, 1.0, hubs, 4, 10.0)
    assert (plain.distances(queries, gallery).argmin(axis=1) == 4).all()
    assert (hubbed.distances(queries, gallery).argmin(axis=1) == np.arange(4)).all()


def test_maps_of_every_pair_of_two_modalities_with_enough_fabrics():
    rng = np.random.default_rng(4)
    latent = rng.standard_normal((12, 2))
    d, t, c = Modality.DEPTH, Modality.TOUCH, Modality.COLOR
    items = {
        d: _items(latent, rng.standard_normal((2, 4)), rng),
        t: _items(latent, rng.standard_normal((2, 4)), rng),
        c: _items(latent[:2], rng.standard_normal((2, 4)), rng),  # 2 fabrics: too few
    }
    maps = fit_cross_maps(items, Pair.every([d, t, c]))
    assert set(maps) == {Pair(t, d), Pair(d, t)}
