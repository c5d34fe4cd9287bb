"""Evaluation workflow: hand-built embeddings, report files, npz round trip and the CLI."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from lookfeel.checkpoint import load_model
from lookfeel.cli import main
from lookfeel.config import ConfigError, EvalConfig, RunConfig, from_dict, load_config
from lookfeel.data import DatasetError, scan
from lookfeel.embedding import EmbeddedItems
from lookfeel.evaluate import (
    EmbeddingFileError,
    EmbeddingSet,
    embed_checkpoint,
    embedded_from_arrays,
    evaluate_checkpoint,
    evaluate_embedding_file,
    evaluate_embeddings,
    load_embeddings,
    pools_final_embedding,
    save_embeddings,
    write_report,
)
from lookfeel.evaluate.core import press_queries
from lookfeel.metrics import PAPER_C, ScoringProtocol, score_pairs
from lookfeel.modality import Modality, Pair, PressKind
from lookfeel.train import train

from ._library import evaluate_cli
from ._tiny import write_recordings, write_tiny_dataset

TINY = Path(__file__).resolve().parents[1] / "configs" / "tiny.yaml"
D, C, T = Modality.DEPTH, Modality.COLOR, Modality.TOUCH
FAST = EvalConfig(n_boot=100, max_presses=3)


def _world(
    n_fabrics: int = 12,
    per: dict[Modality, int] | None = None,
    noise: float | dict[Modality, float] = 0.0,
    dim: int = 8,
    seed: int = 0,
    first_id: int = 1,
) -> tuple[dict[Modality, EmbeddedItems], np.ndarray]:
    """Items of each modality = their fabric's centre + Gaussian noise; returns the centres."""
    rng = np.random.default_rng(seed)
    centres = rng.standard_normal((n_fabrics, dim))
    centres -= centres.mean(axis=1, keepdims=True)  # orthogonal to (1, ..., 1): see the max test
    per = per or {D: 4, C: 4, T: 6}
    emb, fab = {}, {}
    for m, k in per.items():
        sigma = noise[m] if isinstance(noise, dict) else noise
        f = np.repeat(np.arange(n_fabrics), k)
        emb[m] = centres[f] + sigma * rng.standard_normal((len(f), dim))
        fab[m] = f + first_id
    return embedded_from_arrays(emb, fab), centres


def test_a_perfect_embedding_picks_right_every_time():
    embedded, _ = _world(noise=0.0)
    r = evaluate_embeddings(embedded, FAST)
    assert len(r.pairs) == 9
    for pair in r.pairs:
        m = r.metrics
        assert m[f"{pair}_top1"] == pytest.approx(1.0)
        assert m[f"{pair}_top1_sampled"] == pytest.approx(1.0)
        assert m[f"{pair}_map"] == pytest.approx(1.0)
        assert m[f"{pair}_median_rank"] == 1.0
        assert m[f"{pair}_top1_chance"] == pytest.approx(0.1)
        assert m[f"{pair}_top3_chance"] == pytest.approx(0.3)
        assert m[f"{pair}_n_fabrics"] == 12


def test_a_random_embedding_scores_chance():
    rng = np.random.default_rng(1)
    n_f, per = 24, 10
    emb = {m: rng.standard_normal((n_f * per, 16)) for m in (D, T)}
    fab = {m: np.repeat(np.arange(n_f), per) for m in (D, T)}
    r = evaluate_embeddings(embedded_from_arrays(emb, fab), FAST)
    m = r.metrics
    for pair in ("touch_to_depth", "depth_to_touch", "depth_to_depth", "touch_to_touch"):
        # Same-modality pairs too: a query never finds itself, so chance is all it can do.
        assert m[f"{pair}_top1"] == pytest.approx(0.1, abs=0.03)
        assert m[f"{pair}_top3"] == pytest.approx(0.3, abs=0.05)
        assert m[f"{pair}_top1_sampled"] == pytest.approx(0.1, abs=0.04)
        assert m[f"{pair}_map"] == pytest.approx(m[f"{pair}_map_chance"], abs=0.03)
        assert m[f"{pair}_recall5"] == pytest.approx(m[f"{pair}_recall5_chance"], abs=0.08)
        assert m[f"{pair}_top1_ci_low"] <= 0.1 <= m[f"{pair}_top1_ci_high"]
        assert m[f"{pair}_fabric_accuracy"] == pytest.approx(1 / n_f, abs=0.04)


def test_pooling_presses_helps_noisy_touch_and_sets_the_main_keys():
    embedded, _ = _world(per={D: 3, T: 15}, noise={D: 0.05, T: 1.2}, n_fabrics=16, seed=3)
    r = evaluate_embeddings(embedded, dataclasses.replace(FAST, max_presses=5))
    m = r.metrics
    one, three, five = (m[f"touch_to_depth_presses{p}_top1"] for p in (1, 3, 5))
    assert one < 0.8 and three > one + 0.1 and five >= three - 0.02
    assert m["touch_to_depth_presses1_top1"] == m["touch_to_depth_top1"]  # main keys: P = 1
    assert m["touch_to_depth_presses3_n_queries"] == 16 * 5  # 15 presses per fabric, groups of 3
    curve = {c.gallery: c for c in r.press_curves()}[D]
    assert curve.presses.tolist() == [1, 2, 3, 4, 5]
    assert np.all(curve.low <= curve.value) and np.all(curve.value <= curve.high)

    r3 = evaluate_embeddings(embedded, dataclasses.replace(FAST, presses=3))
    assert r3.config.presses == 3
    assert r3.metrics["touch_to_depth_top1"] == pytest.approx(three)
    assert r3.metrics["touch_to_depth_n_queries"] == 16 * 5
    # A pooled touch query never counts its own presses as candidates.
    assert r3.metrics["touch_to_touch_n_queries"] == 16 * 5
    # Depth picks among the same pooled presses (the Multi-input Net's touch candidates), not
    # among single presses: exactly the pick over the groups' pooled embeddings.
    groups = press_queries(embedded[T], 3, r3.config.seed)
    assert len(groups.fabric) == 16 * 5
    emb = {k: e.embeddings for k, e in embedded.items()}
    fab = {k: e.fabric_ids for k, e in embedded.items()}
    exact = ScoringProtocol(ks=(1,), gallery=False, sampled=False, n_boot=0)
    pair = Pair(D, T)
    pooled = score_pairs(emb, fab, exact, [pair], galleries={T: groups})[pair].metrics["top1"]
    single = score_pairs(emb, fab, exact, [pair])[pair].metrics["top1"]
    assert r3.metrics["depth_to_touch_n_queries"] == 16 * 3
    assert r3.metrics["depth_to_touch_top1"] == pytest.approx(pooled, abs=1e-12)
    assert m["depth_to_touch_top1"] == pytest.approx(single, abs=1e-12) and pooled != single


def test_every_key_is_there_with_chance_and_interval():
    embedded, centres = _world(noise=0.5)
    reference, _ = _world(noise=0.5, seed=1, first_id=101)
    labels = {f + 1: [c[0], c[1]] for f, c in enumerate(centres)}
    labels |= {100 + f + 1: [c[0], c[1]] for f, c in enumerate(_world(seed=1)[1])}
    cfg = dataclasses.replace(FAST, released_variant=True)
    r = evaluate_embeddings(
        embedded,
        cfg,
        {i: i % 3 for i in range(1, 13)},
        labels,
        label_names=["a", "b"],
        reference=reference,
    )
    m = r.metrics
    for pair in r.pairs:
        for k in (1, 3):
            for suffix in ("", "_chance", "_ci_low", "_ci_high", "_sampled", "_sampled_se"):
                assert f"{pair}_top{k}{suffix}" in m
            assert f"{pair}_top{k}_released" in m
        for name in ("map", "recall1", "recall5", "recall10", "median_rank"):
            for suffix in ("", "_chance", "_ci_low", "_ci_high"):
                assert f"{pair}_{name}{suffix}" in m
        for name in ("c", "c_fitted", "fabric_accuracy", "fabric_accuracy_chance", "ece", "nll"):
            assert f"{pair}_{name}" in m
        assert m[f"{pair}_c_fitted"] == 1.0  # fitted on the reference fabrics
    for p in (1, 2, 3):
        for g in ("depth", "color", "touch"):
            for suffix in ("", "_chance", "_ci_low", "_ci_high"):
                assert f"touch_to_{g}_presses{p}_top1{suffix}" in m
    for mod in ("depth", "color", "touch"):
        for probe in ("knn", "ridge"):
            for stat in ("r2", "spearman", "mae", "mae_chance"):
                assert f"property_{mod}_a_{probe}_{stat}" in m
    assert all(isinstance(v, float) for v in m.values())


def test_fitted_c_is_better_calibrated_than_the_papers():
    embedded, _ = _world(noise=0.3, seed=4)
    reference, _ = _world(noise=0.3, seed=5, first_id=101)
    fitted = evaluate_embeddings(embedded, FAST, reference=reference)
    paper = evaluate_embeddings(embedded, FAST)
    fixed = evaluate_embeddings(embedded, dataclasses.replace(FAST, c=0.5), reference=reference)
    pair = "touch_to_depth"
    assert paper.calibration[pair].c == PAPER_C and paper.calibration[pair].c_source == "paper"
    assert fixed.metrics[f"{pair}_c"] == 0.5 and fixed.calibration[pair].c_source == "fixed"
    assert fitted.calibration[pair].c_source == "fitted"
    assert fitted.metrics[f"{pair}_nll"] < paper.metrics[f"{pair}_nll"] - 0.1
    assert fitted.metrics[f"{pair}_ece"] < paper.metrics[f"{pair}_ece"]


