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

The export uses PyTorch's TorchScript-based exporter (``dynamo=False``): the newer exporter
needs the ``onnxscript`` package, which lookfeel does not depend on.
"""

from __future__ import annotations

import json
import os
import tempfile
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch import Tensor, nn

from lookfeel.atomic import atomic_write_bytes, atomic_write_text
from lookfeel.checkpoint import load_model
from lookfeel.config import to_dict
from lookfeel.errors import LookfeelError
from lookfeel.modality import Modality
from lookfeel.models import Branch

__all__ = ["EXPORT_FORMATS", "ExportError", "ExportedBranch", "export_onnx"]

EXPORT_FORMATS = ("onnx",)


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
    modalities: list[Modality] | None = None,
    opset: int = 17,
    check: bool = True,
    atol: float = 1e-4,
) -> list[ExportedBranch]:
    """Write one ONNX model per modality branch of a checkpoint (see the module docstring).

    Args:
        checkpoint: a lookfeel checkpoint.
        out: output folder (created).
        modalities: branches to export; default all.
        opset: ONNX opset version.
        check: compare each file with PyTorch under onnxruntime.
        atol: the largest difference the check accepts.

    Returns:
        The exported branches.

    Raises:
        CheckpointError: the checkpoint cannot be read.
        ExportError: naming a modality the model has no branch for, or a branch whose
            ONNX outputs differ from PyTorch's by more than ``atol`` (nothing is written then).
    """
    loaded = load_model(checkpoint)
    model = loaded.model.eval()
    wanted = list(modalities) if modalities else list(model.modalities)
    for m in wanted:
        if m not in model.modalities:
            have = ", ".join(x.value for x in model.modalities)
            raise ExportError(f"the model has no {m.value} branch (it has: {have})")
    out_dir = Path(out)
    out_dir.mkdir(parents=True, exist_ok=True)
    gen = torch.Generator().manual_seed(0)
    exported = []
    for m in wanted:
        shape: list[int | str]
        module = _BranchGraph(model.branch(m.value)).eval()  # eval: the exporter restores modes
        c = module.branch.in_channels
        size = loaded.config.data.size_of(m)
        if m is Modality.TOUCH and loaded.config.data.video_embed == "views":
            name, shape = "views", ["batch", "presses", "views", c, size, size]
            example = torch.rand(2, 2, 3, c, size, size, generator=gen)
            axes = {name: {0: "batch", 1: "presses", 2: "views"}, "embedding": {0: "batch"}}
            checks = [
                torch.rand(1, 1, loaded.config.data.video_views + 1, c, size, size, generator=gen),
                torch.rand(3, 2, 4, c, size, size, generator=gen),
            ]
        elif m is Modality.TOUCH:
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
            data = (Path(tmp) / "branch.onnx").read_bytes()
        diff = _check(data, module, checks, name) if check else None
        if diff is not None and diff > atol:
            raise ExportError(
                f"{m.value} branch: ONNX outputs differ from PyTorch's by {diff:.3g} "
                f"(> {atol:g}) under onnxruntime; not written"
            )
        path = atomic_write_bytes(out_dir / f"{m.value}.onnx", data)
        exported.append(ExportedBranch(m, path, name, shape, model.embed_dim, diff))
    meta: dict[str, Any] = {
        "format": "onnx",
        "opset": opset,
        "checkpoint": str(Path(checkpoint).resolve()),
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
