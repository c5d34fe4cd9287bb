"""Recordings as they lie: objects named in labels.csv, videos as touch presses, class labels
(ranks and words), the class heads and the class metrics."""

from __future__ import annotations

import json
import math
import re
import warnings
from pathlib import Path

import numpy as np
import pytest
import torch

from lookfeel.config import LossConfig, ModelConfig, RunConfig, from_dict
from lookfeel.config._core import ConfigError
from lookfeel.data import scan
from lookfeel.data.datasets import class_matrix
from lookfeel.data.labels import read_labels
from lookfeel.losses import create_loss
from lookfeel.metrics.classes import UNKNOWN, accuracy, knn_classes, macro_f1, majority_class
from lookfeel.modality import Modality, PressKind
from lookfeel.models import CLASSES, create_model
from lookfeel.train.loop import resolve_classes, resolve_properties

from ._tiny import QUICKTIME, write_recordings

LABELS = """object,hardness,roughness,material,description
sponge,0,2,fabric,a kitchen sponge
steel_spoon,2,0,metal,a spoon
cork,1,1,wood,a cork
felt_pad,0,1,fabric,a felt pad
apple,,,,
"""


def _recordings(root: Path, presses: dict[str, int], labels: str = LABELS) -> Path:
    return write_recordings(root, presses, labels)


def test_object_keyed_labels_have_text_columns_and_keep_every_cell(tmp_path: Path):
    path = tmp_path / "labels.csv"
    path.write_text(LABELS, encoding="utf-8")
    table, problems = read_labels(path)
    assert problems == []
    assert table.key == "object"
    assert table.columns == ("hardness", "roughness")  # numeric: regression targets
    assert table.text_columns == ("material", "description")
    row = table.named["steel_spoon"]
    assert row.values == {"hardness": 2.0, "roughness": 0.0}
    assert row.text == {
        "hardness": "2",
        "roughness": "0",
        "material": "metal",
        "description": "a spoon",
    }
    assert table.named["apple"].values == {} and table.named["apple"].text == {}


def test_a_typo_in_a_numeric_column_is_reported_not_taken_for_a_word(tmp_path: Path):
    path = tmp_path / "labels.csv"
    path.write_text("object,hardness\na,0\nb,1\nc,2x\n", encoding="utf-8")
    table, problems = read_labels(path)
    assert table.columns == ("hardness",)
    assert [(p.line, p.message) for p in problems] == [
        (4, "column 'hardness': '2x' is not a number")
    ]


def test_videos_folder_scans_named_objects_with_ids_in_name_order(tmp_path: Path):
    root = _recordings(tmp_path / "rec", {"steel_spoon": 3, "sponge": 2, "cork": 2, "felt_pad": 1})
    catalog = scan(root)
    assert [f.name for f in catalog.fabrics] == ["cork", "felt_pad", "sponge", "steel_spoon"]
    assert catalog.ids == [2, 3, 4, 5]  # apple (1) is labelled but has no video
    spoon = catalog.fabric(5)
    assert spoon.display_name == "steel_spoon"
    presses = spoon.items_of(Modality.TOUCH)
    assert [(it.press, it.kind, it.path.name) for it in presses] == [
        ("0", None, "steel_spoon_0.mov"),
        ("1", None, "steel_spoon_1.mov"),
        ("2", None, "steel_spoon_2.mov"),
    ]
    # a press of no stated kind is of every kind: a fold-press config still reads it
    assert len(spoon.items_of(Modality.TOUCH, [PressKind.FOLD])) == 3
    assert spoon.class_of("hardness") == "2" and spoon.class_of("material") == "metal"
    assert catalog.errors == ()
    assert [(p.path.name, p.message) for p in catalog.warnings] == [
        ("labels.csv", "object 'apple' is in labels.csv but has no video")
    ]
    s = catalog.summary()
    assert (s["touch_videos"], s["named_objects"], s["touch_frames"]) == (8, 4, 0)
    assert s["touch_presses_by_kind"] == {"any kind": 8}
    # descriptions are all different: not classes; ranks and words are
    assert s["classes"] == {
        "material": {"fabric": 2, "metal": 1, "wood": 1},
        "hardness": {"0": 2, "1": 1, "2": 1},
        "roughness": {"0": 1, "1": 2, "2": 1},
    }


def test_objects_named_like_gelfabric_ids_are_objects_of_an_object_keyed_labels_file(
    tmp_path: Path,
):
    # A user's objects may be called F0001 and F0002: with labels.csv keyed by `object`, their
    # videos are those objects' presses, not fabric 1's (which "had no row in labels.csv")
    labels = "object,hardness\nF0001,0\nF0002,2\n"
    root = _recordings(tmp_path / "rec", {"F0001": 2, "F0002": 1}, labels)
    catalog = scan(root)
    assert catalog.errors == ()
    assert [f.name for f in catalog.fabrics] == ["F0001", "F0002"]
    assert [len(f.items_of(Modality.TOUCH)) for f in catalog.fabrics] == [2, 1]
    assert [f.class_of("hardness") for f in catalog.fabrics] == ["0", "2"]


def test_video_names_and_containers_are_checked(tmp_path: Path):
    root = _recordings(tmp_path / "rec", {"cork": 1})
    (root / "videos" / "nonumber.mov").write_bytes(QUICKTIME)
    (root / "videos" / "cork_1.mov").write_bytes(b"\x89PNG\r\n\x1a\n" + bytes(32))
    (root / "videos" / "notes.txt").write_text("x", encoding="utf-8")
    (root / "touch").mkdir()
    (root / "touch" / "F0009_fold_7.mp4").write_bytes(QUICKTIME)
    (root / "touch" / "F0009_7.mp4").write_bytes(QUICKTIME)
    catalog = scan(root, check_headers=True)
    errors = {p.path.name: p.message for p in catalog.errors}
    assert errors["nonumber.mov"].startswith("video name does not parse; expected <object>_<n>")
    assert errors["cork_1.mov"] == "not a video container (QuickTime .mov, MP4, AVI or Matroska)"
    assert errors["F0009_7.mp4"].startswith("touch video name has no press kind")
    assert [p.path.name for p in catalog.skipped if p.path.name == "notes.txt"] == ["notes.txt"]
    (fold,) = catalog.fabric(9).items_of(Modality.TOUCH)
    assert (fold.kind, fold.press, fold.frames) == (PressKind.FOLD, "7", (fold.path,))


def _config(**model: object) -> RunConfig:
    return RunConfig(
        model=ModelConfig(backbone="compact", width=4, embed_dim=8, dropout=0.0, **model)  # type: ignore[arg-type]
    )


