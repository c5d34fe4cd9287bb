import dataclasses
import typing
from pathlib import Path
from typing import Any

import pytest

import lookfeel.config.loss as config_loss
from lookfeel.config import (
    AugmentConfig,
    ConfigError,
    DataConfig,
    EvalConfig,
    LossConfig,
    ModelConfig,
    RunConfig,
    TrainConfig,
    apply_overrides,
    from_dict,
    load_config,
    save_config,
    to_dict,
)
from lookfeel.config.loss import loss_kinds
from lookfeel.config.model import backbone_names
from lookfeel.modality import Modality, Pair, PressKind


def test_defaults_then_yaml_then_overrides(tmp_path: Path):
    path = tmp_path / "c.yaml"
    path.write_text(
        "image_size: 64\naugment:\n  color: {gamma: [0.5, 2.0], permute_channels: true}\n",
        encoding="utf-8",
    )
    cfg = load_config(DataConfig, path, ["image_size=32", "touch_kinds=fold,flat", "presses=3"])
    assert cfg.image_size == 32
    assert cfg.presses == 3
    assert cfg.touch_kinds == (PressKind.FOLD, PressKind.FLAT)
    assert cfg.augment[Modality.COLOR] == AugmentConfig(gamma=(0.5, 2.0), permute_channels=True)
    assert cfg.depth_min_mm == 800.0  # untouched default


def test_a_bad_value_is_blamed_on_the_file_or_on_the_set_that_gave_it(tmp_path: Path):
    path = tmp_path / "c.yaml"
    path.write_text("train:\n  steps: 10\n  lr: fast\n", encoding="utf-8")
    with pytest.raises(ConfigError, match=r"^--set train.steps=abc: train.steps: expected an"):
        load_config(RunConfig, path, ["train.lr=0.1", "train.steps=abc"])
    with pytest.raises(ConfigError, match=rf"^{path}: train.lr: expected a number"):
        load_config(RunConfig, path, ["train.steps=5"])
    with pytest.raises(ConfigError, match=r"^--set train.stepz=3: unknown key train.stepz;"):
        load_config(RunConfig, path, ["train.stepz=3"])
    # A whole section given with --set answers for the keys inside it.
    with pytest.raises(ConfigError, match=r"^--set train=\{steps: x\}: train.steps:"):
        load_config(RunConfig, None, ["train={steps: x}"])


@pytest.mark.parametrize(
    ("data", "message"),
    [
        ({"image_sise": 64}, "unknown key image_sise"),
        ({"image_size": "big"}, "image_size: expected an integer, got 'big'"),
        ({"image_size": True}, "image_size: expected an integer"),
        ({"touch_kinds": ["fold", "pinch"]}, r"touch_kinds\[1\]: 'pinch' is not one of"),
        ({"augment": {"colour": {}}}, "augment.colour: 'colour' is not one of"),
        ({"augment": {"color": {"gama": [1, 2]}}}, "unknown key augment.color.gama"),
        ({"augment": {"color": {"gamma": [1]}}}, "augment.color.gamma: expected 2 values"),
        ({"depth_holes": "zero"}, "data.depth_holes: 'zero' is not one of nearest, clip"),
        ({"same_fraction": 1.5}, "same_fraction: must be in"),
        ({"touch_zoom": 0}, r"data.touch_zoom: must be in \(0, 1\], got 0"),
        ({"color_size": 4}, "data.color_size: must be >= 8 or null, got 4"),
        ({"touch_frames": [0, "last"]}, r"touch_frames\[1\]: expected an integer, got .last."),
        ({"touch_frames": list(range(9))}, "data.touch_frames: at most 8 frames, got 9"),
        (
            {"touch_frames": [0, -1], "augment": {"touch": {"permute_channels": True}}},
            "data.augment.touch.permute_channels: would mix the frames",
        ),
    ],
)
def test_strict_errors_name_the_key(data, message):
    with pytest.raises(ConfigError, match=message):
        from_dict(DataConfig, data)


def test_touch_frames_null_means_none_as_the_empty_list_does(tmp_path: Path):
    """QA: ``--set data.touch_frames=null`` was refused (expected an integer, got None) while
    ``[]`` said the same: no frames stacked, the one frame ``touch_frame``."""
    stacked = load_config(RunConfig, None, ["data.touch_frames=[0,1,2]"])
    for none in ("null", "[]", ""):
        sets = ["data.touch_frames=[0,1,2]", f"data.touch_frames={none}"]
        cfg = load_config(RunConfig, None, sets)
        assert cfg.data.touch_frames == () and cfg.data.touch_frame_indices == (-2,)
        assert cfg == load_config(RunConfig) != stacked
    save_config(load_config(RunConfig, None, ["data.touch_frames=null"]), tmp_path / "c.yaml")
    assert "touch_frames: []" in (tmp_path / "c.yaml").read_text(encoding="utf-8")


