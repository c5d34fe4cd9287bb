"""``lookfeel embed``: embed a dataset's items with a trained checkpoint into an ``.npz`` file.

Embed the items of a dataset with a checkpoint's model and write FILE.npz: embeddings_<modality>
(N, D), fabric_id_<modality> (N,), path_<modality> (N,) (touch: one row per press), and for
--split val/novel/paper the reference (training) items as reference_* arrays, so `lookfeel
evaluate --embeddings` can fit c and the property probes from the file alone.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from lookfeel.atomic import remove_stale_temps
from lookfeel.cli._args import (
    Choices,
    Subparsers,
    add_choice,
    add_command,
    add_data_out,
    add_forward,
    check_embeddings_out,
)
from lookfeel.modality import Modality


def add_parser(subparsers: Subparsers) -> None:
    """Register ``embed``."""
    emb = add_command(subparsers, "embed", __doc__, run)
    emb.add_argument("--checkpoint", type=Path, required=True, help="a run's checkpoint (.pt)")
    add_data_out(
        emb,
        "the .npz file to write; an existing file is replaced only if it is one lookfeel "
        "embed wrote, and never inside --data",
        file=True,
    )
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
    emb.add_argument(
        "--quiet",
        action="store_true",
        help="no progress bars (on stderr: each modality's images decoded, its items embedded)",
    )


def run(args: argparse.Namespace) -> int:
    """Embed and save, then say how many items of each modality went where."""
    check_embeddings_out(args.out, args.data)  # before any work
    remove_stale_temps(args.out)  # what a killed write of it left
    from lookfeel.evaluate import embed_checkpoint, save_embeddings

    emb = embed_checkpoint(
        args.checkpoint,
        args.data,
        args.split,
        reference=not args.no_reference,
        batch_size=args.batch_size,
        device=args.device,
        progress=not args.quiet,
    )
    path = save_embeddings(args.out, emb)
    counts = ", ".join(f"{m.value} {len(e.embeddings)}" for m, e in emb.embedded.items())
    print(f"Embedded {counts} ({emb.meta['split_description']}) into {path}")
    if emb.reference:
        ref = ", ".join(f"{m.value} {len(e.embeddings)}" for m, e in emb.reference.items())
        print(f"  with the reference (training) items: {ref}")
    # --split all: the description above already names what of the dataset is left out.
    note = _kinds_left_out(args.data, emb.meta.get("data_config", {}).get("touch_kinds"))
    if Modality.TOUCH in emb.embedded and note and args.split != "all":
        print(f"  {note}")
    return 0


def _kinds_left_out(data: Path, kinds: object) -> str | None:
    """A line saying which touch presses of ``data`` the run's press kinds (``kinds``, from
    the checkpoint's ``data.touch_kinds``) leave out, e.g. ``touch: fold presses only (the
    run's data.touch_kinds); 8 flat presses of the dataset left out``; None when none is."""
    from lookfeel.data.layout import scan

    if not isinstance(kinds, (list, tuple)) or not kinds:
        return None
    wanted = {str(k) for k in kinds}
    left: dict[str, int] = {}
    for it in scan(data, check_headers=False).items(Modality.TOUCH):
        if it.kind is not None and it.kind.value not in wanted:
            left[it.kind.value] = left.get(it.kind.value, 0) + 1
    if not left:
        return None
    taken = "/".join(sorted(wanted))
    others = ", ".join(f"{n} {k}" for k, n in sorted(left.items()))
    return (
        f"touch: {taken} presses only (the run's data.touch_kinds); {others} presses of the "
        "dataset left out"
    )
