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
from lookfeel.data import Catalog, check_dataset, scan
from lookfeel.modality import Modality, PressKind, parse_modalities


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
    from lookfeel.demo import print_demo_result, run_demo

    result = run_demo(
        args.out, real_data=args.data, fabrics=args.fabrics, budget=args.budget, overrides=args.set
    )
    print_demo_result(result)
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


def _cmd_cv(args: argparse.Namespace) -> int:
    from lookfeel.config import RunConfig, load_config
    from lookfeel.crossval import cross_validate, format_summary

    overrides = list(args.set)
    if args.folds is not None:
        overrides.append(f"train.folds={args.folds}")
    if args.fold_size is not None:
        overrides.append(f"train.fold_size={args.fold_size}")
    config = load_config(RunConfig, args.config, overrides)
    summary = cross_validate(
        config,
        args.data,
        args.out,
        seeds=args.seeds,
        folds=args.only_folds,
        tta=args.tta,
        n_boot=args.n_boot,
    )
    print(format_summary(summary), end="")
    print(f"Wrote {args.out / 'cv.json'} and {args.out / 'cv.md'}")
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


def _cmd_index_build(args: argparse.Namespace) -> int:
    from lookfeel.index import LibraryError, build_library

    kinds = None
    if args.kinds:
        kinds = [PressKind(k.strip()) for k in args.kinds.split(",") if k.strip()]
    try:
        result = build_library(
            args.checkpoint,
            args.data,
            args.out,
            backend=args.backend,
            shard_size=args.shard_size,
            batch_size=args.batch_size,
            kinds=kinds,
            target_false_accept=args.false_accept,
            folds=args.folds,
            seed=args.seed,
            calibration_queries=args.calibration_queries,
            progress=not args.quiet,
        )
    except LibraryError as e:
        print(f"lookfeel: {e}", file=sys.stderr)
        return 1
    items = ", ".join(f"{n} {m.value}" for m, n in result.items.items())
    print(
        f"Library {result.root}: {items}; {result.shards_embedded} shard(s) embedded, "
        f"{result.shards_reused} reused; search {result.backend}; {result.seconds:.1f} s"
    )
    for key, p in result.calibration.pairs.items():
        print(
            f"  {key:<16} top1 {p.top1:.3f}  c {p.c:.4g}  unknown below P {p.threshold:.3g}: "
            f"false accept {p.false_accept:.3f}, true accept {p.true_accept:.3f}"
        )
    return 0


def _cmd_index_info(args: argparse.Namespace) -> int:
    from lookfeel.index import Library, LibraryError

    try:
        library = Library.open(args.library)
    except LibraryError as e:
        print(f"lookfeel: {e}", file=sys.stderr)
        return 1
    summary = library.summary()
    if args.json:
        print(json.dumps(summary, indent=2))
        return 0
    model = summary["model"]
    print(f"Library {library.root}")
    print(f"  checkpoint  {library.checkpoint} (step {model['step']})")
    print(
        f"  model       {model['backbone']} at {model['image_size']} px, D = {model['embed_dim']}"
    )
    print(f"  data        {summary['data_root']}")
    items = ", ".join(f"{n} {m}" for m, n in summary["items"].items())
    print(f"  items       {items}; {summary['fabrics']} fabrics; search {library.backend}")
    cal = library.calibration
    print(f"  calibration target false-accept {cal.target_false_accept:g}, {cal.folds} folds")
    for key, p in cal.pairs.items():
        print(
            f"    {key:<16} top1 {p.top1:.3f}  c {p.c:.4g}  threshold {p.threshold:.3g}  "
            f"false accept {p.false_accept:.3f}  true accept {p.true_accept:.3f}"
        )
    for note in cal.notes:
        print(f"    note: {note}")
    return 0


def _cmd_match(args: argparse.Namespace) -> int:
    import dataclasses

    from lookfeel.data import ImageError
    from lookfeel.index import Library, LibraryError, Matcher, format_match

    try:
        matcher = Matcher(Library.open(args.index, checkpoint=args.checkpoint))
        results = matcher.match_files(
            args.images, Modality(args.modality), top=args.top, gallery=args.gallery
        )
    except (LibraryError, ImageError) as e:
        print(f"lookfeel: {e}", file=sys.stderr)
        return 1
    if args.json:
        print(json.dumps([dataclasses.asdict(r) for r in results], indent=2))
    else:
        print("\n\n".join(format_match(r) for r in results))
    return 0