def test_confusion_is_ordered_by_cluster_and_examples_are_consistent():
    embedded, _ = _world(noise=0.6, seed=2)
    clusters = {i: (i * 7) % 4 for i in range(1, 13)}
    r = evaluate_embeddings(embedded, FAST, clusters)
    assert r.figure_pairs == ("touch_to_depth",)
    con = r.calibration["touch_to_depth"].confusion
    assert con is not None
    assert [clusters[int(f)] for f in con.rows] == sorted(clusters[int(f)] for f in con.rows)
    np.testing.assert_allclose(con.matrix.sum(axis=1), 1.0)
    cc = r.calibration["touch_to_depth"].cluster_confusion
    assert cc is not None and cc.matrix.shape == (4, 4)
    assert r.calibration["depth_to_color"].confusion is None  # not a figure pair
    examples = r.examples["touch_to_depth"]
    assert len(examples) == 4
    right = [ex.true_position == 0 for ex in examples]
    assert any(right) and not all(right)  # both a success and a failure are shown
    t_fab, d_fab = embedded[T].fabric_ids, embedded[D].fabric_ids
    for ex in examples:
        assert len(ex.candidates) == 10 and list(ex.distances) == sorted(ex.distances)
        fabrics = d_fab[list(ex.candidates)]
        assert len(set(fabrics.tolist())) == 10  # one candidate per fabric
        assert fabrics[ex.true_position] == t_fab[ex.query_rows[0]]


def test_property_probes_predict_labels_the_embedding_encodes():
    embedded, centres = _world(noise=0.05, n_fabrics=16, seed=6)
    reference, ref_centres = _world(noise=0.05, n_fabrics=24, seed=7, first_id=101)
    w = np.arange(1, 9, dtype=float)
    labels = {f + 1: [float(c @ w), np.nan] for f, c in enumerate(centres)}
    labels |= {101 + f: [float(c @ w), 1.0] for f, c in enumerate(ref_centres)}
    r = evaluate_embeddings(
        embedded, FAST, labels=labels, label_names=["x", "unknown"], reference=reference
    )
    m = r.metrics
    assert m["property_depth_x_ridge_r2"] > 0.9
    assert m["property_depth_x_ridge_mae"] < 0.3 * m["property_depth_x_ridge_mae_chance"]
    assert m["property_touch_x_knn_spearman"] > 0.5
    assert np.isnan(m["property_depth_unknown_ridge_r2"])  # no test fabric has the label
    assert r.properties[D]["ridge"]["x"]["n_test"] == 16


def test_glance_ranks_the_true_look_and_reads_the_feel_from_the_nearest_training_fabrics():
    embedded, _ = _world(noise=0.0, n_fabrics=12, seed=3)
    reference, _ = _world(noise=0.0, n_fabrics=12, seed=3, first_id=101)
    # Training fabric 100 + f has fabric f's centre: every query's nearest training fabric.
    labels = {f + 1: [float(f), np.nan] for f in range(12)}
    labels |= {101 + f: [10.0 * f, 1.0] for f in range(12)}
    cfg = dataclasses.replace(FAST, probe_k=1, presses=2)
    r = evaluate_embeddings(
        embedded, cfg, labels=labels, label_names=["x", "y"], reference=reference
    )
    assert len(r.glance) == 3
    assert len({g.fabric for g in r.glance}) == 3  # distinct query fabrics
    t_fab = embedded[T].fabric_ids
    for g in r.glance:
        assert len(g.query_rows) == 2 and set(t_fab[list(g.query_rows)]) == {g.fabric}
        assert [look.modality for look in g.galleries] == [D, C]
        for look in g.galleries:
            assert look.true_rank == 1 and look.fabrics[0] == g.fabric
            assert look.n_fabrics == 12 and len(look.rows) == len(set(look.fabrics)) == 5
            rows_fab = embedded[look.modality].fabric_ids[list(look.rows)]
            assert rows_fab.tolist() == list(look.fabrics)
        assert g.label_names == ("x", "y") and g.neighbours == (g.fabric + 100,)
        assert g.predicted == (10.0 * (g.fabric - 1), 1.0)
        assert g.truth[0] == g.fabric - 1 and np.isnan(g.truth[1])
    # The query's own fabric is never its own neighbour, even when training shares it.
    same = evaluate_embeddings(embedded, cfg, labels=labels, reference=embedded)
    assert all(g.fabric not in g.neighbours for g in same.glance)
    # Noise moves the true look down the ranking; the rank counts from 1.
    noisy, _ = _world(noise={D: 3.0, C: 0.0, T: 0.0}, seed=4)
    ranks = [g.galleries[0].true_rank for g in evaluate_embeddings(noisy, FAST).glance]
    assert all(1 <= k <= 12 for k in ranks) and max(ranks) > 1
    assert not evaluate_embeddings(noisy, FAST).glance[0].label_names  # no labels: no feel
    assert not evaluate_embeddings(embedded, dataclasses.replace(FAST, examples=0)).glance
    only_touch, _ = _world(per={T: 4})
    assert not evaluate_embeddings(only_touch, FAST).glance


def test_few_training_fabrics_neither_average_them_all_nor_hide_an_overconfident_c(
    tmp_path: Path,
):
    """QA (a rig of 10 fabrics, 5 trained on): the glance's feel and the k-NN probe averaged
    the nearest 5 of 5 training fabrics, so every query got their mean and the probe scored
    chance's MAE exactly; and c fitted on the 5 training fabrics (told apart far better than
    new ones) gave an NLL of 118 against chance's 1.6 with nothing flagging it. Now a k-NN
    averages at most half its training fabrics, said in the notes and the report, and a row
    whose NLL is above chance's, or whose c was fitted on fewer than 10 fabrics, is flagged."""
    from lookfeel.evaluate.report import _feel_title

    embedded, centres = _world(n_fabrics=5, noise=1.0, seed=8)
    reference, ref_centres = _world(n_fabrics=5, noise=0.02, seed=9, first_id=101)
    labels = {f + 1: [float(c[0])] for f, c in enumerate(centres)}
    labels |= {101 + f: [float(c[0])] for f, c in enumerate(ref_centres)}
    r = evaluate_embeddings(embedded, FAST, labels=labels, label_names=["x"], reference=reference)
    m = r.metrics
    # The feel: the nearest 2 of 5, so the queries do not all get one answer.
    assert r.glance and all(len(g.neighbours) == 2 and g.n_reference == 5 for g in r.glance)
    assert len({g.predicted for g in r.glance}) > 1
    assert "the glance's feel: the mean of the nearest 2 of the 5 training fabrics" in r.notes[-1]
    assert "the nearest 5 of 5 would be all of them" in r.notes[-1]
    # The probe: k = 2, in the metrics and the report; not chance's MAE to the last digit.
    for mod in ("depth", "color", "touch"):
        assert m[f"property_{mod}_x_knn_k"] == 2.0
        assert m[f"property_{mod}_x_knn_mae"] != m[f"property_{mod}_x_knn_mae_chance"]
    assert any(
        n.startswith("k-NN property probe: the mean of the nearest 2 of the 5") for n in r.notes
    )
    # Calibration: c fitted on 5 nearly noiseless training fabrics is far too sharp for noisy
    # test ones.
    pair = "touch_to_depth"
    cal = r.calibration[pair]
    assert cal.c_source == "fitted" and cal.fit_fabrics == 5
    assert cal.nll > 5 * cal.nll_chance and cal.overconfident
    assert m[f"{pair}_overconfident"] == 1.0 and m[f"{pair}_c_fit_fabrics"] == 5.0
    text = write_report(r, tmp_path / "few").report.read_text(encoding="utf-8")
    row = next(line for line in text.splitlines() if line.startswith("| touch → depth | 2"))
    assert "| fitted on 5 training fabrics |" in row
    assert f"{cal.nll:.3f} (overconfident: NLL clearly above chance's) | 1.609 |" in row
    assert "\nOverconfident: depth → depth, " in text
    assert "c fitted on 5 training fabrics only: those are the fabrics the model was" in text
    assert "| touch | x | knn (k=2) |" in text
    assert "k-NN (mean of the nearest 5, but at most half the reference fabrics" in text
    assert (
        _feel_title(r.glance[0]) == "Feels like (mean of the 2\ntraining fabrics nearest in touch)"
    )
    one = dataclasses.replace(r.glance[0], neighbours=(101,), n_reference=1)
    assert _feel_title(one) == "Feels like (the only training\nfabric with labels)"
    assert "the training fabric\nnearest" in _feel_title(dataclasses.replace(one, n_reference=3))

    # Flagged beyond its noise only: the 5 fabrics' own NLLs spread, so an NLL above chance's
    # by less than twice their standard error is not (QA: 8 of 9 rows of a 5-fabric rig were
    # flagged, most by under 0.11 nats).
    assert m[f"{pair}_nll_se"] == cal.nll_se > 0
    assert cal.nll_chance + 2 * cal.nll_se > 2 * cal.nll_chance  # spread wide by a few ...
    assert cal.nll > 2 * cal.nll_chance  # ... yet far above chance: flagged (above)
    near = dataclasses.replace(cal, nll_se=0.1, nll=cal.nll_chance + 0.19)
    assert not near.overconfident
    assert dataclasses.replace(near, nll=cal.nll_chance + 0.21).overconfident
    assert dataclasses.replace(near, nll_se=math.nan).overconfident  # unknown: any amount
    # As many training fabrics as the demo's 100 (here 12): k stays 5 and nothing is flagged;
    # the report reads as before.
    embedded, centres = _world(noise=0.3, seed=4)
    reference, ref_centres = _world(noise=0.3, seed=5, first_id=101)
    labels = {f + 1: [float(c[0])] for f, c in enumerate(centres)}
    labels |= {101 + f: [float(c[0])] for f, c in enumerate(ref_centres)}
    r = evaluate_embeddings(embedded, FAST, labels=labels, label_names=["x"], reference=reference)
    assert all(len(g.neighbours) == 5 and g.n_reference == 12 for g in r.glance)
    assert r.metrics["property_touch_x_knn_k"] == 5.0
    assert r.calibration[pair].fit_fabrics == 12 and not r.calibration[pair].overconfident
    assert r.metrics[f"{pair}_overconfident"] == 0.0
    assert not any("nearest" in n for n in r.notes)
    text = write_report(r, tmp_path / "many").report.read_text(encoding="utf-8")
    assert "k-NN (mean of the nearest 5) and ridge regression." in text
    assert "(k=" not in text and "Overconfident" not in text and "training fabrics only" not in text
    assert f"| {r.calibration[pair].c:.4g} | fitted | " in text
    assert "paper" in str(evaluate_embeddings(embedded, FAST).calibration[pair].c_source)
    assert np.isnan(evaluate_embeddings(embedded, FAST).metrics[f"{pair}_c_fit_fabrics"])


