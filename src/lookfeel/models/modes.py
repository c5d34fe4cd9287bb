"""Small shared helpers around a model's calls: eval mode for a block, the touch press axis,
and the device settings of a forward pass (its precision and channels-last on CUDA only)."""

from __future__ import annotations

import contextlib
from collections.abc import Iterator

import torch
from torch import Tensor, nn

from lookfeel.config.model import Precision
from lookfeel.modality import Modality

__all__ = ["add_press_axis", "autocast", "drop_press_axis", "eval_mode", "to_channels_last"]


@contextlib.contextmanager
def eval_mode(model: nn.Module) -> Iterator[nn.Module]:
    """Put ``model`` in eval mode for the block and restore its training flag afterwards
    (also when the block raises)."""
    was_training = model.training
    model.eval()
    try:
        yield model
    finally:
        model.train(was_training)


def add_press_axis(x: Tensor, modality: Modality) -> Tensor:
    """(B, 3, S, S) touch images -> (B, P=1, 3, S, S), one press each (any `Modality.pooled`
    modality alike); other modalities as they are. The same for trunk features: (B, *F) ->
    (B, 1, *F)."""
    return x.unsqueeze(1) if modality.pooled else x


def drop_press_axis(x: Tensor, modality: Modality) -> Tensor:
    """The inverse of `add_press_axis`: (B, 1, ...) touch -> (B, ...)."""
    return x.squeeze(1) if modality.pooled else x


def autocast(
    device: torch.device, cache: bool = True, precision: Precision = "auto"
) -> contextlib.AbstractContextManager[object]:
    """The precision of a forward pass (`ModelConfig.precision`): on CUDA, bf16 autocast
    (``auto``) or full fp32 with TF32 off (``fp32``); on any other device nothing, fp32 (on CPU
    bf16 is ~100x slower than fp32 on the machines this runs on, and fp32 keeps CPU runs
    bit-reproducible). ``cache=False`` for code captured in a CUDA graph (autocast's cast
    cache must not outlive the capture)."""
    if device.type != "cuda":
        return contextlib.nullcontext()
    if precision == "fp32":
        return _no_tf32()
    return torch.autocast("cuda", dtype=torch.bfloat16, cache_enabled=cache)


@contextlib.contextmanager
def _no_tf32() -> Iterator[None]:
    """Full fp32 on CUDA for the block: TF32 off for matrix products and cuDNN's convolutions
    (cuDNN allows it by default), the previous settings restored afterwards."""
    matmul, cudnn = torch.backends.cuda.matmul.allow_tf32, torch.backends.cudnn.allow_tf32
    torch.backends.cuda.matmul.allow_tf32 = torch.backends.cudnn.allow_tf32 = False
    try:
        yield
    finally:
        torch.backends.cuda.matmul.allow_tf32, torch.backends.cudnn.allow_tf32 = matmul, cudnn


def to_channels_last(x: Tensor) -> Tensor:
    """Images in channels-last layout (what cuDNN's and oneDNN's fastest convolutions read):
    (N, C, H, W) directly, (B, P, C, H, W) per press, (B, P, V, C, H, W) per view; other
    tensors unchanged."""
    if x.dim() == 4:
        return x.contiguous(memory_format=torch.channels_last)
    if x.dim() == 5:  # channels-last per press: flatten(0, 1) then gives an NHWC batch
        return x.permute(0, 1, 3, 4, 2).contiguous().permute(0, 1, 4, 2, 3)
    if x.dim() == 6:  # (B, P, V, C, H, W): the same per view
        return x.permute(0, 1, 2, 4, 5, 3).contiguous().permute(0, 1, 2, 5, 3, 4)
    return x
