"""Matching through a cross-modal map: two embeddings of the same fabrics in different spaces,
paired by the training fabrics alone (no labels)."""

from __future__ import annotations

import numpy as np
import pytest

from lookfeel.metrics import pairwise_distances, pick_k_of_n_exact
from lookfeel.metrics.cross_map import CrossMap, fit_cross_map, fit_cross_maps, fit_linear_map
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
