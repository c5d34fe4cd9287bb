"""The shipped recipe `lookfeel train` and `lookfeel cv` use when no --config is named."""

import argparse
import shutil
import warnings
from pathlib import Path

import pytest
import yaml

from lookfeel.cli import main
from lookfeel.cli._args import run_config_source
from lookfeel.config import ConfigError, RunConfig, load_config
from lookfeel.config.recipes import default_recipe, recipe_path
from lookfeel.data import ImageLoader, scan
from lookfeel.modality import Modality, PressKind
from lookfeel.train import select_split

from ._tiny import write_tiny_dataset

D, C, T = Modality.DEPTH, Modality.COLOR, Modality.TOUCH


@pytest.mark.parametrize(
    ("held", "name", "views"),
    [
        ({D, C, T}, "synth_cross.yaml", ["depth", "color", "touch"]),
        ({T, D}, "synth_cross.yaml", ["depth", "touch"]),
        ({C, T}, "synth_cross.yaml", ["color", "touch"]),
        ({T}, "physiclear.yaml", ["touch", "touch"]),
        ({D}, "real_depth.yaml", ["depth", "depth"]),
    ],
)
def test_the_recipe_follows_the_senses_the_folder_holds(held, name, views):
    recipe = default_recipe(held, Path("data"))
    assert recipe.name == name
    assert recipe.path.is_file()
    config = load_config(RunConfig, recipe.path, recipe.overrides)
    assert list(config.train.views) == views
    if held == {C, T}:  # no depth to bridge colour and touch: their own term is trained
        assert config.loss.pair_weights == {}


@pytest.mark.parametrize(("held", "words"), [({C}, "colour photos alone"), (set(), "no depth")])
def test_no_recipe_is_guessed_for_colour_alone_or_nothing(held, words):
    with pytest.raises(ConfigError, match=words):
        default_recipe(held, Path("data"))


def _args(data: Path, config: Path | None = None, sets: tuple[str, ...] = ()) -> argparse.Namespace:
    return argparse.Namespace(data=data, config=config, set=list(sets))


def test_a_named_config_is_used_as_given(tiny_dataset: Path, tmp_path: Path, capsys):
    mine = tmp_path / "my.yaml"
    mine.write_text("train: {steps: 3}\n", encoding="utf-8")
    path, overrides = run_config_source(_args(tiny_dataset, mine, ("a.b=1",)))
    assert (path, overrides) == (mine, ["a.b=1"])
    assert capsys.readouterr().err == ""


def test_without_config_the_folder_picks_and_the_user_overrides_win(tiny_dataset: Path, capsys):
    path, overrides = run_config_source(_args(tiny_dataset, sets=("train.views=[depth,touch]",)))
    assert path.name == "synth_cross.yaml"
    assert "No --config: configs/synth_cross.yaml" in capsys.readouterr().err
    config = load_config(RunConfig, path, overrides)
    assert list(config.train.views) == ["depth", "touch"]  # the user's --set comes last

    shutil.rmtree(tiny_dataset / "color")
    shutil.rmtree(tiny_dataset / "depth")
    path, _ = run_config_source(_args(tiny_dataset))
    assert path.name == "physiclear.yaml"


def _train_quickly(data: Path, out: Path, *sets: str) -> tuple[list[str], dict]:
    """``lookfeel train`` with no --config, two steps; (its argv, the run's saved config)."""
    small = ["train.steps=2", "train.val_every=0", "train.split=none", "model.width=8", *sets]
    argv = ["train", "--data", str(data), "--out", str(out)]
    assert main([*argv, *(x for s in small for x in ("--set", s))]) == 0
    return argv, yaml.safe_load((out / "config.yaml").read_text(encoding="utf-8"))


