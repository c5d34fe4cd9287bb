"""``lookfeel data info``, ``data check`` and ``data leakage``: what a dataset folder holds,
every problem in it, and whether its background alone identifies the fabric (or object)."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from lookfeel.cli._args import Subparsers, add_json, add_modalities, number

_ROOT_HELP = (
    "dataset folder: fabrics' images in depth/, color/, touch/ (F<id>_...), or recordings in "
    "videos/ (<object>_<n>.mov); labels.csv keyed by fabric_id or object"
)
"""The ``root`` argument of every ``data`` action: both layouts the scan reads (README, Data)."""


def add_parser(subparsers: Subparsers) -> None:
    """Register ``data info``, ``data check`` and ``data leakage``."""
    data = subparsers.add_parser(
        "data",
        description="Inspect and check a dataset folder: fabrics' images (depth/, color/, "
        "touch/) or recordings of objects (videos/<object>_<n>.mov), with labels.csv.",
    )
    actions = data.add_subparsers(dest="data_command", metavar="ACTION", required=True)
    info = actions.add_parser(
        "info",
        help="what a dataset holds: fabrics or objects, items per modality and press kind, "
        "labels, clusters",
        description="Summarise a dataset in the lookfeel layout (the README's Data section): "
        "fabrics' images in depth/, color/ and touch/, or press videos of objects in "
        "videos/<object>_<n>.mov, and labels.csv keyed by fabric_id or object. It reads names "
        "and file headers only; `data check` decodes every file.",
    )
    info.add_argument("root", type=Path, help=_ROOT_HELP)
    add_json(info, "print the summary as JSON")
    info.set_defaults(func=run_info)

    check = actions.add_parser(
        "check",
        help="decode every file and report every problem; exit 1 if there is an error",
        description=(
            "Decode every file of a dataset and report all problems at once, each with its "
            "path: undecodable or truncated files, depth that is not 16-bit, touch names and "
            "video names (videos/<object>_<n>.mov) that do not parse, press videos with no press "
            "(a warning: runs leave them out), fabrics or objects missing from labels.csv (or "
            "labelled without images or videos, a warning), fabrics lacking a modality, image "
            "files lookfeel does not read (.tif, .npy ...) and press frames in subfolders, "
            "depth maps whose values do not read as "
            "millimetres or lie mostly outside data.depth_min_mm..+data.depth_range_mm (by "
            "their defaults), frames of more than one shape, and, as warnings: truncated or "
            "two-press videos, a press video whose first frames look pressed beside its "
            "object's others, grey videos or images among colour ones, images under 16 px, "
            "names differing only in case, files with the same bytes, and background leaks. "
            "Exit 1 on errors, 0 when clean. Nothing under ROOT is modified."
        ),
    )
    check.add_argument("root", type=Path, help=_ROOT_HELP)
    add_modalities(
        check,
        "--require",
        "modalities every fabric or object must have",
        "each modality any fabric or object has",
    )
    check.add_argument("--strict", action="store_true", help="treat warnings as errors")
    add_json(check, "print the report as JSON")
    check.add_argument(
        "--workers", type=number(int, 1), default=2, help="decoding threads (default 2)"
    )
    check.add_argument(
        "--no-leakage",
        action="store_true",
        help="skip the background leak check (it scores raw pixels; ~5 s on 1,104 depth maps)",
    )
    check.add_argument(
        "--quiet",
        action="store_true",
        help="no progress bars (on stderr: the files decoded, the modalities scored for leaks)",
    )
    check.set_defaults(func=run_check)

    leakage = actions.add_parser(
        "leakage",
        help="does the background alone (no cloth; a press video's no-contact frame) identify "
        "the fabric or object? per modality",
        description=(
            "Score how well each image modality's background identifies an item's fabric (or "
            "object, in recordings: videos/<object>_<n>.mov): pick 1 of 10 top-1 (of all of "
            "them where there are fewer) from raw pixels (mean-pooled to at most 64 px, "
            "z-scored) of the background alone, beside the whole image and chance, with 95% "
            "intervals over fabrics or objects. Background = pixels that stay still across the "
            "modality's images: within "
            "--tolerance of their per-pixel median (depth 20 mm, colour/touch 12 levels) in at "
            "least --static-fraction of them (cloth moves by centimetres between drapes, the "
            "room by millimetres), or the white pixels of a --mask image; for press videos, "
            "the no-contact frame (the sensor's own light before the press), scored beside the "
            "raw pressed frame and lookfeel's input (that frame minus the no-contact one). A "
            "background whose "
            "interval lies above 2x chance is reported as a LEAK: a model can learn the capture "
            "session instead of the material; with fewer than 3 fabrics or objects 2x chance is "
            "1 or more, which no score can lie above, and the verdict is 'too few fabrics to "
            "decide' (--json: verdict \"too few fabrics\"), not 'no leak found'. With "
            "--position, depth images are also registered (the room fitted, the drape found) "
            "and scored by where the drape lies in the image: a camera that moved between "
            "sessions puts each session's drapes at their own place, a cue that masking the "
            "room does not remove. Exit 0 either way, "
            "1 for a folder with no usable image (as data check); nothing under ROOT is "
            "modified."
        ),
    )
    leakage.add_argument("root", type=Path, help=_ROOT_HELP)
    add_modalities(leakage, "--modalities", "modalities to score", "every image modality it has")
    leakage.add_argument(
        "--mask",
        action="append",
        default=[],
        metavar="[MODALITY=]PATH",
        help="background mask image (white = background, resized to the images) replacing "
        "the still-pixel rule; MODALITY= limits it to one modality; repeatable",
    )
    leakage.add_argument(
        "--tolerance",
        type=number(float, 0),
        default=None,
        help="how far a still pixel may stray from its median, in the modality's units "
        "(default: depth 20 mm, colour and touch 12 levels)",
    )
    leakage.add_argument(
        "--static-fraction",
        type=number(float, 0, 1, open_low=True),
        default=0.95,
        help="share of images in which a background pixel must be still (default 0.95)",
    )
    leakage.add_argument(
        "--pool",
        type=number(int, 1),
        default=None,
        help="mean-pooling factor (default: to <= 64 px)",
    )
    leakage.add_argument(
        "--position",
        action="store_true",
        help="also register every depth image and score where the drape lies (its top and "
        "centroid); about 0.1 s per 224 px image per thread",
    )
    leakage.add_argument(
        "--focal-px",
        type=number(float, 0, open_low=True),
        default=None,
        help="with --position: the depth camera's focal length in pixels "
        "(data.depth_focal_px; default GelFabric's Kinect crop)",
    )
    leakage.add_argument("--seed", type=int, default=0, help="bootstrap seed (default 0)")
    leakage.add_argument(
        "--workers", type=number(int, 1), default=2, help="decoding threads (default 2)"
    )
    add_json(leakage, "print the report as JSON")
    leakage.set_defaults(func=run_leakage)


def run_info(args: argparse.Namespace) -> int:
    """Print a dataset's summary (or its JSON), with the errors ``data check`` reports that the
    scan alone does not but that need no decoding: of the dataset as a whole (empty, or a
    single fabric), and of files the scan skipped that were meant as data (a ``.tif`` depth
    map, a press's frames in a subfolder), which are then errors, not skipped, as in ``data
    check``; and the paper split that training makes (labels.csv's ``paper_split`` column, or
    on GelFabric in its authors' folders the built-in list, `lookfeel.data.paper_split`)."""
    from dataclasses import replace

    from lookfeel.data import paper_split, scan
    from lookfeel.data.check import size_problems, unread_problems
    from lookfeel.data.summary import format_summary

    catalog = scan(args.root)
    whole = size_problems(catalog.root, catalog.fabrics)
    unread, skipped = unread_problems(catalog)  # reads names only, as the scan
    catalog = replace(catalog, problems=(*catalog.problems, *whole, *unread), skipped=skipped)
    paper = paper_split(catalog)  # warns when GelFabric's built-in list holds fabrics out
    if paper.source == "builtin":
        # Its "paper split" line shows the split training makes, as labels.csv's column would.
        sides = {i: "train" for i in paper.train} | {i: "test" for i in paper.test}
        fabrics = (replace(f, paper_split=sides.get(f.id, "excluded")) for f in catalog.fabrics)
        catalog = replace(catalog, fabrics=tuple(fabrics))
    if args.json:
        print(json.dumps(catalog.summary(), indent=2))
    else:
        print(format_summary(catalog, shown=unread))
    return 0


def run_check(args: argparse.Namespace) -> int:
    """Print every problem of a dataset; 1 if there is an error (or, with --strict, a warning)."""
    from lookfeel.data import check_dataset

    catalog = check_dataset(args.root, args.require, workers=args.workers, progress=not args.quiet)
    if not args.no_leakage and not catalog.errors and len(catalog.fabrics) >= 2:
        import warnings as python_warnings  # `warnings` below: the check's own
        from dataclasses import replace

        from lookfeel.data.leakage import leakage_problems, leakage_report
        from lookfeel.data.video import TruncatedVideoWarning, TwoPressesWarning
        from lookfeel.progress import bar

        # One modality at a time, for the bar: each is scored on its own anyway (with the
        # same seed), and its leaks come in the order one call for all gives them.
        leaks = []
        mods = catalog.modalities
        scoring = bar(mods, desc="leakage", unit="modality", show=not args.quiet)
        for m in scoring:
            scoring.set_postfix_str(m.value)
            with python_warnings.catch_warnings():  # the check above said them, as problems
                python_warnings.simplefilter("ignore", TruncatedVideoWarning)
                python_warnings.simplefilter("ignore", TwoPressesWarning)
                report = leakage_report(catalog, modalities=[m], n_boot=200, workers=args.workers)
            leaks += leakage_problems(report)
        catalog = replace(catalog, problems=(*catalog.problems, *leaks))
    errors, warnings = catalog.errors, catalog.warnings
    failed = bool(errors) or (args.strict and bool(warnings))
    if args.json:
        print(
            json.dumps(
                {
                    "ok": not failed,
                    "data_root": str(catalog.root),
                    "errors": [p.to_dict() for p in errors],
                    "warnings": [p.to_dict() for p in warnings],
                    "skipped": [p.to_dict() for p in catalog.skipped],
                    "summary": catalog.summary(),
                },
                indent=2,
            )
        )
        return 1 if failed else 0
    files = sum(len(it.frames) for f in catalog.fabrics for its in f.items.values() for it in its)
    named = any(f.name is not None for f in catalog.fabrics)
    what = "objects" if named else "fabrics"
    print(f"Checked {catalog.root}: {len(catalog.fabrics)} {what}, {files} files decoded.")
    for p in errors:
        print(f"ERROR    {p}")
    for p in warnings:
        print(f"WARNING  {p}")
    for p in catalog.skipped:
        print(f"SKIPPED  {p}")
    verdict = "FAILED" if failed else "OK"
    print(f"{verdict}: {len(errors)} error(s), {len(warnings)} warning(s).")
    return 1 if failed else 0


def run_leakage(args: argparse.Namespace) -> int:
    """Print how well each modality's background alone identifies the fabric (or its JSON);
    a folder with no usable image is refused in ``data check``'s line (`leakage_report`)."""
    from lookfeel.config import DataConfig
    from lookfeel.data import scan
    from lookfeel.data.leakage import format_leakage, leakage_report, parse_mask_options
    from lookfeel.modality import Modality

    catalog = scan(args.root)
    tolerance = None if args.tolerance is None else {m: args.tolerance for m in Modality}
    report = leakage_report(
        catalog,
        modalities=args.modalities,
        masks=parse_mask_options(args.mask),
        tolerance=tolerance,
        static_fraction=args.static_fraction,
        pool=args.pool,
        seed=args.seed,
        workers=args.workers,
        position=args.position,
        position_config=DataConfig(depth_input="registered", depth_focal_px=args.focal_px),
    )
    print(json.dumps(report.to_dict(), indent=2) if args.json else format_leakage(report))
    return 0
