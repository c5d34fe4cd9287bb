"""Cross-validation: folds of a fixed size, resumable runs, intervals, baseline and the CLI."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest
import torch
import yaml

from lookfeel.cli import main
from lookfeel.config import ConfigError, EvalConfig, RunConfig, load_config
from lookfeel.crossval import cross_validate
from lookfeel.data import scan, stratified_fabric_folds
from lookfeel.train import train

from ._tiny import write_tiny_dataset

TINY = Path(__file__).resolve().parents[1] / "configs" / "tiny.yaml"
OVERRIDES = [
    "train.views=[depth,depth]",
    "train.val_pairs=[depth_to_depth]",
    "train.folds=2",
    "train.fold_size=3",
    "train.steps=6",
    "train.val_every=0",
]


@pytest.fixture(scope="module")
def data(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return write_tiny_dataset(tmp_path_factory.mktemp("cv") / "data", fabrics=7, drapes=3)


def test_folds_of_a_fixed_size_are_disjoint_and_spread_over_clusters():
    ids = list(range(1, 101))
    clusters = {i: i % 8 for i in ids}
    folds = stratified_fabric_folds(ids, clusters, 5, seed=3, fold_size=18)
    tests = [set(f.test) for f in folds]
    assert [len(t) for t in tests] == [18] * 5
    assert len(set().union(*tests)) == 90  # disjoint
    for f in folds:
        assert set(f.train) | set(f.test) == set(ids)
        per_cluster = np.bincount([clusters[i] for i in f.test], minlength=8)
        assert per_cluster.max() - per_cluster.min() <= 1  # 18 over 8 clusters: 2 or 3 each
    # Named as the config key and as cv's flag, with a size that fits (100 // 5).
    fits = r"train.fold_size=20 \(--fold-size 20\) fits"
    with pytest.raises(
        ValueError, match=r"5 folds of 21 fabrics need 105 .*--fold-size\)" + ".*" + fits
    ):
        stratified_fabric_folds(ids, clusters, 5, fold_size=21)


def test_cross_validate_scores_every_run_and_resumes(data: Path, tmp_path: Path):
    config = load_config(RunConfig, TINY, OVERRIDES)
    logs: list[str] = []
    summary = cross_validate(
        config, data, tmp_path / "cv", seeds=[0, 1], n_boot=50, log=logs.append
    )
    assert summary["runs"] == 4
    # what made the numbers: the resamples, the dataset and the software
    assert summary["n_boot"] == 50
    assert summary["data_root"] == str(data) and "data" not in summary
    assert summary["data_fingerprint"] == scan(data).fingerprint()
    assert set(summary["software"]) == {"lookfeel", "torch", "python"}
    pair = summary["pairs"]["depth_to_depth"]
    for key in ("model_top1", "model_top3", "raw_pixels_top1", "raw_pixels_top3"):
        low, high = pair[key]["ci95"]
        assert 0.0 <= low <= pair[key]["mean"] <= high <= 1.0, key
        assert len(pair[key]["per_run"]) == 4
    # 3 held-out fabrics: pick 1 of 10 offers only 3 candidates, and chance says so.
    assert pair["chance_top1"] == pytest.approx(1 / 3)
    assert pair["chance_top3"] == pytest.approx(1.0)
    # Each run held out the fold's own fabrics and trained on the rest.
    seen = set()
    for seed in (0, 1):
        for fold in (0, 1):
            run = tmp_path / "cv" / f"seed{seed}-fold{fold}"
            split = json.loads((run / "split.json").read_text(encoding="utf-8"))
            res = json.loads((run / "result.json").read_text(encoding="utf-8"))
            assert res["test_fabrics"] == split["val"] and len(split["val"]) == 3
            assert not set(split["val"]) & set(split["train"])
            seen.add(tuple(split["val"]))
    assert len(seen) == 2
    props = summary["properties"]["depth"]
    assert set(props["model"]) == set(scan(data).label_columns)
    report = (tmp_path / "cv" / "cv.md").read_text(encoding="utf-8")
    assert report.startswith("Fabric-disjoint cross-validation")
    assert "(1 of all of them where a fold holds fewer than 10: see chance)" in report
    # The labelled fabrics also give matching in label space, fitted on each run's training.
    low, high = pair["model_labels_top1"]["ci95"]
    assert 0.0 <= low <= pair["model_labels_top1"]["mean"] <= high <= 1.0
    assert "Matching in label space" in report and "| depth_to_depth |" in report
    assert any("label space" in line and "trained in" in line for line in logs)
    # Every held-out fabric's own top-1, named as the data names it; its queries in all runs.
    items = pair["per_item"]
    assert sorted(r["fabric_id"] for r in items) == sorted(i for t in seen for i in t)
    assert all(r["item"] == f"F{r['fabric_id']:04d}" and r["runs"] == 2 for r in items)
    assert sum(r["queries"] for r in items) == 2 * 6 * 3  # 2 seeds x 2 folds of 3 x 3 drapes
    assert "Held-out items matched worst" in report

    # A rerun keeps every finished run (nothing is retrained) and gives the same summary.
    before = {p: p.stat().st_mtime_ns for p in (tmp_path / "cv").rglob("last.pt")}
    logs.clear()
    again = cross_validate(config, data, tmp_path / "cv", seeds=[0, 1], n_boot=50, log=logs.append)
    assert all("done before" in line for line in logs)
    assert {p: p.stat().st_mtime_ns for p in before} == before
    assert again["pairs"] == summary["pairs"]


def test_cross_validate_resumes_an_interrupted_run(data: Path, tmp_path: Path):
    config = load_config(RunConfig, TINY, [*OVERRIDES, "train.checkpoint_every=3"])
    run = tmp_path / "cv" / "seed0-fold1"
    # A run of the same config that stopped at step 3 of 6 (as if killed after a checkpoint).
    stopped = ["train.split=fold", "train.fold=1", "train.seed=0", "train.steps=3"]
    train(
        load_config(RunConfig, TINY, [*OVERRIDES, "train.checkpoint_every=3", *stopped]), data, run
    )
    logs: list[str] = []
    cross_validate(config, data, tmp_path / "cv", folds=[1], n_boot=20, log=logs.append)
    assert any("resuming" in line for line in logs)
    assert json.loads((run / "result.json").read_text(encoding="utf-8"))["step"] == 6


def test_cross_validate_errors_name_the_value(data: Path, tmp_path: Path):
    config = load_config(RunConfig, TINY, OVERRIDES)
    with pytest.raises(ConfigError, match="fold 5: the config has train.folds=2"):
        cross_validate(config, data, tmp_path / "cv", folds=[5])


def test_cli_cv_writes_the_report(data: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]):
    args = ["cv", "--config", str(TINY), "--data", str(data), "--out", str(tmp_path / "o")]
    args += ["--only-folds", "0", "--tta", "--n-boot", "20"]
    for o in OVERRIDES:
        args += ["--set", o]
    assert main(args) == 0
    out = capsys.readouterr().out
    assert "| depth_to_depth |" in out and "raw pixels" in out
    summary = json.loads((tmp_path / "o" / "cv.json").read_text(encoding="utf-8"))
    assert summary["tta"] is True and summary["folds"] == [0]
    with pytest.raises(SystemExit):
        main([*args[:7], "--only-folds", "a,b"])


def test_score_checkpoint_on_another_dataset(data: Path, tmp_path: Path):
    from lookfeel.crossval import score_checkpoint

    other = write_tiny_dataset(tmp_path / "other", fabrics=5, drapes=3)
    config = load_config(RunConfig, TINY, [*OVERRIDES, "train.split=none"])
    run = train(config, data, tmp_path / "run")
    scored = score_checkpoint(run.last_checkpoint, other, n_boot=30)
    assert scored["data_root"] == str(other)  # the folder is data_root, as in every output
    pair = scored["pairs"]["depth_to_depth"]
    assert pair["chance_top1"] == pytest.approx(1 / 5)  # pick 1 of 10 offers the 5 fabrics
    for key in ("model_top1", "raw_pixels_top1"):
        low, high = pair[key]["ci95"]
        assert 0.0 <= low <= pair[key]["mean"] <= high <= 1.0
    # The tiny drapes of one fabric are near-copies: raw pixels find them.
    assert pair["raw_pixels_top1"]["mean"] > 0.9


def test_rescoring_keeps_the_runs_and_refuses_another_config(data: Path, tmp_path: Path):
    config = load_config(RunConfig, TINY, OVERRIDES)
    first = cross_validate(config, data, tmp_path / "cv", folds=[0], n_boot=20, log=lambda _: None)
    logs: list[str] = []
    again = cross_validate(
        config, data, tmp_path / "cv", folds=[0], tta=True, n_boot=20, log=logs.append
    )
    assert logs[0] == (
        "seed 0 fold 0: trained before, scoring again (scored with other settings: tta true, "
        "was false)"
    )
    assert again["train_seconds"]["mean"] == first["train_seconds"]["mean"]
    assert again["tta"] is True
    other = load_config(RunConfig, TINY, [*OVERRIDES, "train.lr=0.01"])
    with pytest.raises(ConfigError, match="finished run of another config"):
        cross_validate(other, data, tmp_path / "cv", folds=[0], n_boot=20)


def test_a_cv_names_the_finished_runs_of_its_folder_that_its_summary_leaves_out(
    data: Path, tmp_path: Path
):
    config = load_config(RunConfig, TINY, OVERRIDES)
    out = tmp_path / "cv"
    logs: list[str] = []
    cross_validate(config, data, out, folds=[0], n_boot=20, log=logs.append)
    assert not any("also holds" in line for line in logs)
    # `--only-folds 1` after `--only-folds 0`: its summary is of fold 1, and it says so.
    logs.clear()
    summary = cross_validate(config, data, out, folds=[1], n_boot=20, log=logs.append)
    assert summary["folds"] == [1] and summary["runs"] == 1
    assert json.loads((out / "cv.json").read_text(encoding="utf-8"))["folds"] == [1]
    assert logs[-1] == (
        f"{out} also holds finished runs of seed 0 fold 0, scored with these settings (not in "
        "this summary): `lookfeel cv` with the same options but --seeds 0 --only-folds 0,1 "
        "summarises them together without training"
    )
    logs.clear()
    both = cross_validate(config, data, out, folds=[0, 1], n_boot=20, log=logs.append)
    assert both["runs"] == 2 and all("done before, kept" in line for line in logs)
    # Only finished runs of these settings on this data count: a result of seed 1 counts, one
    # scored otherwise, one of other data, an unfinished run and a folder cv never makes do not.
    result = json.loads((out / "seed0-fold1" / "result.json").read_text(encoding="utf-8"))

    def planted(name: str, seed: int, **changes: object) -> None:
        res = json.loads(json.dumps(result | changes)) | {"seed": seed}
        res["key"]["config"]["train"]["seed"] = seed
        (out / name).mkdir()
        (out / name / "result.json").write_text(json.dumps(res), encoding="utf-8")

    planted("seed1-fold1", 1)
    planted("seed2-fold1", 2, key={**result["key"], "tta": True})
    planted("seed3-fold1", 3, data_root="elsewhere", data_fingerprint="0123456789abcdef")
    planted("seed01-fold1", 1)
    (out / "seed4-fold1" / "checkpoints").mkdir(parents=True)
    logs.clear()
    cross_validate(config, data, out, folds=[0], n_boot=20, log=logs.append)
    assert [line for line in logs if "also holds" in line] == [
        f"{out} also holds finished runs of seed 0 fold 1, seed 1 fold 1, scored with these "
        "settings (not in this summary): `lookfeel cv` with the same options but --seeds 0,1 "
        "--only-folds 0,1 summarises them together, running seed 1 fold 0 first"
    ]
    # Scored with --tta: only the run scored so counts.
    logs.clear()
    cross_validate(config, data, out, folds=[0], tta=True, n_boot=20, log=logs.append)
    assert [line for line in logs if "also holds" in line] == [
        f"{out} also holds finished runs of seed 2 fold 1, scored with these settings (not in "
        "this summary): `lookfeel cv` with the same options but --seeds 0,2 --only-folds 0,1 "
        "summarises them together, running seed 0 fold 1, seed 2 fold 0 first"
    ]


def test_a_cv_folder_keeps_its_runs_for_the_same_data_moved_and_refuses_other_data(
    data: Path, tmp_path: Path
):
    import shutil

    config = load_config(RunConfig, TINY, OVERRIDES)
    cross_validate(config, data, tmp_path / "cv", folds=[0], n_boot=20, log=lambda _: None)
    moved = Path(shutil.copytree(data, tmp_path / "moved"))
    logs: list[str] = []
    cross_validate(config, moved, tmp_path / "cv", folds=[0], n_boot=20, log=logs.append)
    assert logs == [f"seed 0 fold 0: done before, kept ({tmp_path / 'cv' / 'seed0-fold0'}"
                    "/result.json)"]  # fmt: skip
    # The same fabrics with one more drape, or a label changed, is another dataset.
    other = write_tiny_dataset(tmp_path / "other", fabrics=7, drapes=4)
    with pytest.raises(ConfigError, match=re.escape(f"holds a run on another dataset ({data})")):
        cross_validate(config, other, tmp_path / "cv", folds=[0], n_boot=20)
    labels = moved / "labels.csv"
    lines = labels.read_text(encoding="utf-8").splitlines()
    head, row = lines[0].split(","), lines[1].split(",")
    col = head.index("thickness_mm")
    row[col] = str(float(row[col]) + 1.0)
    labels.write_text("\n".join([lines[0], ",".join(row), *lines[2:]]) + "\n", encoding="utf-8")
    with pytest.raises(ConfigError, match="before its files or labels changed"):
        cross_validate(config, moved, tmp_path / "cv", folds=[0], n_boot=20)
    # The same names and labels with other pixels (a world rendered again at another seed):
    # a file of another size is another dataset too.
    again = Path(shutil.copytree(data, tmp_path / "again"))
    image = next(iter(sorted((again / "depth").iterdir())))
    image.write_bytes(image.read_bytes() + b"\0")
    with pytest.raises(ConfigError, match="before its files or labels changed"):
        cross_validate(config, again, tmp_path / "cv", folds=[0], n_boot=20)


def test_a_cv_folder_of_an_earlier_lookfeel_resumes_and_is_summarised_as_before(
    data: Path, tmp_path: Path
):
    """cv.json and each result.json name the dataset ``data_root`` and ``data_fingerprint``,
    as index info and embed do, where they held ``data: {root, fingerprint}``. A folder of the
    earlier form is read alike: its runs are kept (nothing trained or scored again) and
    summarised as before, another dataset's refused by its folder, and a finished run of it
    outside the summary is named."""
    config = load_config(RunConfig, TINY, OVERRIDES)
    out = tmp_path / "cv"
    summary = cross_validate(config, data, out, folds=[0], n_boot=20, log=lambda _: None)
    fingerprint = scan(data).fingerprint()
    path = out / "seed0-fold0" / "result.json"
    res = json.loads(path.read_text(encoding="utf-8"))
    for written in (summary, json.loads((out / "cv.json").read_text(encoding="utf-8")), res):
        assert (written["data_root"], written["data_fingerprint"]) == (str(data), fingerprint)
        assert "data" not in written
    # No loss.options given: the key is as before options existed, so an earlier folder's
    # results (whose keys have none) are its own, not "trained before, scoring again".
    assert "options" not in res["key"]["config"]["loss"]

    def earlier(result: dict, root: str, fingerprint: str) -> dict:
        """``result`` as lookfeel wrote it before the rename."""
        old = {k: v for k, v in result.items() if k not in ("data_root", "data_fingerprint")}
        return old | {"data": {"root": root, "fingerprint": fingerprint}}

    kept = json.dumps(earlier(res, str(data), fingerprint))
    path.write_text(kept, encoding="utf-8")
    trained = {p: p.stat().st_mtime_ns for p in out.rglob("last.pt")}
    logs: list[str] = []
    again = cross_validate(config, data, out, folds=[0], n_boot=20, log=logs.append)
    assert logs == [f"seed 0 fold 0: done before, kept ({path})"]
    assert path.read_text(encoding="utf-8") == kept  # kept as it was, not written again
    assert {p: p.stat().st_mtime_ns for p in trained} == trained
    assert json.dumps(again, sort_keys=True) == json.dumps(summary, sort_keys=True)
    # A finished run of the earlier form outside the summary counts as one; on other data not.
    for seed, at in ((1, str(data)), (2, "elsewhere")):
        other = earlier(res, at, fingerprint if seed == 1 else "0123456789abcdef")
        other["seed"] = seed
        other["key"]["config"]["train"]["seed"] = seed
        (out / f"seed{seed}-fold0").mkdir()
        (out / f"seed{seed}-fold0" / "result.json").write_text(json.dumps(other), encoding="utf-8")
    logs.clear()
    cross_validate(config, data, out, folds=[0], n_boot=20, log=logs.append)
    assert logs[-1].startswith(f"{out} also holds finished runs of seed 1 fold 0, scored with")
    # The earlier form on other data is refused, naming the folder it recorded.
    path.write_text(json.dumps(earlier(res, "elsewhere", "0123456789abcdef")), encoding="utf-8")
    with pytest.raises(ConfigError, match=re.escape("holds a run on another dataset (elsewhere)")):
        cross_validate(config, data, out, folds=[0], n_boot=20, log=lambda _: None)


def test_a_fingerprint_recorded_before_file_sizes_counted_still_matches(data: Path):
    import hashlib
    import json
    import os

    catalog = scan(data)
    rows = [  # the digest as lookfeel took it up to session 52 (names and labels only)
        [
            f.id,
            f.name,
            sorted(f.labels.items()),
            sorted(f.text_labels.items()),
            f.cluster,
            [
                [m.value, [[os.path.relpath(p, data) for p in it.frames] for it in its]]
                for m, its in sorted(f.items.items(), key=lambda kv: kv[0].value)
            ],
        ]
        for f in catalog.fabrics
    ]
    old = hashlib.sha256(json.dumps(rows).encode()).hexdigest()[:16]
    assert old != catalog.fingerprint()
    assert catalog.matches_fingerprint(old) and catalog.matches_fingerprint(catalog.fingerprint())
    assert not catalog.matches_fingerprint("0123456789abcdef")


def test_an_auto_property_head_is_the_same_run_when_scored_again(data: Path, tmp_path: Path):
    auto = load_config(RunConfig, TINY, [*OVERRIDES, "model.num_properties=auto"])
    cross_validate(auto, data, tmp_path / "cv", folds=[0], n_boot=20, log=lambda _: None)
    logs: list[str] = []
    cross_validate(auto, data, tmp_path / "cv", folds=[0], tta=True, n_boot=20, log=logs.append)
    assert logs[0] == (
        "seed 0 fold 0: trained before, scoring again (scored with other settings: tta true, "
        "was false)"
    )
    saved = json.loads(
        (tmp_path / "cv" / "seed0-fold0" / "result.json").read_text(encoding="utf-8")
    )
    assert saved["key"]["config"]["model"]["num_properties"] == "auto"
    assert set(saved["properties"]["depth"]["model"]) == {
        "thickness_mm",
        "density",
        "stiffness",
        "stretchiness",
    }


def test_synth_cross_config_trains_every_pair_with_its_property_head(data: Path, tmp_path: Path):
    """The shipped cross-modal config runs as docs/synth.md says, on a small synthetic world."""
    path = Path(__file__).resolve().parents[1] / "configs" / "synth_cross.yaml"
    overrides = ["train.folds=2", "train.fold_size=3", "train.steps=4", "train.val_every=0"]
    config = load_config(RunConfig, path, [*overrides, "data.image_size=32"])
    summary = cross_validate(config, data, tmp_path / "cv", n_boot=20)
    modalities = ("depth", "color", "touch")
    pairs = {f"{a}_to_{b}" for a in modalities for b in modalities}
    assert set(summary["pairs"]) == pairs
    for pair, entry in summary["pairs"].items():  # cross-modal pairs: also through the map
        a, b = pair.split("_to_")
        assert ("model_mapped_top1" in entry) == (a != b), pair
        if a != b:
            low, high = entry["model_mapped_top1"]["ci95"]
            assert 0.0 <= low <= entry["model_mapped_top1"]["mean"] <= high <= 1.0
    assert "model_mapped_swapped_top1" in summary["pairs"]["touch_to_depth"]
    assert "Matching through a cross-modal map" in (tmp_path / "cv" / "cv.md").read_text(
        encoding="utf-8"
    )
    run = tmp_path / "cv" / "seed0-fold0"
    saved = yaml.safe_load((run / "config.yaml").read_text(encoding="utf-8"))
    assert saved["model"]["branch_dropout"] == {"depth": 0.3, "touch": 0.3}
    assert saved["model"]["dropout"] == 0.0  # colour's branch
    assert saved["data"]["touch_frames"] == [0, 1, 2]  # a press's three frames, stacked
    assert saved["loss"]["pair_weights"] == {"color_touch": 0.0}  # colour meets touch via depth
    assert (
        torch.load(run / "checkpoints" / "last.pt", weights_only=True)["model"][
            "branches.touch.backbone.features.0.0.weight"
        ].shape[1]
        == 9
    )
    logged = [
        json.loads(line)
        for line in (run / "metrics.jsonl").read_text(encoding="utf-8").splitlines()
    ]
    terms = {k for row in logged for k in row if k.endswith("_loss")}
    assert {"depth_color_loss", "depth_touch_loss", "property_loss"} <= terms
    assert "color_touch_loss" not in terms  # colour and touch meet through depth


@pytest.mark.filterwarnings("ignore:pick 10")
def test_background_control_in_cv_and_evaluate(
    leaky_depth: Path, tmp_path: Path, capsys: pytest.CaptureFixture
):
    """A dataset whose room identifies the fabric (a planted session leak): raw pixels drop
    when the backgrounds are swapped; the control's keys are in cv.json, cv.md, metrics.json
    and report.md, and are gone when it is turned off."""
    from lookfeel.evaluate import evaluate_checkpoint, write_report

    data = leaky_depth
    config = load_config(RunConfig, TINY, [*OVERRIDES, "train.steps=2", "train.split_seed=1"])
    summary = cross_validate(config, data, tmp_path / "cv", folds=[0], n_boot=20, log=print)
    pair = summary["pairs"]["depth_to_depth"]
    swapped_keys = ("model_swapped_top1", "model_swapped_top3", "raw_pixels_swapped_top1")
    for key in (*swapped_keys, "model_labels_swapped_top1"):
        low, high = pair[key]["ci95"]
        assert 0.0 <= low <= pair[key]["mean"] <= high <= 1.0, key
    assert summary["background_control"] == {"on": True, "seed": 0, "skipped": None}
    assert pair["raw_pixels_top1"]["mean"] > pair["raw_pixels_swapped_top1"]["mean"] + 0.2
    md = (tmp_path / "cv" / "cv.md").read_text(encoding="utf-8")
    assert "Background control" in md and "raw pixels top-1, background swapped" in md
    assert "label space top-1, background swapped" in md
    # The room alone as a property probe, beside the model's (the room here sits 20 mm a
    # fabric apart and thickness grows with the fabric: it reads thickness from the room).
    room = summary["properties"]["depth"]["room"]
    assert set(room) == set(summary["properties"]["depth"]["model"])
    assert room["thickness_mm"]["r2"] > 0.5
    assert "room alone R²" in md and "Room alone:" in md
    # Off: no control keys, and the summary says so.
    off = cross_validate(
        config, data, tmp_path / "cv", folds=[0], n_boot=20, background_control=False
    )
    assert "model_swapped_top1" not in off["pairs"]["depth_to_depth"]
    assert "model_labels_swapped_top1" not in off["pairs"]["depth_to_depth"]
    assert off["background_control"]["on"] is False
    assert "room" not in off["properties"]["depth"]
    assert "room alone" not in (tmp_path / "cv" / "cv.md").read_text(encoding="utf-8")

    ckpt = tmp_path / "cv" / "seed0-fold0" / "checkpoints" / "last.pt"
    result = evaluate_checkpoint(ckpt, data, "val", EvalConfig(n_boot=20))
    m = result.metrics
    for key in ("depth_to_depth_top1_swapped", "depth_to_depth_raw_pixels_top1_swapped"):
        assert 0.0 <= m[f"{key}_ci_low"] <= m[key] <= m[f"{key}_ci_high"] <= 1.0, key
    assert m["depth_to_depth_raw_pixels_top1"] > m["depth_to_depth_raw_pixels_top1_swapped"]
    report = (write_report(result, tmp_path / "eval").report).read_text(encoding="utf-8")
    assert "## Background control" in report
    plain = evaluate_checkpoint(ckpt, data, "val", EvalConfig(n_boot=20, background_control=False))
    assert not any(k.endswith("_swapped") for k in plain.metrics)

    capsys.readouterr()


@pytest.mark.filterwarnings("ignore:pick 10")
def test_room_control_in_cv_and_evaluate_for_registered_depth(leaky_depth: Path, tmp_path: Path):
    """Registered depth gets the room control beside the swap: its keys (model, label space,
    raw pixels) in cv.json and cv.md, in metrics.json and report.md; raw depth does not."""
    from lookfeel.evaluate import evaluate_checkpoint, write_report

    registered = ["data.depth_input=registered", "data.depth_focal_px=45.0"]
    config = load_config(
        RunConfig, TINY, [*OVERRIDES, "train.steps=2", "train.split_seed=1", *registered]
    )
    summary = cross_validate(config, leaky_depth, tmp_path / "cv", folds=[0], n_boot=20)
    pair = summary["pairs"]["depth_to_depth"]
    for key in ("model_room_top1", "model_labels_room_top1", "raw_pixels_room_top1"):
        low, high = pair[key]["ci95"]
        assert 0.0 <= low <= pair[key]["mean"] <= high <= 1.0, key
    md = (tmp_path / "cv" / "cv.md").read_text(encoding="utf-8")
    assert "model top-1, in another fabric's room" in md
    assert "label space top-1, in another fabric's room" in md
    ckpt = tmp_path / "cv" / "seed0-fold0" / "checkpoints" / "last.pt"
    result = evaluate_checkpoint(ckpt, leaky_depth, "val", EvalConfig(n_boot=20))
    m = result.metrics
    for key in ("depth_to_depth_top1_room", "depth_to_depth_raw_pixels_top1_room"):
        assert 0.0 <= m[f"{key}_ci_low"] <= m[key] <= m[f"{key}_ci_high"] <= 1.0, key
    report = (write_report(result, tmp_path / "eval").report).read_text(encoding="utf-8")
    assert "model, in another fabric's room" in report
    raw = load_config(RunConfig, TINY, [*OVERRIDES, "train.steps=2", "train.split_seed=1"])
    raw_summary = cross_validate(raw, leaky_depth, tmp_path / "raw", folds=[0], n_boot=20)
    assert "model_room_top1" not in raw_summary["pairs"]["depth_to_depth"]
    raw_md = (tmp_path / "raw" / "cv.md").read_text(encoding="utf-8")
    assert "another fabric's room" not in raw_md and "background swapped" in raw_md


@pytest.mark.filterwarnings("ignore:model.freeze=to_block4 freezes")
def test_a_run_that_drops_the_cloth_near_the_walls_trains_on_it_and_resumes_exactly(
    leaky_depth: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
):
    """``data.depth_wall_drop`` through `train`: the drops change what the net learns (its
    weights differ from the same run without them), two runs agree bit for bit, and a run
    killed and resumed ends where the unbroken one does (the drops come from the step's seed).
    A frozen trunk's cached run, which reads each drape whole, says so. A band along the walls
    changes no training draw of such a run, and every image of a run without the drops."""

    def state(run: Path) -> dict[str, torch.Tensor]:
        return torch.load(run / "checkpoints" / "last.pt", weights_only=True)["model"]

    registered = ["data.depth_input=registered", "data.depth_focal_px=45.0"]
    base = [*OVERRIDES, "train.steps=4", "train.checkpoint_every=2", *registered]
    plain = load_config(RunConfig, TINY, base)
    # These drapes hang 110-160 mm from the side panel: walls moved up to 200 mm reach them.
    walls = ["data.depth_wall_drop=1.0", "data.depth_wall_shift_mm=200.0"]
    dropping = load_config(RunConfig, TINY, [*base, *walls])
    train(plain, leaky_depth, tmp_path / "plain")
    train(dropping, leaky_depth, tmp_path / "a")
    train(dropping, leaky_depth, tmp_path / "b")
    a, b, without = state(tmp_path / "a"), state(tmp_path / "b"), state(tmp_path / "plain")
    assert all(torch.equal(a[k], b[k]) for k in a)
    assert any(not torch.equal(a[k], without[k]) for k in a)

    class Kill(Exception):
        pass

    def kill(step: int, _: object) -> None:
        if step == 3:
            raise Kill

    with pytest.raises(Kill):
        train(dropping, leaky_depth, tmp_path / "broken", on_step=kill)
    resumed = state(train(dropping, leaky_depth, tmp_path / "broken", resume=True).run_dir)
    assert all(torch.equal(a[k], resumed[k]) for k in a)
    frozen = load_config(RunConfig, TINY, [*base, *walls, "model.freeze=to_block4"])
    with pytest.warns(UserWarning, match=r"data.depth_wall_drop=1 is not used with a frozen"):
        train(frozen, leaky_depth, tmp_path / "frozen")
    # A band along the walls (data.depth_wall_band_mm) reaching these drapes: every draw of a
    # run with depth_wall_drop=1 drops near randomly moved walls instead, so it trains the
    # same weights; without the drop, the band is in every training image.
    band = ["data.depth_wall_band_mm=130.0"]
    banded = load_config(RunConfig, TINY, [*base, *walls, *band])
    import lookfeel.data.register as register

    calls: dict[str, int] = {}
    registering = register.register_configured

    def counted(name: str, config: RunConfig) -> dict[str, torch.Tensor]:
        def count(*args: object) -> object:
            calls[name] = calls.get(name, 0) + 1
            return registering(*args)  # type: ignore[arg-type]

        monkeypatch.setattr(register, "register_configured", count)
        out = state(train(config, leaky_depth, tmp_path / name).run_dir)
        monkeypatch.undo()
        return out

    same = counted("banded", banded)
    assert all(torch.equal(a[k], same[k]) for k in a)
    # Training reads each drape's views alone: the banded image is not registered as well.
    counted("dropping", dropping)
    assert calls["banded"] == calls["dropping"] > 0
    plain_band = state(train(load_config(RunConfig, TINY, [*base, *band]), leaky_depth,
                             tmp_path / "plain_band").run_dir)  # fmt: skip
    assert any(not torch.equal(plain_band[k], without[k]) for k in without)


def test_cv_pools_presses_into_touch_queries_as_evaluate_does(data: Path, tmp_path: Path):
    """With ``presses`` 3 every touch query is one group of 3 presses of a fabric (the
    Multi-input Net's protocol), in the model, raw pixels, label space and through the map;
    cv's numbers through the map equal `lookfeel evaluate`'s on the same run."""
    from lookfeel.evaluate import evaluate_checkpoint

    path = Path(__file__).resolve().parents[1] / "configs" / "synth_cross.yaml"
    overrides = ["train.folds=2", "train.fold_size=3", "train.steps=4", "train.val_every=0"]
    config = load_config(RunConfig, path, [*overrides, "data.image_size=32"])
    single = cross_validate(config, data, tmp_path / "cv", folds=[0], n_boot=20)
    pooled = cross_validate(config, data, tmp_path / "cv", folds=[0], n_boot=20, presses=3)
    assert (single["presses"], pooled["presses"]) == (1, 3)
    run = json.loads((tmp_path / "cv" / "seed0-fold0" / "result.json").read_text(encoding="utf-8"))
    assert run["key"]["presses"] == 3
    held = run["test_fabrics"]
    for pair in ("touch_to_depth", "touch_to_touch"):
        entry = run["pairs"][pair]
        assert sorted(entry["query_fabric"]) == sorted(held)  # 3 fold presses: one query each
        methods = [k for k in entry if k not in ("query_fabric", "chance")]
        assert {"model", "model_labels"} <= set(methods)
        assert all(len(entry[k]) == len(held) for k in methods), pair
    assert "raw_pixels" in run["pairs"]["touch_to_touch"]
    assert len(run["pairs"]["depth_to_touch"]["query_fabric"]) == 3 * len(held)  # drapes
    assert "pools 3 presses of one fabric, as a query and as the candidates" in (
        tmp_path / "cv" / "cv.md"
    ).read_text(encoding="utf-8")

    ckpt = tmp_path / "cv" / "seed0-fold0" / "checkpoints" / "last.pt"
    m = evaluate_checkpoint(ckpt, data, "val", EvalConfig(n_boot=20, presses=3)).metrics
    # Both ways: a touch query pools 3 presses, and so does each touch candidate of a drape.
    for pair in ("touch_to_depth", "touch_to_color", "depth_to_touch", "color_to_touch"):
        for key, method in (("top1", "model"), ("top1_mapped", "model_mapped")):
            cv_top1 = float(np.mean(np.asarray(run["pairs"][pair][method])[:, 0]))
            assert cv_top1 == pytest.approx(m[f"{pair}_{key}"], abs=1e-9), (pair, key)
    with pytest.raises(ConfigError, match="presses"):
        cross_validate(config, data, tmp_path / "cv2", folds=[0], presses=0)
    with pytest.raises(ConfigError, match="no held-out fabric has 4 touch presses"):
        cross_validate(config, data, tmp_path / "cv", folds=[0], presses=4)


def test_the_room_probe_reads_labels_that_follow_the_session_and_no_others(tmp_path: Path):
    """`RoomProbe` on rooms 3 mm a session apart, one fabric a session: thickness grows with
    the fabric (as the room moves) and is read; stretchiness alternates and is not; with one
    room for every session nothing is read; without labels there is no probe."""
    from lookfeel.crossval import RoomProbe

    from ._scene import write_scene_dataset

    train_ids, held_ids = [1, 2, 4, 5, 7, 8], [3, 6]
    moving = scan(write_scene_dataset(tmp_path / "moving", 8, 2, 32, 3.0, 0.3))
    probe = RoomProbe(moving)
    r2 = {k: v["r2"] for k, v in (probe(train_ids, held_ids) or {}).items()}
    assert probe.background_pixels > 0
    assert r2["thickness_mm"] > 0.8 and r2["stretchiness"] < 0.2, r2
    still = scan(write_scene_dataset(tmp_path / "still", 8, 2, 32, 0.0, 0.3))
    r2_still = {k: v["r2"] for k, v in (RoomProbe(still)(train_ids, held_ids) or {}).items()}
    assert r2_still and all(v < 0.2 for v in r2_still.values()), r2_still
    (tmp_path / "moving" / "labels.csv").unlink()
    assert RoomProbe(scan(tmp_path / "moving"))(train_ids, held_ids) is None


def test_each_held_out_item_is_scored_over_its_own_queries_worst_first():
    from lookfeel.crossval.report import _per_item_lines
    from lookfeel.crossval.summary import _per_item
    from lookfeel.modality import Pair

    pair = Pair.parse("touch_to_touch")
    nan = float("nan")
    runs = [
        {"pairs": {pair: {  # item 1 right once in two queries; item 2's query had no pick
            "query_fabric": [1, 1, 2],
            "model": [[1.0, 1.0], [0.0, 1.0], [nan, nan]],
            "raw_pixels": [[1.0, 1.0], [1.0, 1.0], [nan, nan]],
        }}},
        {"pairs": {pair: {
            "query_fabric": [2, 3, 3, 3, 3],
            "model": [[1.0, 1.0], [0.25, 1.0], [0.25, 1.0], [1.0, 1.0], [0.5, 1.0]],
            "raw_pixels": [[0.0, 1.0], [0.0, 0.0], [0.0, 0.0], [0.0, 1.0], [0.0, 1.0]],
        }}},
    ]  # fmt: skip
    rows = _per_item(runs, pair, {1: "sponge", 2: "ruler"})
    # Worst first, ties by name; an unnamed item keeps its id; a query with no pick is not counted.
    assert [r["item"] for r in rows] == ["F0003", "sponge", "ruler"]
    assert [r["model_top1"] for r in rows] == [0.5, 0.5, 1.0]
    assert [r["raw_pixels_top1"] for r in rows] == [0.0, 1.0, 0.0]
    assert [(r["queries"], r["runs"]) for r in rows] == [(4, 1), (2, 1), (1, 1)]
    assert "model_swapped_top1" not in rows[0]  # only what every run scored

    lines = _per_item_lines({"pairs": {pair: {"per_item": rows}}})
    table = [line for line in lines if line.startswith("| touch_to_touch |")]
    assert table[0] == "| touch_to_touch | F0003 | 4 | 0.500 | 0.000 |"
    assert table[-1] == "| touch_to_touch | (1 of 3 items always right) | | | |"
    assert _per_item_lines({"pairs": {pair: {}}}) == []


def test_cli_cv_refuses_a_negative_seed_and_a_too_small_image_before_any_work(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
):
    """``--seeds=-1`` ended in numpy's traceback ("expected non-negative integer") and alexnet
    at 32 px in one from the trunk (QA). Both are one line now, before the folds are made:
    the dataset given does not exist, and OUT is not created."""
    out = tmp_path / "cv"
    args = ["cv", "--config", str(TINY), "--data", str(tmp_path / "none"), "--out", str(out)]
    with pytest.raises(SystemExit) as e:
        main([*args, "--seeds=0,-1,-2"])
    assert e.value.code == 2
    err = capsys.readouterr().err
    assert err.splitlines()[-1] == (
        "lookfeel cv: error: argument --seeds: a seed must be an integer >= 0, got -1, -2"
    )
    assert main([*args, "--set", "model.backbone=alexnet", "--set", "model.width=null"]) == 1
    assert capsys.readouterr().err.startswith(
        "lookfeel: data.image_size=32 is below the 63 px on each side that model.backbone=alexnet"
    )
    assert not out.exists()


def _hand_made_run(fold: int, pairs: dict[str, dict[str, list]]) -> dict:
    """A run's result as `_score` writes it: per pair its queries' fabrics, per method the
    per-query (top-1, top-3), and chance."""
    from lookfeel.modality import Pair

    out = {}
    for name, methods in pairs.items():
        fabrics = [10 * fold + i for i in range(len(methods["model"]))]
        out[Pair.parse(name)] = {"query_fabric": fabrics, "chance": [0.25, 0.75], **methods}
    return {"fold": fold, "pairs": out, "properties": {}}


def _report(results: list[dict], summarise: dict | None = None, **extra) -> tuple[dict, str]:
    """`_summarise` (with ``summarise``'s keyword arguments) and `format_cv_summary` of
    hand-made runs, numpy's warnings as errors."""
    import warnings

    from lookfeel.crossval import format_cv_summary
    from lookfeel.crossval.summary import _summarise
    from lookfeel.evaluate.core import no_query_scored

    pairs = list(results[0]["pairs"])
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)
        summary = _summarise(
            results,
            pairs,
            20,
            why=lambda p: no_query_scored(p, 3, option="--presses "),
            **(summarise or {}),
        )
        summary |= {"folds": [0, 1], "seeds": [0], "fold_size": 4, "presses": 3} | extra
        return summary, format_cv_summary(summary)


def test_a_pair_no_query_of_which_was_scored_says_why_and_warns_nothing():
    """Touch to touch with every press of a fabric in its query has nothing to find in any
    run: cv.json gives the reason instead of NaN numbers, cv.md says so, numpy stays silent;
    the other pairs and a pair scored in only some runs keep their numbers."""
    nan = float("nan")
    runs = [
        _hand_made_run(fold, {
            "touch_to_depth": {"model": [[1.0, 1.0], [0.0, 1.0]]},
            "touch_to_touch": {"model": [[nan, nan]] * 2, "raw_pixels": [[nan, nan]] * 2},
            "depth_to_depth": {"model": [[nan, nan], [nan, nan]] if fold else [[1.0, 1.0]] * 2},
        })
        for fold in (0, 1)
    ]  # fmt: skip
    summary, md = _report(runs)
    t2t = summary["pairs"]["touch_to_touch"]
    assert t2t["not_scored"].startswith("no test fabric has more than 3 touch presses")
    assert t2t["not_scored"].endswith("use --presses 2 or fewer")
    assert not any(k.startswith(("model", "raw_pixels")) for k in t2t)
    assert t2t["chance_top1"] == 0.25 and t2t["per_item"] == []
    assert summary["pairs"]["touch_to_depth"]["model_top1"]["mean"] == pytest.approx(0.5)
    d2d = summary["pairs"]["depth_to_depth"]["model_top1"]  # scored in fold 0 only
    assert d2d["mean"] == 1.0 and np.isnan(d2d["per_run"][1])
    assert "| touch_to_touch | not scored | - | - | - | n/a |" in md  # no chance to beat
    # A number only some runs scored says on how many it rests.
    assert "| depth_to_depth | 1.000 [1.000, 1.000] (1 of 2 runs) |" in md
    assert f"Not scored: touch to touch: {t2t['not_scored']}." in md
    assert "touch to touch picks among the single presses outside the query (none is left" in md
    assert "nan" not in md


@pytest.mark.filterwarnings("error::RuntimeWarning")
def test_cv_with_every_fold_press_in_one_query_marks_touch_to_touch_not_scored(
    data: Path, tmp_path: Path
):
    """The tiny data's 3 fold presses a fabric, pooled 3 at a time: cv trains and scores every
    other pair, and touch to touch carries the reason, with the presses to use, in cv.json,
    cv.md and the run's line."""
    path = Path(__file__).resolve().parents[1] / "configs" / "synth_cross.yaml"
    overrides = ["train.folds=2", "train.fold_size=3", "train.steps=2", "train.val_every=0"]
    pairs = "train.val_pairs=[touch_to_touch,touch_to_depth]"  # the run's line: the first
    config = load_config(RunConfig, path, [*overrides, "data.image_size=32", pairs])
    logs: list[str] = []
    summary = cross_validate(
        config,
        data,
        tmp_path / "cv",
        folds=[0],
        n_boot=20,
        presses=3,
        background_control=False,
        log=logs.append,
    )
    why = summary["pairs"]["touch_to_touch"]["not_scored"]
    assert why == (
        "no held-out fabric has more than 3 touch presses (fold), so each query pools every "
        "press of its fabric and leaves none to find among the single presses it picks from; "
        "use --presses 2 or fewer"
    )
    assert (
        json.loads((tmp_path / "cv" / "cv.json").read_text(encoding="utf-8"))["pairs"][
            "touch_to_touch"
        ]
        == (summary["pairs"]["touch_to_touch"])
    )
    assert 0.0 <= summary["pairs"]["touch_to_depth"]["model_top1"]["mean"] <= 1.0
    assert f"Not scored: touch to touch: {why}." in (tmp_path / "cv" / "cv.md").read_text(
        encoding="utf-8"
    )
    assert logs[-1].startswith("seed 0 fold 0: touch_to_touch not scored (trained in")


def test_cv_md_says_only_what_the_options_made():
    """Without the background control the label-space paragraph points at no control section;
    with it, it does; the room-alone note holds for any dataset; one run is one run."""
    base = {"model": [[1.0, 1.0], [0.0, 1.0]], "model_labels": [[1.0, 1.0], [1.0, 1.0]]}
    _, plain = _report([_hand_made_run(0, {"depth_to_depth": base})], runs=1)
    assert "Matching in label space" in plain and "background" not in plain
    assert plain.startswith("Fabric-disjoint cross-validation: 1 run (")
    swapped = base | {"model_labels_swapped": [[0.0, 1.0], [1.0, 1.0]]}
    summary, control = _report([_hand_made_run(0, {"depth_to_depth": swapped})])
    assert "background swapped, as in the background control below." in control
    probe = {"thickness_mm": {"r2": 0.5, "r2_std": 0.1, "spearman": 0.4, "spearman_std": 0.1}}
    summary["properties"] = {"depth": {"model": probe, "raw_pixels": probe, "room": probe}}
    from lookfeel.crossval import format_cv_summary

    md = format_cv_summary(summary)
    assert "Where it scores, the background follows the labels" in md
    assert "Every fabric was captured in one session" not in md


def test_impossible_folds_or_presses_are_refused_before_anything_is_printed_or_written(
    data: Path, tmp_path: Path
):
    """2 folds of 5 of the 7 fabrics, or touch queries of more presses than any fabric has:
    refused with the numbers, no line logged and no folder made."""
    from lookfeel.data import SplitError

    logs: list[str] = []
    big = load_config(RunConfig, TINY, [*OVERRIDES, "train.fold_size=5"])
    with pytest.raises(SplitError, match="2 folds of 5 fabrics need 10 training fabrics"):
        cross_validate(big, data, tmp_path / "cv", log=logs.append)
    touch = load_config(RunConfig, TINY, ["train.folds=2", "train.fold_size=3"])
    with pytest.raises(ConfigError, match=r"has more than 3\); use --presses 3 or fewer"):
        cross_validate(touch, data, tmp_path / "cv", presses=4, log=logs.append)
    assert logs == [] and not (tmp_path / "cv").exists()


def _strict_json(path: Path) -> dict:
    """``path`` read as strict JSON: a bare NaN or Infinity (Python's own extension) fails."""

    def refuse(constant: str) -> None:
        raise AssertionError(f"{path} holds {constant}, which strict JSON parsers refuse")

    return json.loads(path.read_text(encoding="utf-8"), parse_constant=refuse)


def test_cv_md_says_which_fabrics_were_held_out_and_json_is_strict(tmp_path: Path):
    """QA: a constant label printed ``nan`` in cv.md and a bare NaN in cv.json, and the first
    line said "every fabric held out once" for ``--only-folds 0`` and left out the fabrics kept
    for the paper's test without a word. Now: ``n/a`` with the reason, null in every JSON cv
    writes, and the first line counts what was held out, not run, only trained on, unused."""
    data = write_tiny_dataset(tmp_path / "data", fabrics=8, drapes=2)
    labels = data / "labels.csv"
    rows = [line.split(",") for line in labels.read_text(encoding="utf-8").splitlines()]
    for row in rows[1:]:
        row[5] = "1"  # stretchiness: every fabric 1
    rows[-1][6] = "test"  # fabric 8: the paper's test, never used by cv
    labels.write_text("\n".join(",".join(r) for r in rows) + "\n", encoding="utf-8")
    config = load_config(RunConfig, TINY, OVERRIDES)
    cross_validate(config, data, tmp_path / "cv", folds=[0], n_boot=20, log=lambda _: None)
    summary = _strict_json(tmp_path / "cv" / "cv.json")
    _strict_json(tmp_path / "cv" / "seed0-fold0" / "result.json")
    probe = summary["properties"]["depth"]["model"]["stretchiness"]
    assert probe["r2"] is None and probe["not_scored"] == "every value 1"
    assert (probe["runs"], probe["runs_total"]) == (0, 1)
    assert summary["properties"]["depth"]["model"]["thickness_mm"]["runs"] == 1
    md = (tmp_path / "cv" / "cv.md").read_text(encoding="utf-8")
    assert "nan" not in md.lower()
    assert "| stretchiness | n/a: every value 1 | n/a | n/a | 3 (1 of 1 runs) |" in md
    assert md.startswith(
        "Fabric-disjoint cross-validation: 1 run (folds [0], seeds [0]; 3 of the 8 fabrics held "
        "out, each once, 3 per fold; fold 1 of 2 not run (--only-folds): 3 fabrics not held "
        "out; 1 fabric in no fold, only trained on (2 folds of train.fold_size=3); 1 fabric "
        "never used, neither trained on nor held out (F0008): 1 marked paper_split=test in "
        "labels.csv"
    )
    assert summary["coverage"]["never_used"]["items"] == ["F0008"]
    # 3 held out a fold: top-3 among 3 is always right, so it is n/a, and said so.
    assert "| depth_to_depth |" in md and "Top-3 is n/a for depth to depth" in md


def test_folds_holding_out_one_item_are_refused_before_anything_is_trained(
    data: Path, tmp_path: Path
):
    """QA: 3 objects in 3 folds ran, every score 1.000 and chance 1.000 (one held-out object
    finds itself among itself). Now a fold must hold out 2: refused in one line naming the
    flag and the counts, before any line is logged or the folder made; objects are objects."""
    from lookfeel.crossval.run import _fold_plan
    from lookfeel.data import SplitError

    from ._tiny import write_recordings

    logs: list[str] = []
    config = load_config(RunConfig, TINY, [*OVERRIDES, "train.fold_size=null", "train.folds=4"])
    with pytest.raises(SplitError, match=r"^--folds 4 \(train.folds\) of the 7 fabrics of .* "
                       r"leaves 1 held out in some fold; .*: use --folds 3 or fewer$"):  # fmt: skip
        cross_validate(config, data, tmp_path / "cv", log=logs.append)
    one = load_config(RunConfig, TINY, [*OVERRIDES, "train.fold_size=1"])
    with pytest.raises(SplitError, match=r"^--fold-size 1 \(train.fold_size\): .* use "
                       "--fold-size 2 or more"):  # fmt: skip
        cross_validate(one, data, tmp_path / "cv", log=logs.append)
    assert logs == [] and not (tmp_path / "cv").exists()
    labels = "object,hardness\n" + "".join(f"{n},{i % 3}\n" for i, n in enumerate("abcde"))
    five = scan(write_recordings(tmp_path / "five", dict.fromkeys("abcde", 2), labels))
    three_folds = load_config(RunConfig, TINY, ["train.folds=3"])
    with pytest.raises(SplitError, match=r"--folds 3 \(train.folds\) of the 5 objects of "):
        _fold_plan(five, three_folds, [0])
    assert _fold_plan(five, load_config(RunConfig, TINY, ["train.folds=2"]), [0])["noun"] == (
        "object"
    )
    three = scan(write_recordings(tmp_path / "three", dict.fromkeys("abc", 2), labels))
    with pytest.raises(SplitError, match=r"has 3 objects to hold out; cross-validation needs "
                       "at least 4"):  # fmt: skip
        _fold_plan(three, three_folds, [0])


def test_cv_md_says_on_how_many_runs_each_number_rests():
    """QA (4 of 12 objects labelled, 6 folds): a probe from the one fold with 2 labelled
    held-out objects stood as "mean ± std over runs", a column of one value printed nan, and
    the label-space table vanished because one fold had none, without a word. Now each probe
    row counts its runs and held-out objects, a Spearman over 2 is n/a (it is ±1), a label no
    run could score says why, and a section a run lacked says which run and why."""
    nan = float("nan")

    def probe(r2: float, spearman: float, n_test: int) -> dict:
        return {"r2": r2, "spearman": spearman, "mae": nan, "n_train": 3.0, "n_test": n_test}

    runs = []
    for fold in range(3):
        both = {"model": [[1.0, 1.0], [0.0, 1.0]]}
        if fold != 1:  # fold 1 had too few labelled training objects for a label space
            both["model_labels"] = [[1.0, 1.0], [1.0, 1.0]]
        run = _hand_made_run(fold, {"touch_to_touch": both})
        table = {
            "hardness": probe(0.5, 1.0, 2) if fold == 0 else probe(nan, nan, fold - 1),
            "roughness": probe(0.1 * fold, 0.5, 4),
            "bumpiness": probe(nan, nan, 4),
        }
        run["properties"] = {"touch": {"model": table, "raw_pixels": table}}
        runs.append(run)
    values = {"hardness": [0.0, 1.0, 2.0], "roughness": [0.0, 1.0], "bumpiness": [0.0] * 4}
    summary, md = _report(runs, {"label_values": values, "noun": "object"})
    rows = {line.split(" | ")[0][2:]: line for line in md.splitlines() if line.startswith("| ")}
    assert rows["hardness"] == (
        "| hardness | 0.50 (1 of 3 runs) | n/a: at most 2 labelled held-out objects a fold: "
        "their Spearman is ±1 whatever the probe predicts | 0.50 (1 of 3 runs) | n/a | 1 of 3 (2) |"
    )
    assert rows["roughness"] == (
        "| roughness | 0.10 ± 0.10 | 0.50 ± 0.00 | 0.10 ± 0.10 | 0.50 ± 0.00 | 3 of 3 (12) |"
    )
    assert rows["bumpiness"] == "| bumpiness | n/a: every value 0 | n/a | n/a | n/a | 0 of 3 (0) |"
    assert "| label | model R² | model Spearman | raw pixels R² | raw pixels Spearman | runs " in md
    one_fold = _report(runs, {"noun": "object"})[1]  # without the values: from the runs
    assert "| bumpiness | n/a: the held-out values are alike within each fold |" in one_fold
    assert summary["pairs"]["touch_to_touch"]["missing_in"] == {"model_labels": ["fold 1"]}
    assert "Matching in label space: not shown for pairs some run could not score (touch to " \
        "touch: fold 1: no label column had 3 or more labelled training objects" in md  # fmt: skip
    assert "| touch_to_touch | model top-1 | label space" not in md
    assert md.startswith("Object-disjoint cross-validation") and "fabric" not in md


def test_a_temperature_at_the_search_edge_is_marked_not_fitted():
    """QA: "temperature 15455.50" printed as if fitted, from a head that knows nothing; and
    "right" differed from the classes table's accuracy with no word of why. Now it is n/a at
    the search edge, left out of what to put in model.class_temperature, and the table says
    how each is averaged; a head's fitted temperature is still given."""
    from lookfeel.crossval.report import _calibration_lines
    from lookfeel.crossval.summary import _calibration
    from lookfeel.metrics.classes import logit_temperature, softmax

    rng = np.random.default_rng(2)
    u = rng.normal(0, 1.5, (300, 3))
    truth = (rng.random(300)[:, None] > softmax(u).cumsum(1)).sum(1)
    guess = rng.integers(0, 3, 300)  # classes unrelated to the logits: no temperature fits
    assert logit_temperature(u, guess).at_edge and not logit_temperature(3 * u, truth).at_edge
    sure = [{"truth": t.tolist(), "logits": (3 * u[i::2]).tolist()} for i, t in
            enumerate((truth[0::2], truth[1::2]))]  # fmt: skip
    blind = [{"truth": guess[i::2].tolist(), "logits": u[i::2].tolist()} for i in range(2)]
    c_sure, c_blind = _calibration(sure), _calibration(blind)
    assert c_blind["temperature_search_edge"] > 100 and math.isnan(c_blind["temperature"])
    assert c_blind["cross_fitted_at_edge"] == 2
    assert c_sure["temperature"] == pytest.approx(3.0, rel=0.3)
    assert math.isnan(c_sure["temperature_search_edge"])
    lines = _calibration_lines(
        "touch", {"hardness": {"calibration": c_sure}, "material": {"calibration": c_blind}}
    )
    text = "\n".join(lines)
    (row,) = [line for line in lines if line.startswith("| material |")]
    assert row.endswith("| n/a: at the search edge (" + f"{c_blind['temperature_search_edge']:.3g}"
                        + "): not fitted |")  # fmt: skip
    assert "(at the search edge in 2 of 2 runs)" in row
    assert "Not fitted: material:" in text
    assert f"`model.class_temperature: {{hardness: {c_sure['temperature']:.2f}}}`" in text
    assert "right is over them all, where the classes table averages each run's" in text
    assert "held-out presses" in text and "presss" not in text


def test_a_catalog_reads_its_files_sizes_once_however_often_it_is_fingerprinted(
    data: Path, monkeypatch: pytest.MonkeyPatch
):
    """evaluate fingerprints one scan up to three times (the run's data, the selection check,
    the embeddings' record): each read every file's size again."""
    from lookfeel.data import catalog as catalog_module

    catalog = scan(data)
    sized: list[Path] = []
    size = catalog_module._size
    monkeypatch.setattr(catalog_module, "_size", lambda p: sized.append(p) or size(p))
    first = catalog.fingerprint()
    assert catalog.matches_fingerprint(first) and catalog.fingerprint() == first
    files = sum(len(it.frames) for f in catalog.fabrics for its in f.items.values() for it in its)
    assert len(sized) == files > 0


def _probe_runs(
    seeds: tuple[int, ...] = (0, 1), folds: tuple[int, ...] = (0, 1, 2)
) -> tuple[list[dict], np.ndarray, np.ndarray]:
    """Runs of 30 fabrics in 3 folds (fabric i in fold (i - 1) % 3), each probed by `_probe` as
    `_score` probes them: ``stiffness`` is the embedding's first coordinate (a ridge finds it
    exactly), ``noise`` is drawn apart from it; raw pixels are noise too. Returns the runs,
    each fabric's labels (30, 2) and fold."""
    from lookfeel.crossval.score import _probe
    from lookfeel.data import Catalog, Fabric

    rng = np.random.default_rng(21)
    ids = np.arange(1, 31)
    centre = rng.standard_normal((30, 4))
    labels = np.stack([2.0 * centre[:, 0] + 1.0, rng.standard_normal(30)], 1)
    catalog = Catalog(
        root=Path("."),
        fabrics=tuple(
            Fabric(int(i), {"stiffness": float(s), "noise": float(n)})
            for i, (s, n) in zip(ids, labels, strict=True)
        ),
        label_columns=("stiffness", "noise"),
    )
    item_fabric = np.repeat(ids, 2)  # two items a fabric, averaged by the probe
    fold_of = (ids - 1) % 3
    runs = []
    for seed in seeds:
        emb = centre[item_fabric - 1] + 0.01 * rng.standard_normal((60, 4))  # a seed's model
        pix = rng.standard_normal((60, 6))
        for fold in folds:
            held = fold_of[item_fabric - 1] == fold
            props = {
                name: _probe(catalog, x[~held], item_fabric[~held], x[held], item_fabric[held])
                for name, x in (("model", emb), ("raw_pixels", pix))
            }
            run = _hand_made_run(fold, {"depth_to_depth": {"model": [[1.0, 1.0], [0.0, 1.0]]}})
            runs.append(run | {"seed": seed, "properties": {"depth": props}})
    return runs, labels, fold_of


def test_probes_pool_each_seeds_held_out_fabrics_with_intervals_and_chance():
    """Each run keeps every held-out fabric's prediction; a seed's folds pooled cover every
    fabric once, and R², Spearman and chance R² over them get 95% intervals resampling the
    fabrics: a label the embedding holds scores near 1, one it does not near chance (an R²
    a little below 0, a Spearman interval around 0); chance R² is the fold's training mean
    predicted, worked out here by hand. The mean over seeds and its interval, as the class
    tables; the per-run mean ± std stays in cv.json."""
    from lookfeel.crossval.summary import _summarise_probes

    runs, labels, fold_of = _probe_runs()
    kept = runs[0]["properties"]["depth"]["model"]["stiffness"]["held_out"]
    assert kept["fabric"] == list(range(1, 31, 3))  # fold 0 holds out fabrics 1, 4, ..., 28
    assert kept["truth"] == pytest.approx(labels[0::3, 0]) and len(kept["pred"]) == 10
    assert kept["train_mean"] == pytest.approx(labels[fold_of != 0, 0].mean())
    props = _summarise_probes(runs, None, "fabric", n_boot=300)["depth"]
    stiff, noise = props["model"]["stiffness"], props["model"]["noise"]
    for row in (stiff, noise):  # the per-run scores, as before
        assert row["runs"] == 6 and not math.isnan(row["r2_std"]) and "spearman_std" in row
    pooled = stiff["pooled"]
    assert pooled["held_out"] == 30 and pooled["seeds"] == [0, 1]
    assert len(pooled["r2"]["per_seed"]) == 2 and len(pooled["r2"]["per_seed_ci95"]) == 2
    assert pooled["r2"]["mean"] == pytest.approx(np.mean(pooled["r2"]["per_seed"]))
    for score in ("r2", "spearman"):
        low, high = pooled[score]["ci95"]
        assert 0.9 <= low <= pooled[score]["mean"] <= high <= 1.0, score
    # Chance: each fold's training mean for its held-out fabrics, over all 30 at once.
    for j, row in ((0, stiff), (1, noise)):
        truth = labels[:, j]
        guess = np.array([truth[fold_of != f].mean() for f in fold_of])
        want = 1.0 - ((truth - guess) ** 2).sum() / ((truth - truth.mean()) ** 2).sum()
        chance = row["pooled"]["chance_r2"]
        assert chance["mean"] == pytest.approx(want) and -0.3 < want <= 0.0
        assert chance["per_seed"] == pytest.approx([want, want])  # the labels alone: no seed
    low, high = noise["pooled"]["spearman"]["ci95"]
    assert low < 0.0 < high
    low, high = noise["pooled"]["r2"]["ci95"]
    assert low < noise["pooled"]["chance_r2"]["mean"] < high and -0.15 < high < 0.3
    raw = props["raw_pixels"]["stiffness"]["pooled"]["r2"]
    assert raw["ci95"][1] < 0.5  # pixels of noise hold nothing of it
    # One seed: its own interval is the interval.
    one = _summarise_probes(runs[:3], None, "fabric", n_boot=300)["depth"]["model"]["noise"]
    assert one["pooled"]["r2"]["ci95"] == one["pooled"]["r2"]["per_seed_ci95"][0]


def test_cv_md_shows_the_pooled_probes_and_old_summaries_as_before():
    """cv.md's probe tables: R² in one, Spearman in the next, each for the model, raw pixels
    and chance [95%] per label, and the fabrics each row is over (a seed's) with the runs
    that predicted them; a cv of some folds (--only-folds) says which fabrics it pools; a
    summary of runs scored before the predictions were kept shows its table as it was."""
    from lookfeel.crossval.report import _interval

    runs, _, _ = _probe_runs()
    summary, md = _report(runs)
    stiff = summary["properties"]["depth"]["model"]["stiffness"]
    raw = summary["properties"]["depth"]["raw_pixels"]["stiffness"]["pooled"]
    p = stiff["pooled"]
    for score in ("r2", "spearman"):
        assert (
            f"| stiffness | {_interval(p[score])} | {_interval(raw[score])} | "
            f"{_interval(p[f'chance_{score}'])} | 30 (6 of 6 runs) |"
        ) in md
    assert "| label | model R² | raw pixels R² | chance R² | fabrics (runs) |" in md
    assert (
        "| label | model Spearman | raw pixels Spearman | chance Spearman | fabrics (runs) |"
    ) in md
    assert "the mean over 2 seeds. Chance: each fold's training mean" in md
    assert "Pooled over" not in md and "nan" not in md
    # Two of the three folds run: the pooled numbers are over their 20 fabrics, and said so.
    some = [r for r in runs if r["fold"] != 2]
    coverage = {
        "held_out": [i for i in range(1, 31) if i % 3 != 0],
        "items": 30,
        "fold_sizes": [10, 10],
        "folds_total": 3,
        "not_run": {"folds": [2], "items": list(range(3, 31, 3))},
        "train_only": [],
        "never_used": {"ids": [], "items": [], "why": None},
    }
    summary, md = _report(some, coverage=coverage)
    assert summary["properties"]["depth"]["model"]["stiffness"]["pooled"]["held_out"] == 20
    assert (
        "Pooled over the 20 fabrics the folds run held out, not every fabric (1 of the 3 folds "
        "not run: --only-folds)."
    ) in md
    # Runs scored before: no predictions kept, the table as it was.
    for r in runs:
        for per in r["properties"]["depth"].values():
            for c in per.values():
                del c["held_out"]
    old, md = _report(runs)
    assert "pooled" not in old["properties"]["depth"]["model"]["stiffness"]
    assert "| label | model R² | model Spearman | raw pixels R² | raw pixels Spearman | runs " in md
    assert "chance R²" not in md and " ± " in md


def test_a_run_scored_before_probe_predictions_were_kept_is_scored_again():
    """A kept result stands only when its key matches: with labels, the key now asks for the
    probes' held-out predictions, so a run scored before is scored again, not kept."""
    from lookfeel.crossval.run import _result_key
    from lookfeel.modality import Pair

    config = load_config(RunConfig, TINY, OVERRIDES)
    pairs = [Pair.parse("depth_to_depth")]
    assert _result_key(config, False, pairs, 1, None, labelled=True)["probe_predictions"]
    assert "probe_predictions" not in _result_key(config, False, pairs, 1, None, labelled=False)


def _kept_runs(
    folds: list[dict[str, tuple[list[float], list[float]]]], seeds: tuple[int, ...] = (0,)
) -> list[dict]:
    """Hand-made runs whose probes kept their held-out predictions, with known answers:
    ``folds[f][label]`` is (the truths of fold f's labelled held-out fabrics, the probe's
    predictions of them). Fold f holds out the next block of fabric ids (as long as its
    longest list); its chance, the training mean, is the mean of the other folds' truths
    (0 for a fold alone);
    each run's own scores are `ProbeColumn.scores`, as `_probe` writes them. Raw pixels
    predict as the model; every seed's runs are the same."""
    from lookfeel.metrics.properties import ProbeColumn

    runs = []
    for seed in seeds:
        start = 1
        for f, fold in enumerate(folds):
            table = {}
            for label, (truth, pred) in fold.items():
                ids = list(range(start, start + len(truth)))
                others = [t for g, o in enumerate(folds) if g != f for t in o[label][0]]
                col = ProbeColumn(
                    np.array(ids), np.array(truth, float), np.array(pred, float),
                    len(others), float(np.mean(others)) if others else 0.0,
                )  # fmt: skip
                held = {"fabric": ids, "truth": truth, "pred": pred, "train_mean": col.train_mean}
                table[label] = col.scores() | {"held_out": held}
            start += max(len(t) for t, _ in fold.values())
            run = _hand_made_run(f, {"depth_to_depth": {"model": [[1.0, 1.0], [0.0, 1.0]]}})
            props = {"depth": {"model": table, "raw_pixels": table}}
            runs.append(run | {"seed": seed, "properties": props})
    return runs


def test_chance_spearman_is_measured_from_the_folds_not_said_to_be_0():
    """QA: cv.md said "chance Spearman is 0", false once folds are pooled: a fold's training
    mean is anti-correlated with that fold's held-out labels. Folds {1, 2} and {3, 4}: chance
    predicts 3.5 for 1 and 2 and 1.5 for 3 and 4, ties within each fold ranked as one value
    (mid-ranks): Spearman -2/sqrt(5), R² 1 - 17/5. The tables show it, with its interval,
    beside raw pixels' Spearman, and say why the model is read against it."""
    from lookfeel.crossval.report import _interval

    runs = _kept_runs(
        [{"stiffness": ([1.0, 2.0], [1.0, 2.0])}, {"stiffness": ([3.0, 4.0], [3.0, 4.0])}]
    )
    summary, md = _report(runs)
    pooled = summary["properties"]["depth"]["model"]["stiffness"]["pooled"]
    chance = pooled["chance_spearman"]
    assert chance["mean"] == pytest.approx(-2.0 / math.sqrt(5.0))
    assert chance["per_seed"] == pytest.approx([-2.0 / math.sqrt(5.0)])
    assert -1.0 <= chance["ci95"][0] <= chance["mean"] <= chance["ci95"][1] <= 1.0
    assert pooled["chance_r2"]["mean"] == pytest.approx(1.0 - 17.0 / 5.0)
    assert pooled["spearman"]["mean"] == pytest.approx(1.0)  # the probe is right
    assert "chance Spearman is 0" not in md
    assert "| label | model Spearman | raw pixels Spearman | chance Spearman |" in md
    assert f"| {_interval(pooled['spearman'])} | {_interval(chance)} | 4 (2 of 2 runs) |" in md
    assert (
        "Pooling folds pulls R² and Spearman down, chance's and the model's alike (a known bias "
        "of cross-validated R² and correlation: each fold's training mean lies away from that "
        "fold's held-out fabrics), so read the model's numbers against the chance column, not "
        "against 0."
    ) in md
    # One fold run: one training mean, no order to rank; n/a, and said why.
    md = _report(_kept_runs([{"stiffness": ([1.0, 2.0, 4.0], [1.0, 2.0, 3.0])}]))[1]
    assert "| 1.00 [1.00, 1.00] | n/a | 3 (1 of 1 runs) |" in md
    assert "Chance Spearman is n/a where every held-out fabric got the same training mean" in md


def test_chance_spearman_ties_training_means_equal_but_for_rounding():
    """Two folds' training means of the same labels summed in another order differ in their
    last bit (0.20000000000000004 and 0.19999999999999998); ranked apart, they would order
    a tie. The chance Spearman is that of the means tied, as scipy ranks exact ties; one fold
    alone (one training mean) has none."""
    from scipy.stats import spearmanr

    from lookfeel.crossval.summary import _pooled_probe

    a, b = (0.1 + 0.2 + 0.3) / 3, (0.2 + 0.3 + 0.1) / 3
    assert a != b
    truth = [[1.0, 5.0], [2.0, 4.0], [3.0, 6.0]]
    means = [a, b, 0.5]
    cells = [
        {"held_out": {"fabric": [2 * f + 1, 2 * f + 2], "truth": t, "pred": t, "train_mean": m}}
        for f, (t, m) in enumerate(zip(truth, means, strict=True))
    ]
    pooled = _pooled_probe(cells, [0, 0, 0], 50, "fabric")
    assert pooled is not None
    want = spearmanr([t for ts in truth for t in ts], [0.2] * 4 + [0.5] * 2).statistic
    assert pooled["chance_spearman"]["mean"] == pytest.approx(want)
    one = _pooled_probe(cells[:1], [0], 50, "fabric")
    assert one is not None and math.isnan(one["chance_spearman"]["mean"])


def test_probe_tables_count_the_fabrics_their_numbers_are_over():
    """QA: the "runs (held-out fabrics)" cell said ``4 of 5 (16)`` where R² was pooled over 20
    fabrics (a fold whose held-out labels are all one value has no R² of its own, yet its
    fabrics are pooled), and ``10 of 10 (40)`` over 2 seeds of 20 fabrics. Now: the fabrics
    each number is over (a seed's) and the runs that predicted them. A label each fold holds
    out one fabric of has no R² of any run, but its pooled R² is shown, not "n/a"."""
    folds = [
        {"flat": ([1.0, 2.0, 3.0, 4.0], [1.5, 2.0, 2.5, 4.0]), "one": ([1.0], [1.5])},
        {"flat": ([5.0, 6.0, 7.0, 8.0], [5.0, 6.5, 7.0, 7.5]), "one": ([2.0], [2.5])},
        {"flat": ([3.0, 3.0, 3.0, 3.0], [2.0, 3.0, 3.5, 4.0]), "one": ([6.0], [5.0])},
    ]
    summary, md = _report(_kept_runs(folds))
    rows = summary["properties"]["depth"]["model"]
    assert (rows["flat"]["runs"], rows["flat"]["held_out"]) == (2, 8)  # the runs' own R²
    assert rows["flat"]["pooled"]["held_out"] == 12 and rows["flat"]["pooled"]["runs"] == 3
    assert rows["one"]["not_scored"] == "at most 1 labelled held-out fabric a fold"
    r2 = rows["one"]["pooled"]["r2"]["mean"]
    assert r2 == pytest.approx(1.0 - (0.25 + 0.25 + 1.0) / (((np.array([1, 2, 6]) - 3) ** 2).sum()))
    lines = [line for line in md.splitlines() if line.startswith("| flat |")]
    assert len(lines) == 2 and all(line.endswith(" | 12 (3 of 3 runs) |") for line in lines)
    assert f"| one | {r2:.2f} [" in md and "n/a: at most 1" not in md
    assert "3 (3 of 3 runs) |" in md
    # Pooled and still no R²: the reason is the pooled fabrics', not a fold's.
    same = [{"same": ([3.0, 3.0], [2.0, 4.0]), "lone": (t, t)} for t in ([5.0], [], [])]
    md_same = _report(_kept_runs(same))[1]
    assert "| same | n/a: every labelled held-out fabric's value is 3 |" in md_same
    assert "| lone | n/a: 1 labelled held-out fabric in all |" in md_same
    two, md = _report(_kept_runs(folds, seeds=(0, 1)))
    assert two["properties"]["depth"]["model"]["flat"]["pooled"]["per_seed_held_out"] == [12, 12]
    assert "| 12 (6 of 6 runs) |" in md and "(24)" not in md
    assert "how many held-out fabrics each number is over (each seed's), and how many runs" in md


def test_cv_json_keeps_each_runs_own_probe_scores():
    """QA: cv.md said each run's own R² and Spearman are in cv.json, which held only their
    mean and std. Now ``per_run`` lists them, run by run (a Spearman over fewer than 3
    fabrics, left out of the mean, is NaN there too), and the docs say the report shows
    ``pooled``."""
    import lookfeel.crossval
    import lookfeel.crossval.summary

    folds = [
        {"stiffness": ([1.0, 2.0, 3.0], [1.0, 3.0, 2.0])},
        {"stiffness": ([4.0, 5.0], [5.0, 4.0])},
    ]
    runs = _kept_runs(folds, seeds=(7,))
    summary, md = _report(runs)
    row = summary["properties"]["depth"]["model"]["stiffness"]
    first = runs[0]["properties"]["depth"]["model"]["stiffness"]
    assert row["per_run"][0] == {
        "seed": 7, "fold": 0, "r2": first["r2"], "spearman": pytest.approx(0.5), "held_out": 3,
    }  # fmt: skip
    assert row["per_run"][1]["fold"] == 1 and row["per_run"][1]["r2"] == pytest.approx(-3.0)
    assert math.isnan(row["per_run"][1]["spearman"])  # over 2 fabrics: ±1 whatever
    assert row["r2"] == pytest.approx(np.mean([r["r2"] for r in row["per_run"]]))
    assert "are in `cv.json` (`per_run`, `r2`, `spearman`); these tables are its `pooled`." in md
    for module in (lookfeel.crossval, lookfeel.crossval.summary):
        assert "``pooled.r2.mean``" in (module.__doc__ or "")


def test_probe_intervals_over_too_few_fabrics_are_said_to_say_little():
    """QA: with --only-folds 0 (4 fabrics) ``1.00 [1.00, 1.00]`` and ``-0.02 [-97.82, -0.01]``
    looked precise. reproduce's rule (under `MIN_FABRICS` = 10 fabrics, intervals say little)
    now marks them, naming the labels where only some are few; 30 fabrics get no mark."""
    from lookfeel.crossval import report
    from lookfeel.metrics.bootstrap import MIN_INTERVAL_FABRICS
    from lookfeel.reproduce.report import MIN_FABRICS

    assert report.FEW_FABRICS is MIN_INTERVAL_FABRICS is MIN_FABRICS
    four = _kept_runs([{"a": ([1.0, 2.0, 3.0, 4.0], [1.0, 2.5, 2.5, 4.0])}])
    md = _report(four)[1]
    assert (
        "**The intervals rest on 4 fabrics: under 10, they say little**, as the bootstrap can "
        "only resample the few fabrics there are"
    ) in md
    some = _kept_runs(
        [
            {"a": (list(range(12)), list(range(12))), "b": ([1.0, 2.0, 3.0, 5.0], [1.0] * 4)},
            {"a": (list(range(12, 24)), list(range(12, 24))), "b": ([4.0, 2.0], [3.0] * 2)},
        ]
    )
    md = _report(some)[1]
    assert "**The intervals of b (6 fabrics): under 10, they say little**" in md
    probes = _report(_probe_runs()[0])[1].split("Physical properties from depth")[1]
    assert "say little" not in probes  # 30 fabrics (its pick table's 6 are said to be few)


def test_pick_intervals_over_too_few_fabrics_are_said_to_say_little():
    """QA: the pick 1 of 10 tables printed ``0.500 [0.000, 1.000]`` over 4 held-out fabrics
    with no word, while the property tables say when theirs rest on fewer than
    `MIN_INTERVAL_FABRICS`. The pick tables now say it the same way: in full under the first,
    pointing at it under the others over the same queries; naming the pairs where only some
    are few; a fabric held out by two seeds is one fabric, as the bootstrap draws it; 12
    fabrics get no mark."""
    few = {"model": [[1.0, 1.0], [0.0, 1.0]], "model_labels": [[1.0, 1.0], [0.0, 1.0]]}
    many = {k: v * 6 for k, v in few.items()}  # 12 queries a fold: 12 fabrics a fold
    seeds = [
        _hand_made_run(fold, {"touch_to_depth": few}) | {"seed": seed}
        for seed in (0, 1)
        for fold in (0, 1)
    ]
    summary, md = _report(seeds)
    assert len(summary["pairs"]["touch_to_depth"]["per_item"]) == 4
    first, label_space = md.split("Matching in label space")
    assert (
        "**The intervals rest on 4 fabrics: under 10, they say little**, as the bootstrap can "
        "only resample the few fabrics there are"
    ) in first
    assert (
        "**The intervals rest on 4 fabrics: under 10, they say little**, as under the "
        in (label_space.split("Physical properties")[0])
    )
    some = [_hand_made_run(f, {"touch_to_depth": many, "depth_to_depth": few}) for f in (0, 1)]
    md = _report(some)[1]
    assert "**The intervals of depth to depth (4 fabrics): under 10, they say little**" in md
    assert "touch to depth (" not in md
    objects = _report(seeds, summarise={"noun": "object"})[1]
    assert "**The intervals rest on 4 objects: under 10, they say little**" in objects
    assert "the few objects there are" in objects
    assert "say little" not in _report([_hand_made_run(0, {"touch_to_depth": many})])[1]


def test_probe_tables_show_chance_r2_with_its_interval():
    """QA: chance R² was shown without the interval cv.json holds. Now it has it; a bound
    that rounds to zero prints 0.00, never -0.00."""
    from lookfeel.crossval.report import _interval

    runs, _, _ = _probe_runs(seeds=(0,))
    summary, md = _report(runs)
    chance = summary["properties"]["depth"]["model"]["noise"]["pooled"]["chance_r2"]
    low, high = chance["ci95"]
    assert low < chance["mean"] < high
    assert f"| {_interval(chance)} | 30 (3 of 3 runs) |" in md
    assert _interval({"mean": -0.3, "ci95": [-0.9, -0.001]}) == "-0.30 [-0.90, 0.00]"
