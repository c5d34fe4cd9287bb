"""One training run of each real-data recipe, as a user starts it (issue #12's target: one
`configs/real_depth.yaml` run in <= 5 minutes on 2 cores; issue #13's: one
`configs/physiclear.yaml` run in <= 10 minutes).

Each run is ``python -m lookfeel train --config configs/RECIPE.yaml --data ROOT --out RUN`` in
a fresh process and a fresh folder, nothing cached from an earlier run (real depth is
registered, the videos are decoded and their presses found, every time): the wall time a user
waits, the interpreter's start and torch's import included. ``median_s`` is the median of
``TRAIN_REAL_BENCH_RUNS`` runs (3). A recipe whose data is absent is skipped and says so.

    python -m benchmarks --only train_real [--data ../shared/data/gelfabric]
    TRAIN_REAL_PHYSICLEAR=/path/to/physiclear python -m benchmarks --only train_real
"""

from __future__ import annotations

import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from benchmarks.bench_decode_video import DEFAULT_VIDEOS
from lookfeel.config import RunConfig, load_config
from lookfeel.config.recipes import recipe_path

SHARED = DEFAULT_VIDEOS.parent.parent
"""``../shared/data``, beside the repository, where the real datasets lie."""
RUNS = int(os.environ.get("TRAIN_REAL_BENCH_RUNS", "3"))

RECIPES = {
    "real_depth": ("real_depth.yaml", 300.0, "issue #12"),
    "physiclear": ("physiclear.yaml", 600.0, "issue #13"),
}
"""Recipe -> (its config, the target in seconds, where the target comes from)."""


def _roots(data: Path | None) -> dict[str, Path]:
    gelfabric = data if data is not None else SHARED / "gelfabric"
    physiclear = Path(os.environ.get("TRAIN_REAL_PHYSICLEAR", SHARED / "physiclear"))
    return {"real_depth": gelfabric, "physiclear": physiclear}


def _train_once(config: Path, root: Path, out: Path) -> float:
    """Wall seconds of one ``lookfeel train`` in a fresh process; raises if it fails."""
    command = [sys.executable, "-m", "lookfeel", "train", "--config", str(config)]
    command += ["--data", str(root), "--out", str(out)]
    started = time.perf_counter()
    done = subprocess.run(command, capture_output=True, text=True, check=False)
    seconds = time.perf_counter() - started
    if done.returncode != 0:
        raise RuntimeError(f"{' '.join(command)} failed ({done.returncode}): {done.stderr[-2000:]}")
    return seconds


def _recipe(name: str, root: Path) -> dict[str, object]:
    file, target, source = RECIPES[name]
    config = recipe_path(file)
    if not root.is_dir():
        return {"skipped": f"no data at {root}", "target_s": target, "target_from": source}
    loaded = load_config(RunConfig, config)
    seconds = []
    with tempfile.TemporaryDirectory(prefix=f"bench_train_{name}_") as tmp:
        for i in range(RUNS):
            seconds.append(_train_once(config, root, Path(tmp) / f"run{i}"))
    median = statistics.median(seconds)
    return {
        "config": f"configs/{file}",
        "data": str(root),
        "steps": loaded.train.steps,
        "batch_size": loaded.train.batch_size,
        "networks": loaded.model.members,
        "runs": RUNS,
        "seconds_all": [round(s, 1) for s in seconds],
        "median_s": round(median, 1),
        "target_s": target,
        "target_from": source,
        "met": median <= target,
    }


def run(data: Path | None) -> dict[str, object]:
    load_before = os.getloadavg()
    recipes = {name: _recipe(name, root) for name, root in _roots(data).items()}
    measured = [r for r in recipes.values() if "met" in r]
    return {
        "recipes": recipes,
        "load_average_before": [round(x, 2) for x in load_before],
        "load_average_after": [round(x, 2) for x in os.getloadavg()],
        "met": all(r["met"] for r in measured) if measured else None,
    }
