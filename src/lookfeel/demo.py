"""The demo that ``make demo`` runs: the whole system on the embedded default, in minutes.

1. Summarise the real GelFabric data when it is present (``../shared/data/gelfabric``).
2. Generate a synthetic fabric world of 150 fabrics, 100 to train on as in the paper and 50
   held out (the paper held out 18), with fewer images of each than ``lookfeel synth`` makes by
   default (`demo_world`), or reuse the one a previous demo left. A new world starts afresh
   what the demo made from the old one (`RUN_FOLDERS`): nothing trained or scored on another
   world is resumed or reported.
3. Reproduce the paper's experiments on it at the ``tiny`` budget: train the Flat,
   Cross-modal, Auxiliary and Multi-input nets, the colour-augmentation variants and Table 4's
   pair, evaluate each on held-out fabrics, and write the report beside the paper's numbers.
   On a CPU the runs train side by side, one process of one thread per core (`reproduce`);
   they share one cache of decoded images (``cache/`` in the demo folder), so each image is
   decoded once.
4. Train the recipe that connects the senses here (``configs/synth_cross.yaml``, shortened:
   `CROSS_OVERRIDES`) on the world's 100 training fabrics.
5. Evaluate it in full on the other 50: every pair in the embedding and through the cross-modal map
   fitted on the training fabrics, with intervals; calibration, confusion matrices, pick
   examples and the glance figure (a touch query, its nearest drapes and photos, what it
   feels like against the truth).

Every long step shows that it is alive: each step's line says which of the five it is and the
minutes so far, the world's rendering and every training run show a progress bar on stderr
(``train.progress=true``, which a ``--set train.progress=false`` turns off), and each
reproduction run prints a line as it starts.
"""

from __future__ import annotations

import json
import shutil
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from lookfeel.config import ConfigError, EvalConfig, RunConfig, load_config
from lookfeel.config.recipes import recipe_path
from lookfeel.data import scan
from lookfeel.data.summary import format_summary
from lookfeel.evaluate import EvalResult, evaluate_checkpoint, write_report
from lookfeel.modality import Modality, Pair
from lookfeel.reproduce import BUDGETS, EXPERIMENTS, ReproduceResult, headline, reproduce
from lookfeel.reproduce.report import verdict_text
from lookfeel.reproduce.run import config_dir, experiment_overrides, split_overrides
from lookfeel.synth import SynthConfig, generate
from lookfeel.synth.world import GENERATOR_VERSION, MANIFEST
from lookfeel.train import run_started, train

__all__ = [
    "CROSS_OVERRIDES",
    "DEMO_BUDGETS",
    "DEMO_FABRICS",
    "DEMO_REPRINTS",
    "DemoResult",
    "check_demo",
    "demo_test_fabrics",
    "demo_world",
    "print_demo_result",
    "run_demo",
]

DEMO_BUDGETS = tuple(b for b in BUDGETS if b != "paper")
"""The reproduction budgets the demo offers: ``paper`` needs ImageNet weights the demo never has."""

DEMO_REPRINTS = 1
"""Re-printed renders of each photo in the demo's world, and what its short run reads (the
full recipe reads four): its world is the one of before session 28. Four lifted colour ↔ depth
and left colour ↔ touch in the 500-step run on a demo-sized world (session 30, docs/synth.md)."""

