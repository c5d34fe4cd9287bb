"""``lookfeel index build`` and ``lookfeel index info``: build a calibrated fabric library from a
dataset, and say what one holds."""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
from typing import TYPE_CHECKING

from lookfeel.cli._args import (
    Choices,
    Subparsers,
    add_choice,
    add_data_out,
    add_forward,
    add_json,
    check_out_beside_data,
    number,
)
from lookfeel.modality import PressKind

if TYPE_CHECKING:
    from lookfeel.index import PairCalibration


def add_parser(subparsers: Subparsers) -> None:
    """Register ``index build`` and ``index info``."""
    index = subparsers.add_parser(
        "index", description="Build and inspect a fabric library (for match, serve)."
    )
    actions = index.add_subparsers(dest="index_command", metavar="ACTION", required=True)
    ib = actions.add_parser(
        "build",
        help="embed every item of a dataset into a library, calibrated; resumable",
        description=(
            "Embed every item of every modality of DATA with the model of CHECKPOINT into the "
            "library folder OUT (shards, manifest; written atomically). A library at OUT stays "
            "as it is, usable, until the new one is complete: the build writes OUT.building/ "
            "and then swaps it in. A killed build continues from there when run again with the "
            "same arguments; a rebuild reuses the shards whose files did not change. A finished "
            "library of another checkpoint or dataset folder is replaced only with --replace. "
            "One build at a time per OUT (OUT.lock). Calibrates c of P ∝ exp(-c D²) and an "
            "'unknown' threshold on the library's own items (in-sample: each query's own item "
            "left out, and for the threshold its fabric, by folds). When 10 or more "
            "fabrics have two modalities, fits a cross-modal map between them on the library's "
            "fabrics, and matches the pair through it when calibration (the map refitted "
            "without each fold's fabrics) finds it better."
        ),
    )
    ib.add_argument("--checkpoint", type=Path, required=True, help="trained checkpoint (.pt)")
    add_data_out(ib, "library folder to write")
    add_choice(
        ib,
        "--backend",
        Choices("lookfeel.index", "BACKENDS"),
        "auto",
        "search: exact numpy, faiss HNSW, or auto by size (default; faiss from 100,000 "
        "items in a modality): %(choices)s",
    )
    ib.add_argument(
        "--shard-size", type=number(int, 1), default=2048, help="items per shard (default 2048)"
    )
    add_forward(ib)
    ib.add_argument(
        "--kinds",
        type=_kinds,
        default=None,
        help="touch press kinds, e.g. fold,flat (default: the run's)",
    )
    ib.add_argument(
        "--false-accept",
        type=float,
        default=0.05,
        help="target rate of unknown materials accepted as a known fabric (default 0.05)",
    )
    ib.add_argument(
        "--folds", type=int, default=5, help="leave-fabrics-out folds, at least 2 (default 5)"
    )
    ib.add_argument("--seed", type=number(int, 0), default=0, help="calibration seed (default 0)")
    ib.add_argument(
        "--calibration-queries",
        type=int,
        default=1000,
        help="held-out queries per modality pair (default 1000)",
    )
    ib.add_argument(
        "--no-cross-map",
        dest="cross_map",
        action="store_false",
        help="never match through a cross-modal map (by default one is fitted on the library's "
        "fabrics, and a pair uses it when calibration finds it better)",
    )
    ib.add_argument(
        "--replace",
        action="store_true",
        help="replace the finished library at --out even though it was built from another "
        "checkpoint (by content) or dataset folder; it stays usable until the new one is "
        "complete (without --replace such a build is refused)",
    )
    ib.add_argument("--quiet", action="store_true", help="no line per shard")
    ib.set_defaults(func=run_build)

    ii = actions.add_parser(
        "info",
        help="what a library holds and how it is calibrated",
        description=(
            "Say what the library folder LIBRARY holds: its checkpoint and model, the dataset "
            "it was built from, its items of each modality and fabrics, and each modality "
            "pair's calibration (top-1 beside chance, c of P ∝ exp(-c D²), the 'unknown' "
            "threshold with its false and true accept), measured in-sample on the library's "
            "own items; and whether a rebuild is running or was stopped. --json: all of it "
            "as JSON."
        ),
    )
    ii.add_argument("library", type=Path, help="library folder")
    add_json(ii)
    ii.set_defaults(func=run_info)


def _kinds(text: str) -> list[PressKind]:
    """``"fold,flat"`` -> the press kinds (an argparse type: a bad name is one usage line
    naming ``--kinds`` and the kinds there are)."""
    names = [k.strip() for k in text.split(",") if k.strip()]
    allowed = ", ".join(k.value for k in PressKind)
    if not names:
        raise argparse.ArgumentTypeError(f"no press kind given (choose from {allowed})")
    for name in names:
        if name not in {k.value for k in PressKind}:
            raise argparse.ArgumentTypeError(
                f"{name!r} is not a press kind (choose from {allowed})"
            )
    return [PressKind(name) for name in names]


