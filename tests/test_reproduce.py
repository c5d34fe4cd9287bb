"""`lookfeel reproduce`: runs, skips with reasons, resumes, and reports beside the paper."""

import json
import re
import shutil
from pathlib import Path

import pytest

from lookfeel.cli import main
from lookfeel.config import ConfigError
from lookfeel.reproduce import TABLE_4, reproduce
from lookfeel.reproduce.report import findings

from ._tiny import write_tiny_dataset

FAST = ["train.steps=3", "train.batch_size=8"]


@pytest.fixture(scope="module")
def data(tmp_path_factory: pytest.TempPathFactory) -> Path:
    root = tmp_path_factory.mktemp("rep") / "data"
    return write_tiny_dataset(root, fabrics=10, drapes=5, fold_presses=4, flat_presses=2)


def test_runs_reports_and_resumes(data: Path, tmp_path: Path):
    out = tmp_path / "out"
    only = ["cross_modal", "snn_depth"]
    result = reproduce(
        data, out, budget="tiny", only=only, n_boot=50, overrides=FAST, log=lambda s: None
    )
    assert set(result.results) == set(only)
    metrics = result.results["cross_modal"]["metrics"]
    assert 0.0 <= metrics["touch_to_depth_top1"] <= 1.0
    assert metrics["touch_to_depth_top1_chance"] == pytest.approx(1 / 3)  # 3 held-out fabrics
    assert set(result.results["snn_depth"]) >= {"seen", "novel"}
    report = result.report.read_text()
    row = r"\| depth_to_touch \| - \(0\.306\) \| \d\.\d{3} \[[\d., ]+\] \(0\.429\) \|"
    assert re.search(row, report)  # not run: the paper's number alone; run: ours beside it
    assert f"({TABLE_4['snn_depth']['novel_top1']:.3f})" in report
    assert result.findings["model_order"]["verdict"] == "not tested"
    snn = result.results["snn_depth"]  # 3 novel fabrics: top-3 of 3 candidates is always 1
    assert snn["novel"]["n_effective"] == 3 and snn["novel"]["top3_chance"] == 1.0
    assert "top-3 of 3 candidates is always 1" in report
    assert snn["not_scored"] == {  # one of 5 depth images per fabric held out
        "seen": "no seen fabric has two depth images in the held-out fifth of its images, one "
        "to query and one to find"
    }
    held = result.results["cross_modal"]["test_fabric_ids"]
    assert len(held) == 3 and snn["test_fabric_ids"] == held and snn["seen_fabrics"] == 7
    assert f"Tables 1-3 score on 3 fabrics ({', '.join(map(str, held))}) held out" in report
    assert "the data marks no fabric paper_split=test" in report
    text = (out / "results.json").read_text()
    assert "NaN" not in text and "null" in text  # a number not measured is JSON's null
    saved = json.loads(text)
    assert saved["meta"]["budget"] == "tiny" and saved["meta"]["overrides"] == FAST
    assert saved["meta"]["paper_test_fabrics"] == 0
    evals = sorted(out.glob("runs/*/seed0/eval.json"))
    assert len(evals) == 2
    stamps = [p.stat().st_mtime_ns for p in evals]
    again = reproduce(
        data, out, budget="tiny", only=only, n_boot=50, overrides=FAST, log=lambda s: None
    )
    assert [p.stat().st_mtime_ns for p in evals] == stamps  # finished runs are not redone
    assert json.dumps(again.results) == json.dumps(result.results)  # NaN-safe equality


def test_runs_the_data_cannot_serve_are_skipped_with_reasons(data: Path, tmp_path: Path):
    depth_only = tmp_path / "depth_only"
    shutil.copytree(data / "depth", depth_only / "depth")
    shutil.copy(data / "labels.csv", depth_only / "labels.csv")
    result = reproduce(
        depth_only, tmp_path / "o", budget="tiny", n_boot=20, overrides=FAST, log=lambda s: None
    )
    assert set(result.results) == {"snn_depth"}
    assert result.skipped["multi_input"] == "needs color, touch; the data has depth"
    assert "- `cross_modal_depth_touch`: needs touch" in result.report.read_text()


