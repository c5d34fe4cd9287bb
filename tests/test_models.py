"""Models: backbone layouts and shapes, the trunk/head split, freezing, pretrained loading,
press pooling, shared and independent branches, heads and gradients."""

from __future__ import annotations

import copy
import dataclasses
import warnings
from pathlib import Path

import pytest
import torch
from torch import nn

from lookfeel.config import ConfigError, ModelConfig, from_dict, load_config
from lookfeel.config.model import backbone_names, backbone_spec
from lookfeel.errors import LookfeelError
from lookfeel.modality import Modality
from lookfeel.models import (
    BACKBONES,
    AlexNet,
    Backbone,
    BranchEnsemble,
    Embedder,
    ModelInputError,
    PretrainedError,
    create_backbone,
    create_model,
    head_key,
    list_backbones,
    load_pretrained,
    register_backbone,
)

from ._registry import TinyViT, restored_registries

torch.set_num_threads(2)

ALEX_PX = 67  # AlexNet's smallest input is 63 px
SMALL_PX = 32

# torchvision.models.alexnet().state_dict(), written out so the test does not trust our code.
TORCHVISION_ALEXNET = {
    "features.0.weight": (64, 3, 11, 11),
    "features.0.bias": (64,),
    "features.3.weight": (192, 64, 5, 5),
    "features.3.bias": (192,),
    "features.6.weight": (384, 192, 3, 3),
    "features.6.bias": (384,),
    "features.8.weight": (256, 384, 3, 3),
    "features.8.bias": (256,),
    "features.10.weight": (256, 256, 3, 3),
    "features.10.bias": (256,),
    "classifier.1.weight": (4096, 9216),
    "classifier.1.bias": (4096,),
    "classifier.4.weight": (4096, 4096),
    "classifier.4.bias": (4096,),
    "classifier.6.weight": (1000, 4096),
    "classifier.6.bias": (1000,),
}

COMPACT = ModelConfig(backbone="compact", width=4)  # D = 32


@pytest.fixture(scope="module")
def alexnet() -> AlexNet:
    torch.manual_seed(0)
    model = create_backbone("alexnet")
    assert isinstance(model, AlexNet)
    return model