def test_classes_are_resolved_from_the_labels_in_their_own_order(tmp_path: Path):
    catalog = scan(_recordings(tmp_path / "rec", {"sponge": 1, "steel_spoon": 1, "cork": 1}))
    cfg = resolve_classes(catalog, _config(class_heads=("hardness", "material")))
    assert cfg.model.classes == {
        "hardness": ("0", "1", "2"),
        "material": ("fabric", "metal", "wood"),
    }
    assert cfg.model.class_sizes == (3, 3)
    m = class_matrix(catalog.fabrics, cfg.model.classes)
    assert m.tolist() == [[1, 2], [0, 0], [2, 1]]  # cork, sponge, steel_spoon
    with pytest.raises(ConfigError, match="'stiffness' is not a column of labels.csv"):
        resolve_classes(catalog, _config(class_heads=("stiffness",)))
    with pytest.raises(ConfigError, match="no classes for hardness"):
        _ = _config(class_heads=("hardness",)).model.class_sizes


def test_a_class_temperature_names_a_head_and_is_positive():
    cfg = _config(class_heads=("hardness",), class_temperature={"hardness": 2.5})
    assert cfg.model.class_temperature == {"hardness": 2.5}
    # A column with no head is ignored: a recipe's temperatures outlive fewer heads.
    assert _config(class_heads=("hardness",), class_temperature={"roughness": 2.0})
    # It changes neither training nor the cv's scores: a cv keeps runs trained without it.
    from lookfeel.crossval.run import _result_config

    assert _result_config(cfg) == _result_config(_config(class_heads=("hardness",)))
    for bad in (0.0, -1.0, float("inf"), "hot", True):
        with pytest.raises(ConfigError, match="class_temperature.hardness: must be a number > 0"):
            _config(class_heads=("hardness",), class_temperature={"hardness": bad})


def test_the_temperature_that_fits_a_head_is_the_one_it_was_drawn_at():
    from lookfeel.metrics.classes import UNKNOWN, fit_logit_temperature, softmax

    rng = np.random.default_rng(0)
    u = rng.normal(0, 2, (20000, 3))  # the true log-odds
    p = softmax(u)
    truth = (rng.random(20000)[:, None] > p.cumsum(1)).sum(1)  # classes drawn from softmax(u)
    # A head three times surer than it should be: its logits are 3u; T = 3 undoes that.
    assert fit_logit_temperature(3 * u, truth) == pytest.approx(3.0, rel=0.05)
    assert fit_logit_temperature(u / 2, truth) == pytest.approx(0.5, rel=0.05)
    unknown = np.r_[truth[:100], [UNKNOWN] * 5]
    assert fit_logit_temperature(np.r_[3 * u[:105]], unknown) == pytest.approx(
        fit_logit_temperature(3 * u[:100], truth[:100])
    )  # rows of unknown class are left out
    assert fit_logit_temperature(u[:3], [UNKNOWN] * 3) == 1.0
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a head that knows nothing: the edge, no warning
        assert fit_logit_temperature(u, rng.integers(0, 3, 20000)) > 100
    assert softmax(u[:4]).sum(1) == pytest.approx(np.ones(4))


def test_cv_says_how_far_a_heads_probabilities_can_be_trusted():
    from lookfeel.crossval.report import _calibration_lines
    from lookfeel.crossval.summary import _calibration
    from lookfeel.metrics.classes import softmax

    rng = np.random.default_rng(1)
    runs = []
    for _ in range(3):  # three runs of a head four times surer than it is right
        u = rng.normal(0, 1.5, (400, 3))
        truth = (rng.random(400)[:, None] > softmax(u).cumsum(1)).sum(1)
        truth[:10] = -1  # unknown labels
        runs.append({"truth": truth.tolist(), "logits": (4 * u).tolist()})
    c = _calibration(runs)
    assert c["confidence"] > c["accuracy"] + 0.1  # surer than right
    assert c["ece"] > 0.1
    assert c["temperature"] == pytest.approx(4.0, rel=0.15)
    # A temperature fitted on the other runs brings each run's probability near its accuracy.
    assert abs(c["confidence_cross_fitted"] - c["accuracy"]) < 0.03
    assert c["ece_cross_fitted"] < c["ece"] / 2
    one = _calibration(runs[:1])
    assert math.isnan(one["ece_cross_fitted"]) and not math.isnan(one["ece"])
    # Runs of one fold held out the same objects: no temperature is fitted on other objects.
    same = _calibration(runs, folds=[0, 0, 0])
    assert math.isnan(same["ece_cross_fitted"]) and same["ece"] == c["ece"]
    assert _calibration(runs, folds=[0, 0, 1])["ece_cross_fitted"] < c["ece"] / 2
    lines = _calibration_lines("touch", {"hardness": {"calibration": c}, "material": {}})
    (row,) = [line for line in lines if line.startswith("| hardness |")]
    assert row.endswith(f"| {c['temperature']:.2f} |") and f"{c['ece']:.3f}" in row
    assert _calibration_lines("touch", {"material": {}}) == []
    unknown = _calibration([{"truth": [-1, -1], "logits": [[0.0, 1.0], [1.0, 0.0]]}])
    assert all(math.isnan(v) for v in unknown.values())  # no known class: nothing to say
    (row,) = _calibration_lines("touch", {"h": {"calibration": unknown}})[-1:]
    assert row == "| h | - | - | - | - | - | - |"


def test_auto_property_head_follows_the_numeric_label_columns(tmp_path: Path):
    catalog = scan(_recordings(tmp_path / "rec", {"sponge": 1, "steel_spoon": 1}))
    cfg = resolve_properties(catalog, _config(num_properties="auto"))
    assert cfg.model.num_properties == 2  # hardness, roughness; words are not regressed
    assert cfg.model.property_outputs == 2
    unlabelled = _recordings(tmp_path / "bare", {"sponge": 1}, labels="object\nsponge\n")
    bare = resolve_properties(scan(unlabelled), _config(num_properties="auto"))
    assert bare.model.num_properties == 0
    with pytest.raises(ConfigError, match=r"num_properties=4, but labels.csv has 2 .*auto"):
        resolve_properties(catalog, _config(num_properties=4))
    with pytest.raises(ConfigError, match="auto is not resolved yet"):
        create_model(_config(num_properties="auto").model, [Modality.TOUCH])
    with pytest.raises(ConfigError, match="num_properties: must be >= 0 or auto"):
        _config(num_properties=-1)
    loaded = from_dict(RunConfig, {"model": {"num_properties": "auto"}})
    assert loaded.model.num_properties == "auto"
    with pytest.raises(ConfigError, match="model.num_properties"):
        from_dict(RunConfig, {"model": {"num_properties": "many"}})


