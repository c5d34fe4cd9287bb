"""What `lookfeel evaluate` says beside its numbers: a best checkpoint scored on the fabrics it
was chosen on, whose number each printed control is, and a Spearman over too few fabrics."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest

from lookfeel.checkpoint import load_model
from lookfeel.config import EvalConfig
from lookfeel.data import scan
from lookfeel.evaluate import (
    embedded_from_arrays,
    evaluate_checkpoint,
    evaluate_embeddings,
    summary_lines,
    write_report,
)
from lookfeel.metrics.properties import MIN_SPEARMAN
from lookfeel.modality import Modality

from ._library import evaluate_cli

D, C, T = Modality.DEPTH, Modality.COLOR, Modality.TOUCH
QUICK = ["--no-background-control", "--set", "n_boot=20", "--set", "sampled=false"]
QUICK += ["--set", "max_presses=1"]


def _evaluated(
    ckpt: Path, data: Path, out: Path, capsys: pytest.CaptureFixture[str], *split: str
) -> tuple[str, str, dict[str, object]]:
    """(printed, report.md, metrics.json) of ``lookfeel evaluate`` on ``ckpt``: its numbers, and
    in ``info`` what was scored."""
    assert evaluate_cli(ckpt, data, out, *split, *QUICK) == 0
    printed = capsys.readouterr().out
    return (
        printed,
        (out / "report.md").read_text(encoding="utf-8"),
        json.loads((out / "metrics.json").read_text(encoding="utf-8")),
    )


@pytest.mark.filterwarnings("ignore:pick 10")
def test_a_best_checkpoint_scored_on_the_fabrics_it_was_chosen_on_says_so(
    run: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
):
    """QA: `lookfeel evaluate --checkpoint RUN/checkpoints/best.pt` scores by default the run's
    validation fabrics, the very fabrics training chose best.pt on (the best validation
    top-1), and said nothing: an optimistic score read as a held-out one. Now the printed
    lines, report.md (beside the scores) and metrics.json (``selected_on_split``) say so;
    last.pt, and best.pt on fabrics it was not chosen on, say nothing of the kind."""
    data, last = run
    best = last.parent / "best.pt"
    assert best.is_file()
    printed, report, metrics = _evaluated(best, data, tmp_path / "best", capsys)
    said = (
        "this checkpoint (best.pt, step 20) was chosen as the run's best by its validation "
        "top-1 on these same fabrics, so its scores here are optimistic: evaluate last.pt for "
        "an unbiased score"
    )
    lines = printed.splitlines()
    assert lines[0] == "Evaluated the run's held-out fabrics (2):"
    assert lines[1].startswith(f"  Note: {said}")
    assert "or fabrics the run never saw" in lines[1]
    assert f"**Optimistic scores:** {said}" in report.split("## Pick")[0]  # above the scores
    assert report.count(said) == 1  # not again among the notes
    assert metrics["selected_on_split"] == 1.0

    printed, report, metrics = _evaluated(last, data, tmp_path / "last", capsys)
    assert "optimistic" not in printed and "optimistic" not in report.lower()
    assert metrics["selected_on_split"] == 0.0
    printed, report, metrics = _evaluated(
        best, data, tmp_path / "train", capsys, "--split", "train"
    )
    assert "optimistic" not in printed and metrics["selected_on_split"] == 0.0

    # Every item of the dataset holds the 2 validation fabrics among its 6: said as such.
    cfg = EvalConfig(n_boot=0, sampled=False, max_presses=1, background_control=False)
    every = evaluate_checkpoint(best, data, "all", cfg)
    assert every.metrics["selected_on_split"] == 1.0
    assert summary_lines(every)[1].startswith(
        "  Note: 2 of these 6 test fabrics are the run's validation fabrics, on which this "
        "checkpoint (best.pt, step 20) was chosen"
    )


def test_which_checkpoint_counts_as_chosen_and_on_what(run: tuple[Path, Path], tmp_path: Path):
    """best.pt records the score it was chosen by (session 54), so a renamed copy is known too;
    an older best.pt by its name; with a run that validated. A seen run was chosen on its
    held-out items, not on its training fabrics as such."""
    import shutil

    from lookfeel.evaluate.from_checkpoint import _chosen_on

    data, last = run
    catalog = scan(data)
    loaded = load_model(last.parent / "best.pt")
    val = catalog.subset(loaded.split["val"])
    chosen = _chosen_on(loaded, catalog, val, "val")
    assert chosen == {"shared": 2, "of": 2, "unit": "fabrics", "step": 20}
    assert _chosen_on(loaded, catalog, catalog.subset(loaded.split["train"]), "train") is None
    assert loaded.chosen_by == "val/touch_to_depth_top1" and load_model(last).chosen_by is None
    assert _chosen_on(load_model(last), catalog, val, "val") is None
    renamed = load_model(shutil.copyfile(last.parent / "best.pt", tmp_path / "model.pt"))
    assert _chosen_on(renamed, catalog, val, "val") == chosen
    older = dataclasses.replace(loaded, chosen_by=None)  # a best.pt of before session 54
    assert _chosen_on(older, catalog, val, "val") == chosen
    assert (
        _chosen_on(dataclasses.replace(older, path=tmp_path / "model.pt"), catalog, val, "val")
        is None
    )
    no_val = dataclasses.replace(loaded, split={**loaded.split, "val": []})
    assert _chosen_on(no_val, catalog, val, "val") is None  # train.split=none: no best.pt

    fabric = catalog.subset([loaded.split["train"][0]])
    items = [it for m in fabric.modalities for it in fabric.items(m)]
    held = [str(it.path) for it in items[::2]]
    seen = dataclasses.replace(loaded, split={"kind": "seen", "val": [], "val_items": held})
    assert _chosen_on(seen, catalog, fabric, "val") == {
        "shared": len(held),
        "of": len(items),
        "unit": "items",
        "step": 20,
    }


def _result_with_controls():
    """Three fabrics' embeddings scored, then given the background control's keys: the model's
    and raw pixels' swapped scores, each with an interval, all different numbers."""
    rng = np.random.default_rng(0)
    centres = rng.standard_normal((3, 4))
    f = np.repeat(np.arange(3), 4)
    emb = {m: centres[f] + 0.3 * rng.standard_normal((12, 4)) for m in (D, T)}
    r = evaluate_embeddings(
        embedded_from_arrays(emb, {m: f + 1 for m in emb}), EvalConfig(n_boot=20, sampled=False)
    )
    m = dict(r.metrics)
    m |= {
        "depth_to_depth_top1_swapped": 0.411,
        "depth_to_depth_top1_swapped_ci_low": 0.301,
        "depth_to_depth_top1_swapped_ci_high": 0.521,
        "depth_to_depth_raw_pixels_top1": 0.917,
        "depth_to_depth_raw_pixels_top1_ci_low": 0.833,
        "depth_to_depth_raw_pixels_top1_ci_high": 0.999,
        "depth_to_depth_raw_pixels_top1_swapped": 0.622,
        "depth_to_depth_raw_pixels_top1_swapped_ci_low": 0.512,
        "depth_to_depth_raw_pixels_top1_swapped_ci_high": 0.732,
        "touch_to_depth_top1_swapped": 0.355,
        "touch_to_depth_top1_swapped_ci_low": 0.255,
        "touch_to_depth_top1_swapped_ci_high": 0.455,
    }
    return dataclasses.replace(r, metrics=m)


