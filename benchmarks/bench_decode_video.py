"""Decoding real GelSight Mini press videos and finding their presses (issue 13 target: all 401
PhysiCLeAR videos in <= 60 s on 2 cores).

Each video goes through `lookfeel.data.video.read_press` as the image loader calls it: read the
file, decode every frame (PyAV), find the press on the small luma frames, convert the deepest
frame and the reference frames to RGB and take their difference. Cold: nothing is cached.

- ``median_s``: all videos on ``--workers`` processes (default 2, forked fresh each repeat and
  counted in the time; they die with this process), median of ``--repeats`` (default 3);
- ``per_video_ms``: one process, each video timed alone (median, 95th percentile);
- ``loader_s``: the same through `ImageLoader.preload` (227x227 difference images, 2 threads, in
  this process), the videos with a press only; median of ``--repeats``;
- what was found: how many presses, which videos failed and why, and the distribution of the
  reference length, start, peak and end frames.

``cpu_s`` is the CPU time of a repeat (this process and its workers): on a machine shared with
other jobs, ``cpu_s / workers`` is what the wall time would be on free cores.

    python -m benchmarks.bench_decode_video [--videos ../shared/data/physiclear/videos]
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import sys
import time
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context
from pathlib import Path
from typing import TypeVar

import numpy as np

from lookfeel.config import DataConfig
from lookfeel.data import ImageLoader
from lookfeel.data.catalog import Item
from lookfeel.data.video import VIDEO_SUFFIXES, VideoError, read_press
from lookfeel.modality import Modality
from lookfeel.processes import die_with_parent

HERE = Path(__file__).resolve().parent
T = TypeVar("T")
DEFAULT_VIDEOS = HERE.parent.parent / "shared" / "data" / "physiclear" / "videos"
TARGET_S = 60.0
REPEATS = 3
WORKERS = 2
_START = "fork" if sys.platform.startswith("linux") else "spawn"
"""Forked workers start at once (a spawned one imports lookfeel and torch again: seconds)."""


def _press(path: str) -> tuple[str, tuple[int, int, int, int, int, int] | str]:
    """(name, (reference start, reference stop, start, peak, end, frames)) or (name, error)."""
    try:
        s = read_press(path).span
    except VideoError as e:
        return Path(path).name, e.reason
    return Path(path).name, (*s.reference, s.start, s.peak, s.end, s.frames)


def _cpu() -> float:
    me = resource.getrusage(resource.RUSAGE_SELF)
    kids = resource.getrusage(resource.RUSAGE_CHILDREN)
    return me.ru_utime + me.ru_stime + kids.ru_utime + kids.ru_stime


def map_videos(
    fn: Callable[[str], T], paths: list[str], workers: int, chunksize: int = 0
) -> list[T]:
    """``fn`` of every path, in order, in ``workers`` fresh processes that die with this one
    (``chunksize`` 0: about 8 chunks a worker)."""
    with ProcessPoolExecutor(
        workers,
        mp_context=get_context(_START),
        initializer=die_with_parent,
        initargs=(os.getpid(),),
    ) as pool:
        return list(pool.map(fn, paths, chunksize=chunksize or max(1, len(paths) // (8 * workers))))


def video_main(name: str, run: Callable[..., dict[str, object]], argv: list[str] | None) -> int:
    """The command line of a benchmark over the real press videos: ``run(None, videos,
    workers)`` with ``--videos``, ``--workers`` and ``--out``."""
    parser = argparse.ArgumentParser(prog=f"python -m benchmarks.bench_{name}")
    parser.add_argument("--videos", type=Path, default=None, help=f"default {DEFAULT_VIDEOS}")
    parser.add_argument("--workers", type=int, default=WORKERS)
    parser.add_argument("--out", type=Path, default=None, help="also write the JSON here")
    args = parser.parse_args(argv)
    from benchmarks.__main__ import write_standalone

    started = time.time()
    return write_standalone(name, started, run(None, args.videos, args.workers), args.out)


def _pool_run(paths: list[str], workers: int) -> tuple[float, float, list]:
    cpu, start = _cpu(), time.perf_counter()
    found = map_videos(_press, paths, workers)
    return time.perf_counter() - start, _cpu() - cpu, found


def _percentiles(values: list[int]) -> dict[str, float]:
    q = np.percentile(values, [0, 5, 50, 95, 100])
    names = ("min", "p5", "median", "p95", "max")
    return {name: round(float(v), 1) for name, v in zip(names, q, strict=True)}


def videos_folder(data: Path | None) -> Path | None:
    """The PhysiCLeAR videos: beside ``data`` (a GelFabric root), or ../shared/data/physiclear."""
    candidates = [] if data is None else [data.parent / "physiclear" / "videos"]
    for c in [*candidates, DEFAULT_VIDEOS]:
        if c.is_dir():
            return c
    return None


def run(
    data: Path | None,
    videos: Path | None = None,
    workers: int = WORKERS,
    repeats: int = REPEATS,
) -> dict[str, object]:
    folder = videos if videos is not None else videos_folder(data)
    if folder is None or not folder.is_dir():
        return {"skipped": f"real press videos not found at {DEFAULT_VIDEOS}", "met": None}
    paths = sorted(str(p) for p in folder.iterdir() if p.suffix.lower() in VIDEO_SUFFIXES)
    if not paths:
        return {"skipped": f"no videos in {folder}", "met": None}
    runs = [_pool_run(paths, workers) for _ in range(repeats)]
    found = runs[0][2]
    single = []
    for p in paths:
        start = time.perf_counter()
        _press(p)
        single.append(time.perf_counter() - start)
    spans = [r for _, r in found if not isinstance(r, str)]
    failed = {name: r for name, r in found if isinstance(r, str)}
    median = statistics.median(t for t, _, _ in runs)
    items = [
        Item(Modality.TOUCH, i, (Path(p),), None, Path(p).stem)
        for i, p in enumerate(paths)
        if Path(p).name not in failed
    ]
    loader_s = []
    for _ in range(repeats):
        loader = ImageLoader(DataConfig(image_size=227, workers=2))
        start = time.perf_counter()
        loader.preload(items)
        loader_s.append(time.perf_counter() - start)
    return {
        "videos": len(paths),
        "folder": str(folder),
        "workers": workers,
        "repeats": repeats,
        "seconds_all": [round(t, 2) for t, _, _ in runs],
        "cpu_s_all": [round(c, 2) for _, c, _ in runs],
        "median_s": round(median, 2),
        "videos_per_s": round(len(paths) / median, 1),
        "per_video_ms": {
            "median": round(1000 * statistics.median(single), 1),
            "p95": round(1000 * float(np.percentile(single, 95)), 1),
            "one_process_total_s": round(sum(single), 2),
        },
        "loader_s": round(statistics.median(loader_s), 2),
        "loader_s_all": [round(t, 2) for t in loader_s],
        "presses_found": len(spans),
        "failed": failed,
        "reference_frames": _percentiles([s[1] - s[0] for s in spans]),
        "start": _percentiles([s[2] for s in spans]),
        "peak": _percentiles([s[3] for s in spans]),
        "end": _percentiles([s[4] for s in spans]),
        "contact_frames": _percentiles([s[4] - s[2] for s in spans]),
        "frames": _percentiles([s[5] for s in spans]),
        "target_s": TARGET_S,
        "met": median <= TARGET_S,
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.bench_decode_video")
    parser.add_argument("--videos", type=Path, default=None, help=f"default {DEFAULT_VIDEOS}")
    parser.add_argument("--workers", type=int, default=WORKERS)
    parser.add_argument("--repeats", type=int, default=REPEATS)
    parser.add_argument("--out", type=Path, default=None, help="also write the JSON here")
    args = parser.parse_args(argv)
    from benchmarks.__main__ import write_standalone

    started = time.time()
    result = run(None, args.videos, args.workers, args.repeats)
    return write_standalone("decode_video", started, result, args.out)


if __name__ == "__main__":
    raise SystemExit(main())
