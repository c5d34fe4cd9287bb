"""Exporting a trained model to ONNX: one file per modality branch, for use without PyTorch.

``DIR/depth.onnx``, ``DIR/color.onnx``, ``DIR/touch.onnx`` each map preprocessed images in
[0, 1] to (B, D) embeddings:

- depth: input ``image`` (B, 1, S, S); colour: ``image`` (B, 3, S, S);
- touch: input ``presses`` (B, P, 3, S, S), the P presses of each query max-pooled inside the
  graph (the Multi-input Net; P = 1 for one press). A run with ``data.video_embed: views``
  embeds a press video from several views of it (`lookfeel.data.video.view_frames`: its
  deepest frame and ``data.video_views`` frames across its contact span, each preprocessed as
  an image); its graph takes input ``views`` (B, P, V, 3, S, S) and averages a press's V views
  inside, as `lookfeel.models.Branch` does, so it equals lookfeel's own embedding.

B (and P, V) are dynamic, S is the run's ``data.image_size`` (colour's ``data.color_size``
when set). ``DIR/export.json`` records the shapes, the embedding size and the run's data
settings: preprocess inputs exactly as `lookfeel.data.images.preprocess_depth` /
`preprocess_rgb` do (ImageNet normalisation is inside the graph). Each file is checked
against PyTorch under onnxruntime on random inputs of two batch sizes (and two press and view
counts) before it is written; the largest difference is recorded, and one above ``atol``
(1e-4) is an error.

Everything runs on the CPU, the checkpoint loaded there whatever the machine has (there is no
``device``, and no ``lookfeel export --device``): an ONNX file names no device (onnxruntime
runs it on whichever it is given), exporting a small branch takes seconds, and the check
compares onnxruntime's ``CPUExecutionProvider`` with PyTorch on the same inputs, where PyTorch
on a GPU would add the GPU's own rounding to the difference (convolutions run in TF32 there
by default, with about 3 significant digits) and could fail an export that is exact.

The export uses PyTorch's TorchScript-based exporter (``dynamo=False``): the newer exporter
needs the ``onnxscript`` package, which lookfeel does not depend on. It writes ONNX opsets
`MIN_OPSET` (13) up to the highest that exporter supports in the installed torch
(`supported_opsets`; 20 in torch 2.13); any other is refused before the checkpoint is read.
"""

from __future__ import annotations

import contextlib
import json
import os
import sys
import tempfile
import warnings
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import Tensor, nn

from lookfeel.atomic import atomic_write_bytes, atomic_write_text
from lookfeel.checkpoint import load_model
from lookfeel.config import to_dict
from lookfeel.errors import LookfeelError, error_line
from lookfeel.modality import Modality
from lookfeel.models import Branch

__all__ = [
    "DEFAULT_OPSET",
    "EXPORT_FORMATS",
    "MIN_OPSET",
    "ExportError",
    "ExportedBranch",
    "export_onnx",
    "supported_opsets",
]

EXPORT_FORMATS = ("onnx",)

DEFAULT_OPSET = 17
"""The ONNX opset `export_onnx` writes unless asked for another (``lookfeel export --opset``)."""

MIN_OPSET = 13
"""The lowest ONNX opset every lookfeel model exports to. The touch branch un-flattens its
presses' features, (B * P, D) -> (B, P, D), before pooling them (`lookfeel.models.Branch`), and
the TorchScript exporter writes ``Tensor.unflatten`` from opset 13 on. (Measured with torch 2.13
on the compact CNN, AlexNet and ResNet-18: depth and colour branches alone export from opset 9;
below 9 the exporter cannot write ``expand``, and opset 8's graph does not load in onnxruntime.)"""


def supported_opsets() -> range:
    """The ONNX opsets `export_onnx` accepts: `MIN_OPSET` up to the highest the installed
    torch's TorchScript exporter supports (above it torch only warns that the opset is
    unsupported, so lookfeel refuses it rather than write a file torch does not stand behind)."""
    try:  # a private module of torch's (2.0 to 2.13 at least); without it, the default only
        from torch.onnx import _constants

        high = getattr(_constants, "ONNX_TORCHSCRIPT_EXPORTER_MAX_OPSET", _constants.ONNX_MAX_OPSET)
    except (ImportError, AttributeError):
        high = DEFAULT_OPSET
    return range(MIN_OPSET, int(high) + 1)