def test_runs_pooling_more_presses_than_a_fabric_has_are_skipped_with_reasons(tmp_path: Path):
    """The Multi-input Net pools 3 fold presses into a touch input; with 2 a fabric its touch
    inputs cannot be formed, so it is skipped before training, as a missing modality is."""
    two = write_tiny_dataset(tmp_path / "two", fabrics=10, drapes=2, fold_presses=2)
    lines: list[str] = []
    args = dict(budget="tiny", n_boot=20, overrides=FAST, log=lines.append)
    result = reproduce(two, tmp_path / "o", only=["multi_input", "multi_input_aug"], **args)
    reason = (
        "pools 3 fold touch presses of one fabric into each touch input (data.presses); "
        "the data has at most 2 per fabric"
    )
    assert result.skipped == {"multi_input": reason, "multi_input_aug": reason}
    assert not result.results and not (tmp_path / "o" / "runs").exists()  # nothing trained
    assert f"skip multi_input: {reason}" in lines
    report = result.report.read_text()
    assert f"- `multi_input`: {reason}" in report
    assert "**No run was made**" in report and "held-out fabrics" not in report
    assert json.loads((tmp_path / "o" / "results.json").read_text())["skipped"] == result.skipped


def test_a_pair_the_held_out_fabrics_cannot_score_is_na_with_its_reason(data: Path, tmp_path):
    """QA: Table 2's Multi-input touch to touch read "n/a (0.935)" with no reason: each of
    the fixture's fabrics has 4 fold presses, one touch input of 3, so no second to find."""
    out = tmp_path / "out"
    args = dict(budget="tiny", n_boot=20, overrides=FAST, log=lambda s: None)
    result = reproduce(data, out, only=["multi_input"], **args)
    why = (
        "each touch input pools 3 fold presses of one fabric, and no held-out fabric has 6 to "
        "make a second input for a query to find"
    )
    assert result.results["multi_input"]["not_scored"] == {"touch_to_touch": why}
    report = result.report.read_text()
    assert "| n/a^1 (0.935) |" in report and f"- ^1 multi_input touch_to_touch: {why}." in report
    saved = json.loads((out / "results.json").read_text())
    assert saved["results"]["multi_input"]["not_scored"] == {"touch_to_touch": why}
    # 3 held-out fabrics: no finding gets a verdict, in the JSON as in the report.
    tested = [f for f in saved["findings"].values() if f["verdict"] != "not tested"]
    assert tested and all(f["verdict"] == "too few fabrics" for f in tested)
    assert all(f["fabrics"] == 3 for f in tested)
    assert "| **too few fabrics (3)** |" in report and "| **holds** |" not in report

    # An eval.json of an earlier lookfeel recorded no reasons: the resumed report showed a
    # generic one. It is derived from the run's config.yaml, else said to be unrecorded.
    done = out / "runs" / "multi_input" / "seed0" / "eval.json"
    old = json.loads(done.read_text())
    del old["not_scored"]
    done.write_text(json.dumps(old))
    again = reproduce(data, out, only=["multi_input"], **args)
    assert again.results["multi_input"]["not_scored"] == {"touch_to_touch": why}
    (done.parent / "config.yaml").unlink()
    again = reproduce(data, out, only=["multi_input"], **args)
    assert again.results["multi_input"]["not_scored"] == {}
    assert (
        "- ^1 multi_input touch_to_touch: reason not recorded (computed by an earlier "
        "lookfeel): delete the run's eval.json and rerun to record it."
    ) in again.report.read_text()