def test_class_heads_and_their_loss_mask_unknown_labels():
    cfg = ModelConfig(
        backbone="compact",
        width=4,
        embed_dim=8,
        dropout=0.0,
        class_heads=("hardness", "material"),
        classes={"hardness": ("0", "1", "2"), "material": ("fabric", "metal")},
    )
    torch.manual_seed(0)
    model = create_model(cfg, [Modality.TOUCH])
    x = torch.rand(4, 1, 3, 32, 32)
    out = model({"touch": x}, heads=True)
    assert out[f"touch/{CLASSES}"].shape == (4, 5)
    loss_fn = create_loss(LossConfig(pair_weight=0.0, class_weight=2.0), cfg.class_sizes)
    target = torch.tensor([[0, 1], [2, -1], [-1, -1], [1, 0]])
    terms = loss_fn(out, classes={"touch": target})
    assert set(terms) == {"class_loss", "loss"}
    logits = out[f"touch/{CLASSES}"]
    ce = torch.nn.functional.cross_entropy
    expected = ce(logits[[0, 1, 3], :3], target[[0, 1, 3], 0]) + ce(
        logits[[0, 3], 3:], target[[0, 3], 1]
    )
    torch.testing.assert_close(terms["class_loss"], 2.0 * expected)


def test_accuracy_and_macro_f1_by_hand():
    truth = [0, 0, 1, 1, 2, UNKNOWN]
    pred = [0, 1, 1, 1, 0, 2]
    assert accuracy(truth, pred) == pytest.approx(3 / 5)
    # class 0: tp 1 fp 1 fn 1 -> 0.5; class 1: tp 2 fp 1 fn 0 -> 0.8; class 2: tp 0 fn 1 -> 0
    assert macro_f1(truth, pred, 3) == pytest.approx((0.5 + 0.8 + 0.0) / 3)
    assert np.isnan(accuracy([UNKNOWN], [0]))
    assert majority_class([2, 1, 1, UNKNOWN, 2, 2], 3) == 2
    assert majority_class([UNKNOWN], 3) == UNKNOWN


def test_knn_classes_votes_among_known_neighbours():
    train = np.array([[0.0], [0.1], [0.2], [5.0], [5.1], [9.0]])
    classes = np.array([0, 0, 0, 1, 1, UNKNOWN])
    got = knn_classes(train, classes, np.array([[0.05], [5.05], [8.9]]), 2, k=3)
    assert got.tolist() == [0, 1, 1]  # 8.9: the unknown row at 9 does not vote


# ---- end to end: a folder of press videos, as a user records them ---------------------------

OBJECTS = {  # name: (hardness, material)
    "foam": ("0", "fabric"),
    "felt": ("0", "fabric"),
    "cork": ("1", "wood"),
    "leaf": ("1", "paper"),
    "spoon": ("2", "metal"),
    "tile": ("2", "metal"),
}


@pytest.fixture(scope="module")
def recordings(tmp_path_factory: pytest.TempPathFactory) -> Path:
    pytest.importorskip("av")
    from ._video import object_press, write_objects, write_video

    root = write_objects(tmp_path_factory.mktemp("recordings"), OBJECTS, 3)
    write_video(root / "videos" / "foam_3.mov", object_press(0, {}, t=14))  # never pressed
    return root


def _count_calls(monkeypatch: pytest.MonkeyPatch, module: object, name: str) -> list[str]:
    """Replace ``module.name`` (a function whose first argument is a path) by one that also
    records the file name of each call; returns the record."""
    calls: list[str] = []
    real = getattr(module, name)

    def counting(path, *args, **kwargs):
        calls.append(Path(path).name)
        return real(path, *args, **kwargs)

    monkeypatch.setattr(module, name, counting)
    return calls


TINY = [
    "--set", "data.image_size=32", "--set", "model.width=4", "--set", "model.embed_dim=8",
    "--set", "train.steps=4", "--set", "train.batch_size=8", "--set", "train.checkpoint_every=0",
    "--set", "model.class_heads=[hardness, material]",
]  # fmt: skip


def test_recordings_train_predict_and_embed_as_the_readme_says(
    recordings: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
):
    from lookfeel.cli import main

    assert main(["data", "check", str(recordings)]) == 0
    out = capsys.readouterr()
    assert "foam_3.mov" in out.out + out.err and "no contact found" in out.out + out.err
    assert re.search(r"^Checked .*: \d+ objects, \d+ files decoded\.$", out.out, re.M)

    run = tmp_path / "run"
    config = str(Path(__file__).resolve().parents[1] / "configs" / "physiclear.yaml")
    with pytest.warns(UserWarning, match=r"1 of 19 touch videos hold no press .*foam_3\.mov"):
        code = main(
            ["train", "--config", config, "--data", str(recordings), "--out", str(run), *TINY]
        )
    assert code == 0
    ck = run / "checkpoints" / "last.pt"
    capsys.readouterr()

    videos = sorted(str(p) for p in (recordings / "videos").glob("*_0.mov"))
    assert main(["predict", "--checkpoint", str(ck), *videos, "--json"]) == 0
    answers = json.loads(capsys.readouterr().out)
    assert [a["path"] for a in answers] == videos
    for a in answers:
        assert set(a["properties"]) == {"hardness", "material"}
        hardness = a["properties"]["hardness"]
        assert hardness["value"] in (0, 1, 2)  # the column's own terms: ranks, not "1.0"
        assert sum(hardness["probabilities"].values()) == pytest.approx(1.0, abs=1e-3)
        assert hardness["probability"] == max(hardness["probabilities"].values())
        assert a["properties"]["material"]["value"] in {"fabric", "wood", "paper", "metal"}

    # A temperature per head (model.class_temperature) softens the probabilities, never the class.
    from dataclasses import replace

    from lookfeel.checkpoint import load_model
    from lookfeel.predict import predict_files

    lm = load_model(ck)
    # the dataset as `evaluate` scans it (foam_3 kept): --split val does not say "another dataset"
    assert lm.data_fingerprint == scan(recordings).fingerprint()
    temps = {**lm.config.model.class_temperature, "hardness": 1000.0}
    hot = replace(lm.config.model, class_temperature=temps)
    (soft,) = predict_files(replace(lm, config=replace(lm.config, model=hot)), videos[:1])
    hardness = soft.properties["hardness"]
    assert hardness.value == answers[0]["properties"]["hardness"]["value"]
    assert max(hardness.probabilities.values()) < 0.34  # near 1/3 each at T = 1000
    assert (
        soft.properties["material"].probability
        == answers[0]["properties"]["material"]["probability"]
    )  # a head without a temperature is as before

    together = [str(p) for p in sorted((recordings / "videos").glob("cork_*.mov"))]
    assert main(["predict", "--checkpoint", str(ck), *together, "--together", "--json"]) == 0
    (pooled,) = json.loads(capsys.readouterr().out)
    assert pooled["paths"] == together

    assert (
        main(["predict", "--checkpoint", str(ck), str(recordings / "videos" / "foam_3.mov")]) == 1
    )
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "foam_3.mov: no contact found" in err[0]

    npz = tmp_path / "e.npz"
    with pytest.warns(UserWarning, match="hold no press"):
        code = main(
            ["embed", "--checkpoint", str(ck), "--data", str(recordings), "--out", str(npz)]
        )
    assert code == 0
    with np.load(npz) as e:
        assert e["embeddings_touch"].shape == (18, 3 * 8)  # the recipe's three networks
        ids = e["fabric_id_touch"]
        assert len(set(ids.tolist())) == 6
        assert not any("foam_3" in str(p) for p in e["path_touch"])


