"""The demo's cross-modal run (steps 4 and 5 of `make demo`) trained at several seeds and, on
CUDA, in both precisions, on the demo's world: how far each pair of senses moves with the seed
alone, and whether bf16 autocast (``model.precision=auto``, CUDA's default) moves it against
full fp32 (``model.precision=fp32``, what a CPU computes).

`make demo` trains seed 0 once; its 50 held-out fabrics leave each pair an interval about 0.09
wide (18, before session 46: about 0.15), and this says how much of a difference between two
machines is the seed's chance.

    python -m benchmarks.bench_demo_seeds [--seeds 0,1,2] [--precision auto,fp32] \\
        [--world DIR | --fabrics 150 --world-seed 0] [--set KEY=VALUE ...] \\
        [--out benchmarks/results/demo_seeds.json]

Without ``--world`` it renders the demo's world (`lookfeel.demo.demo_world`: 150 fabrics,
seed 0, the same files as `make demo`'s) in a temporary folder, or one of its kind with
``--fabrics`` fabrics and seed ``--world-seed`` (the world holds out a third of its fabrics,
`lookfeel.demo.demo_test_fabrics`: 50 of 150). On a CPU both precisions are
fp32 and train the same weights, so ``--precision`` matters only on CUDA. ``--set`` changes the
demo's run for a screen (``--set train.lr=0.002``, repeatable, after the demo's own overrides);
the result records them. About 1 minute a run on 2 cores (AMD EPYC), 40 s on one H200.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path
from typing import cast, get_args

from benchmarks.__main__ import add_set_option, write_standalone
from benchmarks.bench_demo import demo_pairs
from lookfeel.config import ConfigError, EvalConfig
from lookfeel.config.model import Precision
from lookfeel.demo import DEMO_FABRICS, cross_config, demo_test_fabrics, demo_world
from lookfeel.evaluate import evaluate_checkpoint
from lookfeel.synth import generate
from lookfeel.train import train

WORLD_FIELDS = ("fabrics", "test_fabrics", "seed", "drapes", "presses_flat", "presses_fold")
"""What the result records of a world it rendered."""


def measure(
    world: Path,
    seeds: Sequence[int],
    precisions: Sequence[str],
    work: Path,
    overrides: Sequence[str] = (),
    n_boot: int = 500,
) -> dict[str, object]:
    """Train and evaluate the demo's cross-modal run for every precision and seed.

    Args:
        world: the dataset (the demo's world, or any with depth, colour and touch).
        seeds: ``train.seed`` of each run.
        precisions: ``model.precision`` of each run (``auto``, ``fp32``).
        work: where the runs go.
        overrides: more ``key=value`` overrides, after the demo's own (tests shrink the run).
        n_boot: bootstrap resamples of each interval (the demo's 500).

    Returns:
        ``runs`` (each run's pairs as `bench_demo` records them, and its seconds) and
        ``summary``: per precision, each pair's top-1 through the map, mean and range over the
        seeds, and the mean of all pairs.
    """
    runs: list[dict[str, object]] = []
    for precision in precisions:
        for seed in seeds:
            config = cross_config(
                [
                    "train.progress=false",
                    f"train.seed={seed}",
                    f"model.precision={precision}",
                    *overrides,
                ]
            )
            started = time.perf_counter()
            trained = train(config, world, work / f"{precision}-seed{seed}")
            trained_s = time.perf_counter() - started
            result = evaluate_checkpoint(
                trained.last_checkpoint, world, split="val", config=EvalConfig(n_boot=n_boot)
            )
            runs.append(
                {
                    "precision": precision,
                    "seed": seed,
                    "train_s": round(trained_s, 1),
                    "evaluate_s": round(time.perf_counter() - started - trained_s, 1),
                    "pairs": demo_pairs(result.metrics),
                }
            )
    return {"runs": runs, "summary": summarise(runs)}


def summarise(runs: Sequence[dict[str, object]]) -> dict[str, dict[str, object]]:
    """Per precision: each pair's top-1 through the map over the seeds (mean, lowest,
    highest), the mean of all pairs, and the lowest interval bound of any pair."""
    out: dict[str, dict[str, object]] = {}
    for precision in dict.fromkeys(str(r["precision"]) for r in runs):
        mine = [
            cast(dict[str, dict[str, float]], r["pairs"])
            for r in runs
            if r["precision"] == precision
        ]
        pairs: dict[str, dict[str, float]] = {}
        for pair in mine[0]:
            values = [p[pair]["mapped"] for p in mine]
            pairs[pair] = {
                "mean": round(statistics.mean(values), 4),
                "low": round(min(values), 4),
                "high": round(max(values), 4),
            }
        out[precision] = {
            "seeds": len(mine),
            "pairs": pairs,
            "mean_of_pairs": round(statistics.mean(v["mean"] for v in pairs.values()), 4),
        }
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m benchmarks.bench_demo_seeds", description=__doc__.splitlines()[0]
    )
    ap.add_argument("--seeds", default="0,1,2", help="training seeds, comma-separated")
    ap.add_argument("--precision", default="auto", help="model.precision values: auto,fp32")
    ap.add_argument("--world", type=Path, default=None, help="the demo's world, if rendered")
    ap.add_argument(
        "--fabrics", type=int, default=DEMO_FABRICS, help="fabrics of the world to render"
    )
    ap.add_argument("--world-seed", type=int, default=0, help="seed of the world to render")
    add_set_option(ap, "train.lr=0.002")
    ap.add_argument("--out", type=Path, default=None, help="write the JSON here")
    args = ap.parse_args(argv)
    try:
        seeds = [int(s) for s in args.seeds.split(",")]
    except ValueError:
        ap.error(f"--seeds: integers separated by commas, got {args.seeds!r}")
    precisions = [p.strip() for p in args.precision.split(",")]
    if bad := [p for p in precisions if p not in get_args(Precision)]:
        ap.error(f"--precision: one of {', '.join(get_args(Precision))}, got {', '.join(bad)}")
    if args.world is not None and not args.world.is_dir():
        ap.error(f"--world: {args.world} is not a folder")
    if demo_test_fabrics(args.fabrics) < 10:
        ap.error(
            f"--fabrics: at least 29, so that a third, 10, are held out to pick 1 of 10; got "
            f"{args.fabrics}"
        )
    try:
        cross_config(args.overrides)
    except ConfigError as e:
        ap.error(f"--set: {e}")
    started = time.time()
    made = demo_world(args.fabrics, args.world_seed)
    with tempfile.TemporaryDirectory(prefix="bench_demo_seeds_") as tmp:
        world = args.world
        if world is None:
            world = Path(tmp) / "world"
            generate(made, world, progress=True)
        result = measure(world, seeds, precisions, Path(tmp) / "runs", args.overrides)
    result["world"] = (
        str(args.world) if args.world is not None else {k: getattr(made, k) for k in WORLD_FIELDS}
    )
    result["overrides"] = list(args.overrides)
    return write_standalone("demo_seeds", started, result, args.out)


if __name__ == "__main__":
    sys.exit(main())