def test_train_without_config_trains_the_cross_modal_recipe(tiny_dataset: Path, tmp_path: Path):
    out = tmp_path / "run"
    argv, saved = _train_quickly(tiny_dataset, out)
    assert saved["train"]["views"] == ["depth", "color", "touch"]
    assert saved["data"]["touch_frame"] == -1  # synth_cross.yaml's own choice
    assert saved["model"]["width"] == 8
    assert saved["model"]["num_properties"] == 4  # auto: thickness, density, stiffness, stretch
    # Resuming without --config continues the run with its own saved recipe.
    assert main([*argv, "--resume", "--set", "train.steps=3"]) == 0
    assert yaml.safe_load((out / "config.yaml").read_text(encoding="utf-8"))["train"]["steps"] == 3


def test_a_resume_takes_an_auto_property_head_as_the_size_it_became(
    tiny_dataset: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
):
    out = tmp_path / "run"
    argv, _ = _train_quickly(tiny_dataset, out)
    # The user's own config still says auto: a resume accepts it as the number it became.
    resume = [*argv, "--resume", "--set", "model.num_properties=auto", "--set", "train.steps=3"]
    assert main(resume) == 0
    assert yaml.safe_load((out / "config.yaml").read_text(encoding="utf-8"))["train"]["steps"] == 3
    # Another number is another run.
    assert main([*argv, "--resume", "--set", "model.num_properties=3"]) != 0
    assert "model.num_properties (4 -> 3)" in capsys.readouterr().err


def test_the_cross_modal_recipe_trains_on_data_without_labels(tiny_dataset: Path, tmp_path):
    (tiny_dataset / "labels.csv").unlink()  # a user's own recordings, not measured
    _, saved = _train_quickly(tiny_dataset, tmp_path / "run")
    assert saved["train"]["views"] == ["depth", "color", "touch"]
    assert saved["model"]["num_properties"] == 0  # no labels, so no property head


def test_a_chosen_recipe_keeps_the_class_heads_the_labels_have(tmp_path: Path, capsys):
    """physiclear.yaml names PhysiCLeAR's hardness, roughness, bumpiness and material; chosen
    for a user's touch recordings labelled with hardness and material, it trains those two and
    says so. A --config the user names, or a --set of the heads, is used as written."""
    from ._tiny import write_recordings

    labels = "object,hardness,material\nsponge,0,foam\ncork,1,wood\nsteel,2,metal\n"
    data = write_recordings(tmp_path / "digit", {"sponge": 2, "cork": 2, "steel": 2}, labels)
    path, overrides = run_config_source(_args(data))
    err = capsys.readouterr().err
    assert path.name == "physiclear.yaml"
    assert "class heads: hardness, material (the recipe's roughness, bumpiness are not in " in err
    assert load_config(RunConfig, path, overrides).model.class_heads == ("hardness", "material")

    path, overrides = run_config_source(_args(data, sets=("model.class_heads=[roughness]",)))
    assert "class heads" not in capsys.readouterr().err
    assert load_config(RunConfig, path, overrides).model.class_heads == ("roughness",)
    path, overrides = run_config_source(_args(data, recipe_path("physiclear.yaml")))
    assert len(load_config(RunConfig, path, overrides).model.class_heads) == 4

    (data / "labels.csv").unlink()  # no labels at all: no class head
    path, overrides = run_config_source(_args(data))
    assert "class heads: none (no labels.csv for the recipe's hardness, " in capsys.readouterr().err
    assert load_config(RunConfig, path, overrides).model.class_heads == ()


def _rig(root: Path, fabrics: int = 8) -> Path:
    """A user's own rig in the GelFabric layout: depth and colour drapes, and touch presses
    recorded as videos in touch/ (``F0001_fold_101.mp4``), labels.csv without paper_split."""
    from ._video import PRESS, object_press, write_video

    data = write_tiny_dataset(root, fabrics, drapes=2, fold_presses=0, flat_presses=0)
    (data / "touch").mkdir()
    for f in range(1, fabrics + 1):
        for p, kind in enumerate(("fold", "fold", "flat")):
            frames = object_press(f, PRESS, 14, seed=p)
            write_video(data / "touch" / f"F{f:04d}_{kind}_{100 * f + p}.mp4", frames)
    rows = [f"{f},{0.7 * f:.2f},{f % 3}\n" for f in range(1, fabrics + 1)]
    (data / "labels.csv").write_text(
        "fabric_id,bend_score,softness_rank\n" + "".join(rows), encoding="utf-8"
    )
    return data