@pytest.mark.filterwarnings("ignore:pick 10")
def test_each_printed_control_says_whose_number_it_is_with_its_interval():
    """QA: the printed line read ``... raw pixels 0.917 [0.833, 1.000]  background swapped
    0.750``: the model's swapped score, read as raw pixels', with no interval, and raw pixels'
    own swapped score (in metrics.json and report.md) never printed. Now the model's controls
    stand with the model and raw pixels' with raw pixels, each with its interval."""
    r = _result_with_controls()
    lines = summary_lines(r)
    i = next(k for k, x in enumerate(lines) if x.startswith("  depth_to_depth "))
    own, model, raw = lines[i], lines[i + 1].strip(), lines[i + 2].strip()
    assert own.startswith("  depth_to_depth   top-1 ") and "swapped" not in own
    assert model == "model, background swapped 0.411 [0.301, 0.521]"
    assert raw == "raw pixels 0.917 [0.833, 0.999], background swapped 0.622 [0.512, 0.732]"
    j = next(k for k, x in enumerate(lines) if x.startswith("  touch_to_depth "))
    assert lines[j + 1].strip() == "model, background swapped 0.355 [0.255, 0.455]"
    assert "raw pixels" not in " ".join(lines[j:])  # across senses: none
    # A pair with nothing beside it keeps one line.
    k = next(k for k, x in enumerate(lines) if x.startswith("  touch_to_touch "))
    assert k + 1 == len(lines) or not lines[k + 1].startswith(" " * 19)


