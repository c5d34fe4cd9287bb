"""`lookfeel reproduce`: runs, skips with reasons, resumes, and reports beside the paper."""

import json
import re
import shutil
from pathlib import Path

import pytest
import yaml

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
    report = result.report.read_text(encoding="utf-8")
    row = r"\| depth_to_touch \| -\^1 \(0\.306\) \| \d\.\d{3} \[[\d., ]+\] \(0\.429\) \|"
    assert re.search(row, report)  # left out: -^1 and the paper's number; run: ours beside it
    assert "seeds: 1; --only: cross_modal, snn_depth; " in report
    assert "- ^1 flat, auxiliary, multi_input: not run (--only cross_modal, snn_depth)." in report
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
    text = (out / "results.json").read_text(encoding="utf-8")
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
    assert "- `cross_modal_depth_touch`: needs touch" in result.report.read_text(encoding="utf-8")


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
    report = result.report.read_text(encoding="utf-8")
    assert f"- `multi_input`: {reason}" in report
    assert "**No run was made**" in report and "held-out fabrics" not in report
    assert (
        json.loads((tmp_path / "o" / "results.json").read_text(encoding="utf-8"))["skipped"]
        == result.skipped
    )


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
    report = result.report.read_text(encoding="utf-8")
    # Table 2's note 1 is the columns --only left out, "-^1".
    assert "| n/a^2 (0.935) |" in report and f"- ^2 multi_input touch_to_touch: {why}." in report
    saved = json.loads((out / "results.json").read_text(encoding="utf-8"))
    assert saved["results"]["multi_input"]["not_scored"] == {"touch_to_touch": why}
    # 3 held-out fabrics: no finding gets a verdict, in the JSON as in the report.
    tested = [f for f in saved["findings"].values() if f["verdict"] != "not tested"]
    assert tested and all(f["verdict"] == "too few fabrics" for f in tested)
    assert all(f["fabrics"] == 3 for f in tested)
    assert "| **too few fabrics (3)** |" in report and "| **holds** |" not in report

    # An eval.json of an earlier lookfeel recorded no reasons: the resumed report showed a
    # generic one. It is derived from the run's config.yaml, else said to be unrecorded.
    done = out / "runs" / "multi_input" / "seed0" / "eval.json"
    old = json.loads(done.read_text(encoding="utf-8"))
    del old["not_scored"]
    done.write_text(json.dumps(old), encoding="utf-8")
    again = reproduce(data, out, only=["multi_input"], **args)
    assert again.results["multi_input"]["not_scored"] == {"touch_to_touch": why}
    (done.parent / "config.yaml").unlink()
    again = reproduce(data, out, only=["multi_input"], **args)
    assert again.results["multi_input"]["not_scored"] == {}
    assert (
        "- ^2 multi_input touch_to_touch: reason not recorded (computed by an earlier "
        "lookfeel): delete the run's eval.json and rerun to record it."
    ) in again.report.read_text(encoding="utf-8")


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
    with pytest.raises(ConfigError, match="workers must be >= 0"):
        reproduce(data, tmp_path / "w", workers=-1)
    with pytest.raises(ConfigError, match="seeds: 1 given more than once"):
        reproduce(data, tmp_path / "w", seeds=[1, 0, 1])
    with pytest.raises(ConfigError, match="seeds: at least one training seed is needed"):
        reproduce(data, tmp_path / "w", seeds=[])
    # The command refuses it first, by the flag's name (argparse's usage error).
    args = ["reproduce", "--data", str(data), "--out", str(tmp_path / "w"), "--workers", "-1"]
    with pytest.raises(SystemExit) as e:
        main(args)
    assert e.value.code == 2
    err = capsys.readouterr().err
    assert err.splitlines()[-1].endswith("argument --workers: must be >= 0, got -1")
    assert "Traceback" not in err
    assert not (tmp_path / "w").exists()  # refused before anything is written


def test_seeds_are_trained_in_the_order_given_and_found_again_by_their_folders(
    data: Path, tmp_path: Path
):
    """QA: ``reproduce --seeds N`` trained seeds 0 to N-1 where ``cv --seeds N`` trains seed
    N. The seeds are a list now, trained in the order given, each in ``runs/NAME/seed{S}`` as
    before: a folder of the older seeds 0 to N-1 resumes, and the older form (an int ``n``:
    seeds 0 to n-1) still reads it."""
    out = tmp_path / "out"
    args = dict(budget="tiny", only=["flat"], n_boot=20, overrides=FAST, workers=1)
    lines: list[str] = []
    result = reproduce(data, out, seeds=[1, 0], log=lines.append, **args)
    started = [ln for ln in lines if ln.startswith("run ")]
    assert [ln.split("(")[0].strip() for ln in started] == ["run  flat seed 1", "run  flat seed 0"]
    for seed in (0, 1):
        saved = yaml.safe_load(
            (out / "runs" / "flat" / f"seed{seed}" / "config.yaml").read_text(encoding="utf-8")
        )
        assert saved["train"]["seed"] == seed
    meta = json.loads((out / "results.json").read_text(encoding="utf-8"))["meta"]
    assert meta["seeds"] == 2 and meta["seed_list"] == [1, 0]
    assert result.results["flat"]["seeds"] == 2
    assert "seeds: 2" in result.report.read_text(encoding="utf-8")
    for older in (1, [0]):  # seed 0 alone: found finished, read back, nothing trained
        lines.clear()
        again = reproduce(data, out, seeds=older, log=lines.append, **args)
        assert not any(ln.startswith("run ") for ln in lines), lines
        assert any(ln.startswith("read flat seed 0") for ln in lines), lines
        assert again.results["flat"]["seeds"] == 1
        # QA (upgrading): the report leaves seed 1 out, and a line says so and how to have it
        assert f"{out} also holds finished runs of seed 1, which --seeds leaves out of the " in (
            "\n".join(lines)
        )
        assert any("(--seeds 0,1 reports them with these;" in ln for ln in lines), lines


