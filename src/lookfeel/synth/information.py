"""The world's information table: how much each modality's pixels reveal about each fabric.

A synthetic world (`lookfeel.synth.generate`) knows every fabric's true parameters. This module
measures, for each latent parameter and each modality, how much of it a simple probe trained on
pixels can recover from held-out fabrics, and how well fabrics can be matched across modalities
using nothing but those probes. It is the world's *honest ceiling* for what a learned model could
pick up from the images: run it before and after a generator change to see which latents became
visible (or invisible) to which sensor.

    >>> result = information_table(Path("out/world"))
    >>> print(format_information_table(result))

or from a shell::

    python -m lookfeel.synth.information out/world --json info.json

How it works, step by step:

1. **Features** (`image_features`): every image becomes a fixed vector computed from its pixels
   only (never from file names or the manifest): a 16x16 thumbnail, per-channel intensity
   quantiles, a radially averaged log power spectrum and gradient-magnitude quantiles at two
   scales. Images are decoded small (`read_image`): JPEG through ``Image.draft``, depth by
   hole-aware block averaging.
2. **Probe** (per latent, per modality): standardise the features, PCA to at most 64 dimensions,
   then ridge regression (continuous latents) or logistic regression (classes). The ridge
   ``alpha`` and logistic ``C`` are chosen by an inner cross-validation that is itself split by
   fabric, on the training fabrics only.
3. **Fabric-disjoint folds**: fabrics (not images) are split into K folds; each fold's fabrics are
   predicted by probes fitted on the other folds' fabrics only. Nothing (scaler, PCA, ridge,
   inner CV) ever sees a held-out fabric.
4. **Scores**: R^2 per image (each image's prediction against its fabric's truth) and per fabric
   (the mean prediction over the fabric's images); class accuracy per image and per fabric beside
   the majority-class rate.
5. **Matching from probes alone**: within a held-out fold, an image of modality A is mapped to its
   predicted latent vector; each fabric of modality B is represented by its mean predicted vector;
   the query picks 1 of 10 (its fabric plus 9 others of the same fold) by Euclidean distance,
   scored as everywhere in lookfeel: the exact expectation over the 9 others
   (`lookfeel.metrics.pick_k_of_n_exact`), an interval resampling fabrics
   (`lookfeel.metrics.bootstrap_ci`).
   Continuous latents are in standard deviations of the training fabrics' truth; each class
   latent's probabilities are divided by ``sqrt(1 - sum p_k^2)`` (p: the training class
   frequencies), so that a one-hot truth block has total variance 1, like one latent.

Reading the table: R^2 is out of sample, so it can be below 0 (a probe worse than the training
mean); about 0 means "not visible to this probe". The probe is linear in fixed features, so it
is a floor on what the pixels hold and a ceiling on what they *easily* give: e.g. touch as a whole
can score below both its flat and fold halves, whose images look different. Within a modality
(A = B) matching rewards any fabric-consistent signal that reaches the predictions, not only
correct latents (the query's own drape or press is left out of its fabric's mean, so the same
press's other frames do not count). Everything is deterministic for a given ``seed`` except the
timings.

Latents: ``log thickness_mm``, ``log density``, ``stiffness``, ``stretchiness``,
``log bending_length_mm`` (continuous) and ``material``, ``weave`` (classes); a latent missing
from the world's ``synth.json`` is skipped.
"""

from __future__ import annotations

import argparse
import importlib
import json
import math
import os
import re
import sys
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from functools import lru_cache
from multiprocessing import get_context
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from PIL import Image
from threadpoolctl import threadpool_limits  # type: ignore[import-untyped]

from lookfeel.data.holes import fill_holes
from lookfeel.data.layout import parse_touch_name
from lookfeel.metrics import bootstrap_ci, pick_k_of_n_exact
from lookfeel.processes import available_cores, die_with_parent

__all__ = [
    "CLASS_LATENTS",
    "CONTINUOUS_LATENTS",
    "MODALITIES",
    "STREAMS",
    "WorldError",
    "WorldImage",
    "extract_features",
    "fabric_folds",
    "feature_names",
    "file_features",
    "format_information_table",
    "image_features",
    "information_table",
    "main",
    "read_image",
    "read_world",
]

MODALITIES = ("depth", "color", "touch")
"""The modalities, as the world's folder names."""

STREAMS = ("depth", "color", "touch", "touch_flat", "touch_fold")
"""Columns of the probe table: the modalities, and touch split by press kind."""

CONTINUOUS_LATENTS: dict[str, tuple[str, bool]] = {
    "log_thickness_mm": ("thickness_mm", True),
    "log_density": ("density", True),
    "stiffness": ("stiffness", False),
    "stretchiness": ("stretchiness", False),
    "log_bending_length_mm": ("bending_length_mm", True),
}
"""Continuous latents: name -> (key in ``synth.json``'s fabric truth, take the log)."""

CLASS_LATENTS = ("material", "weave")
"""Categorical latents (keys in ``synth.json``'s fabric truth)."""

THUMB = 16
"""Side of the thumbnail in the feature vector."""
SPECTRUM_BINS = 12
"""Radial bins of the log power spectrum."""
QUANTILES = (0.02, 0.1, 0.25, 0.5, 0.75, 0.9, 0.98)
"""Intensity quantiles per channel."""
GRADIENT_QUANTILES = (0.5, 0.9, 0.99)
"""Gradient-magnitude quantiles (at each of two scales)."""
MIN_SIDE = 96
"""`read_image` decodes to the smallest size whose short side is still >= this."""
MAX_PCA = 64
"""Most principal components the probe keeps."""
CANDIDATES = 10
"""Matching picks 1 of this many fabrics (the true one and ``CANDIDATES - 1`` others)."""
BOOTSTRAP = 1000
"""Bootstrap resamples (of held-out fabrics) for the matching intervals."""

