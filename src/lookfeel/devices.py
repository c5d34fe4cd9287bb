"""Where a model runs: `resolve_device` turns a user's device name into a ``torch.device``.

Every entry point that takes a device (`lookfeel.checkpoint.load_model`, and through it
`lookfeel.index.Matcher` and `lookfeel.evaluate.evaluate_checkpoint`; training's
``train.device``) checks it here first, so a device this machine or this PyTorch cannot use
is refused in one line (`DeviceError`) instead of torch's assertion or traceback from deep in
the first tensor moved there:

    >>> resolve_device("cuda")  # on a CPU-only PyTorch
    DeviceError: device 'cuda': this PyTorch has no CUDA (torch 2.13.0+cpu, CPU build)

Apple's GPU (``mps``) is refused even where the machine has it: training and embedding sum in
float64, which MPS lacks, and the data loader pins memory for any accelerator, which torch 2.5
and 2.6 refuse on MPS. A Mac runs lookfeel on its CPU (``auto`` picks the CPU there).
"""

from __future__ import annotations

import torch

from lookfeel.errors import LookfeelError

__all__ = ["DeviceError", "resolve_device"]


class DeviceError(LookfeelError):
    """A device name torch does not know, or a device this machine or PyTorch build lacks."""


def resolve_device(value: str | torch.device, name: str = "device") -> torch.device:
    """The ``torch.device`` that ``value`` names, checked to be usable here.

    Args:
        value: ``"cpu"``, ``"cuda"``, ``"cuda:1"``, a ``torch.device``, or
            ``"auto"`` (CUDA when this machine has it, else the CPU).
        name: what the value is called in the error (``device``, ``train.device``).

    Returns:
        The device (``cuda`` keeps no index: torch's current CUDA device).

    Raises:
        DeviceError: naming the value: torch knows no such device; or this PyTorch build
            has no CUDA (a CPU build), no CUDA device is visible, the CUDA index is past the
            devices there are, or another accelerator (``xpu``) cannot be used; or it is
            ``mps`` (Apple's GPU), which lookfeel does not support yet.
    """
    text = str(value)
    if isinstance(value, str) and value.strip() == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    try:
        device = torch.device(value)
    except (RuntimeError, TypeError, ValueError) as e:
        reason = " ".join(str(e).split()) or type(e).__name__
        raise DeviceError(f"{name} {text!r}: not a device torch knows: {reason[:300]}") from None
    if device.type == "cpu":
        return device
    if device.type == "cuda":
        _check_cuda(device, f"{name} {text!r}")
        return device
    if device.type == "mps":
        if not torch.backends.mps.is_available():
            raise DeviceError(
                f"{name} {text!r}: this PyTorch or machine has no MPS (Apple GPU) device "
                f"(torch {torch.__version__}); use cpu"
            )
        raise DeviceError(
            f"{name} {text!r}: Apple's GPU (MPS) is not supported yet (training and embedding "
            "sum in float64, which MPS lacks); use cpu"
        )
    try:  # another accelerator (xpu, hpu, ...): does this build reach it?
        torch.empty(0, device=device)
    except Exception as e:  # "not compiled with ... enabled", and such, of many types
        reason = " ".join(str(e).split()).split(". ")[0] or type(e).__name__
        raise DeviceError(
            f"{name} {text!r}: this PyTorch cannot use it (torch {torch.__version__}: "
            f"{reason[:200]}); use cpu or cuda"
        ) from None
    return device


def _check_cuda(device: torch.device, what: str) -> None:
    """Raise `DeviceError` (``what`` first) unless CUDA ``device`` can be used here."""
    if torch.version.cuda is None and torch.version.hip is None:
        raise DeviceError(
            f"{what}: this PyTorch has no CUDA (torch {torch.__version__}, CPU build); use cpu, "
            "or install a CUDA build of PyTorch"
        )
    if not torch.cuda.is_available():
        raise DeviceError(
            f"{what}: no CUDA device is visible (torch {torch.__version__}, built for CUDA "
            f"{torch.version.cuda or torch.version.hip}); check the driver and "
            "CUDA_VISIBLE_DEVICES, or use cpu"
        )
    count = torch.cuda.device_count()
    if device.index is not None and device.index >= count:
        names = "cuda:0" if count == 1 else f"cuda:0 to cuda:{count - 1}"
        raise DeviceError(
            f"{what}: this machine has {count} CUDA device{'s' if count != 1 else ''} ({names})"
        )
