"""Measurements taken from rendered pixels only, to check that the physics shows in the images.

Nothing here reads the generator's variables: drape extent and fold count come from a depth
image (and the empty room, as a real experimenter would capture it once), the fold's width in
a GelSight frame from that frame and the sensor's no-contact frame. Tests and the benchmark
correlate them with the fabrics' true parameters.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy import ndimage, signal

__all__ = [
    "cloth_mask",
    "drape_extent",
    "fold_count",
    "fold_density",
    "touch_contrast",
    "touch_fold_width",
    "touch_texture",
]


def cloth_mask(
    depth: NDArray[np.uint16], room: NDArray[np.float32], margin_mm: float = 25.0
) -> NDArray[np.bool_]:
    """Pixels where something stands at least ``margin_mm`` in front of the empty room."""
    d = depth.astype(np.float32)
    return (d > 0) & (d < room - margin_mm)


def drape_extent(depth: NDArray[np.uint16], room: NDArray[np.float32]) -> float:
    """How far the drape stands out: share of the image's width the cloth covers, averaged
    over the rows where it hangs in front of the wall (rows 20-37% of the height)."""
    mask = cloth_mask(depth, room)
    h = mask.shape[0]
    band = mask[int(0.2 * h) : int(0.37 * h)]
    band = ndimage.binary_closing(band, np.ones((1, 5), bool))
    return float(band.mean())


def _runs(row: NDArray[np.bool_]) -> list[tuple[int, int]]:
    edges = np.flatnonzero(np.diff(np.concatenate([[0], row.astype(np.int8), [0]])))
    return list(zip(edges[0::2].tolist(), edges[1::2].tolist(), strict=True))


def _crests(
    depth: NDArray[np.uint16], room: NDArray[np.float32], prominence_mm: float
) -> tuple[float, float]:
    mask = cloth_mask(depth, room)
    d = depth.astype(np.float32)
    h = mask.shape[0]
    counts, widths = [], []
    for y in range(int(0.2 * h), int(0.5 * h), max(1, h // 112)):
        runs = _runs(mask[y])
        if not runs:
            continue
        a, b = max(runs, key=lambda r: r[1] - r[0])
        cut = max(1, (b - a) // 10)
        prof = d[y, a + cut : b - cut]
        if prof.size < 5:
            continue
        valid = prof > 0
        if not valid.all():
            idx = np.arange(prof.size)
            if valid.any():
                prof = np.interp(idx, idx[valid], prof[valid]).astype(np.float32)
        prof = ndimage.gaussian_filter1d(prof, 1.0)
        peaks, _ = signal.find_peaks(-prof, prominence=prominence_mm)
        counts.append(len(peaks))
        widths.append(prof.size)
    if not counts:
        return 0.0, 0.0
    return float(np.mean(counts)), 100.0 * float(np.sum(counts)) / float(np.sum(widths))


def fold_count(
    depth: NDArray[np.uint16], room: NDArray[np.float32], prominence_mm: float = 3.0
) -> float:
    """Fold crests facing the camera across the hanging cloth, averaged over rows 20-50% down.

    In each row the widest run of cloth is taken, its outer 10% on either side dropped, and
    local depth minima (fold crests) standing out by ``prominence_mm`` counted.
    """
    return _crests(depth, room, prominence_mm)[0]


def fold_density(
    depth: NDArray[np.uint16], room: NDArray[np.float32], prominence_mm: float = 3.0
) -> float:
    """Fold crests per 100 pixels of cloth width (as `fold_count`): the inverse fold width."""
    return _crests(depth, room, prominence_mm)[1]


def touch_texture(frame: NDArray[np.uint8], background: NDArray[np.uint8]) -> float:
    """Fine structure in a GelSight frame: mean absolute high-pass (above ~2 px) of its
    change from the no-contact frame; sensor noise alone gives a small floor."""
    diff = frame.astype(np.float32).sum(-1) - background.astype(np.float32).sum(-1)
    smooth = ndimage.gaussian_filter(diff, 0.7)
    return float(np.abs(smooth - ndimage.gaussian_filter(diff, 2.5)).mean())


def touch_contrast(frame: NDArray[np.uint8], background: NDArray[np.uint8]) -> NDArray[np.float32]:
    """Per-pixel colour change from the sensor's no-contact frame, (H, W), lightly smoothed."""
    diff = np.abs(frame.astype(np.float32) - background.astype(np.float32)).sum(-1)
    return ndimage.gaussian_filter(diff, 1.5).astype(np.float32)


def touch_fold_width(
    frame: NDArray[np.uint8], background: NDArray[np.uint8]
) -> tuple[float, float]:
    """Width and elongation of the contact region in a GelSight frame.

    The contact region is where the colour changed by more than a quarter of the frame's
    strongest change (99.5th percentile). Its second moments give its orientation and extent:
    a fold pressed flat makes a long band whose width grows with the fold's radius; a flat
    press makes a round patch where the domed gel met the cloth.

    Returns:
        ``(width, elongation)``: the band's width, ``sqrt(12)`` times the standard deviation
        across it, as a share of the frame's short side; and the ratio of the extents along
        and across it (about 1 for a round patch, large for a band).
    """
    c = touch_contrast(frame, background)
    h, w = c.shape
    thr = max(0.25 * float(np.percentile(c, 99.5)), 3.0 * float(np.median(c)))
    ys, xs = np.nonzero(c > thr)
    if len(xs) < 10:
        return 0.0, 1.0
    cov = np.cov(np.stack([xs, ys]).astype(np.float64))
    lo, hi = np.linalg.eigvalsh(cov)
    lo = max(float(lo), 1e-6)
    return float(np.sqrt(12.0 * lo)) / min(h, w), float(np.sqrt(max(float(hi), lo) / lo))
