"""Decoding and preprocessing all real depth images to 227x227 (issue target: < 10 s, 2 cores).

Cold loads: a fresh `ImageLoader` (empty memory cache, no disk cache) per repeat, so every
file is read, decoded, hole-filled, mapped and resized each time. Median of 5 repeats.
"""

from __future__ import annotations

import statistics
import time
from pathlib import Path

from lookfeel.config import DataConfig
from lookfeel.data import ImageLoader, scan
from lookfeel.modality import Modality

TARGET_S = 10.0
REPEATS = 5


def run(data: Path | None) -> dict[str, object]:
    if data is None:
        return {"skipped": "real GelFabric data not found (pass --data)", "met": None}
    items = scan(data).items(Modality.DEPTH)
    config = DataConfig(image_size=227, workers=2)
    times = []
    for _ in range(REPEATS):
        loader = ImageLoader(config)
        start = time.perf_counter()
        loader.preload(items)
        times.append(time.perf_counter() - start)
    single = []
    for _ in range(3):
        loader = ImageLoader(DataConfig(image_size=227, workers=1))
        start = time.perf_counter()
        loader.preload(items, workers=1)
        single.append(time.perf_counter() - start)
    median = statistics.median(times)
    return {
        "images": len(items),
        "image_size": 227,
        "workers": 2,
        "repeats": REPEATS,
        "seconds_all": [round(t, 3) for t in times],
        "median_s": round(median, 3),
        "images_per_s": round(len(items) / median, 1),
        "median_s_one_thread": round(statistics.median(single), 3),
        "thread_speedup": round(statistics.median(single) / median, 2),
        "target_s": TARGET_S,
        "met": median < TARGET_S,
    }
