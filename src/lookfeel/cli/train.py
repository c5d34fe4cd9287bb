"""``lookfeel train``: train a run config on a dataset, in one process or many (torchrun).

Train a run config (see configs/) on a dataset folder. Writes RUN/config.yaml, RUN/split.json,
RUN/metrics.jsonl and RUN/checkpoints/{last,best}.pt. Runs on many processes under `torchrun
--nproc_per_node N -m lookfeel train ...`.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from lookfeel.cli._args import Subparsers, add_command, add_run_config


def add_parser(subparsers: Subparsers) -> None:
    """Register ``train``."""
    tr = add_command(subparsers, "train", __doc__, run)
    add_run_config(tr, "run directory to write")
    tr.add_argument("--resume", action="store_true", help="continue the run in --out")
    tr.add_argument(
        "--pretrained",
        type=Path,
        default=None,
        help="local ImageNet weights file for the backbone (torchvision's AlexNet layout); "
        "never downloaded",
    )


def run(args: argparse.Namespace) -> int:
    """Train, then print where the run is and its validation numbers."""
    from lookfeel.config import RunConfig, load_config
    from lookfeel.train import train

    overrides = list(args.set)
    if args.pretrained is not None:
        overrides.append(f"model.pretrained={args.pretrained}")
    config = load_config(RunConfig, args.config, overrides)
    result = train(config, args.data, args.out, resume=args.resume)
    print(f"Trained {result.steps} steps; run in {result.run_dir}")
    print(f"  last checkpoint: {result.last_checkpoint}")
    if result.best_checkpoint is not None:
        print(f"  best checkpoint: {result.best_checkpoint}")
    for key in sorted(k for k in result.validation if k.endswith("_top1")):
        v = result.validation[key]
        chance = result.validation.get(key.replace("_top1", "_chance"))
        print(f"  val {key:<24} {v:.3f}" + (f"  (chance {chance:.3f})" if chance else ""))
    return 0
