"""Which image of a press video to show the model: touch-to-touch retrieval from raw pixels.

For every PhysiCLeAR video with a press (`lookfeel.data.video.detect_press`), candidate images
are made from its frames, shrunk to 32x24 RGB, every pixel z-scored over the videos, and each
video's nearest neighbours scored by pick 1 of 10 among objects (`score_pairs`, the
``EXACT_PICK`` protocol with 95% bootstrap intervals over query objects; the object id is the
file name without its ``_<n>``). No model: this measures what the pixels themselves carry, and
chose the defaults of ``DataConfig.video_*``:

- ``raw_peak``: the frame of deepest contact; ``raw_second_to_last``: frame -2 (what
  ``touch_frame`` would take from a folder of frames); ``raw_reference``: the no-contact frame
  alone (no touch at all: what identifies a recording session rather than a feel);
- ``diff_peak_g{gain}``: `difference_image` of the deepest frame from the no-contact frame;
- ``diff_mean{n}_g8`` / ``raw_mean5``: the mean of n frames spread across the contact span.

    python -m benchmarks.bench_video_pixels [--videos ../shared/data/physiclear/videos]
"""

from __future__ import annotations

import re
import time
from pathlib import Path

import numpy as np
from PIL import Image

from benchmarks.bench_decode_video import DEFAULT_VIDEOS, map_videos, video_main, videos_folder
from lookfeel.data.video import (
    VIDEO_SUFFIXES,
    VideoError,
    contact_frames,
    detect_press,
    difference_image,
    read_video,
    reference_frame,
)
from lookfeel.metrics.scoring import ScoringProtocol, score_pairs

GAINS = (2, 4, 8, 16, 32, 64)
MEANS = (3, 5, 9, 17)
SIZE = (32, 24)
PROTOCOL = ScoringProtocol(gallery=False, sampled=False, n_boot=1000)


def _small(a: np.ndarray) -> np.ndarray:
    im = Image.fromarray(np.ascontiguousarray(a)).resize(SIZE, Image.Resampling.BILINEAR)
    return np.asarray(im, np.float32).reshape(-1)


def _mean(images: list[np.ndarray]) -> np.ndarray:
    return np.rint(np.mean([i.astype(np.float32) for i in images], axis=0)).astype(np.uint8)


def features(path: str) -> tuple[str, dict[str, np.ndarray] | None]:
    """Every candidate image of one video, shrunk and flattened (None: no press found)."""
    try:
        frames = read_video(path)
        span = detect_press(frames, path)
    except VideoError:
        return path, None
    ref = reference_frame(frames, span)
    peak = frames[span.peak]
    out = {
        "raw_peak": _small(peak),
        "raw_second_to_last": _small(frames[-2]),
        "raw_reference": _small(np.rint(ref).astype(np.uint8)),
        "raw_mean5": _small(_mean([frames[i] for i in contact_frames(span, 5)])),
    }
    for g in GAINS:
        out[f"diff_peak_g{g}"] = _small(difference_image(peak, ref, g))
    for n in MEANS:
        diffs = [difference_image(frames[i], ref, 8.0) for i in contact_frames(span, n)]
        out[f"diff_mean{n}_g8"] = _small(_mean(diffs))
    return path, out


def _score(x: np.ndarray, objects: np.ndarray) -> dict[str, float]:
    x = x.astype(np.float64)
    sd = x.std(axis=0)
    keep = sd > 1e-9
    z = (x[:, keep] - x[:, keep].mean(axis=0)) / sd[keep]
    (score,) = score_pairs({"touch": z}, {"touch": objects}, PROTOCOL, ["touch_to_touch"]).values()
    m = score.metrics
    keys = ("top1", "top1_ci_low", "top1_ci_high", "top3", "top1_chance")
    return {k: round(m[k], 3) for k in keys}


def run(data: Path | None, videos: Path | None = None, workers: int = 2) -> dict[str, object]:
    folder = videos if videos is not None else videos_folder(data)
    if folder is None or not folder.is_dir():
        return {"skipped": f"real press videos not found at {DEFAULT_VIDEOS}", "met": None}
    paths = sorted(str(p) for p in folder.iterdir() if p.suffix.lower() in VIDEO_SUFFIXES)
    start = time.perf_counter()
    found = [(p, f) for p, f in map_videos(features, paths, workers, chunksize=8) if f is not None]
    seconds = time.perf_counter() - start
    names = [re.sub(r"_\d+$", "", Path(p).stem) for p, _ in found]
    objects = np.unique(names, return_inverse=True)[1]
    scores = {k: _score(np.stack([f[k] for _, f in found]), objects) for k in found[0][1]}
    return {
        "videos": len(paths),
        "with_press": len(found),
        "objects": int(objects.max()) + 1,
        "image": f"{SIZE[0]}x{SIZE[1]} RGB, z-scored per pixel over the videos",
        "protocol": "touch_to_touch exact pick 1 of 10 among objects (EXACT_PICK), 95% CI",
        "features_s": round(seconds, 1),
        "scores": scores,
    }


def main(argv: list[str] | None = None) -> int:
    return video_main("video_pixels", run, argv)


if __name__ == "__main__":
    raise SystemExit(main())