def _cmd_serve(args: argparse.Namespace) -> int:
    import torch

    from lookfeel.index import Library, LibraryError
    from lookfeel.serve import ServeConfig, create_app, serve

    # Queries run side by side, each on few threads: on a busy CPU one OpenMP team per query
    # beats several queries sharing two-thread teams that spin waiting for each other.
    torch.set_num_threads(args.threads)
    config = ServeConfig(
        max_upload_bytes=int(args.max_upload_mb * 1024 * 1024),
        max_concurrency=args.max_concurrency,
    )
    try:
        app = create_app(Library.open(args.index, checkpoint=args.checkpoint), config)
    except LibraryError as e:
        print(f"lookfeel: {e}", file=sys.stderr)
        return 1
    print(f"Serving {args.index} at http://{args.host}:{args.port}/ (Ctrl-C stops)")
    serve(app, host=args.host, port=args.port)
    return 0


def _cmd_export(args: argparse.Namespace) -> int:
    from lookfeel.export import export_onnx

    try:
        exported = export_onnx(args.checkpoint, args.out, opset=args.opset)
    except ValueError as e:
        print(f"lookfeel: {e}", file=sys.stderr)
        return 1
    for branch in exported:
        shape = "x".join(str(s) for s in branch.input_shape)
        check = (
            f"; max |onnx - torch| = {branch.max_abs_diff:.2g}"
            if branch.max_abs_diff is not None
            else ""
        )
        print(
            f"{branch.path}: {branch.input_name} ({shape}) -> embedding "
            f"(batch x {branch.embed_dim}){check}"
        )
    return 0


def _cmd_synth(args: argparse.Namespace) -> int:
    from lookfeel.synth import SIZE_PRESETS, SynthConfig, generate

    try:
        config = SynthConfig(
            **SIZE_PRESETS[args.size],
            fabrics=args.fabrics,
            drapes=args.drapes,
            presses_flat=args.presses_flat,
            presses_fold=args.presses_fold,
            frames=args.frames,
            seed=args.seed,
            workers=args.workers,
            image_format=args.format,
            modalities=args.modalities,
            contact_sheet=not args.no_contact_sheet,
        )
        summary = generate(
            config, args.out, labels=args.labels, progress=not args.quiet, beside=args.beside
        )
    except (ValueError, FileExistsError) as e:
        print(f"lookfeel synth: {e}", file=sys.stderr)
        return 2
    print(
        f"Wrote {summary.fabrics} fabrics to {summary.out} in {summary.seconds:.1f} s: "
        f"{summary.depth_images} depth, {summary.color_images} colour images, "
        f"{summary.touch_presses} touch presses ({summary.touch_frames} frames)."
    )
    if summary.contact_sheet is not None:
        print(f"Contact sheet: {summary.contact_sheet}")
    return 0


