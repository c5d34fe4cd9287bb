"""The backbone registry: a plain dict from name to class (timm's factory, without decorators)."""

from __future__ import annotations

from typing import Any

from lookfeel.models.alexnet import AlexNet
from lookfeel.models.backbone import Backbone
from lookfeel.models.compact import CompactCNN
from lookfeel.models.resnet import ResNet18

__all__ = ["BACKBONES", "create_backbone", "list_backbones"]

BACKBONES: dict[str, type[Backbone]] = {
    AlexNet.name: AlexNet,
    CompactCNN.name: CompactCNN,
    ResNet18.name: ResNet18,
}
"""Name -> backbone class. Every class takes ``in_channels``, ``stem``, ``freeze``, ``dropout``
and ``width`` keywords."""


def list_backbones() -> list[str]:
    """Names `create_backbone` accepts, sorted."""
    return sorted(BACKBONES)


def create_backbone(name: str, **kwargs: Any) -> Backbone:
    """Build a backbone by name, with random weights (see `load_pretrained` for weights).

    Args:
        name: one of `list_backbones`.
        **kwargs: ``in_channels`` (1 or 3), ``stem`` (``replicate`` | ``sum``), ``freeze``
            (a freeze point; ``None`` for the backbone's default), ``dropout``, ``width``.

    Returns:
        The backbone; ``backbone(x)`` maps (N, in_channels, H, W) in [0, 1] to
        (N, backbone.embed_dim), and equals ``backbone.head(backbone.trunk(x))``.

    Raises:
        ValueError: an unknown name (listing the known ones) or a bad keyword value.
    """
    if name not in BACKBONES:
        raise ValueError(
            f"unknown backbone {name!r}; expected one of: {', '.join(list_backbones())}"
        )
    return BACKBONES[name](**kwargs)