def test_the_demo_reproduces_seed_0_alone_as_before(tmp_path: Path, monkeypatch):
    """`make demo`'s reproduction trains seed 0 alone, as its ``seeds=1`` did before
    ``reproduce`` took a list of seeds."""
    import lookfeel.demo as demo
    from lookfeel.reproduce.run import _seed_list

    seen: dict[str, object] = {}

    def fake_reproduce(world: Path, out: Path, **kwargs: object) -> None:
        seen.update(kwargs)
        raise KeyboardInterrupt

    monkeypatch.setattr(demo, "generate", lambda c, w, progress: write_tiny_dataset(w, fabrics=3))
    monkeypatch.setattr(demo, "reproduce", fake_reproduce)
    with pytest.raises(KeyboardInterrupt):
        demo.run_demo(tmp_path / "demo", fabrics=9, log=lambda line: None)
    assert _seed_list(seen["seeds"]) == _seed_list(1) == [0]  # type: ignore[arg-type]
    assert _seed_list(3) == [0, 1, 2]


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
    said = [f"run  {n} seed 0 ({cites[n]})" for n in only if n != "snn_depth"]  # as they start
    said.append(
        f"read snn_depth seed 0 ({cites['snn_depth']}): finished, read back from its eval.json"
    )
    assert sorted(lines) == sorted(said)
    assert list(side.results) == only  # the experiments' order, whichever finished first
    assert json.dumps(side.results) == json.dumps(alone.results)
    for name in ("cross_modal", "cross_modal_depth_touch"):  # trained in the workers
        record = json.loads(
            (tmp_path / "side" / "runs" / name / "seed0" / "eval.json").read_text(encoding="utf-8")
        )
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
    meta = {"data_root": "w", "budget": "tiny", "seeds": 1, "split": "paper", "minutes": 1.0}
    write_reproduction_report(result, meta)
    report = result.report.read_text(encoding="utf-8")
    assert report.splitlines()[2].startswith("Data: `w`; budget: **tiny**; ")
    # results.json's meta as written before the dataset folder was ``data_root``: read alike.
    old = {k: v for k, v in meta.items() if k != "data_root"} | {"data": "w"}
    write_reproduction_report(result, old)
    assert result.report.read_text(encoding="utf-8") == report
    order = result.findings["model_order"]["detail"]
    assert order == (
        "in the paper's order: multi_input 0.300, auxiliary 0.200, cross_modal 0.100, flat 0.120"
    )
    assert "| touch_to_touch | - (" not in report and "| n/a^1 (" in report and "nan" not in report
    assert "| snn_depth | n/a^1 (0.482) | n/a^1 (0.660) | 0.700 [0.50, 0.90] (0.554) |" in report
    # Each side's, top-1 and top-3; none where no query was scored (the seen side here).
    assert "| chance | n/a^1 | n/a^1 | 0.167 | 0.500 |" in report
    assert "It **holds** when every comparison goes the paper's way" in report