def _probed(n_test: int, tmp_path: Path) -> tuple[str, dict[str, float]]:
    """The Physical properties section, and metrics, of ``n_test`` test fabrics whose label
    the embedding encodes, probed from 8 reference fabrics."""
    rng = np.random.default_rng(1)
    n = n_test + 8
    centres = rng.standard_normal((n, 4))
    f = np.repeat(np.arange(n), 3)
    emb = centres[f] + 0.01 * rng.standard_normal((len(f), 4))
    test, ref = f < n_test, f >= n_test
    embedded = embedded_from_arrays({D: emb[test]}, {D: f[test] + 1})
    reference = embedded_from_arrays({D: emb[ref]}, {D: f[ref] + 1})
    labels = {i + 1: [float(centres[i] @ np.arange(1.0, 5.0))] for i in range(n)}
    r = evaluate_embeddings(
        embedded,
        EvalConfig(n_boot=0, sampled=False, probes=("ridge",)),
        labels=labels,
        label_names=["x"],
        reference=reference,
    )
    report = write_report(r, tmp_path / f"r{n_test}").report.read_text(encoding="utf-8")
    return report.split("## Physical properties")[1].split("\n## ")[0], r.metrics


@pytest.mark.filterwarnings("ignore:pick 10")
def test_no_spearman_over_too_few_test_fabrics_and_each_score_says_how_many(tmp_path: Path):
    """QA: the report's property table printed a Spearman over 2 test fabrics (+1 or -1
    whatever the probe predicts) with no word, where `lookfeel cv` shows none under
    MIN_SPEARMAN. Now it shows none either, says why under the table, and says over how many
    test fabrics each R² and Spearman is."""
    from lookfeel.evaluate.report import SPEARMAN_MARK

    section, m = _probed(2, tmp_path)
    assert abs(m["property_depth_x_ridge_spearman"]) == pytest.approx(1.0)  # what was printed
    assert m["property_depth_x_ridge_n_test"] == 2.0
    row = next(x for x in section.splitlines() if x.startswith("| depth | x | ridge |"))
    cells = [c.strip() for c in row.strip("|").split("|")]
    assert cells[4] == f"n/a {SPEARMAN_MARK}" and cells[-1] == "8 / 2"
    assert "1.000" not in cells[4]
    assert f"{SPEARMAN_MARK} Not shown: a Spearman over fewer than {MIN_SPEARMAN} test fabrics" in (
        section
    )
    assert "Each R², Spearman and MAE is over the test fabrics with that label: 2 test " in section
    assert "| fabrics train / test |" in section

    section, m = _probed(MIN_SPEARMAN, tmp_path)
    row = next(x for x in section.splitlines() if x.startswith("| depth | x | ridge |"))
    cells = [c.strip() for c in row.strip("|").split("|")]
    assert math.isfinite(m["property_depth_x_ridge_spearman"])
    assert cells[4] == f"{m['property_depth_x_ridge_spearman']:.3f}"
    assert SPEARMAN_MARK not in section
    assert f"with that label: {MIN_SPEARMAN} test fabrics here" in section


def test_the_fabric_accuracy_of_the_calibration_has_its_interval(tmp_path: Path):
    """QA: the calibration table's fabric accuracy stood beside its chance with no interval,
    though every pick score had one."""
    rng = np.random.default_rng(1)
    centres = rng.standard_normal((6, 4))
    f = np.repeat(np.arange(6), 4)
    emb = {m: centres[f] + 0.8 * rng.standard_normal((24, 4)) for m in (D, T)}
    arrays = embedded_from_arrays(emb, {m: f + 1 for m in emb})
    r = evaluate_embeddings(arrays, EvalConfig(n_boot=200, sampled=False, c=1.0))
    key = "touch_to_depth_fabric_accuracy"
    low, acc, high = (r.metrics[k] for k in (f"{key}_ci_low", key, f"{key}_ci_high"))
    assert 0.0 <= low < acc < high <= 1.0
    row = next(
        line
        for line in write_report(r, tmp_path / "r").report.read_text(encoding="utf-8").splitlines()
        if line.startswith("| touch → depth | 1 | fixed |")  # the calibration table's row
    )
    assert f"{acc:.3f} [{low:.3f}, {high:.3f}]" in row
    none = evaluate_embeddings(arrays, EvalConfig(n_boot=0, sampled=False, c=1.0))
    assert math.isnan(none.metrics[f"{key}_ci_low"])
