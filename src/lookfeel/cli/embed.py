"""``lookfeel embed``: embed a dataset's items with a trained checkpoint into an ``.npz`` file.

Embed the items of a dataset with a checkpoint's model and write FILE.npz: embeddings_<modality>
(N, D), fabric_id_<modality> (N,), path_<modality> (N,) (touch: one row per press), and for
--split val/novel/paper the reference (training) items as reference_* arrays, so `lookfeel
evaluate --embeddings` can fit c and the property probes from the file alone.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from lookfeel.cli._args import (
    Choices,
    Subparsers,
    add_choice,
    add_command,
    add_data_out,
    add_forward,
)


def add_parser(subparsers: Subparsers) -> None:
    """Register ``embed``."""
    emb = add_command(subparsers, "embed", __doc__, run)
    emb.add_argument("--checkpoint", type=Path, required=True, help="a run's checkpoint (.pt)")
    add_data_out(emb, "the .npz file to write", file=True)
    add_choice(
        emb,
        "--split",
        Choices("lookfeel.evaluate", "SPLITS"),
        "all",
        "which items, one of %(choices)s: the run's held-out (val) or training (train) "
        "items, a seen run's novel fabrics, the paper's test fabrics, or all (default)",
    )
    emb.add_argument(
        "--no-reference", action="store_true", help="do not embed the reference (training) items"
    )
    add_forward(emb)


def run(args: argparse.Namespace) -> int:
    """Embed and save, then say how many items of each modality went where."""
    from lookfeel.evaluate import embed_checkpoint, save_embeddings

    emb = embed_checkpoint(
        args.checkpoint,
        args.data,
        args.split,
        reference=not args.no_reference,
        batch_size=args.batch_size,
        device=args.device,
    )
    path = save_embeddings(args.out, emb)
    counts = ", ".join(f"{m.value} {len(e.embeddings)}" for m, e in emb.embedded.items())
    print(f"Embedded {counts} ({emb.meta['split_description']}) into {path}")
    if emb.reference:
        ref = ", ".join(f"{m.value} {len(e.embeddings)}" for m, e in emb.reference.items())
        print(f"  with the reference (training) items: {ref}")
    return 0