def _report(tmp_path: Path, results: dict, meta: dict, skipped: dict | None = None) -> str:
    """The report of hand-made results (``meta``: beside the data, budget, seeds, minutes)."""
    from lookfeel.reproduce.report import write_reproduction_report
    from lookfeel.reproduce.result import ReproduceResult

    result = ReproduceResult(
        tmp_path, tmp_path / "report.md", results, skipped or {}, findings(results)
    )
    write_reproduction_report(
        result, {"data_root": "w", "budget": "tiny", "seeds": 1, "minutes": 1.0} | meta
    )
    return result.report.read_text(encoding="utf-8")


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
    assert "| chance | n/a^1 | n/a^1 | 0.500 | 1.000 |" in table_4  # no seen query: no pick
    assert "| fabrics / queries | 0 / 0 | 0 / 0 | 2 / 6 | 2 / 6 |" in table_4
    assert "- ^1 snn_depth seen, seen chance: no seen fabric has two depth images." in table_4
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
    """And each number with its interval and chance (QA, session 54: depth's had neither)."""
    from lookfeel.reproduce.run import headline

    t2d = {"touch_to_depth_top1": 0.25, "touch_to_depth_top1_chance": 0.1}
    lines = headline(
        {
            "flat": {"metrics": t2d},
            "cross_modal": {
                "metrics": t2d
                | {"touch_to_depth_top1_ci_low": 0.2, "touch_to_depth_top1_ci_high": 0.3}
            },
            "snn_depth": {"novel": {"top1": float("nan"), "chance": 0.25}},
            "cross_modal_depth_touch": {
                "novel": {
                    "top1": 0.556,
                    "chance": 0.25,
                    "top1_ci_low": 0.306,
                    "top1_ci_high": 0.847,
                }
            },
        }
    )
    assert lines == [
        "cross_modal  touch->depth top-1 0.250 [0.200, 0.300] (chance 0.100)",
        "flat         touch->depth top-1 0.250 (chance 0.100)",
        "snn_depth    depth->depth top-1 on novel fabrics n/a (chance 0.250)",
        "cross_modal_depth_touch depth->depth top-1 on novel fabrics 0.556 [0.306, 0.847] "
        "(chance 0.250)",
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


def _cells(**cells: tuple[float, float, float]) -> dict:
    """A run's metrics: each pair's top-1 with its interval (value, low, high)."""
    m = {}
    for pair, (v, lo, hi) in cells.items():
        m |= {f"{pair}_top1": v, f"{pair}_top1_ci_low": lo, f"{pair}_top1_ci_high": hi}
    return {"metrics": m}


def test_findings_on_means_show_their_intervals_and_a_pair_the_other_way(tmp_path: Path):
    """QA: Multi-input's colour to touch fell from 0.127 [0.09, 0.17] to 0.054 [0.03, 0.09]
    with augmentation, intervals apart, while the finding read "within noise ... 0.117 ->
    0.095 (mean of the colour pairs; 1 of 4 up)": the means' intervals were not shown, nor
    the pair that went the other way. The verdict stays the means'."""
    before = {
        "touch_to_color": (0.111, 0.06, 0.17),
        "color_to_touch": (0.127, 0.09, 0.17),
        "depth_to_color": (0.116, 0.05, 0.19),
        "color_to_depth": (0.115, 0.08, 0.16),
    }
    after = {
        "touch_to_color": (0.085, 0.02, 0.16),
        "color_to_touch": (0.054, 0.03, 0.085),
        "depth_to_color": (0.112, 0.05, 0.18),
        "color_to_depth": (0.130, 0.06, 0.22),
    }
    results = {"multi_input": _cells(**before), "multi_input_aug": _cells(**after)}
    f = findings(results)["augmentation_helps_color"]
    assert f["verdict"] == "within noise"  # the means' intervals overlap
    assert f["detail"] == (
        "multi_input: 0.117 [0.07, 0.17] -> 0.095 [0.04, 0.16] with augmentation (means of the "
        "colour pairs; 1 of 4 up, the paper: all; went the other way beyond both intervals: "
        "color_to_touch 0.127 [0.09, 0.17] -> 0.054 [0.03, 0.09]) (the means' 95% intervals "
        "overlap)"
    )
    # Within against across: a within pair below an across one beyond both intervals is named.
    within = {"depth_to_depth": (0.8, 0.7, 0.9), "color_to_color": (0.9, 0.85, 0.95)}
    across = {"touch_to_depth": (0.2, 0.1, 0.3), "depth_to_touch": (0.3, 0.25, 0.35)}
    low = {"touch_to_touch": (0.15, 0.11, 0.19)}
    f = findings({"flat": _cells(**within, **across, **low)})["within_beats_across"]
    assert f["verdict"] == "holds"  # the means' intervals apart
    assert f["detail"] == (
        "flat: within 0.617 [0.55, 0.68] vs across 0.250 [0.17, 0.32] (means; went the other "
        "way beyond both intervals: touch_to_touch 0.150 [0.11, 0.19] below depth_to_touch "
        "0.300 [0.25, 0.35])"
    )
    report = _report(tmp_path, results, {"split": "paper"})
    assert "Two findings compare means over pairs: within against across one modality" in report
    assert "named in the evidence but does not decide the verdict" in report


def test_only_says_which_runs_it_left_out(tmp_path: Path):
    """QA: with --only the findings of the runs left out read "not tested" with "its runs were
    skipped", Table 4's "needs both Table 4 runs (depth and touch data)" (as if the data
    lacked a sense), and their cells "-" unexplained."""
    from lookfeel.reproduce.report import write_reproduction_report
    from lookfeel.reproduce.result import ReproduceResult

    cells = {"touch_to_depth": (0.3, 0.2, 0.4), "touch_to_color": (0.2, 0.1, 0.3)}
    results = {"auxiliary": _cells(**cells)}
    only = ["auxiliary"]
    f = findings(results, only=only)
    for key in ("model_order", "augmentation_helps_color", "touch_helps_depth"):
        assert f[key] == {
            "verdict": "not tested",
            "detail": "not run (--only auxiliary)",
            "claim": f[key]["claim"],
        }
    assert f["depth_beats_color"]["verdict"] == "within noise"  # auxiliary's own pairs
    # Asked for but skipped (the data lacks touch): the reason is the data's.
    skipped = {"cross_modal_depth_touch": "needs touch; the data has depth, color"}
    table_4 = findings({}, only=["snn_depth", "cross_modal_depth_touch"])["touch_helps_depth"]
    assert table_4["detail"] == "needs both Table 4 runs (depth and touch data)"
    assert findings({})["touch_helps_depth"]["detail"] == table_4["detail"]
    # Finished runs --only left out but reported all the same test the findings as any.
    earlier = {m: _cells(**cells) for m in ("flat", "cross_modal", "multi_input")}
    assert findings(results | earlier, only=only)["model_order"]["verdict"] == "within noise"

    result = ReproduceResult(tmp_path, tmp_path / "report.md", results, skipped, f)
    meta = {"data_root": "w", "budget": "tiny", "seeds": 1, "minutes": 1.0, "only": only}
    write_reproduction_report(result, meta)
    report = result.report.read_text(encoding="utf-8")
    assert "Data: `w`; budget: **tiny**; seeds: 1; --only: auxiliary; 1.0 min." in report
    assert "| **not tested** | not run (--only auxiliary) |" in report
    assert "**not tested**: a run it needs was not run (--only auxiliary) or was skipped)" in (
        report
    )
    assert "| touch_to_depth | -^1 | -^1 | 0.300 [0.20, 0.40] | -^1 |" in report
    assert "- ^1 flat, cross_modal, multi_input: not run (--only auxiliary)." in report
    assert "| snn_depth | -^1 (0.482) | -^1 (0.660) | -^1 (0.554) | -^1 (0.729) |" in report
    assert "| cross_modal_depth_touch | -^2 (0.608) |" in report
    assert "- ^1 snn_depth: not run (--only auxiliary)." in report
    assert "- ^2 cross_modal_depth_touch: skipped (see Skipped below)." in report
    assert "-^k: the column's run was not run, note k says why" in report
    assert "its runs were skipped" not in report

    meta |= {"only": only, "earlier": ["flat"]}
    write_reproduction_report(result, meta)
    assert (
        "--only: auxiliary (and flat from finished runs of an earlier reproduction here); "
        in result.report.read_text(encoding="utf-8")
    )
    # Without --only nothing of it; the plain "-" of a run neither left out nor skipped stays.
    report = _report(tmp_path, results, {"split": "paper"})
    assert "--only" not in report and "-^" not in report and "its runs were skipped" in report
    assert "| touch_to_depth | - | - | 0.300 [0.20, 0.40] | - |" in report


def test_the_report_says_how_seeds_and_few_candidates_make_its_numbers(tmp_path: Path):
    """QA: with --seeds 2 the report said "95% bootstrap interval over test fabrics (first
    seed)", yet every number, bounds included, is the mean over the seeds; over 6 test
    fabrics it said "pick 1 of 10" where chance was 1/6."""

    def run(n: int) -> dict:
        row = _cells(touch_to_depth=(0.3, 0.2, 0.4))
        row["metrics"] |= {"touch_to_depth_n_effective": float(n)}
        return row

    novel = {"top1": 0.5, "n_effective": 6.0}
    report = _report(tmp_path, {"flat": run(10)}, {"split": "paper", "seeds": 3})
    assert "first seed" not in report
    assert (
        "Each cell: the mean over the 3 seeds of our top-1 accuracy (top-1 or top-3 in Table 4's "
        "columns; exact expectation over the draw) of pick 1 of 10, its 95% bootstrap interval "
        "over test fabrics (each bound the "
        "mean over the 3 seeds of that seed's interval), ±the standard deviation over the "
        "seeds, and (the paper's number);"
    ) in report
    report = _report(tmp_path, {"flat": run(10)}, {"seeds": 1, "n_boot": 0})
    assert "of pick 1 of 10, no interval (--n-boot 0: none was drawn), and (the paper's" in report
    report = _report(tmp_path, {"flat": run(6), "snn_depth": {"novel": novel}}, {"seeds": 1})
    assert (
        "Each cell: our top-1 accuracy (top-1 or top-3 in Table 4's columns; exact expectation "
        "over the draw) of pick 1 of 6 (the "
        "paper's pick 1 of 10, but the test fabrics offer only 6 candidates a draw), its 95% "
        "bootstrap interval over test fabrics, and (the paper's number);"
    ) in report
    seen = {"top1": 0.5, "n_effective": 10.0}
    report = _report(
        tmp_path, {"flat": run(6), "snn_depth": {"novel": novel, "seen": seen}}, {"seeds": 1}
    )
    assert (
        "pick 1 of as many candidates as the test fabrics offer, up to the paper's 10 (here 1 "
        "of 6 on Tables 1-3, 1 of 10 on Table 4's seen side, 1 of 6 on Table 4's novel side)"
    ) in report


# --- helper-rrun: --only accumulates, run times, interrupts and warnings of workers ----------


def test_only_adds_to_the_finished_runs_in_out(data: Path, tmp_path: Path, capsys):
    """QA: rerunning ``--only auxiliary`` into a finished --out replaced the report with
    auxiliary alone, results.json did not say what was asked, and a resumed reproduction's
    header read "0.0 min". Now the finished runs trained with the same settings are reported
    too (``meta.earlier``), ``meta.only`` is what was asked, and ``runs`` / ``run_minutes`` are
    the runs behind the numbers and their own time (a resumed run's with its logged training
    before the resume)."""
    from lookfeel.config import ConfigError

    out = tmp_path / "out"
    args = dict(budget="tiny", n_boot=20, overrides=FAST)
    first = reproduce(data, out, only=["cross_modal"], log=lambda s: None, **args)
    meta = json.loads((out / "results.json").read_text(encoding="utf-8"))["meta"]
    assert meta["only"] == ["cross_modal"] and meta["earlier"] == [] and meta["runs"] == 1
    lines: list[str] = []
    second = reproduce(data, out, only=["snn_depth"], log=lines.append, **args)
    assert list(second.results) == ["cross_modal", "snn_depth"]
    assert json.dumps(second.results["cross_modal"]) == json.dumps(first.results["cross_modal"])
    assert f"also reported, from finished runs in {out}: cross_modal (seed 0)" in lines
    saved = json.loads((out / "results.json").read_text(encoding="utf-8"))
    assert list(saved["results"]) == ["cross_modal", "snn_depth"]
    assert saved["meta"]["only"] == ["snn_depth"] and saved["meta"]["earlier"] == ["cross_modal"]
    seconds = [
        json.loads(p.read_text(encoding="utf-8"))["seconds"]
        for p in out.glob("runs/*/seed0/eval.json")
    ]
    assert saved["meta"]["runs"] == 2
    assert saved["meta"]["run_minutes"] == round(sum(seconds) / 60, 1)

    # A run killed after its training logged 3 steps at 0.001 steps/s (3,000 s), resumed.
    run_dir = out / "runs" / "cross_modal" / "seed0"
    (run_dir / "eval.json").unlink()
    slow = {"step": 3, "loss": 1.0, "lr": 0.001, "steps_per_s": 0.001}
    (run_dir / "metrics.jsonl").write_text(json.dumps(slow) + "\n", encoding="utf-8")
    argv = ["reproduce", "--data", str(data), "--out", str(out), "--budget", "tiny"]
    argv += ["--only", "cross_modal", "--n-boot", "20", "--set", FAST[0], "--set", FAST[1]]
    assert main(argv) == 0
    resumed = json.loads((run_dir / "eval.json").read_text(encoding="utf-8"))["seconds"]
    assert 3000 <= resumed < 3300
    meta = json.loads((out / "results.json").read_text(encoding="utf-8"))["meta"]
    assert meta["only"] == ["cross_modal"] and meta["earlier"] == ["snn_depth"]
    assert meta["run_minutes"] >= 50 and meta["minutes"] < 5
    printed = capsys.readouterr().out
    assert f"2 run(s) behind these numbers, {meta['run_minutes']} min of training" in printed
    header = (out / "report.md").read_text(encoding="utf-8")
    assert f"2 runs behind these numbers, {meta['run_minutes']} min of training and scoring; " in (
        header
    )
    assert f"this reproduction {meta['minutes']} min." in header

    # A finished run trained with other settings: left out, saying how, when not asked for;
    # refused, before any training, when asked for.
    config = run_dir / "config.yaml"
    config.write_text(
        config.read_text(encoding="utf-8").replace("lr: 0.001", "lr: 0.002"), encoding="utf-8"
    )
    lines.clear()
    third = reproduce(data, out, only=["snn_depth"], log=lines.append, **args)
    assert list(third.results) == ["snn_depth"] and third.meta["earlier"] == []
    assert (
        f"not reported: {run_dir}, a finished run trained with other settings than this "
        "reproduction's (train.lr: trained 0.002, asked 0.001)" in lines
    )
    with pytest.raises(ConfigError, match=r"finished run trained with other settings .*train\.lr"):
        reproduce(data, out, only=["cross_modal"], log=lambda s: None, **args)
    config.unlink()  # not readable: left out, saying so
    lines.clear()
    assert list(reproduce(data, out, only=["snn_depth"], log=lines.append, **args).results) == [
        "snn_depth"
    ]
    assert any(
        line.startswith(f"not reported: {run_dir}, a finished run whose config.yaml cannot be read")
        for line in lines
    ), lines


def test_the_training_time_a_run_logged_and_warnings_sent_from_workers():
    from lookfeel.reproduce.run import _logged_seconds, _sendable

    lines = [
        {"step": 50, "loss": 1.0, "steps_per_s": 0.5},  # 100 s
        {"step": 50, "val/x_top1": 0.3},  # a validation: no time
        {"step": 100, "loss": 1.0, "steps_per_s": None},  # not measured
        {"step": 150, "loss": 1.0, "steps_per_s": 2.0},  # 100 steps since step 50: 50 s
    ]
    path = Path(__file__).parent / "_not_there.jsonl"
    assert _logged_seconds(path) == 0.0
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "metrics.jsonl"
        path.write_text("".join(json.dumps(x) + "\n" for x in lines) + "{cut\n", encoding="utf-8")
        assert _logged_seconds(path) == pytest.approx(150.0)

    local = type("Local", (UserWarning,), {})  # pickle cannot name it
    assert _sendable(local) is UserWarning and _sendable(RuntimeWarning) is RuntimeWarning


_FAKE_RUNS = """
import os, sys, time, warnings

import lookfeel.reproduce.run as run


def fake_run_one(exp, config, catalog, data, run_dir, n_boot):
    run_dir.mkdir(parents=True, exist_ok=True)
    if exp.name == "flat":
        warnings.warn("fake: flat warns")
        return {"experiment": "flat", "seconds": 0.0, "not_scored": {}}
    (run_dir / "pid").write_text(str(os.getpid()))
    time.sleep(600)
    raise AssertionError("not interrupted")


run._run_one = fake_run_one  # here and in each spawned worker, which imports this file

if __name__ == "__main__":
    from lookfeel.cli import run as cli

    sys.exit(cli(sys.argv[1:]))
"""


def _sigint_as_in_a_terminal() -> None:
    import signal

    signal.signal(signal.SIGINT, signal.SIG_DFL)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})


