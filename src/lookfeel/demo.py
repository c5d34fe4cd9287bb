"""The demo that ``make demo`` runs: the whole system on the embedded default, in minutes.

1. Summarise the real GelFabric data when it is present (``../shared/data/gelfabric``).
2. Generate a small synthetic fabric world (depth, colour, GelSight touch), or reuse the one a
   previous demo left complete.
3. Reproduce the paper's experiments on it at the ``tiny`` budget: train the Flat,
   Cross-modal, Auxiliary and Multi-input nets, the colour-augmentation variants and Table 4's
   pair, evaluate each on held-out fabrics, and write the report beside the paper's numbers.
4. Evaluate the Multi-input Net in full: calibration, confusion matrices, pick examples.

Every long step shows that it is alive: each step's line says which of the four it is and the
minutes so far, the world's rendering and every training run show a progress bar on stderr
(``train.progress=true``, which a ``--set train.progress=false`` turns off), and each
reproduction run prints a line as it starts.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from lookfeel.config import EvalConfig
from lookfeel.data import scan
from lookfeel.data.summary import format_summary
from lookfeel.evaluate import evaluate_checkpoint, write_report
from lookfeel.reproduce import BUDGETS, ReproduceResult, headline, reproduce
from lookfeel.synth import SynthConfig, generate
from lookfeel.synth.world import GENERATOR_VERSION, MANIFEST

__all__ = ["DEMO_BUDGETS", "DemoResult", "print_demo_result", "run_demo"]

DEMO_BUDGETS = tuple(b for b in BUDGETS if b != "paper")
"""The reproduction budgets the demo offers: ``paper`` needs ImageNet weights the demo never has."""


@dataclass(frozen=True)
class DemoResult:
    """Where the demo put things, and how long it took."""

    world: Path
    reproduction: ReproduceResult
    evaluation: Path | None
    """The full evaluation report (figures included) of the Multi-input Net, when it ran."""
    seconds: float


def _complete_world(path: Path, config: SynthConfig) -> bool:
    """Whether ``path`` holds a finished synthetic world made with ``config`` by this version
    of the generator."""
    try:
        manifest = json.loads((path / MANIFEST).read_text())
    except (OSError, ValueError):
        return False
    wanted = {k: v for k, v in config.to_dict().items() if k != "workers"}
    return bool(
        manifest.get("status") == "complete"
        and manifest.get("version") == GENERATOR_VERSION
        and manifest.get("config") == wanted
    )


def run_demo(
    out: Path,
    real_data: Path | None = None,
    fabrics: int = 36,
    budget: str = "tiny",
    seed: int = 0,
    overrides: Sequence[str] = (),
    log: Callable[[str], None] = print,
) -> DemoResult:
    """Run the demo; see the module docstring.

    Args:
        out: demo folder (``world/`` and ``reproduce/`` go inside; re-runs reuse them).
        real_data: a real dataset to summarise first, when it exists.
        fabrics: fabrics in the synthetic world (36: its own test share aside, 10 fabrics are
            held out, enough for a true pick 1 of 10).
        budget: the reproduction budget (``tiny`` for minutes on 2 cores).
        seed: seed of the world.
        overrides: ``key=value`` overrides of every training run.
        log: where progress lines go.
    """
    started = time.perf_counter()

    def step(k: int, text: str) -> None:
        log(f"[{k}/4, {(time.perf_counter() - started) / 60:.1f} min] {text}")

    if real_data is not None and real_data.is_dir():
        step(1, f"Real GelFabric data at {real_data}:")
        log(format_summary(scan(real_data)))
        log("")
    world = out / "world"
    config = SynthConfig(fabrics=fabrics, seed=seed, workers=2)
    if _complete_world(world, config):
        step(2, f"Reusing the synthetic world in {world}.")
    else:
        step(2, f"Generating a synthetic world of {fabrics} fabrics in {world} ...")
        generate(config, world, progress=True)
    log(format_summary(scan(world)))
    log("")
    step(3, f"Reproducing the paper's experiments (budget {budget}) in {out / 'reproduce'} ...")
    result = reproduce(
        world,
        out / "reproduce",
        budget=budget,
        seeds=1,
        n_boot=500,
        overrides=["train.progress=true", *overrides],  # a bar per run; the user's come last
        log=log,
    )
    report = None
    run = out / "reproduce" / "runs" / "multi_input" / "seed0" / "checkpoints" / "last.pt"
    if run.exists():
        step(
            4, "Evaluating the Multi-input Net in full (calibration, confusion, pick examples) ..."
        )
        evaluated = evaluate_checkpoint(run, world, split="val", config=EvalConfig(n_boot=500))
        report = write_report(evaluated, out / "evaluate").report
    return DemoResult(world, result, report, time.perf_counter() - started)


def print_demo_result(result: DemoResult, log: Callable[[str], None] = print) -> None:
    """The headline numbers and where everything is."""
    log("")
    log("Headline (pick 1 of 10 on held-out fabrics of the synthetic world):")
    for line in headline(result.reproduction.results):
        log(f"  {line}")
    log("Findings of the paper, checked here:")
    for f in result.reproduction.findings.values():
        log(f"  {f['verdict']:>13}: {f['claim']}")
    log("")
    log(f"Report:        {result.reproduction.report}")
    if result.evaluation is not None:
        log(f"Evaluation:    {result.evaluation} (figures beside it)")
        glance = result.evaluation.parent / "figures" / "glance.png"
        if glance.exists():
            log(f"At a glance:   {glance} (touch queries, their nearest drapes and photos)")
    log(f"Contact sheet: {result.world / 'contact_sheet.png'}")
    log(f"Done in {result.seconds / 60:.1f} min.")
