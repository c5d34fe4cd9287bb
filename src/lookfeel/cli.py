"""The ``lookfeel`` command. Flags become config objects here; library code never sees argv.

lookfeel data info ROOT [--json]      what a dataset holds
lookfeel data check ROOT [--require]  every problem in a dataset, exit 1 if any error
lookfeel demo                         the main job on the embedded default
"""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Sequence
from pathlib import Path

from lookfeel import __version__
from lookfeel.data import Catalog, DatasetError, check_dataset, scan
from lookfeel.modality import Modality, parse_modalities


def _modalities(text: str) -> tuple[Modality, ...]:
    try:
        return parse_modalities(text)
    except ValueError as e:
        raise argparse.ArgumentTypeError(str(e)) from None


def _ranges(ids: Sequence[int]) -> str:
    """``[1, 2, 3, 7]`` -> ``"1-3, 7"``."""
    out, start, prev = [], None, None
    for i in sorted(ids):
        if start is None:
            start = prev = i
        elif prev is not None and i == prev + 1:
            prev = i
        else:
            out.append(f"{start}-{prev}" if start != prev else f"{start}")
            start = prev = i
    if start is not None:
        out.append(f"{start}-{prev}" if start != prev else f"{start}")
    return ", ".join(out)


def format_summary(catalog: Catalog) -> str:
    """A dataset summary a person reads (``lookfeel data info``)."""
    s = catalog.summary()
    rows: list[tuple[str, str]] = [("fabrics", f"{s['fabrics']} (ids {_ranges(catalog.ids)})")]
    per = s["items_per_fabric"]
    assert isinstance(per, dict)
    items = s["items"]
    assert isinstance(items, dict)
    for m in Modality:
        if m.value not in items:
            rows.append((m.value, "none"))
            continue
        rng = per[m.value]
        unit = "presses" if m is Modality.TOUCH else "images"
        line = f"{items[m.value]} {unit} ({rng['min']}-{rng['max']} per fabric)"
        if m is Modality.TOUCH:
            kinds = s["touch_presses_by_kind"]
            assert isinstance(kinds, dict)
            line += ": " + ", ".join(f"{k} {v}" for k, v in kinds.items())
            line += f"; {s['touch_frames']} frames"
        rows.append((m.value, line))
    cols = s["label_columns"]
    assert isinstance(cols, list)
    rows.append(
        (
            "labels",
            (", ".join(cols) if cols else "no labels.csv")
            + f"; {s['fabrics_with_physical_labels']} fabrics with physical labels",
        )
    )
    clusters = s["clusters"]
    assert isinstance(clusters, dict)
    if clusters:
        dist = " ".join(f"{k}:{v}" for k, v in clusters.items())
        rows.append(
            (
                "clusters",
                f"{len(clusters)} from {s['cluster_column'] or 'k-means'}, "
                f"{s['fabrics_with_cluster']} of {s['fabrics']} fabrics ({dist})",
            )
        )
    else:
        rows.append(("clusters", "none (add a cluster8 column, or use k-means on labels)"))
    split = s["paper_split"]
    assert isinstance(split, dict)
    if split:
        rows.append(("paper split", ", ".join(f"{k} {v}" for k, v in split.items())))
    held = s["labelled_without_images"]
    assert isinstance(held, list)
    if held:
        rows.append(("no images", f"{len(held)} labelled fabrics: {_ranges(held)}"))
    if catalog.skipped:
        names = ", ".join(p.path.name for p in catalog.skipped[:5] if p.path is not None)
        more = f" and {len(catalog.skipped) - 5} more" if len(catalog.skipped) > 5 else ""
        rows.append(("skipped", f"{len(catalog.skipped)} not in the layout: {names}{more}"))
    rows.append(
        (
            "problems",
            f"{s['errors']} errors, {s['warnings']} warnings"
            + (" (run `lookfeel data check`)" if s["errors"] or s["warnings"] else ""),
        )
    )
    width = max(len(k) for k, _ in rows)
    return "\n".join([f"Dataset {catalog.root}"] + [f"  {k:<{width}}  {v}" for k, v in rows])


