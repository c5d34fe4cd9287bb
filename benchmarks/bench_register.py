"""Registering the real depth images: the room fitted and the cloth found in each of
GelFabric's 1,104 drapes (`lookfeel.data.register.register_configured` with
`configs/real_depth.yaml`'s settings), in one thread, images decoded beforehand. Median of 3.

Every registered run (`data.depth_input: registered`) does this once per image, unless
``data.cache_dir`` keeps the results between runs, and the background control of `lookfeel
evaluate` and `lookfeel cv` does it for every held-out depth image. No target: the recipe's
training time (issue #12, 5 minutes a run) includes it.

    python -m benchmarks --only register --data ../shared/data/gelfabric
"""

from __future__ import annotations

import statistics
import time
from pathlib import Path

from lookfeel.config import RunConfig, load_config
from lookfeel.config.recipes import recipe_path
from lookfeel.data import decode_depth, scan
from lookfeel.data.register import register_configured
from lookfeel.modality import Modality

REPEATS = 3


def run(data: Path | None) -> dict[str, object]:
    if data is None:
        return {"skipped": "real GelFabric data not found (pass --data)", "met": None}
    config = load_config(RunConfig, recipe_path("real_depth.yaml")).data
    images = [decode_depth(it.path) for it in scan(data).items(Modality.DEPTH)]
    times = []
    for _ in range(REPEATS):
        start = time.perf_counter()
        for d in images:
            register_configured(d, config)
        times.append(time.perf_counter() - start)
    median = statistics.median(times)
    return {
        "images": len(images),
        "threads": 1,
        "repeats": REPEATS,
        "seconds_all": [round(t, 2) for t in times],
        "median_s": round(median, 2),
        "ms_per_image": round(1000 * median / len(images), 1),
        "met": None,
    }