def test_the_recipe_chosen_for_a_small_rig_with_touch_videos_loads_and_splits(
    tmp_path: Path, capsys
):
    """QA: the cross-modal recipe chosen for 8 fabrics whose presses are videos stacked frame
    images of a press (data.touch_frames) and asked for 5 folds of 18 fabrics."""
    data = _rig(tmp_path / "rig")
    path, overrides = run_config_source(_args(data))
    err = capsys.readouterr().err
    assert path.name == "synth_cross.yaml"
    assert "touch videos read as physiclear.yaml does" in err
    # 4 folds of 2: cv refuses a fold that holds out fewer than 2.
    assert "8 fabrics to train on, fewer than the recipe's 5 folds of 18: 4 folds" in err
    config = load_config(RunConfig, path, overrides)
    physiclear = load_config(RunConfig, recipe_path("physiclear.yaml")).data
    assert config.data.touch_frames == () and config.data.color_reprints == 0
    assert (config.data.video_views, config.data.video_embed) == (
        physiclear.video_views,
        physiclear.video_embed,
    )
    catalog = scan(data)
    loader = ImageLoader(config.data)
    for m in (Modality.DEPTH, Modality.COLOR, Modality.TOUCH):
        item = catalog.items(m)[0]
        assert loader.load(item).shape[-1] == config.data.size_of(m)
        assert (len(loader.views(item)) > 1) == (m is Modality.TOUCH)  # frames of the press
    train, val, info = select_split(catalog, config)  # fold 0 of folds dealing all 8
    assert val is not None and sorted(train.ids + val.ids) == list(range(1, 9))
    assert (config.train.folds, len(val.ids)) == (4, 2)
    assert (info["kind"], info["fold_size"]) == ("fold", None)
    # Frame images (a synthetic world's) keep the recipe's stacked frames; 2 fabrics, 2 folds.
    world = write_tiny_dataset(tmp_path / "world", fabrics=2, drapes=1, flat_presses=0)
    path, overrides = run_config_source(_args(world))
    assert "touch videos" not in capsys.readouterr().err
    config = load_config(RunConfig, path, overrides)
    assert config.data.touch_frames == (0, 1, 2)
    assert (config.train.folds, config.train.fold_size) == (2, None)


def test_the_reason_says_the_users_folds_not_the_recipes(tmp_path: Path, capsys):
    """QA: `cv --folds 3` (a train.folds=3 after the recipe's) on 8 fabrics ran 3 folds while
    the chooser's line claimed its own 4 (train.folds=4). The user's folds and fold size are
    kept and said as theirs; too many folds for 2 held out each are said in the same line."""
    data = write_tiny_dataset(tmp_path / "eight", 8, drapes=1, fold_presses=2, flat_presses=0)
    path, overrides = run_config_source(_args(data, sets=("train.folds=3",)))
    err = capsys.readouterr().err
    assert "your 3 folds dealing them all (train.fold_size=null)" in err
    assert "train.folds=4" not in err and "4 folds" not in err
    config = load_config(RunConfig, path, overrides)
    assert (config.train.folds, config.train.fold_size) == (3, None)

    path, overrides = run_config_source(_args(data, sets=("train.folds=6",)))
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1
    assert "your train.folds=6 leaves 1 of the 8 fabrics held out in some fold" in err
    assert "use train.folds=4 or fewer" in err
    assert load_config(RunConfig, path, overrides).train.folds == 6

    # The user's fold size: the recipe's folds made to fit it, said so.
    path, overrides = run_config_source(_args(data, sets=("train.fold_size=2",)))
    err = capsys.readouterr().err
    assert "too few for the recipe's 5 folds of your 2 (train.fold_size): 4 folds" in err
    config = load_config(RunConfig, path, overrides)
    assert (config.train.folds, config.train.fold_size) == (4, 2)