def test_file_errors_name_the_file(tmp_path: Path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("# notes\n\n```bash\n", encoding="utf-8")
    with pytest.raises(ConfigError, match="bad.yaml: not valid YAML: found character") as e:
        load_config(DataConfig, bad)
    assert str(e.value).endswith("at line 3, column 1") and "\n" not in str(e.value)
    bad.write_text("- 1\n- 2\n", encoding="utf-8")
    with pytest.raises(ConfigError, match="bad.yaml: the top level must be a mapping"):
        load_config(DataConfig, bad)
    bad.write_text("presses: 0\n", encoding="utf-8")
    with pytest.raises(ConfigError, match="bad.yaml: data.presses: must be >= 1"):
        load_config(DataConfig, bad)
    with pytest.raises(ConfigError, match="missing.yaml: cannot read"):
        load_config(DataConfig, tmp_path / "missing.yaml")


def test_overrides_do_not_modify_input_and_reject_bad_syntax():
    base = {"augment": {"color": {"crop_p": 0.1}}}
    out = apply_overrides(base, ["augment.color.crop_p=0.2", "augment.touch.noise_std=0.05"])
    assert base == {"augment": {"color": {"crop_p": 0.1}}}
    assert out["augment"] == {"color": {"crop_p": 0.2}, "touch": {"noise_std": 0.05}}
    with pytest.raises(ConfigError, match="expected key=value"):
        apply_overrides({}, ["image_size"])
    with pytest.raises(ConfigError, match="image_size is not a mapping"):
        apply_overrides({"image_size": 3}, ["image_size.x=1"])
    with pytest.raises(ConfigError, match=r"'views=\[depth,': the value is not valid YAML") as e:
        apply_overrides({}, ["views=[depth,"])  # raised yaml's ParserError: a traceback
    assert "\n" not in str(e.value)


def test_save_and_load_round_trip(tmp_path: Path):
    cfg = DataConfig(
        image_size=48,
        touch_kinds=(PressKind.FLAT,),
        augment={Modality.TOUCH: AugmentConfig(crop_p=0.2, noise_std=0.01)},
    )
    save_config(cfg, tmp_path / "run" / "config.yaml")
    assert load_config(DataConfig, tmp_path / "run" / "config.yaml") == cfg
    assert to_dict(cfg)["touch_kinds"] == ["flat"]
    assert [p.name for p in (tmp_path / "run").iterdir()] == ["config.yaml"]  # no temp left


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        (
            ["train.split=random"],
            "train.split: 'random' is not one of stratified, paper, seen, fold",
        ),
        (["loss.kind=arcface"], "loss.kind: 'arcface' is not one of contrastive, infonce, triplet"),
        (["loss.distance=cosine"], "loss.distance: 'cosine' is not one of euclidean, mean_squared"),
        (["model.backbone=vgg"], "model.backbone: 'vgg' is not one of alexnet, compact, resnet18"),
        (["model.press_pool=sum"], "model.press_pool: 'sum' is not one of max, mean"),
        (["data.touch_crop=left"], "data.touch_crop: 'left' is not one of auto, center, none"),
        (["train.device=tpu"], "train.device: 'tpu' is not one of auto, cpu, cuda"),
        (["train.lr_schedule=step"], "train.lr_schedule: 'step' is not one of constant, cosine"),
        (["train.split=1"], r"train.split: expected a string, got 1"),
    ],
)
def test_a_bad_literal_choice_names_the_key_and_the_allowed_values(overrides, message):
    with pytest.raises(ConfigError, match=message):
        load_config(RunConfig, overrides=overrides)


def test_literal_choices_are_checked_when_built_in_code_too():
    with pytest.raises(ConfigError, match="loss.kind: 'arcface' is not one of contrastive"):
        LossConfig(kind="arcface")  # type: ignore[arg-type]
    with pytest.raises(ConfigError, match=r"eval.probes: 'svm' is not one of knn, ridge"):
        load_config(EvalConfig, overrides=["probes=[knn,svm]"])
    with pytest.raises(ConfigError, match="train.split: 'random' is not one of"):
        dataclasses.replace(TrainConfig(), split="random")  # type: ignore[arg-type]


def test_every_choice_field_is_a_literal():
    # A choice kept as a bare ``str`` would escape the loader's check. The two choices a user
    # can extend (lookfeel.models.register_backbone, lookfeel.losses.register_loss) are
    # checked against their registries instead.
    registered = {(ModelConfig, "backbone"): backbone_names(), (LossConfig, "kind"): loss_kinds()}
    for cls in (DataConfig, ModelConfig, LossConfig, TrainConfig, EvalConfig):
        for name, tp in typing.get_type_hints(cls).items():
            assert tp is not str or (cls, name) in registered, (
                f"{cls.__name__}.{name} is a bare str"
            )
    for (cls, name), allowed in registered.items():
        with pytest.raises(
            ConfigError, match=f"is not one of {', '.join(allowed)} \\(one of your own: "
        ):
            cls(**{name: "nothing_registered"})