CROSS_OVERRIDES = (
    "model.width=16",
    f"data.color_reprints={DEMO_REPRINTS}",
    "data.color_size=null",
    "train.steps=500",
    "train.val_every=0",
    "train.split=paper",
    "model.precision=fp32",
)
"""``configs/synth_cross.yaml`` as the demo trains it: half the width and 500 of its 1,000
steps, one re-printed render of each photo (`DEMO_REPRINTS`, not four) and the photo at 64 px
like the other senses (the recipe reads it at 96, which at 150 steps lowered colour to depth
from 0.333 to 0.281 on folds 0-2 of a demo-sized world of seed 1, session 29), on the world's
100 training fabrics, its test fabrics held out (``paper_split``: 50 since session 46). It
keeps the recipe's dropout on depth and touch, its three frames a press and its loss, which has
no colour-touch term (session 23: colour and touch meet through depth). Chosen in session 30
on folds 0-2 of two demo-sized worlds (seeds 1 and 2), never on the demo's own: against the 150
steps without dropout and with one frame a press that the demo ran before, the mean of the six
cross-modal pairs through the map rose in all six folds (0.25 -> 0.31 and 0.23 -> 0.29), and
500 steps without the dropout and the frames gained less (0.28 on seed 1) (docs/synth.md).

On CUDA it computes in full fp32 (``model.precision=fp32``), as on a CPU, not in bf16 autocast:
on one H200 (session 42, `benchmarks.bench_demo_seeds`, seeds 0-2, two batches) bf16 read the
mean of the six pairs 0.009 lower than fp32 in both batches (0.321 / 0.322 against 0.330 /
0.331; a CPU: 0.328; fp32 ahead at the same seed in 5 of 6), touch <-> depth 0.01-0.02
lower, and trained no faster for a network this small (12.4-12.5 against 11.3-12.3 s)."""


DEMO_FABRICS = 150
"""Fabrics in the demo's world: the paper's 100 to train on, and 50 held out (`demo_test_fabrics`).

The paper held out 18 of 118, and so did the demo until session 46. Over 18 held-out fabrics
a pair's 95% interval is about 0.15 wide; over 50, about 0.09. On worlds of seeds 1-3 (never the
demo's own) the demo's run read colour <-> touch at 0.19-0.29 over 18 held-out fabrics and at
0.21-0.25 over 50 (docs/synth.md). The 32 more fabrics cost about 13 s of rendering and 5 s of
evaluation on 2 cores."""


def demo_test_fabrics(fabrics: int) -> int:
    """Fabrics the demo holds out of a world of ``fabrics``: a third (50 of `DEMO_FABRICS`)."""
    return round(fabrics / 3)


def demo_world(fabrics: int, seed: int, test_fabrics: int | None = None) -> SynthConfig:
    """The demo's world: ``fabrics`` fabrics with 8 drapes (depth and colour, one re-printed
    render of each photo) and 4 flat and 12 fold presses each: fewer than ``lookfeel synth``
    makes by default, so that 150 fabrics render in about 50 s on 2 cores. ``test_fabrics``
    are held out (``None``: `demo_test_fabrics`, a third). It renders with one process per
    available core (the files do not depend on how many: `lookfeel.synth.world`).

    Session 42 doubled the drapes and presses (from 4, 2 and 6). This was chosen on worlds of
    seeds 1 and 2, never the demo's own. The demo's run there, through the map: colour -> touch
    0.238 -> 0.269 and 0.163 -> 0.216, and touch -> colour 0.210 -> 0.263 and 0.163 -> 0.200.
    The mean of the six pairs went 0.291 -> 0.313 and 0.281 -> 0.335. Doubling the drapes alone,
    or the presses alone, gained less. It costs about 20 s of rendering and 5 s of evaluation
    (docs/synth.md)."""
    return SynthConfig(
        fabrics=fabrics,
        drapes=8,
        presses_flat=4,
        presses_fold=12,
        seed=seed,
        workers=0,
        reprints=DEMO_REPRINTS,
        test_fabrics=demo_test_fabrics(fabrics) if test_fabrics is None else test_fabrics,
    )


def cross_config(overrides: Sequence[str] = ()) -> RunConfig:
    """``configs/synth_cross.yaml`` with `CROSS_OVERRIDES`, then ``overrides``."""
    return load_config(RunConfig, recipe_path("synth_cross.yaml"), [*CROSS_OVERRIDES, *overrides])


def _run_overrides(out: Path, overrides: Sequence[str]) -> list[str]:
    """The overrides the demo gives every reproduction run: a progress bar, one decode cache for
    all runs (they read the same images at one size: 52 -> 39 s on 2 cores, the results the
    same), then the user's, which win. The cache path is quoted: an override's value is YAML,
    where "demo #1" would end at the "#"."""
    return ["train.progress=true", f"data.cache_dir={json.dumps(str(out / 'cache'))}", *overrides]


