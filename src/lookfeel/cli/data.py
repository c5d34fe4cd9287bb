"""``lookfeel data info`` and ``lookfeel data check``: what a dataset folder holds, and every
problem in it."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from lookfeel.cli._args import Subparsers, add_json, add_modalities


def add_parser(subparsers: Subparsers) -> None:
    """Register ``data info`` and ``data check``."""
    data = subparsers.add_parser("data", description="Inspect and check a dataset folder.")
    actions = data.add_subparsers(dest="data_command", metavar="ACTION", required=True)
    info = actions.add_parser(
        "info",
        help="what a dataset holds: fabrics, items per modality and press kind, labels, clusters",
        description="Summarise a dataset in the lookfeel layout (see DATASET.md).",
    )
    info.add_argument("root", type=Path, help="dataset folder (depth/, color/, touch/, labels.csv)")
    add_json(info, "print the summary as JSON")
    info.set_defaults(func=run_info)

    check = actions.add_parser(
        "check",
        help="decode every file and report every problem; exit 1 if there is an error",
        description=(
            "Decode every file of a dataset and report all problems at once, each with its "
            "path: undecodable or truncated files, depth that is not 16-bit, touch names that "
            "do not parse, fabrics missing from labels.csv (or labelled without images, a "
            "warning), fabrics lacking a modality. Exit 1 on errors, 0 when clean. Nothing "
            "under ROOT is modified."
        ),
    )
    check.add_argument("root", type=Path, help="dataset folder")
    add_modalities(
        check, "--require", "modalities every fabric must have", "each modality any fabric has"
    )
    check.add_argument("--strict", action="store_true", help="treat warnings as errors")
    add_json(check, "print the report as JSON")
    check.add_argument("--workers", type=int, default=2, help="decoding threads (default 2)")
    check.set_defaults(func=run_check)


def run_info(args: argparse.Namespace) -> int:
    """Print a dataset's summary (or its JSON)."""
    from lookfeel.data import scan
    from lookfeel.data.summary import format_summary

    catalog = scan(args.root)
    if args.json:
        print(json.dumps(catalog.summary(), indent=2))
    else:
        print(format_summary(catalog))
    return 0


def run_check(args: argparse.Namespace) -> int:
    """Print every problem of a dataset; 1 if there is an error (or, with --strict, a warning)."""
    from lookfeel.data import check_dataset

    catalog = check_dataset(args.root, args.require, workers=args.workers)
    errors, warnings = catalog.errors, catalog.warnings
    failed = bool(errors) or (args.strict and bool(warnings))
    if args.json:
        print(
            json.dumps(
                {
                    "ok": not failed,
                    "root": str(catalog.root),
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
    print(f"Checked {catalog.root}: {len(catalog.fabrics)} fabrics, {files} files decoded.")
    for p in errors:
        print(f"ERROR    {p}")
    for p in warnings:
        print(f"WARNING  {p}")
    for p in catalog.skipped:
        print(f"SKIPPED  {p}")
    verdict = "FAILED" if failed else "OK"
    print(f"{verdict}: {len(errors)} error(s), {len(warnings)} warning(s).")
    return 1 if failed else 0