def _int_list(text: str) -> list[int]:
    """``"0,1,2"`` -> ``[0, 1, 2]`` (an argparse type)."""
    try:
        values = [int(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"{text!r} is not a comma-separated list of integers"
        ) from None
    if not values:
        raise argparse.ArgumentTypeError("an empty list")
    return values


def _add_set(parser: argparse.ArgumentParser, help: str) -> None:
    """The repeatable ``--set KEY=VALUE`` config override."""
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help=help)


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

    syn = sub.add_parser(
        "synth",
        help="generate a synthetic visuo-tactile fabric world in the dataset layout",
        description=(
            "Generate depth and colour images of fabrics draped over the post and GelSight press "
            "sequences (flat and on a fold) from physical fabric parameters, in the layout that "
            "`lookfeel data check` reads. With --labels, render exactly the fabrics of a "
            "labels.csv (ids kept) from their labels: by default colour and touch, to stand "
            "beside real depth images. The same seed gives byte-identical files. See docs/synth.md."
        ),
    )
    syn.add_argument(
        "out", type=Path, help="output folder (new, empty, or an earlier synth output)"
    )
    syn.add_argument("--fabrics", type=int, default=118, help="fabrics to sample (default 118)")
    syn.add_argument("--drapes", type=int, default=10, help="drapes per fabric (default 10)")
    syn.add_argument("--presses-flat", type=int, default=10, help="flat presses (default 10)")
    syn.add_argument("--presses-fold", type=int, default=15, help="fold presses (default 15)")
    syn.add_argument("--frames", type=int, default=3, help="frames per press (default 3)")
    syn.add_argument(
        "--size",
        choices=["tiny", "net", "full"],
        default="net",
        help="image sizes: net (depth 224, colour 256, touch 320x240), tiny, or full "
        "(touch 960x720 like the authors' sensor)",
    )
    syn.add_argument("--seed", type=int, default=0)
    syn.add_argument("--workers", type=int, default=0, help="processes (0: all cores)")
    syn.add_argument(
        "--labels", type=Path, default=None, help="label-conditioned mode: a labels.csv"
    )
    syn.add_argument(
        "--modalities",
        type=_modalities,
        default=None,
        help="what to render, e.g. depth,color,touch (default: all; with --labels: color,touch)",
    )
    syn.add_argument("--format", choices=["jpg", "png"], default="jpg", help="colour and touch")
    syn.add_argument("--no-contact-sheet", action="store_true", help="skip contact_sheet.png")
    syn.add_argument(
        "--beside",
        type=Path,
        default=None,
        metavar="ROOT",
        help="a dataset folder (e.g. the real GelFabric data, with --labels ROOT/labels.csv) "
        "whose depth images of the same fabrics open each row of the contact sheet",
    )
    syn.add_argument("--quiet", action="store_true", help="no progress bar")
    syn.set_defaults(func=_cmd_synth)

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
    _add_set(tr, "override a config key, e.g. --set train.steps=100 (repeatable)")
    tr.add_argument("--resume", action="store_true", help="continue the run in --out")
    tr.add_argument(
        "--pretrained",
        type=Path,
        default=None,
        help="local ImageNet weights file for the backbone (torchvision's AlexNet layout); "
        "never downloaded",
    )
    tr.set_defaults(func=_cmd_train)

    cv = sub.add_parser(
        "cv",
        help="cross-validate a config over fabric-disjoint folds, beside raw pixels and chance",
        description=(
            "Train a config on every fold of cluster-stratified, fabric-disjoint folds (and "
            "every seed), score each run's last checkpoint by pick 1 of 10 among the fabrics its "
            "fold held out, beside the raw-pixel nearest neighbour and chance, and predict the "
            "physical labels of held-out fabrics from their embeddings. Writes OUT/cv.json, "
            "OUT/cv.md and a run per fold and seed (OUT/seed{S}-fold{F}); a rerun keeps finished "
            "runs and resumes an interrupted one."
        ),
    )
    cv.add_argument("--config", type=Path, required=True, help="run config YAML (configs/...)")
    cv.add_argument("--data", type=Path, required=True, help="dataset folder")
    cv.add_argument("--out", type=Path, required=True, help="cross-validation folder to write")
    cv.add_argument(
        "--folds", type=int, default=None, help="number of folds (default: the config's)"
    )
    cv.add_argument(
        "--fold-size",
        type=int,
        default=None,
        help="fabrics per fold (default: the config's; 18 holds out test sets like the paper's)",
    )
    cv.add_argument(
        "--only-folds",
        type=_int_list,
        default=None,
        metavar="F,F",
        help="run only these folds, e.g. 0,1,2 (default: all)",
    )
    cv.add_argument(
        "--seeds", type=_int_list, default=[0], metavar="S,S", help="training seeds (default 0)"
    )
    cv.add_argument(
        "--tta",
        action="store_true",
        help="test-time pooling: average each image's embedding with its mirror image's",
    )
    cv.add_argument("--n-boot", type=int, default=1000, help="bootstrap resamples (default 1000)")
    _add_set(cv, "override a config key, e.g. --set train.steps=100 (repeatable)")
    cv.set_defaults(func=_cmd_cv)

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
    _add_set(rep, "override every run's config")
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
    _add_set(ev, "override an EvalConfig key, e.g. --set n_boot=200 (repeatable)")
    ev.add_argument(
        "--released-variant",
        action="store_true",
        help="also score the released code's sampled variant (own fabric may be a distractor)",
    )
    ev.add_argument("--batch-size", type=int, default=64, help="images per forward pass")
    ev.add_argument("--device", default="cpu", help="torch device (default cpu)")
    ev.set_defaults(func=_cmd_evaluate)

    index = sub.add_parser("index", help="build and inspect a fabric library (for match, serve)")
    index_sub = index.add_subparsers(dest="index_command", metavar="ACTION", required=True)
    ib = index_sub.add_parser(
        "build",
        help="embed every item of a dataset into a library, calibrated; resumable",
        description=(
            "Embed every item of every modality of DATA with the model of CHECKPOINT into the "
            "library folder OUT (shards, manifest; written atomically). A killed build continues "
            "when run again with the same arguments. Calibrates c of P ∝ exp(-c D²) and an "
            "'unknown' threshold on held-out fabrics (leave fabrics out)."
        ),
    )
    ib.add_argument("--checkpoint", type=Path, required=True, help="trained checkpoint (.pt)")
    ib.add_argument("--data", type=Path, required=True, help="dataset folder")
    ib.add_argument("--out", type=Path, required=True, help="library folder to write")
    ib.add_argument(
        "--backend",
        choices=("auto", "numpy", "faiss"),
        default="auto",
        help="search: exact numpy, faiss HNSW, or auto by size (default; faiss from 100,000 "
        "items in a modality)",
    )
    ib.add_argument("--shard-size", type=int, default=2048, help="items per shard (2048)")
    ib.add_argument("--batch-size", type=int, default=64, help="images per forward pass (64)")
    ib.add_argument(
        "--kinds", default=None, help="touch press kinds, e.g. fold,flat (default: the run's)"
    )
    ib.add_argument(
        "--false-accept",
        type=float,
        default=0.05,
        help="target rate of unknown materials accepted as a known fabric (0.05)",
    )
    ib.add_argument("--folds", type=int, default=5, help="leave-fabrics-out folds (5)")
    ib.add_argument("--seed", type=int, default=0, help="calibration seed (0)")
    ib.add_argument(
        "--calibration-queries",
        type=int,
        default=1000,
        help="held-out queries per modality pair (1000)",
    )
    ib.add_argument("--quiet", action="store_true", help="no line per shard")
    ib.set_defaults(func=_cmd_index_build)
    ii = index_sub.add_parser("info", help="what a library holds and how it is calibrated")
    ii.add_argument("library", type=Path, help="library folder")
    ii.add_argument("--json", action="store_true", help="print as JSON")
    ii.set_defaults(func=_cmd_index_info)

    mt = sub.add_parser(
        "match",
        help="which library fabric is this image, how does it look and feel, its properties",
        description=(
            "Rank the library's fabrics for query images of one modality: calibrated "
            "probabilities, each fabric's nearest items in every modality, predicted physical "
            "properties, and 'no known fabric' below the calibrated threshold. Several touch "
            "images are the presses of one query (pooled); depth and colour images are matched "
            "one by one."
        ),
    )
    mt.add_argument("images", type=Path, nargs="+", metavar="IMAGE", help="query image file(s)")
    mt.add_argument("--index", type=Path, required=True, help="library folder")
    mt.add_argument(
        "--modality", choices=[m.value for m in Modality], required=True, help="what they show"
    )
    mt.add_argument("--top", type=int, default=5, help="fabrics to list (5)")
    mt.add_argument(
        "--gallery",
        type=Modality,
        default=None,
        metavar="MODALITY",
        help="modality to match against (default: the best in calibration)",
    )
    mt.add_argument(
        "--checkpoint", type=Path, default=None, help="the library's checkpoint, if it moved"
    )
    mt.add_argument("--json", action="store_true", help="print the results as JSON")
    mt.set_defaults(func=_cmd_match)

    sv = sub.add_parser(
        "serve",
        help="web page and JSON API to match images against a library",
        description="Serve a page and a JSON API (OpenAPI at /openapi.json) over a library.",
    )
    sv.add_argument("--index", type=Path, required=True, help="library folder")
    sv.add_argument("--host", default="127.0.0.1", help="address (127.0.0.1: this machine only)")
    sv.add_argument("--port", type=int, default=8000, help="port (8000)")
    sv.add_argument("--max-upload-mb", type=float, default=8.0, help="largest upload (8 MB)")
    sv.add_argument(
        "--max-concurrency", type=int, default=2, help="queries the model runs at once (2)"
    )
    sv.add_argument("--threads", type=int, default=1, help="PyTorch threads per query (1)")
    sv.add_argument(
        "--checkpoint", type=Path, default=None, help="the library's checkpoint, if it moved"
    )
    sv.set_defaults(func=_cmd_serve)

    ex = sub.add_parser(
        "export",
        help="export each modality branch of a checkpoint (ONNX)",
        description=(
            "Write DIR/<modality>.onnx per branch (dynamic batch; touch with dynamic presses) "
            "and DIR/export.json, each checked against PyTorch under onnxruntime."
        ),
    )
    ex.add_argument("--checkpoint", type=Path, required=True, help="trained checkpoint (.pt)")
    ex.add_argument("--format", choices=("onnx",), default="onnx", help="export format (onnx)")
    ex.add_argument("--out", type=Path, required=True, help="output folder")
    ex.add_argument("--opset", type=int, default=17, help="ONNX opset (17)")
    ex.set_defaults(func=_cmd_export)

    demo = sub.add_parser(
        "demo",
        help="the whole system on a generated synthetic world, in minutes",
        description=(
            "Summarise the real GelFabric data when present, generate a small synthetic fabric "
            "world (or reuse a complete one), reproduce the paper's experiments on it at the "
            "tiny budget, and print the headline numbers and where the report is."
        ),
    )
    demo.add_argument(
        "--data",
        type=Path,
        default=Path("../shared/data/gelfabric"),
        help="real data to summarise first when present (default ../shared/data/gelfabric)",
    )
    demo.add_argument("--out", type=Path, default=Path("demo-output"), help="demo folder")
    demo.add_argument("--fabrics", type=int, default=36, help="fabrics in the synthetic world")
    demo.add_argument("--budget", choices=["tiny", "small"], default="tiny")
    _add_set(demo, "override every run's config")
    demo.set_defaults(func=_cmd_demo)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help()
        return 2
    from lookfeel.errors import LookfeelError

    try:
        status: int = args.func(args)
    except LookfeelError as e:
        print(f"lookfeel: {e}", file=sys.stderr)
        return 1
    return status


if __name__ == "__main__":
    sys.exit(main())