def _demo_configs(
    fabrics: int, held: int, budget: str, overrides: Sequence[str]
) -> list[tuple[str, RunConfig]]:
    """Every run the demo trains, named, with its config as it will train (but for its decode
    cache): the reproduction's, as `lookfeel.reproduce.reproduce` loads them on this world, and
    the cross-modal recipe; ``overrides`` are the user's.

    Raises:
        ConfigError: an override names an unknown key or gives a bad value.
    """
    # The world marks its held-out fabrics paper_split=test: `reproduce` splits it so.
    models, vision, _ = split_overrides(held >= 10, fabrics - held)
    mine_too = ["train.progress=true", *overrides]
    configs = []
    for exp in EXPERIMENTS:
        mine = experiment_overrides(exp, budget, models, vision, mine_too)
        configs.append((exp.name, load_config(RunConfig, config_dir() / f"{exp.name}.yaml", mine)))
    configs.append(("cross-modal recipe", cross_config(mine_too)))
    return configs


def _trained_on(config: RunConfig, fabrics: int, held: int) -> int:
    """How many fabrics a run of ``config`` trains on in a demo world of ``fabrics`` with
    ``held`` held out (as `lookfeel.train.loop.select_split` splits it)."""
    t = config.train
    pool = fabrics - held  # no split trains on the world's held-out fabrics but ``none``
    if t.split == "none":
        return fabrics
    if t.split == "stratified":
        return pool - t.val_fabrics
    if t.split == "fold":
        return pool - (t.fold_size if t.fold_size is not None else -(-pool // t.folds))
    return pool  # paper, seen (its novel fabrics are the held-out ones)


def _fabrics_needed(config: RunConfig) -> int:
    """Training fabrics a run needs: one per slot of a tuple when slots come from different
    fabrics (`lookfeel.data.datasets.TupleDataset`), else one."""
    return len(config.train.views) if config.data.same_fraction < 1.0 else 1


def _world_problem(fabrics: int, held: int, budget: str, overrides: Sequence[str]) -> str | None:
    """Why the demo's runs cannot train on a world of ``fabrics`` with ``held`` held out, or
    None when they can.

    Raises:
        ConfigError: an override names an unknown key or gives a bad value.
    """
    if held < 2 or fabrics - held < 2:
        return "at least 2 must be held out and 2 left to train on"
    for name, config in _demo_configs(fabrics, held, budget, overrides):
        trained, needed = _trained_on(config, fabrics, held), _fabrics_needed(config)
        if trained < needed:
            how = {
                "stratified": f" (it validates on {config.train.val_fabrics} of the "
                f"{fabrics - held} not held out, as the reproduction does with fewer than 10 "
                "held out)",
                "fold": " (the others less its fold's test fabrics)",
            }.get(config.train.split, "")
            return (
                f"the {name} run trains on {max(trained, 0)} fabric(s){how} and draws "
                f"{needed} different fabrics for each training tuple"
            )
    return None


def check_demo(
    fabrics: int, test_fabrics: int | None, budget: str = "tiny", overrides: Sequence[str] = ()
) -> None:
    """Check what the demo is asked before it does anything: the budget, every override (on
    every config the demo trains) and that the world has enough fabrics for each of its runs.

    Args:
        fabrics: fabrics in the world (``--fabrics``).
        test_fabrics: fabrics held out (``--test-fabrics``; ``None``: `demo_test_fabrics`).
        budget: the reproduction budget.
        overrides: the user's ``key=value`` overrides of every training run (``--set``).

    Raises:
        ConfigError: naming the budget, the override, or the fabrics and the smallest world
            that runs.
    """
    if budget not in DEMO_BUDGETS:
        raise ConfigError(f"demo: budget {budget!r} is not one of {', '.join(DEMO_BUDGETS)}")
    held = demo_test_fabrics(fabrics) if test_fabrics is None else test_fabrics
    problem = _world_problem(fabrics, held, budget, overrides)
    if problem is None:
        return
    hint = ""
    for more in range(max(fabrics, held + 2) + 1, max(fabrics, held) + 200):
        more_held = demo_test_fabrics(more) if test_fabrics is None else test_fabrics
        if _world_problem(more, more_held, budget, overrides) is None:
            hint = f"; use --fabrics {more} or more"
            break
    raise ConfigError(
        f"demo: {fabrics} fabrics with {held} held out: {problem}{hint} (--fabrics, --test-fabrics)"
    )


@dataclass(frozen=True)
class DemoResult:
    """Where the demo put things, and how long it took."""

    world: Path
    reproduction: ReproduceResult
    evaluation: Path | None
    """The full evaluation report (figures included) of the cross-modal recipe."""
    seconds: float
    cross: EvalResult | None = None
    """That evaluation's result (its metrics: `print_demo_result` prints the pairs)."""
    step_seconds: dict[int, float] = field(default_factory=dict)
    """Wall seconds of each numbered step that ran (1: the real data's summary ... 5)."""


RUN_FOLDERS = ("reproduce", "cross", "evaluate", "cache")
"""What the demo makes from its world, in its folder: removed when it renders a new world, so
that nothing trained or scored on another world is resumed or reported."""


def _complete_world(path: Path, config: SynthConfig) -> bool:
    """Whether ``path`` holds a finished synthetic world made with ``config`` by this version
    of the generator."""
    try:
        manifest = json.loads((path / MANIFEST).read_text(encoding="utf-8"))
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
    fabrics: int = DEMO_FABRICS,
    test_fabrics: int | None = None,
    budget: str = "tiny",
    seed: int = 0,
    overrides: Sequence[str] = (),
    log: Callable[[str], None] = print,
) -> DemoResult:
    """Run the demo; see the module docstring.

    Args:
        out: demo folder (``world/``, ``reproduce/``, ``cross/`` and ``evaluate/`` go inside;
            re-runs reuse what is finished).
        real_data: a real dataset to summarise first, when it exists.
        fabrics: fabrics in the synthetic world (`DEMO_FABRICS`: 100 to train on, 50 held
            out).
        test_fabrics: fabrics held out; ``None``: a third (`demo_test_fabrics`).
        budget: the reproduction budget (``tiny`` for minutes on 2 cores).
        seed: seed of the world.
        overrides: ``key=value`` overrides of every training run.
        log: where progress lines go.
    """
    started = time.perf_counter()
    # Every check before any work: a typo in --set or a world too small for a run would
    # otherwise show only after minutes of rendering and training.
    check_demo(fabrics, test_fabrics, budget, overrides)

    marks: list[tuple[int, float]] = []

    def step(k: int, text: str) -> None:
        marks.append((k, time.perf_counter()))
        log(f"[{k}/5, {(marks[-1][1] - started) / 60:.1f} min] {text}")

    if real_data is not None and real_data.is_dir():
        step(1, f"Real GelFabric data at {real_data}:")
        log(format_summary(scan(real_data)))
        log("")
    elif real_data is not None:  # e.g. run outside the repository, beside no ../shared/data
        step(1, f"No real data at {real_data} (--data) to summarise: on to the synthetic world.")
    world = out / "world"
    config = demo_world(fabrics, seed, test_fabrics)
    held = config.test_fabrics
    assert held is not None  # demo_world always sets it
    if _complete_world(world, config):
        step(2, f"Reusing the synthetic world in {world}.")
    else:
        step(
            2,
            f"Generating a synthetic world of {fabrics} fabrics ({config.test_fabrics} held "
            f"out) in {world} ...",
        )
        stale = [d for d in RUN_FOLDERS if (out / d).is_dir()]
        if stale:  # made on another world: their runs would be resumed or reused as done
            log(f"The world is new: starting {', '.join(f'{d}/' for d in stale)} afresh.")
            for d in stale:
                shutil.rmtree(out / d)
        generate(config, world, progress=True)
    log(format_summary(scan(world)))
    log("")
    step(3, f"Reproducing the paper's experiments (budget {budget}) in {out / 'reproduce'} ...")
    result = reproduce(
        world,
        out / "reproduce",
        budget=budget,
        seeds=(0,),
        n_boot=500,
        overrides=_run_overrides(out, overrides),
        log=log,
    )
    cross = cross_config(["train.progress=true", *overrides])
    run = out / "cross"
    step(
        4,
        f"Training the cross-modal recipe (configs/synth_cross.yaml, width "
        f"{cross.model.width}, {cross.train.steps} steps) in {run} ...",
    )
    trained = train(cross, world, run, resume=run_started(run))
    step(5, "Evaluating it in full on the world's test fabrics ...")
    evaluated = evaluate_checkpoint(
        trained.last_checkpoint, world, split="val", config=EvalConfig(n_boot=500)
    )
    report = write_report(evaluated, out / "evaluate").report
    ended = time.perf_counter()
    ends = [t for _, t in marks[1:]] + [ended]
    seconds = {k: round(end - t, 2) for (k, t), end in zip(marks, ends, strict=True)}
    return DemoResult(world, result, report, ended - started, evaluated, seconds)


def print_demo_result(result: DemoResult, log: Callable[[str], None] = print) -> None:
    """The headline numbers and where everything is."""
    log("")
    log("Headline (pick 1 of 10 on held-out fabrics of the synthetic world):")
    for line in headline(result.reproduction.results):
        log(f"  {line}")
    log("Findings of the paper, checked here:")
    for f in result.reproduction.findings.values():
        log(f"  {verdict_text(f):>13}: {f['claim']}")
    if result.cross is not None:
        log("")
        log(_cross_title(result.cross))
        for line in cross_lines(result.cross.metrics):
            log(f"  {line}")
    log("")
    log(f"Report:        {result.reproduction.report}")
    if result.evaluation is not None:
        log(f"Evaluation:    {result.evaluation} (figures beside it)")
        glance = result.evaluation.parent / "figures" / "glance.png"
        if glance.exists():
            log(f"At a glance:   {glance} (touch queries, their nearest drapes and photos)")
    log(f"Contact sheet: {result.world / 'contact_sheet.png'}")
    log(f"Done in {result.seconds / 60:.1f} min.")


def _cross_title(result: EvalResult) -> str:
    n = len(result.info.get("fabrics", []))
    return (
        f"Look and feel connected (the cross-modal recipe, pick 1 of 10 on {n} held-out "
        "fabrics, top-1 [95% interval]):"
    )


def cross_lines(metrics: dict[str, float]) -> list[str]:
    """One line per pair of two senses: top-1 through the cross-modal map with its interval,
    in the embedding itself, and chance (pairs without the map: the embedding alone)."""
    lines = []
    senses = [m for m in Modality if any(k.startswith(f"{m.value}_to_") for k in metrics)]
    for pair in Pair.every(senses):
        key = f"{pair}_top1"
        if pair.same or key not in metrics:
            continue
        chance = metrics.get(f"{key}_chance", float("nan"))
        low, high = (metrics.get(f"{key}_ci_{s}", float("nan")) for s in ("low", "high"))
        own = f"{metrics[key]:.3f} [{low:.3f}, {high:.3f}]"
        name = f"{pair.query.value} -> {pair.gallery.value}"
        if f"{key}_mapped" in metrics:
            low, high = (metrics.get(f"{key}_mapped_ci_{s}", float("nan")) for s in ("low", "high"))
            lines.append(
                f"{name:<16} {metrics[f'{key}_mapped']:.3f} [{low:.3f}, {high:.3f}] through the "
                f"map, {own} in the embedding (chance {chance:.3f})"
            )
        else:
            lines.append(f"{name:<16} {own} in the embedding (chance {chance:.3f})")
    return lines
