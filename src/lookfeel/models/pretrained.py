"""Load a user's local torchvision weights into a backbone, checking every key and shape.

Weights are never downloaded: the user names a file they already have (for AlexNet,
torchvision's ``alexnet-owt-7be5be79.pth``). It is read with ``weights_only=True``, so a file
cannot run code. A one-channel ``sum`` stem receives the sum of the file's RGB filters.

Files as other code saves them are taken too: a state dict wrapped in a dict of other things
(``{"state_dict": ..., "epoch": 3}``) is unwrapped when exactly one entry is a state dict, keys
all prefixed ``module.`` (saved from DistributedDataParallel) or ``_orig_mod.``
(`torch.compile`) are stripped, and the ImageNet classifier no embedding uses (ResNet-18's
``fc``) may be absent (a self-supervised checkpoint) or of another size.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path

import torch
from torch import Tensor, nn

from lookfeel.errors import LookfeelError, load_problem
from lookfeel.models.backbone import Backbone

__all__ = ["PretrainedError", "apply_state_dict", "load_pretrained", "read_state_dict"]

_SHOWN = 3  # offending keys named in an error message

_PREFIXES = ("module.", "_orig_mod.")
"""Key prefixes that wrappers add (DistributedDataParallel, `torch.compile`), stripped when
every key has one."""


class PretrainedError(LookfeelError):
    """A pretrained weights file is missing, unreadable, or does not fit the model."""


def _first(keys: list[str]) -> str:
    more = f" (and {len(keys) - _SHOWN} more)" if len(keys) > _SHOWN else ""
    return ", ".join(keys[:_SHOWN]) + more


def _is_state_dict(value: object) -> bool:
    """Whether ``value`` is a non-empty mapping of names to tensors."""
    return (
        isinstance(value, Mapping)
        and bool(value)
        and all(isinstance(k, str) and isinstance(v, Tensor) for k, v in value.items())
    )


def _strip_prefixes(state: dict[str, Tensor]) -> dict[str, Tensor]:
    """``state`` without the wrapper prefixes (`_PREFIXES`) that every key shares."""
    stripped = True
    while stripped:
        stripped = False
        for prefix in _PREFIXES:
            if state and all(k.startswith(prefix) for k in state):
                state = {k.removeprefix(prefix): v for k, v in state.items()}
                stripped = True
    return state


def read_state_dict(path: str | os.PathLike[str]) -> dict[str, Tensor]:
    """Read a state dict (parameter name -> tensor) from a local file, safely.

    A dict whose one entry is a state dict (``{"state_dict": ..., "epoch": 3}``,
    ``{"model": ...}``) gives that entry; the ``module.`` or ``_orig_mod.`` prefix that every
    key carries, if any, is stripped.

    Args:
        path: a ``.pth`` file written by ``torch.save(model.state_dict(), path)``.

    Raises:
        PretrainedError: naming the file, when it is absent, unreadable, or not a state dict
            (nor a dict holding exactly one).
    """
    p = Path(path)
    if not p.is_file():
        raise PretrainedError(
            f"{p}: pretrained weights file not found (weights are never "
            "downloaded; give the path of a local torchvision .pth file)"
        )
    try:
        # Memory-mapped: the tensors are copied into each branch straight from the page cache.
        data = torch.load(p, map_location="cpu", weights_only=True, mmap=True)
    except Exception:
        try:  # files in the legacy (pre-zip) format cannot be memory-mapped
            data = torch.load(p, map_location="cpu", weights_only=True)
        except Exception as e:  # torch raises several types for corrupt or foreign files
            raise PretrainedError(
                f"{p}: not a readable PyTorch weights file ({load_problem(e, p)})"
            ) from None
    if not isinstance(data, Mapping):
        raise PretrainedError(
            f"{p}: not a state dict (a mapping of parameter names to tensors); "
            f"it holds a {type(data).__name__}"
        )
    if "config" in data and "model" in data and "version" in data:
        raise PretrainedError(
            f"{p}: a lookfeel checkpoint, not a backbone's weights file; start from it with "
            "model.init_from instead of model.pretrained"
        )
    bad = [str(k) for k, v in data.items() if not isinstance(k, str) or not isinstance(v, Tensor)]
    if bad:
        inner = [str(k) for k, v in data.items() if _is_state_dict(v)]
        if len(inner) == 1:  # {"state_dict": ..., "epoch": 3}: what a training script saves
            return _strip_prefixes(dict(data[inner[0]]))
        if inner:
            raise PretrainedError(
                f"{p}: holds several state dicts ({_first(inner)}); save the backbone's alone, "
                f"e.g. torch.save(torch.load(file)[{inner[0]!r}], 'weights.pth')"
            )
        raise PretrainedError(f"{p}: not a state dict; entries that are not tensors: {_first(bad)}")
    return _strip_prefixes(dict(data))


def apply_state_dict(model: Backbone, state: Mapping[str, Tensor], source: str = "") -> None:
    """Copy ``state`` into ``model`` after checking that keys and shapes match exactly.

    A one-channel ``sum`` stem takes the sum over the RGB axis of a three-channel first filter.
    A first layer reading F frames stacked (3F channels, ``data.touch_frames``) takes the RGB
    filter once per frame, divided by F (inflated as I3D inflates 2D filters over time), so
    F copies of one image give what that image gave the pretrained network.
    A missing BatchNorm ``num_batches_tracked`` (old torchvision files) is allowed, and so is
    a layer no embedding uses (`Backbone.unused_keys`: ResNet-18's ImageNet classifier ``fc``)
    that is absent or of another shape: the model keeps its own.

    Args:
        model: the backbone to fill.
        state: its torchvision-layout weights.
        source: the file name, for error messages.

    Raises:
        PretrainedError: naming ``source`` and the first missing, unexpected or misshapen keys.
    """
    where = f"{source}: " if source else ""
    expected = model.state_dict()
    unused = model.unused_keys()
    hint = _prefix_hint(state)
    missing = [
        k
        for k in expected
        if k not in state and k not in unused and not k.endswith("num_batches_tracked")
    ]
    if missing:
        raise PretrainedError(f"{where}missing keys for {model.name}: {_first(missing)}{hint}")
    unexpected = [k for k in state if k not in expected]
    if unexpected:
        raise PretrainedError(
            f"{where}unexpected keys for {model.name}: {_first(unexpected)}{hint}"
        )
    adapted: dict[str, Tensor] = {}
    wrong: list[str] = []
    for key, want in expected.items():
        if key not in state:
            adapted[key] = want  # num_batches_tracked, or an unused layer
            continue
        have = state[key]
        if key in unused and have.shape != want.shape:
            adapted[key] = want  # e.g. a classifier of 10 classes, not ImageNet's 1000
            continue
        if have.dim() == 4 and want.dim() == 4 and have.shape[1] == 3 and want.shape[1] == 1:
            have = have.sum(dim=1, keepdim=True)  # RGB filters -> one grey filter
        elif have.dim() == 4 and want.dim() == 4 and have.shape[1] == 3 and want.shape[1] > 3:
            frames = want.shape[1] // 3  # RGB filters -> one per stacked frame
            have = have.repeat(1, frames, 1, 1) / frames
        if have.shape != want.shape:
            wrong.append(f"{key} (file {tuple(have.shape)}, model {tuple(want.shape)})")
        adapted[key] = have
    if wrong:
        raise PretrainedError(f"{where}shapes do not match {model.name}: {_first(wrong)}")
    model.load_state_dict(adapted, strict=True)


def _prefix_hint(state: Mapping[str, Tensor]) -> str:
    """A hint for keys of which some, not all, carry a wrapper's prefix."""
    for prefix in _PREFIXES:
        some = sum(k.startswith(prefix) for k in state)
        if some:
            return (
                f" ({some} of {len(state)} keys start with {prefix!r}, as a wrapped model's do: "
                f"save the inner model's state dict, or strip {prefix!r} from every key)"
            )
    return ""


def load_pretrained(model: nn.Module, path: str | os.PathLike[str]) -> None:
    """Load a local torchvision weights file into a backbone.

    Args:
        model: a `Backbone` whose layout matches the file (``alexnet``, ``resnet18``).
        path: e.g. ``~/.cache/torch/hub/checkpoints/alexnet-owt-7be5be79.pth``.

    Raises:
        PretrainedError: the file is absent, unreadable, not a state dict, or its keys or shapes
            do not match the model (the message names the file and the first offending keys).
    """
    if not isinstance(model, Backbone):
        raise TypeError(f"load_pretrained takes a Backbone, got {type(model).__name__}")
    path = Path(path).expanduser()
    apply_state_dict(model, read_state_dict(path), source=str(path))