def test_the_untouched_control_shows_what_a_moment_without_contact_looks_like(tmp_path: Path):
    pytest.importorskip("av")
    from lookfeel.config import DataConfig
    from lookfeel.data import ImageLoader
    from lookfeel.data.catalog import Item
    from lookfeel.data.touch_control import UntouchedControl

    from ._video import PRESS, object_press, sensor, write_video

    path = write_video(tmp_path / "cork_0.mov", object_press(3, PRESS, t=14))
    item = Item(Modality.TOUCH, 1, (path,))
    diff = DataConfig(image_size=32)
    pressed = ImageLoader(diff).array(path, Modality.TOUCH).astype(np.float64)
    control = UntouchedControl(diff)
    assert control.applies([item])
    untouched = control.loader([item]).array(path, Modality.TOUCH).astype(np.float64)
    assert untouched.shape == pressed.shape == (32, 32, 3)
    # the difference of two no-contact frames is flat grey: only noise is left
    assert abs(untouched.mean() - 128) < 2 and untouched.std() < 0.25 * pressed.std()

    raw = UntouchedControl(DataConfig(image_size=32, video_reference="none"))
    light = raw.loader([item]).array(path, Modality.TOUCH).astype(np.float64)
    expected = np.asarray(
        torch.nn.functional.interpolate(
            torch.from_numpy(sensor()).permute(2, 0, 1)[None], size=(32, 32), mode="area"
        )[0].permute(1, 2, 0)
    )
    assert np.abs(light - expected).mean() < 4  # the sensor's own light pattern
    frame_item = Item(Modality.TOUCH, 1, (tmp_path / "F0001_fold_01_1.png",), PressKind.FOLD, "1")
    assert not UntouchedControl.applies([frame_item])


def test_cv_on_recordings_reports_classes_and_the_untouched_control(
    recordings: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch
):
    from lookfeel.cli import main
    from lookfeel.data import touch_control

    still = _count_calls(monkeypatch, touch_control, "untouched_image")
    config = str(Path(__file__).resolve().parents[1] / "configs" / "physiclear.yaml")
    args = ["cv", "--config", config, "--data", str(recordings), "--out", str(tmp_path / "cv")]
    with pytest.warns(UserWarning, match="hold no press"):
        assert main([*args, *TINY, "--folds", "2", "--seeds", "0,1", "--n-boot", "50"]) == 0
    # each held-out press made untouched once, for both seeds of its fold
    assert sorted(still) == sorted(set(still)) and len(still) == 18
    summary = json.loads((tmp_path / "cv" / "cv.json").read_text(encoding="utf-8"))
    pair = summary["pairs"]["touch_to_touch"]
    for key in (
        "model_top1",
        "raw_pixels_top1",
        "model_untouched_top1",
        "raw_pixels_untouched_top1",
    ):
        assert 0.0 <= pair[key]["mean"] <= 1.0 and len(pair[key]["per_run"]) == 4
    hardness = summary["classes"]["touch"]["hardness"]
    assert hardness["classes"] == ["0", "1", "2"] and hardness["chance"] == pytest.approx(1 / 3)
    for method in ("model", "model_pooled", "probe", "raw_pixels", "majority"):
        assert 0.0 <= hardness[method]["accuracy"] <= 1.0
    assert hardness["model"]["queries"] == 36  # every press with a label, held out once per seed
    assert hardness["model_pooled"]["queries"] == 12  # one per object and seed
    report = (tmp_path / "cv" / "cv.md").read_text(encoding="utf-8")
    assert "Untouched control" in report and "| hardness |" in report
    assert "every object held out once" in report  # objects are objects (QA)
    assert report.startswith("Object-disjoint cross-validation") and "presss" not in report

    # Scored again (--tta): the finished runs, whose configs now name their classes, are kept.
    capsys.readouterr()
    with pytest.warns(UserWarning, match="hold no press"):
        assert main([*args, *TINY, "--folds", "2", "--seeds", "0,1", "--tta"]) == 0
    assert "seed 1 fold 1: trained before, scoring again" in capsys.readouterr().out


def test_training_views_change_the_run_and_resume_exactly(recordings: Path, tmp_path: Path):
    from lookfeel.config import load_config
    from lookfeel.train import train

    config = Path(__file__).resolve().parents[1] / "configs" / "physiclear.yaml"
    tiny = [TINY[i + 1] for i in range(0, len(TINY), 2)] + [
        "train.steps=6",
        "train.checkpoint_every=2",
    ]
    cfg = load_config(RunConfig, config, tiny)
    assert cfg.data.video_views == 12

    def weights(run: Path) -> dict[str, torch.Tensor]:
        return torch.load(run / "checkpoints" / "last.pt", weights_only=True)["model"]

    with pytest.warns(UserWarning, match="hold no press"):
        unbroken = weights(train(cfg, recordings, tmp_path / "unbroken").run_dir)

    class Kill(Exception):
        pass

    def kill(step: int, _: object) -> None:
        if step == 5:
            raise Kill

    with pytest.warns(UserWarning, match="hold no press"), pytest.raises(Kill):
        train(cfg, recordings, tmp_path / "broken", on_step=kill)
    with pytest.warns(UserWarning, match="hold no press"):
        resumed = weights(train(cfg, recordings, tmp_path / "broken", resume=True).run_dir)
    assert unbroken.keys() == resumed.keys()
    assert [k for k in unbroken if not torch.equal(unbroken[k], resumed[k])] == []

    one = load_config(RunConfig, config, [*tiny, "data.video_views=1", "data.video_embed=image"])
    with pytest.warns(UserWarning, match="hold no press"):
        single = weights(train(one, recordings, tmp_path / "single").run_dir)
    assert any(not torch.equal(unbroken[k], single[k]) for k in unbroken)  # views were drawn


def test_a_training_run_decodes_each_press_video_once(
    recordings: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
):
    from lookfeel.config import load_config
    from lookfeel.data import images as images_module
    from lookfeel.train import train

    decoded = _count_calls(monkeypatch, images_module, "read_press")
    config = Path(__file__).resolve().parents[1] / "configs" / "physiclear.yaml"
    tiny = [TINY[i + 1] for i in range(0, len(TINY), 2)] + ["train.steps=2"]
    with pytest.warns(UserWarning, match="hold no press"):
        train(load_config(RunConfig, config, tiny), recordings, tmp_path / "run")
    assert len(decoded) == 19 and len(set(decoded)) == 19  # every video, views and all, once