def _mixed(labels: np.ndarray, first_id: int, seed: int) -> dict[Modality, EmbeddedItems]:
    """Depth and touch items whose embeddings are two different linear mixes of their fabric's
    labels: the embeddings do not meet, the labels do."""
    rng = np.random.default_rng(seed)
    mixes = {D: np.random.default_rng(10).standard_normal((3, 8)), T: np.eye(3, 8)[::-1]}
    emb, fab = {}, {}
    for m, per in ((D, 4), (T, 6)):
        f = np.repeat(np.arange(len(labels)), per)
        emb[m] = labels[f] @ mixes[m] + 0.05 * rng.standard_normal((len(f), 8))
        fab[m] = f + first_id
    return embedded_from_arrays(emb, fab)


def test_label_space_connects_modalities_whose_embeddings_do_not_meet():
    rng = np.random.default_rng(5)
    test_labels, train_labels = rng.standard_normal((12, 3)), rng.standard_normal((40, 3))
    labels = {1 + i: list(v) for i, v in enumerate(test_labels)}
    labels |= {101 + i: list(v) for i, v in enumerate(train_labels)}
    embedded, reference = _mixed(test_labels, 1, 0), _mixed(train_labels, 101, 1)
    cfg = dataclasses.replace(FAST, presses=2)
    plain = evaluate_embeddings(embedded, cfg, labels=labels, reference=reference)
    mapped = evaluate_embeddings(
        embedded, dataclasses.replace(cfg, space="labels"), labels=labels, reference=reference
    )
    assert plain.metrics["touch_to_depth_top1"] < 0.5
    assert mapped.metrics["touch_to_depth_top1"] > 0.9  # pooled touch queries mapped too
    assert mapped.metrics["depth_to_touch_top1"] > 0.9
    assert mapped.embedded[D].embeddings.shape == (48, 3)
    assert any("label space" in n for n in mapped.notes)
    with pytest.raises(ConfigError, match="eval.space: labels needs the fabrics' labels"):
        evaluate_embeddings(embedded, dataclasses.replace(cfg, space="labels"))
    with pytest.raises(ConfigError, match="reference .* of touch"):
        evaluate_embeddings(
            embedded,
            dataclasses.replace(cfg, space="labels"),
            labels=labels,
            reference={D: reference[D]},
        )
    with pytest.raises(ConfigError, match="eval.space"):
        EvalConfig(space="pixels")  # type: ignore[arg-type]


def test_a_cross_modal_map_connects_them_without_labels(tmp_path: Path):
    rng = np.random.default_rng(5)
    test_labels, train_labels = rng.standard_normal((12, 3)), rng.standard_normal((40, 3))
    embedded, reference = _mixed(test_labels, 1, 0), _mixed(train_labels, 101, 1)
    cfg = dataclasses.replace(FAST, presses=2)
    r = evaluate_embeddings(embedded, cfg, reference=reference)  # no labels given
    m = r.metrics
    assert m["touch_to_depth_top1"] < 0.5  # the embeddings do not meet ...
    assert m["touch_to_depth_top1_mapped"] > 0.9  # ... the map, fitted on other fabrics, does
    assert m["depth_to_touch_top1_mapped"] > 0.9
    lo, hi = m["touch_to_depth_top1_mapped_ci_low"], m["touch_to_depth_top1_mapped_ci_high"]
    assert lo <= m["touch_to_depth_top1_mapped"] <= hi
    assert set(r.cross_maps) == {p for p in r.pairs if not p.same}
    # The glance shows the drapes the map finds: the query's own first.
    shown = [g for ex in r.glance for g in ex.galleries]
    assert shown and all(g.mapped and g.true_rank == 1 for g in shown)
    assert not any(k.startswith(("depth_to_depth", "touch_to_touch")) and "mapped" in k for k in m)
    text = write_report(r, tmp_path / "eval").report.read_text(encoding="utf-8")
    assert "Through a cross-modal map" in text
    assert f"{m['touch_to_depth_top1_mapped']:.3f}" in text
    off = evaluate_embeddings(
        embedded, dataclasses.replace(cfg, cross_map=False), reference=reference
    )
    assert not any("mapped" in k for k in off.metrics) and not off.cross_maps
    assert not any(g.mapped for ex in off.glance for g in ex.galleries)
    assert not any("mapped" in k for k in evaluate_embeddings(embedded, cfg).metrics)


def test_without_reference_or_labels_the_probes_are_skipped_with_a_note():
    embedded, _ = _world()
    r = evaluate_embeddings(embedded, FAST, labels={1: [1.0]})
    assert not r.properties and not any(k.startswith("property_") for k in r.metrics)
    assert any("probes skipped" in n for n in r.notes)
    with pytest.raises(ValueError, match="no embeddings"):
        evaluate_embeddings({})


def test_one_modality_is_scored_against_itself():
    embedded, _ = _world(per={D: 5}, noise=0.3)
    r = evaluate_embeddings(embedded, FAST)
    assert r.pairs == ("depth_to_depth",) and r.figure_pairs == ("depth_to_depth",)
    assert not r.press_curves() and not any("presses" in k for k in r.metrics)


def test_eval_config_is_strict():
    assert from_dict(EvalConfig, {"n_boot": 50, "ks": [1, 5]}).ks == (1, 5)
    with pytest.raises(ConfigError, match="eval.n"):
        EvalConfig(n=1)
    with pytest.raises(ConfigError, match="eval.probes"):
        EvalConfig(probes=("svm",))
    with pytest.raises(ConfigError, match="unknown key"):
        from_dict(EvalConfig, {"nboot": 3})
    with pytest.raises(ConfigError, match="figure_pairs"):
        EvalConfig(figure_pairs=("touch-depth",))


def test_report_files(tmp_path: Path):
    embedded, _ = _world(noise=0.6, seed=2)
    r = evaluate_embeddings(embedded, FAST, {i: i % 3 for i in range(1, 13)})
    files = write_report(r, tmp_path / "eval")
    data = json.loads(
        files.metrics.read_text(encoding="utf-8"), parse_constant=lambda c: pytest.fail(c)
    )
    assert data["touch_to_depth_top1"] == pytest.approx(r.metrics["touch_to_depth_top1"])
    assert data.pop("info") == {}  # bare embeddings: nothing known of what made them
    assert data.keys() == r.metrics.keys()  # the rest: every metric, and only them
    text = files.report.read_text(encoding="utf-8")
    for needle in ("touch → depth", "chance", "95% interval", "Calibration", "presses"):
        assert needle in text
    assert f"{r.metrics['touch_to_depth_top1']:.3f}" in text
    names = {p.name for p in files.figures}
    assert names == {
        "presses.png",
        "reliability_touch_to_depth.png",
        "confusion_touch_to_depth.png",
        "confusion_clusters_touch_to_depth.png",
    }  # no example figure: these hand-made items have no image files
    assert any("pick examples of touch_to_depth not drawn" in line for line in text.splitlines())
    assert any("glance figure not drawn" in line for line in text.splitlines())
    for p in files.figures:
        assert f"(figures/{p.name})" in text
    with Image.open(tmp_path / "eval" / "figures" / "presses.png") as im:
        assert im.size == (650, 450)