def test_one_item_per_held_out_fabric_is_not_scored_with_its_reason(monkeypatch):
    """QA: a world of one depth image per fabric leaves depth to depth nothing to find; the
    pair is NaN with its reason, not a number or a crash."""
    import numpy as np

    import lookfeel.reproduce.run as run
    from lookfeel.config import RunConfig, load_config
    from lookfeel.embedding import EmbeddedItems
    from lookfeel.modality import Modality

    def embedded(model, catalog, loader, modalities=None):
        rng = np.random.default_rng(0)
        depth = rng.normal(size=(4, 8)).astype(np.float32)  # one image of each of 4 fabrics
        color = rng.normal(size=(8, 8)).astype(np.float32)  # two of each
        return {
            Modality.DEPTH: EmbeddedItems(Modality.DEPTH, depth, np.arange(4), ()),
            Modality.COLOR: EmbeddedItems(Modality.COLOR, color, np.arange(8) // 2, ()),
        }

    monkeypatch.setattr(run, "embed_catalog", embedded)
    config = load_config(
        RunConfig, run.config_dir() / "cross_modal.yaml", list(run.BUDGETS["tiny"])
    )
    metrics, why = run._score(None, None, config, n_boot=0, seed=0)
    assert why == {
        "depth_to_depth": "no held-out fabric has a second depth item for a query to find"
    }
    assert metrics["depth_to_depth_top1"] != metrics["depth_to_depth_top1"]  # NaN
    assert 0 <= metrics["color_to_color_top1"] <= 1 and 0 <= metrics["depth_to_color_top1"] <= 1


def test_held_out_fabrics_without_enough_presses_are_named():
    import numpy as np

    from lookfeel.data import DatasetError
    from lookfeel.reproduce.run import _pooled

    emb, fabric = np.ones((5, 4)), np.array([3, 3, 7, 7, 8])
    _, ids = _pooled(emb, fabric, 2, seed=0)
    assert ids.tolist() == [3, 7]  # fabric 8's single press is left out
    with pytest.raises(DatasetError) as e:
        _pooled(emb, fabric, 3, seed=0)
    assert str(e.value) == (
        "touch inputs pool 3 presses of one fabric (data.presses), but none of the 3 "
        "held-out fabrics has 3: fabric 3 has the most, 2"
    )


def test_findings_logic_on_hand_made_results():
    def model(td: float, tc: float) -> dict:
        return {"metrics": {"touch_to_depth_top1": td, "touch_to_color_top1": tc}}

    results = {
        "multi_input": model(0.5, 0.4),
        "auxiliary": model(0.45, 0.41),
        "cross_modal": model(0.43, 0.3),
        "flat": model(0.3, 0.2),
        "snn_depth": {"novel": {"top1": 0.55}, "seen": {"top1": float("nan")}},
        "cross_modal_depth_touch": {"novel": {"top1": 0.6}, "seen": {"top1": 0.6}},
    }
    f = findings(results)
    assert f["model_order"]["verdict"] == "holds"
    assert f["depth_beats_color"]["verdict"] == "holds"
    assert f["augmentation_helps_color"]["verdict"] == "not tested"
    assert f["touch_helps_depth"]["verdict"] == "holds"
    assert f["touch_helps_depth"]["detail"] == "novel: SNN 0.550 vs joint 0.600"
    results["flat"] = model(0.44, 0.2)
    assert findings(results)["model_order"]["verdict"] == "does not hold"


def test_findings_are_decided_only_beyond_the_intervals():
    """A comparison counts when the two 95% intervals do not overlap: at chance, with
    overlapping intervals, a finding is noise whichever way its numbers point."""

    def model(td: tuple[float, float, float], tc: tuple[float, float, float]) -> dict:
        m = {}
        for pair, (v, lo, hi) in (("touch_to_depth", td), ("touch_to_color", tc)):
            m |= {f"{pair}_top1": v, f"{pair}_top1_ci_low": lo, f"{pair}_top1_ci_high": hi}
        for pair in ("color_to_touch", "depth_to_color", "color_to_depth"):
            m |= {f"{pair}_top1": 0.1, f"{pair}_top1_ci_low": 0.07, f"{pair}_top1_ci_high": 0.13}
        return {"metrics": m}

    chance = (0.10, 0.07, 0.13)
    results = {
        "multi_input": model((0.12, 0.09, 0.15), chance),
        "auxiliary": model((0.11, 0.08, 0.14), chance),
        "cross_modal": model((0.10, 0.07, 0.13), chance),
        "flat": model((0.09, 0.06, 0.12), chance),
        "cross_modal_aug": model((0.10, 0.07, 0.13), (0.104, 0.074, 0.134)),
        "multi_input_aug": model((0.12, 0.09, 0.15), (0.104, 0.074, 0.134)),
        "snn_depth": {"novel": {"top1": 0.46, "top1_ci_low": 0.41, "top1_ci_high": 0.51}},
        "cross_modal_depth_touch": {
            "novel": {"top1": 0.28, "top1_ci_low": 0.24, "top1_ci_high": 0.33}
        },
    }
    f = findings(results)
    # Every number points the paper's way, inside each other's intervals.
    assert f["model_order"]["verdict"] == "within noise"
    assert f["model_order"]["detail"].endswith("(95% intervals overlap)")
    assert f["depth_beats_color"]["verdict"] == "within noise"
    assert f["augmentation_helps_color"]["verdict"] == "within noise"
    # The joint net is below the SNN beyond both intervals.
    assert f["touch_helps_depth"]["verdict"] == "does not hold"

    results["multi_input"] = model((0.50, 0.45, 0.55), (0.30, 0.25, 0.35))
    results["auxiliary"] = model((0.40, 0.35, 0.44), (0.20, 0.15, 0.25))
    results["cross_modal"] = model((0.30, 0.26, 0.34), (0.15, 0.10, 0.20))
    results["flat"] = model((0.20, 0.15, 0.25), (0.10, 0.07, 0.13))
    f = findings(results)
    assert f["model_order"]["verdict"] == "holds"
    assert f["depth_beats_color"]["verdict"] == "holds"


def test_bad_requests(data: Path, tmp_path: Path, capsys):
    with pytest.raises(ConfigError, match="needs the ImageNet weights"):
        reproduce(data, tmp_path, budget="paper")
    with pytest.raises(ConfigError, match="unknown experiment.* nope"):
        reproduce(data, tmp_path, only=["nope"])
    assert (
        main(["reproduce", "--data", str(data), "--out", str(tmp_path), "--budget", "paper"]) == 1
    )
    assert "--pretrained" in capsys.readouterr().err
    args = ["reproduce", "--data", str(data), "--out", str(tmp_path / "w"), "--workers", "-1"]
    assert main(args) == 1
    err = capsys.readouterr().err
    assert "workers must be >= 0" in err and "Traceback" not in err
    assert not (tmp_path / "w").exists()  # refused before anything is written


def test_runs_side_by_side_in_workers_give_the_numbers_of_one_process(
    data: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
):
    import torch

    import lookfeel.reproduce.run as run

    monkeypatch.setattr(run, "available_cores", lambda: 2)  # 2 workers of 1 thread each
    only = ["cross_modal", "snn_depth", "cross_modal_depth_touch"]
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        alone = reproduce(
            data,
            tmp_path / "alone",
            "tiny",
            only=only,
            n_boot=50,
            overrides=FAST,
            log=lambda s: None,
            workers=1,
        )
    finally:
        torch.set_num_threads(threads)
    # One run already finished (copied from the run in this process), two to train side by side.
    shutil.copytree(
        tmp_path / "alone" / "runs" / "snn_depth", tmp_path / "side" / "runs" / "snn_depth"
    )
    lines: list[str] = []
    side = reproduce(
        data, tmp_path / "side", "tiny", only=only, n_boot=50, overrides=FAST, log=lines.append
    )
    cites = {e.name: e.cites for e in run.EXPERIMENTS}
    assert sorted(lines) == sorted(f"run  {n} seed 0 ({cites[n]})" for n in only)  # as they start
    assert list(side.results) == only  # the experiments' order, whichever finished first
    assert json.dumps(side.results) == json.dumps(alone.results)
    for name in ("cross_modal", "cross_modal_depth_touch"):  # trained in the workers
        record = json.loads((tmp_path / "side" / "runs" / name / "seed0" / "eval.json").read_text())
        assert record["threads"] == 1


def test_the_weights_file_is_a_path_not_yaml(tmp_path: Path, monkeypatch):
    """Under the paper budget every run names the weights file by its absolute path, as given
    (a name with ``: `` would be a YAML mapping)."""
    from lookfeel.config import RunConfig, load_config
    from lookfeel.reproduce.run import EXPERIMENTS, config_dir, experiment_overrides

    monkeypatch.chdir(tmp_path)
    exp = EXPERIMENTS[0]
    overrides = experiment_overrides(exp, "paper", [], [], pretrained="w/a: b.pth")
    config = load_config(RunConfig, config_dir() / f"{exp.name}.yaml", overrides)
    assert config.model.pretrained == str(tmp_path / "w" / "a: b.pth")


def test_the_report_says_what_it_measured(tmp_path: Path):
    """QA: the evidence printed ">" between numbers in the wrong order, NaN cells read "nan",
    Table 4 gave one chance for both sides and no interval, and the verdicts were defined only
    in the README."""
    from lookfeel.reproduce.report import write_reproduction_report
    from lookfeel.reproduce.result import ReproduceResult

    def model(td: float, tt: float) -> dict:
        return {"metrics": {"touch_to_depth_top1": td, "touch_to_touch_top1": tt}}

    nan = float("nan")
    novel = {"top1": 0.7, "top3": 0.99, "chance": 1 / 6, "top1_ci_low": 0.5, "top1_ci_high": 0.9}
    results = {
        "multi_input": model(0.30, nan),  # one group of presses per fabric: nothing to find
        "auxiliary": model(0.20, 0.5),
        "cross_modal": model(0.10, 0.5),
        "flat": model(0.12, 0.5),
        "snn_depth": {"seen": {"top1": nan, "top3": nan, "chance": 0.1}, "novel": novel,
                      "test_fabrics": 6},
    }  # fmt: skip
    result = ReproduceResult(tmp_path, tmp_path / "report.md", results, {}, findings(results))
    meta = {"data": "w", "budget": "tiny", "seeds": 1, "split": "paper", "minutes": 1.0}
    write_reproduction_report(result, meta)
    report = result.report.read_text()
    order = result.findings["model_order"]["detail"]
    assert order == (
        "in the paper's order: multi_input 0.300, auxiliary 0.200, cross_modal 0.100, flat 0.120"
    )
    assert "| touch_to_touch | - (" not in report and "| n/a^1 (" in report and "nan" not in report
    assert "| snn_depth | n/a^1 (0.482) | n/a^1 (0.660) | 0.700 [0.50, 0.90] (0.554) |" in report
    assert "| chance | 0.100 | 0.300 | 0.167 | 0.500 |" in report  # each side's, top-1 and top-3
    assert "It **holds** when every comparison goes the paper's way" in report


def _report(tmp_path: Path, results: dict, meta: dict, skipped: dict | None = None) -> str:
    """The report of hand-made results (``meta``: beside the data, budget, seeds, minutes)."""
    from lookfeel.reproduce.report import write_reproduction_report
    from lookfeel.reproduce.result import ReproduceResult

    result = ReproduceResult(
        tmp_path, tmp_path / "report.md", results, skipped or {}, findings(results)
    )
    write_reproduction_report(
        result, {"data": "w", "budget": "tiny", "seeds": 1, "minutes": 1.0} | meta
    )
    return result.report.read_text()


def test_cells_without_a_number_say_why_and_top_k_of_k_is_not_a_score(tmp_path: Path):
    """QA: Table 2's Multi-input touch to touch read "n/a (0.935)" with no reason (the only
    legend, under Table 4, gave another), and Table 4 showed novel top-3 "1.000" over 2 novel
    fabrics, where top-3 of 2 is 1 whatever the model, with no chance for either side."""
    nan = float("nan")
    why = "each touch input pools 3 fold presses of one fabric, and no held-out fabric has 6"
    depth = "no held-out fabric has a second depth item for a query to find"
    novel = {
        "top1": 0.64,
        "top3": 1.0,
        "chance": 0.5,
        "top3_chance": 1.0,
        "n_effective": 2.0,
        "n_queries": 6.0,
        "n_fabrics": 2.0,
        "top1_ci_low": 0.56,
        "top1_ci_high": 0.72,
    }
    seen = {
        "top1": nan,
        "top3": nan,
        "chance": 0.1,
        "top3_chance": 0.3,
        "n_effective": 10.0,
        "n_queries": 0.0,
        "n_fabrics": 0.0,
    }
    results = {
        "multi_input": {
            "metrics": {"touch_to_touch_top1": nan, "depth_to_depth_top1": nan},
            "not_scored": {"touch_to_touch": why, "depth_to_depth": depth},
        },
        "flat": {"metrics": {"depth_to_depth_top1": nan}, "not_scored": {"depth_to_depth": depth}},
        "snn_depth": {"seen": seen, "novel": novel, "test_fabrics": 2,
                      "not_scored": {"seen": "no seen fabric has two depth images"}},
    }  # fmt: skip
    report = _report(tmp_path, results, {"split": "paper", "paper_test_fabrics": 2})
    table_2 = report[report.index("## Table 2") : report.index("## Table 3")]
    assert "| depth_to_depth | n/a^1 (0.603) | - (0.626) | - (0.622) | n/a^1 (0.646) |" in table_2
    assert "| touch_to_touch | - (0.802) | - (0.767) | - (0.809) | n/a^2 (0.935) |" in table_2
    assert f"- ^1 flat depth_to_depth, multi_input depth_to_depth: {depth}." in table_2
    assert f"- ^2 multi_input touch_to_touch: {why}." in table_2
    table_4 = report[report.index("## Table 4") :]
    assert (
        "| snn_depth | n/a^1 (0.482) | n/a^1 (0.660) | 0.640 [0.56, 0.72] (0.554) | n/a^2 (0.729) |"
        in table_4
    )
    assert "| chance | 0.100 | 0.300 | 0.500 | 1.000 |" in table_4
    assert "| fabrics / queries | 0 / 0 | 0 / 0 | 2 / 6 | 2 / 6 |" in table_4
    assert "- ^1 snn_depth seen: no seen fabric has two depth images." in table_4
    assert "- ^2 snn_depth novel top-3: top-3 of 2 candidates is always 1" in table_4
    assert "1.000 (" not in report and "fewer than two held-out items per fabric" not in report


def test_the_report_says_which_fabrics_each_table_scores_and_how_many(tmp_path: Path):
    """QA: over 4 held-out fabrics a cell read 0.019 [0.00, 0.04] with chance 0.250, while the
    report said "over 18 test fabrics an interval is about 0.15 wide" and showed no counts; its
    header did not say that the data's 2 paper_split=test fabrics went unused by Tables 1-3,
    nor that Table 4's novel side scored those 2, not Tables 1-3's 4."""

    def cell(v: float, lo: float, hi: float, fabrics: int, queries: int) -> dict:
        p = "touch_to_color_top1"
        counts = {"touch_to_color_n_fabrics": fabrics, "touch_to_color_n_queries": queries}
        return {p: v, f"{p}_ci_low": lo, f"{p}_ci_high": hi, f"{p}_chance": 0.25} | counts

    held = {"test_fabrics": 4, "test_fabric_ids": [4, 7, 12, 13]}
    results = {
        "cross_modal": {"metrics": cell(0.3, 0.1, 0.5, 4, 12), **held},
        "multi_input_aug": {"metrics": cell(0.019, 0.0, 0.04, 4, 4), **held},
        "snn_depth": {
            "novel": {"top1": 0.6, "top1_ci_low": 0.5, "top1_ci_high": 0.7, "chance": 0.5},
            "test_fabrics": 2, "test_fabric_ids": [5, 9], "seen_fabrics": 12,
        },
    }  # fmt: skip
    meta = {"split": "stratified, 4 held-out fabrics", "paper_test_fabrics": 2}
    report = _report(tmp_path, results, meta)
    assert (
        "- Tables 1-3 score on 4 fabrics (4, 7, 12, 13) held out of the training fabrics "
        "(cluster-stratified); the data's 2 paper_split=test fabrics are not used there "
        "(neither trained on nor scored): the paper's split needs at least 10"
    ) in report
    assert (
        "- Table 4 scores its novel side on the data's 2 fabrics (5, 9) marked "
        "paper_split=test, not the 4 that Tables 1-3 score on; its seen side on the held-out "
        "fifth of the depth images of each of the 12 fabrics it trains on."
    ) in report
    assert (
        "| touch_to_color | 0.300 [0.10, 0.50] (0.395) | - (0.436) | - (0.430) "
        "| 0.019 [0.00, 0.04] (0.494) | 0.250 | 4 / 4-12 |"
    ) in report  # Table 3, with the fabrics and queries behind its numbers
    assert "18 test fabrics" not in report
    assert (
        "here they rest on 4 test fabrics (Tables 1-3) and 2 (Table 4's novel side) and are on "
        "average 0.21 wide"  # (0.4 + 0.04 + 0.2) / 3
    ) in report
    assert (
        "under 10, they say little, and the findings that rest on them get no verdict "
        "(too few fabrics)"
    ) in report
    assert "below 10 test fabrics they say little" in report

    for run in ("cross_modal", "multi_input_aug"):
        results[run] |= {"test_fabrics": 18, "test_fabric_ids": list(range(101, 119))}
    del results["snn_depth"]
    report = _report(tmp_path, results, {"split": "paper", "paper_test_fabrics": 18})
    assert "- Tables 1-3 score on the data's 18 fabrics (101, " in report
    assert "marked paper_split=test (the paper's split)." in report
    assert "here they rest on 18 test fabrics (Tables 1-3) and are on average" in report
    assert "say little" not in report

    report = _report(tmp_path, {}, meta, skipped={"flat": "needs touch"})
    assert "**No run was made**: every experiment asked for was skipped" in report
    assert "Tables 1-3 score" not in report and "stratified" not in report


def test_above_chance_is_the_papers_first_finding():
    """Section 5.1: "all the networks can predict the matching images better than average
    chance", checked on every cell of Figure 7 beyond its interval."""

    def model(lo: float, hi: float) -> dict:
        m = {}
        for pair in ("touch_to_depth", "touch_to_color"):
            m |= {f"{pair}_top1": (lo + hi) / 2, f"{pair}_top1_ci_low": lo}
            m |= {f"{pair}_top1_ci_high": hi, f"{pair}_top1_chance": 0.1}
        return {"metrics": m}

    results = {m: model(0.2, 0.4) for m in ("flat", "cross_modal", "auxiliary", "multi_input")}
    f = findings(results)
    assert next(iter(f)) == "above_chance" and f["above_chance"]["verdict"] == "holds"
    assert f["above_chance"]["detail"] == "8 of 8 cells above chance beyond their interval"
    results["flat"] = model(0.05, 0.2)  # its interval holds chance
    f = findings(results)["above_chance"]
    assert f["verdict"] == "within noise"
    assert "6 of 8 cells above chance" in f["detail"]
    assert "not: flat touch_to_depth 0.125 (chance 0.100)" in f["detail"]
    assert findings({})["above_chance"]["verdict"] == "not tested"


def test_depth_over_colour_reads_both_ways_and_within_over_across():
    """Section 5.1: touch matches depth better than colour as the query (Figure 7) and as the
    candidates (Table 1); matching within a modality (Table 2) is much higher than across."""

    def model(**top1: float) -> dict:
        return {"metrics": {f"{pair}_top1": v for pair, v in top1.items()}}

    across = {"touch_to_depth": 0.4, "touch_to_color": 0.3, "depth_to_touch": 0.4}
    results = {"cross_modal": model(**across, color_to_touch=0.5, depth_to_depth=0.8)}
    f = findings(results)
    # As the query depth wins, as the candidates colour does: against the paper.
    assert f["depth_beats_color"]["verdict"] == "does not hold"
    assert f["depth_beats_color"]["detail"] == (
        "cross_modal touch_to_depth 0.400 vs touch_to_color 0.300; "
        "cross_modal depth_to_touch 0.400 vs color_to_touch 0.500"
    )
    assert f["within_beats_across"]["verdict"] == "holds"
    assert f["within_beats_across"]["detail"] == "cross_modal: within 0.800 vs across 0.400 (means)"
    assert findings({})["within_beats_across"]["verdict"] == "not tested"


def test_the_headline_says_n_a_for_a_cell_that_could_not_be_scored():
    from lookfeel.reproduce.run import headline

    lines = headline(
        {
            "flat": {"metrics": {"touch_to_depth_top1": 0.25, "touch_to_depth_top1_chance": 0.1}},
            "snn_depth": {"novel": {"top1": float("nan")}},
            "cross_modal_depth_touch": {"novel": {"top1": None}},
        }
    )
    assert lines == [
        "flat         touch->depth top-1 0.250 (chance 0.100)",
        "snn_depth    depth->depth top-1 on novel fabrics n/a",
        "cross_modal_depth_touch depth->depth top-1 on novel fabrics n/a",
    ]


def test_an_old_eval_json_s_reasons_are_derived_from_what_is_stored(tmp_path: Path):
    """Table 4's sides need only their name; a pair needs the run's config.yaml (the presses
    its touch inputs pool); without it no reason is made up."""
    from lookfeel.config import RunConfig, load_config, save_config
    from lookfeel.reproduce.run import BUDGETS, _old_reasons, config_dir

    nan = float("nan")
    vision = {"seen": {"top1": nan}, "novel": {"top1": 0.4}}
    assert _old_reasons(vision, tmp_path) == {
        "seen": "no seen fabric has two depth images in the held-out fifth of its images, one "
        "to query and one to find"
    }
    record = {"metrics": {"touch_to_touch_top1": nan, "depth_to_depth_top1": nan, "x_top1": 0.5}}
    assert _old_reasons(record, tmp_path) == {}  # no config.yaml: not recorded
    config = load_config(RunConfig, config_dir() / "multi_input.yaml", list(BUDGETS["tiny"]))
    save_config(config, tmp_path / "config.yaml")
    assert _old_reasons(record, tmp_path) == {
        "touch_to_touch": "each touch input pools 3 fold presses of one fabric, and no held-out "
        "fabric has 6 to make a second input for a query to find",
        "depth_to_depth": "no held-out fabric has a second depth item for a query to find",
    }


def test_findings_resting_on_fewer_than_10_fabrics_get_no_verdict(
    tmp_path: Path, capsys, monkeypatch
):
    """QA: over 4 held-out fabrics the findings still read "holds" / "does not hold", with
    only a warning above them. A finding one of whose intervals is over fewer than 10
    fabrics now reads "too few fabrics" with the count; at 10 or more nothing changes."""
    from lookfeel.cli import reproduce as cli

    def model(td: tuple[float, float, float], tc: tuple[float, float, float], n: int) -> dict:
        m = {}
        for pair, (v, lo, hi) in (("touch_to_depth", td), ("touch_to_color", tc)):
            m |= {f"{pair}_top1": v, f"{pair}_top1_ci_low": lo, f"{pair}_top1_ci_high": hi}
            m |= {f"{pair}_top1_chance": 0.05, f"{pair}_n_fabrics": n}
        return {"metrics": m, "test_fabrics": n}

    def side(v: float, n: int) -> dict:
        return {"top1": v, "top1_ci_low": v - 0.02, "top1_ci_high": v + 0.02, "n_fabrics": n}

    def results(n: int, novel: int) -> dict:
        return {
            "multi_input": model((0.50, 0.45, 0.55), (0.30, 0.25, 0.35), n),
            "auxiliary": model((0.40, 0.35, 0.44), (0.20, 0.15, 0.25), n),
            "cross_modal": model((0.30, 0.26, 0.34), (0.15, 0.12, 0.20), n),
            "flat": model((0.20, 0.15, 0.25), (0.10, 0.07, 0.13), n),
            "snn_depth": {"seen": side(0.5, 20), "novel": side(0.4, novel)},
            "cross_modal_depth_touch": {"seen": side(0.6, 20), "novel": side(0.5, novel)},
        }

    many = findings(results(10, 10))
    assert {k: f["verdict"] for k, f in many.items()} == {
        "above_chance": "holds",
        "model_order": "holds",
        "depth_beats_color": "holds",
        "within_beats_across": "not tested",
        "augmentation_helps_color": "not tested",
        "touch_helps_depth": "holds",
    }
    assert all("fabrics" not in f for f in many.values())
    few = findings(results(4, 10))
    for key in ("above_chance", "model_order", "depth_beats_color"):
        assert few[key]["verdict"] == "too few fabrics" and few[key]["fabrics"] == 4
        assert (
            few[key]["detail"]
            == many[key]["detail"] + " (an interval here is over 4 fabrics, under 10)"
        )
    assert few["touch_helps_depth"]["verdict"] == "holds"  # Table 4 rests on 20 and 10
    table_4 = findings(results(10, 2))["touch_helps_depth"]
    assert (table_4["verdict"], table_4["fabrics"]) == ("too few fabrics", 2)
    # The old records without counts are decided as before.
    bare = results(10, 10)
    for row in bare.values():
        row.pop("test_fabrics", None)
        for part in (row.get("metrics", {}), row.get("seen", {}), row.get("novel", {})):
            for key in [k for k in part if "n_fabrics" in k]:
                del part[key]
    assert findings(bare)["model_order"]["verdict"] == "holds"

    report = _report(tmp_path, results(4, 10), {"split": "paper", "paper_test_fabrics": 4})
    assert "| **too few fabrics (4)** |" in report
    assert "**too few fabrics** (how many): no verdict, as an interval it rests on" in report
    assert "too few" not in _report(tmp_path, results(10, 10), {"split": "paper"})

    from lookfeel.reproduce.result import ReproduceResult

    done = ReproduceResult(tmp_path, tmp_path / "report.md", results(4, 10), {}, few)
    monkeypatch.setattr("lookfeel.reproduce.reproduce", lambda *a, **k: done)
    monkeypatch.setattr(cli, "check_out_folder", lambda *a: None)
    assert main(["reproduce", "--data", str(tmp_path), "--out", str(tmp_path / "o")]) == 0
    out = capsys.readouterr().out
    assert "too few fabrics (4): Multi-input > Auxiliary > Cross-modal > Flat" in out
    # Right-aligned to the longest verdict, "too few fabrics (4)" (19 characters).
    assert "\n" + " " * 14 + "holds: joint training with touch improves depth-to-depth" in out
