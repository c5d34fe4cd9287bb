"""Fidelity of the synthetic drapes: a depth encoder trained only on synthetic depth, scored on
real GelFabric depth (issue #3's target: it beats the raw-pixel nearest neighbour).

Generates a synthetic depth-only world, trains `configs/real_depth.yaml`'s recipe on all of it
(no real image is seen), and scores pick 1 of 10 among the 100 real training fabrics, beside
raw pixels and chance, with 95% intervals that resample the real fabrics, and the background
control (each real image's background swapped with another fabric's, cloth kept). Since issue
#12 the recipe trains on registered depth (`data.depth_input: registered`): the synthetic
world's room registers as the real one does (floor, wall, side panel), so both worlds are
seen as the cloth's height above the fitted floor. One network (`model.members=1`): the recipe
has trained three used as one since session 32, which triples the training and is a gain on
real depth; this benchmark asks what synthetic drapes teach, so it keeps the single network
every stored result was measured with; ``python -m benchmarks.bench_synth_fidelity --data
DIR --members 3 --out FILE`` trains the recipe's three (``--keep DIR`` keeps the world and the
run, to score again; ``--set KEY=VALUE`` changes the recipe). Needs --data.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from benchmarks.__main__ import add_set_option, write_standalone
from lookfeel.config import ConfigError, RunConfig, load_config
from lookfeel.crossval import score_checkpoint
from lookfeel.modality import Modality
from lookfeel.synth import SynthConfig, generate
from lookfeel.train import train

CONFIG = Path(__file__).resolve().parents[1] / "configs" / "real_depth.yaml"
FABRICS = 300
DRAPES = 10
MEMBERS = 1


def run(
    data: Path | None,
    members: int = MEMBERS,
    keep: Path | None = None,
    overrides: Sequence[str] = (),
) -> dict[str, Any]:
    """Render the world, train on it, score on ``data``; ``members`` networks used as one
    (the recipe's own is 3); ``keep``: a folder to keep the world and the run in (new or
    empty), else a temporary one; ``overrides``: ``key=value`` changes of the recipe, after
    the benchmark's own."""
    if data is None:
        return {"skipped": "needs the real GelFabric depth (--data)"}
    with tempfile.TemporaryDirectory() as tmp:
        work = keep if keep is not None else Path(tmp)
        world = work / "world"
        started = time.perf_counter()
        generate(
            SynthConfig(fabrics=FABRICS, drapes=DRAPES, modalities=(Modality.DEPTH,), seed=1),
            world,
            progress=False,
        )
        synth_s = time.perf_counter() - started
        own = ["train.split=none", "train.progress=false", f"model.members={members}"]
        config = load_config(RunConfig, CONFIG, [*own, *overrides])
        started = time.perf_counter()
        result = train(config, world, work / "run")
        train_s = time.perf_counter() - started
        scored = score_checkpoint(result.last_checkpoint, data, pairs=["depth_to_depth"])
    pair = scored["pairs"]["depth_to_depth"]
    model, raw = pair["model_top1"], pair["raw_pixels_top1"]
    return {
        "what": "pick 1 of 10 on real depth (100 fabrics) by an encoder trained on synthetic "
        "depth only",
        "world": {"fabrics": FABRICS, "drapes": DRAPES, "seconds": round(synth_s, 1)},
        "config": str(CONFIG.name),
        "members": members,
        "overrides": list(overrides),
        "train_seconds": round(train_s, 1),
        "model_top1": model["mean"],
        "model_top1_ci95": model["ci95"],
        "model_top3": pair["model_top3"]["mean"],
        "raw_pixels_top1": raw["mean"],
        "raw_pixels_top1_ci95": raw["ci95"],
        "raw_pixels_top3": pair["raw_pixels_top3"]["mean"],
        "depth_input": config.data.depth_input,
        "model_top1_background_swapped": pair.get("model_swapped_top1", {}).get("mean"),
        "raw_pixels_top1_background_swapped": pair.get("raw_pixels_swapped_top1", {}).get("mean"),
        "chance_top1": pair["chance_top1"],
        "target": "model top-1 > raw-pixel top-1",
        "met": model["mean"] > raw["mean"],
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m benchmarks.bench_synth_fidelity", description=__doc__.splitlines()[0]
    )
    ap.add_argument("--data", type=Path, required=True, help="the real GelFabric root")
    ap.add_argument(
        "--members", type=int, default=MEMBERS, help=f"networks used as one (default {MEMBERS})"
    )
    ap.add_argument("--keep", type=Path, default=None, help="keep the world and the run here")
    add_set_option(ap, "train.steps=1200")
    ap.add_argument("--out", type=Path, default=None, help="write the JSON here")
    args = ap.parse_args(argv)
    if not args.data.is_dir():
        ap.error(f"--data: {args.data} is not a folder")
    if args.members < 1:
        ap.error(f"--members: at least 1, got {args.members}")
    if args.keep is not None and args.keep.exists() and any(args.keep.iterdir()):
        ap.error(f"--keep: {args.keep} is not empty")
    try:
        load_config(RunConfig, CONFIG, args.overrides)
    except ConfigError as e:
        ap.error(f"--set: {e}")
    started = time.time()
    result = run(args.data, args.members, args.keep, args.overrides)
    return write_standalone("synth_fidelity", started, result, args.out)


if __name__ == "__main__":
    sys.exit(main())