def test_an_interrupt_ends_the_workers_at_once_and_their_warnings_are_one_line(
    data: Path, tmp_path: Path
):
    """QA: SIGINT sent to the command alone left it running 50+ s (the pool's shutdown waited
    for the runs in its workers), and a worker's warning came out in Python's own form, with
    file, line and source line. Fake runs in 2 workers: flat warns and ends (its warning is
    one line, raised again in the command), cross_modal and auxiliary wait 600 s."""
    import os
    import signal
    import subprocess
    import sys
    import time

    script = tmp_path / "fake_runs.py"
    script.write_text(_FAKE_RUNS, encoding="utf-8")
    out = tmp_path / "out"
    argv = [sys.executable, str(script), "reproduce", "--data", str(data), "--out", str(out)]
    argv += ["--budget", "tiny", "--workers", "2", "--only", "flat", "cross_modal", "auxiliary"]
    pids = [out / "runs" / name / "seed0" / "pid" for name in ("cross_modal", "auxiliary")]
    proc = subprocess.Popen(
        argv,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        # As in a terminal: SIGINT neither ignored nor blocked, whatever this process (pytest,
        # a shell's background job, an earlier test) left for its children to inherit; with
        # either, Python never raises KeyboardInterrupt.
        preexec_fn=_sigint_as_in_a_terminal,
    )
    try:
        deadline = time.monotonic() + 120  # two spawned workers import torch: seconds
        while not all(p.exists() and p.read_text(encoding="utf-8") for p in pids):
            assert proc.poll() is None, proc.communicate()
            assert time.monotonic() < deadline, "the fake runs never started"
            time.sleep(0.1)
        # auxiliary started after flat's result (and its warnings) came back: both running.
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=90)  # was: until the runs end (600 s)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode == 130, err
    assert err.count("lookfeel: warning: fake: flat warns\n") == 1, err
    assert "UserWarning" not in err and "Traceback" not in err, err
    assert err.endswith("lookfeel: interrupted\n"), err
    for path in pids:  # the workers ended with their runs
        pid = int(path.read_text(encoding="utf-8"))
        for _ in range(50):
            try:
                os.kill(pid, 0)
            except ProcessLookupError:
                break
            time.sleep(0.1)
        else:
            pytest.fail(f"worker {pid} still runs")


def test_sigint_while_waiting_on_the_pool_is_raised_as_the_wait_returns():
    """A KeyboardInterrupt raised inside ``concurrent.futures.wait`` can leave its futures'
    locks held, and the pool's shutdown then waits forever: SIGINT during the wait is noted
    and raised as the wait returns, with every lock free; outside the wait it raises at once;
    the handler is Python's own again afterwards."""
    import os
    import signal
    import threading
    from concurrent.futures import Future

    from lookfeel.reproduce.run import _interrupt_between_waits

    before = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        future: Future[int] = Future()
        with _interrupt_between_waits() as interrupts:
            assert signal.getsignal(signal.SIGINT) == interrupts.handle
            timer = threading.Timer(0.3, os.kill, (os.getpid(), signal.SIGINT))
            timer.start()
            with pytest.raises(KeyboardInterrupt):
                interrupts.wait_for({future: 0})
            timer.join()
            assert interrupts.pending and future._condition.acquire(timeout=1)
            future._condition.release()
            with pytest.raises(KeyboardInterrupt):  # not waiting: at once
                interrupts.handle(signal.SIGINT, None)
            done: Future[int] = Future()
            done.set_result(1)
            interrupts.pending = False
            assert interrupts.wait_for({done: 0, future: 1}) == {done}
        assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        with _interrupt_between_waits():  # ignored (a background job): left as it is
            assert signal.getsignal(signal.SIGINT) is signal.SIG_IGN
    finally:
        signal.signal(signal.SIGINT, before)