_RIDGE_ALPHAS = np.logspace(-5.0, 2.0, 15)
"""Ridge penalties, as multiples of the number of training images."""
_LOGISTIC_CS = (0.001, 0.01, 0.1, 1.0)
"""Inverse logistic penalties tried by the inner CV."""
_INNER_FOLDS = 3
_INNER_MAX_ROWS = 3000
_IN_PROCESS_BELOW = 1500


class WorldError(ValueError):
    """The folder is not a complete synthetic world (the message names the path)."""


# ---------------------------------------------------------------------------------------------
# Pixels -> features.


def read_image(path: Path, modality: str, min_side: int = MIN_SIDE) -> NDArray[np.float32]:
    """Decode an image of the world small, keeping its short side at least ``min_side``.

    Args:
        path: the image file.
        modality: ``depth`` (16-bit PNG in mm, 0 = hole), ``color`` or ``touch`` (RGB).
        min_side: smallest acceptable short side; JPEGs are decoded at a reduced DCT scale
            (``Image.draft``), other images reduced by whole-pixel blocks.

    Returns:
        Depth: (H, W) float32 mm with 0 where the block held no reading. Colour and touch:
        (H, W, 3) float32 in 0..255.
    """
    with Image.open(path) as img:
        w, h = img.size
        factor = max(1, min(w, h) // max(1, min_side))
        if modality == "depth":
            d = np.asarray(img, dtype=np.float32)
            if d.ndim == 3:
                d = d[..., 0]
            return _hole_aware_reduce(d, factor)
        if img.format == "JPEG" and factor > 1:
            img.draft("RGB", (math.ceil(w / factor), math.ceil(h / factor)))
        rgb = img.convert("RGB")
        factor = max(1, min(rgb.size) // max(1, min_side))
        if factor > 1:
            rgb = rgb.reduce(factor)
        return np.asarray(rgb, dtype=np.float32)


def _block_sum(a: NDArray[np.float32], factor: int) -> NDArray[np.float32]:
    h, w = a.shape[0] // factor, a.shape[1] // factor
    out = np.zeros((h, w), np.float32)
    for dy in range(factor):
        for dx in range(factor):
            out += a[dy : h * factor : factor, dx : w * factor : factor]
    return out


def _hole_aware_reduce(d: NDArray[np.float32], factor: int) -> NDArray[np.float32]:
    """Mean of the non-zero pixels of each ``factor`` x ``factor`` block (0 if none)."""
    if factor <= 1:
        return d
    total = _block_sum(d, factor)
    if not (d == 0).any():
        reduced: NDArray[np.float32] = total / np.float32(factor * factor)
        return reduced
    count = _block_sum((d > 0).astype(np.float32), factor)
    out: NDArray[np.float32] = np.where(count > 0, total / np.maximum(count, 1.0), 0.0).astype(
        np.float32
    )
    return out


def _quantiles(x: NDArray[np.float32], q: Sequence[float], most: int = 4096) -> NDArray[np.float32]:
    """Quantiles of each row of ``x`` (linear interpolation), from an evenly strided subset of
    at most about ``most`` values per row (exact for smaller rows)."""
    step = max(1, x.shape[-1] // most)
    s = np.sort(x[..., ::step], axis=-1)
    pos = np.asarray(q) * (s.shape[-1] - 1)
    lo = np.floor(pos).astype(np.intp)
    hi = np.minimum(lo + 1, s.shape[-1] - 1)
    frac = (pos - lo).astype(np.float32)
    out: NDArray[np.float32] = s[..., lo] * (1 - frac) + s[..., hi] * frac
    return out


def feature_names(modality: str) -> list[str]:
    """Names of `image_features`' entries for ``modality``, in order."""
    channels = ["depth"] if modality == "depth" else ["r", "g", "b"]
    names = [f"thumb_{c}_{y}_{x}" for c in channels for y in range(THUMB) for x in range(THUMB)]
    names += [f"q{round(q * 100):02d}_{c}" for c in channels for q in QUANTILES]
    names += [f"mean_{c}" for c in channels] + [f"std_{c}" for c in channels]
    names += [f"log_power_{i}" for i in range(SPECTRUM_BINS)]
    names += [f"grad{s}_q{round(q * 100):02d}" for s in (1, 2) for q in GRADIENT_QUANTILES]
    names += ["grad1_mean", "grad2_mean"]
    return names


def image_features(img: NDArray[Any], modality: str) -> NDArray[np.float32]:
    """A fixed feature vector of one image, from its pixels only.

    The entries (named by `feature_names`), for C channels (1 for depth, 3 for RGB):

    - ``16 x 16 x C`` thumbnail (area average; depth holes filled from the nearest reading
      first, values in mm);
    - per channel: intensity quantiles `QUANTILES`, mean and standard deviation;
    - radially averaged log power spectrum of the grey image (mean removed, Hann window) in
      `SPECTRUM_BINS` log-spaced bins of spatial frequency, 2 px .. Nyquist: texture scale,
      independent of orientation;
    - gradient magnitude of the grey image at two scales (the image and its 2x2 block mean):
      quantiles `GRADIENT_QUANTILES` and mean.

    The statistics are invariant to rotation and position, which a linear probe cannot compute
    from raw pixels. The length depends only on the modality (not on the image size).

    Args:
        img: depth: (H, W) mm with 0 = hole; colour and touch: (H, W, 3) RGB (any numeric
            dtype; 0..255). `read_image` gives these.
        modality: ``depth``, ``color`` or ``touch``.

    Returns:
        float32 vector of ``len(feature_names(modality))`` entries.
    """
    a = np.asarray(img, dtype=np.float32)
    if modality == "depth":
        if a.ndim == 3:
            a = a[..., 0]
        a = fill_holes(a)[..., None]
    elif a.ndim == 2:
        a = np.repeat(a[..., None], 3, axis=2)
    elif a.shape[2] != 3:
        a = a[..., :3]
    chans = np.ascontiguousarray(a.transpose(2, 0, 1))  # (C, H, W)
    parts: list[NDArray[np.float32]] = []
    for c in chans:
        thumb = Image.fromarray(c).resize((THUMB, THUMB), Image.Resampling.BOX)
        parts.append(np.asarray(thumb, dtype=np.float32).ravel())
    flat = chans.reshape(len(chans), -1)
    parts.append(_quantiles(flat, QUANTILES).ravel())
    parts.append(flat.mean(axis=1, dtype=np.float64).astype(np.float32))
    parts.append(flat.std(axis=1, dtype=np.float64).astype(np.float32))
    grey = chans.mean(axis=0) if len(chans) > 1 else chans[0]
    parts.append(_log_power_spectrum(grey))
    parts.append(_gradient_stats(grey))
    return np.concatenate(parts).astype(np.float32)


@lru_cache(maxsize=16)
def _spectrum_bins(h: int, w: int) -> tuple[NDArray[np.intp], NDArray[np.float64]]:
    """Radial bin of each rfft2 coefficient (-1: outside the bins), and its weight: 2 for the
    coefficients that stand for their mirror image too, else 1 (the full plane's count)."""
    fy = np.fft.fftfreq(h)[:, None]
    fx = np.fft.rfftfreq(w)[None, :]
    r = np.sqrt(fx**2 + fy**2)
    lo = 1.0 / max(2, min(h, w))
    edges = np.geomspace(lo, 0.5, SPECTRUM_BINS + 1)
    idx = np.searchsorted(edges, r, side="right") - 1
    idx[(r < lo) | (r > 0.5)] = -1
    idx = np.minimum(idx, SPECTRUM_BINS - 1)
    weight = np.full(r.shape, 2.0)
    weight[:, 0] = 1.0
    if w % 2 == 0:
        weight[:, -1] = 1.0
    return idx.astype(np.intp), weight


@lru_cache(maxsize=16)
def _hann(h: int, w: int) -> NDArray[np.float32]:
    return np.outer(np.hanning(h), np.hanning(w)).astype(np.float32)


def _log_power_spectrum(grey: NDArray[np.float32]) -> NDArray[np.float32]:
    h, w = grey.shape
    g = (grey - grey.mean()) * _hann(h, w)
    power = np.abs(np.fft.rfft2(g)) ** 2 / (h * w)
    idx, weight = _spectrum_bins(h, w)
    keep = idx >= 0
    sums = np.bincount(idx[keep], weights=(power * weight)[keep], minlength=SPECTRUM_BINS)
    counts = np.bincount(idx[keep], weights=weight[keep], minlength=SPECTRUM_BINS)
    mean = sums / np.maximum(counts, 1.0)
    return np.log(mean + 1e-6).astype(np.float32)


def _gradient_stats(grey: NDArray[np.float32]) -> NDArray[np.float32]:
    out = []
    means = []
    g = grey
    for scale in (1, 2):
        if scale == 2:
            h, w = (g.shape[0] // 2) * 2, (g.shape[1] // 2) * 2
            g = g[:h, :w].reshape(h // 2, 2, w // 2, 2).mean(axis=(1, 3))
        if min(g.shape) < 3:
            out += [0.0] * len(GRADIENT_QUANTILES)
            means.append(0.0)
            continue
        gy = g[2:, 1:-1] - g[:-2, 1:-1]
        gx = g[1:-1, 2:] - g[1:-1, :-2]
        mag = 0.5 * np.sqrt(gx * gx + gy * gy) * scale  # per original pixel
        out += _quantiles(mag.ravel(), GRADIENT_QUANTILES).tolist()
        means.append(float(mag.mean()))
    return np.asarray(out + means, dtype=np.float32)


def file_features(path: Path, modality: str) -> NDArray[np.float32]:
    """`image_features` of the image at ``path`` decoded by `read_image`."""
    return image_features(read_image(path, modality), modality)


def _features_of_files(items: Sequence[tuple[str, str]]) -> NDArray[np.float32]:
    """Features of ``(path, modality)`` pairs of one modality, stacked (a worker's job)."""
    return np.stack([file_features(Path(p), m) for p, m in items])


# ---------------------------------------------------------------------------------------------
# The world on disk.


_FABRIC = re.compile(r"^F0*(\d+)_")


@dataclass(frozen=True)
class WorldImage:
    """One image of a world, as `read_world` lists it."""

    path: Path
    modality: str
    fabric: int
    group: str
    """Images sharing a group (a drape, a press) are not independent views of the fabric."""
    kind: str | None = None
    """Touch: ``flat`` or ``fold``."""


def read_world(world: Path | str) -> tuple[list[dict[str, Any]], list[WorldImage]]:
    """The fabrics' truth (from ``synth.json``) and the world's images, sorted.

    Raises:
        WorldError: the folder is missing, has no readable ``synth.json``, is not complete,
            lists no fabrics or holds no image.
    """
    world = Path(world)
    if not world.is_dir():
        raise WorldError(f"world folder {world} does not exist (or is not a folder)")
    manifest = world / "synth.json"
    if not manifest.is_file():
        raise WorldError(f"{manifest} not found: {world} is not a `lookfeel synth` world")
    try:
        data = json.loads(manifest.read_text(encoding="utf-8"))
    except (OSError, ValueError) as e:
        raise WorldError(f"{manifest} is not readable JSON ({e})") from None
    if not isinstance(data, dict):
        raise WorldError(f"{manifest} is not a JSON object")
    if data.get("status") != "complete":
        raise WorldError(
            f"world {world} is not complete (synth.json status: {data.get('status')!r}); "
            "wait for `lookfeel synth` to finish"
        )
    fabrics = data.get("fabrics")
    if not isinstance(fabrics, list) or not fabrics:
        raise WorldError(f"{manifest} lists no fabrics")
    try:
        fabrics = [f for f in fabrics if isinstance(f, dict) and "fabric_id" in f]
        known = {int(f["fabric_id"]) for f in fabrics}
    except (TypeError, ValueError):
        raise WorldError(f"{manifest} has a fabric_id that is not an integer") from None
    if not known:
        raise WorldError(f"{manifest} lists no fabric with a fabric_id")
    images: list[WorldImage] = []
    for modality in MODALITIES:
        folder = world / modality
        if not folder.is_dir():
            continue
        for p in sorted(folder.iterdir()):
            if p.name.startswith(".") or p.suffix.lower() not in (".png", ".jpg", ".jpeg"):
                continue
            m = _FABRIC.match(p.stem)
            if m is None or int(m[1]) not in known:
                continue
            fid = int(m[1])
            kind = None
            group = p.stem
            if modality == "touch":
                t = parse_touch_name(p.name)
                if t is not None and t.kind is not None and t.kind.value in ("flat", "fold"):
                    kind = t.kind.value
                    group = f"{kind}_{t.press}"
            images.append(WorldImage(p, modality, fid, group, kind))
    if not images:
        raise WorldError(f"world {world} holds no depth/, color/ or touch/ image")
    return fabrics, images


def _subsample(images: list[WorldImage], cap: int | None, seed: int) -> list[WorldImage]:
    """At most ``cap`` images per fabric of each stream (depth, colour, touch flat, touch fold),
    drawn at random without replacement (keyed by seed, stream and fabric)."""
    if cap is None:
        return images
    by: dict[tuple[str, int], list[WorldImage]] = {}
    for im in images:
        by.setdefault((_stream_of(im), im.fabric), []).append(im)
    keep: list[WorldImage] = []
    codes = {s: i for i, s in enumerate(STREAMS)}
    for (stream, fid), ims in sorted(by.items()):
        if len(ims) <= cap:
            keep += ims
            continue
        rng = np.random.default_rng([seed, 17, codes[stream], fid])
        pick = np.sort(rng.choice(len(ims), size=cap, replace=False))
        keep += [ims[i] for i in pick]
    return sorted(keep, key=lambda im: (MODALITIES.index(im.modality), str(im.path)))


def _stream_of(im: WorldImage) -> str:
    if im.modality == "touch" and im.kind in ("flat", "fold"):
        return f"touch_{im.kind}"
    return im.modality


def _workers(workers: int) -> int:
    return workers if workers > 0 else available_cores()


def extract_features(
    images: Sequence[WorldImage], workers: int = 0, chunk: int = 256
) -> dict[str, NDArray[np.float32]]:
    """Features of every image, stacked per modality in the order given.

    Args:
        images: the images (from `read_world`).
        workers: processes; 0 = one per available core; 1 = in this process (as is any
            call with fewer than 1500 images).
        chunk: images per job.
    """
    # The worker function by its importable name, also when this file runs as ``__main__``.
    module = importlib.import_module("lookfeel.synth.information")
    fn: Callable[[Sequence[tuple[str, str]]], NDArray[np.float32]] = module._features_of_files
    out: dict[str, NDArray[np.float32]] = {}
    n_workers = _workers(workers)
    jobs: list[tuple[str, list[tuple[str, str]]]] = []
    for modality in MODALITIES:
        items = [(str(im.path), modality) for im in images if im.modality == modality]
        jobs += [(modality, items[i : i + chunk]) for i in range(0, len(items), chunk)]
    # A worker costs seconds to start (it imports torch through lookfeel): small jobs stay here.
    if n_workers == 1 or len(jobs) <= 1 or len(images) < _IN_PROCESS_BELOW:
        results = [fn(items) for _, items in jobs]
    else:
        ctx = get_context("spawn")
        with ProcessPoolExecutor(
            min(n_workers, len(jobs)),
            mp_context=ctx,
            initializer=die_with_parent,
            initargs=(os.getpid(),),
        ) as pool:
            results = list(pool.map(fn, [items for _, items in jobs]))
    for modality in MODALITIES:
        parts = [r for (m, _), r in zip(jobs, results, strict=True) if m == modality]
        if parts:
            out[modality] = np.concatenate(parts)
    return out


# ---------------------------------------------------------------------------------------------
# The probe.


def fabric_folds(fabric_ids: Sequence[int], folds: int, seed: int) -> dict[int, int]:
    """Fabric id -> fold (0..folds-1): a seeded shuffle dealt round-robin, so folds differ in
    size by at most one fabric. Every image of a fabric is in its fabric's fold."""
    ids = sorted(set(int(f) for f in fabric_ids))
    if folds < 2 or folds > len(ids):
        raise ValueError(f"folds must be in [2, {len(ids)}] (the number of fabrics), got {folds}")
    order = np.random.default_rng([seed, 11]).permutation(len(ids))
    return {ids[j]: pos % folds for pos, j in enumerate(order)}


class _Reducer:
    """Standardise, then PCA to at most `MAX_PCA` dims (fitted on the rows given only)."""

    def __init__(self, x: NDArray[np.float64]) -> None:
        self.mean = x.mean(axis=0)
        sd = x.std(axis=0)
        self.scale = np.where(sd > 1e-12, sd, 1.0)
        z = (x - self.mean) / self.scale
        k = max(1, min(MAX_PCA, z.shape[0] - 1, z.shape[1]))
        _, s, vt = np.linalg.svd(z, full_matrices=False)
        keep = s[:k] > 1e-9 * max(float(s[0]), 1e-300)
        self.components = vt[:k][keep]

    def __call__(self, x: NDArray[np.float64]) -> NDArray[np.float64]:
        out: NDArray[np.float64] = ((x - self.mean) / self.scale) @ self.components.T
        return out


def _group_splits(groups: NDArray[np.int64], n: int) -> list[NDArray[np.bool_]]:
    """Masks of held-out rows for ``n`` folds over the distinct groups (round-robin)."""
    uniq = np.unique(groups)
    n = min(n, len(uniq))
    fold_of = {int(g): i % n for i, g in enumerate(uniq)}
    f = np.array([fold_of[int(g)] for g in groups])
    return [f == i for i in range(n)]


def _ridge_path(
    x: NDArray[np.float64], y: NDArray[np.float64], alphas: NDArray[np.float64]
) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Ridge weights for every alpha at once: (alphas, d, t) weights, x mean, y mean."""
    xm, ym = x.mean(axis=0), y.mean(axis=0)
    xc = x - xm
    evals, evecs = np.linalg.eigh(xc.T @ xc)
    proj = evecs.T @ (xc.T @ (y - ym))  # (d, t)
    w = np.stack([evecs @ (proj / (np.maximum(evals, 0.0) + a)[:, None]) for a in alphas])
    return w, xm, ym


def _fit_ridge(
    x: NDArray[np.float64], y: NDArray[np.float64], groups: NDArray[np.int64]
) -> Callable[[NDArray[np.float64]], NDArray[np.float64]]:
    """Ridge regression of every column of ``y``, each with its own alpha chosen by an inner
    CV split by ``groups`` (fabrics) on these rows only."""
    alphas = _RIDGE_ALPHAS * len(x)
    err = np.zeros((len(alphas), y.shape[1]))
    splits = _group_splits(groups, _INNER_FOLDS)
    if len(splits) >= 2:
        for held in splits:
            w, xm, ym = _ridge_path(x[~held], y[~held], alphas)
            pred = np.einsum("nd,adt->ant", x[held] - xm, w) + ym
            err += ((pred - y[held]) ** 2).sum(axis=1)
    best = err.argmin(axis=0)
    w, xm, ym = _ridge_path(x, y, alphas)
    wb = np.stack([w[best[t], :, t] for t in range(y.shape[1])], axis=1)

    def predict(xn: NDArray[np.float64]) -> NDArray[np.float64]:
        out: NDArray[np.float64] = (xn - xm) @ wb + ym
        return out

    return predict


def _fit_logistic(
    x: NDArray[np.float64], labels: NDArray[np.int64], n_classes: int, groups: NDArray[np.int64]
) -> Callable[[NDArray[np.float64]], NDArray[np.float64]]:
    """Multinomial logistic regression on ``x``, with C chosen by an inner CV split
    by ``groups`` (on at most `_INNER_MAX_ROWS` rows, C path warm-started); the returned
    function gives probabilities over all ``n_classes`` (0 for classes absent here)."""
    from sklearn.exceptions import ConvergenceWarning
    from sklearn.linear_model import LogisticRegression

    present = np.unique(labels)
    if len(present) == 1:
        const = np.zeros(n_classes)
        const[present[0]] = 1.0
        return lambda xn: np.tile(const, (len(xn), 1))
    # One scale for all components (not whitening): the penalty keeps favouring the
    # principal directions, as ridge does; the scale only helps the solver.
    sd = float(x.std())
    sd = sd if sd > 1e-12 else 1.0
    xw = x / sd

    def fit_path(xf: NDArray[np.float64], yf: NDArray[np.int64]) -> list[Any]:
        model = LogisticRegression(C=_LOGISTIC_CS[0], max_iter=200, tol=1e-3, warm_start=True)
        models = []
        for c in _LOGISTIC_CS:
            model.set_params(C=c)
            model.fit(xf, yf)
            models.append((c, model.classes_.copy(), model.coef_.copy(), model.intercept_.copy()))
        return models

    def proba(m: Any, xn: NDArray[np.float64]) -> NDArray[np.float64]:
        _, classes, coef, intercept = m
        p = np.zeros((len(xn), n_classes))
        if len(classes) == 2:  # sklearn keeps one logit for two classes
            s = xn @ coef[0] + intercept[0]
            p[:, classes[1]] = 1.0 / (1.0 + np.exp(-s))
            p[:, classes[0]] = 1.0 - p[:, classes[1]]
            return p
        logits = xn @ coef.T + intercept
        logits -= logits.max(axis=1, keepdims=True)
        e = np.exp(logits)
        p[:, classes] = e / e.sum(axis=1, keepdims=True)
        return p

    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        loss = np.zeros(len(_LOGISTIC_CS))
        rows = np.arange(len(xw))
        if len(rows) > _INNER_MAX_ROWS:  # C needs no more rows; evenly strided, deterministic
            rows = rows[:: math.ceil(len(rows) / _INNER_MAX_ROWS)]
        xs, ys, gs = xw[rows], labels[rows], groups[rows]
        for held in _group_splits(gs, _INNER_FOLDS):
            if len(np.unique(ys[~held])) < 2:
                continue
            for i, m in enumerate(fit_path(xs[~held], ys[~held])):
                p = proba(m, xs[held]) + 1e-6
                loss[i] -= np.log(p[np.arange(len(p)), ys[held]] / p.sum(axis=1)).sum()
        best = int(loss.argmin())
        model = LogisticRegression(C=_LOGISTIC_CS[best], max_iter=300, tol=1e-4).fit(xw, labels)
    final = (_LOGISTIC_CS[best], model.classes_, model.coef_, model.intercept_)
    return lambda xn: proba(final, xn / sd)


@dataclass
class _Latents:
    """The fabrics' truth as arrays, rows in the order of ``ids``."""

    ids: list[int]
    continuous: dict[str, NDArray[np.float64]]
    classes: dict[str, tuple[list[str], NDArray[np.int64]]]


def _latents(fabrics: list[dict[str, Any]]) -> _Latents:
    ids = [int(f["fabric_id"]) for f in fabrics]
    cont: dict[str, NDArray[np.float64]] = {}
    for name, (key, log) in CONTINUOUS_LATENTS.items():
        vals = [f.get(key) for f in fabrics]
        if not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in vals):
            continue
        v = np.asarray(vals, dtype=np.float64)
        if log:
            if (v <= 0).any():
                continue
            v = np.log(v)
        cont[name] = v
    classes: dict[str, tuple[list[str], NDArray[np.int64]]] = {}
    for key in CLASS_LATENTS:
        labs = [f.get(key) for f in fabrics]
        if not all(isinstance(v, str) for v in labs):
            continue
        names = sorted(set(str(v) for v in labs))
        classes[key] = (names, np.array([names.index(str(v)) for v in labs], dtype=np.int64))
    return _Latents(ids, cont, classes)


def _r2(pred: NDArray[np.float64], truth: NDArray[np.float64]) -> float | None:
    sst = float(((truth - truth.mean()) ** 2).sum())
    if sst <= 1e-12 or len(truth) < 2:
        return None
    return 1.0 - float(((pred - truth) ** 2).sum()) / sst


def _round(v: float | None, digits: int = 4) -> float | None:
    return None if v is None or not math.isfinite(v) else round(float(v), digits)


@dataclass
class _StreamPredictions:
    """Out-of-fold predictions of one stream: rows are its images."""

    fabric: NDArray[np.int64]  # fabric id per image
    group: list[str]
    continuous: NDArray[np.float64]  # (n, n_cont), truth units
    probs: dict[str, NDArray[np.float64]]  # class latent -> (n, n_classes)
    vector: NDArray[np.float64]  # (n, dims): the matching space (training-truth units)


def _probe_stream(
    x: NDArray[np.float64],
    fabric: NDArray[np.int64],
    group: list[str],
    lat: _Latents,
    fold_of: dict[int, int],
    folds: int,
) -> _StreamPredictions:
    """Fit and apply the probes of one stream fold by fabric-disjoint fold."""
    row = {fid: i for i, fid in enumerate(lat.ids)}
    fi = np.array([row[int(f)] for f in fabric])
    fold = np.array([fold_of[int(f)] for f in fabric])
    cont_names = list(lat.continuous)
    y = (
        np.stack([lat.continuous[n][fi] for n in cont_names], axis=1)
        if cont_names
        else np.zeros((len(x), 0))
    )
    pred = np.full_like(y, np.nan)
    probs = {k: np.full((len(x), len(names)), np.nan) for k, (names, _) in lat.classes.items()}
    dims = len(cont_names) + sum(len(names) for names, _ in lat.classes.values())
    vector = np.full((len(x), dims), np.nan)
    fold_fabrics = np.array([fold_of[f] for f in lat.ids])
    for k in range(folds):
        test = fold == k
        train = ~test
        if not test.any() or not train.any():
            continue
        reducer = _Reducer(x[train])
        ztr, zte = reducer(x[train]), reducer(x[test])
        # Matching units: the training fabrics' truth (fabric level, not image level).
        tr_fab = fold_fabrics != k
        parts = []
        if cont_names:
            predict = _fit_ridge(ztr, y[train], fabric[train])
            pred[test] = predict(zte)
            mu = np.array([lat.continuous[n][tr_fab].mean() for n in cont_names])
            sd = np.array([lat.continuous[n][tr_fab].std() for n in cont_names])
            parts.append((pred[test] - mu) / np.where(sd > 1e-12, sd, 1.0))
        for key, (names, labels) in lat.classes.items():
            clf = _fit_logistic(ztr, labels[fi[train]], len(names), fabric[train])
            probs[key][test] = clf(zte)
            freq = np.bincount(labels[tr_fab], minlength=len(names)) / max(1, int(tr_fab.sum()))
            spread = 1.0 - float((freq**2).sum())
            # A one-hot truth block then has total variance 1, like one standardised latent.
            parts.append(probs[key][test] / math.sqrt(spread if spread > 1e-12 else 1.0))
        if parts:
            vector[test] = np.concatenate(parts, axis=1)
    return _StreamPredictions(fabric, group, pred, probs, vector)


def _score_stream(p: _StreamPredictions, lat: _Latents) -> dict[str, Any]:
    row = {fid: i for i, fid in enumerate(lat.ids)}
    fi = np.array([row[int(f)] for f in p.fabric])
    fabs = np.unique(fi)
    members = [fi == f for f in fabs]
    out: dict[str, Any] = {"images": len(fi), "fabrics": len(fabs)}
    for j, name in enumerate(lat.continuous):
        truth = lat.continuous[name]
        per_image = p.continuous[:, j]
        per_fabric = np.array([per_image[m].mean() for m in members])
        out[name] = {
            "r2_fabric": _round(_r2(per_fabric, truth[fabs])),
            "r2_image": _round(_r2(per_image, truth[fi])),
        }
    for key, (names, labels) in lat.classes.items():
        pr = p.probs[key]
        img_ok = pr.argmax(axis=1) == labels[fi]
        fab_ok = np.array(
            [pr[m].mean(axis=0).argmax() == labels[f] for f, m in zip(fabs, members, strict=True)]
        )
        counts = np.bincount(labels[fabs], minlength=len(names))
        img_counts = np.bincount(labels[fi], minlength=len(names))
        out[key] = {
            "acc_fabric": _round(float(fab_ok.mean())),
            "acc_image": _round(float(img_ok.mean())),
            "majority_fabric": _round(float(counts.max() / counts.sum())),
            "majority_image": _round(float(img_counts.max() / img_counts.sum())),
            "classes": len(names),
        }
    return out


# ---------------------------------------------------------------------------------------------
# Matching from the probes.


def _match(
    a: _StreamPredictions,
    b: _StreamPredictions,
    fold_of: dict[int, int],
    same: bool,
    seed: int,
    pair_code: int,
) -> dict[str, Any]:
    """Pick 1 of `CANDIDATES` by Euclidean distance between A's image predictions and B's
    fabric mean predictions, candidates from the query's held-out fold.

    Scored as the rest of the project scores: the exact expectation over the distractor draw
    (`lookfeel.metrics.pick_k_of_n_exact`, per fold) and a percentile interval resampling the
    query fabrics (`lookfeel.metrics.bootstrap_ci`). With ``same`` (A = B) the query's own
    drape or press is left out of its fabric's mean.
    """
    b_fabs = np.unique(b.fabric)
    sums = {int(f): b.vector[b.fabric == f].sum(axis=0) for f in b_fabs}
    counts = {int(f): int((b.fabric == f).sum()) for f in b_fabs}
    group_sums: dict[tuple[int, str], tuple[NDArray[np.float64], int]] = {}
    if same:
        for i, (fab, grp) in enumerate(zip(b.fabric, b.group, strict=True)):
            part, k = group_sums.get((int(fab), grp), (np.zeros(b.vector.shape[1]), 0))
            group_sums[(int(fab), grp)] = (part + b.vector[i], k + 1)
    ok = np.isfinite(a.vector).all(axis=1)
    values, groups, chance = [], [], []
    for fold in sorted({fold_of[int(f)] for f in b_fabs}):
        fabs = np.array([f for f in b_fabs if fold_of[int(f)] == fold])
        if len(fabs) < 2:
            continue
        gallery = np.stack([sums[int(fid)] / counts[int(fid)] for fid in fabs])
        rows = np.flatnonzero(ok & np.isin(a.fabric, fabs))
        dist = np.linalg.norm(a.vector[rows, None, :] - gallery[None], axis=-1)
        if same:
            keep = []
            for r, q in enumerate(rows.tolist()):
                fid = int(a.fabric[q])
                part, k = group_sums[(fid, a.group[q])]
                if counts[fid] - k < 1:
                    continue  # nothing of its fabric left once its own drape or press is out
                own = (sums[fid] - part) / (counts[fid] - k)
                dist[r, int(np.searchsorted(fabs, fid))] = np.linalg.norm(a.vector[q] - own)
                keep.append(r)
            rows, dist = rows[keep], dist[keep]
        if not len(rows):
            continue
        res = pick_k_of_n_exact(dist, a.fabric[rows], fabs, n=CANDIDATES, ks=(1,))
        values.append(res.per_query[:, 0])
        groups.append(a.fabric[rows])
        chance.append(np.full(len(rows), res.chance[0]))
    if not values:
        return {"top1": None, "ci95": [None, None], "chance": None, "queries": 0, "fabrics": 0}
    v, fabric = np.concatenate(values), np.concatenate(groups)
    lo, hi = bootstrap_ci(v, fabric, n_boot=BOOTSTRAP, seed=seed * 1000 + pair_code)
    return {
        "top1": _round(float(v.mean())),
        "ci95": [_round(float(lo)), _round(float(hi))],
        "chance": _round(float(np.concatenate(chance).mean())),
        "queries": len(v),
        "fabrics": len(np.unique(fabric)),
    }


# ---------------------------------------------------------------------------------------------
# The table.


def _probe_all(
    feats: dict[str, NDArray[np.float32]],
    by_mod: dict[str, list[WorldImage]],
    lat: _Latents,
    fold_of: dict[int, int],
    folds: int,
) -> tuple[dict[str, _StreamPredictions], dict[str, Any]]:
    """Probe every stream: out-of-fold predictions and scores, by stream."""
    preds: dict[str, _StreamPredictions] = {}
    probe: dict[str, Any] = {}
    for stream in STREAMS:
        modality = stream.split("_")[0]
        if modality not in feats:
            continue
        ims = by_mod[modality]
        mask = np.array([stream == modality or _stream_of(im) == stream for im in ims])
        sel = [im for im, k in zip(ims, mask, strict=True) if k]
        fab = np.array([im.fabric for im in sel], dtype=np.int64)
        if len(np.unique(fab)) < folds:
            continue
        p = _probe_stream(
            feats[modality][mask].astype(np.float64),
            fab,
            [im.group for im in sel],
            lat,
            fold_of,
            folds,
        )
        preds[stream] = p
        probe[stream] = _score_stream(p, lat)
    return preds, probe


def information_table(
    world: Path | str,
    folds: int = 5,
    seed: int = 0,
    max_images_per_fabric: int | None = None,
    workers: int = 0,
) -> dict[str, Any]:
    """Measure how much each modality's pixels reveal about each latent of the world.

    Args:
        world: a complete `lookfeel synth` output folder.
        folds: fabric-disjoint folds (each fabric is held out exactly once).
        seed: seeds the folds, the subsampling, the matching candidates and the bootstrap.
        max_images_per_fabric: keep at most this many images per fabric of each of depth,
            colour, touch-flat and touch-fold (drawn at random; ``None``: all).
        workers: feature-extraction processes; 0 = one per available core; 1 = in-process.

    Returns:
        JSON-able dict: ``probe[stream][latent]`` holds ``r2_fabric`` / ``r2_image`` for
        continuous latents, ``acc_fabric`` / ``acc_image`` beside ``majority_fabric`` /
        ``majority_image`` for classes; ``matching["A->B"]`` holds ``top1``, its ``ci95``
        (bootstrap over held-out fabrics), ``chance``, ``queries`` and ``fabrics``; plus what
        was measured on (counts, feature sizes, seconds). R^2 is ``None`` where the truth does
        not vary.

    Raises:
        WorldError: ``world`` is not a complete synthetic world.
        ValueError: ``folds`` is not in [2, number of fabrics].
    """
    started = time.perf_counter()
    world = Path(world)
    fabrics, images = read_world(world)
    lat = _latents(fabrics)
    fold_of = fabric_folds(lat.ids, folds, seed)
    images = _subsample(images, max_images_per_fabric, seed)
    t0 = time.perf_counter()
    feats = extract_features(images, workers)
    feature_s = time.perf_counter() - t0
    t0 = time.perf_counter()

    by_mod = {m: [im for im in images if im.modality == m] for m in feats}
    # Small matrices: one BLAS thread is faster, and far faster on a busy machine.
    with threadpool_limits(limits=1):
        preds, probe = _probe_all(feats, by_mod, lat, fold_of, folds)
    probe_s = time.perf_counter() - t0

    t0 = time.perf_counter()
    matching: dict[str, Any] = {}
    mods = [m for m in MODALITIES if m in preds]
    for i, a in enumerate(mods):
        for j, b in enumerate(mods):
            matching[f"{a}->{b}"] = _match(
                preds[a], preds[b], fold_of, a == b, seed, 10 * i + j + 1
            )
    match_s = time.perf_counter() - t0

    counts = {m: len(v) for m, v in by_mod.items()}
    for stream in ("touch_flat", "touch_fold"):
        counts[stream] = sum(1 for im in by_mod.get("touch", []) if _stream_of(im) == stream)
    return {
        "what": "how much each modality's pixels reveal about each latent: fabric-disjoint "
        f"{folds}-fold probes (standardise, PCA <= {MAX_PCA}, ridge / logistic with inner "
        f"fabric-split CV) and pick-1-of-{CANDIDATES} matching from the probes' predictions",
        "world": str(world),
        "fabrics": len(lat.ids),
        "folds": folds,
        "seed": seed,
        "max_images_per_fabric": max_images_per_fabric,
        "images": counts,
        "features": {m: int(f.shape[1]) for m, f in feats.items()},
        "latents": {"continuous": list(lat.continuous), "classes": list(lat.classes)},
        "probe": probe,
        "matching": matching,
        "seconds": {
            "features": round(feature_s, 2),
            "features_ms_per_image": round(1000 * feature_s / max(1, len(images)), 3),
            "probes": round(probe_s, 2),
            "matching": round(match_s, 2),
            "total": round(time.perf_counter() - started, 2),
        },
    }


def _fmt(v: Any, digits: int = 2) -> str:
    return "–" if v is None else f"{v:.{digits}f}"


def format_information_table(result: dict[str, Any]) -> str:
    """Markdown tables of an `information_table` result.

    First the probes: rows are latents, columns the streams; a continuous latent's cell is
    ``per-fabric R^2 (per-image R^2)``, a class's cell ``per-fabric accuracy (per-image)`` with
    the majority-class rate in the row's name. Then the matching: rows query modality A,
    columns gallery modality B, cells ``top-1 [95% interval]``.
    """
    probe: dict[str, Any] = result["probe"]
    streams = [s for s in STREAMS if s in probe]
    heads = {
        "depth": "depth",
        "color": "colour",
        "touch": "touch",
        "touch_flat": "touch-flat",
        "touch_fold": "touch-fold",
    }
    lines = [
        f"Information table of {result['world']} ({result['fabrics']} fabrics, "
        f"{result['folds']} fabric-disjoint folds, seed {result['seed']})",
        "",
        "| latent | " + " | ".join(heads[s] for s in streams) + " |",
        "|---|" + "---:|" * len(streams),
    ]
    for name in result["latents"]["continuous"]:
        cells = [
            f"{_fmt(probe[s][name]['r2_fabric'])} ({_fmt(probe[s][name]['r2_image'])})"
            for s in streams
        ]
        lines.append(f"| {name} R² | " + " | ".join(cells) + " |")
    for key in result["latents"]["classes"]:
        first = probe[streams[0]][key] if streams else {}
        label = (
            f"{key} acc ({first.get('classes')} classes, majority "
            f"{_fmt(first.get('majority_fabric'))})"
        )
        cells = [
            f"{_fmt(probe[s][key]['acc_fabric'])} ({_fmt(probe[s][key]['acc_image'])})"
            for s in streams
        ]
        lines.append(f"| {label} | " + " | ".join(cells) + " |")
    lines += [
        "",
        "Cells: per fabric (per image). R² of the prediction averaged over the fabric's images "
        "(of each image); class accuracy likewise.",
        "",
    ]
    matching: dict[str, Any] = result["matching"]
    mods = [m for m in MODALITIES if f"{m}->{m}" in matching]
    if mods:
        chance = [v["chance"] for v in matching.values() if v.get("chance") is not None]
        lines += [
            f"Pick 1 of {CANDIDATES} (the true fabric and others of its held-out fold) by "
            "distance between the probes' predictions: top-1 [95% interval over fabrics], "
            f"chance {_fmt(float(np.mean(chance)) if chance else None)}. Rows: query images "
            "of A; columns: fabrics of B, each its images' mean prediction (A = B: the "
            "query's own drape or press left out).",
            "",
            "| A \\ B | " + " | ".join(heads[m] for m in mods) + " |",
            "|---|" + "---:|" * len(mods),
        ]
        for a in mods:
            cells = []
            for b in mods:
                v = matching[f"{a}->{b}"]
                lo, hi = v["ci95"]
                cells.append(f"{_fmt(v['top1'])} [{_fmt(lo)}, {_fmt(hi)}]")
            lines.append(f"| {heads[a]} | " + " | ".join(cells) + " |")
    secs = result.get("seconds", {})
    if secs:
        lines += [
            "",
            f"{sum(result['images'][m] for m in MODALITIES if m in result['images'])} images; "
            f"features {secs['features']} s ({secs['features_ms_per_image']} ms/image), "
            f"probes {secs['probes']} s, matching {secs['matching']} s, "
            f"total {secs['total']} s.",
        ]
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    """``python -m lookfeel.synth.information WORLD [--json OUT]``: print the tables."""
    parser = argparse.ArgumentParser(
        prog="python -m lookfeel.synth.information",
        description="How much each modality's pixels reveal about each latent of a synthetic "
        "world (probes and cross-modal matching).",
    )
    parser.add_argument("world", type=Path, help="a complete `lookfeel synth` output folder")
    parser.add_argument("--json", type=Path, default=None, help="also write the result here")
    parser.add_argument("--folds", type=int, default=5)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--max-images-per-fabric", type=int, default=None)
    parser.add_argument("--workers", type=int, default=0, help="0 = one per core")
    args = parser.parse_args(argv)
    try:
        result = information_table(
            args.world, args.folds, args.seed, args.max_images_per_fabric, args.workers
        )
    except (WorldError, ValueError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    if args.json is not None:
        from lookfeel.atomic import atomic_write_text

        atomic_write_text(args.json, json.dumps(result, indent=2) + "\n")
    print(format_information_table(result), end="")
    return 0


if __name__ == "__main__":
    sys.exit(main())
