"""``lookfeel train``: train a run config on a dataset, in one process or many (torchrun).

Train a run config (see configs/) on a dataset folder; without --config, the shipped recipe
for what the folder holds (a synthetic world or other data with two or more senses:
configs/synth_cross.yaml, which connects them; touch alone: configs/physiclear.yaml; depth
alone: configs/real_depth.yaml). Writes RUN/config.yaml, RUN/split.json,
RUN/metrics.jsonl and RUN/checkpoints/last.pt, and best.pt (the checkpoint that validated
best) where the run holds out fabrics to validate on (not with train.split=none). Runs on many
processes under `torchrun --nproc_per_node N -m lookfeel train ...`.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path
from typing import TYPE_CHECKING

from lookfeel.cli._args import (
    Subparsers,
    add_command,
    add_run_config,
    check_out_folder,
    path_flag,
    run_config_source,
)

if TYPE_CHECKING:
    from lookfeel.config._core import Override


def add_parser(subparsers: Subparsers) -> None:
    """Register ``train``."""
    tr = add_command(subparsers, "train", __doc__, run)
    add_run_config(tr, "run directory to write")
    tr.add_argument("--resume", action="store_true", help="continue the run in --out")
    tr.add_argument(
        "--pretrained",
        type=Path,
        default=None,
        help="local ImageNet weights file for the backbone (torchvision's AlexNet or ResNet-18 "
        "layout); never downloaded. Sets model.pretrained to the file's absolute path, so the "
        "run's config.yaml names it from any folder",
    )


RUN_FILES = ("config.yaml", "checkpoints", "members")
"""What a run folder holds (an ensemble's members first): an existing, non-empty --out must
hold one (a run to resume, or one ``train`` then refuses to write over without --resume)."""


def run(args: argparse.Namespace) -> int:
    """Train, then print where the run is and its validation numbers."""
    check_out_folder(args.out, args.data, RUN_FILES, "a lookfeel run")  # before any work
    from lookfeel.config import RunConfig, load_config
    from lookfeel.train import train

    saved = args.out / "config.yaml"
    if args.config is None and args.resume and saved.is_file():
        path, overrides = saved, list(args.set)  # a resumed run keeps its own recipe
    else:
        path, overrides = run_config_source(args)
    given: list[str | Override] = [*overrides]
    if args.pretrained is not None:
        given.append(path_flag("model.pretrained", "--pretrained", args.pretrained))
    config = load_config(RunConfig, path, given)
    result = train(config, args.data, args.out, resume=args.resume)
    if int(os.environ.get("RANK", "0")) != 0:
        return 0  # under torchrun one process reports (they trained one run)
    print(f"Trained {result.steps} steps; run in {result.run_dir}")
    print(f"  last checkpoint: {result.last_checkpoint}")
    if result.best_checkpoint is not None:
        print(f"  best checkpoint: {result.best_checkpoint}")
    val = result.validation
    keys = {k.removesuffix("_top1") for k in val if k.endswith("_top1")}
    keys |= {k.removesuffix("_not_scored") for k in val if k.endswith("_not_scored")}
    for pair in sorted(keys):
        key, v = f"{pair}_top1", val.get(f"{pair}_top1")
        if not isinstance(v, float):  # a pair with no query to score: why, never NaN
            print(f"  val {key:<24} not scored: {val.get(f'{pair}_not_scored', 'no query')}")
            continue
        chance = val.get(f"{pair}_chance")
        shown = f"  (chance {chance:.3f})" if isinstance(chance, float) and chance else ""
        print(f"  val {key:<24} {v:.3f}{shown}")
    return 0