# --- helper-rdata: runs on another dataset, another --n-boot, what results.json records --------


def test_runs_trained_on_another_dataset_are_refused_before_any_training(
    data: Path, tmp_path: Path, capsys
):
    """QA: rerunning into a folder whose runs were trained on another world reused them
    silently, its numbers written under the new ``meta.data``. Now a folder with runs (finished
    or started, asked for or not) whose checkpoint records another dataset is refused, in one
    line, before any training; the same dataset in another folder is still reused."""
    out = tmp_path / "out"
    args = dict(budget="tiny", n_boot=20, overrides=FAST, log=lambda s: None, workers=1)
    reproduce(data, out, only=["flat"], **args)
    done = out / "runs" / "flat" / "seed0" / "eval.json"
    stamps = {p: p.stat().st_mtime_ns for p in [done, out / "results.json"]}
    moved = shutil.copytree(data, tmp_path / "moved")  # the same files: reused
    reproduce(moved, out, only=["flat"], **args)
    assert done.stat().st_mtime_ns == stamps[done]
    stamps[out / "results.json"] = (out / "results.json").stat().st_mtime_ns

    other = write_tiny_dataset(
        tmp_path / "other", fabrics=10, drapes=5, fold_presses=4, flat_presses=3
    )
    said = (
        f"{out} holds runs trained on another dataset (runs/flat/seed0), or on {other} before "
        "its files or labels changed; use another --out"
    )
    with pytest.raises(ConfigError) as e:
        reproduce(other, out, only=["flat"], **args)
    assert str(e.value) == said
    argv = ["reproduce", "--data", str(other), "--out", str(out), "--budget", "tiny"]
    assert main([*argv, "--only", "flat", "--n-boot", "20"]) == 1
    assert capsys.readouterr().err == f"lookfeel: {said}\n"
    with pytest.raises(ConfigError, match="trained on another dataset"):  # not asked for
        reproduce(other, out, only=["snn_depth"], **args)
    assert not (out / "runs" / "snn_depth").exists()  # nothing trained
    assert {p: p.stat().st_mtime_ns for p in stamps} == stamps  # nothing written

    # A label changed: another dataset too. A started run (no eval.json): its checkpoint's.
    relabelled = shutil.copytree(data, tmp_path / "relabelled")
    labels = relabelled / "labels.csv"
    labels.write_text(
        labels.read_text(encoding="utf-8").replace("\n1,0,0.5,", "\n1,0,0.7,"), encoding="utf-8"
    )
    done.unlink()
    with pytest.raises(ConfigError, match=r"trained on another dataset \(runs/flat/seed0\)"):
        reproduce(relabelled, out, only=["flat"], **args)
    assert not done.exists()


def test_a_rerun_with_another_n_boot_scores_the_kept_runs_again(data: Path, tmp_path: Path):
    """QA: rerunning a finished folder with another --n-boot kept the intervals of the first
    --n-boot. Now each finished run scored otherwise is scored again from its checkpoint (not
    trained again), giving the numbers a fresh reproduction with that --n-boot gives; one
    whose checkpoint is gone is refused, before any training."""
    only = ["flat", "snn_depth"]
    lines: list[str] = []
    args = dict(budget="tiny", only=only, overrides=FAST, log=lines.append, workers=1)
    out = tmp_path / "out"
    first = reproduce(data, out, n_boot=20, **args)
    checkpoints = sorted(out.glob("runs/*/seed0/checkpoints/*.pt"))
    stamps = [p.stat().st_mtime_ns for p in checkpoints]
    seconds = [
        json.loads(p.read_text(encoding="utf-8"))["seconds"]
        for p in sorted(out.glob("runs/*/*/eval.json"))
    ]
    lines.clear()
    again = reproduce(data, out, n_boot=50, **args)
    said = lines[0]
    assert [p.stat().st_mtime_ns for p in checkpoints] == stamps  # not trained again
    fresh = reproduce(data, tmp_path / "fresh", n_boot=50, **args)
    assert json.dumps(again.results) == json.dumps(fresh.results)  # NaN-safe equality
    assert json.dumps(again.results) != json.dumps(first.results)  # the intervals moved
    assert said == (
        "scoring again with --n-boot 50, from their checkpoints, the finished runs scored "
        "otherwise: flat seed 0, snn_depth seed 0"
    )
    saved = json.loads((out / "results.json").read_text(encoding="utf-8"))
    assert saved["meta"]["n_boot"] == 50
    evals = sorted(out.glob("runs/*/*/eval.json"))
    assert [json.loads(p.read_text(encoding="utf-8"))["n_boot"] for p in evals] == [50, 50]
    assert [
        json.loads(p.read_text(encoding="utf-8"))["seconds"] for p in evals
    ] == seconds  # its training's

    # Scored with 50, its checkpoint gone: another --n-boot is refused, before any training.
    (out / "runs" / "flat" / "seed0" / "checkpoints" / "last.pt").unlink()
    report = (out / "report.md").stat().st_mtime_ns
    with pytest.raises(ConfigError) as e:
        reproduce(data, out, n_boot=20, **args)
    assert str(e.value) == (
        f"{out / 'runs' / 'flat' / 'seed0'} is a finished run scored with --n-boot 50, and its "
        "checkpoint checkpoints/last.pt, needed to score it again with --n-boot 20, is gone: "
        "rerun with --n-boot 50, reproduce into another --out, or delete the run to train it "
        "anew"
    )
    assert (out / "report.md").stat().st_mtime_ns == report


def test_results_json_records_what_it_takes_to_reproduce_it(tmp_path: Path):
    """QA: ``results.json`` did not record --n-boot, --workers, which dataset or which
    software. A reproduction that trains nothing (each run skipped) writes them all."""
    from lookfeel.data import scan
    from lookfeel.provenance import software_versions

    two = write_tiny_dataset(tmp_path / "two", fabrics=10, drapes=2, fold_presses=2)
    out = tmp_path / "o"
    args = dict(budget="tiny", n_boot=30, overrides=FAST, log=lambda s: None)
    reproduce(two, out, only=["multi_input"], **args)
    meta = json.loads((out / "results.json").read_text(encoding="utf-8"))["meta"]
    assert meta["n_boot"] == 30
    assert meta["workers"] == 0 and meta["workers_resolved"] == 1  # 0: the default, resolved
    assert meta["data_fingerprint"] == scan(two, require=[], strict=True).fingerprint()
    assert meta["software"] == software_versions()
    assert set(meta["software"]) == {"lookfeel", "torch", "python"}
    assert meta["budget"] == "tiny"  # the keys it had
    # The dataset folder, named as index info, embed and cv name it (``data`` before).
    assert meta["data_root"] == str(two) and "data" not in meta
    assert f"Data: `{two}`; budget: **tiny**" in (out / "report.md").read_text(encoding="utf-8")
    assert "budget: **tiny**" in (out / "report.md").read_text(encoding="utf-8")


