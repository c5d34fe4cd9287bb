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


def _cmd_reproduce(args: argparse.Namespace) -> int:
    from lookfeel.reproduce import headline, reproduce

    result = reproduce(
        args.data,
        args.out,
        budget=args.budget,
        seeds=args.seeds,
        pretrained=args.pretrained,
        only=args.only or (),
        n_boot=args.n_boot,
        overrides=args.set,
    )
    print()
    for line in headline(result.results):
        print(line)
    for f in result.findings.values():
        print(f"{f['verdict']:>13}: {f['claim']}")
    print(f"\nReport: {result.report}")
    return 0


def _cmd_embed(args: argparse.Namespace) -> int:
    from lookfeel.evaluate import embed_checkpoint, save_embeddings

    emb = embed_checkpoint(
        args.checkpoint,
        args.data,
        args.split,
        reference=not args.no_reference,
        batch_size=args.batch_size,
        device=args.device,
    )
    path = save_embeddings(args.out, emb)
    counts = ", ".join(f"{m.value} {len(e.embeddings)}" for m, e in emb.embedded.items())
    print(f"Embedded {counts} ({emb.meta['split_description']}) into {path}")
    if emb.reference:
        ref = ", ".join(f"{m.value} {len(e.embeddings)}" for m, e in emb.reference.items())
        print(f"  with the reference (training) items: {ref}")
    return 0