def test_pairs_load_as_pairs_and_save_as_their_names(tmp_path: Path):
    cfg = load_config(RunConfig, overrides=["train.val_pairs=[touch_to_depth,depth_to_depth]"])
    assert cfg.train.val_pairs == ("touch_to_depth", "depth_to_depth")
    assert all(isinstance(p, Pair) for p in cfg.train.val_pairs)
    assert cfg.train.val_pairs[0].gallery is Modality.DEPTH
    save_config(cfg, tmp_path / "config.yaml")
    assert "- touch_to_depth" in (tmp_path / "config.yaml").read_text(encoding="utf-8")
    assert load_config(RunConfig, tmp_path / "config.yaml") == cfg
    assert to_dict(cfg)["train"]["val_pairs"] == ["touch_to_depth", "depth_to_depth"]
    assert type(to_dict(cfg)["train"]["val_pairs"][0]) is str
    assert TrainConfig(val_pairs=("color_to_touch",)).val_pairs[0].query is Modality.COLOR
    with pytest.raises(ConfigError, match=r"train.val_pairs\[1\]: 'touch_depth' is not a modality"):
        load_config(RunConfig, overrides=["train.val_pairs=[touch_to_depth,touch_depth]"])
    with pytest.raises(ConfigError, match="eval.figure_pairs: 'touch_to_smell' is not a modality"):
        EvalConfig(figure_pairs=("touch_to_smell",))  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("section", "cls", "key"),
    [
        ("train", TrainConfig, "seed"),
        ("train", TrainConfig, "split_seed"),
        ("eval", EvalConfig, "seed"),
    ],
)
def test_a_negative_seed_is_refused_naming_its_key(section: str, cls: type, key: str):
    """numpy's generators take no negative seed: -1 failed deep in training or evaluation with
    numpy's "expected non-negative integer" (QA); the config refuses it, and 0 is a seed."""
    with pytest.raises(ConfigError, match=rf"^{section}\.{key}: must be >= 0, got -1$"):
        from_dict(cls, {key: -1})
    assert getattr(from_dict(cls, {key: 0}), key) == 0
    if section == "train":  # as `lookfeel train --set train.seed=-1` gives it
        with pytest.raises(ConfigError, match=rf"^--set train\.{key}=-1: train\.{key}: must"):
            load_config(RunConfig, None, [f"train.{key}=-1"])


def test_an_input_smaller_than_the_backbone_takes_is_refused_naming_the_size_key():
    """alexnet at 32 px, compact or resnet18 at 8 px trained until the first forward pass and
    died with a traceback (QA). The minimum is the backbone class's own, passed in."""
    from lookfeel.models import BACKBONES

    for name, cls in BACKBONES.items():
        low = cls.min_size - 1
        cfg = load_config(RunConfig, None, [f"model.backbone={name}", f"data.image_size={low}"])
        with pytest.raises(ConfigError) as e:
            cfg.check_input_sizes(cls.min_size)
        assert str(e.value) == (
            f"data.image_size={low} is below the {cls.min_size} px on each side that "
            f"model.backbone={name} accepts; set data.image_size to at least {cls.min_size}, "
            "or choose another model.backbone"
        )
        at_min = dataclasses.replace(cfg, data=DataConfig(image_size=cls.min_size))
        at_min.check_input_sizes(cls.min_size)  # the minimum itself is fine


def test_the_colour_size_is_checked_where_colour_has_its_own_and_is_trained():
    from lookfeel.models import BACKBONES

    least = BACKBONES["alexnet"].min_size
    base = ["model.backbone=alexnet", f"data.image_size={least + 1}"]
    small_colour = load_config(RunConfig, None, [*base, "data.color_size=32"])
    with pytest.raises(
        ConfigError, match=rf"^data\.color_size=32 is below the {least} px .*alexnet"
    ):
        small_colour.check_input_sizes(least)
    both = load_config(RunConfig, None, [*base, "data.image_size=32", "data.color_size=32"])
    with pytest.raises(ConfigError, match=r"^data\.image_size=32 and data\.color_size=32 are "):
        both.check_input_sizes(least)
    # Without colour in the training tuple its size is never used, so never refused.
    no_colour = load_config(
        RunConfig, None, [*base, "data.color_size=32", "train.views=[depth,touch]"]
    )
    no_colour.check_input_sizes(least)


