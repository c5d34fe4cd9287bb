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
import json
import os
import warnings
from collections.abc import Mapping, Sequence
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
    from lookfeel.config import RunConfig
    from lookfeel.config._core import Override
    from lookfeel.data.catalog import Catalog

__all__ = ["RUN_FILES", "add_parser", "check_senses", "run", "validation_header"]


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


RUN_FILES = ("split.json", "checkpoints", "members", "metrics.jsonl")
"""What a run folder holds (an ensemble's members first): an existing, non-empty --out must
hold one (a run to resume, or one ``train`` then refuses to write over without --resume). Not
``config.yaml`` alone, which a run writes with ``split.json`` beside it: a folder of the
user's own ``config.yaml`` (their --config, with its comments) is not a run to write into."""


def run(args: argparse.Namespace) -> int:
    """Train, then print where the run is and its validation numbers."""
    check_out_folder(args.out, args.data, RUN_FILES, "a lookfeel run")  # before any work
    from lookfeel.config import ConfigError, RunConfig, load_config
    from lookfeel.models import BACKBONES
    from lookfeel.train import train

    saved = args.out / "config.yaml"
    chosen = False  # whether the recipe was chosen for what --data holds
    if args.config is None and args.resume and saved.is_file():
        path, overrides = saved, list(args.set)  # a resumed run keeps its own recipe
    else:
        path, overrides = run_config_source(args)
        chosen = args.config is None
    given: list[str | Override] = [*overrides]
    if args.pretrained is not None:
        given.append(path_flag("model.pretrained", "--pretrained", args.pretrained))
    try:
        config = load_config(RunConfig, path, given)
    except ConfigError as e:
        # A run trained with a plugin this process lacks: name it, as evaluate does.
        hint = _trained_with(args.out) if args.resume else ""
        if not hint:
            raise
        raise ConfigError(f"{e}{hint}") from None
    # As `train` does first: images smaller than the backbone takes, before any data is read.
    config.check_input_sizes(BACKBONES[config.model.backbone].min_size)
    check_senses(config, args.data, chosen=chosen)
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
    if keys:
        n = _held_out_fabrics(val, result.run_dir)
        print(validation_header(n, config.train.split, config.data.presses, sorted(keys)))
    for pair in sorted(keys):
        key, v = f"{pair}_top1", val.get(f"{pair}_top1")
        if not isinstance(v, float):  # a pair with no query to score: why, never NaN
            print(f"  val {key:<24} not scored: {val.get(f'{pair}_not_scored', 'no query')}")
            continue
        chance = val.get(f"{pair}_chance")
        notes = [f"chance {chance:.3f}"] if isinstance(chance, float) and chance else []
        fabrics = val.get(f"{pair}_fabrics")
        if isinstance(fabrics, int) and n is not None and fabrics != n:
            notes.append(f"queries from {fabrics} of the {n} fabrics")
        shown = f"  ({'; '.join(notes)})" if notes else ""
        print(f"  val {key:<24} {v:.3f}{shown}")
    return 0


def _trained_with(out: Path) -> str:
    """`lookfeel.plugins.trained_with_hint` of the run in ``out``: the plugin modules its
    checkpoint records (an ensemble's: its first started member's) that this process has not
    loaded; ``""`` where there are none, or no checkpoint to read them from."""
    from lookfeel.checkpoint import CheckpointError, read_checkpoint
    from lookfeel.plugins import trained_with_hint
    from lookfeel.train.loop import MEMBERS, resume_checkpoint

    for folder in [out, *sorted((out / MEMBERS).glob("*"))]:
        source = resume_checkpoint(folder)
        if source is not None:
            try:
                return trained_with_hint(read_checkpoint(source).get("plugins") or ())
            except CheckpointError:
                return ""
    return ""


def _held_out_fabrics(val: Mapping[str, object], run_dir: Path) -> int | None:
    """How many fabrics the validation's queries came from: the most of any pair
    (``{pair}_fabrics``, `lookfeel.train.validate.validate`), else the fabrics the run's
    split.json names as validating, else None."""
    counts = [v for k, v in val.items() if k.endswith("_fabrics") and isinstance(v, int)]
    if counts:
        return max(counts)
    try:
        held = json.loads((run_dir / "split.json").read_text(encoding="utf-8")).get("val")
    except (OSError, ValueError, AttributeError):
        return None
    return len(held) if isinstance(held, list) and held else None


def validation_header(n: int | None, split: str, presses: int, pairs: Sequence[str]) -> str:
    """The line above ``train``'s validation numbers: what they were measured on (``n``
    fabrics, held out, or for ``split`` ``seen`` the held-out items of training fabrics), that
    each query is one item (a touch query one press, where a pair's query is touch), and how
    `lookfeel evaluate` of the checkpoint differs (it pools ``presses`` presses a touch query,
    the run's ``data.presses``, and gives intervals)."""
    noun = "fabric" if n == 1 else "fabrics"
    if split == "seen":
        what = f"the held-out items of {n} training {noun}" if n else "held-out items"
    else:
        what = f"{n} held-out {noun}" if n else "held-out fabrics"
    touch = any(p.startswith("touch_to_") for p in pairs)
    if touch and presses > 1:
        how = (
            f"one press a touch query; `lookfeel evaluate` pools {presses} presses a query, "
            "the run's data.presses, and gives intervals"
        )
    elif touch:
        how = "one press a touch query; `lookfeel evaluate` gives intervals"
    else:
        how = "one image a query; `lookfeel evaluate` gives intervals"
    return f"  validation on {what} ({how}):"