def test_cv_folds_reach_the_recipe_chooser(tmp_path: Path, capsys):
    data = write_tiny_dataset(tmp_path / "eight", 8, drapes=1, fold_presses=2, flat_presses=0)
    assert main(["cv", "--data", str(data), "--out", str(tmp_path / "cv"), "--folds", "6"]) == 1
    err = capsys.readouterr().err
    chosen, refused = err.splitlines()  # the recipe's line, then cv's own refusal
    assert "your 6 folds dealing them all" in chosen and "4 folds dealing" not in chosen
    assert "your train.folds=6 leaves 1 of the 8 fabrics held out" in chosen
    assert refused.startswith("lookfeel: --folds 6 (train.folds) of the 8 fabrics")


def _depth_as_tif(data: Path) -> None:
    """Every depth map saved as a TIFF, a format the scan skips."""
    from PIL import Image

    for png in sorted((data / "depth").glob("*.png")):
        Image.open(png).save(png.with_suffix(".tif"))
        png.unlink()


def test_train_says_a_sense_whose_every_file_was_skipped(
    tiny_dataset: Path, tmp_path: Path, capsys
):
    """QA: all depth maps were .tif (skipped by the scan): the recipe chosen for the folder
    trained colour and touch without a word of depth. It warns in one line; a config whose
    views use depth is refused in one line, not one per fabric."""
    _depth_as_tif(tiny_dataset)
    with pytest.warns(UserWarning) as caught:
        _, saved = _train_quickly(tiny_dataset, tmp_path / "run")
    assert saved["train"]["views"] == ["color", "touch"]
    said = [str(w.message) for w in caught if "depth" in str(w.message)]
    assert len(said) == 1
    assert "all 18 depth file(s) of depth/ were skipped or unreadable (e.g. F0001_" in said[0]
    assert "so this run trains without depth" in said[0]

    capsys.readouterr()
    argv = ["train", "--data", str(tiny_dataset), "--out", str(tmp_path / "named")]
    assert main([*argv, "--config", str(recipe_path("synth_cross.yaml"))]) == 1
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1
    assert "the run's train.views use depth, but all 18 depth file(s)" in err
    assert "leave depth out of train.views" in err
    assert not (tmp_path / "named").exists()


def test_train_says_a_damaged_sense_in_one_line(tiny_dataset: Path, tmp_path: Path, capsys):
    """The chooser reads names only, so damaged depth PNGs still choose depth: the run is
    refused in one line naming the sense, not a line per file and per fabric."""
    for png in (tiny_dataset / "depth").glob("*.png"):
        png.write_bytes(b"not a png")
    argv = ["train", "--data", str(tiny_dataset), "--out", str(tmp_path / "run")]
    assert main(argv) == 1
    refused = capsys.readouterr().err.splitlines()[1:]  # after the recipe's own line
    assert len(refused) == 1
    assert "depth must be a 16-bit greyscale PNG" in refused[0]
    assert "move depth/ aside to train without depth" in refused[0]


def _far(data: Path, mm: int = 2000) -> None:
    """Every depth map of ``data`` moved ``mm`` further from the camera (its holes kept)."""
    import numpy as np
    from PIL import Image

    for png in (data / "depth").glob("*.png"):
        d = np.asarray(Image.open(png)).astype(np.uint16)
        Image.fromarray(np.where(d > 0, d + mm, 0).astype(np.uint16)).save(png)