def test_a_press_is_embedded_as_the_mean_of_its_views_everywhere(recordings: Path):
    from lookfeel.config import DataConfig
    from lookfeel.data import ImageLoader
    from lookfeel.data.recordings import drop_unpressed
    from lookfeel.data.touch_control import UntouchedControl
    from lookfeel.embedding import embed_items, raw_pixels
    from lookfeel.index.query import load_query_image, query_batch

    data = DataConfig(image_size=32, video_views=4, video_embed="views")
    with pytest.warns(UserWarning, match="hold no press"):
        catalog = drop_unpressed(scan(recordings), ImageLoader(data))
    items = catalog.items(Modality.TOUCH)[:5]
    model = create_model(ModelConfig(backbone="compact", width=4, embed_dim=8), [Modality.TOUCH])
    model.eval()
    loader = ImageLoader(data)
    got = embed_items(model, items, loader, batch_size=2)
    views = [loader.load_embedded(it) for it in items]
    assert all(v.shape == (5, 3, 32, 32) for v in views)
    with torch.no_grad():
        each = [model({"touch": v.unsqueeze(1)})["touch"].mean(0) for v in views]
    np.testing.assert_allclose(got, torch.stack(each).numpy(), rtol=1e-4, atol=1e-5)
    deepest = embed_items(model, items, ImageLoader(DataConfig(image_size=32)))
    assert not np.allclose(got, deepest, atol=1e-4)  # the views change the embedding
    pixels = raw_pixels(items, loader)
    np.testing.assert_allclose(pixels, torch.stack([v.mean(0).reshape(-1) for v in views]))

    # A query file is embedded the same way (predict, match and serve read it so).
    query = load_query_image(items[0].path, Modality.TOUCH, data)
    with torch.no_grad():
        one = model({"touch": query_batch([query], Modality.TOUCH)})["touch"]
    np.testing.assert_allclose(one[0].numpy(), got[0], rtol=1e-4, atol=1e-5)

    # The untouched control serves one image per press, embedded as such.
    still = UntouchedControl(data).loader(items)
    mixed = embed_items(model, items, still)
    assert mixed.shape == got.shape and not np.allclose(mixed, got, atol=1e-4)


def test_a_library_of_press_videos_decodes_each_once_and_matches_like_embed(
    recordings: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
):
    from lookfeel.config import load_config
    from lookfeel.data import images as images_module
    from lookfeel.index.build import build_library
    from lookfeel.index.library import Library
    from lookfeel.train import train

    config = Path(__file__).resolve().parents[1] / "configs" / "physiclear.yaml"
    tiny = [TINY[i + 1] for i in range(0, len(TINY), 2)] + ["train.steps=2"]
    with pytest.warns(UserWarning, match="hold no press"):
        run = train(load_config(RunConfig, config, tiny), recordings, tmp_path / "run").run_dir
    read_press = images_module.read_press
    decoded = _count_calls(monkeypatch, images_module, "read_press")
    with pytest.warns(UserWarning, match="hold no press"):
        build_library(run / "checkpoints" / "last.pt", recordings, tmp_path / "lib", shard_size=5)
    assert len(decoded) == 19 and len(set(decoded)) == 19  # every video, views and all, once
    table = Library.open(tmp_path / "lib").table(Modality.TOUCH)
    assert table.embeddings.shape == (18, 3 * 8)

    # The rows are what `embed` computes: each press from its views (data.video_embed).
    from lookfeel.checkpoint import load_model
    from lookfeel.data import ImageLoader
    from lookfeel.embedding import embed_items

    monkeypatch.setattr(images_module, "read_press", read_press)
    loaded = load_model(run / "checkpoints" / "last.pt")
    assert loaded.config.data.video_embed == "views"
    items = [it for it in scan(recordings).items(Modality.TOUCH) if "foam_3" not in str(it.path)]
    want = embed_items(loaded.model, items, ImageLoader(loaded.config.data))
    np.testing.assert_allclose(table.embeddings, want, rtol=1e-4, atol=1e-5)

    # match reads a query video the same way: a library press comes back as itself, and an
    # upload of the same bytes (serve) is the same query.
    from lookfeel.index.match import Matcher
    from lookfeel.index.query import load_query_bytes, load_query_image

    query = items[4].path
    matcher = Matcher(Library.open(tmp_path / "lib"))
    (r,) = matcher.match_files([query], Modality.TOUCH)
    assert r.known and r.fabrics[0].fabric_id == items[4].fabric_id
    uploaded = load_query_bytes(query.read_bytes(), "up.mov", Modality.TOUCH, loaded.config.data)
    assert torch.equal(uploaded, load_query_image(query, Modality.TOUCH, loaded.config.data))
    assert uploaded.shape == (13, 3, 32, 32)


def test_press_videos_decode_in_worker_processes_as_in_threads(recordings: Path):
    from lookfeel.config import DataConfig
    from lookfeel.data import ImageLoader

    items = [it for it in scan(recordings).items(Modality.TOUCH) if "foam" not in it.path.name]
    held = {}
    for decode in ("threads", "processes"):
        data = DataConfig(image_size=32, video_views=4, video_embed="views", decode=decode)
        loader = ImageLoader(data)
        assert loader.preload(items, views=True) == len(items)  # training views
        assert loader.preload(items) == 0  # what `embed` uses came from the same decode
        held[decode] = [(loader.views(it), loader.embed_array(it)) for it in items]
    for (tv, te), (pv, pe) in zip(held["threads"], held["processes"], strict=True):
        assert tv.shape[0] > 1 and np.array_equal(tv, pv) and np.array_equal(te, pe)


# ---- a model trained on press videos, used: what it takes, how it names objects ----------------