def check_senses(config: RunConfig, data: Path, *, chosen: bool) -> None:
    """What to say of ``data`` before a run of ``config`` trains on it, once (rank 0 under
    torchrun):

    - a sense whose files the scan read none of (every one skipped or unreadable,
      `lookfeel.config.recipes.unread_senses`): an error in one line where the run's
      ``train.views`` use it, else, where the recipe was ``chosen`` for what the folder holds
      (no --config), a warning that the run goes without it;
    - a config the data cannot serve (`_check_fits`): a modality of ``train.views`` it holds
      no item of, no touch press of ``data.touch_kinds``, a class head labels.csv cannot give;
    - raw depth that lies mostly outside the range the run maps it from (its own
      ``data.depth_min_mm`` and ``data.depth_range_mm``): a warning in one line with a range
      that holds it (`_say_depth_range`).

    Raises:
        DatasetError: a sense the run uses has no readable file, or no item; no press of the
            run's kinds.
        ConfigError: a class head labels.csv cannot give.
    """
    from lookfeel.config.recipes import unread_senses
    from lookfeel.data.layout import scan
    from lookfeel.data.problems import DatasetError, Problem

    catalog = scan(data)  # the headers checked, as the run's own scan does
    used = set(config.train.modalities)
    says = int(os.environ.get("RANK", "0")) == 0
    for sense in unread_senses(catalog):
        m = sense.modality.value
        if sense.modality in used:
            how = (
                f"move {sense.folder.name}/ aside to train without {m}"
                if chosen
                else f"leave {m} out of train.views"
            )
            raise DatasetError(
                [
                    Problem(
                        sense.folder,
                        f"the run's train.views use {m}, but {sense.why}: convert them (see "
                        f"`lookfeel data check {data}`), or {how}",
                    )
                ]
            )
        if chosen and says:
            warnings.warn(
                f"{sense.folder}: {sense.why}, so this run trains without {m} (see "
                f"`lookfeel data check {data}`)",
                stacklevel=2,
            )
    _check_fits(config, catalog)
    if says:
        _say_depth_range(config, catalog)


def _check_fits(config: RunConfig, catalog: Catalog) -> None:
    """Refuse, before the run decodes anything, a config the data cannot serve, each reason in
    one line with the ``--set`` that fits it: modalities of ``train.views`` the data holds no
    item of (`lookfeel.train.loop.views_problem`), touch presses none of which is of the run's
    ``data.touch_kinds`` (`lookfeel.data.catalog.Catalog.lacking`), class heads
    (``model.class_heads``) that labels.csv cannot give (`lookfeel.train.loop.resolve_classes`).

    Raises:
        DatasetError: the views or press kinds (both, where both are wrong).
        ConfigError: a class head.
    """
    from lookfeel.data.problems import DatasetError
    from lookfeel.modality import Modality
    from lookfeel.train.loop import resolve_classes, views_problem

    problems = [p for p in [views_problem(catalog, config)] if p is not None]
    touch, kinds = Modality.TOUCH, config.data.touch_kinds
    # No press of the run's kinds in the whole dataset (fewer fabrics lacking them may all
    # validate: the training split's own check, in `TupleDataset`, decides).
    if (
        touch in config.train.modalities
        and catalog.items(touch)
        and not catalog.items(touch, kinds)
    ):
        problems += catalog.lacking([touch], kinds)
    if problems:
        raise DatasetError(problems, catalog.root)
    resolve_classes(catalog, config)


def _say_depth_range(config: RunConfig, catalog: Catalog) -> None:
    """Warn, in one line, where fewer than `lookfeel.data.check.MIN_IN_RANGE` of the valid
    pixels of a sample of the depth maps (`lookfeel.config.recipes.depth_samples`) lie inside
    the range this run maps raw depth from (``data.depth_min_mm`` to ``+ data.depth_range_mm``,
    the defaults or the user's): the rest become 0 or 1, so the network sees an almost constant
    image. The warning names the range that covers the sample's 2nd to 98th percentile (the
    one a recipe chosen for the data maps from). Registered depth is left alone."""
    from lookfeel.config.recipes import covering_depth_range, depth_in_range, depth_samples
    from lookfeel.data.check import MIN_IN_RANGE
    from lookfeel.modality import Modality

    c = config.data
    if Modality.DEPTH not in config.train.modalities or c.depth_input != "raw":
        return
    samples = depth_samples(catalog)
    low, high = c.depth_min_mm, c.depth_min_mm + c.depth_range_mm
    if not samples or (share := depth_in_range(samples, low, high)) >= MIN_IN_RANGE:
        return
    start, width, median = covering_depth_range(samples)
    maps = f"{len(samples)} depth map{'s' if len(samples) != 1 else ''}"
    warnings.warn(
        f"{catalog.root / Modality.DEPTH.value}: only {share:.0%} of the valid depth pixels (a "
        f"sample of {maps}) lie between {low:,.0f} and {high:,.0f} mm, the range this run maps "
        f"raw depth from to 0..1 (data.depth_min_mm {low:g}, data.depth_range_mm "
        f"{c.depth_range_mm:g}): the rest become 0 or 1, so the network sees an almost constant "
        f"image; the depth maps' median is {median:,.0f} mm: set data.depth_min_mm={start} and "
        f"data.depth_range_mm={width} (their 2nd-98th percentile) so the cloth lies inside "
        "(data.depth_input: registered maps heights above the floor instead)",
        stacklevel=3,
    )
