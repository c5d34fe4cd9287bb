"""``lookfeel export``: each modality branch of a checkpoint as a file that runs without PyTorch
(ONNX).

Write DIR/<modality>.onnx per branch (dynamic batch; touch with dynamic presses, and dynamic
views for a run that embeds a press video from its views) and DIR/export.json, each checked
against PyTorch under onnxruntime.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from lookfeel.cli._args import Choices, Subparsers, add_choice, add_command, out_folder


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
    ex.add_argument("--opset", type=int, default=17, help="ONNX opset (17)")


def run(args: argparse.Namespace) -> int:
    """Export every branch and print each file with its input, output and check."""
    from lookfeel.export import export_onnx

    exported = export_onnx(args.checkpoint, args.out, opset=args.opset)
    for branch in exported:
        shape = "x".join(str(s) for s in branch.input_shape)
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