def _valid_depth(data: Path):
    import numpy as np
    from PIL import Image

    maps = [np.asarray(Image.open(p)) for p in sorted((data / "depth").glob("*.png"))]
    return np.concatenate([m[m > 0] for m in maps])


def test_the_chooser_maps_raw_depth_from_a_range_that_holds_it(tiny_dataset: Path, capsys):
    """QA: a rig's depth from another camera pose (median 1,644 mm) was mapped from the
    default 800-1,300 mm and trained as a constant image. The chooser maps raw depth from the
    2nd-98th percentile of a sample of the valid pixels, rounded to 10 mm, and says so; depth
    the default range holds, or a range the user sets, is left as it is."""
    import numpy as np

    path, overrides = run_config_source(_args(tiny_dataset))  # 940-1,160 mm: the default
    assert "depth maps' valid pixels" not in capsys.readouterr().err
    assert not [o for o in overrides if o.startswith("data.depth_")]

    _far(tiny_dataset)  # ~3 m: past 800-1,300 mm
    path, overrides = run_config_source(_args(tiny_dataset))
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1
    c = load_config(RunConfig, path, overrides).data
    lo, hi = np.percentile(_valid_depth(tiny_dataset), [2, 98])
    assert c.depth_min_mm % 10 == 0 and c.depth_range_mm % 10 == 0
    assert c.depth_min_mm <= lo < c.depth_min_mm + 10
    assert hi <= c.depth_min_mm + c.depth_range_mm < hi + 10
    low, high = int(c.depth_min_mm), int(c.depth_min_mm + c.depth_range_mm)
    assert (
        "0% of the depth maps' valid pixels lie inside the recipe's 800-1,300 mm (their median: "
        in err
    )
    assert (
        f"raw depth mapped from their 2nd-98th percentile, {low:,}-{high:,} mm "
        f"(data.depth_min_mm={low}, data.depth_range_mm={high - low})" in err
    )
    # The user's own range (or either half of it) is theirs.
    path, overrides = run_config_source(_args(tiny_dataset, sets=("data.depth_min_mm=5000",)))
    assert "depth_min_mm=" not in capsys.readouterr().err
    assert load_config(RunConfig, path, overrides).data.depth_range_mm == 500
    # Registered depth is not mapped from a range: nothing fitted.
    path, overrides = run_config_source(_args(tiny_dataset, sets=("data.depth_input=registered",)))
    assert "depth_min_mm" not in capsys.readouterr().err


def test_real_and_synthetic_depth_keep_the_default_range(real_data: Path, tmp_path: Path):
    """GelFabric's Kinect depth (medians 999-1,089 mm: 77% inside 800-1,300 mm) and a
    synthetic world's keep the recipe's range, whichever recipe reads them raw."""
    from lookfeel.config.recipes import fit_dataset
    from lookfeel.synth import SIZE_PRESETS, SynthConfig, generate

    world = tmp_path / "world"
    tiny = SynthConfig(
        fabrics=2, drapes=2, presses_flat=1, presses_fold=1, workers=1, **SIZE_PRESETS["tiny"]
    )
    generate(tiny, world, progress=False)
    for data in (real_data, world):
        recipe = default_recipe({D, T}, data)  # synth_cross.yaml: raw depth
        fitted = fit_dataset(recipe, scan(data, check_headers=False))
        assert not [o for o in fitted.overrides if o.startswith("data.depth_")], data
        assert "depth maps' valid pixels" not in fitted.reason