def test_a_report_written_again_removes_only_the_figures_the_last_one_wrote(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
):
    """QA: `lookfeel evaluate --out DIR` run twice kept the first run's figures that the second
    did not draw, so figures/ and report.md disagreed. Now the figures the last report listed
    that this one does not write are removed; a file the user put there stays, and so does
    one outside the folder that a tampered list names. A report killed midway has listed every
    figure it began, so the next one removes them too."""
    import lookfeel.evaluate.report as report_module
    from lookfeel.evaluate.report import FIGURES_MANIFEST

    clusters = {i: i % 3 for i in range(1, 13)}
    out = tmp_path / "eval"
    figures = out / "figures"
    touch, _ = _world(noise=0.6, seed=2)
    first = write_report(evaluate_embeddings(touch, FAST, clusters), out)
    assert "presses.png" in {p.name for p in first.figures}
    mine = figures / "mine.png"
    mine.write_bytes(b"the user's own")
    (out / "outside.png").write_bytes(b"not a figure")
    listed = json.loads((figures / FIGURES_MANIFEST).read_text(encoding="utf-8"))
    assert listed["figures"] == sorted(p.name for p in first.figures)
    listed["figures"] += ["../outside.png", "/etc/passwd"]
    (figures / FIGURES_MANIFEST).write_text(json.dumps(listed), encoding="utf-8")

    looks, _ = _world(per={D: 4, C: 4}, noise=0.6, seed=2)  # no touch: no presses.png
    config = dataclasses.replace(FAST, figure_pairs=(Pair(C, D),))
    second = write_report(evaluate_embeddings(looks, config, clusters), out)
    drawn = {p.name for p in second.figures}
    assert drawn and drawn.isdisjoint(p.name for p in first.figures)
    assert {p.name for p in figures.iterdir()} == drawn | {"mine.png", FIGURES_MANIFEST}
    assert mine.read_bytes() == b"the user's own"
    assert (out / "outside.png").read_bytes() == b"not a figure"
    report = (out / "report.md").read_text(encoding="utf-8")
    assert all(f"(figures/{name})" in report for name in drawn)
    assert json.loads((figures / FIGURES_MANIFEST).read_text(encoding="utf-8"))[
        "figures"
    ] == sorted(drawn)

    # Killed while writing its second figure: both names are listed already.
    real, calls = report_module.save_figure, []

    def dies_second(fig: object, path: Path) -> Path:
        calls.append(Path(path).name)
        if len(calls) == 2:
            raise KeyboardInterrupt
        return real(fig, path)  # type: ignore[arg-type]

    monkeypatch.setattr(report_module, "save_figure", dies_second)
    with pytest.raises(KeyboardInterrupt):
        write_report(evaluate_embeddings(touch, FAST, clusters), out)
    monkeypatch.setattr(report_module, "save_figure", real)
    listed_now = set(
        json.loads((figures / FIGURES_MANIFEST).read_text(encoding="utf-8"))["figures"]
    )
    assert set(calls) <= listed_now
    # QA: the last report's numbers stayed beside the new figures; now none is left.
    assert not (out / "metrics.json").exists() and not (out / "report.md").exists()
    write_report(evaluate_embeddings(looks, config, clusters), out)
    assert {p.name for p in figures.iterdir()} == drawn | {"mine.png", FIGURES_MANIFEST}


def test_embeddings_file_round_trip(tmp_path: Path):
    embedded, _ = _world(noise=0.2)
    reference, _ = _world(noise=0.2, seed=1, first_id=101)
    path = save_embeddings(tmp_path / "e.npz", EmbeddingSet(embedded, reference, {"presses": 2}))
    with np.load(path) as z:
        assert z["embeddings_touch"].shape == (72, 8) and z["embeddings_touch"].dtype == np.float32
        assert z["fabric_id_depth"].dtype == np.int64 and z["path_color"].shape == (48,)
    back = load_embeddings(path)
    assert back.meta["presses"] == 2 and back.reference is not None
    for m in (D, C, T):
        np.testing.assert_array_equal(back.embedded[m].embeddings, embedded[m].embeddings)
        np.testing.assert_array_equal(back.reference[m].fabric_ids, reference[m].fabric_ids)
        assert back.embedded[m].paths == embedded[m].paths
    (tmp_path / "bad.npz").write_bytes(b"not a zip")
    # NumPy reads such a file as a pickle and advises loading it unsafely: never said here.
    with pytest.raises(EmbeddingFileError, match=r"bad\.npz: not a readable npz file \(not an "):
        load_embeddings(tmp_path / "bad.npz")
    with pytest.raises(EmbeddingFileError, match="not found"):
        load_embeddings(tmp_path / "none.npz")


# ------------------------------------------------------------------------------------------
# With a trained checkpoint and a dataset.


@pytest.fixture(scope="module")
def run(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, Path]:
    """A tiny dataset, and two 3-step runs: without a projection (max-pooling presses equals
    the model's pooling) and with one (tiny.yaml's embed_dim 16)."""
    root = tmp_path_factory.mktemp("eval")
    data = write_tiny_dataset(root / "data", fabrics=8, drapes=3, fold_presses=4, flat_presses=0)
    base = ["train.steps=3", "train.val_every=0", "train.val_fabrics=3"]
    cfg = load_config(RunConfig, TINY, [*base, "model.embed_dim=null"])
    plain = train(cfg, data, root / "plain").last_checkpoint
    projected = train(load_config(RunConfig, TINY, base), data, root / "proj").last_checkpoint
    return data, plain, projected


def test_embed_then_evaluate_equals_evaluate_checkpoint(run: tuple[Path, Path, Path], tmp_path):
    data, ckpt, _ = run
    val = load_model(ckpt).split["val"]
    npz = tmp_path / "e.npz"
    assert (
        main(
            [
                "embed",
                "--checkpoint",
                str(ckpt),
                "--data",
                str(data),
                "--out",
                str(npz),
                "--split",
                "val",
            ]
        )
        == 0
    )
    with np.load(npz) as z:
        assert set(np.unique(z["fabric_id_touch"]).tolist()) == set(val)
        assert z["embeddings_touch"].shape[0] == 4 * len(val)  # one row per press
        meta = json.loads(str(z["meta"]))  # what made it (session 54)
        from lookfeel.data import scan
        from lookfeel.provenance import software_versions

        assert meta["data_fingerprint"] == scan(data).fingerprint()
        assert meta["software"] == software_versions()
        assert z["embeddings_depth"].shape == (3 * len(val), z["embeddings_depth"].shape[1])
        assert z["path_depth"][0].endswith(".png")
        assert z["reference_embeddings_depth"].shape[0] == 3 * (8 - len(val))
    sets = ["--set", "n_boot=50", "--set", "max_presses=3"]
    a, b = tmp_path / "a", tmp_path / "b"
    # The background control (on by default for depth) needs the images, not only embeddings.
    assert evaluate_cli(ckpt, data, a, "--split", "val", "--no-background-control", *sets) == 0
    assert (
        main(["evaluate", "--embeddings", str(npz), "--data", str(data), "--out", str(b), *sets])
        == 0
    )
    ma = json.loads((a / "metrics.json").read_text(encoding="utf-8"))
    mb = json.loads((b / "metrics.json").read_text(encoding="utf-8"))
    # What was scored, in "info": the checkpoint, split, dataset and software (provenance.py),
    # from the checkpoint, and from the embeddings file's record of it.
    info_a, info_b = ma.pop("info"), mb.pop("info")
    made = {
        "checkpoint": str(ckpt),
        "step": load_model(ckpt).step,
        "split": "val",
        "data_root": str(data),
        "data_fingerprint": meta["data_fingerprint"],
        "software": software_versions(),
    }
    assert info_a == made and info_b == made | {"embeddings_file": str(npz)}
    assert ma == mb  # the same float32 embeddings give the same numbers, NaN (null) included
    assert all(v is None or isinstance(v, float | int) for v in ma.values())  # numbers only
    assert ma["touch_to_depth_c_fitted"] == 1.0  # c fitted on the run's training fabrics
    assert "property_depth_thickness_mm_ridge_r2" in ma
    assert ma["touch_to_depth_n_queries"] == 2 * len(val)  # the run's 2 presses per query
    sizes = {
        "presses.png": (650, 450),
        "reliability_touch_to_depth.png": (600, 650),
        "confusion_touch_to_depth.png": (750, 650),
        "confusion_clusters_touch_to_depth.png": (750, 650),
        "examples_touch_to_depth.png": (550, 740),  # 3 fabrics: 3 candidates, 4 rows
        "glance.png": (806, 1110),  # 3 queries, 3 fabrics shown, depth and colour, the feel
    }
    for name, size in sizes.items():
        with Image.open(a / "figures" / name) as im:
            assert im.size == size, name
    report = (a / "report.md").read_text(encoding="utf-8")
    assert "![pick examples](figures/examples_touch_to_depth.png)" in report
    assert "![at a glance](figures/glance.png)" in report
    assert "the run's held-out fabrics (3)" in report


def test_checkpoint_splits(run: tuple[Path, Path, Path]):
    data, ckpt, _ = run
    loaded = load_model(ckpt)
    cfg = dataclasses.replace(FAST, n_boot=0, sampled=False, max_presses=1)
    every = evaluate_checkpoint(loaded, data, "all", cfg)
    assert every.info["fabrics"] == list(range(1, 9)) and "property_" not in str(every.metrics)
    trained = evaluate_checkpoint(loaded, data, "train", cfg)
    assert trained.info["fabrics"] == sorted(loaded.split["train"])
    # Each refusal points to a split that this run and dataset have.
    with pytest.raises(DatasetError, match="paper's test fabrics .* use --split val for the run"):
        evaluate_checkpoint(loaded, data, "paper", cfg)
    with pytest.raises(
        DatasetError, match=r"novel fabrics \(it is not a seen run\); use --split all$"
    ):
        evaluate_checkpoint(loaded, data, "novel", cfg)
    emb = embed_checkpoint(loaded, data, "all")
    assert emb.reference is None and emb.meta["split"] == "all"