@contextlib.contextmanager
def _quiet_native_output() -> Iterator[None]:
    """Discard what C++ code writes to the process's stdout and stderr (file descriptors 1 and
    2) inside.

    When the TorchScript exporter fails, it prints its whole graph to stdout, hundreds of lines,
    before raising: its ``setup_onnx_logging`` switches ONNX logging on whatever the setting
    (it tests the function ``_jit_is_onnx_log_enabled``, not its result; torch 2.13).
    `export_onnx` says in one line what failed instead.
    """
    sys.stdout.flush()
    sys.stderr.flush()
    saved = {fd: os.dup(fd) for fd in (1, 2)}
    try:
        with open(os.devnull, "wb") as devnull:
            for fd in saved:
                os.dup2(devnull.fileno(), fd)
        yield
    finally:
        for fd, copy in saved.items():
            os.dup2(copy, fd)
            os.close(copy)


class ExportError(LookfeelError):
    """A checkpoint cannot be exported as asked; the message says which branch and why."""


class _BranchGraph(nn.Module):
    """One branch as a plain ``x -> embedding`` module (what the exporter traces)."""

    def __init__(self, branch: Branch) -> None:
        super().__init__()
        self.branch = branch

    def forward(self, x: Tensor) -> Tensor:
        return self.branch(x)


@dataclass(frozen=True)
class ExportedBranch:
    """One exported branch.

    Attributes:
        modality: the branch's modality.
        path: the ``.onnx`` file.
        input_name: ``image``, ``presses`` or ``views``.
        input_shape: symbolic shape, e.g. ``["batch", "presses", 3, 64, 64]``.
        embed_dim: D.
        max_abs_diff: largest |onnxruntime - PyTorch| over the check inputs (None: not checked).
    """

    modality: Modality
    path: Path
    input_name: str
    input_shape: list[int | str]
    embed_dim: int
    max_abs_diff: float | None


def _check(onnx_bytes: bytes, module: nn.Module, inputs: list[Tensor], name: str) -> float:
    """The largest |onnxruntime - PyTorch| of the exported graph over ``inputs``.

    Raises:
        Whatever onnxruntime raises for a graph it cannot load or run (`export_onnx` says
        which branch and opset).
    """
    import onnxruntime as ort  # type: ignore[import-untyped]

    session = ort.InferenceSession(onnx_bytes, providers=["CPUExecutionProvider"])
    worst = 0.0
    with torch.inference_mode():
        for x in inputs:
            want = module(x).numpy()
            got = session.run(None, {name: x.numpy()})[0]
            worst = max(worst, float(np.abs(got - want).max()))
    return worst


