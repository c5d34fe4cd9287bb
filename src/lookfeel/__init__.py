"""lookfeel: one embedding space for how fabrics look and how they feel.

An implementation of Yuan, Wang, Dong & Adelson, "Connecting Look and Feel: Associating the
visual and tactile properties of physical materials" (CVPR 2017), and beyond.

Start here (README.md's "Training" and "Using a trained model" say more):

    >>> from lookfeel import RunConfig, load_config, load_model
    >>> from lookfeel.train import train
    >>> config = load_config(RunConfig, "configs/tiny.yaml")
    >>> result = train(config, "my_fabrics/", "runs/first")
    >>> loaded = load_model(result.last_checkpoint)  # loaded.model embeds images

Training is `lookfeel.train.train`: the name ``lookfeel.train`` is its package. Matching
images against a library of fabrics is `lookfeel.index`, scoring a checkpoint
`lookfeel.evaluate`. A backbone or loss of one's own is registered with
`lookfeel.models.register_backbone` or `lookfeel.losses.register_loss` (`list_backbones`,
`list_losses` name what is registered; docs/ARCHITECTURE.md, "Where to add things").
Metrics are keyed by a `Pair` of modalities (``touch_to_depth``). ``import lookfeel`` stays
light (no torch): `load_model` and the other names here that need torch are imported the first
time they are used.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from lookfeel.config import (
    AugmentConfig,
    ConfigError,
    DataConfig,
    EvalConfig,
    LossConfig,
    ModelConfig,
    RunConfig,
    TrainConfig,
    load_config,
)
from lookfeel.errors import LookfeelError
from lookfeel.modality import Modality, ModalityError, Pair, PressKind

if TYPE_CHECKING:
    from lookfeel.checkpoint import LoadedModel, load_model
    from lookfeel.devices import DeviceError, resolve_device

__version__ = "0.1.0"

_LAZY = {
    "DeviceError": "lookfeel.devices",
    "LoadedModel": "lookfeel.checkpoint",
    "load_model": "lookfeel.checkpoint",
    "resolve_device": "lookfeel.devices",
}
"""Names exported here whose modules import torch: imported on first use (`__getattr__`)."""

__all__ = [
    "AugmentConfig",
    "ConfigError",
    "DataConfig",
    "DeviceError",
    "EvalConfig",
    "LoadedModel",
    "LookfeelError",
    "LossConfig",
    "Modality",
    "ModalityError",
    "ModelConfig",
    "Pair",
    "PressKind",
    "RunConfig",
    "TrainConfig",
    "__version__",
    "load_config",
    "load_model",
    "resolve_device",
]


def __getattr__(name: str) -> Any:
    """Import a name of `_LAZY` from its module the first time it is asked for."""
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'lookfeel' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value  # later lookups skip this function
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *_LAZY})