def test_split_all_says_what_of_the_dataset_the_model_leaves_out(
    run: tuple[Path, Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
):
    """QA: `lookfeel embed --split all` said "every item of the dataset", then that the run's
    press kinds left presses out. Now the description says so itself, once (evaluate prints and
    reports the same description); a dataset nothing of which is left out keeps the plain
    words."""
    from lookfeel.evaluate import summary_lines
    from lookfeel.evaluate.from_checkpoint import _left_out

    data, ckpt, _ = run  # trained on fold presses (data.touch_kinds' default)
    loaded = load_model(ckpt)
    plain = "every item of the dataset (training fabrics included)"
    assert embed_checkpoint(loaded, data, "all").meta["split_description"] == plain
    other = write_tiny_dataset(
        tmp_path / "other", fabrics=3, drapes=1, fold_presses=2, flat_presses=2
    )
    npz = tmp_path / "e.npz"
    argv = ["embed", "--checkpoint", str(ckpt), "--data", str(other), "--out", str(npz)]
    assert main(argv) == 0
    said = (
        "every item of the dataset the model embeds (training fabrics included; left out: "
        "6 flat presses (the run's data.touch_kinds: fold))"
    )
    lines = capsys.readouterr().out.splitlines()
    assert lines[0] == f"Embedded depth 3, color 3, touch 6 ({said}) into {npz}"
    assert not any("left out" in line for line in lines[1:])  # named once
    cfg = dataclasses.replace(
        FAST, n_boot=0, sampled=False, max_presses=1, background_control=False
    )
    result = evaluate_checkpoint(loaded, other, "all", cfg)
    assert summary_lines(result)[0] == f"Evaluated {said}:"
    assert f"| split | all: {said} |" in write_report(result, tmp_path / "r").report.read_text(
        encoding="utf-8"
    )
    # A modality the model does not embed, and videos that hold no press, are named too.
    catalog = scan(other)
    pressed = catalog.with_items(
        it for m in catalog.modalities for it in catalog.items(m) if it.press != "101"
    )
    assert _left_out(catalog, pressed, [T], (PressKind.FOLD,)) == [
        "3 depth images (the model does not embed depth)",
        "3 color images (the model does not embed color)",
        "6 flat presses (the run's data.touch_kinds: fold)",
        "1 touch video with no press",
    ]


def test_a_seen_run_evaluates_its_held_out_items(run: tuple[Path, Path, Path], tmp_path: Path):
    data = run[0]
    cfg = load_config(
        RunConfig,
        TINY,
        ["train.steps=2", "train.val_every=0", "train.split=seen", "train.val_fabrics=2"],
    )
    loaded = load_model(train(cfg, data, tmp_path / "seen").last_checkpoint)
    held = {Path(p).name for p in loaded.split["val_items"]}
    val = embed_checkpoint(loaded, data, "val")
    assert val.reference is not None
    for m in (D, C, T):
        assert {Path(p).name for p in val.embedded[m].paths} <= held
        assert not {Path(p).name for p in val.reference[m].paths} & held
        assert set(val.embedded[m].fabric_ids.tolist()) == set(loaded.split["train"])
    novel = embed_checkpoint(loaded, data, "novel")
    assert set(novel.embedded[D].fabric_ids.tolist()) == set(loaded.split["novel"])
    r = evaluate_embeddings(val.embedded, FAST, labels={1: [0.0]}, reference=val.reference)
    assert not r.properties and any("share fabrics" in n for n in r.notes)


def test_presses_are_pooled_by_the_model_when_it_projects_after_pooling(
    run: tuple[Path, Path, Path], tmp_path: Path
):
    data, plain, projected = run
    assert pools_final_embedding(load_model(plain).model)
    model = load_model(projected)
    assert not pools_final_embedding(model.model)
    cfg = dataclasses.replace(FAST, n_boot=0, max_presses=2)
    direct = evaluate_checkpoint(model, data, "val", cfg)
    save_embeddings(tmp_path / "p.npz", embed_checkpoint(model, data, "val"))
    from_file = evaluate_embedding_file(tmp_path / "p.npz", cfg, data)
    assert any("pools before its projection" in n for n in from_file.notes)
    # Single items agree; pooled touch queries differ (the model's pooling is not the max of
    # its projected embeddings).
    assert direct.metrics["depth_to_color_nll"] == pytest.approx(
        from_file.metrics["depth_to_color_nll"]
    )
    assert direct.metrics["touch_to_depth_nll"] != pytest.approx(
        from_file.metrics["touch_to_depth_nll"]
    )


def test_cli_errors(
    run: tuple[Path, Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
):
    data, ckpt, _ = run
    out = str(tmp_path / "x")
    assert main(["evaluate", "--checkpoint", str(ckpt), "--out", out]) == 2
    assert "needs --data" in capsys.readouterr().err
    assert main(["evaluate", "--embeddings", str(tmp_path / "no.npz"), "--out", out]) == 1
    assert "not found" in capsys.readouterr().err
    assert evaluate_cli(ckpt, data, out, "--set", "nboot=1") == 1
    assert "unknown key" in capsys.readouterr().err
    assert evaluate_cli(ckpt, data, out, "--split", "paper") == 1
    assert "one of the paper's test fabrics" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        main(["evaluate", "--checkpoint", str(ckpt), "--embeddings", "e.npz", "--out", out])


def _with_weights(ckpt: Path, out: Path, change: dict[str, float]) -> Path:
    """A copy of ``ckpt`` with each tensor whose name ends in a key of ``change`` filled with
    that value."""
    import torch

    state = torch.load(ckpt, weights_only=True)
    for name, t in state["model"].items():
        for end, value in change.items():
            if name.endswith(end):
                t.fill_(value)
    torch.save(state, out)
    return out


def test_a_checkpoint_with_non_finite_weights_is_refused_by_name(
    run: tuple[Path, Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
):
    from lookfeel.checkpoint import CheckpointError

    data, _, ckpt = run
    bad = _with_weights(ckpt, tmp_path / "nan.pt", {"touch.project.bias": float("nan")})
    said = (
        f"lookfeel: {bad}: its weights hold NaN or infinity (branches.touch.project.bias): the "
        "run diverged or the file is damaged; use an earlier checkpoint of the run\n"
    )
    npz = tmp_path / "e.npz"
    assert main(["embed", "--checkpoint", str(bad), "--data", str(data), "--out", str(npz)]) == 1
    assert capsys.readouterr().err == said and not npz.exists()
    assert evaluate_cli(bad, data, tmp_path / "ev") == 1
    assert capsys.readouterr().err == said
    # Finite weights so large that every embedding overflows: refused as they are embedded.
    huge = _with_weights(ckpt, tmp_path / "huge.pt", {"fc.1.weight": 1e30, "project.weight": 3e38})
    with pytest.raises(CheckpointError) as e:
        embed_checkpoint(huge, data)
    assert str(e.value).startswith(f"{huge}: the model embeds ")
    assert "items as NaN or infinity (first " in str(e.value)


def test_an_embeddings_file_holding_nan_is_refused_by_name(tmp_path: Path):
    embedded, _ = _world()
    embedded[T].embeddings[3, 1] = np.nan
    path = save_embeddings(tmp_path / "e.npz", EmbeddingSet(embedded))
    with pytest.raises(EmbeddingFileError) as e:
        load_embeddings(path)
    assert str(e.value) == (
        f"{path}: embeddings_touch holds NaN or infinity in 1 of 72 rows: the model that "
        "embedded them diverged or the file is damaged"
    )


def test_evaluate_checkpoint_in_label_space(run: tuple[Path, Path, Path], tmp_path: Path):
    data, _, ckpt = run
    out = tmp_path / "labels"
    sets = ["--set", "n_boot=20", "--set", "max_presses=2", "--set", "space=labels"]
    assert evaluate_cli(ckpt, data, out, "--split", "val", *sets) == 0
    metrics = json.loads((out / "metrics.json").read_text(encoding="utf-8"))
    assert "touch_to_depth_top1" in metrics and "depth_to_depth_top1_swapped" in metrics
    assert "label space" in (out / "report.md").read_text(encoding="utf-8")
    assert not any("mapped" in k for k in metrics)  # label space is a map of its own
    # Without labels there is nothing to map onto: one line naming the key.
    bare = tmp_path / "bare"
    write_tiny_dataset(bare, fabrics=8, drapes=3, fold_presses=4, flat_presses=0)
    (bare / "labels.csv").write_text(
        "fabric_id\n" + "".join(f"{i}\n" for i in range(1, 9)), encoding="utf-8"
    )
    with pytest.raises(ConfigError, match="eval.space: labels needs"):
        evaluate_checkpoint(ckpt, bare, "val", dataclasses.replace(FAST, space="labels"))


def test_figures_show_depth_whole_and_touch_as_its_last_frame(tmp_path: Path):
    """A figure's depth image is the whole (H, W) map, not its last three columns; a touch
    press read as stacked frames shows its last frame's three colours."""
    from types import SimpleNamespace

    from lookfeel.config import DataConfig
    from lookfeel.data import ImageLoader, scan
    from lookfeel.evaluate.report import _image

    data = write_tiny_dataset(tmp_path / "data", fabrics=3, drapes=1, fold_presses=1)
    catalog = scan(data)
    items = {m: catalog.items(m) for m in (D, T)}
    result = SimpleNamespace(embedded={m: SimpleNamespace(items=v) for m, v in items.items()})
    loader = ImageLoader(DataConfig(image_size=32))
    assert _image(loader, result, D, 0).shape == (32, 32)  # type: ignore[arg-type]
    assert _image(loader, result, T, 0).shape == (32, 32, 3)  # type: ignore[arg-type]
    stacked = ImageLoader(DataConfig(image_size=32, touch_frames=(0, -1)))
    last = _image(stacked, result, T, 0)  # type: ignore[arg-type]
    assert last.shape == (32, 32, 3)


def test_a_split_of_the_run_on_another_dataset_is_warned_of(run: tuple[Path, Path, Path], tmp_path):
    import shutil
    import warnings

    data, ckpt, _ = run
    loaded = load_model(ckpt)
    assert loaded.data_fingerprint == scan(data).fingerprint()
    import platform

    import torch

    import lookfeel

    assert loaded.software == {  # what wrote it, for a number read months later
        "lookfeel": lookfeel.__version__,
        "torch": str(torch.__version__),
        "python": platform.python_version(),
    }
    moved = Path(shutil.copytree(data, tmp_path / "moved"))  # the same data elsewhere: quiet
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        embed_checkpoint(loaded, moved, "val")
    other = write_tiny_dataset(tmp_path / "other", fabrics=8, drapes=2, fold_presses=4)
    for split in ("val", "train"):
        with pytest.warns(UserWarning, match=rf"trained on another dataset .* --split {split}"):
            embed_checkpoint(loaded, other, split)
    with warnings.catch_warnings():  # every item of any dataset: nothing of the run's is used
        warnings.simplefilter("error")
        embed_checkpoint(loaded, other, "all")


def test_touch_to_touch_with_every_press_in_its_query_is_not_scored_and_says_why(
    tmp_path: Path,
):
    """Three presses a fabric pooled three at a time leave no press of the query's fabric
    among touch to touch's single presses: that pair is marked not scored with the reason
    (result, notes, printed summary, report), its calibration is NaN, and the other pairs are
    scored as they were."""
    from lookfeel.evaluate import summary_lines

    embedded, _ = _world(per={D: 4, T: 3}, noise=0.1)
    r = evaluate_embeddings(embedded, dataclasses.replace(FAST, presses=3))
    t2t = Pair(T, T)
    assert set(r.not_scored) == {t2t}
    why = r.not_scored[t2t]
    assert "no test fabric has more than 3 touch presses" in why
    assert why.endswith("use --set presses=2 or fewer")
    assert any(n.startswith("touch_to_touch not scored: ") for n in r.notes)
    assert np.isnan(r.metrics["touch_to_touch_top1"])
    cal = r.calibration[t2t]
    assert all(np.isnan(v) for v in (cal.accuracy, cal.confidence, cal.nll, cal.reliability.ece))
    assert r.metrics["touch_to_depth_top1"] == pytest.approx(1.0)  # pooled queries still score
    assert not any("c for touch_to_touch" in n for n in r.notes)  # no c fitted on nothing
    lines = summary_lines(r)
    assert f"  touch_to_touch   not scored: {why}" in lines
    assert not any("nan" in line for line in lines)
    report = write_report(r, tmp_path).report.read_text(encoding="utf-8")
    assert "| touch → touch | not scored |" in report
    assert f"Not scored: touch → touch: {why}." in report
    # Two presses a query leave one to find: scored, nothing marked.
    r2 = evaluate_embeddings(embedded, dataclasses.replace(FAST, presses=2))
    assert not r2.not_scored and r2.metrics["touch_to_touch_top1"] == pytest.approx(1.0)


OBJECTS = (
    "bark", "cork", "denim", "felt", "foam", "leaf", "linen", "moss", "rice_spatula_head", "sponge",
)  # fmt: skip


def test_the_report_names_the_objects_the_data_names_and_numbers_the_rest(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
):
    """Recordings (``videos/<object>_<n>.mov``) name their objects: the report's pick examples,
    glance, confusion axes and test fabrics say ``sponge`` (a long name broken after an
    underscore to fit under its image); numbered fabrics keep ``F3``."""
    from lookfeel.evaluate import report as report_module

    labels = "object,hardness\n" + "".join(f"{o},{k % 3}\n" for k, o in enumerate(OBJECTS))
    data = write_recordings(tmp_path / "rec", dict.fromkeys(OBJECTS, 1), labels)
    name_of = {f.id: f.name for f in scan(data).fabrics}
    assert sorted(name_of) == list(range(1, 11))
    embedded, _ = _world(n_fabrics=10, noise=0.6, seed=2)
    npz = save_embeddings(tmp_path / "e.npz", EmbeddingSet(embedded, None, {}))
    named = evaluate_embedding_file(npz, FAST, data)
    assert named.names == name_of
    numbered = evaluate_embeddings(embedded, FAST)
    assert numbered.names == {}

    drawn: dict[str, list[tuple[object, ...]]] = {}

    def spy(name: str) -> None:  # record each call's arguments, then draw
        real = getattr(report_module, name)

        def recording(*args: object, **kwargs: object) -> object:
            drawn.setdefault(name, []).append(args)
            return real(*args, **kwargs)

        monkeypatch.setattr(report_module, name, recording)

    for name in ("pick_examples_figure", "glance_figure", "confusion_figure"):
        spy(name)
    # The hand-made items have no files: every figure shows a blank image.
    monkeypatch.setattr(report_module, "_image", lambda *a: np.zeros((8, 8, 3), np.uint8))

    def flat(label: str) -> str:  # a label as one line
        return label.replace("_\n", "_").replace("\n", " ")

    t_fab, d_fab = embedded[T].fabric_ids, embedded[D].fabric_ids
    for result in (named, numbered):
        want = {i: name_of[i] if result is named else f"F{i}" for i in range(1, 11)}
        drawn.clear()
        report = write_report(result, tmp_path / str(len(result.names))).report.read_text(
            encoding="utf-8"
        )
        [[picks]] = drawn["pick_examples_figure"]
        [[glances]] = drawn["glance_figure"]
        con = result.calibration["touch_to_depth"].confusion
        assert con is not None
        confusion_axes = drawn["confusion_figure"][0][1:3]  # then the clusters'
        for ex, row in zip(result.examples["touch_to_depth"], picks, strict=True):
            assert flat(row.query_label) == f"query: touch {want[t_fab[ex.query_rows[0]]]}"
            labels = [flat(c.split("\nD = ")[0]) for c in row.candidate_labels]
            assert labels == [f"{k + 1}. {want[d_fab[c]]}" for k, c in enumerate(ex.candidates)]
        for ex, row in zip(result.glance, glances, strict=True):
            assert flat(row.query_label) == f"query: touch {want[ex.fabric]}"
            for g, look in zip(ex.galleries, row.looks, strict=True):
                assert [flat(x) for x in look.labels] == [
                    f"{k + 1}. {want[f]}" for k, f in enumerate(g.fabrics)
                ]
        texts = [row.query_label for row in [*picks, *glances]]
        texts += [x for row in picks for x in row.candidate_labels]
        texts += [x for row in glances for look in row.looks for x in look.labels]
        assert max(len(line) for x in texts for line in x.split("\n")) <= 17
        if result is named:
            assert any("rice_spatula_\nhead" in x for x in texts)
            assert list(confusion_axes) == [
                [name_of[int(f)] for f in ids] for ids in (con.rows, con.cols)
            ]
            shown, unit = ", ".join(OBJECTS), "objects"
        else:  # numbered fabrics: their ids, as before
            assert list(confusion_axes) == [
                [str(int(f)) for f in ids] for ids in (con.rows, con.cols)
            ]
            shown, unit = ", ".join(str(i) for i in range(1, 11)), "fabrics"
        assert f"| test {unit} | 10: {shown} |" in report


def test_a_split_the_run_did_not_hold_out_is_refused_before_any_video_is_decoded(
    run: tuple[Path, Path, Path],
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
):
    """A run with train.split=none held out nothing: --split val (evaluate, embed) and novel
    are refused from the checkpoint and the catalog alone, before a press video is decoded
    (minutes on hundreds of videos)."""
    from lookfeel.checkpoint import read_checkpoint, save_checkpoint
    from lookfeel.data import images as images_module

    labels = "object,hardness\ncork,1\nsponge,0\n"
    data = write_recordings(tmp_path / "rec", {"cork": 2, "sponge": 2}, labels)
    catalog = scan(data)
    state = read_checkpoint(run[1])
    state["split"] = {"kind": "none", "train": catalog.ids, "val": []}  # as train writes it
    state["data_fingerprint"] = catalog.fingerprint()  # trained on these recordings
    ckpt = save_checkpoint(tmp_path / "none.pt", state)

    def decode(*args: object, **kwargs: object) -> None:
        raise AssertionError("a press video was decoded before the split was refused")

    monkeypatch.setattr(images_module, "read_press", decode)
    refused = r"the run held out no fabrics \(it trained on every fabric \(train.split=none\)\); "
    with pytest.raises(DatasetError, match=refused + "use --split all$"):
        evaluate_checkpoint(ckpt, data, "val", FAST)
    with pytest.raises(DatasetError, match=refused):
        embed_checkpoint(ckpt, data, "val")
    with pytest.raises(DatasetError, match=r"held out no novel fabrics \(it is not a seen run\)"):
        embed_checkpoint(ckpt, data, "novel")
    capsys.readouterr()
    assert evaluate_cli(ckpt, data, tmp_path / "out", "--split", "val") == 1
    [line] = capsys.readouterr().err.strip().splitlines()
    assert "train.split=none" in line and "use --split all" in line


def test_the_report_says_how_presses_were_pooled():
    """QA: the report said "element-wise max" for a checkpoint whose model pools its presses
    before its projection, where the embeddings file's max-pooling gives other numbers."""
    from lookfeel.config import EvalConfig
    from lookfeel.evaluate import EvalResult
    from lookfeel.evaluate.report import _pooled_by

    def said(info: dict) -> str:
        return _pooled_by(EvalResult({}, EvalConfig(), (), {}, {}, {}, {}, info=info))

    assert said({"pool_exact": False}).startswith("by the model's own press pooling")
    assert said({"pool_exact": True}) == "by element-wise max of their embeddings"
    file = {"pool_exact": False, "embeddings_file": "e.npz"}  # an npz can only max-pool
    assert said(file) == "by element-wise max of their embeddings"


# ------------------------------------------------------------------------------------------
# Beside the model: raw pixels and the controls, scored as `lookfeel cv` scores them, and what
# the numbers rest on.


def _row(section: str, start: str) -> list[str]:
    """The cells of the first table row of ``section`` that starts with ``start``."""
    line = next(x for x in section.splitlines() if x.startswith(start))
    return [c.strip() for c in line.strip("|").split("|")]


def _section(report: str, heading: str) -> str:
    return report.split(f"## {heading}")[1].split("\n## ")[0]


def _printed(lines: list[str], pair: str) -> list[str]:
    """A pair's printed lines (`summary_lines`): its own, then those under it (its controls,
    the cross-modal map, raw pixels), stripped."""
    start = next(i for i, x in enumerate(lines) if x.startswith(f"  {pair} "))
    under = lines[start + 1 :]
    end = next((i for i, x in enumerate(under) if not x.startswith(" " * 19)), len(under))
    return [x.strip() for x in [lines[start], *under[:end]]]


@pytest.mark.filterwarnings("ignore:pick 10")
def test_the_background_control_pools_touch_as_the_scores_and_raw_pixels_join_each_sense(
    run: tuple[Path, Path, Path], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
):
    """QA: with touch queries pooling presses (tiny.yaml's 2; the paper's Multi-input Net 3)
    the background control skipped every pair with touch ("its touch pools 2 presses"), while
    `lookfeel cv` scored it; raw pixels stood beside depth to depth only; the control's table
    showed raw pixels without their interval. Now touch pools the same presses under the
    control as in the main scores (with nothing swapped the control scores exactly them), and
    raw pixels of every pair of one sense stand beside it, as cv's, with intervals."""
    from lookfeel.data import ImageLoader
    from lookfeel.embedding import raw_pixels
    from lookfeel.evaluate import summary_lines
    from lookfeel.evaluate.core import exact_protocol
    from lookfeel.metrics import QuerySet

    data, _, ckpt = run  # the model pools its presses itself (a projection follows)
    cfg = dataclasses.replace(FAST, n_boot=50, max_presses=2)
    r = evaluate_checkpoint(ckpt, data, "val", cfg)
    m = r.metrics
    assert r.config.presses == 2 and not any("skipped" in n for n in r.notes)
    for key in ("touch_to_depth_top1_swapped", "depth_to_touch_top1_swapped"):
        assert 0.0 <= m[f"{key}_ci_low"] <= m[key] <= m[f"{key}_ci_high"] <= 1.0, key
    # Raw pixels of each sense against itself, as cv: a pooled touch query the mean of its
    # presses' pixels; none across senses.
    loader = ImageLoader(load_model(ckpt).config.data)
    protocol = exact_protocol(r.config)
    for mod in (D, C, T):
        pair, e = Pair(mod, mod), r.embedded[mod]
        pix = raw_pixels(e.items, loader)
        queries = {}
        if mod is T:
            q = r.pooled_queries[T]
            assert q.members.shape[1] == 2
            queries = {T: QuerySet(pix[q.members].mean(axis=1), q.fabric, q.members)}
        want = score_pairs({mod: pix}, {mod: e.fabric_ids}, protocol, [pair], queries=queries)
        for k in ("top1", "top1_ci_low", "top1_ci_high", "top3"):
            assert m[f"{pair}_raw_pixels_{k}"] == want[pair].metrics[k], (pair, k)
    assert not [
        k
        for k in m
        if "raw_pixels" in k and not k.startswith(("depth_to_d", "color_to_c", "touch_to_t"))
    ]
    printed = _printed(summary_lines(r), "touch_to_touch")
    raw = "touch_to_touch_raw_pixels_top1"
    assert f"raw pixels {m[raw]:.3f} [{m[f'{raw}_ci_low']:.3f}, " in printed[-1]

    report = write_report(r, tmp_path / "r").report.read_text(encoding="utf-8")
    pick = _row(_section(report, "Pick"), "| color → color |")
    lo, hi = m["color_to_color_raw_pixels_top1_ci_low"], m["color_to_color_raw_pixels_top1_ci_high"]
    assert f"{m['color_to_color_raw_pixels_top1']:.3f} ({lo:.3f} – {hi:.3f}" in pick[3]
    control = _section(report, "Background control")
    header = _row(control, "| pair |")
    for pair in ("depth → depth", "touch → depth"):
        cells = dict(zip(header, _row(control, f"| {pair} | top-1 |"), strict=True))
        assert " – " in cells["model, background swapped"], pair
    cells = dict(zip(header, _row(control, "| depth → depth | top-1 |"), strict=True))
    for name, key in (("raw pixels", ""), ("raw pixels, background swapped", "_swapped")):
        key = f"depth_to_depth_raw_pixels_top1{key}"
        lo, hi = m[f"{key}_ci_low"], m[f"{key}_ci_high"]
        assert cells[name].startswith(f"{m[key]:.3f} ({lo:.3f} – {hi:.3f}"), name

    class NoSwap:  # every image with its own background: the control must score as the main
        has_room_control = False

        def __init__(self, config: object, seed: int) -> None:
            self.config = config

        def loader(self, items: object) -> ImageLoader:
            return ImageLoader(self.config)  # type: ignore[arg-type]

    from lookfeel.evaluate import controls

    monkeypatch.setattr(controls, "BackgroundControl", NoSwap)
    for space in ("embedding", "labels"):
        same = evaluate_checkpoint(ckpt, data, "val", dataclasses.replace(cfg, space=space))
        s = same.metrics
        pairs = [p for p in same.pairs if D in (p.query, p.gallery)]
        assert len(pairs) == 5
        for pair in pairs:
            for key in (f"{pair}_top1", f"{pair}_top1_mapped", f"{pair}_raw_pixels_top1"):
                if key in s:
                    assert s[f"{key}_swapped"] == s[key], (space, key)


@pytest.fixture(scope="module")
def press_videos(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """Six objects pressed three times each (press videos), and tiny.yaml trained on their
    touch for 2 steps with 3 objects held out; its touch queries pool 2 presses."""
    pytest.importorskip("av")
    from ._video import PRESS, object_press, write_video

    root = tmp_path_factory.mktemp("press_videos")
    data = root / "data"
    (data / "videos").mkdir(parents=True)
    names = OBJECTS[:6]
    (data / "labels.csv").write_text(
        "object,hardness\n" + "".join(f"{n},{k % 3}\n" for k, n in enumerate(names)),
        encoding="utf-8",
    )
    for k, name in enumerate(names):
        for i in range(3):
            frames = object_press(k, PRESS, t=14, seed=10 * k + i)
            write_video(data / "videos" / f"{name}_{i}.mov", frames)
    steps = ["train.views=[touch, touch]", "train.steps=2", "train.val_every=0"]
    cfg = load_config(RunConfig, TINY, [*steps, "train.val_fabrics=3"])
    return data, train(cfg, data, root / "run").last_checkpoint


def test_press_videos_get_the_untouched_control_as_cv_scores_it(
    press_videos: tuple[Path, Path], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
):
    """QA: `lookfeel evaluate` on press videos showed the model against chance only; cv puts
    the untouched control beside it (every press replaced by a moment of its video without
    contact: the sensor's light identifies a session). Now evaluate does too, pooled touch
    queries pooling the same presses' moments (with the presses themselves in their place,
    the control scores exactly what the main scores did), with raw pixels, in metrics.json,
    report.md and the printed lines."""
    from lookfeel.data import ImageLoader
    from lookfeel.data.touch_control import UntouchedControl
    from lookfeel.evaluate import summary_lines

    data, ckpt = press_videos
    cfg = dataclasses.replace(FAST, n_boot=50, max_presses=2)
    r = evaluate_checkpoint(ckpt, data, "val", cfg)
    m = r.metrics
    assert r.config.presses == 2  # pooled: the model's own pooling of the presses' moments
    keys = ["touch_to_touch_top1_untouched", "touch_to_touch_raw_pixels_top1_untouched"]
    for key in ["touch_to_touch_raw_pixels_top1", *keys]:
        assert 0.0 <= m[f"{key}_ci_low"] <= m[key] <= m[f"{key}_ci_high"] <= 1.0, key
    lines = summary_lines(r)
    assert lines[0] == "Evaluated the run's held-out objects (3):"
    printed = _printed(lines, "touch_to_touch")
    key = "touch_to_touch_top1_untouched"
    lo, hi = m[f"{key}_ci_low"], m[f"{key}_ci_high"]
    assert f"model, untouched {m[key]:.3f} [{lo:.3f}, {hi:.3f}]" in printed
    raw = [x for x in printed if x.startswith("raw pixels ")]
    assert raw and f"untouched {m[keys[1]]:.3f} [" in raw[0]  # raw pixels' own, beside theirs
    files = write_report(r, tmp_path / "r")
    assert keys[0] in json.loads(files.metrics.read_text(encoding="utf-8"))
    section = _section(files.report.read_text(encoding="utf-8"), "Untouched control")
    cells = dict(
        zip(_row(section, "| pair |"), _row(section, "| touch → touch | top-1 |"), strict=True)
    )
    lo, hi = m[f"{keys[0]}_ci_low"], m[f"{keys[0]}_ci_high"]
    assert cells["model, untouched"].startswith(f"{m[keys[0]]:.3f} ({lo:.3f} – {hi:.3f}")
    assert cells["raw pixels, untouched"].startswith(f"{m[keys[1]]:.3f} (")

    def pressed(self: UntouchedControl, items: object) -> ImageLoader:
        return ImageLoader(self.config)

    monkeypatch.setattr(UntouchedControl, "loader", pressed)
    same = evaluate_checkpoint(ckpt, data, "val", cfg).metrics
    for key in ("touch_to_touch_top1", "touch_to_touch_top3", "touch_to_touch_raw_pixels_top1"):
        assert same[f"{key}_untouched"] == same[key], key


def test_the_report_says_what_a_pick_offered_and_how_many_fabrics_an_interval_rests_on(
    tmp_path: Path,
):
    """QA: on 2 held-out fabrics the report said "10 candidates ... 9 other fabrics" and
    printed ``0.583 [0.583, 0.583]`` as if it were tight. Now it says how many candidates each
    pick offered, beside each pair the queries and fabrics its numbers rest on, and under
    `lookfeel.metrics.bootstrap.MIN_INTERVAL_FABRICS` (10) that the interval says little;
    data that names its objects says "objects"."""
    from lookfeel.evaluate import summary_lines

    few = evaluate_embeddings(_world(n_fabrics=3, noise=0.5)[0], FAST)
    t2d = next(x for x in summary_lines(few) if "touch_to_depth" in x)
    assert "(18 queries, 3 fabrics: too few for the interval to say much)" in t2d
    report = write_report(few, tmp_path / "few").report.read_text(encoding="utf-8")
    pick = _section(report, "Pick")
    assert pick.startswith(" 1 of 3 (")
    assert "A query is shown 3 candidates" in pick and "each of the 2 other test fabrics" in pick
    assert "9 other" not in report and "10 candidates" not in report
    row = _row(pick, "| touch → depth |")
    assert row[2].endswith("†") and row[-1] == "18 / 3"
    rule = "† Over 3 test fabrics only: under 10, an interval says little, as the bootstrap"
    assert f"{rule} can only resample the few test fabrics there are: it may be far" in pick
    assert "| queries / test fabrics / candidates per pick | 18 / 3 / 3 |" in pick

    many = evaluate_embeddings(_world(n_fabrics=12, noise=0.5)[0], FAST)
    t2d = next(x for x in summary_lines(many) if "touch_to_depth" in x)
    assert "(72 queries, 12 fabrics)  chance" in t2d
    pick = _section(
        write_report(many, tmp_path / "many").report.read_text(encoding="utf-8"), "Pick"
    )
    assert pick.startswith(" 1 of 10 (") and "†" not in pick
    assert "one item of its own fabric and one of each of 9 other fabrics drawn at" in pick

    named = dataclasses.replace(many, names={i: f"thing{i}" for i in range(1, 13)})
    report = write_report(named, tmp_path / "named").report.read_text(encoding="utf-8")
    pick = _section(report, "Pick").split("\n### ")[0]
    assert "one item of its own object and one of each of 9 other objects drawn" in pick
    assert "| queries / objects |" in pick and "fabric" not in pick
    assert "| test objects | 12: thing1, " in report


def test_evaluate_marks_intervals_by_the_rule_reproduce_and_cv_use(tmp_path: Path):
    """QA: evaluate marked an interval as saying little under 5 test fabrics, reproduce and cv
    under `MIN_INTERVAL_FABRICS` (10): 6 fabrics got no mark here and "too few fabrics" there.
    One rule now: 6 are marked, in the report (every table that shows the interval, with the
    rule under it) and the printed line; 10 are not."""
    from lookfeel.evaluate import summary_lines
    from lookfeel.metrics.bootstrap import MIN_INTERVAL_FABRICS

    assert MIN_INTERVAL_FABRICS == 10
    six = evaluate_embeddings(_world(n_fabrics=6, noise=0.5)[0], FAST)
    t2d = next(x for x in summary_lines(six) if "touch_to_depth" in x)
    assert "(36 queries, 6 fabrics: too few for the interval to say much)" in t2d
    pick = _section(write_report(six, tmp_path / "six").report.read_text(encoding="utf-8"), "Pick")
    assert _row(pick, "| touch → depth |")[2].endswith("†")
    assert "† Over 6 test fabrics only: under 10, an interval says little" in pick
    assert "Hold out 10 or more (or cross-validate, `lookfeel cv`)" in pick

    ten = evaluate_embeddings(_world(n_fabrics=MIN_INTERVAL_FABRICS, noise=0.5)[0], FAST)
    assert not any("too few" in x for x in summary_lines(ten))
    report = write_report(ten, tmp_path / "ten").report.read_text(encoding="utf-8")
    assert "†" not in report and "says little" not in report


def test_the_press_curve_note_counts_the_presses_of_the_kinds_evaluated():
    """QA: a rig with 2 flat and 2 fold presses a fabric, evaluated on its fold presses (the
    run's data.touch_kinds), was told "no fabric has 3 touch presses" although each has 4: the
    note names the kind it counted and the most a fabric has."""
    from lookfeel.config import DataConfig
    from lookfeel.data import Item

    embedded, _ = _world(per={D: 3, T: 2}, noise=0.1)
    touch = embedded[T]
    folds = tuple(
        Item(T, int(f), (Path(f"touch/F{int(f):04d}_fold_{i}.mp4"),), PressKind.FOLD, str(i))
        for i, f in enumerate(touch.fabric_ids)
    )
    kinded = {**embedded, T: dataclasses.replace(touch, items=folds)}
    r = evaluate_embeddings(kinded, FAST, data_config=DataConfig())
    said = [n for n in r.notes if "press curve" in n]
    assert said == [
        "no fabric has 3 fold touch presses (the kind evaluated: the run's data.touch_kinds; "
        "2 at most): the press curve stops before 3"
    ]
    # Presses of no stated kind (an embeddings file read without its dataset): counted as such.
    plain = evaluate_embeddings(embedded, FAST)
    assert [n for n in plain.notes if "press curve" in n] == [
        "no fabric has 3 touch presses (2 at most): the press curve stops before 3"
    ]
    pooled = evaluate_embeddings(kinded, dataclasses.replace(FAST, presses=3))
    assert any(
        n.startswith("no fabric has 3 fold touch presses (the kind evaluated; 2 at most) to pool")
        for n in pooled.notes
    )


def test_the_nll_s_standard_error_is_over_fabrics_not_queries():
    """Queries of one fabric are not independent: the error is the spread of the fabrics' own
    mean NLLs (one fabric of 3 queries weighs as one of 1), NaN for a single fabric."""
    from lookfeel.evaluate.core import _se_over_fabrics

    values = np.array([1.0, 1.0, 1.0, 3.0, 5.0])
    fabric = np.array([7, 7, 7, 2, 9])
    assert _se_over_fabrics(values, fabric) == pytest.approx(
        np.std([3.0, 1.0, 5.0], ddof=1) / math.sqrt(3)
    )
    assert math.isnan(_se_over_fabrics(values[:3], fabric[:3]))


def test_metrics_json_writes_a_path_in_info_as_text(tmp_path: Path):
    # A Python caller's info may hold a Path (evaluate_embeddings(info=...)): it is written as
    # its text, not a TypeError out of write_report.
    from types import SimpleNamespace

    from lookfeel.evaluate.report import write_metrics

    result = SimpleNamespace(
        metrics={"depth_to_depth_top1": 0.5, "depth_to_depth_map": float("nan")},
        info={"checkpoint": tmp_path / "last.pt", "step": 3, "unrelated": "left out"},
    )
    path = write_metrics(result, tmp_path / "metrics.json")  # type: ignore[arg-type]
    written = json.loads(path.read_text(encoding="utf-8"))
    assert written == {
        "info": {"checkpoint": str(tmp_path / "last.pt"), "step": 3},
        "depth_to_depth_top1": 0.5,
        "depth_to_depth_map": None,
    }
