"""Training speed of the compact recipes in channels-last (NHWC) and NCHW memory layout.

`TrainConfig.channels_last` (on by default since session 26; before, on CUDA only) lays the
images and the convolutions' weights out channels-last, which oneDNN's fastest CPU
convolutions and pools read. This times both layouts on one small synthetic world of the
demo's kind (36 fabrics, generated in seconds), for two recipes:

- ``demo``: `configs/synth_cross.yaml` as `make demo` trains it (`lookfeel.demo.cross_config`:
  width 16, every sense at 64 px);
- ``full``: `configs/synth_cross.yaml` itself (width 32, the photo at 96 px).

Each run trains ``STEPS`` steps from scratch; its rate is taken over the steps after the first
``WARMUP`` (set-up, decoding and the first allocations excluded). The layouts alternate,
``REPEATS`` runs each; the result is each layout's median steps/s and their ratio, with the
last logged loss of each run (the layouts round differently, so the losses agree in the
leading digits only).

    python -m benchmarks --only train_layout

Target: channels-last at least as fast as NCHW (ratio >= 1.0) for both recipes.
"""

from __future__ import annotations

import statistics
import tempfile
import time
from collections.abc import Mapping
from dataclasses import replace
from pathlib import Path

from lookfeel.config import RunConfig, load_config
from lookfeel.config.recipes import recipe_path
from lookfeel.demo import cross_config, demo_world
from lookfeel.synth import SynthConfig, generate
from lookfeel.train import train

FABRICS = 36
STEPS = {"demo": 60, "full": 30}
WARMUP = 5
REPEATS = 3
OVERRIDES = ["train.split=paper", "train.progress=false"]


def _config(recipe: str, channels_last: bool) -> RunConfig:
    steps = STEPS[recipe]
    over = [
        *OVERRIDES,
        f"train.steps={steps}",
        "train.val_every=0",
        f"train.checkpoint_every={steps}",
    ]
    over.append(f"train.channels_last={str(channels_last).lower()}")
    if recipe == "demo":
        return cross_config(over)
    return load_config(RunConfig, recipe_path("synth_cross.yaml"), over)


def _timed_run(cfg: RunConfig, world: Path, out: Path) -> tuple[float, float]:
    """(steps/s after the warm-up, last loss) of one training run."""
    stamps: list[float] = []
    last: dict[str, float] = {}

    def on_step(step: int, terms: Mapping[str, float]) -> None:
        stamps.append(time.perf_counter())
        last.update(terms)

    train(cfg, world, out, on_step=on_step)
    timed = stamps[WARMUP:]
    rate = (len(timed) - 1) / (timed[-1] - timed[0])
    return rate, float(last.get("loss", float("nan")))


def world_config(fabrics: int = FABRICS) -> SynthConfig:
    """A world of the demo's kind with as many re-printed renders of each photo as either
    recipe reads (`data.color_reprints`: the demo one, the full recipe four)."""
    reprints = max(_config(r, True).data.color_reprints for r in STEPS)
    return replace(demo_world(fabrics, seed=0), reprints=reprints)


def run(data: Path | None) -> dict[str, object]:
    del data  # a synthetic world of its own
    with tempfile.TemporaryDirectory() as tmp:
        world = Path(tmp) / "world"
        generate(world_config(), world, progress=False)
        recipes: dict[str, dict[str, object]] = {}
        for recipe in STEPS:
            rates: dict[str, list[float]] = {"channels_last": [], "nchw": []}
            losses: dict[str, list[float]] = {"channels_last": [], "nchw": []}
            for r in range(REPEATS):
                for layout in ("channels_last", "nchw"):
                    cfg = _config(recipe, layout == "channels_last")
                    rate, loss = _timed_run(cfg, world, Path(tmp) / f"{recipe}-{layout}-{r}")
                    rates[layout].append(round(rate, 3))
                    losses[layout].append(round(loss, 4))
            median = {k: statistics.median(v) for k, v in rates.items()}
            recipes[recipe] = {
                "steps": STEPS[recipe],
                "steps_per_s": median,
                "steps_per_s_all": rates,
                "last_loss_all": losses,
                "ratio": round(median["channels_last"] / median["nchw"], 3),
            }
    met = all(float(r["ratio"]) >= 1.0 for r in recipes.values())  # type: ignore[arg-type]
    return {
        "world_fabrics": FABRICS,
        "warmup_steps": WARMUP,
        "repeats": REPEATS,
        "recipes": recipes,
        "target_ratio": 1.0,
        "met": met,
    }