def test_loss_options_are_settings_of_one_s_own_loss_recorded_with_the_run(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
):
    """QA (session 57, F5): a loss of one's own could have no setting of its own (``--set
    loss.alpha=...`` is an unknown key). ``loss.options`` holds them, free-form, checked only
    as names and plain values that config.yaml (and so the checkpoint) records."""
    monkeypatch.setitem(config_loss._LOSS_KINDS, "lfopts", None)  # as register_loss does
    assert LossConfig().options == {}
    sets = ["loss.kind=lfopts", "loss.options.alpha=0.5", "loss.options.mode=soft"]
    cfg = load_config(RunConfig, overrides=[*sets, "loss.options.ks=[1, {a: null}]"])
    assert cfg.loss.options == {"alpha": 0.5, "mode": "soft", "ks": [1, {"a": None}]}
    save_config(cfg, tmp_path / "config.yaml")
    assert load_config(RunConfig, tmp_path / "config.yaml") == cfg
    assert to_dict(cfg)["loss"]["options"] == cfg.loss.options
    for given, message in [
        ("loss.options=[1, 2]", "--set loss.options=[1, 2]: loss.options: expected a mapping"),
        ("loss.options={1: a}", "--set loss.options={1: a}: loss.options.1: expected a string"),
    ]:
        with pytest.raises(ConfigError) as e:
            load_config(RunConfig, overrides=["loss.kind=lfopts", given])
        assert str(e.value).startswith(message)
    bad: list[tuple[Any, str]] = [
        ({"f": object()}, "loss.options.f: a value of type object cannot be written in config"),
        ({"n": {"ok": [1, {2: 3}]}}, r"loss.options.n.ok\[1\]: a name must be text, got 2"),
        ({3: 1}, "loss.options: a name must be text, got 3"),
        ([("a", 1)], "loss.options: expected a mapping of names to values, got a list"),
    ]
    for options, message in bad:
        with pytest.raises(ConfigError, match=f"^{message}"):
            LossConfig(kind="lfopts", options=options)
    # The built-in objectives take none: their settings are keys of their own.
    with pytest.raises(ConfigError) as e:
        load_config(RunConfig, overrides=["loss.options.alpha=1"])
    assert str(e.value) == (
        "--set loss.options.alpha=1: loss.options.alpha: the built-in loss 'contrastive' takes "
        "no options (its settings are loss's own keys, e.g. loss.margin); options are for a loss "
        "registered with lookfeel.losses.register_loss"
    )


def test_load_config_reads_a_shipped_config_by_name_from_any_folder(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
):
    """``load_config(RunConfig, "configs/tiny.yaml")``, the package's first example, failed
    outside a checkout (QA F8); it now means what ``--config`` means (`config_file`): a file
    that exists as it is, else the shipped config of that name."""
    from lookfeel.config.recipes import recipe_path

    monkeypatch.chdir(tmp_path)
    shipped = load_config(RunConfig, recipe_path("tiny.yaml"))
    for name in ("configs/tiny.yaml", "tiny.yaml", "tiny"):
        assert load_config(RunConfig, name, ["train.steps=3"]) == dataclasses.replace(
            shipped, train=dataclasses.replace(shipped.train, steps=3)
        )
    (tmp_path / "tiny.yaml").write_text(
        "train:\n  steps: 7\n", encoding="utf-8"
    )  # a file that exists wins
    assert load_config(RunConfig, "tiny.yaml").train.steps == 7
    with pytest.raises(ConfigError, match=r"^nosuch: cannot read config file .*, nor a shipped"):
        load_config(RunConfig, "nosuch")


def test_a_config_that_is_not_utf8_is_one_line_naming_it(tmp_path: Path):
    path = tmp_path / "latin1.yaml"
    path.write_bytes("# Gewebe für Mäntel\ntrain:\n  steps: 3\n".encode("latin-1"))
    with pytest.raises(ConfigError, match=r"latin1\.yaml: not UTF-8 text \(byte 10: invalid") as e:
        load_config(RunConfig, path)
    assert "\n" not in str(e.value)
    utf8 = tmp_path / "utf8.yaml"
    utf8.write_text("# Gewebe für Mäntel, 布料\ntrain:\n  steps: 3\n", encoding="utf-8")
    assert load_config(RunConfig, utf8).train.steps == 3


@pytest.mark.parametrize("value", [float("nan"), float("inf"), [1.0, float("-inf")]])
def test_a_loss_option_that_is_no_finite_number_is_refused(
    value: Any, monkeypatch: pytest.MonkeyPatch
):
    # NaN equals nothing: a run with it could never be resumed or compared with its config.
    monkeypatch.setitem(config_loss._LOSS_KINDS, "mine", None)  # as register_loss does
    with pytest.raises(ConfigError, match=r"^loss\.options\.eps.*is not a finite number"):
        LossConfig(kind="mine", options={"eps": value})
