"""``lookfeel export``: each modality branch of a checkpoint as a file that runs without PyTorch
(ONNX).

Write DIR/<modality>.onnx per branch (dynamic batch; touch with dynamic presses, and dynamic
views for a run that embeds a press video from its views) and DIR/export.json, each checked
against PyTorch under onnxruntime. It runs on the CPU, with no --device: an ONNX file names
no device (onnxruntime runs it on any), and the check compares onnxruntime's CPU outputs with
PyTorch's, which on a GPU would differ by the GPU's own rounding.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from lookfeel.cli._args import (
    Choices,
    Subparsers,
    add_choice,
    add_command,
    check_out_folder,
    clear_stale_temps,
    out_folder,
)
from lookfeel.modality import Modality

EXPORT_FILES = ("export.json", *(f"{m.value}.onnx" for m in Modality))
"""What an export folder holds (the branches first): an existing, non-empty --out must hold
one (an export written again)."""


def add_parser(subparsers: Subparsers) -> None:
    """Register ``export``."""
    ex = add_command(subparsers, "export", __doc__, run)
    ex.add_argument("--checkpoint", type=Path, required=True, help="trained checkpoint (.pt)")
    add_choice(
        ex,
        "--format",
        Choices("lookfeel.export", "EXPORT_FORMATS"),
        "onnx",
        "export format: %(choices)s (default onnx)",
    )
    ex.add_argument("--out", type=out_folder, required=True, help="output folder")
    ex.add_argument(
        "--opset",
        type=_opset,
        default=17,  # lookfeel.export.DEFAULT_OPSET, not imported: it loads torch
        help="ONNX opset, 13 up to the highest the installed torch exports (default 17)",
    )


def _opset(text: str) -> int:
    """``--opset``: an opset lookfeel's models export to with the installed torch (an argparse
    type: outside them, argparse's one-line usage error naming the flag and the range)."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
    # Imported only when --opset is given: it loads torch, which `lookfeel --help` must not.
    import torch

    from lookfeel.export import supported_opsets

    opsets = supported_opsets()
    if value not in opsets:
        raise argparse.ArgumentTypeError(
            f"must be in [{opsets[0]}, {opsets[-1]}] (the ONNX opsets lookfeel's models export "
            f"to with torch {torch.__version__}), got {text}"
        )
    return value


def run(args: argparse.Namespace) -> int:
    """Export every branch and print each file with its input, output and check."""
    check_out_folder(args.out, None, EXPORT_FILES, "a lookfeel export")  # before any work
    clear_stale_temps(args.out)
    from lookfeel.export import export_onnx

    exported = export_onnx(args.checkpoint, args.out, opset=args.opset)
    for branch in exported:
        shape = " x ".join(str(s) for s in branch.input_shape)
        check = (
            f"; max |onnx - torch| = {branch.max_abs_diff:.2g}"
            if branch.max_abs_diff is not None
            else ""
        )
        print(
            f"{branch.path}: {branch.input_name} ({shape}) -> embedding "
            f"(batch x {branch.embed_dim}){check}"
        )
    return 0
