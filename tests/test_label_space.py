"""Matching in label space: the map recovers labels an embedding encodes, fitted per fabric."""

from __future__ import annotations

import numpy as np
import pytest

from lookfeel.metrics import pairwise_distances, pick_k_of_n_exact
from lookfeel.metrics.label_space import fit_label_space, fit_label_spaces, normal_scores


def test_normal_scores_rank_ties_and_nan():
    z = normal_scores([3.0, 1.0, 2.0, np.nan, 2.0])
    assert np.isnan(z[3])
    assert z[1] < z[2] == z[4] < z[0]  # ties share their mean rank
    assert z[2] == pytest.approx(0.0) and z[0] == pytest.approx(-z[1])


def _items(labels: np.ndarray, rng: np.random.Generator, mix: np.ndarray, per: int = 4):
    """Items whose embedding is a fixed linear mix of their fabric's labels, plus noise."""
    fabrics = np.repeat(np.arange(len(labels)), per)
    emb = labels[fabrics] @ mix + 0.05 * rng.standard_normal((len(fabrics), mix.shape[1]))
    return emb, fabrics


def test_two_modalities_meet_in_label_space_that_their_embeddings_do_not_share():
    rng = np.random.default_rng(0)
    train = rng.standard_normal((60, 2)) * [1.0, 5.0]  # columns on very different scales
    test = rng.standard_normal((20, 2)) * [1.0, 5.0]
    labels = {i: list(v) for i, v in enumerate(train)} | {
        100 + i: list(v) for i, v in enumerate(test)
    }
    mixes = [rng.standard_normal((2, 6)) for _ in range(2)]  # each modality its own embedding
    spaces, projected, fabs = [], [], []
    for mix in mixes:
        emb, f = _items(train, rng, mix)
        spaces.append(fit_label_space(emb, f, labels, ["a", "b"]))
        emb_te, f_te = _items(test, rng, mix)
        projected.append(spaces[-1].project(emb_te))
        fabs.append(f_te + 100)
    assert spaces[0].columns == ("a", "b") and spaces[0].coef.shape == (6, 2)
    # The projection is the labels' normal scores among the training fabrics: rank preserved.
    order = np.argsort(test[:, 1])
    per_fabric = projected[0][::4, 1]
    assert np.corrcoef(per_fabric[order], np.sort(per_fabric))[0, 1] > 0.99
    cross = pick_k_of_n_exact(
        pairwise_distances(projected[0], projected[1]), fabs[0], fabs[1], n=10, ks=(1,)
    )
    raw = pick_k_of_n_exact(
        pairwise_distances(_items(test, rng, mixes[0])[0], _items(test, rng, mixes[1])[0]),
        fabs[0],
        fabs[1],
        n=10,
        ks=(1,),
    )
    assert cross.mean[0] > 0.8 and raw.mean[0] < 0.5  # only label space connects them


def test_columns_too_few_fabrics_know_are_left_out():
    rng = np.random.default_rng(1)
    emb = rng.standard_normal((12, 3))
    f = np.repeat(np.arange(6), 2)
    labels = {i: [float(i), 1.0 if i < 2 else np.nan, 5.0] for i in range(6)}
    space = fit_label_space(emb, f, labels, ["known", "rare", "constant"])
    assert space.columns == ("known",) and space.project(emb).shape == (12, 1)
    with pytest.raises(ValueError, match="no label column"):
        fit_label_space(emb, f, {i: [np.nan] for i in range(6)}, ["x"])
    with pytest.raises(ValueError, match="do not match"):
        fit_label_space(emb[:5], f, labels, ["known", "rare", "constant"])


def test_several_modalities_share_the_columns_all_of_them_map():
    rng = np.random.default_rng(2)
    f = np.repeat(np.arange(8), 2)
    labels = {i: [float(i), float(i % 3), np.nan] for i in range(8)}
    only_first = {i: [float(i), np.nan, np.nan] for i in range(8)}
    spaces = fit_label_spaces(
        {"a": (rng.standard_normal((16, 4)), f), "b": (rng.standard_normal((16, 5)), f)},
        labels,
        ["x", "y", "z"],
    )
    assert spaces["a"].columns == spaces["b"].columns == ("x", "y")
    assert spaces["b"].project(rng.standard_normal((3, 5))).shape == (3, 2)
    mixed = fit_label_spaces(
        {"a": (rng.standard_normal((16, 4)), f), "none": (rng.standard_normal((16, 4)), f + 50)},
        only_first,
        ["x", "y", "z"],
    )
    assert set(mixed) == {"a"} and mixed["a"].columns == ("x",)  # no labels for fabrics 50+
