"""``lookfeel reproduce``: every experiment of the paper on a dataset, reported beside its numbers.

Train and evaluate the paper's experiments (Figure 7, Tables 1-4) on a dataset and write
DIR/report.md and DIR/results.json. Budgets: tiny (compact CNN at 40 px, 120 steps: seconds a
run; make demo's eight took 39 s side by side on 2 cores, session 46); small (the default:
compact CNN at 64 px, 1,500 steps of batch 64: about 34 min a run, two at a time on 2 cores, at
the 0.73 steps/s measured in session 51 on a loaded machine); paper (the paper's AlexNet
configs; needs --pretrained). Runs whose modalities the data lacks are skipped with the
reason. Re-running resumes finished runs, and the report covers every finished run in DIR
trained with the same settings: --only adds to it. A DIR of runs trained on another dataset is
refused; another --n-boot scores the finished runs again from their checkpoints.
"""

from __future__ import annotations

import argparse
import os
from pathlib import Path

from lookfeel.cli._args import (
    Choices,
    NameList,
    Subparsers,
    add_choice,
    add_command,
    add_data_out,
    add_name_list,
    add_set,
    check_out_folder,
    clear_stale_temps,
    number,
    number_list,
)

REPRODUCE_FILES = ("results.json", "runs")
"""What a reproduce folder holds (its runs first): an existing, non-empty --out must hold one
(a rerun resumes its finished runs)."""


def add_parser(subparsers: Subparsers) -> None:
    """Register ``reproduce``."""
    rep = add_command(subparsers, "reproduce", __doc__, run)
    add_data_out(rep, "output folder")
    add_choice(
        rep,
        "--budget",
        Choices("lookfeel.reproduce", "BUDGETS"),
        "small",
        "%(choices)s (default small; see above)",
    )
    rep.add_argument(
        "--seeds",
        type=number_list("seed"),
        default=[0],
        metavar="S,S",
        help="training seeds of every experiment, integers >= 0, trained in this order, e.g. "
        "0,1 (default 0), as cv --seeds; the numbers are their means. Runs are "
        "DIR/runs/NAME/seed{S}, so a rerun resumes the seeds it names",
    )
    rep.add_argument(
        "--pretrained",
        type=Path,
        default=None,
        help="ImageNet AlexNet weights (the runs' config.yaml names the file's absolute path)",
    )
    add_name_list(
        rep,
        "--only",
        NameList("lookfeel.reproduce.run", "EXPERIMENT_NAMES"),
        "experiments to run, of %(choices)s (default all), comma- or space-separated; the "
        "report also covers the finished runs of the others already in --out with the same "
        "settings",
    )
    rep.add_argument(
        "--n-boot",
        type=number(int, 0),
        default=1000,
        help="bootstrap resamples (default 1000)",
    )
    rep.add_argument(
        "--workers",
        type=number(int, 0),
        default=0,
        help="runs trained at once, each in its own process with a share of the cores "
        "(default 0: one per core on a CPU, 1 on CUDA; 1: one after the other in this process)",
    )
    add_set(rep, "override every run's config, e.g. --set train.steps=100 (repeatable)")


def run(args: argparse.Namespace) -> int:
    """Reproduce, then print the headline numbers, the paper's findings checked, the report."""
    check_out_folder(args.out, args.data, REPRODUCE_FILES, "a lookfeel reproduce folder")
    clear_stale_temps(args.out)
    from lookfeel.reproduce import headline, reproduce
    from lookfeel.reproduce.report import verdict_text

    result = reproduce(
        args.data,
        args.out,
        budget=args.budget,
        seeds=args.seeds,
        # Absolute: each run's config.yaml then names the file from any folder.
        pretrained=None if args.pretrained is None else os.path.abspath(args.pretrained),
        only=args.only or (),
        n_boot=args.n_boot,
        overrides=args.set,
        workers=args.workers,
    )
    print()
    for line in headline(result.results):
        print(line)
    verdicts = [(verdict_text(f), f["claim"]) for f in result.findings.values()]
    width = max([13, *(len(v) for v, _ in verdicts)])  # 13: "does not hold"
    for verdict, claim in verdicts:
        print(f"{verdict:>{width}}: {claim}")
    meta = result.meta
    if meta.get("runs"):  # a resumed reproduction's own minutes are not the numbers' cost
        print(
            f"\n{meta['runs']} run(s) behind these numbers, {meta['run_minutes']} min of training "
            f"and scoring; this reproduction {meta['minutes']} min"
        )
    print(f"\nReport: {result.report}")
    return 0