# --- Table 4 beside raw pixels and the background control ------------------------------------


@pytest.fixture(scope="module")
def vision(data: Path, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A finished reproduction of ``snn_depth`` alone (Table 4), its folder: read, or copied
    before it is changed."""
    out = tmp_path_factory.mktemp("vision") / "out"
    reproduce(
        data,
        out,
        budget="tiny",
        only=["snn_depth"],
        n_boot=50,
        overrides=FAST,
        log=lambda s: None,
        workers=1,
    )
    return out


def _ordered(side: dict, key: str) -> bool:
    """``side[key]`` in [0, 1], inside its interval when it has one."""
    v = side[key]
    low, high = side.get(f"{key}_ci_low", v), side.get(f"{key}_ci_high", v)
    return 0.0 <= low <= v <= high <= 1.0


def test_table_4_has_raw_pixels_and_the_background_control_beside_the_model(vision: Path):
    """QA: Table 4's depth numbers stood beside chance alone. On GelFabric each
    fabric is captured in its own session, so the room behind the cloth names it. Each side now
    carries, on the same queries, raw pixels' top-1 and the model's and raw pixels' with each
    depth image's background swapped for another fabric's, each with its interval; eval.json,
    results.json, the report and the headline show them."""
    from lookfeel.reproduce.report import CONTROLS_NOTE
    from lookfeel.reproduce.run import CONTROL_KEYS, headline

    record = json.loads(
        (vision / "runs" / "snn_depth" / "seed0" / "eval.json").read_text(encoding="utf-8")
    )
    saved = json.loads((vision / "results.json").read_text(encoding="utf-8"))["results"][
        "snn_depth"
    ]
    for novel in (record["novel"], saved["novel"]):
        assert set(CONTROL_KEYS) <= set(novel)
        for key in ("top1", "raw_pixels_top1", "top1_swapped", "raw_pixels_top1_swapped"):
            assert f"{key}_ci_low" in novel and _ordered(novel, key), key
        assert novel["top1_swapped"] != novel["top1"]  # the swap changed the images
    # The seen side has no query (one held-out depth image a fabric): every number n/a, for
    # the side's reason; results.json has null for them, as for the model's.
    assert all(record["seen"][k] != record["seen"][k] for k in CONTROL_KEYS)
    assert all(saved["seen"][k] is None for k in CONTROL_KEYS)
    assert set(record["not_scored"]) == {"seen"}
    report = (vision / "report.md").read_text(encoding="utf-8")
    table_4 = report[report.index("## Table 4") :]
    n = record["novel"]
    for label, key in (
        ("snn_depth, background swapped", "top1_swapped"),
        ("raw pixels, snn_depth's queries", "raw_pixels_top1"),
        ("raw pixels, snn_depth's queries, background swapped", "raw_pixels_top1_swapped"),
    ):
        cell = f"{n[key]:.3f} [{n[f'{key}_ci_low']:.2f}, {n[f'{key}_ci_high']:.2f}]"
        assert f"| {label} | n/a^1 | n/a^1 | {cell} | n/a^2 |" in table_4, label
    assert CONTROLS_NOTE in table_4 and "keeps its score when the background is swapped" in (
        CONTROLS_NOTE
    )
    assert "- ^1 snn_depth seen, seen chance: no seen fabric has two depth images" in table_4

    def shown(key: str) -> str:
        return f"{n[key]:.3f} [{n[f'{key}_ci_low']:.3f}, {n[f'{key}_ci_high']:.3f}]"

    assert headline({"snn_depth": saved}) == [
        f"snn_depth    depth->depth top-1 on novel fabrics {shown('top1')} (chance 0.333)",
        f"    background swapped {shown('top1_swapped')}; raw pixels {shown('raw_pixels_top1')}, "
        f"swapped {shown('raw_pixels_top1_swapped')}",
    ]


def test_the_controls_score_the_models_queries_by_its_protocol(
    vision: Path, data: Path, monkeypatch: pytest.MonkeyPatch
):
    """With nothing swapped (each image served with its own background) the background
    control reproduces the model's number and interval exactly, and raw pixels' likewise: the
    same queries, protocol, seed and resamples. One fabric has no other to take a background
    from: its swapped numbers are n/a with the reason, the rest scored."""
    import math

    from lookfeel.checkpoint import load_model
    from lookfeel.data import ImageLoader, scan
    from lookfeel.data.background_swap import BackgroundControl
    from lookfeel.reproduce.run import _depth_pick

    loaded = load_model(vision / "runs" / "snn_depth" / "seed0" / "checkpoints" / "last.pt")
    catalog = scan(data, require=[], strict=True)
    novel = catalog.subset(loaded.split["novel"])
    args = (loaded.model, novel, loaded.config, 50, 0, "novel")
    monkeypatch.setattr(BackgroundControl, "loader", lambda self, items: ImageLoader(self.config))
    side, why = _depth_pick(*args)
    assert why == {}
    for suffix in ("", "_ci_low", "_ci_high"):
        assert side[f"top1_swapped{suffix}"] == side[f"top1{suffix}"]
        assert side[f"raw_pixels_top1_swapped{suffix}"] == side[f"raw_pixels_top1{suffix}"]
    monkeypatch.undo()

    one = catalog.subset(loaded.split["novel"][:1])
    side, why = _depth_pick(loaded.model, one, loaded.config, 50, 0, "novel")
    assert side["top1"] == 1.0 and side["raw_pixels_top1"] == 1.0  # pick 1 of 1
    assert math.isnan(side["top1_swapped"]) and math.isnan(side["raw_pixels_top1_swapped"])
    assert why == {
        "novel_swapped": "background control skipped: background swap needs images of two or "
        "more fabrics; got 1"
    }


def test_a_table_4_run_scored_without_the_controls_is_scored_again_from_its_checkpoint(
    vision: Path, data: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
):
    """An eval.json of an earlier lookfeel has no raw pixels or background control: the run is
    scored again from its checkpoint (not trained again), as a fresh one is, its time kept;
    its checkpoint gone, the report says n/a with the reason, and nothing fails. Each run's
    eval.json is read once (it was read three times)."""
    from lookfeel.reproduce.run import CONTROL_KEYS, NO_CHECKPOINT

    out = tmp_path / "out"
    shutil.copytree(vision, out)
    done = out / "runs" / "snn_depth" / "seed0" / "eval.json"
    fresh_text = done.read_text(encoding="utf-8")
    fresh = json.loads(fresh_text)
    old = dict(fresh)
    for side in ("seen", "novel"):
        old[side] = {k: v for k, v in fresh[side].items() if k.removesuffix("_ci_low")
                     .removesuffix("_ci_high") not in CONTROL_KEYS}  # fmt: skip
    old_text = json.dumps(old)
    done.write_text(old_text, encoding="utf-8")
    checkpoint = out / "runs" / "snn_depth" / "seed0" / "checkpoints" / "last.pt"
    stamp = checkpoint.stat().st_mtime_ns
    reads: list[str] = []
    read_text = Path.read_text

    def counted(self: Path, *a, **k) -> str:
        if self.name == "eval.json":
            reads.append(str(self))
        return read_text(self, *a, **k)

    monkeypatch.setattr(Path, "read_text", counted)
    lines: list[str] = []
    args = dict(budget="tiny", only=["snn_depth"], n_boot=50, overrides=FAST, workers=1)
    reproduce(data, out, log=lines.append, **args)
    assert reads == [str(done)]
    assert lines[0] == (
        "scoring again from their checkpoints, to add raw pixels and the background control "
        "beside Table 4's numbers, the finished runs scored without them: snn_depth seed 0"
    )
    assert checkpoint.stat().st_mtime_ns == stamp  # not trained again
    assert (
        done.read_text(encoding="utf-8") == fresh_text
    )  # as the fresh run wrote it, its time kept
    first = json.loads((vision / "results.json").read_text(encoding="utf-8"))["results"][
        "snn_depth"
    ]
    assert (
        json.loads((out / "results.json").read_text(encoding="utf-8"))["results"]["snn_depth"]
        == first
    )

    # Its checkpoint gone: reported, the controls n/a with why.
    done.write_text(old_text, encoding="utf-8")
    checkpoint.unlink()
    lines.clear()
    gone = reproduce(data, out, log=lines.append, **args).results["snn_depth"]
    assert lines[0] == (
        "no raw pixels or background control for snn_depth seed 0: scored without them by an "
        "earlier lookfeel, and the checkpoint is gone (the report says n/a)"
    )
    assert all(gone["novel"][k] != gone["novel"][k] for k in CONTROL_KEYS)
    assert gone["novel"]["top1"] == fresh["novel"]["top1"]
    assert gone["not_scored"]["novel_swapped"] == NO_CHECKPOINT
    report = (out / "report.md").read_text(encoding="utf-8")
    assert "| raw pixels, snn_depth's queries | n/a^1 | n/a^1 | n/a^3 | n/a^3 |" in report
    assert (
        "- ^3 snn_depth novel background swapped, snn_depth novel raw pixels, snn_depth novel "
        f"raw pixels background swapped: {NO_CHECKPOINT}."
    ) in report
    assert done.read_text(encoding="utf-8") == old_text  # left as it was


def test_table_4_s_controls_in_the_report_and_over_seeds(tmp_path: Path):
    """Hand-made: each control row under its model, a swap that could not be made n/a with
    its reason (the model's number kept), and the mean over seeds of a number one seed lacks
    is over the seeds that have it."""
    from lookfeel.reproduce.run import _aggregate

    nan = float("nan")
    novel = {"top1": 0.5, "top3": 0.8, "chance": 0.1, "n_effective": 10.0, "top1_ci_low": 0.4,
             "top1_ci_high": 0.6, "raw_pixels_top1": 0.3, "raw_pixels_top3": 0.6,
             "raw_pixels_top1_ci_low": 0.2, "raw_pixels_top1_ci_high": 0.4,
             "top1_swapped": nan, "top3_swapped": nan, "raw_pixels_top1_swapped": nan,
             "raw_pixels_top3_swapped": nan}  # fmt: skip
    why = "background control skipped: background swap needs images of two or more fabrics"
    results = {
        "cross_modal_depth_touch": {"novel": novel, "not_scored": {"novel_swapped": why}},
    }
    report = _report(tmp_path, results, {"split": "paper"})
    table_4 = report[report.index("## Table 4") :]
    assert "| cross_modal_depth_touch | - (0.608) | - (0.786) | 0.500 [0.40, 0.60] (0.606) |" in (
        table_4
    )
    assert "| cross_modal_depth_touch, background swapped | - | - | n/a^1 | n/a^1 |" in table_4
    assert (
        "| raw pixels, cross_modal_depth_touch's queries | - | - | 0.300 [0.20, 0.40] | 0.600 |"
    ) in table_4
    assert (
        f"- ^1 cross_modal_depth_touch novel background swapped, cross_modal_depth_touch novel "
        f"raw pixels background swapped: {why}."
    ) in table_4
    assert "in another fabric's room" not in table_4  # registered depth only
    one = {"seen": {"top1": 0.5, "top1_swapped": 0.4}, "not_scored": {}}
    two = {"seen": {"top1": 0.7}, "not_scored": {}}  # an older record, without it
    assert _aggregate([one, two])["seen"] == {"top1": pytest.approx(0.6), "top1_swapped": 0.4}


# --- Table 4: top-3 intervals, the headline's controls, read-back runs, sides not scored ------


def test_table_4_records_the_models_top_3_interval_and_adds_it_to_an_old_run(
    vision: Path, data: Path, tmp_path: Path
):
    """QA: each control's top-3 had its interval in results.json, the model's top-3 none. Now
    it has one too. An eval.json of an earlier lookfeel without it is scored again from its
    checkpoint (not trained again); its checkpoint gone, the interval is n/a with the reason."""
    import math

    record = json.loads(
        (vision / "runs" / "snn_depth" / "seed0" / "eval.json").read_text(encoding="utf-8")
    )
    saved = json.loads((vision / "results.json").read_text(encoding="utf-8"))["results"][
        "snn_depth"
    ]
    for novel in (record["novel"], saved["novel"]):
        assert "top3_ci_low" in novel and _ordered(novel, "top3")

    out = tmp_path / "out"
    shutil.copytree(vision, out)
    done = out / "runs" / "snn_depth" / "seed0" / "eval.json"
    fresh_text = done.read_text(encoding="utf-8")
    old = json.loads(fresh_text)
    old["novel"] = {k: v for k, v in old["novel"].items() if not k.startswith("top3_ci_")}
    old_text = json.dumps(old)
    done.write_text(old_text, encoding="utf-8")
    lines: list[str] = []
    args = dict(budget="tiny", only=["snn_depth"], n_boot=50, overrides=FAST, workers=1)
    reproduce(data, out, log=lines.append, **args)
    assert lines == [
        "scoring again from their checkpoints, to add the top-3 interval to Table 4's numbers, "
        "the finished runs scored without it: snn_depth seed 0",
        "score snn_depth seed 0 (Table 4 (SNN, only depth)): finished, scored again from its "
        "checkpoint, not trained",
    ]
    assert done.read_text(encoding="utf-8") == fresh_text  # as the fresh run wrote it

    done.write_text(old_text, encoding="utf-8")
    (done.parent / "checkpoints" / "last.pt").unlink()
    lines.clear()
    gone = reproduce(data, out, log=lines.append, **args).results["snn_depth"]
    assert lines[0] == (
        "no top-3 interval for snn_depth seed 0: scored without it by an earlier lookfeel, and "
        "the checkpoint is gone (the report says n/a)"
    )
    assert math.isnan(gone["novel"]["top3_ci_low"]) and math.isnan(gone["novel"]["top3_ci_high"])
    assert gone["novel"]["top3"] == record["novel"]["top3"]
    from lookfeel.reproduce.run import NO_TOP3_INTERVAL

    assert gone["not_scored"]["novel_top3_interval"] == NO_TOP3_INTERVAL
    assert done.read_text(encoding="utf-8") == old_text  # left as it was


def test_every_number_of_table_4_shows_its_interval(tmp_path: Path):
    """QA: Table 4 showed no top-3 interval, the model's or a control's, though the text says
    each cell has its 95% interval; nor, over seeds, ±the spread the text promises. A top-3
    interval an earlier lookfeel did not record is n/a with its reason."""
    nan = float("nan")

    def bounded(key: str, v: float) -> dict:
        return {key: v, f"{key}_ci_low": v - 0.1, f"{key}_ci_high": v + 0.1}

    novel = {"chance": 0.1, "n_effective": 10.0, "n_queries": 30.0, "n_fabrics": 10.0}
    values = {"top1": 0.5, "top3": 0.8, "raw_pixels_top1": 0.3, "raw_pixels_top3": 0.6,
              "top1_swapped": 0.45, "top3_swapped": 0.75, "raw_pixels_top1_swapped": 0.25,
              "raw_pixels_top3_swapped": 0.55}  # fmt: skip
    for key, v in values.items():
        novel |= bounded(key, v)
    spread = {"top1": 0.02, "top3": 0.01, "raw_pixels_top3": 0.03}
    why = "scored without the top-3 interval, and the checkpoint is gone"
    joint = bounded("top1", 0.6) | {"top3": 0.9, "top3_ci_low": nan, "top3_ci_high": nan}
    results = {
        "snn_depth": {"seeds": 2, "novel": novel, "novel_spread": spread, "not_scored": {}},
        "cross_modal_depth_touch": {
            "seeds": 2, "novel": joint | {"chance": 0.1, "n_effective": 10.0},
            "not_scored": {"novel_top3_interval": why},
        },
    }  # fmt: skip
    report = _report(tmp_path, results, {"split": "paper", "seeds": 2})
    table_4 = report[report.index("## Table 4") :]
    assert (
        "| snn_depth | - (0.482) | - (0.660) | 0.500 [0.40, 0.60] ±0.020 (0.554) "
        "| 0.800 [0.70, 0.90] ±0.010 (0.729) |"
    ) in table_4
    assert (
        "| snn_depth, background swapped | - | - | 0.450 [0.35, 0.55] | 0.750 [0.65, 0.85] |"
        in (table_4)
    )
    assert (
        "| raw pixels, snn_depth's queries | - | - | 0.300 [0.20, 0.40] "
        "| 0.600 [0.50, 0.70] ±0.030 |"
    ) in table_4
    assert (
        "| raw pixels, snn_depth's queries, background swapped | - | - | 0.250 [0.15, 0.35] "
        "| 0.550 [0.45, 0.65] |"
    ) in table_4
    assert (
        "| cross_modal_depth_touch | - (0.608) | - (0.786) | 0.600 [0.50, 0.70] (0.606) "
        "| 0.900 [n/a^1] (0.786) |"
    ) in table_4
    assert f"- ^1 cross_modal_depth_touch novel top-3 interval: {why}." in table_4
    assert "its 95% bootstrap interval over test fabrics" in report


def test_the_headline_shows_table_4_s_controls_on_their_own_line_with_intervals():
    """QA: "0.556 [0.306, 0.847] (raw pixels 0.528, background swapped 0.542; chance 0.250)"
    read as raw pixels swapped, while 0.542 is the model's, and the controls had no interval.
    The controls now stand on an indented line of their own, each with its interval; one not
    measured is n/a alone."""
    from lookfeel.reproduce.run import headline

    def bounded(key: str, v: float, low: float, high: float) -> dict:
        return {key: v, f"{key}_ci_low": low, f"{key}_ci_high": high}

    novel = {"chance": 0.25} | bounded("top1", 0.556, 0.306, 0.847)
    novel |= bounded("top1_swapped", 0.542, 0.278, 0.833)
    novel |= bounded("raw_pixels_top1", 0.528, 0.343, 0.713)
    novel |= bounded("raw_pixels_top1_swapped", 0.528, 0.361, 0.736)
    # --n-boot 0 (no intervals), no background swapped (NaN; null in results.json)
    joint = {"top1": 0.449, "chance": 0.25, "raw_pixels_top1": 0.528}
    joint |= {"top1_swapped": float("nan"), "raw_pixels_top1_swapped": None}
    lines = headline({"snn_depth": {"novel": novel}, "cross_modal_depth_touch": {"novel": joint}})
    assert lines == [
        "snn_depth    depth->depth top-1 on novel fabrics 0.556 [0.306, 0.847] (chance 0.250)",
        "    background swapped 0.542 [0.278, 0.833]; raw pixels 0.528 [0.343, 0.713], swapped "
        "0.528 [0.361, 0.736]",
        "cross_modal_depth_touch depth->depth top-1 on novel fabrics 0.449 (chance 0.250)",
        "    background swapped n/a; raw pixels 0.528, swapped n/a",
    ]
    assert max(len(line) for line in lines) <= 108  # 110 with the demo's indent


def test_a_finished_run_is_said_to_be_read_back_not_run(vision: Path, data: Path, tmp_path):
    """QA: a second reproduce printed "run  snn_depth seed 0 (...)" for a finished run, though
    nothing was trained: it says the run is read back (scored again: the test above)."""
    out = tmp_path / "out"
    shutil.copytree(vision, out)
    lines: list[str] = []
    args = dict(budget="tiny", only=["snn_depth"], n_boot=50, overrides=FAST, workers=1)
    reproduce(data, out, log=lines.append, **args)
    assert lines == [
        "read snn_depth seed 0 (Table 4 (SNN, only depth)): finished, read back from its eval.json"
    ]


def test_a_table_4_side_without_a_scored_query_has_no_chance_and_no_pick(tmp_path: Path):
    """QA: Table 4 showed the seen side's chance 0.100 / 0.300 beside 0 / 0 fabrics, and the
    text said "1 of 10 on Table 4's seen side", though nothing was scored there. That side's
    chance is now n/a with the side's reason, and the text names no pick for it."""
    nan = float("nan")
    seen = {"top1": nan, "top3": nan, "chance": 0.1, "top3_chance": 0.3, "n_effective": 10.0,
            "n_queries": 0.0, "n_fabrics": 0.0}  # fmt: skip
    novel = {"top1": 0.556, "top3": 0.986, "chance": 0.25, "top3_chance": 0.75,
             "n_effective": 4.0, "n_queries": 12.0, "n_fabrics": 4.0}  # fmt: skip
    why = "no seen fabric has two depth images in the held-out fifth of its images"
    run = {"seen": seen, "novel": novel, "not_scored": {"seen": why}, "test_fabrics": 4}
    results = {"snn_depth": run, "cross_modal_depth_touch": run}
    report = _report(tmp_path, results, {"split": "paper"})
    table_4 = report[report.index("## Table 4") :]
    assert "| chance | n/a^1 | n/a^1 | 0.250 | 0.750 |" in table_4
    assert "| fabrics / queries | 0 / 0 | 0 / 0 | 4 / 12 | 4 / 12 |" in table_4
    assert f"- ^1 snn_depth seen, cross_modal_depth_touch seen, seen chance: {why}." in table_4
    assert "seen side" not in report.split("## Findings")[0].split("Each cell:")[1]
    assert (
        "Each cell: our top-1 accuracy (top-1 or top-3 in Table 4's columns; exact expectation "
        "over the draw) of pick 1 of 4 (the "
        "paper's pick 1 of 10, but the test fabrics offer only 4 candidates a draw), its 95% "
    ) in report


def test_the_report_names_seeds_other_than_the_first_ones():
    """`reproduce --seeds 3,5` trains seeds 3 and 5: the report said "seeds: 2" as of 0 and 1."""
    from lookfeel.reproduce.report import _seeds

    assert _seeds({"seeds": 2, "seed_list": [3, 5]}) == "2 (3, 5)"
    assert _seeds({"seeds": 2, "seed_list": [0, 1]}) == "2"
    assert _seeds({"seeds": 3}) == "3"  # a results.json from before the list was kept
