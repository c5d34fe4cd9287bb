"""What in a real press reads how an object feels: a dozen hand-made contact statistics, probed
on held-out objects (issue #13's hardness, roughness and bumpiness).

No network. For every PhysiCLeAR video with a press (`lookfeel.data.video.detect_press`), the
difference of each frame from the no-contact frame (gain 1, grey levels, the mean over RGB of
its absolute value, 4x4 block means) gives two groups of numbers:

- ``peak``, the frame of deepest contact: how much of the field changed (the log fraction of
  blocks changed by more than 2, 4 and 8 grey levels), how much (the log mean change, its 50th,
  90th and 99th percentiles) and how sharply (log mean and largest gradient of the change);
- ``course``, the time course of the loading, first contact to the deepest frame: the changed
  area and the 99th-percentile change at 16 evenly spaced moments, each divided by its value at
  the deepest frame (the shape of the curve, not its level), and the log number of frames of
  the loading and of the whole contact;
- ``release``, the unloading, the deepest frame to the first out of contact, sampled alike (a soft
  object that springs back after the gel, or a sticky one, would let go more slowly than a
  hard one), with the log number of frames of the unloading and its log ratio to the loading's.

A standardised logistic regression on each group (and on the peak with the others) predicts
each label's rank from one press; it is fitted on the presses of 4/5 of the labelled objects and
scored on the rest, over ``PARTITIONS`` random object-disjoint 5-fold partitions. Accuracy is
per press, averaged within each object, then over objects (every object counts once), beside
the training folds' majority class.

    python -m benchmarks.bench_touch_cues [--videos ../shared/data/physiclear/videos]
"""

from __future__ import annotations

import csv
import re
import time
from pathlib import Path

import numpy as np

from benchmarks.bench_decode_video import DEFAULT_VIDEOS, map_videos, video_main, videos_folder
from lookfeel.data.video import (
    VIDEO_SUFFIXES,
    VideoError,
    detect_press,
    read_video,
    reference_frame,
)

LABELS = ("hardness", "roughness", "bumpiness")
POINTS = 16
"""Moments of the loading at which the course is sampled."""
PARTITIONS = 10
FOLDS = 5
C = 0.3
"""Inverse L2 strength of the logistic regression (not tuned: the one value tried)."""
PEAK_NAMES = (
    "log area > 2",
    "log area > 4",
    "log area > 8",
    "log mean change",
    "change p50",
    "change p90",
    "change p99",
    "log mean gradient",
    "log largest gradient",
)