def _cmd_evaluate(args: argparse.Namespace) -> int:
    from lookfeel.config import EvalConfig, load_config
    from lookfeel.evaluate import (
        EmbeddingFileError,
        evaluate_checkpoint,
        evaluate_embedding_file,
        write_report,
    )

    overrides = list(args.set)
    if args.released_variant:
        overrides.append("released_variant=true")
    config = load_config(EvalConfig, args.config, overrides)
    if args.checkpoint is not None:
        if args.data is None:
            print("lookfeel evaluate: --checkpoint needs --data", file=sys.stderr)
            return 2
        result = evaluate_checkpoint(
            args.checkpoint,
            args.data,
            args.split or "val",
            config,
            batch_size=args.batch_size,
            device=args.device,
        )
    else:
        if args.split is not None:
            print(
                "lookfeel evaluate: --split applies to --checkpoint; an embeddings file holds "
                "the split it was embedded with",
                file=sys.stderr,
            )
            return 2
        try:
            result = evaluate_embedding_file(args.embeddings, config, args.data)
        except EmbeddingFileError as e:
            print(f"lookfeel: {e}", file=sys.stderr)
            return 1
    files = write_report(result, args.out)
    k = result.config.ks[0]
    print(f"Evaluated {result.info.get('split_description', 'the embeddings')}:")
    for pair in result.pairs:
        m = result.metrics
        v, lo, hi = (m.get(f"{pair}_top{k}{s}", float("nan")) for s in ("", "_ci_low", "_ci_high"))
        chance = m.get(f"{pair}_top{k}_chance", float("nan"))
        print(f"  {pair:<16} top-{k} {v:.3f} [{lo:.3f}, {hi:.3f}]  chance {chance:.3f}")
    print(f"Wrote {files.metrics}, {files.report} and {len(files.figures)} figures")
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

    rep = sub.add_parser(
        "reproduce",
        help="run every experiment of the paper and report ours beside its numbers",
        description=(
            "Train and evaluate the paper's experiments (Figure 5, Tables 1-4) on a dataset and "
            "write DIR/report.md and DIR/results.json. Budgets: tiny (seconds per run), small "
            "(minutes per run, compact CNN at 64 px), paper (the paper's AlexNet configs; needs "
            "--pretrained). Runs whose modalities the data lacks are skipped with the reason. "
            "Re-running resumes finished runs."
        ),
    )
    rep.add_argument("--data", type=Path, required=True, help="dataset folder")
    rep.add_argument("--out", type=Path, required=True, help="output folder")
    rep.add_argument("--budget", choices=["tiny", "small", "paper"], default="small")
    rep.add_argument("--seeds", type=int, default=1, help="training seeds per experiment")
    rep.add_argument("--pretrained", type=Path, default=None, help="ImageNet AlexNet weights")
    rep.add_argument("--only", nargs="*", default=None, metavar="NAME", help="experiments to run")
    rep.add_argument("--n-boot", type=int, default=1000, help="bootstrap resamples")
    rep.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override every run's config",
    )
    rep.set_defaults(func=_cmd_reproduce)

    emb = sub.add_parser(
        "embed",
        help="embed a dataset's items with a trained checkpoint into an .npz file",
        description=(
            "Embed the items of a dataset with a checkpoint's model and write FILE.npz: "
            "embeddings_<modality> (N, D), fabric_id_<modality> (N,), path_<modality> (N,) "
            "(touch: one row per press), and for --split val/novel/paper the reference "
            "(training) items as reference_* arrays, so `lookfeel evaluate --embeddings` can "
            "fit c and the property probes from the file alone."
        ),
    )
    emb.add_argument("--checkpoint", type=Path, required=True, help="a run's checkpoint (.pt)")
    emb.add_argument("--data", type=Path, required=True, help="dataset folder")
    emb.add_argument("--out", type=Path, required=True, help="the .npz file to write")
    emb.add_argument(
        "--split",
        choices=["val", "train", "novel", "paper", "all"],
        default="all",
        help="which items: the run's held-out (val) or training (train) items, a seen run's "
        "novel fabrics, the paper's test fabrics, or all (default)",
    )
    emb.add_argument(
        "--no-reference", action="store_true", help="do not embed the reference (training) items"
    )
    emb.add_argument("--batch-size", type=int, default=64, help="images per forward pass")
    emb.add_argument("--device", default="cpu", help="torch device (default cpu)")
    emb.set_defaults(func=_cmd_embed)

    ev = sub.add_parser(
        "evaluate",
        help="score a checkpoint or an embeddings file: metrics.json, report.md, figures",
        description=(
            "Score every modality pair by the paper's pick 1 of 10 (exact and sampled), mAP, "
            "recall@k and median rank, with chance levels and bootstrap intervals over test "
            "fabrics; multi-press touch queries; calibration of P ~ exp(-c D^2) with confusion "
            "matrices; physical-property probes. Writes OUT/metrics.json, OUT/report.md and "
            "OUT/figures/*.png. --split: val (default) the run's held-out items, c and probes "
            "fitted on its training items; train; novel (a seen run's held-out fabrics); paper "
            "(the paper's 18 test fabrics); all."
        ),
    )
    src = ev.add_mutually_exclusive_group(required=True)
    src.add_argument("--checkpoint", type=Path, help="a run's checkpoint (.pt); needs --data")
    src.add_argument("--embeddings", type=Path, help="an .npz written by `lookfeel embed`")
    ev.add_argument(
        "--data",
        type=Path,
        default=None,
        help="dataset folder (with --embeddings: optional, for clusters, labels and images)",
    )
    ev.add_argument("--out", type=Path, required=True, help="folder for the report")
    ev.add_argument(
        "--split",
        choices=["val", "train", "novel", "paper", "all"],
        default=None,
        help="with --checkpoint: which items are the test set (default val)",
    )
    ev.add_argument("--config", type=Path, default=None, help="evaluation config YAML (EvalConfig)")
    ev.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override an EvalConfig key, e.g. --set n_boot=200 (repeatable)",
    )
    ev.add_argument(
        "--released-variant",
        action="store_true",
        help="also score the released code's sampled variant (own fabric may be a distractor)",
    )
    ev.add_argument("--batch-size", type=int, default=64, help="images per forward pass")
    ev.add_argument("--device", default="cpu", help="torch device (default cpu)")
    ev.set_defaults(func=_cmd_evaluate)

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