def test_train_warns_of_depth_outside_the_range_the_run_maps_it_from(
    tiny_dataset: Path, tmp_path: Path
):
    """The warning before a run checks the run's own range (a user's, too), in train's words,
    and names a range that holds the depth; a chosen recipe's fitted range is not warned of."""
    _far(tiny_dataset)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        _, saved = _train_quickly(tiny_dataset, tmp_path / "fitted")
    assert saved["data"]["depth_min_mm"] > 2000
    assert not [w for w in caught if "valid depth pixels" in str(w.message)]

    with pytest.warns(UserWarning) as caught:
        _train_quickly(tiny_dataset, tmp_path / "yours", "data.depth_min_mm=5000")
    said = [str(w.message) for w in caught if "valid depth pixels" in str(w.message)]
    assert len(said) == 1 and len(said[0].splitlines()) == 1
    assert (
        "only 0% of the valid depth pixels (a sample of 18 depth maps) lie between 5,000 and "
        in (said[0])
    )
    assert (
        "5,500 mm, the range this run maps raw depth from to 0..1 (data.depth_min_mm 5000, "
        in (said[0])
    )
    assert "reads no run config" not in said[0] and "the defaults" not in said[0]
    assert f"set data.depth_min_mm={saved['data']['depth_min_mm']:g} and " in said[0]
    # A run whose own range holds the depth is not warned.
    with warnings.catch_warnings(record=True) as caught2:
        warnings.simplefilter("always")
        _train_quickly(tiny_dataset, tmp_path / "own", "data.depth_min_mm=2800")
    assert not [w for w in caught2 if "valid depth pixels" in str(w.message)]


def test_the_chooser_trains_on_the_press_kinds_the_data_holds(tmp_path: Path, capsys):
    """QA: with flat presses only, `lookfeel train` failed "fabric 1 has no touch (fold
    presses) item" (the default data.touch_kinds); with both kinds, half the presses went
    unused without a word."""
    flat = write_tiny_dataset(tmp_path / "flat", 4, drapes=1, fold_presses=0, flat_presses=2)
    path, overrides = run_config_source(_args(flat))
    err = capsys.readouterr().err
    assert (
        "touch: 8 flat presses, no fold press (the recipe's data.touch_kinds): trains on those "
        "(data.touch_kinds=[flat])" in err
    )
    assert load_config(RunConfig, path, overrides).data.touch_kinds == (PressKind.FLAT,)
    _, saved = _train_quickly(flat, tmp_path / "run")
    assert saved["data"]["touch_kinds"] == ["flat"]

    both = write_tiny_dataset(tmp_path / "both", 4, drapes=1, fold_presses=2, flat_presses=1)
    path, overrides = run_config_source(_args(both))
    err = capsys.readouterr().err
    assert (
        "trains on the 8 fold presses (the recipe's data.touch_kinds); 4 flat presses left out: "
        '--set "data.touch_kinds=[flat,fold]" to use them' in err
    )
    assert load_config(RunConfig, path, overrides).data.touch_kinds == (PressKind.FOLD,)
    path, overrides = run_config_source(_args(both, sets=("data.touch_kinds=[flat,fold]",)))
    assert "presses" not in capsys.readouterr().err
    assert set(load_config(RunConfig, path, overrides).data.touch_kinds) == {
        PressKind.FLAT,
        PressKind.FOLD,
    }
    # A fabric without a press of the recipe's kind: every kind.
    for press in (both / "touch").glob("F0002_fold_*"):
        press.unlink()
    path, overrides = run_config_source(_args(both))
    assert (
        "F0002 has no fold press (the recipe's data.touch_kinds): trains on the 4 flat and 6 "
        "fold presses (data.touch_kinds=[flat,fold])" in capsys.readouterr().err
    )
    # Presses of no stated kind (an object's videos/<object>_<n>.mov) are of every kind.
    from ._tiny import write_recordings

    labels = "object,hardness\nsponge,0\ncork,1\n"
    videos = write_recordings(tmp_path / "videos", {"sponge": 2, "cork": 2}, labels)
    path, overrides = run_config_source(_args(videos))
    assert "touch_kinds" not in capsys.readouterr().err
    assert not [o for o in overrides if "touch_kinds" in o]