def _change(frames: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """(T, h, w) float32 mean absolute change over RGB of (T, H, W, 3) frames, 4x4 means."""
    d = np.abs(frames.astype(np.float32) - reference).mean(axis=3)
    t, h, w = d.shape
    h, w = h // 4 * 4, w // 4 * 4
    return d[:, :h, :w].reshape(t, h // 4, 4, w // 4, 4).mean(axis=(2, 4))


def _peak_stats(g: np.ndarray) -> list[float]:
    """`PEAK_NAMES` of one (h, w) change map."""
    gy, gx = np.gradient(g)
    grad = np.hypot(gx, gy)
    eps = 1e-3
    return [
        *(float(np.log((g > t).mean() + eps)) for t in (2.0, 4.0, 8.0)),
        float(np.log(g.mean() + eps)),
        *(float(np.percentile(g, q)) for q in (50, 90, 99)),
        float(np.log(grad.mean() + eps)),
        float(np.log(grad.max() + eps)),
    ]


def features(path: str) -> tuple[str, dict[str, np.ndarray] | None]:
    """The ``peak``, ``course`` and ``release`` numbers of one video (None: no press found)."""
    try:
        frames = read_video(path)
        span = detect_press(frames, path)
    except VideoError:
        return path, None
    ref = reference_frame(frames, span)
    # The contact span and the first frame after it (where the release ends), if any.
    g = _change(frames[span.start : span.end + 1], ref)
    deepest = span.peak - span.start
    flat = g.reshape(len(g), -1)
    area = (flat > 4.0).mean(axis=1)
    top = np.percentile(flat, 99, axis=1)
    course = [_shape(c[: deepest + 1], c[deepest]) for c in (area, top)]
    release = [_shape(c[deepest:], c[deepest]) for c in (area, top)]
    loading = np.log(span.peak - span.start + 1)
    unloading = np.log(span.end - span.peak + 1)
    contact = np.log(span.end - span.start + 1)
    return path, {
        "peak": np.asarray(_peak_stats(g[deepest]), np.float32),
        "course": np.asarray([*course[0], *course[1], loading, contact], np.float32),
        "release": np.asarray(
            [*release[0], *release[1], unloading, unloading - loading], np.float32
        ),
    }


def _shape(curve: np.ndarray, at_deepest: float) -> np.ndarray:
    """``curve`` resampled at `POINTS` evenly spaced moments, divided by its value at the
    deepest frame."""
    at = np.linspace(0, len(curve) - 1, POINTS)
    return np.interp(at, np.arange(len(curve)), curve / (at_deepest + 1e-6))


def _labels(folder: Path) -> dict[str, dict[str, int]]:
    """Object name -> its ranks, from the labels.csv beside the videos (labelled rows only)."""
    with (folder.parent / "labels.csv").open(newline="", encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    return {
        r["object"]: {k: int(r[k]) for k in LABELS}
        for r in rows
        if all((r.get(k) or "").strip() for k in LABELS)
    }


def probe(
    x: np.ndarray, y: np.ndarray, objects: np.ndarray, partitions: int = PARTITIONS
) -> dict[str, float]:
    """Object-disjoint accuracy of a logistic regression on ``x`` (see the module's docstring)."""
    from sklearn.linear_model import LogisticRegression
    from sklearn.pipeline import make_pipeline
    from sklearn.preprocessing import StandardScaler

    names = np.unique(objects)
    accuracy, majority = [], []
    for seed in range(partitions):
        folds = np.array_split(np.random.default_rng(seed).permutation(names), FOLDS)
        hit = np.zeros(len(y), bool)
        hit_majority = np.zeros(len(y), bool)
        for fold in folds:
            test = np.isin(objects, fold)
            model = make_pipeline(StandardScaler(), LogisticRegression(C=C, max_iter=5000))
            model.fit(x[~test], y[~test])
            hit[test] = model.predict(x[test]) == y[test]
            hit_majority[test] = y[test] == np.bincount(y[~test]).argmax()
        accuracy.append(np.mean([hit[objects == o].mean() for o in names]))
        majority.append(np.mean([hit_majority[objects == o].mean() for o in names]))
    return {
        "accuracy": round(float(np.mean(accuracy)), 3),
        "accuracy_sd_over_partitions": round(float(np.std(accuracy)), 3),
        "majority": round(float(np.mean(majority)), 3),
    }


def run(data: Path | None, videos: Path | None = None, workers: int = 2) -> dict[str, object]:
    folder = videos if videos is not None else videos_folder(data)
    if folder is None or not folder.is_dir() or not (folder.parent / "labels.csv").is_file():
        return {"skipped": f"real press videos not found at {DEFAULT_VIDEOS}", "met": None}
    labels = _labels(folder)
    paths = sorted(str(p) for p in folder.iterdir() if p.suffix.lower() in VIDEO_SUFFIXES)
    start = time.perf_counter()
    found = [(p, f) for p, f in map_videos(features, paths, workers, chunksize=8) if f is not None]
    seconds = time.perf_counter() - start
    rows = [(re.sub(r"_\d+$", "", Path(p).stem), f) for p, f in found]
    rows = [(o, f) for o, f in rows if o in labels]
    objects = np.array([o for o, _ in rows])
    groups = {k: np.stack([f[k] for _, f in rows]) for k in ("peak", "course", "release")}
    for combo in ("peak+course", "peak+release", "peak+course+release"):
        groups[combo] = np.concatenate([groups[k] for k in combo.split("+")], axis=1)
    scores: dict[str, dict[str, dict[str, float]]] = {}
    for label in LABELS:
        y = np.array([labels[o][label] for o in objects])
        scores[label] = {name: probe(x, y, objects) for name, x in groups.items()}
        for i, name in enumerate(PEAK_NAMES):  # each peak number alone
            scores[label][f"peak: {name}"] = probe(groups["peak"][:, [i]], y, objects)
    return {
        "videos": len(paths),
        "with_press": len(found),
        "labelled_presses": len(rows),
        "labelled_objects": len(set(objects.tolist())),
        "protocol": (
            f"logistic regression (C={C}, standardised) on one press, {FOLDS} object-disjoint "
            f"folds x {PARTITIONS} random partitions; accuracy per press averaged per object"
        ),
        "features_s": round(seconds, 1),
        "scores": scores,
    }


def main(argv: list[str] | None = None) -> int:
    return video_main("touch_cues", run, argv)


if __name__ == "__main__":
    raise SystemExit(main())
