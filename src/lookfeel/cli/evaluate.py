"""``lookfeel evaluate``: score a checkpoint or an embeddings file into metrics, a report and
figures.

Score every modality pair by the paper's pick 1 of 10 (exact and sampled), mAP, recall@k and
median rank, with chance levels and bootstrap intervals over test fabrics; multi-press touch
queries; calibration of P ~ exp(-c D^2) with confusion matrices; physical-property probes.
Writes OUT/metrics.json (every metric, and in "info" the checkpoint and its step, split, dataset
folder and fingerprint and software versions), OUT/report.md and OUT/figures/*.png. --split: val
(default) the run's held-out items, c and probes fitted on its training items (a run's best.pt
was chosen on them: its scores there are said to be optimistic; last.pt's are not); train; novel
(a seen run's held-out fabrics); paper (the paper's 18 test fabrics); all. For a checkpoint with
a depth branch the background control is on by default: every pair with depth is scored again
with each test depth image's background replaced by another fabric's (cloth kept), beside raw
pixels, and both numbers are printed and reported side by side; registered depth is also scored
with each image registered in that other fabric's fitted room (--no-background-control turns
both off). With training (reference) fabrics, every pair of two modalities is also matched
through a cross-modal map fitted on them (keys *_mapped; --set cross_map=false turns it off).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from lookfeel.cli._args import (
    Choices,
    Subparsers,
    add_choice,
    add_command,
    add_forward,
    add_set,
    check_out_folder,
    clear_stale_temps,
    out_folder,
    usage_error,
)

REPORT_FILES = ("metrics.json", "figures/.lookfeel-figures.json")
"""What an evaluation report folder holds: an existing, non-empty --out must hold one (a report
written again; the figure list alone: one stopped before its numbers were written)."""


def add_parser(subparsers: Subparsers) -> None:
    """Register ``evaluate``."""
    ev = add_command(subparsers, "evaluate", __doc__, run)
    src = ev.add_mutually_exclusive_group(required=True)
    src.add_argument("--checkpoint", type=Path, help="a run's checkpoint (.pt); needs --data")
    src.add_argument("--embeddings", type=Path, help="an .npz written by `lookfeel embed`")
    ev.add_argument(
        "--data",
        type=Path,
        default=None,
        help="dataset folder (with --embeddings: optional, for clusters, labels and images)",
    )
    ev.add_argument("--out", type=out_folder, required=True, help="folder for the report")
    add_choice(
        ev,
        "--split",
        Choices("lookfeel.evaluate", "SPLITS"),
        None,
        "with --checkpoint: which items are the test set, one of %(choices)s (default val)",
    )
    ev.add_argument("--config", type=Path, default=None, help="evaluation config YAML (EvalConfig)")
    add_set(ev, "override an EvalConfig key, e.g. --set n_boot=200 (repeatable)")
    ev.add_argument(
        "--released-variant",
        action="store_true",
        help="also score the released code's sampled variant (own fabric may be a distractor)",
    )
    ev.add_argument(
        "--no-background-control",
        dest="background_control",
        action="store_false",
        help="skip the background control (on by default for a depth model: test depth "
        "images scored again with another fabric's background, cloth kept, and registered "
        "depth also in another fabric's fitted room; registers each test depth image, about "
        "0.2 s each)",
    )
    add_forward(ev)


def run(args: argparse.Namespace) -> int:
    """Evaluate and write the report; print each pair's top-k with its interval and chance."""
    # Options that go together, argparse's usage errors (exit 2), before any work.
    if args.checkpoint is not None and args.data is None:
        return usage_error(args, "--checkpoint needs --data (the dataset it scores)")
    if args.embeddings is not None and args.split is not None:
        return usage_error(
            args,
            "--split applies to --checkpoint; an embeddings file holds the split it was "
            "embedded with",
        )
    from lookfeel.config import EvalConfig, load_config
    from lookfeel.evaluate import (
        evaluate_checkpoint,
        evaluate_embedding_file,
        summary_lines,
        write_report,
    )

    check_out_folder(args.out, args.data, REPORT_FILES, "a lookfeel evaluation report")
    clear_stale_temps(args.out, "figures")
    overrides = list(args.set)
    if args.released_variant:
        overrides.append("released_variant=true")
    if not args.background_control:
        overrides.append("background_control=false")
    config = load_config(EvalConfig, args.config, overrides)
    if args.checkpoint is not None:
        result = evaluate_checkpoint(
            args.checkpoint,
            args.data,
            args.split or "val",
            config,
            batch_size=args.batch_size,
            device=args.device,
        )
    else:
        result = evaluate_embedding_file(args.embeddings, config, args.data)
    files = write_report(result, args.out)
    print("\n".join(summary_lines(result)))
    print(f"Wrote {files.metrics}, {files.report} and {len(files.figures)} figures")
    return 0
