"""The interface every backbone shares: a frozen trunk, a trainable head, one embedding size.

A backbone is an ordered list of stages. Its freeze point cuts that list in two: the `trunk`
(input normalisation plus the frozen stages) and the `head` (the stages that train), with
``forward(x) == head(trunk(x))``. The trunk has no trainable parameter and always runs in eval
mode, so it is a fixed function of the image: a trainer may compute ``trunk(x)`` once per image,
cache it, and train on ``head(cached)`` (ARCHITECTURE.md, "What makes it fast").
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import ClassVar

import torch
from torch import Tensor, nn

from lookfeel.errors import LookfeelError

__all__ = [
    "IMAGENET_MEAN",
    "IMAGENET_STD",
    "INPUT_RANGE",
    "Backbone",
    "BackboneError",
    "ModelInputError",
]

IMAGENET_MEAN = (0.485, 0.456, 0.406)
IMAGENET_STD = (0.229, 0.224, 0.225)

INPUT_RANGE = (-0.5, 1.5)
"""The values `Backbone.prepare` accepts on the CPU. Images are in [0, 1]; the margin lets
through what resampling overshoots, and refuses what is plainly another scale (0-255 pixels,
depth in millimetres, standardised inputs), NaN and infinity."""


class ModelInputError(LookfeelError):
    """An image batch a network cannot embed: wrong shape, not floating point, or values
    plainly outside [0, 1]; the message says what was given."""


class BackboneError(LookfeelError):
    """A backbone class that breaks the `Backbone` contract (a stage that is not one of its
    submodules, no `Backbone._set_stages` call, an embedding of another shape than
    (N, embed_dim)); the message names the class and what is wrong."""


class Backbone(nn.Module):
    """Base class: input checks, ImageNet normalisation, the trunk/head split and freezing.

    Every backbone is built as ``Cls(in_channels, stem, freeze, dropout, width)``. Subclasses build
    their layers in `_build` (keeping torchvision's attribute names where one exists, so
    state-dict keys match its files), which ends by calling `_set_stages`.

    A backbone of one's own is registered with `lookfeel.models.register_backbone`, which
    reads the class attributes below (those with a default may be left out); a config then
    selects it with ``model.backbone``.

    Attributes:
        name: registry name (``alexnet``, ``compact``, ``resnet18``).
        freeze_points: freeze point name -> number of stages in the trunk (``none``: 0).
        default_freeze: the freeze point used when ``model.freeze`` is unset.
        loads_pretrained: whether a local weights file in its layout can be loaded
            (``model.pretrained``, `lookfeel.models.load_pretrained`).
        takes_width: whether ``model.width`` means something to it.
        pretrained_width: the ``model.width`` pretrained weights need (``None``: any).
        embed_dim: size D of the embedding `forward` returns.
        in_channels: channels of the input images (1 for depth, 3 for colour and touch, 3 per
            frame for touch frames stacked).
        min_size: smallest input side in pixels the layers accept.
    """

    name: ClassVar[str]
    freeze_points: ClassVar[dict[str, int]]
    default_freeze: ClassVar[str] = "none"
    loads_pretrained: ClassVar[bool] = False
    takes_width: ClassVar[bool] = True
    pretrained_width: ClassVar[int | None] = None
    min_size: ClassVar[int] = 1

    def __init__(
        self,
        in_channels: int = 3,
        stem: str = "replicate",
        freeze: str | None = None,
        dropout: float = 0.5,
        width: int | None = None,
    ) -> None:
        """Set up the input path, then build the layers (`_build`).

        Args:
            in_channels: 1 (depth), 3 (colour, touch) or 3 per frame of a press read
                together (``data.touch_frames``).
            stem: for one-channel input, ``replicate`` copies it into three channels before a
                three-channel first layer; ``sum`` makes the first layer one-channel.
            freeze: a freeze point; ``None`` is the subclass's default.
            dropout: dropout probability where the subclass has dropout.
            width: the subclass's width parameter; ``None`` is its default.
        """
        super().__init__()
        if in_channels < 1 or (in_channels != 1 and in_channels % 3):
            raise ValueError(f"in_channels must be 1 or a multiple of 3, got {in_channels}")
        if stem not in ("replicate", "sum"):
            raise ValueError(f"stem must be 'replicate' or 'sum', got {stem!r}")
        self.in_channels = in_channels
        self.stem = stem
        self._replicate = in_channels == 1 and stem == "replicate"
        self.stem_channels = 3 if self._replicate else in_channels
        """Input channels of the first layer (1 only for a ``sum`` stem)."""
        mean: tuple[float, ...] = IMAGENET_MEAN
        std: tuple[float, ...] = IMAGENET_STD
        if self.stem_channels == 1:  # one grey channel: the mean of the RGB statistics
            mean, std = (sum(IMAGENET_MEAN) / 3,), (sum(IMAGENET_STD) / 3,)
        else:  # RGB, or several RGB frames stacked: the RGB statistics for each
            mean, std = mean * (self.stem_channels // 3), std * (self.stem_channels // 3)
        # Not persistent: the state dict keeps exactly torchvision's keys.
        self.mean: Tensor
        self.std: Tensor
        self.register_buffer("mean", torch.tensor(mean).view(1, -1, 1, 1), persistent=False)
        self.register_buffer("std", torch.tensor(std).view(1, -1, 1, 1), persistent=False)
        self.embed_dim = 0
        self.freeze = "none"
        self._stages: list[nn.Module] = []
        self._unused: list[nn.Module] = []
        self._cut = 0
        self._build(freeze, dropout, width)
        if not self._stages:
            raise BackboneError(
                f"{self._who()}: _build did not call self._set_stages(stages, freeze, "
                "embed_dim), so the backbone has no layers"
            )

    def _who(self) -> str:
        """How messages name this backbone: ``tinyvit (mymodule.TinyViT)``."""
        cls = type(self)
        name = getattr(cls, "name", None)
        where = f"{cls.__module__}.{cls.__qualname__}"
        return f"{name} ({where})" if name else where

    def _build(self, freeze: str | None, dropout: float, width: int | None) -> None:
        """Build the layers and call `_set_stages` (each subclass says what its arguments mean)."""
        raise NotImplementedError

    def _set_stages(
        self,
        stages: Sequence[nn.Module],
        freeze: str,
        embed_dim: int,
        unused: Sequence[nn.Module] = (),
    ) -> None:
        """Record the stages, cut them at ``freeze`` and freeze the trunk's parameters.

        Every stage's parameters and buffers must belong to the backbone: assign each layer
        as an attribute (``self.conv = nn.Conv2d(...)``, or a container such as
        ``nn.Sequential``) before listing it here. A layer created inside the list only would
        be neither optimised nor saved, so it is refused. A stage may be a new container of
        such layers (``nn.Sequential(self.conv1, self.bn1)``) or a layer without parameters
        (``nn.Flatten(1)``).

        Args:
            stages: the layers in order; their composition maps a normalised image to (N, D).
            freeze: a key of `freeze_points`.
            embed_dim: D.
            unused: layers kept only for state-dict compatibility (ImageNet classifiers);
                their parameters are frozen since no output depends on them, and a pretrained
                file may lack them or hold them in another shape (`apply_state_dict`).

        Raises:
            BackboneError: a stage that is not a module, or holds a parameter or buffer that
                is not registered in the backbone; no stages; an ``embed_dim`` below 1.
            ValueError: ``freeze`` is not one of `freeze_points`.
        """
        if freeze not in self.freeze_points:
            valid = ", ".join(self.freeze_points)
            raise ValueError(f"{self.name}: freeze {freeze!r} is not one of {valid}")
        # A plain list, not a ModuleList: the stages are already registered under their
        # torchvision names, and registering them twice would duplicate state-dict keys.
        self._stages = list(stages)
        self._check_stages(embed_dim)
        self._cut = self.freeze_points[freeze]
        self.freeze = freeze
        self.embed_dim = embed_dim
        for stage in self._stages[: self._cut]:
            stage.requires_grad_(False)
        self._unused = list(unused)
        for module in self._unused:
            module.requires_grad_(False)
        self.train(self.training)

    def _check_stages(self, embed_dim: int) -> None:
        """Refuse stages whose weights the backbone does not hold (see `_set_stages`)."""
        if not self._stages:
            raise BackboneError(f"{self._who()}: _set_stages got no stages")
        if not isinstance(embed_dim, int) or embed_dim < 1:
            raise BackboneError(f"{self._who()}: embed_dim must be an int >= 1, got {embed_dim!r}")
        own = {id(t) for t in (*self.parameters(), *self.buffers())}
        for i, stage in enumerate(self._stages):
            if not isinstance(stage, nn.Module):
                raise BackboneError(
                    f"{self._who()}: stage {i} is a {type(stage).__name__}, not an nn.Module"
                )
            stray = [
                n
                for n, t in (*stage.named_parameters(), *stage.named_buffers())
                if id(t) not in own
            ]
            if stray:
                raise BackboneError(
                    f"{self._who()}: stage {i} ({type(stage).__name__}) holds "
                    f"{', '.join(stray[:3])}{' ...' if len(stray) > 3 else ''} outside the "
                    "backbone's registered layers, so it would be neither trained nor saved: "
                    "assign the layer as an attribute (self.name = ...) before _set_stages"
                )

    def unused_keys(self) -> set[str]:
        """State-dict keys of the layers no output depends on (``unused`` of `_set_stages`:
        e.g. ResNet-18's ImageNet classifier ``fc.weight``, ``fc.bias``)."""
        unused = {id(m) for m in self._unused}
        keys: set[str] = set()
        for prefix, module in self.named_modules():
            if id(module) in unused:
                keys.update(f"{prefix}.{k}" if prefix else k for k in module.state_dict())
        return keys

    def train(self, mode: bool = True) -> Backbone:
        """Set train or eval mode; the frozen trunk stays in eval mode either way."""
        super().train(mode)
        for stage in self._stages[: self._cut]:
            stage.eval()
        return self

    def prepare(self, x: Tensor) -> Tensor:
        """Check an image batch in [0, 1] and normalise it with the ImageNet statistics.

        The images are what `lookfeel.data.images.to_tensor` makes of a preprocessed image
        (``preprocess_depth``, ``preprocess_rgb``): floats in [0, 1] (float64 is taken as the
        weights' float32), never 0-255 pixels. A
        batch that is not floating point is refused; on the CPU, so is one with a value
        outside `INPUT_RANGE` or NaN (one min/max pass over the batch, well under 1% of a
        forward pass). On an accelerator the values are not read: that would wait for the
        device at every batch. Nor are they while tracing (ONNX export) or compiling.

        Args:
            x: (N, in_channels, H, W) in [0, 1].

        Returns:
            (N, stem_channels, H, W), normalised.

        Raises:
            ModelInputError: the shape, the dtype or (on the CPU) the values are wrong.
        """
        if x.dim() != 4 or x.shape[1] != self.in_channels:
            raise ModelInputError(
                f"{self.name}: expected images of shape (N, {self.in_channels}, H, W), "
                f"got {tuple(x.shape)}"
            )
        if min(x.shape[-2:]) < self.min_size:
            raise ModelInputError(
                f"{self.name}: inputs must be at least {self.min_size} px on each side, "
                f"got {tuple(x.shape[-2:])}"
            )
        if not x.is_floating_point():
            hint = " (0-255 pixels? use x.float() / 255)" if x.dtype == torch.uint8 else ""
            raise ModelInputError(
                f"{self.name}: inputs must be float images in [0, 1], got {x.dtype}{hint}; "
                "lookfeel.data.images.to_tensor makes them of preprocess_depth/preprocess_rgb"
            )
        if not _tracing() and x.device.type == "cpu" and x.numel():
            _check_range(self.name, x)
        if x.dtype == torch.float64:  # NumPy's default: the weights are float32
            x = x.to(self.mean.dtype)
        if self._replicate:
            x = x.expand(-1, 3, -1, -1)  # (N, 1, H, W) -> (N, 3, H, W)
        return (x - self.mean) / self.std

    def trunk(self, x: Tensor) -> Tensor:
        """The frozen part: a fixed function of the image (cacheable per image).

        Args:
            x: (N, in_channels, H, W) in [0, 1].

        Returns:
            (N, *F) features; F depends on the backbone and freeze point.
        """
        x = self.prepare(x)
        for stage in self._stages[: self._cut]:
            x = stage(x)
        return x

    def head(self, features: Tensor) -> Tensor:
        """The trainable part, from `trunk` features to the embedding.

        Args:
            features: (N, *F) from `trunk`.

        Returns:
            (N, D) embeddings.

        Raises:
            BackboneError: the stages gave another shape than (N, embed_dim) (a shape check
                only: nothing is read from the device; skipped while tracing or compiling).
        """
        n = features.shape[0]
        for stage in self._stages[self._cut :]:
            features = stage(features)
        if not _tracing() and (features.dim() != 2 or tuple(features.shape) != (n, self.embed_dim)):
            raise BackboneError(
                f"{self._who()}: returned embeddings of shape {tuple(features.shape)} for "
                f"{n} inputs; expected ({n}, {self.embed_dim}), (N, embed_dim) as declared in "
                "_set_stages (pool or flatten the last stage's output to (N, D))"
            )
        return features

    def forward(self, x: Tensor) -> Tensor:
        """Embed images: ``head(trunk(x))``.

        Args:
            x: (N, in_channels, H, W) in [0, 1].

        Returns:
            (N, D) embeddings.
        """
        return self.head(self.trunk(x))


def _tracing() -> bool:
    """Whether the forward pass is being traced or compiled (a value read would be baked in)."""
    return bool(torch.jit.is_tracing() or torch.compiler.is_compiling())


def _check_range(name: str, x: Tensor) -> None:
    """Raise `ModelInputError` when ``x`` holds a value outside `INPUT_RANGE` or NaN."""
    lo, hi = (float(v) for v in x.detach().aminmax())  # NaN if any value is NaN
    if INPUT_RANGE[0] <= lo and hi <= INPUT_RANGE[1]:  # False for NaN
        return
    if math.isnan(lo) or math.isnan(hi):
        raise ModelInputError(f"{name}: inputs must be images in [0, 1], got NaN among them")
    hint = ""
    if not math.isfinite(lo) or not math.isfinite(hi):
        pass  # infinity: no scale explains it
    elif hi > 2 and lo >= 0:
        hint = " (0-255 pixels? divide by 255; depth? preprocess_depth maps it to [0, 1])"
    elif lo < 0:
        hint = " (standardised? the model normalises [0, 1] images itself)"
    raise ModelInputError(
        f"{name}: inputs must be images in [0, 1], got values from {lo:g} to {hi:g}{hint}"
    )