def _with_words(data: Path, **columns: list[str]) -> None:
    """labels.csv of ``data`` with columns of words added, one value a fabric in order."""
    lines = (data / "labels.csv").read_text(encoding="utf-8").splitlines()
    names = ",".join(columns)
    rows = [",".join(v[i] for v in columns.values()) for i in range(len(lines) - 1)]
    text = [f"{lines[0]},{names}", *(f"{a},{b}" for a, b in zip(lines[1:], rows, strict=True))]
    (data / "labels.csv").write_text("\n".join(text) + "\n", encoding="utf-8")


def test_the_chooser_adds_class_heads_for_columns_of_words(tmp_path: Path, capsys):
    """QA: the cross-modal recipe left labels.csv's material unused (no class head), so
    `lookfeel match` answered a material from the library's neighbours while `lookfeel
    predict` on the same checkpoint answered none. The chooser adds a head for each column of
    words it can learn, and says why it leaves one out."""
    from lookfeel.predict import predict_files

    data = write_tiny_dataset(tmp_path / "words", 6, drapes=1, fold_presses=2, flat_presses=0)
    _with_words(
        data,
        material=["wool", "wool", "cotton", "cotton", "silk", "felt"],
        note=[f"drape {i}" for i in range(6)],
        maker=["acme", "acme", "acme", "acme", "bolt", "coil"],
    )
    path, overrides = run_config_source(_args(data))
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1
    assert (
        'class heads for labels.csv\'s words: material (model.class_heads=["material"]), so '
        "that `lookfeel predict` answers them as `lookfeel match` does" in err
    )
    assert (
        "no class head for labels.csv's note: every fabric has its own word (descriptions, not "
        "classes)" in err
    )
    assert (
        "no class head for labels.csv's maker: only 1 of its 3 classes is held by 2 fabrics or "
        "more, too few to learn" in err
    )
    assert load_config(RunConfig, path, overrides).model.class_heads == ("material",)
    out = tmp_path / "run"
    _, saved = _train_quickly(data, out)
    assert saved["model"]["classes"] == {"material": ["cotton", "felt", "silk", "wool"]}
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", ".*probabilities are as trained, not calibrated")
        [answer] = predict_files(out / "checkpoints" / "last.pt", data / "color" / "F0001_1.png")
    assert answer.properties["material"].value in {"cotton", "felt", "silk", "wool"}
    # The user's own heads (none, here) are theirs; a recipe with heads keeps its own.
    capsys.readouterr()
    path, overrides = run_config_source(_args(data, sets=("model.class_heads=[]",)))
    assert "class head" not in capsys.readouterr().err
    assert load_config(RunConfig, path, overrides).model.class_heads == ()


def test_a_shipped_config_is_named_the_same_from_any_folder(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
):
    from lookfeel.config.recipes import config_file, shipped_configs

    monkeypatch.chdir(tmp_path)  # no configs/ here: as after `pip install lookfeel`
    assert "physiclear" in shipped_configs() and "paper/flat" in shipped_configs()
    for name in ("tiny", "tiny.yaml", "configs/tiny.yaml"):
        assert config_file(name) == recipe_path("tiny.yaml")
    assert config_file("configs/paper/flat.yaml") == recipe_path("paper/flat.yaml")
    assert config_file("paper/flat") == recipe_path("paper/flat.yaml")
    Path("tiny.yaml").write_text(
        "train: {steps: 3}\n", encoding="utf-8"
    )  # the user's own file comes first
    assert config_file("tiny.yaml") == Path("tiny.yaml")
    for wrong in (
        "nosuch",
        "configs/nosuch.yaml",
        str(tmp_path / "paper" / "flat.yaml"),
        "../tiny",
    ):
        with pytest.raises(ConfigError, match=r"no such config file, nor a shipped .*physiclear"):
            config_file(wrong)
    (tmp_path / "data").mkdir()
    argv = ["train", "--data", str(tmp_path / "data"), "--out", str(tmp_path / "run")]
    assert main([*argv, "--config", "nosuch"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("lookfeel: nosuch: no such config file, nor a")
