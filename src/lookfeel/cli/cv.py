"""``lookfeel cv``: cross-validate a run config over fabric-disjoint folds, beside raw pixels and
chance.

Train a config (without --config, the shipped recipe for what the folder holds, as `lookfeel
train` chooses it) on every fold of cluster-stratified, fabric-disjoint folds (and every seed),
score each run's last checkpoint by pick 1 of 10 among the fabrics its fold held out, beside the
raw-pixel nearest neighbour and chance, and predict the physical labels of held-out fabrics from
their embeddings. For a depth model the background control is on by default: the same queries
are scored again with every depth image's background (room, wall, floor) replaced by another
fabric's and the cloth kept, for the model and for raw pixels, side by side; a model that
reads the cloth scores the same, one that reads the capture session drops. Registered depth
also gets the room control: each image registered against the room fitted on that other
fabric's own image, nothing refitted. The depth property probes also stand beside the room
alone: the same probe on each raw image's background pixels, no cloth (a label the capture
sessions follow is read from the room). --no-background-control turns all three off. Each
held-out fabric or object is also scored on its own queries, beside raw pixels, and the report
lists those matched worst. Writes OUT/cv.json, OUT/cv.md and a run per fold and seed
(OUT/seed{S}-fold{F}); a rerun keeps finished runs and resumes an interrupted one.
"""

from __future__ import annotations

import argparse

from lookfeel.cli._args import (
    Subparsers,
    add_command,
    add_run_config,
    check_out_folder,
    clear_stale_temps,
    number,
    number_list,
    run_config_source,
)

CV_FILES = ("cv.json", "cv.md", "seed*-fold*")
"""What a cross-validation folder holds (its runs first): an existing, non-empty --out must
hold one (a rerun keeps its finished runs)."""


def add_parser(subparsers: Subparsers) -> None:
    """Register ``cv``."""
    cv = add_command(subparsers, "cv", __doc__, run)
    add_run_config(cv, "cross-validation folder to write")
    cv.add_argument(
        "--folds",
        type=int,
        default=None,
        help="number of folds, at least 2 (default: the config's)",
    )
    cv.add_argument(
        "--fold-size",
        type=number(int, 1),
        default=None,
        help="fabrics per fold (default: the config's; 18 holds out test sets like the paper's)",
    )
    cv.add_argument(
        "--only-folds",
        type=number_list("fold"),
        default=None,
        metavar="F,F",
        help="run only these folds, e.g. 0,1,2 (default: all)",
    )
    cv.add_argument(
        "--seeds",
        type=number_list("seed"),
        default=[0],
        metavar="S,S",
        help="training seeds, integers >= 0, e.g. 0,1 (default 0); as reproduce --seeds",
    )
    cv.add_argument(
        "--tta",
        action="store_true",
        help="test-time pooling: average each image's embedding with its mirror image's",
    )
    cv.add_argument(
        "--presses",
        type=number(int, 1),
        default=None,
        help="presses of one fabric pooled into each touch query, as the Multi-input Net "
        "(default: the config's data.presses)",
    )
    cv.add_argument(
        "--n-boot", type=number(int, 0), default=1000, help="bootstrap resamples (default 1000)"
    )
    cv.add_argument(
        "--no-background-control",
        dest="background_control",
        action="store_false",
        help="skip the background control (on by default for depth: held-out depth images "
        "scored again with another fabric's background, cloth kept, and registered depth also "
        "in another fabric's fitted room, and the property probes on the room alone; "
        "registers each held-out image, about 0.2 s each, once per fold)",
    )


def run(args: argparse.Namespace) -> int:
    """Cross-validate, then print the summary and where it was written."""
    if args.folds is not None and args.folds < 2:  # before the config: 0 reads as no fold
        from lookfeel.data.splits import SplitError

        raise SplitError(
            f"--folds {args.folds} (train.folds): cross-validation needs at least 2 folds"
        )
    check_out_folder(args.out, args.data, CV_FILES, "a cross-validation folder")
    clear_stale_temps(args.out)
    from lookfeel.cli.train import check_senses
    from lookfeel.config import RunConfig, load_config
    from lookfeel.crossval import cross_validate, format_cv_summary
    from lookfeel.models import BACKBONES

    # --folds and --fold-size are the user's overrides, last: the recipe chosen without
    # --config is fitted around them, and its reason says the folds that run.
    sets = list(args.set)
    if args.folds is not None:
        sets.append(f"train.folds={args.folds}")
    if args.fold_size is not None:
        sets.append(f"train.fold_size={args.fold_size}")
    path, overrides = run_config_source(argparse.Namespace(**{**vars(args), "set": sets}))
    config = load_config(RunConfig, path, overrides)
    # Before the folds are made and the first run starts (each run checks again, in `train`).
    config.check_input_sizes(BACKBONES[config.model.backbone].min_size)
    check_senses(config, args.data, chosen=args.config is None)
    summary = cross_validate(
        config,
        args.data,
        args.out,
        seeds=args.seeds,
        folds=args.only_folds,
        tta=args.tta,
        n_boot=args.n_boot,
        background_control=args.background_control,
        presses=args.presses,
    )
    print(format_cv_summary(summary), end="")
    print(f"Wrote {args.out / 'cv.json'} and {args.out / 'cv.md'}")
    return 0