@pytest.fixture(scope="module")
def video_model(recordings: Path, tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """(checkpoint, library): the recipe (three networks, merged into one checkpoint) trained
    for a few steps on `recordings`, and a library of its presses."""
    from lookfeel.cli import main

    root = tmp_path_factory.mktemp("video_model")
    config = str(Path(__file__).resolve().parents[1] / "configs" / "physiclear.yaml")
    args = ["--data", str(recordings), *TINY, "--set", "train.steps=2"]
    with pytest.warns(UserWarning, match="hold no press"):
        assert main(["train", "--config", config, "--out", str(root / "run"), *args]) == 0
    ck = root / "run" / "checkpoints" / "last.pt"
    with pytest.warns(UserWarning, match="hold no press"):
        code = main(["index", "build", "--checkpoint", str(ck), "--data", str(recordings),
                     "--out", str(root / "lib")])  # fmt: skip
    assert code == 0
    return ck, root / "lib"


def _still_frame(recordings: Path, path: Path) -> Path:
    """One raw frame of a press video, saved as a PNG: what a still GelSight image looks like."""
    from ._video import PRESS, object_press

    Image = pytest.importorskip("PIL.Image")
    Image.fromarray(object_press(2, PRESS, t=14)[7]).save(path)
    return path


def test_a_video_model_refuses_a_still_touch_image_by_name(
    recordings: Path,
    video_model: tuple[Path, Path],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
):
    from lookfeel.checkpoint import TOUCH_VIDEOS, load_model, read_checkpoint
    from lookfeel.cli import main
    from lookfeel.index.query import STILL_TOUCH_REFUSED

    ck, lib = video_model
    assert read_checkpoint(ck)["touch_input"] == TOUCH_VIDEOS  # the members' merged checkpoint
    member = ck.parents[1] / "members" / "0" / "checkpoints" / "last.pt"
    assert read_checkpoint(member)["touch_input"] == TOUCH_VIDEOS
    assert load_model(ck).touch_input == TOUCH_VIDEOS

    still = _still_frame(recordings, tmp_path / "still.png")
    video = str(recordings / "videos" / "cork_0.mov")
    refused = f"lookfeel: {still}: {STILL_TOUCH_REFUSED}"
    capsys.readouterr()
    # match pools its touch files into one query: refused, nothing matched
    assert main(["match", "--index", str(lib), "--modality", "touch", video, str(still)]) == 1
    out = capsys.readouterr()
    assert out.err.strip().splitlines() == [refused] and out.out == ""
    # predict answers each input: the still image with its error, the video all the same
    unanswered = f"lookfeel: warning: {still}: {STILL_TOUCH_REFUSED}; nothing predicted for it"
    assert main(["predict", "--checkpoint", str(ck), str(still)]) == 1  # nothing answered
    out = capsys.readouterr()
    assert out.err.strip().splitlines() == [unanswered]
    assert out.out.strip() == f"{still}: {STILL_TOUCH_REFUSED} (nothing predicted)"
    together = f"{still}: {STILL_TOUCH_REFUSED}; it is one of the 2 presses given together"
    assert main(["predict", "--checkpoint", str(ck), video, str(still), "--together"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"lookfeel: warning: {together}; nothing predicted for it"]
    assert main(["predict", "--checkpoint", str(ck), video, str(still), "--json"]) == 0
    out = capsys.readouterr()
    assert out.err.strip().splitlines() == [unanswered]
    answers = json.loads(out.out)
    assert [a["path"] for a in answers] == [video, str(still)]
    assert answers[0]["error"] is None and answers[0]["properties"]
    assert answers[1]["error"] == f"{still}: {STILL_TOUCH_REFUSED}"
    assert answers[1]["properties"] == {} and answers[1]["modality"] == "touch"

    # serve: the upload is refused with a 422 naming the client's file, a video is matched
    import httpx

    from lookfeel.serve import background_server, create_app

    with background_server(create_app(lib)) as url:
        png = ("files", ("my press.png", still.read_bytes(), "image/png"))
        r = httpx.post(url + "/api/match", data={"modality": "touch"}, files=[png])
        assert r.status_code == 422 and r.json()["detail"] == f"my press.png: {STILL_TOUCH_REFUSED}"
        mov = ("files", ("cork.mov", Path(video).read_bytes(), "video/quicktime"))
        r = httpx.post(url + "/api/match", data={"modality": "touch"}, files=[mov])
        assert r.status_code == 200, r.text

    # A checkpoint from before the record is not checked (nor is a library built with it).
    state = torch.load(ck, weights_only=True)
    del state["touch_input"]
    old = tmp_path / "old.pt"
    torch.save(state, old)
    assert load_model(old).touch_input is None
    assert main(["predict", "--checkpoint", str(old), str(still)]) == 0
    assert capsys.readouterr().out.startswith(f"{still}: hardness ")


def test_a_video_model_refuses_a_dataset_of_still_presses_as_match_refuses_each(
    video_model: tuple[Path, Path],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
):
    """QA: `index build` and `evaluate --split all` of a model trained on press videos, on a
    dataset of still GelSight frames, succeeded silently (a library and a score of presses
    read as the model never read one), while `match` then refused every still press. Build,
    evaluate and embed refuse it in match's line, before anything is embedded."""
    import lookfeel.evaluate.from_checkpoint as from_checkpoint
    import lookfeel.index.build as build
    from lookfeel.cli import main
    from lookfeel.index.query import STILL_TOUCH_REFUSED

    from ._tiny import write_tiny_dataset

    def never(*args: object, **kwargs: object) -> None:
        raise AssertionError("embedded before the presses were checked")

    monkeypatch.setattr(build, "embed_items", never)
    monkeypatch.setattr(from_checkpoint, "embed_catalog", never)
    ck, _ = video_model
    data = write_tiny_dataset(tmp_path / "stills", 2, drapes=1, fold_presses=2, flat_presses=0)
    first = data / "touch" / "F0001_fold_01_100.png"
    refused = (
        f"lookfeel: {first}: {STILL_TOUCH_REFUSED} (all 4 touch presses of {data} are still images)"
    )
    capsys.readouterr()
    common = ["--checkpoint", str(ck), "--data", str(data)]
    for argv in (
        ["index", "build", *common, "--out", str(tmp_path / "lib")],
        ["evaluate", *common, "--split", "all", "--out", str(tmp_path / "eval")],
        ["embed", *common, "--out", str(tmp_path / "e.npz")],
    ):
        assert main(argv) == 1, argv
        out = capsys.readouterr()
        assert out.err.strip().splitlines() == [refused] and out.out == "", argv
    assert not (tmp_path / "lib").exists() and not (tmp_path / "e.npz").exists()


def test_a_dataset_s_presses_are_checked_as_a_query_s_once_for_all(tmp_path: Path):
    """What `check_touch_dataset` (index build, evaluate, embed) refuses and warns of is what
    `check_touch_input` (match, predict) does of one query, said once for the dataset."""
    from lookfeel.checkpoint import TOUCH_BOTH, TOUCH_FRAMES, TOUCH_VIDEOS
    from lookfeel.config import DataConfig
    from lookfeel.data import ImageError
    from lookfeel.index.match import check_touch_dataset, check_touch_input

    diff, raw = DataConfig(image_size=32), DataConfig(image_size=32, video_reference="none")
    stacked = DataConfig(image_size=32, touch_frames=(0, 1, 2))
    root = tmp_path / "data"
    stills = [root / "touch" / f"F0001_fold_01_{p}.png" for p in (100, 101, 102)]
    videos = [root / "touch" / f"F0002_fold_{p}.mov" for p in (200, 201)]
    with pytest.raises(ImageError, match=r"F0001_fold_01_100\.png: this model was trained on "):
        check_touch_input(stills, TOUCH_VIDEOS, diff)
    with pytest.raises(
        ImageError,
        match=r"^\S+F0001_fold_01_100\.png: this model was trained on press videos.*\(3 of the "
        r"5 touch presses of \S+data are still images\)$",
    ):
        check_touch_dataset([*videos, *stills], TOUCH_VIDEOS, diff, root)
    with pytest.raises(ImageError, match=r"F0002_fold_200\.mov: .*\(all 2 touch presses of "):
        check_touch_dataset(videos, TOUCH_FRAMES, stacked, root)
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        check_touch_dataset([*stills, *videos], TOUCH_FRAMES, diff, root)
    assert [str(w.message).split(":")[0] for w in said] == [
        f"{videos[0]} (and 1 other press video of {root})"
    ]
    assert "trained on still GelSight frames" in str(said[0].message)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # nothing refused, nothing said
        check_touch_dataset(videos, TOUCH_VIDEOS, diff, root)
        check_touch_dataset(stills, TOUCH_VIDEOS, raw, root)
        for trained_on in (TOUCH_BOTH, None):
            check_touch_dataset([*stills, *videos], trained_on, diff, root)
        check_touch_dataset(stills, TOUCH_FRAMES, stacked, root)
        check_touch_dataset([], TOUCH_VIDEOS, diff, root)


def test_the_still_frame_check_spares_raw_frame_and_frame_trained_models(tmp_path: Path):
    from lookfeel.checkpoint import TOUCH_BOTH, TOUCH_FRAMES, TOUCH_VIDEOS, touch_input_of
    from lookfeel.config import DataConfig
    from lookfeel.data import ImageError
    from lookfeel.index.query import check_touch_query, load_query_bytes

    assert touch_input_of(["a/cup_0.MOV", "b/cup_1.mp4"]) == TOUCH_VIDEOS
    assert touch_input_of(["touch/F0001_fold_01_100.png"]) == TOUCH_FRAMES
    assert touch_input_of(["cup_0.mkv", "touch/F0001_fold_01_100.jpg"]) == TOUCH_BOTH
    assert touch_input_of([]) is None

    diff, raw = DataConfig(image_size=32), DataConfig(image_size=32, video_reference="none")
    with pytest.raises(ImageError, match=r"^a\.png: this model was trained on press videos"):
        check_touch_query("a.png", False, TOUCH_VIDEOS, diff)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # nothing refused, nothing said
        check_touch_query("a.mov", True, TOUCH_VIDEOS, diff)
        # trained on raw frames: a frame is one
        check_touch_query("a.png", False, TOUCH_VIDEOS, raw)
        for trained_on in (TOUCH_FRAMES, TOUCH_BOTH, None):
            check_touch_query("a.png", False, trained_on, diff)
        for trained_on in (TOUCH_BOTH, None):
            check_touch_query("a.mov", True, trained_on, diff)
        check_touch_query("a.mov", True, TOUCH_FRAMES, raw)  # its raw frame: as a still one
    # A still-frame model takes a video, read as a difference image it never saw: a warning.
    with pytest.warns(UserWarning, match=r"^a\.mov: this model was trained on still GelSight"):
        check_touch_query("a.mov", True, TOUCH_FRAMES, diff)
    # an upload is a video by its content, whatever its name says
    png = tmp_path / "x.png"
    Image = pytest.importorskip("PIL.Image")
    Image.fromarray(np.zeros((8, 8, 3), np.uint8)).save(png)
    with pytest.raises(ImageError, match=r"^up\.mov: this model was trained on press videos"):
        load_query_bytes(png.read_bytes(), "up.mov", Modality.TOUCH, diff, trained_on=TOUCH_VIDEOS)
    assert load_query_bytes(png.read_bytes(), "up.png", Modality.TOUCH, diff).shape == (3, 32, 32)


def test_predict_answers_a_single_video_without_a_press_as_it_answers_several(
    recordings: Path, video_model: tuple[Path, Path], capsys: pytest.CaptureFixture[str]
):
    from lookfeel.checkpoint import load_model
    from lookfeel.cli import main
    from lookfeel.predict import predict_files

    ck, _ = video_model
    unpressed = str(recordings / "videos" / "foam_3.mov")
    pressed = str(recordings / "videos" / "cork_0.mov")
    (answer,) = predict_files(load_model(ck), [unpressed])
    assert answer.properties == {} and "foam_3.mov: no contact found" in (answer.error or "")
    capsys.readouterr()
    for inputs, status in (
        ([unpressed], 1),
        ([unpressed, unpressed], 1),
        ([unpressed, pressed], 0),
    ):
        assert main(["predict", "--checkpoint", str(ck), *inputs, "--json"]) == status, inputs
        out = capsys.readouterr()
        answers = json.loads(out.out)
        assert [a["path"] for a in answers] == inputs
        assert answers[0]["properties"] == {} and "no contact found" in answers[0]["error"]
        assert len(out.err.strip().splitlines()) == inputs.count(unpressed)  # one warning each
    assert main(["predict", "--checkpoint", str(ck), unpressed]) == 1
    out = capsys.readouterr()
    assert out.out.strip().endswith("(nothing predicted)") and "foam_3.mov" in out.out


def test_a_pooled_query_leaves_out_a_press_without_contact_and_says_so(
    recordings: Path, video_model: tuple[Path, Path]
):
    """`--together` and a multi-press `match` go on with the presses they have, as a run
    does; a query with none is still answered with its error."""
    from lookfeel.checkpoint import load_model
    from lookfeel.index import Library, Matcher
    from lookfeel.predict import predict_files

    ck, lib = video_model
    videos = recordings / "videos"
    unpressed = videos / "foam_3.mov"
    pressed = sorted(p for p in videos.glob("foam_*.mov") if p != unpressed)
    loaded = load_model(ck)
    with pytest.warns(
        UserWarning, match=r"foam_3\.mov: no contact found.*: left out of the pooled"
    ):
        (pooled,) = predict_files(loaded, [*pressed, unpressed], together=True)
    (alone,) = predict_files(loaded, pressed, together=True)
    assert pooled.error is None and pooled.paths == [str(p) for p in pressed]
    assert pooled.properties == alone.properties
    (none,) = predict_files(loaded, [unpressed, unpressed], together=True)
    assert none.properties == {} and "no contact found" in (none.error or "")
    matcher = Matcher(Library.open(lib))
    with pytest.warns(UserWarning, match=r"foam_3\.mov: .*left out of the pooled query"):
        (res,) = matcher.match_files([*pressed, unpressed], Modality.TOUCH, top=2)
    assert res.paths == [str(p) for p in pressed] and res.presses == len(pressed)


def test_predict_says_when_its_probabilities_are_not_calibrated(
    recordings: Path, video_model: tuple[Path, Path]
):
    import dataclasses
    import warnings

    from lookfeel.checkpoint import load_model
    from lookfeel.predict import predict_files

    ck, _ = video_model
    press = recordings / "videos" / "cork_0.mov"
    loaded = load_model(ck)  # the recipe's: temperatures fitted by `lookfeel cv`
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        predict_files(loaded, [press])
    model = dataclasses.replace(loaded.config.model, class_temperature={})
    bare = dataclasses.replace(loaded, config=dataclasses.replace(loaded.config, model=model))
    with pytest.warns(UserWarning, match=r"probabilities are as trained, not calibrated"):
        predict_files(bare, [press])


def test_match_takes_a_video_as_touch_without_being_told(
    recordings: Path, video_model: tuple[Path, Path], capsys: pytest.CaptureFixture[str]
):
    from lookfeel.cli import main

    _, lib = video_model
    press = str(recordings / "videos" / "cork_0.mov")
    assert main(["match", "--index", str(lib), press, "--json"]) == 0
    assert json.loads(capsys.readouterr().out)[0]["query_modality"] == "touch"
    assert main(["match", "--index", str(lib), str(recordings / "labels.csv")]) == 1
    assert "not a PNG or JPEG image" in capsys.readouterr().err  # what it shows cannot be told


def test_a_grey_press_is_answered_by_a_colour_trained_model_with_one_warning(
    video_model: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
):
    """QA: `predict` and `match` answered a grey video of a press (a camera set to greyscale)
    silently, and unlike the colour video of the same press, with a model trained on colour
    presses. Each still answers, with one warning line naming the file; a colour press gets
    none."""
    from lookfeel.cli import run as cli_run

    from ._video import PRESS, object_press, write_video

    ck, lib = video_model
    frames = object_press(2, PRESS, t=14, seed=20)  # cork_0's press
    grey = write_video(tmp_path / "cork_grey.mkv", frames, "ffv1", "gray")
    colour = write_video(tmp_path / "cork_colour.mov", frames)
    said = (
        f"lookfeel: warning: {grey}: the video has no colour (grey); lookfeel reads a press's "
        "colours, and a model trained on colour presses reads a grey one unlike them"
    )
    capsys.readouterr()
    for argv in (
        ["predict", "--checkpoint", str(ck), str(grey), "--json"],
        ["match", "--index", str(lib), str(grey), "--json"],
    ):
        assert cli_run(argv) == 0, argv
        out = capsys.readouterr()
        assert out.err.splitlines().count(said) == 1, argv
        assert len(json.loads(out.out)) == 1  # answered
    for argv in (
        ["predict", "--checkpoint", str(ck), str(colour)],
        ["match", "--index", str(lib), str(colour)],
    ):
        assert cli_run(argv) == 0, argv
        assert "no colour" not in capsys.readouterr().err, argv


def test_a_checkpoint_records_that_its_presses_had_colour(video_model: tuple[Path, Path]):
    """Whether the training presses were grey is recorded as the run read them (no video is
    decoded again: `test_a_training_run_decodes_each_press_video_once`), and kept when the
    ensemble's members are merged; a grey query is then warned of as above."""
    from lookfeel.checkpoint import load_model

    ck, _ = video_model
    loaded = load_model(ck)
    assert loaded.grey_presses == {"videos": 18, "grey": 0}  # foam_3 (no press) left out
    assert loaded.trained_on_grey is False


def test_a_library_of_named_objects_names_them_and_their_words(
    recordings: Path,
    video_model: tuple[Path, Path],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
):
    import shutil

    from lookfeel.cli import main
    from lookfeel.index import Library, Matcher, format_match

    _, lib = video_model
    library = Library.open(lib)
    by_name = {r.name: r for r in library.fabrics.values()}
    assert set(by_name) == set(OBJECTS)
    assert by_name["spoon"].text_labels == {"hardness": "2", "material": "metal"}
    assert library.text_columns == ("material",)
    assert library.classes == {
        "hardness": ("0", "1", "2"),
        "material": ("fabric", "metal", "paper", "wood"),
    }

    query = str(recordings / "videos" / "spoon_1.mov")  # a library item: it is itself
    assert main(["match", "--index", str(lib), "--modality", "touch", query, "--top", "3"]) == 0
    out = capsys.readouterr().out
    assert "  match: spoon: the query is library item touch:" in out
    rows = out.splitlines()
    header = next(i for i, line in enumerate(rows) if line.lstrip().startswith("rank"))
    assert rows[header].split()[:4] == ["rank", "object", "P", "D"]
    assert rows[header + 1].split()[:2] == ["1", "spoon"]
    props = rows[-1]
    assert re.search(
        r"hardness [012] \(\d+%\), material (fabric|metal|paper|wood) \(\d+%\)$", props
    )
    assert "e-" not in props

    assert main(["match", "--index", str(lib), "--modality", "touch", query, "--json"]) == 0
    [r] = json.loads(capsys.readouterr().out)
    first = r["fabrics"][0]
    assert (first["name"], first["text_labels"]["material"]) == ("spoon", "metal")
    assert first["fabric_id"] == by_name["spoon"].id
    material = r["properties"]["material"]
    assert material["number"] is None and material["value"] in {"fabric", "metal", "paper", "wood"}
    assert material["probability"] == max(material["probabilities"].values())
    assert sum(material["probabilities"].values()) == pytest.approx(1.0, abs=1e-3)

    # A library built before names were recorded opens and names fabrics by id, as it did.
    old = shutil.copytree(lib, tmp_path / "old")
    manifest = json.loads((old / "manifest.json").read_text(encoding="utf-8"))
    manifest.pop("text_columns")
    for f in manifest["fabrics"]:
        del f["name"], f["text_labels"]
    (old / "manifest.json").write_text(json.dumps(manifest), encoding="utf-8")
    former = Matcher(Library.open(old))
    assert all(
        rec.name is None and rec.text_labels == {} for rec in former.library.fabrics.values()
    )
    (res,) = former.match_files([query], Modality.TOUCH, top=2)
    assert res.message.startswith(f"fabric {by_name['spoon'].id}: the query is library item")
    assert res.fabrics[0].name is None
    text = format_match(res)
    assert text.startswith(f"Query touch (1 video: {Path(query).name}) against touch")
    assert f"     1  {by_name['spoon'].id:>6}  " in text
    weighted = r"properties \(the \d likeliest fabrics weighted by P\)"
    assert re.search(weighted + r": hardness [012] \(\d+%\)$", text)


def test_serve_names_objects_and_shows_their_words(video_model: tuple[Path, Path]):
    import httpx

    from lookfeel.serve import background_server, create_app

    _, lib = video_model
    with background_server(create_app(lib)) as url:
        fabrics = httpx.get(url + "/api/fabrics").json()
        spoon = next(f for f in fabrics if f["name"] == "spoon")
        assert spoon["text_labels"]["material"] == "metal"
        item = spoon["items"]["touch"][0]
        r = httpx.post(url + "/api/match/item", json={"item": item, "top": 2})
        assert r.status_code == 200, r.text
        [res] = r.json()["results"]
        assert all(f["name"] in OBJECTS for f in res["fabrics"])
        assert set(res["properties"]) == {"hardness", "material"}