@pytest.fixture(scope="module")
def alexnet_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A file in torchvision's AlexNet layout, with weights unlike any fresh model's."""
    path = tmp_path_factory.mktemp("weights") / "alexnet-owt-7be5be79.pth"
    g = torch.Generator().manual_seed(1)
    state = {k: torch.randn(shape, generator=g) * 0.01 for k, shape in TORCHVISION_ALEXNET.items()}
    torch.save(state, path)
    return path


def _images(b: int, c: int, px: int, seed: int = 0) -> torch.Tensor:
    return torch.rand(b, c, px, px, generator=torch.Generator().manual_seed(seed))


def _grads_ok(model: nn.Module) -> None:
    """Every trainable parameter has a finite, non-zero gradient; every frozen one none."""
    for name, p in model.named_parameters():
        if p.requires_grad:
            assert p.grad is not None, f"{name}: no gradient"
            assert torch.isfinite(p.grad).all(), f"{name}: non-finite gradient"
            assert p.grad.abs().sum() > 0, f"{name}: zero gradient"
        else:
            assert p.grad is None, f"{name}: frozen but has a gradient"


# ------------------------------------------------------------------------------------------
# Backbones


def test_registry_matches_config() -> None:
    # The config declares the built-in backbones without torch; registering their classes
    # checks that the two agree, so a registered name is one the config knows and vice versa.
    assert list_backbones() == list(backbone_names()) == sorted(BACKBONES)
    for name, cls in BACKBONES.items():
        spec = backbone_spec(name)
        assert cls.name == name and spec.freeze_points == tuple(cls.freeze_points)
        assert spec.default_freeze == cls.default_freeze in cls.freeze_points
        assert spec.loads_pretrained == cls.loads_pretrained
    with pytest.raises(ValueError, match="unknown backbone 'vgg'.*alexnet, compact, resnet18"):
        create_backbone("vgg")


def test_a_backbone_registered_from_ones_own_module_is_one_the_config_takes() -> None:
    """QA: a backbone added to BACKBONES, as this page said, was refused by the config, which
    kept its own lists of names, freeze points and defaults. One call now registers both."""
    with pytest.raises(ConfigError, match="model.backbone: 'tinyvit' is not one of alexnet, com"):
        ModelConfig(backbone="tinyvit")
    with restored_registries():
        assert register_backbone("tinyvit")(TinyViT) is TinyViT
        register_backbone("tinyvit", TinyViT)  # a module imported twice: nothing changes
        assert (
            list_backbones()
            == list(backbone_names())
            == [
                "alexnet",
                "compact",
                "resnet18",
                "tinyvit",
            ]
        )
        cfg = load_config(ModelConfig, overrides=["backbone=tinyvit", "freeze=to_patches"])
        assert ModelConfig(backbone="tinyvit").resolved_freeze == "none"
        with pytest.raises(ConfigError, match=r"'to_fc6' is not a freeze point of backbone "):
            ModelConfig(backbone="tinyvit", freeze="to_fc6")
        with pytest.raises(ConfigError, match="'tinyvit' has no pretrained weights; only alex"):
            ModelConfig(backbone="tinyvit", pretrained="w.pth")
        with pytest.raises(ConfigError, match="'vgg' is not one of alexnet, compact, resnet18, t"):
            ModelConfig(backbone="vgg")
        with pytest.warns(UserWarning, match="tinyvit layers, which stay random"):
            model = create_model(cfg, [Modality.DEPTH, Modality.TOUCH])
        b = _batch()
        out = model({"depth": b["depth"], "touch": b["touch"]})
        assert out["touch"].shape == (2, 16) and model.branch("depth").backbone.freeze == (
            "to_patches"
        )
        # Another class under a taken name, or a class that is no backbone, is refused.
        with pytest.raises(ValueError, match="'compact' is already registered .*CompactCNN"):
            register_backbone("compact", TinyViT)
        with pytest.raises(TypeError, match="expected a Backbone subclass"):
            register_backbone("linear", nn.Linear)  # type: ignore[arg-type]

        # As this page used to say: BACKBONES[name] = cls registers it too.
        class Tiny2(TinyViT):
            pass

        BACKBONES["tiny2"] = Tiny2
        assert backbone_spec("tiny2").freeze_points == ("none", "to_patches", "all")
    assert "tinyvit" not in BACKBONES and "tinyvit" not in backbone_names()


class _Inline(Backbone):
    """A stage made inside the list only: never registered, so never trained nor saved."""

    freeze_points = {"none": 0}  # noqa: RUF012

    def _build(self, freeze: str | None, dropout: float, width: int | None) -> None:
        self.pool = nn.Sequential(nn.AdaptiveAvgPool2d(1), nn.Flatten(1))
        stages = [nn.Conv2d(self.stem_channels, 8, 3), self.pool]
        self._set_stages(stages, "none", embed_dim=8)


class _NoStages(Backbone):
    freeze_points = {"none": 0}  # noqa: RUF012

    def _build(self, freeze: str | None, dropout: float, width: int | None) -> None:
        self.conv = nn.Conv2d(self.stem_channels, 8, 3)


def test_a_stage_the_backbone_does_not_hold_is_refused_naming_it() -> None:
    """QA: layers passed to _set_stages inline trained silently, never optimised nor saved."""
    with pytest.raises(
        LookfeelError,
        match=r"^tests\.test_models\._Inline: stage 0 \(Conv2d\) holds weight, bias outside",
    ):
        _Inline()
    with pytest.raises(LookfeelError, match=r"_NoStages: _build did not call self\._set_stages"):
        _NoStages()
    # The shipped backbones keep torchvision's keys: nothing registered twice, nothing added.
    assert list(create_backbone("resnet18", width=4).state_dict())[:3] == [
        "conv1.weight",
        "bn1.weight",
        "bn1.bias",
    ]


class _Shaped(TinyViT):
    """TinyViT whose last stage is left out, or replaced: (N, T, D), 4-D, or another width."""

    name = "shaped"
    mode = "tokens"

    def _build(self, freeze: str | None, dropout: float, width: int | None) -> None:
        super()._build(freeze, dropout, width)
        if self.mode == "tokens":
            self._stages = self._stages[:2]  # (N, T, D)
        elif self.mode == "map":
            self._stages = [self.patch.proj]  # (N, D, h, w)
        else:
            self.narrow = nn.Linear(16, 12)
            self._set_stages([self.patch, self.enc, self.pool, self.narrow], "none", 16)


@pytest.mark.parametrize(
    ("mode", "got"),
    [("tokens", r"\(2, 4, 16\)"), ("map", r"\(2, 16, 2, 2\)"), ("width", r"\(2, 12\)")],
)
def test_a_backbone_that_gives_another_shape_than_it_declares_is_named(mode: str, got: str):
    """QA: (N, T, D), a 4-D map or another width than embed_dim failed deep in the loss with a
    raw traceback, or trained silently."""
    backbone = type("Shaped", (_Shaped,), {"mode": mode})()
    with pytest.raises(
        LookfeelError,
        match=rf"^shaped \(.*Shaped\): returned embeddings of shape {got} "
        r"for 2 inputs; expected \(2, 16\)",
    ):
        backbone(_images(2, 3, 16))


def test_alexnet_has_torchvision_layout_and_embeds_at_fc7(alexnet: AlexNet) -> None:
    state = alexnet.state_dict()
    assert {k: tuple(v.shape) for k, v in state.items()} == TORCHVISION_ALEXNET
    assert list(state) == list(TORCHVISION_ALEXNET)
    assert alexnet.freeze == "to_fc6" and alexnet.embed_dim == 4096
    alexnet.eval()
    x = _images(2, 3, ALEX_PX)
    e = alexnet(x)
    assert e.shape == (2, 4096)
    # E is ReLU(fc7), computed here by hand through torchvision's modules.
    h = alexnet.avgpool(alexnet.features((x - alexnet.mean) / alexnet.std)).flatten(1)
    fc7 = alexnet.classifier[:6](h)
    torch.testing.assert_close(e, fc7)
    with pytest.raises(ValueError, match="at least 63 px"):
        alexnet(_images(1, 3, 62))
    with pytest.raises(ValueError, match=r"\(N, 3, H, W\)"):
        alexnet(_images(1, 1, ALEX_PX))


def test_images_must_be_floats_in_0_1() -> None:
    """A uint8 image, 0-255 floats or NaN were embedded silently, into a wrong embedding (QA).
    Each is refused, saying what was given; a value a little outside [0, 1] (resampling
    overshoot) passes, through `forward` and `trunk` alike."""
    model = create_model(ModelConfig(backbone="compact", width=4), ["depth", "color"]).eval()
    x = _images(2, 3, SMALL_PX)
    depth = _images(2, 1, SMALL_PX)
    with torch.no_grad():
        model({"color": x * 1.2 - 0.1, "depth": depth})  # -0.1 to 1.1
        refused = [
            (
                {"color": (x * 255).to(torch.uint8)},
                r"float images in \[0, 1\], got torch\.uint8 \(",
            ),
            (
                {"color": x.double().mul(255)},
                r"got values from 0\.\d+ to 25\d\.\d+ \(0-255 pixels\?",
            ),
            ({"depth": depth * 1000 + 800}, r"got values from 80\d\.?\d* to 1[78]\d\d\.?\d* \("),
            ({"color": (x - 0.45) / 0.22}, r"from -2\.\d+ to 2\.\d+ \(standardised\? the model"),
            ({"color": x * 1.8}, r"got values from 0\.\d+ to 1\.7\d+$"),
            ({"depth": depth.masked_fill(depth > 0.9, float("nan"))}, "got NaN among them$"),
            ({"color": x.masked_fill(x > 0.9, float("inf"))}, r"got values from \S+ to inf$"),
        ]
        for inputs, says in refused:
            for run in (model, model.trunk):
                with pytest.raises(ModelInputError, match=r"^compact: inputs must be .*" + says):
                    run(inputs)
    with pytest.raises(ModelInputError, match=r"^slot 'color': expected a torch.Tensor, got "
                       r"ndarray \(torch.from_numpy"):  # fmt: skip
        model({"color": x.numpy()})
    with torch.no_grad():  # float64 (NumPy's default) embeds as the float32 it holds
        torch.testing.assert_close(model({"color": x.double()}), model({"color": x}))
    assert issubclass(ModelInputError, LookfeelError)  # the CLI says it in one line


def test_resnet18_has_torchvision_layout() -> None:
    state = create_backbone("resnet18").state_dict()
    assert len(state) == 122  # torchvision.models.resnet18().state_dict()
    assert tuple(state["conv1.weight"].shape) == (64, 3, 7, 7)
    assert tuple(state["layer2.0.downsample.0.weight"].shape) == (128, 64, 1, 1)
    assert tuple(state["layer4.1.bn2.running_var"].shape) == (512,)
    assert tuple(state["fc.weight"].shape) == (1000, 512)


@pytest.mark.parametrize(
    ("name", "channels", "stem", "px", "dim"),
    [
        ("compact", 3, "replicate", SMALL_PX, 32),
        ("compact", 1, "replicate", SMALL_PX, 32),
        ("compact", 1, "sum", SMALL_PX, 32),
        ("resnet18", 3, "replicate", SMALL_PX, 32),
        ("resnet18", 1, "sum", SMALL_PX, 32),
    ],
)
def test_backbone_shapes_and_trunk_head_split(
    name: str, channels: int, stem: str, px: int, dim: int
) -> None:
    model = create_backbone(name, in_channels=channels, stem=stem, width=4, freeze="none")
    model.eval()
    x = _images(2, channels, px)
    e = model(x)
    assert e.shape == (2, dim) == (2, model.embed_dim)
    torch.testing.assert_close(model.head(model.trunk(x)), e)
    conv1 = next(m for m in model.modules() if isinstance(m, nn.Conv2d))
    assert conv1.in_channels == (1 if stem == "sum" else 3)


@pytest.mark.parametrize(("name", "freeze"), [("compact", "to_block4"), ("resnet18", "to_layer2")])
def test_frozen_trunk_is_fixed_and_gets_no_gradient(name: str, freeze: str) -> None:
    torch.manual_seed(0)
    model = create_backbone(name, freeze=freeze, width=4)
    model.train()
    bn_stats = {k: v.clone() for k, v in model.state_dict().items() if "running" in k}
    x = _images(3, 3, SMALL_PX)
    f = model.trunk(x)
    torch.testing.assert_close(model.trunk(x), f)
    model(x).pow(2).sum().backward()
    _grads_ok(model)
    frozen = [n for n, p in model.named_parameters() if not p.requires_grad]
    trainable = [n for n, p in model.named_parameters() if p.requires_grad]
    assert frozen and trainable
    # The frozen trunk's BatchNorm statistics did not move in train mode; the head's did.
    after = model.state_dict()
    moved = {k for k, v in bn_stats.items() if not torch.equal(after[k], v)}
    for k in bn_stats:
        layer = k.rsplit(".", 2)[0]
        in_trunk = any(n.startswith(layer + ".") for n in frozen)
        assert (k not in moved) == in_trunk, k


def test_alexnet_paper_freeze_trains_only_fc7() -> None:
    torch.manual_seed(0)
    with pytest.warns(UserWarning, match="randomly initialised"):
        model = create_model(ModelConfig(cluster_head=True), [Modality.TOUCH])
    model.train()
    touch = torch.rand(2, 2, 3, ALEX_PX, ALEX_PX)
    trunk = model.trunk({"touch": touch})["touch"]
    assert trunk.shape == (2, 2, 4096)  # fc6 output per press
    torch.testing.assert_close(model.trunk({"touch": touch})["touch"], trunk)  # no dropout
    out = model({"touch": touch}, heads=True)
    (out["touch"].pow(2).sum() + out["touch/cluster"].pow(2).sum()).backward()
    _grads_ok(model)
    trainable = {n for n, p in model.named_parameters() if p.requires_grad}
    assert trainable == {
        "branches.touch.backbone.classifier.4.weight",
        "branches.touch.backbone.classifier.4.bias",
        "branches.touch.cluster_head.weight",
        "branches.touch.cluster_head.bias",
    }
    assert set(map(id, model.trainable_parameters())) == {
        id(p) for p in model.parameters() if p.requires_grad
    }


# ------------------------------------------------------------------------------------------
# Pretrained weights


def test_load_pretrained_alexnet_from_torchvision_file(alexnet_file: Path) -> None:
    state = torch.load(alexnet_file, weights_only=True, mmap=True)
    rgb = create_backbone("alexnet")
    load_pretrained(rgb, alexnet_file)
    for k, v in rgb.state_dict().items():
        assert torch.equal(v, state[k]), k
    grey = create_backbone("alexnet", in_channels=1, stem="sum")
    load_pretrained(grey, str(alexnet_file))
    torch.testing.assert_close(
        grey.features[0].weight, state["features.0.weight"].sum(dim=1, keepdim=True)
    )
    assert torch.equal(grey.classifier[4].weight, state["classifier.4.weight"])
    # The summed stem approximates the RGB network on a grey image (it normalises with the
    # mean of the RGB statistics).
    rgb.eval()
    grey.eval()
    x = _images(2, 1, ALEX_PX)
    cos = nn.functional.cosine_similarity(grey(x), rgb(x.expand(-1, 3, -1, -1))).min()
    assert cos > 0.99


def test_stacked_touch_frames_inflate_the_pretrained_first_layer(alexnet_file: Path) -> None:
    state = torch.load(alexnet_file, weights_only=True, mmap=True)
    rgb = create_backbone("alexnet").eval()
    load_pretrained(rgb, alexnet_file)
    stacked = create_backbone("alexnet", in_channels=6).eval()
    load_pretrained(stacked, alexnet_file)
    torch.testing.assert_close(
        stacked.features[0].weight, state["features.0.weight"].repeat(1, 2, 1, 1) / 2
    )
    # Two copies of one image give what the image gives the pretrained network.
    x = _images(2, 3, ALEX_PX)
    torch.testing.assert_close(stacked(torch.cat([x, x], dim=1)), rgb(x), rtol=1e-4, atol=1e-5)
    with pytest.raises(ValueError, match="in_channels must be 1 or a multiple of 3, got 4"):
        create_backbone("compact", in_channels=4)


def test_a_model_reading_stacked_touch_frames_takes_their_channels() -> None:
    model = create_model(
        ModelConfig(backbone="compact", width=4), [Modality.DEPTH, Modality.TOUCH], touch_channels=6
    ).eval()
    assert model.branch("touch").in_channels == 6 and model.branch("depth").in_channels == 1
    out = model({"touch": _images(2, 6, SMALL_PX).unsqueeze(1)})
    assert out["touch"].shape == (2, model.embed_dim)
    with pytest.raises(ValueError, match=r"touch input must be \(B, P, 6, H, W\)"):
        model({"touch": _images(2, 3, SMALL_PX).unsqueeze(1)})


def test_replicated_depth_channel_is_the_rgb_network_on_a_grey_image() -> None:
    rgb = create_backbone("compact", width=4).eval()
    depth = create_backbone("compact", in_channels=1, stem="replicate", width=4).eval()
    depth.load_state_dict(rgb.state_dict())
    x = _images(2, 1, SMALL_PX)
    torch.testing.assert_close(depth(x), rgb(x.expand(-1, 3, -1, -1)))


def test_create_model_loads_weights_once_into_every_branch(alexnet_file: Path) -> None:
    cfg = ModelConfig(pretrained=str(alexnet_file), depth_stem="sum")
    model = create_model(cfg, [Modality.DEPTH, Modality.TOUCH])
    state = torch.load(alexnet_file, weights_only=True)
    depth, touch = model.branch("depth").backbone, model.branch("touch").backbone
    torch.testing.assert_close(
        depth.state_dict()["features.0.weight"], state["features.0.weight"].sum(1, keepdim=True)
    )
    assert torch.equal(touch.state_dict()["classifier.1.weight"], state["classifier.1.weight"])
    # A checkpoint rebuild needs no weights file.
    missing = dataclasses.replace(cfg, pretrained="/nonexistent/alexnet.pth")
    rebuilt = create_model(missing, [Modality.DEPTH], load_weights=False)
    rebuilt.load_state_dict({k: v for k, v in model.state_dict().items() if ".depth." in k})
    with pytest.raises(PretrainedError, match="nonexistent/alexnet.pth: pretrained weights file"):
        create_model(missing, [Modality.DEPTH])


def test_load_pretrained_rejects_wrong_files(alexnet: AlexNet, tmp_path: Path) -> None:
    tiny = {k: torch.zeros(1) for k in TORCHVISION_ALEXNET}
    cases: list[tuple[str, object, str]] = [
        (
            "text.pth",
            None,
            r"text.pth: not a readable PyTorch weights file \(not a file "
            r"torch.save or NumPy wrote: it begins as neither a zip archive nor a pickle\)",
        ),
        ("list.pth", [1, 2, 3], r"list.pth: not a state dict .* holds a list"),
        ("values.pth", {"features.0.weight": 3}, r"values.pth: not a state dict; .*features.0"),
        (
            "missing.pth",
            {k: v for k, v in tiny.items() if k != "features.3.bias"},
            r"missing.pth: missing keys for alexnet: features.3.bias$",
        ),
        (
            "extra.pth",
            {**tiny, "fc.weight": torch.zeros(1)},
            r"extra.pth: unexpected keys for alexnet: fc.weight",
        ),
        (
            "shape.pth",
            tiny,
            r"shape.pth: shapes do not match alexnet: features.0.weight \(file \(1,\), "
            # 14, not 16: the unused ImageNet classifier (classifier.6) may have any shape
            r"model \(64, 3, 11, 11\)\), .* \(and 11 more\)",
        ),
    ]
    for name, content, message in cases:
        path = tmp_path / name
        if content is None:
            path.write_text("not weights", encoding="utf-8")
        else:
            torch.save(content, path)
        with pytest.raises(PretrainedError, match=message):
            load_pretrained(alexnet, path)
    with pytest.raises(PretrainedError, match="absent.pth: pretrained weights file not found"):
        load_pretrained(alexnet, tmp_path / "absent.pth")
    with pytest.raises(TypeError, match="Backbone"):
        load_pretrained(nn.Linear(2, 2), tmp_path / "shape.pth")


def test_weights_files_as_other_code_saves_them_load(tmp_path: Path) -> None:
    """QA: a ResNet-18 file with a 10-class or no ``fc`` (self-supervised checkpoints are
    headless), one saved from DDP (``module.`` keys) or wrapped in ``{"state_dict": ...}`` was
    refused, though ``fc`` is never used and what to do was plain."""
    torch.manual_seed(3)
    source = create_backbone("resnet18", width=4)
    sd = source.state_dict()
    files: dict[str, object] = {
        "fc10.pth": {**sd, "fc.weight": torch.randn(10, 32), "fc.bias": torch.zeros(10)},
        "headless.pth": {k: v for k, v in sd.items() if not k.startswith("fc.")},
        "ddp.pth": {f"module.{k}": v for k, v in sd.items()},
        "wrapped.pth": {"state_dict": sd, "epoch": 3},
        "model.pth": {"model": {f"module.{k}": v for k, v in sd.items()}, "optimizer": {}},
    }
    for name, content in files.items():
        torch.save(content, tmp_path / name)
        model = create_backbone("resnet18", width=4)
        load_pretrained(model, tmp_path / name)
        got = model.state_dict()
        assert all(torch.equal(got[k], v) for k, v in sd.items() if not k.startswith("fc.")), name
    # What is still refused: a used layer of another shape, an ambiguous wrapper, some keys
    # prefixed (said how to fix), and a lookfeel checkpoint (sent to model.init_from).
    refused = {
        "conv.pth": ({**sd, "conv1.weight": torch.zeros(4, 3, 3, 3)}, r"shapes do not .*conv1"),
        "two.pth": ({"model": sd, "ema": sd}, r"holds several state dicts \(model, ema\)"),
        "some.pth": (
            {
                **{f"module.{k}": v for k, v in sd.items() if "layer4" in k},
                **{k: v for k, v in sd.items() if "layer4" not in k},
            },
            r"missing keys .*layer4.* \(30 of 122 keys start with 'module\.', as a wrapped",
        ),
        "run.pth": (
            {"version": 1, "config": {}, "model": sd},
            "use model.init_from|with model.init",
        ),
    }
    for name, (content, message) in refused.items():
        torch.save(content, tmp_path / name)
        with pytest.raises(PretrainedError, match=message):
            load_pretrained(create_backbone("resnet18", width=4), tmp_path / name)


# ------------------------------------------------------------------------------------------
# The joint model


def _batch(p: int = 1, b: int = 2) -> dict[str, torch.Tensor]:
    g = torch.Generator().manual_seed(5)
    return {
        "depth": torch.rand(b, 1, SMALL_PX, SMALL_PX, generator=g),
        "color": torch.rand(b, 3, SMALL_PX, SMALL_PX, generator=g),
        "touch": torch.rand(b, p, 3, SMALL_PX, SMALL_PX, generator=g),
    }


def test_cross_modal_net_has_independent_branches_and_heads() -> None:
    cfg = dataclasses.replace(COMPACT, cluster_head=True, num_properties=4, embed_dim=16)
    model = create_model(cfg, [Modality.DEPTH, Modality.COLOR, Modality.TOUCH])
    assert model.modalities == (Modality.DEPTH, Modality.COLOR, Modality.TOUCH)
    assert list(model.branches) == ["depth", "color", "touch"] and model.embed_dim == 16
    ids = [{id(p) for p in b.parameters()} for b in model.branches.values()]
    assert not (ids[0] & ids[1]) and not (ids[1] & ids[2]) and not (ids[0] & ids[2])
    out = model(_batch(p=2))
    assert {k: tuple(v.shape) for k, v in out.items()} == {
        "depth": (2, 16),
        "color": (2, 16),
        "touch": (2, 16),
    }
    full = model(_batch(p=2), heads=True)
    assert tuple(full[head_key("color", "cluster")].shape) == (2, 8)
    assert tuple(full[head_key("touch", "property")].shape) == (2, 4)
    assert len(full) == 9
    sum(v.pow(2).sum() for v in full.values()).backward()
    _grads_ok(model)


def test_siamese_net_shares_one_branch() -> None:
    model = create_model(COMPACT, [Modality.DEPTH, Modality.DEPTH])
    assert list(model.branches) == ["depth"]
    assert model.branch("depth") is model.branch("depth.1")
    model.eval()
    x = _batch()["depth"]
    out = model({"depth": x, "depth.1": x.flip(0)})
    assert list(out) == ["depth", "depth.1"]
    torch.testing.assert_close(out["depth.1"], out["depth"].flip(0))
    # Slots of unequal batch size take separate passes through the same branch.
    odd = model({"depth": x, "depth.1": x[:1]})
    torch.testing.assert_close(odd["depth.1"], out["depth"][:1])
    model.train()
    model({"depth": x, "depth.1": x.flip(0)})["depth.1"].sum().backward()
    _grads_ok(model)


@pytest.mark.parametrize("pool", ["max", "mean"])
def test_multi_input_net_pools_any_number_of_presses(pool: str) -> None:
    model = create_model(dataclasses.replace(COMPACT, press_pool=pool), [Modality.TOUCH])
    model.eval()
    presses = _batch(p=3)["touch"]  # (B, P, 3, H, W)
    single = [model({"touch": presses[:, i : i + 1]})["touch"] for i in range(3)]
    backbone = model.branch("touch").backbone
    torch.testing.assert_close(single[0], backbone(presses[:, 0]))  # P = 1 is the plain net
    many = model({"touch": presses})["touch"]
    stacked = torch.stack(single, dim=1)  # (B, P, D)
    want = stacked.amax(dim=1) if pool == "max" else stacked.mean(dim=1)
    torch.testing.assert_close(many, want)
    assert not torch.allclose(many, single[0])
    shuffled = model({"touch": presses[:, [2, 0, 1]]})["touch"]
    torch.testing.assert_close(shuffled, many)


@pytest.mark.parametrize("pool", ["max", "mean"])
def test_views_of_a_press_are_averaged_before_the_presses_are_pooled(pool: str) -> None:
    cfg = dataclasses.replace(COMPACT, press_pool=pool, embed_dim=8)
    model = create_model(cfg, [Modality.TOUCH])
    model.eval()
    g = torch.Generator().manual_seed(7)
    x = torch.rand(2, 3, 4, 3, SMALL_PX, SMALL_PX, generator=g)  # (B, P, V, 3, H, W)
    branch = model.branch("touch")
    features = branch.backbone(x.flatten(0, 2)).unflatten(0, (2, 3, 4))  # (B, P, V, D0)
    press = features.mean(dim=2)
    pooled = press.amax(dim=1) if pool == "max" else press.mean(dim=1)
    torch.testing.assert_close(model({"touch": x})["touch"], branch.project(pooled))
    # One press: the (linear) projection makes it the mean of its views' embeddings.
    one = model({"touch": x[:, :1]})["touch"]
    each = torch.stack([model({"touch": x[:, :1, v]})["touch"] for v in range(4)])
    torch.testing.assert_close(one, each.mean(dim=0))
    # V identical views are that one image.
    same = x[:, :, :1].expand(-1, -1, 4, -1, -1, -1)
    torch.testing.assert_close(
        model({"touch": same})["touch"], model({"touch": x[:, :, 0]})["touch"]
    )
    assert not torch.allclose(one, each[0])


def test_forward_from_cached_trunk_equals_forward() -> None:
    cfg = dataclasses.replace(COMPACT, freeze="to_block4", embed_dim=8, normalize=True)
    with pytest.warns(UserWarning, match="freezes randomly initialised compact"):
        model = create_model(cfg, [Modality.DEPTH, Modality.TOUCH])
    model.train()  # frozen trunks stay deterministic, so this also holds in training
    batch = {"depth": _batch()["depth"], "touch": _batch(p=2)["touch"]}
    cached = model.trunk(batch)
    assert cached["depth"].shape == (2, 32) and cached["touch"].shape == (2, 2, 32)
    model.eval()
    direct = model(batch)
    torch.testing.assert_close(model(cached, from_trunk=True), direct)
    norms = direct["touch"].norm(dim=-1)
    torch.testing.assert_close(norms, torch.ones_like(norms))


def test_a_random_frozen_trunk_is_told_what_to_set_by_what_its_backbone_loads() -> None:
    """QA: compact with model.freeze=to_block4 was told to set model.pretrained, which compact
    refuses; only a backbone that loads weights is sent there."""
    compact = dataclasses.replace(COMPACT, freeze="to_block4")
    with pytest.warns(UserWarning) as said:
        create_model(compact, [Modality.DEPTH])
    assert str(said[0].message) == (
        "model.freeze=to_block4 freezes randomly initialised compact layers, which stay random "
        "(compact loads no pretrained weights): set model.freeze=none to train them"
    )
    # The warning names the Python setting beside the CLI flag (QA: it said only the flag).
    says = r"freezes randomly initialised resnet18 .* set model\.pretrained \(ModelConfig\("
    resnet = ModelConfig(backbone="resnet18", width=4, freeze="to_layer2")
    with pytest.warns(UserWarning, match=says + r"pretrained=PATH\), or `lookfeel train --pre"):
        create_model(resnet, [Modality.DEPTH])


def test_embedder_rejects_bad_inputs() -> None:
    model = create_model(COMPACT, [Modality.DEPTH, Modality.TOUCH])
    b = _batch()
    with pytest.raises(ValueError, match=r"slot 'touch'.*press axis"):
        model({"touch": b["color"]})
    with pytest.raises(ValueError, match=r"slot 'depth': expected \(B, 1, H, W\)"):
        model({"depth": b["color"]})
    views = b["touch"].unsqueeze(2).expand(-1, -1, 2, -1, -1, -1)  # (B, P, V, 3, H, W)
    assert model({"touch": views})["touch"].shape == (2, model.embed_dim)
    with pytest.raises(ValueError, match=r"slot 'touch'.*press axis"):
        model.trunk({"touch": views})  # the trunk cache holds one image per press
    with pytest.raises(KeyError, match="no color branch"):
        model({"color": b["color"]})
    with pytest.raises(KeyError, match="'smell' names no modality"):
        model({"smell": b["color"]})
    with pytest.raises(ValueError, match="at least one modality"):
        create_model(COMPACT, [])
    with pytest.raises(ValueError, match="one embedding size"):
        Embedder({Modality.DEPTH: model.branch("depth"), Modality.TOUCH: _other_dim_branch()})


def _other_dim_branch() -> nn.Module:
    other = create_model(dataclasses.replace(COMPACT, embed_dim=3), [Modality.TOUCH])
    return other.branch("touch")


def test_model_state_dict_round_trips() -> None:
    torch.manual_seed(0)
    model = create_model(dataclasses.replace(COMPACT, cluster_head=True), [Modality.TOUCH])
    torch.manual_seed(1)
    again = create_model(model.config or COMPACT, model.modalities, load_weights=False)
    again.load_state_dict(model.state_dict())
    model.eval()
    again.eval()
    x = {"touch": _batch(p=2)["touch"]}
    torch.testing.assert_close(again(x, heads=True), model(x, heads=True))
    assert isinstance(again.branch("touch").backbone, Backbone)
    # A deep copy (EMA, a checkpoint snapshot) runs on its own weights, not the original's.
    twin = copy.deepcopy(model)
    with torch.no_grad():
        for p in twin.parameters():
            p.add_(1.0)
    assert not torch.allclose(twin(x)["touch"], model(x)["touch"])


def test_ensemble_embeds_as_its_members_side_by_side_and_averages_their_heads() -> None:
    cfg = dataclasses.replace(COMPACT, embed_dim=8, members=3)
    cfg = dataclasses.replace(cfg, class_heads=("h",), classes={"h": ("0", "1", "2")})
    cfg = dataclasses.replace(cfg, num_properties=2)
    torch.manual_seed(0)
    model = create_model(cfg, [Modality.DEPTH, Modality.TOUCH]).eval()
    branch = model.branch("touch")
    assert isinstance(branch, BranchEnsemble) and model.embed_dim == 24
    members = branch.member_branches()
    first = dict(members[0].named_parameters())
    assert any(not torch.equal(first[k], v) for k, v in members[1].named_parameters())
    x = _batch(p=2, b=3)["touch"]
    own = [m(x) for m in members]  # each member's own embedding (not normalised here)
    out = model({"touch": x}, heads=True)
    e = out["touch"]
    torch.testing.assert_close(e, torch.cat(own, dim=-1) / 3**0.5)
    # Squared distances (and dot products) of ensemble embeddings are the members' averaged.
    d2 = ((e[0] - e[1]) ** 2).sum()
    torch.testing.assert_close(d2, sum(((m[0] - m[1]) ** 2).sum() for m in own) / 3)
    for name in ("property", "classes"):  # heads: the members' own, on their own parts, averaged
        mean = torch.stack([m.heads(o)[name] for m, o in zip(members, own, strict=True)]).mean(0)
        torch.testing.assert_close(out[head_key("touch", name)], mean)
        torch.testing.assert_close(branch.heads(e)[name], mean)  # from a stored embedding
    again = create_model(cfg, model.modalities, load_weights=False).eval()
    again.load_state_dict(model.state_dict())
    torch.testing.assert_close(again({"touch": x})["touch"], e)
    with pytest.raises(NotImplementedError, match="no one trunk"):
        model.trunk({"touch": x})
    with pytest.raises(ConfigError, match="model.members: must be >= 1"):
        dataclasses.replace(COMPACT, members=0)
    plain = create_model(COMPACT, [Modality.DEPTH]).branch("depth")
    with pytest.raises(ValueError, match="share one modality, embedding size and normalisation"):
        BranchEnsemble([plain, branch.member_branches()[0]])


# ------------------------------------------------------------------------------------------
# Config


def test_model_config_defaults_and_validation() -> None:
    cfg = ModelConfig()
    assert (cfg.backbone, cfg.resolved_freeze, cfg.embed_dim, cfg.num_clusters) == (
        "alexnet",
        "to_fc6",
        None,
        8,
    )
    assert ModelConfig(backbone="compact").resolved_freeze == "none"
    loaded = load_config(ModelConfig, overrides=["backbone=resnet18", "freeze=to_layer3"])
    assert loaded.resolved_freeze == "to_layer3"
    for bad, key in [
        ({"backbone": "vgg"}, "model.backbone"),
        ({"freeze": "to_layer3"}, r"model.freeze: 'to_layer3' is not a freeze point of backbone"),
        ({"backbone": "compact", "pretrained": "x.pth"}, "model.pretrained"),
        ({"depth_stem": "mean"}, "model.depth_stem"),
        ({"press_pool": "sum"}, "model.press_pool"),
        ({"dropout": 1.0}, "model.dropout"),
        (
            {"branch_dropout": {"sound": 0.1}},
            "branch_dropout.sound: 'sound' is not one of depth, color, touch",
        ),
        ({"branch_dropout": {"touch": 1.0}}, r"model.branch_dropout.touch: must be in \[0, 1\)"),
        ({"width": 8}, "model.width: alexnet"),
        ({"backbone": "resnet18", "width": 32, "pretrained": "r.pth"}, "model.width"),
        ({"embed_dim": 0}, "model.embed_dim"),
        ({"num_clusters": 1}, "model.num_clusters"),
        ({"num_properties": -1}, "model.num_properties"),
        ({"embed": 3}, "unknown key embed"),
    ]:
        with pytest.raises(ConfigError, match=key):
            from_dict(ModelConfig, bad)


def test_branch_dropout_overrides_dropout_for_the_named_branches_only() -> None:
    from lookfeel.models.dropout import FastDropout

    cfg = load_config(
        ModelConfig,
        overrides=["backbone=compact", "width=4", "dropout=0.1", "branch_dropout.touch=0.3"],
    )
    model = create_model(cfg, list(Modality))
    rates = {
        m: sorted({d.p for d in model.branch(m).modules() if isinstance(d, FastDropout)})
        for m in ("depth", "color", "touch")
    }
    assert rates == {"depth": [0.1], "color": [0.1], "touch": [0.3]}


def test_fast_dropout_matches_dropout_statistics():
    from lookfeel.models.dropout import FastDropout

    torch.manual_seed(0)
    x = torch.ones(400, 500)
    drop = FastDropout(0.5)
    y = drop(x)
    assert set(torch.unique(y).tolist()) == {0.0, 2.0}
    assert abs((y == 0).float().mean().item() - 0.5) < 0.01
    assert abs(y.mean().item() - 1.0) < 0.02  # expectation kept by the 1/(1-p) scaling
    drop.eval()
    assert drop(x) is x
    odd = FastDropout(0.3)  # 256 * 0.3 is not an integer: exact fallback
    assert abs((odd(x) == 0).float().mean().item() - 0.3) < 0.01
    torch.manual_seed(1)
    a = FastDropout(0.5)(x)
    torch.manual_seed(1)
    assert torch.equal(a, FastDropout(0.5)(x))  # draws from the global generator: seeded


def test_eval_mode_restores_training_flag_and_press_axis_round_trips() -> None:
    from lookfeel.models import add_press_axis, drop_press_axis, eval_mode, to_channels_last

    model = torch.nn.Sequential(torch.nn.Dropout(0.5))
    with eval_mode(model):
        assert not model.training
    assert model.training
    model.eval()
    with pytest.raises(RuntimeError), eval_mode(model):
        raise RuntimeError
    assert not model.training  # restored as it was, also after an error
    x = torch.rand(4, 3, 8, 8)
    assert add_press_axis(x, Modality.TOUCH).shape == (4, 1, 3, 8, 8)
    assert add_press_axis(x, Modality.COLOR) is x
    assert torch.equal(drop_press_axis(add_press_axis(x, Modality.TOUCH), Modality.TOUCH), x)
    five = to_channels_last(torch.rand(2, 3, 3, 8, 8))
    assert five.flatten(0, 1).is_contiguous(memory_format=torch.channels_last)
    assert torch.equal(to_channels_last(x), x)


def test_precision_is_a_checked_choice_that_only_cuda_reads() -> None:
    from lookfeel.models import autocast

    assert ModelConfig().precision == "auto"
    with pytest.raises(ConfigError, match="model.precision"):
        from_dict(ModelConfig, {"precision": "fp16"}, "model")
    cpu = torch.device("cpu")
    for precision in ("auto", "fp32"):
        with autocast(cpu, precision=precision):  # type: ignore[arg-type]
            assert not torch.is_autocast_enabled("cpu")
            assert (torch.ones(2, 2) @ torch.ones(2, 2)).dtype == torch.float32
    # fp32 on CUDA turns TF32 off for the block and restores the user's settings after it
    # (the flags exist without a GPU, so this runs anywhere).
    before = torch.backends.cuda.matmul.allow_tf32, torch.backends.cudnn.allow_tf32
    try:
        torch.backends.cuda.matmul.allow_tf32 = torch.backends.cudnn.allow_tf32 = True
        with autocast(torch.device("cuda"), precision="fp32"):
            assert not torch.backends.cuda.matmul.allow_tf32
            assert not torch.backends.cudnn.allow_tf32
            assert not torch.is_autocast_enabled("cuda")
        assert torch.backends.cuda.matmul.allow_tf32 and torch.backends.cudnn.allow_tf32
    finally:
        torch.backends.cuda.matmul.allow_tf32, torch.backends.cudnn.allow_tf32 = before
    with warnings.catch_warnings():  # "CUDA is not available": only its type is asked here
        warnings.simplefilter("ignore", UserWarning)
        assert isinstance(autocast(torch.device("cuda")), torch.autocast)  # auto: bf16
    cfg = ModelConfig(backbone="compact", width=4, embed_dim=8, precision="fp32")
    assert create_model(cfg, ["touch"]).precision == "fp32"
    branch = create_model(cfg, ["touch"]).branch("touch")
    assert Embedder({Modality.TOUCH: branch}).precision == "auto"  # no config: the default


def test_pooled_modality_is_the_one_declaration_of_a_press_axis(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """`Modality.pooled` (QA F2) is what the model's branch, `_check` and the press-axis helpers
    read: declaring colour pooled gives its branch a press axis too, pooled like touch's."""
    from lookfeel.models import add_press_axis, drop_press_axis

    assert [m for m in Modality if m.pooled] == [Modality.TOUCH]
    monkeypatch.setattr(
        Modality, "pooled", property(lambda m: m in (Modality.TOUCH, Modality.COLOR))
    )
    x = _images(2, 3, SMALL_PX)
    assert add_press_axis(x, Modality.COLOR).shape == (2, 1, 3, SMALL_PX, SMALL_PX)
    assert torch.equal(drop_press_axis(add_press_axis(x, Modality.COLOR), Modality.COLOR), x)
    model = create_model(ModelConfig(backbone="compact", width=4), ["color"]).eval()
    assert model.branch("color").pressed
    presses = torch.stack([x, x.flip(-1), x.flip(-2)], dim=1)  # (B, P=3, 3, S, S)
    with torch.no_grad():
        e = model({"color": presses})["color"]
        again = model({"color": presses.flip(1)})["color"]
    assert e.shape == (2, model.embed_dim)
    assert torch.allclose(e, again, atol=1e-6)  # pooled: the presses' order does not matter
    with pytest.raises(ModelInputError, match=r"color input must be \(B, P, 3, H, W\)"):
        model({"color": x})