def run_build(args: argparse.Namespace) -> int:
    """Build (or finish) the library; print its items and each pair's calibration."""
    from lookfeel.index import LibraryError, build_library

    if args.folds < 2:  # as `cv --folds`; the library function takes 0 or 1: no threshold
        raise LibraryError(
            f"--folds {args.folds}: calibration needs at least 2 folds (the 'unknown' "
            "threshold is fitted on each fold's fabrics left out; fewer would leave the "
            "library without one)"
        )
    check_out_beside_data(args.out, args.data)  # before any work: never into the dataset

    result = build_library(
        args.checkpoint,
        args.data,
        args.out,
        backend=args.backend,
        shard_size=args.shard_size,
        batch_size=args.batch_size,
        kinds=args.kinds,
        target_false_accept=args.false_accept,
        folds=args.folds,
        seed=args.seed,
        calibration_queries=args.calibration_queries,
        cross_map=args.cross_map,
        replace=args.replace,
        device=args.device,
        progress=not args.quiet,
    )
    items = ", ".join(f"{n} {m.value}" for m, n in result.items.items())
    why = f" {result.redo_reason}" if result.redo_reason else ""  # an old library's shards
    print(
        f"Library {result.root}: {items}; {result.shards_embedded} shard(s) embedded{why}, "
        f"{result.shards_reused} reused; search {result.backend}; {result.seconds:.1f} s"
    )
    for line in _LEGEND:
        print(f"  {line}")
    for key, p in result.calibration.pairs.items():
        print(
            f"  {key:<16} top1 {p.top1:.3f} (chance {_chance(p)})  c {p.c:.4g}  unknown below P "
            f"{p.threshold:.3g}: false accept {p.false_accept:.3f}, true accept "
            f"{p.true_accept:.3f}{_how(p)}"
        )
    for note in result.calibration.notes:
        print(f"  note: {note}")
    return 0


_LEGEND = (
    "(top1: how often a library item's best match, its own item left out, is its own fabric, "
    "among all the library's fabrics, not pick 1 of 10; chance: what a random ranking scores, "
    "1 over the fabrics; c: how sharp P is; below the threshold P: no known fabric)",
    "(in-sample: fitted and scored on the library itself, its own items as the queries, each "
    "with the item itself left out; c, the threshold and how a pair is matched were chosen on "
    "these same queries, so false accept is the target met on the queries the threshold was "
    "fitted on, not a rate measured on new data; held-out numbers with intervals: "
    "`lookfeel evaluate` or `lookfeel cv`)",
)
"""The lines printed above the pairs' calibration (`run_build`, `run_info`)."""


def _chance(p: PairCalibration) -> str:
    """A pair's chance top-1, one over its fabrics: ``1/24 = 0.042``."""
    if not p.fabrics:
        return "n/a"
    return f"1/{p.fabrics} = {p.chance:.3f}" if p.chance >= 0.0005 else f"1/{p.fabrics}"


def _how(p: PairCalibration) -> str:
    """How a pair is matched, when a cross-modal map was tried for it."""
    if math.isnan(p.top1_unmapped):
        return ""
    if p.mapped:
        return f"; through the cross-modal map (embedding alone {p.top1_unmapped:.3f})"
    return "; embedding distances (the cross-modal map did no better)"


def run_info(args: argparse.Namespace) -> int:
    """Print what a library holds, its model and its calibration (or all of it as JSON)."""
    from lookfeel.index import Library
    from lookfeel.index.library import work_folder

    library = Library.open(args.library)
    summary = library.summary()
    if args.json:
        print(json.dumps(summary, indent=2))
        return 0
    model = summary["model"]
    print(f"Library {library.root}")
    print(f"  checkpoint  {library.checkpoint} (step {model['step']})")
    sizes = f"{model['image_size']} px"
    if model.get("color_size"):
        sizes += f" (colour {model['color_size']} px)"
    print(f"  model       {model['backbone']} at {sizes}, D = {model['embed_dim']}")
    fingerprint = summary.get("data_fingerprint")
    digest = f" (fingerprint {fingerprint[:12]})" if fingerprint else ""
    print(f"  data        {summary['data_root']}{digest}")
    items = ", ".join(f"{n} {m}" for m, n in summary["items"].items())
    print(f"  items       {items}; {summary['fabrics']} fabrics; search {library.backend}")
    cal = library.calibration
    print(f"  calibration target false-accept {cal.target_false_accept:g}, {cal.folds} folds")
    for line in _LEGEND:
        print(f"    {line}")
    for key, p in cal.pairs.items():
        print(
            f"    {key:<16} top1 {p.top1:.3f} (chance {_chance(p)})  c {p.c:.4g}  threshold "
            f"{p.threshold:.3g}  false accept {p.false_accept:.3f}  true accept "
            f"{p.true_accept:.3f}{_how(p)}"
        )
    for note in cal.notes:
        print(f"    note: {note}")
    root = library.root.resolve() if library.root.is_symlink() else library.root
    work = work_folder(root)  # a build writes beside the folder a link names
    if work.is_dir():
        print(
            f"  note: a rebuild is running or was stopped in {work}; this library is used until "
            "it is complete (`lookfeel index build` again finishes it; removing the folder "
            "discards it)"
        )
    return 0