def _cmd_data_info(args: argparse.Namespace) -> int:
    catalog = scan(args.root)
    if args.json:
        print(json.dumps(catalog.summary(), indent=2))
    else:
        print(format_summary(catalog))
    return 0


def _cmd_data_check(args: argparse.Namespace) -> int:
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


def _cmd_demo(args: argparse.Namespace) -> int:
    data: Path = args.data
    if data.is_dir():
        print(f"Real GelFabric data found at {data}.\n")
        print(format_summary(scan(data)))
        return 0
    print(f"No dataset at {data}; generating a small synthetic world in {args.out} ...\n")
    from lookfeel.synth import SynthConfig, generate

    generate(SynthConfig(fabrics=12, seed=0), args.out, progress=True)
    print(format_summary(scan(args.out)))
    return 0


def _cmd_train(args: argparse.Namespace) -> int:
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


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the ``lookfeel`` command."""
    parser = argparse.ArgumentParser(
        prog="lookfeel",
        description="Connect how fabrics look (colour, depth) with how they feel (GelSight).",
    )
    parser.add_argument("--version", action="version", version=f"lookfeel {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")

    data = sub.add_parser("data", help="inspect and check a dataset folder")
    data_sub = data.add_subparsers(dest="data_command", metavar="ACTION", required=True)
    info = data_sub.add_parser(
        "info",
        help="what a dataset holds: fabrics, items per modality and press kind, labels, clusters",
        description="Summarise a dataset in the lookfeel layout (see DATASET.md).",
    )
    info.add_argument("root", type=Path, help="dataset folder (depth/, color/, touch/, labels.csv)")
    info.add_argument("--json", action="store_true", help="print the summary as JSON")
    info.set_defaults(func=_cmd_data_info)

    check = data_sub.add_parser(
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
    check.add_argument(
        "--require",
        type=_modalities,
        default=None,
        metavar="MODALITIES",
        help="modalities every fabric must have, e.g. depth,touch "
        "(default: each modality any fabric has)",
    )
    check.add_argument("--strict", action="store_true", help="treat warnings as errors")
    check.add_argument("--json", action="store_true", help="print the report as JSON")
    check.add_argument("--workers", type=int, default=2, help="decoding threads (default 2)")
    check.set_defaults(func=_cmd_data_check)

    tr = sub.add_parser(
        "train",
        help="train a model from a config on a dataset",
        description=(
            "Train a run config (see configs/) on a dataset folder. Writes RUN/config.yaml, "
            "RUN/split.json, RUN/metrics.jsonl and RUN/checkpoints/{last,best}.pt. Runs on "
            "many processes under `torchrun --nproc_per_node N -m lookfeel train ...`."
        ),
    )
    tr.add_argument("--config", type=Path, required=True, help="run config YAML (configs/...)")
    tr.add_argument("--data", type=Path, required=True, help="dataset folder")
    tr.add_argument("--out", type=Path, required=True, help="run directory to write")
    tr.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override a config key, e.g. --set train.steps=100 (repeatable)",
    )
    tr.add_argument("--resume", action="store_true", help="continue the run in --out")
    tr.add_argument(
        "--pretrained",
        type=Path,
        default=None,
        help="local ImageNet weights file for the backbone (torchvision's AlexNet layout); "
        "never downloaded",
    )
    tr.set_defaults(func=_cmd_train)

    demo = sub.add_parser(
        "demo",
        help="run the main job on the embedded default",
        description="Summarise the real GelFabric data when present, else a synthetic world.",
    )
    demo.add_argument(
        "--data",
        type=Path,
        default=Path("../shared/data/gelfabric"),
        help="real data folder to use when present (default ../shared/data/gelfabric)",
    )
    demo.add_argument(
        "--out", type=Path, default=Path("demo-output/world"), help="where a synthetic world goes"
    )
    demo.set_defaults(func=_cmd_demo)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return 2
    from lookfeel.checkpoint import CheckpointError
    from lookfeel.config import ConfigError
    from lookfeel.models import PretrainedError

    try:
        status: int = args.func(args)
    except (DatasetError, ConfigError, CheckpointError, PretrainedError) as e:
        print(f"lookfeel: {e}", file=sys.stderr)
        return 1
    return status


if __name__ == "__main__":
    sys.exit(main())