def export_onnx(
    checkpoint: str | os.PathLike[str],
    out: str | os.PathLike[str],
    *,
    modalities: Sequence[Modality | str] | Modality | str | None = None,
    opset: int = DEFAULT_OPSET,
    check: bool = True,
    atol: float = 1e-4,
) -> list[ExportedBranch]:
    """Write one ONNX model per modality branch of a checkpoint (see the module docstring).

    Args:
        checkpoint: a lookfeel checkpoint.
        out: output folder (created once every branch has exported and passed its check).
        modalities: branches to export, each a `Modality` or its name (``"color"``); one
            alone may be given as it is; default all.
        opset: ONNX opset version, one of `supported_opsets` (13 to 20 with torch 2.13).
        check: compare each file with PyTorch under onnxruntime.
        atol: the largest difference the check accepts.

    Returns:
        The exported branches.

    Raises:
        CheckpointError: the checkpoint cannot be read.
        ModalityError: a name that is no modality (said before the checkpoint is read).
        ExportError: an opset outside `supported_opsets`, or an ``out`` that is not a folder
            (both said before the checkpoint is read); naming a modality the model has no
            branch for (before anything is written); or naming the branch and
            opset, a branch that the exporter cannot write, that onnxruntime cannot run, or
            whose ONNX outputs differ from PyTorch's by more than ``atol`` (no file is written
            then).
    """
    opsets = supported_opsets()
    if opset not in opsets:
        raise ExportError(
            f"opset {opset}: lookfeel's models export to ONNX opsets {opsets[0]} to "
            f"{opsets[-1]} with torch {torch.__version__}"
        )
    if isinstance(modalities, str):  # one modality (a Modality is a str too)
        modalities = [modalities]
    asked = list(dict.fromkeys(Modality.of(m) for m in modalities or ()))
    out_dir = Path(out)
    if out_dir.exists() and not out_dir.is_dir():
        raise ExportError(f"{out_dir}: exists and is not a folder (the export's output folder)")
    loaded = load_model(checkpoint, "cpu")  # the module docstring says why
    model = loaded.model.eval()
    wanted = asked or list(model.modalities)
    for m in wanted:
        if m not in model.modalities:
            have = ", ".join(x.value for x in model.modalities)
            raise ExportError(f"the model has no {m.value} branch (it has: {have})")
    gen = torch.Generator().manual_seed(0)
    graphs: list[tuple[Modality, bytes, str, list[int | str], float | None]] = []
    for m in wanted:
        shape: list[int | str]
        module = _BranchGraph(model.branch(m.value)).eval()  # eval: the exporter restores modes
        c = module.branch.in_channels
        size = loaded.config.data.size_of(m)
        if m is Modality.TOUCH and loaded.config.data.video_embed == "views":  # press videos
            name, shape = "views", ["batch", "presses", "views", c, size, size]
            example = torch.rand(2, 2, 3, c, size, size, generator=gen)
            axes = {name: {0: "batch", 1: "presses", 2: "views"}, "embedding": {0: "batch"}}
            checks = [
                torch.rand(1, 1, loaded.config.data.video_views + 1, c, size, size, generator=gen),
                torch.rand(3, 2, 4, c, size, size, generator=gen),
            ]
        elif m.pooled:  # a press axis (`Modality.pooled`: touch)
            name, shape = "presses", ["batch", "presses", c, size, size]
            example = torch.rand(2, 3, c, size, size, generator=gen)
            axes = {name: {0: "batch", 1: "presses"}, "embedding": {0: "batch"}}
            checks = [
                torch.rand(1, 1, c, size, size, generator=gen),
                torch.rand(3, 4, c, size, size, generator=gen),
            ]
        else:
            name, shape = "image", ["batch", c, size, size]
            example = torch.rand(2, c, size, size, generator=gen)
            axes = {name: {0: "batch"}, "embedding": {0: "batch"}}
            checks = [
                torch.rand(1, c, size, size, generator=gen),
                torch.rand(5, c, size, size, generator=gen),
            ]
        with tempfile.TemporaryDirectory(prefix="lookfeel-onnx-") as tmp, warnings.catch_warnings():
            # The TorchScript exporter warns that it is legacy, and the input checks' Python
            # booleans are traced as constants (they hold for any valid input).
            warnings.simplefilter("ignore")
            try:
                with _quiet_native_output():
                    torch.onnx.export(
                        module,
                        (example,),
                        Path(tmp) / "branch.onnx",
                        dynamo=False,
                        input_names=[name],
                        output_names=["embedding"],
                        dynamic_axes=axes,
                        opset_version=opset,
                    )
            except Exception as e:  # the exporter's own errors share no base class
                raise ExportError(
                    f"{m.value} branch: the ONNX export at opset {opset} failed: "
                    + error_line(e, 300)
                ) from None
            data = (Path(tmp) / "branch.onnx").read_bytes()
        try:
            diff = _check(data, module, checks, name) if check else None
        except Exception as e:  # onnxruntime's errors share no base class either
            raise ExportError(
                f"{m.value} branch: onnxruntime cannot run its ONNX export at opset {opset}: "
                f"{error_line(e, 300)}; nothing written"
            ) from None
        if diff is not None and diff > atol:
            raise ExportError(
                f"{m.value} branch: ONNX outputs differ from PyTorch's by {diff:.3g} "
                f"(> {atol:g}) under onnxruntime; nothing written"
            )
        graphs.append((m, data, name, shape, diff))
    # Written once every branch has exported and passed its check: a failure leaves no
    # branch files without their export.json, and no folder it created.
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as e:  # a file in the way above it, a read-only disk, no permission
        raise ExportError(
            f"{out_dir}: cannot create the export's folder ({e.strerror or e})"
        ) from None
    exported = [
        ExportedBranch(
            m,
            atomic_write_bytes(out_dir / f"{m.value}.onnx", data),
            name,
            shape,
            model.embed_dim,
            diff,
        )
        for m, data, name, shape, diff in graphs
    ]
    meta: dict[str, Any] = {
        "format": "onnx",
        "opset": opset,
        "checkpoint": str(loaded.path.resolve()),
        "step": loaded.step,
        "embed_dim": model.embed_dim,
        "branches": {
            e.modality.value: {
                "file": e.path.name,
                "input": e.input_name,
                "shape": e.input_shape,
                "output": "embedding",
                "max_abs_diff_vs_torch": e.max_abs_diff,
            }
            for e in exported
        },
        "data": to_dict(loaded.config.data),
    }
    atomic_write_text(out_dir / "export.json", json.dumps(meta, indent=2) + "\n")
    return exported
