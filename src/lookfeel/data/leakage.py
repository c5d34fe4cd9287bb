"""Leak check: how well does an image's background alone identify its fabric?

A capture session leaves its fingerprint in the pixels where no material lies: the wall, the
floor, the sensor's border sit a few millimetres (or grey levels) differently in every session,
and every drape of a fabric was captured in one session. A model can then learn the session
instead of the material. `leakage_report` measures this, per image modality, for any dataset:

1. **Background pixels.** A pixel is background where it is *static* across the modality's
   images: within ``tolerance`` of its per-pixel median (depth: millimetres; colour and touch:
   8-bit grey levels, the largest of the three channels) in at least ``static_fraction`` of the
   images. Cloth moves by tens of centimetres between drapes, the room by millimetres, so the
   rule finds the room without being told where it is. A user's mask image (white =
   background; resized to the images) replaces the rule for a modality.
2. **Scoring.** Each image is decoded (depth holes filled from the nearest reading),
   mean-pooled by ``pool`` (default: the smallest factor that brings the longer side to at most
   64 px), restricted to the background pixels, and every pixel z-scored over the images. The
   score is the exact pick 1 of 10 (`pick_k_of_n_exact`: each image queries the others, its own
   fabric's other images are the true candidates) top-1, with a 95% bootstrap interval that
   resamples fabrics (`bootstrap_ci`). The same is computed for the whole image, beside chance.
3. **Verdict.** A background *leaks* when its interval's lower bound is above ``factor`` (2)
   times chance: the room alone then tells fabrics apart far better than guessing.
   `leakage_problems` turns each leak into a warning for ``lookfeel data check``. Where
   ``factor`` x chance is 1 or more (fewer than 3 fabrics in a pick, at 2x) no score can lie
   above it: the verdict is then `TOO_FEW`, not "no leak found", which the rule could never
   have contradicted.
4. **Position** (depth, opt-in: ``position=True``, ``lookfeel data leakage --position``).
   Masking the room is not enough when the camera moved between sessions: the cloth then lies
   at a session's own place in the image. `position_leakage` registers every depth image
   (`lookfeel.data.register`, as ``data.depth_input: registered`` does) and scores the same
   pick 1 of 10 from two numbers per image, by their distance in pixels: the image position of
   the drape's top, where the post holds it (`Registration.post_uv`), or the drape's centroid.
   ``data.depth_post_at`` removes the cue from a model's input.
5. **Press videos** (touch). A GelSight's own light (its gel, LEDs and camera, which drift
   between recording sessions) is the background of a press: the **no-contact frame** (the
   mean of the video's frames before contact, `lookfeel.data.video.detect_press`), the sensor
   with nothing touching it, is scored as the background, whole. The whole image is the
   pressed frame as `read_press` picks it with `DataConfig`'s defaults (the deepest contact),
   raw; a third score is the image the models get by default, the pressed frame minus the
   no-contact frame (``data.video_reference: subtract``), which removes most of the light.
   On PhysiCLeAR the no-contact frame alone scores 0.86 (chance 0.10; docs/results/
   real-touch.md, where ``lookfeel cv``'s untouched control is the run's own check). Videos
   with no press are left out, as runs leave them; each video is decoded once (about 0.07 s
   for a 5 s GelSight Mini press, two at a time with ``workers=2``), and its three images are
   made and pooled a band of rows at a time (`_pool_press`), so that a 4K press costs its
   frames and one float32 frame, not a float32 copy of each image.
"""

from __future__ import annotations

import math
import time
import warnings
from collections.abc import Mapping, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from PIL import Image

from lookfeel.config import DataConfig
from lookfeel.data.catalog import Catalog, Item
from lookfeel.data.check import size_problems
from lookfeel.data.images import ImageError, decode_depth, decode_rgb, fill_holes
from lookfeel.data.problems import DatasetError, Problem
from lookfeel.data.video import (
    NoPressError,
    Press,
    band_rows,
    difference_image,
    is_video,
    read_press,
)
from lookfeel.errors import LookfeelError
from lookfeel.metrics.bootstrap import bootstrap_ci
from lookfeel.metrics.distances import pairwise_distances
from lookfeel.metrics.pick import pick_k_of_n_exact
from lookfeel.modality import Modality

__all__ = [
    "DEFAULT_TOLERANCE",
    "LEAK",
    "NOTHING_TO_CHECK",
    "NO_LEAK",
    "TOO_FEW",
    "LeakageReport",
    "MaskError",
    "ModalityLeakage",
    "PositionLeakage",
    "PositionScore",
    "decidable",
    "format_leakage",
    "leakage_problems",
    "leakage_report",
    "load_pooled",
    "parse_mask_options",
    "position_leakage",
    "read_mask",
    "room_pixels",
    "static_mask",
]

DEFAULT_TOLERANCE: Mapping[Modality, float] = {
    Modality.DEPTH: 20.0,  # mm: sessions move the room by a few, drapes move cloth by tens+
    Modality.COLOR: 12.0,  # 8-bit levels
    Modality.TOUCH: 12.0,
}
"""Per modality, how far (depth: mm; colour, touch: 8-bit levels) a static pixel may stray."""

_MAX_SIDE = 64
_N = 10

LEAK = "leak"
"""The verdict (``verdict`` in the JSON) of a score whose interval's lower end lies above
``factor`` x chance."""
NO_LEAK = "no leak"
"""The verdict of a score whose interval's lower end does not."""
TOO_FEW = "too few fabrics"
"""The verdict where ``factor`` x chance is 1 or more (2 fabrics, at 2x: chance 0.50): no
top-1 can lie above it, so the rule cannot find a leak and says nothing of one (`decidable`)."""
NOTHING_TO_CHECK = "nothing to check"
"""The verdict of a modality with no background pixel to score."""


def decidable(chance: float, factor: float) -> bool:
    """Whether the leak rule can be met at all: ``factor`` x ``chance`` below 1 (a top-1 is at
    most 1). With 2 fabrics in a pick, chance 0.50 and 2x chance 1.00: never; with 3, 0.67."""
    return factor * chance < 1.0


class MaskError(LookfeelError):
    """A background mask image cannot be used; the message names the file and why."""


@dataclass(frozen=True)
class ModalityLeakage:
    """The leak check of one modality.

    Attributes:
        modality: the modality scored.
        n_items: images scored (one per depth or colour item, one frame per touch press).
        n_fabrics: fabrics they belong to.
        pooled_shape: (h, w) of the pooled images the scores use.
        pool: the mean-pooling factor.
        mask_source: ``"static"`` (the data-driven rule) or the mask file's path.
        background_fraction: share of the (pooled) pixels that are background.
        whole_top1, whole_ci95: pick 1 of 10 top-1 of the whole image and its 95% interval.
        background_top1, background_ci95: the same on background pixels only (NaN without any:
            ``null`` in `to_dict`, ``n/a`` and why in `format_leakage`).
        chance: top-1 of random guessing (1 / candidates).
        leak: whether the background's interval's lower end lies above ``factor`` x chance.
        press_videos: touch given as press videos (point 5 of the module doc): the whole image
            is the pressed frame, the background the no-contact frame.
        input_top1, input_ci95: press videos: the same of the image lookfeel's models get by
            default, the pressed frame minus the no-contact frame (``data.video_reference:
            subtract``); NaN otherwise.
        left_out: press videos in which no press was found (runs leave them out too).
        folder: the folder the first item lies in (``depth/``, ``videos/`` ...), which a
            warning names; None: ``<root>/<modality>``.
    """

    modality: Modality
    n_items: int
    n_fabrics: int
    pooled_shape: tuple[int, int]
    pool: int
    mask_source: str
    background_fraction: float
    whole_top1: float
    whole_ci95: tuple[float, float]
    background_top1: float
    background_ci95: tuple[float, float]
    chance: float
    leak: bool
    press_videos: bool = False
    input_top1: float = math.nan
    input_ci95: tuple[float, float] = (math.nan, math.nan)
    left_out: int = 0
    folder: str | None = None

    def verdict(self, factor: float = 2.0) -> str:
        """`NOTHING_TO_CHECK` (no background pixel), `LEAK`, `TOO_FEW` (the rule at ``factor``
        x chance cannot be met: `decidable`) or `NO_LEAK`."""
        if self.background_fraction == 0.0 or math.isnan(self.background_top1):
            return NOTHING_TO_CHECK
        if self.leak:
            return LEAK
        return NO_LEAK if decidable(self.chance, factor) else TOO_FEW

    def to_dict(self, factor: float = 2.0) -> dict[str, Any]:
        """The JSON of ``data leakage --json``: the fields, each interval as two numbers
        beside its top-1 (`_intervals`: ``whole_top1_ci_low``, ``whole_top1_ci_high`` ...),
        and the ``verdict``."""
        d = asdict(self)
        d["modality"] = self.modality.value
        d["verdict"] = self.verdict(factor)
        return {k: _json_num(v) for k, v in _intervals(d).items()}


@dataclass(frozen=True)
class PositionScore:
    """How well one position (two numbers per image, in pixels) identifies the fabric.

    Attributes:
        top1, ci95: pick 1 of 10 top-1 by the positions' distance in pixels, and its 95%
            interval.
        within_fabric_px: its spread (std, mean of the two axes) among one fabric's images,
            averaged over fabrics; overall_px: the same over all images.
    """

    top1: float
    ci95: tuple[float, float]
    within_fabric_px: float
    overall_px: float


@dataclass(frozen=True)
class PositionLeakage:
    """Where the drape lies in registered depth images (module doc, point 4).

    Attributes:
        n_items, n_fabrics: depth images registered, and their fabrics.
        image_px: (H, W) of the images (the positions' pixels).
        post_uv: the drape's top, where the post holds it.
        drape_centroid: the drape's centroid.
        chance: top-1 of random guessing.
        leak: whether either interval's lower end lies above ``factor`` x chance.
        no_floor: the depth images in which registration found no floor plane (the cloth
            hides it, or the camera does not see it): their heights are measured from the
            nearest wall instead, so registered depth does not compare them with the rest.
    """

    n_items: int
    n_fabrics: int
    image_px: tuple[int, int]
    post_uv: PositionScore
    drape_centroid: PositionScore
    chance: float
    leak: bool
    no_floor: tuple[str, ...] = ()

    def verdict(self, factor: float = 2.0) -> str:
        """`LEAK`, `TOO_FEW` (the rule at ``factor`` x chance cannot be met: `decidable`) or
        `NO_LEAK`."""
        if self.leak:
            return LEAK
        return NO_LEAK if decidable(self.chance, factor) else TOO_FEW

    def to_dict(self, factor: float = 2.0) -> dict[str, Any]:
        """The JSON of ``data leakage --position --json``: the fields, each position's
        interval as ``top1_ci_low``, ``top1_ci_high`` (`_intervals`), and the ``verdict``."""
        d = asdict(self)
        for name in ("post_uv", "drape_centroid"):
            d[name] = _intervals(d[name])
        out: dict[str, Any] = _json_num(d)
        out["verdict"] = self.verdict(factor)
        return out


@dataclass(frozen=True)
class LeakageReport:
    """`leakage_report`'s answer: one `ModalityLeakage` per modality scored.

    Attributes:
        root: the dataset.
        modalities: per modality, its scores.
        position: where the drape lies in registered depth (`position_leakage`), when asked.
        skipped: modalities not scored, and why (too few fabrics or images).
        tolerance, static_fraction, factor: the settings used (tolerance per modality).
        seconds: how long the check took.
        noun: what the dataset's ids name: ``fabric``, or ``object`` for data that names its
            objects (``videos/<object>_<n>.mov``), as the report's words say.
    """

    root: Path
    modalities: tuple[ModalityLeakage, ...]
    skipped: Mapping[str, str] = field(default_factory=dict)
    tolerance: Mapping[str, float] = field(default_factory=dict)
    static_fraction: float = 0.95
    factor: float = 2.0
    seconds: float = 0.0
    position: PositionLeakage | None = None
    noun: str = "fabric"

    @property
    def leaks(self) -> tuple[ModalityLeakage, ...]:
        """The modalities whose background identifies fabrics far above chance."""
        return tuple(m for m in self.modalities if m.leak)

    def verdict(self) -> str:
        """The whole check's: `LEAK` where any part leaks; else `TOO_FEW` where any part could
        not be decided (`decidable`); else `NO_LEAK` where any part was scored; else
        `NOTHING_TO_CHECK`."""
        parts = [m.verdict(self.factor) for m in self.modalities]
        if self.position is not None:
            parts.append(self.position.verdict(self.factor))
        return next((v for v in (LEAK, TOO_FEW, NO_LEAK) if v in parts), NOTHING_TO_CHECK)

    def to_dict(self) -> dict[str, Any]:
        """The JSON of ``data leakage --json``; the dataset folder is ``data_root``, as in
        ``data info`` and ``index info``."""
        return {
            "data_root": str(self.root),
            "leak": bool(self.leaks) or bool(self.position and self.position.leak),
            "verdict": self.verdict(),
            "modalities": {m.modality.value: m.to_dict(self.factor) for m in self.modalities},
            "position": None if self.position is None else self.position.to_dict(self.factor),
            "skipped": dict(self.skipped),
            "tolerance": dict(self.tolerance),
            "static_fraction": self.static_fraction,
            "factor": self.factor,
            "seconds": round(self.seconds, 3),
            "noun": self.noun,
        }


def _intervals(d: Mapping[str, Any]) -> dict[str, Any]:
    """``d`` with each ``<x>ci95`` pair of a top-1 (the dataclasses' ``whole_ci95``, a
    position's ``ci95``) given as the two numbers ``<x>top1_ci_low`` and ``<x>top1_ci_high``,
    where it stood, as evaluate's ``metrics.json`` names an interval
    (``depth_to_depth_top1_ci_low``)."""
    out: dict[str, Any] = {}
    for k, v in d.items():
        if k.endswith("ci95"):
            metric = k[: -len("ci95")] + "top1"
            out[f"{metric}_ci_low"], out[f"{metric}_ci_high"] = v
        else:
            out[k] = v
    return out


def _json_num(v: Any) -> Any:
    if isinstance(v, float):
        return None if math.isnan(v) else round(v, 4)
    if isinstance(v, tuple | list):
        return [_json_num(x) for x in v]
    if isinstance(v, dict):
        return {k: _json_num(x) for k, x in v.items()}
    return v


# ---- pixels --------------------------------------------------------------------------------


def _frame(item: Item) -> Path:
    # Touch: the frame the models see by default (DataConfig.touch_frame, second to last).
    return item.frame(-2) if item.modality is Modality.TOUCH else item.path


def _decode(item: Item) -> NDArray[np.float32]:
    """(H, W, C) float32: depth in mm (holes filled), colour/touch in 8-bit levels."""
    path = _frame(item)
    if item.modality is Modality.DEPTH:
        return fill_holes(decode_depth(path)).astype(np.float32)[..., None]
    return decode_rgb(path).astype(np.float32)


def _resize(a: NDArray[np.float32], shape: tuple[int, int]) -> NDArray[np.float32]:
    if a.shape[:2] == shape:
        return a
    chans = [
        np.asarray(
            Image.fromarray(a[..., c]).resize((shape[1], shape[0]), Image.Resampling.BILINEAR),
            dtype=np.float32,
        )
        for c in range(a.shape[2])
    ]
    return np.stack(chans, axis=-1)


def _pool(a: NDArray[np.float32], k: int) -> NDArray[np.float32]:
    """Mean-pool the leading two axes of (H, W, ...) by k (the ragged edge is dropped)."""
    if k == 1:
        return a
    h, w = a.shape[0] // k, a.shape[1] // k
    a = a[: h * k, : w * k]
    return a.reshape(h, k, w, k, *a.shape[2:]).mean(axis=(1, 3), dtype=np.float32)


def auto_pool(shape: tuple[int, int]) -> int:
    """The smallest pooling factor bringing the longer side to at most 64 px."""
    return max(1, math.ceil(max(shape) / _MAX_SIDE))


def load_pooled(
    items: Sequence[Item], pool: int | None = None, workers: int = 1
) -> tuple[NDArray[np.float32], tuple[int, int], int]:
    """Decode and mean-pool each item's image, in ``workers`` threads.

    Images of another size than the first are resized to it (bilinear) first.

    Returns:
        ``(stack, shape, pool)``: (N, h, w, C) float32, the full-size (H, W), the factor used.

    Raises:
        ImageError: the first file (in ``items`` order) that cannot be decoded.
    """
    first = _decode(items[0])
    shape = (int(first.shape[0]), int(first.shape[1]))
    k = auto_pool(shape) if pool is None else int(pool)
    if k < 1:
        raise LookfeelError(f"pool must be >= 1; got {pool}")

    def one(it: Item) -> NDArray[np.float32]:
        return _pool(_resize(_decode(it), shape), k)

    rest = items[1:]
    if workers > 1 and len(rest) > 16:
        # Decoding and hole filling release the GIL (1.8x on 2 cores).
        with ThreadPoolExecutor(workers) as ex:
            pooled = list(ex.map(one, rest))
    else:
        pooled = [one(it) for it in rest]
    return np.stack([_pool(first, k), *pooled]), shape, k


def static_mask(
    stack: NDArray[np.float32], tolerance: float, static_fraction: float = 0.95
) -> NDArray[np.bool_]:
    """Pixels that hold still across the images: the background rule (see the module doc).

    Args:
        stack: (N, h, w, C) images.
        tolerance: how far from its per-pixel median a pixel may be and still count as still
            (the largest deviation over channels).
        static_fraction: the share of images in which it must be still.

    Returns:
        (h, w) bool, True where background.
    """
    med = np.median(stack, axis=0)
    near = (np.abs(stack - med[None]).max(axis=-1) <= tolerance).mean(axis=0)
    return np.asarray(near >= static_fraction)


def room_pixels(items: Sequence[Item], workers: int = 1) -> NDArray[np.float64]:
    """(N, B) each depth image's background pixels: what its room alone shows, no cloth.

    The rule of step 1 (module doc) with depth's default tolerance, on the images pooled as
    the leak check pools them; B is 0 where no pixel holds still. `lookfeel cv` fits its
    property probes on them as a control: fabrics captured in one session share a room, so
    where sessions follow the labels the room predicts them without any cloth.

    Raises:
        ImageError: the first file that cannot be decoded.
    """
    stack, _, _ = load_pooled(items, None, workers=workers)
    background = static_mask(stack, DEFAULT_TOLERANCE[Modality.DEPTH])
    return stack[:, background].reshape(len(items), -1).astype(np.float64)


def read_mask(path: str | Path, shape: tuple[int, int], pool: int) -> NDArray[np.bool_]:
    """A user's background mask (white = background), resized to ``shape`` and pooled.

    A pooled pixel is background when at least half of what it pools is.

    Raises:
        MaskError: the file is missing or undecodable, or has no white pixel.
    """
    p = Path(path)
    try:
        im = Image.open(p)
        im.load()
    except FileNotFoundError:
        raise MaskError(f"{p}: mask file not found") from None
    except (OSError, SyntaxError, ValueError) as e:
        raise MaskError(f"{p}: cannot decode mask image: {e}") from None
    grey = np.asarray(im.convert("L").resize((shape[1], shape[0]), Image.Resampling.NEAREST))
    full = (grey >= 128).astype(np.float32)
    if not full.any():
        raise MaskError(f"{p}: mask has no white (background) pixel")
    return np.asarray(_pool(full, pool) >= 0.5)


def parse_mask_options(values: Sequence[str]) -> dict[Modality, Path]:
    """``--mask`` values: ``PATH`` (every modality) or ``MODALITY=PATH`` -> modality -> path.

    Later values win: ``--mask all.png --mask depth=room.png`` masks depth with room.png.

    Raises:
        MaskError: ``MODALITY=`` with no path.
    """
    out: dict[Modality, Path] = {}
    names = {m.value for m in Modality}
    for v in values:
        name, sep, rest = v.partition("=")
        if sep and name in names:
            if not rest:
                raise MaskError(f"--mask {v}: no path after '{name}='")
            out[Modality(name)] = Path(rest)
        else:
            out.update({m: Path(v) for m in Modality})
    return out


# ---- scoring -------------------------------------------------------------------------------


def _top1(
    x: NDArray[np.float32],
    fabric: NDArray[np.int64],
    seed: int,
    n_boot: int,
    zscore: bool = True,
) -> tuple[float, tuple[float, float], float]:
    """Exact pick 1 of 10 top-1 of raw features (z-scored per column unless ``zscore`` is
    False: features in one unit, such as pixels), its interval, chance."""
    x = x.astype(np.float64)
    sd = x.std(axis=0)
    keep = sd > 1e-9
    z = (x[:, keep] - x[:, keep].mean(axis=0)) / (sd[keep] if zscore else 1.0)
    if z.shape[1] == 0:  # nothing varies: every image is the same, nothing to tell apart
        z = np.zeros((len(x), 1))
    dist = pairwise_distances(z, z)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # fewer than 10 fabrics: the chance reported says so
        res = pick_k_of_n_exact(dist, fabric, fabric, n=_N, ks=(1,), exclude_self=np.arange(len(x)))
    per_q = res.per_query[:, 0]
    ok = ~np.isnan(per_q)
    lo, hi = bootstrap_ci(per_q[ok], fabric[ok], n_boot=n_boot, seed=seed)
    return float(res.mean[0]), (float(lo), float(hi)), float(res.chance[0])


def _too_few(fabric: NDArray[np.int64]) -> str | None:
    """Why images of these fabrics cannot be scored by pick 1 of 10, or None."""
    ids, counts = np.unique(fabric, return_counts=True)
    if len(ids) < 2 or not (counts >= 2).any():
        return "needs two fabrics, one of them with two or more images"
    return None


def _read_press(path: Path, config: DataConfig) -> Press:
    """The press of one video as the leak check scores it (module doc, point 5): the frame(s)
    ``config`` picks, raw, and the no-contact frame."""
    return read_press(
        path,
        frames=config.video_frames,
        position=config.video_frame,
        subtract_reference=False,
        gain=config.video_gain,
        rotate=config.video_rotate,
    )


def _pool_press(
    press: Press, gain: float, shape: tuple[int, int], k: int
) -> tuple[NDArray[np.float32], NDArray[np.float32], NDArray[np.float32]]:
    """(pressed, input, no-contact) (h, w, 3) float32 images of one press (`_read_press`), in
    8-bit levels, each mean-pooled by ``k``: the frame(s) read, raw (their mean for several);
    their difference from the no-contact frame as the models get it (``gain``); the no-contact
    frame. A press of another size than ``shape`` (the first one's) is resized to it first.

    Each image is made and pooled a band of rows at a time (whole pooling windows,
    `lookfeel.data.video.band_rows`), so that a press costs its frames and its float32
    no-contact frame, not a full-size float32 copy of each image: a 4K press's were 100 MB
    each. Each pooled pixel is the mean of the same values as pooling the whole image gives,
    in the same order, so the numbers are the same.
    """
    images, reference = press.images, press.reference

    def pressed(rows: slice) -> NDArray[np.float32]:
        return images[:, rows].astype(np.float32).mean(axis=0)

    def model_input(rows: slice) -> NDArray[np.float32]:
        diff = [difference_image(f[rows], reference[rows], gain) for f in images]
        return np.mean(np.stack(diff), axis=0, dtype=np.float32)

    def untouched(rows: slice) -> NDArray[np.float32]:
        return reference[rows].astype(np.float32, copy=False)

    made = (pressed, model_input, untouched)
    if reference.shape[:2] != shape:  # resized whole (bilinear), one image at a time
        p, i, u = (_pool(_resize(make(slice(None)), shape), k) for make in made)
        return p, i, u
    used = shape[0] // k * k  # the rows pooling keeps (it drops the ragged edge)
    step = band_rows(reference[:1].size, k)
    bands = [slice(top, min(top + step, used)) for top in range(0, used, step)] or [slice(0, 0)]
    p, i, u = (np.concatenate([_pool(make(rows), k) for rows in bands]) for make in made)
    return p, i, u


def _score_videos(
    items: Sequence[Item],
    mask: Path | None,
    pool: int | None,
    factor: float,
    seed: int,
    n_boot: int,
    workers: int,
) -> ModalityLeakage | str:
    """`_score_modality` for press videos (module doc, point 5)."""
    config = DataConfig()
    if pool is not None and pool < 1:
        raise LookfeelError(f"pool must be >= 1; got {pool}")
    shape = (0, 0)  # every press is resized to the first one's frame size, then pooled by k
    k = 1

    def one(it: Item) -> tuple[NDArray[np.float32], ...] | None:
        try:
            press = _read_press(it.path, config)
        except NoPressError:
            return None  # runs leave it out: `lookfeel.data.drop_unpressed`
        return _pool_press(press, config.video_gain, shape, k)

    got: list[tuple[NDArray[np.float32], ...] | None] = []
    rest = list(items)
    try:
        while rest and shape == (0, 0):  # the first press found sets the size and pooling
            it = rest.pop(0)
            try:
                press = _read_press(it.path, config)
            except NoPressError:
                got.append(None)
                continue
            shape = (int(press.reference.shape[0]), int(press.reference.shape[1]))
            k = auto_pool(shape) if pool is None else int(pool)
            got.append(_pool_press(press, config.video_gain, shape, k))
            del press
        if workers > 1 and len(rest) > 16:
            with ThreadPoolExecutor(workers) as ex:  # decoding releases the GIL
                got += list(ex.map(one, rest))
        else:
            got += [one(it) for it in rest]
    except ImageError as e:
        return f"cannot decode {e.path}: {e.reason}"
    kept = [(it, g) for it, g in zip(items, got, strict=True) if g is not None]
    fabric = np.array([it.fabric_id for it, _ in kept], dtype=np.int64)
    too_few = _too_few(fabric)
    if too_few:
        return f"{too_few} (press videos with a press: {len(kept)} of {len(items)})"
    pressed, model_input, untouched = (np.stack([g[i] for _, g in kept]) for i in range(3))
    n, h, w, c = pressed.shape
    if mask is not None:
        bg = read_mask(mask, shape, k)[:h, :w]
        source = str(mask)
    else:
        bg = np.ones((h, w), dtype=bool)
        source = "no-contact"
    sel = np.repeat(bg.reshape(-1), c)
    with np.errstate(all="ignore"):
        whole, whole_ci, chance = _top1(pressed.reshape(n, -1), fabric, seed, n_boot)
        given, given_ci, _ = _top1(model_input.reshape(n, -1), fabric, seed, n_boot)
        back, back_ci, _ = _top1(untouched.reshape(n, -1)[:, sel], fabric, seed, n_boot)
    return ModalityLeakage(
        modality=Modality.TOUCH,
        n_items=n,
        n_fabrics=len(np.unique(fabric)),
        pooled_shape=(h, w),
        pool=k,
        mask_source=source,
        background_fraction=float(bg.mean()),
        whole_top1=whole,
        whole_ci95=whole_ci,
        background_top1=back,
        background_ci95=back_ci,
        chance=chance,
        leak=bool(not math.isnan(back_ci[0]) and back_ci[0] > factor * chance),
        press_videos=True,
        input_top1=given,
        input_ci95=given_ci,
        left_out=len(items) - n,
        folder=str(items[0].path.parent),
    )


def _score_modality(
    catalog: Catalog,
    modality: Modality,
    tolerance: float,
    static_fraction: float,
    mask: Path | None,
    pool: int | None,
    factor: float,
    seed: int,
    n_boot: int,
    workers: int,
) -> ModalityLeakage | str:
    items = catalog.items(modality)
    videos = [it for it in items if modality is Modality.TOUCH and is_video(it.path)]
    if videos:
        return _score_videos(videos, mask, pool, factor, seed, n_boot, workers)
    fabric = np.array([it.fabric_id for it in items], dtype=np.int64)
    too_few = _too_few(fabric)
    if too_few:
        return too_few
    ids = np.unique(fabric)
    try:
        stack, shape, k = load_pooled(items, pool, workers)
    except ImageError as e:
        return f"cannot decode {e.path}: {e.reason}"
    n, h, w, c = stack.shape
    if mask is not None:
        bg = read_mask(mask, shape, k)
        if bg.shape != (h, w):  # pooled mask drops the same ragged edge
            bg = bg[:h, :w]
        source = str(mask)
    else:
        bg = static_mask(stack, tolerance, static_fraction)
        source = "static"
    flat = stack.reshape(n, h * w * c)
    with np.errstate(all="ignore"):
        whole, whole_ci, chance = _top1(flat, fabric, seed, n_boot)
        if bg.any():
            sel = np.repeat(bg.reshape(-1), c)
            back, back_ci, _ = _top1(flat[:, sel], fabric, seed, n_boot)
        else:
            back, back_ci = math.nan, (math.nan, math.nan)
    leak = bool(not math.isnan(back_ci[0]) and back_ci[0] > factor * chance)
    return ModalityLeakage(
        modality=modality,
        n_items=n,
        n_fabrics=len(ids),
        pooled_shape=(h, w),
        pool=k,
        mask_source=source,
        background_fraction=float(bg.mean()),
        whole_top1=whole,
        whole_ci95=whole_ci,
        background_top1=back,
        background_ci95=back_ci,
        chance=chance,
        leak=leak,
        folder=str(items[0].path.parent),
    )


def _position_score(
    pos: NDArray[np.float64], fabric: NDArray[np.int64], seed: int, n_boot: int
) -> tuple[PositionScore, float]:
    ok = ~np.isnan(pos).any(axis=1)  # an image without cloth has no position
    top1, ci, chance = _top1(pos[ok].astype(np.float32), fabric[ok], seed, n_boot, zscore=False)
    within = [pos[ok & (fabric == f)].std(axis=0).mean() for f in np.unique(fabric[ok])]
    score = PositionScore(top1, ci, float(np.mean(within)), float(pos[ok].std(axis=0).mean()))
    return score, chance


def position_leakage(
    catalog: Catalog,
    config: DataConfig | None = None,
    *,
    factor: float = 2.0,
    n_boot: int = 1000,
    seed: int = 0,
    workers: int = 2,
) -> PositionLeakage | str:
    """Where the drape lies in each registered depth image, scored as a fabric cue (point 4).

    Args:
        catalog: the dataset; its depth items are registered.
        config: the registration settings (``depth_margin_mm``, ``depth_focal_px``,
            ``depth_cloth``, ``depth_min_height_mm``); default `DataConfig`'s.
        factor, n_boot, seed: as `leakage_report`.
        workers: registration threads (about 0.1 s per 224 px image each).

    Returns:
        A `PositionLeakage`, or why it cannot be scored (no depth, too few fabrics).

    Raises:
        RegistrationError: a file whose room cannot be fitted (named).
    """
    from lookfeel.data.images import decode_depth
    from lookfeel.data.register import (
        RegistrationError,
        drape_post,
        kept_heights,
        register_configured,
    )

    items = catalog.items(Modality.DEPTH)
    fabric = np.array([it.fabric_id for it in items], dtype=np.int64)
    too_few = _too_few(fabric)
    if too_few:
        return too_few
    cfg = config if config is not None else DataConfig(depth_input="registered")

    def one(it: Item) -> tuple[tuple[int, int], list[float], bool]:
        """(image shape, [post u, v, centroid u, v], whether a floor was fitted), the cloth
        registered and kept as `registered_heights` keeps it."""
        try:
            reg = register_configured(decode_depth(it.path), cfg)
        except RegistrationError as e:
            raise RegistrationError(f"{it.path}: cannot register depth: {e}") from None
        height = kept_heights(reg, cfg)
        post = drape_post(reg, height, cfg)
        cloth = np.argwhere(height > 0)
        centroid = cloth.mean(axis=0)[::-1].tolist() if len(cloth) else [math.nan] * 2
        uv = [*(post if post is not None else (math.nan, math.nan)), *centroid]
        return height.shape, uv, reg.plane("floor") is not None

    with ThreadPoolExecutor(max(1, workers)) as ex:
        rows = list(ex.map(one, items))
    pos = np.array([r[1] for r in rows], dtype=np.float64)
    top, chance = _position_score(pos[:, :2], fabric, seed, n_boot)
    centroid, _ = _position_score(pos[:, 2:], fabric, seed, n_boot)
    leak = any(not math.isnan(s.ci95[0]) and s.ci95[0] > factor * chance for s in (top, centroid))
    return PositionLeakage(
        n_items=len(items),
        n_fabrics=len(np.unique(fabric)),
        image_px=rows[0][0],
        post_uv=top,
        drape_centroid=centroid,
        chance=chance,
        leak=leak,
        no_floor=tuple(str(it.path) for it, r in zip(items, rows, strict=True) if not r[2]),
    )


def leakage_report(
    catalog: Catalog,
    *,
    modalities: Sequence[Modality] | None = None,
    masks: Mapping[Modality, str | Path] | None = None,
    tolerance: Mapping[Modality, float] | None = None,
    static_fraction: float = 0.95,
    pool: int | None = None,
    factor: float = 2.0,
    n_boot: int = 1000,
    seed: int = 0,
    workers: int = 2,
    position: bool = False,
    position_config: DataConfig | None = None,
) -> LeakageReport:
    """Score each modality's background against its whole image and chance (module doc).

    Args:
        catalog: the dataset (`scan`).
        modalities: which to score; default every image modality the catalog has.
        masks: per modality, a user's mask image (white = background) replacing the static
            rule.
        tolerance: per modality, how far a static pixel may stray from its median
            (default `DEFAULT_TOLERANCE`: depth 20 mm, colour and touch 12 levels).
        static_fraction: share of images in which a background pixel must be still.
        pool: mean-pooling factor; default: longer side to at most 64 px.
        factor: a background leaks when its interval's lower bound exceeds factor x chance.
        n_boot, seed: the bootstrap over fabrics.
        workers: decoding threads.
        position: also register the depth images and score where the drape lies
            (`position_leakage`, with ``position_config``'s registration settings).

    Returns:
        A `LeakageReport`; modalities that cannot be scored are in ``skipped`` with why (one
        fabric, no image of a modality asked for, ...).

    Raises:
        DatasetError: a catalog with no usable image at all (an empty folder, or one holding
            no image in the layout), in the one line ``data check`` and ``data info`` give
            (`size_problems`): a report of nothing would read as no leak found.
        MaskError: a mask file that cannot be used.
        LookfeelError: bad settings (fractions outside (0, 1], negative tolerance).
    """
    usable = tuple(f for f in catalog.fabrics if any(f.items.values()))
    if not usable:
        raise DatasetError(size_problems(catalog.root, usable))
    if not 0.0 < static_fraction <= 1.0:
        raise LookfeelError(f"static_fraction must be in (0, 1]; got {static_fraction}")
    tol = {**DEFAULT_TOLERANCE, **(tolerance or {})}
    for m, v in tol.items():
        if v < 0:
            raise LookfeelError(f"tolerance must be >= 0; got {v:g} for {m.value}")
    mods = list(modalities) if modalities is not None else list(catalog.modalities)
    masks = dict(masks or {})
    start = time.perf_counter()
    done: list[ModalityLeakage] = []
    skipped: dict[str, str] = {}
    for m in mods:
        mask = masks.get(m)
        res = _score_modality(
            catalog,
            m,
            tol[m],
            static_fraction,
            None if mask is None else Path(mask),
            pool,
            factor,
            seed,
            n_boot,
            workers,
        )
        if isinstance(res, str):
            skipped[m.value] = res
        else:
            done.append(res)
        if m is Modality.TOUCH:
            frames = [it for it in catalog.items(m) if not is_video(it.path)]
            if frames and len(frames) < len(catalog.items(m)):
                skipped["touch frames"] = (
                    f"{len(frames)} presses given as frame images beside press videos: only "
                    "the videos are scored"
                )
    pos = None
    if position:
        got = position_leakage(
            catalog, position_config, factor=factor, n_boot=n_boot, seed=seed, workers=workers
        )
        if isinstance(got, str):
            skipped["position"] = got
        else:
            pos = got
    return LeakageReport(
        root=catalog.root,
        modalities=tuple(done),
        skipped=skipped,
        tolerance={m.value: tol[m] for m in mods},
        static_fraction=static_fraction,
        factor=factor,
        seconds=time.perf_counter() - start,
        position=pos,
        noun="object" if any(f.name is not None for f in catalog.fabrics) else "fabric",
    )


# ---- words ---------------------------------------------------------------------------------


def _ci(ci: tuple[float, float]) -> str:
    return "[ n/a ]" if math.isnan(ci[0]) else f"[{ci[0]:.2f}, {ci[1]:.2f}]"


def _num(x: float, spec: str = ".3f") -> str:
    """A score as the tables print it; ``n/a`` where there is none (never ``nan``)."""
    return "n/a" if math.isnan(x) else format(x, spec)


def _score(top1: float, ci: tuple[float, float], why: str) -> str:
    """``0.480 [0.33, 0.64]``, or ``n/a (why)`` where nothing was scored."""
    return f"n/a ({why})" if math.isnan(top1) else f"{top1:.3f} {_ci(ci)}"


def _rule(ends: Sequence[tuple[str, float]], chance: float, factor: float) -> str:
    """The verdict's rule as it applies: each 95% interval's lower end against ``factor`` x
    chance (a leak: above it), e.g. ``the background's 95% interval's lower end 0.19 is below
    2x chance 0.20``.

    ``ends``: (what, lower end) per score, ``what`` as ``background``, ``drape's top``, or
    ``""`` for ``its``; scores on one side of the rule are said in one clause. Two decimals,
    or up to four where two would print a lower end and the limit alike though they differ.
    """
    limit = factor * chance
    known = [(what, lo) for what, lo in ends if not math.isnan(lo)]
    digits = next(
        (
            d
            for d in (2, 3)
            if all(lo == limit or f"{lo:.{d}f}" != f"{limit:.{d}f}" for _, lo in known)
        ),
        4,
    )
    sides: dict[str, list[tuple[str, float]]] = {}
    for what, lo in known:
        sides.setdefault("above" if lo > limit else "below" if lo < limit else "at", []).append(
            (what, lo)
        )
    clauses = []
    for side, got in sides.items():
        rule = f"{side} {factor:g}x chance {limit:.{digits}f}"
        rule += ", not above it" if side == "at" else ""
        if len(got) == 1:
            what, lo = got[0]
            whose = f"the {what}'s" if what else "its"
            clauses.append(f"{whose} 95% interval's lower end {lo:.{digits}f} is {rule}")
        else:
            names = " and ".join(what for what, _ in got)
            values = " and ".join(f"{lo:.{digits}f}" for _, lo in got)
            clauses.append(f"the 95% intervals' lower ends of the {names}, {values}, are {rule}")
    clauses += [
        f"{f'the {what}' if what else 'it'} has no 95% interval (too few images scored)"
        for what, lo in ends
        if math.isnan(lo)
    ]
    return "; ".join(clauses)


def _source(m: ModalityLeakage) -> str:
    if m.mask_source == "static":
        return "pixels still across images"
    if m.mask_source == "no-contact":
        return "the no-contact frame: the sensor's own light before the press"
    return f"mask {m.mask_source}"


def _background_rule(report: LeakageReport) -> str:
    """How the background was found: the still-pixel rule's settings, and for press videos
    their no-contact frame."""
    units = {"depth": " mm"}
    videos = {m.modality.value for m in report.modalities if m.press_videos}
    tol = [(k, v) for k, v in report.tolerance.items() if k not in videos]
    rules = []
    if tol:
        within = ", ".join(f"{k} {v:g}{units.get(k, ' levels')}" for k, v in tol)
        rules.append(
            f"pixels within {within} of their median in >= {report.static_fraction:.0%} of "
            "images, or a mask"
        )
    if videos:
        rules.append("press videos: their no-contact frame")
    return "; ".join(rules) or "none scored"


def _no_background(m: ModalityLeakage) -> str:
    """Why a modality has no background pixel to score."""
    if m.mask_source == "static":
        return "no pixel is still across images"
    return f"mask {m.mask_source} marks no pixel once pooled {m.pool}x{m.pool}"


def _too_few_to_decide(n: int, chance: float, factor: float, noun: str) -> str:
    """The verdict where the leak rule cannot be met (`TOO_FEW`): said in place of "no leak
    found", which the rule could never have contradicted."""
    said = (
        f"too few {noun}s to decide ({n}): no top-1 can lie above {factor:g}x chance "
        f"{factor * chance:.2f}, so no leak could be found"
    )
    need = math.floor(factor) + 1  # the fewest whose chance, 1 over them, the rule can beat
    return said + (f"; {need} or more {noun}s can tell" if need <= _N else "")


def _verdict(m: ModalityLeakage, factor: float, noun: str = "fabric") -> str:
    if m.background_fraction == 0.0 or math.isnan(m.background_top1):
        return "nothing to check: with no background pixel, there is no background to score"
    rule = _rule([("", m.background_ci95[0])], m.chance, factor)
    if m.leak and m.press_videos:
        return (
            f"LEAK: the sensor with nothing touching it identifies the {noun} at "
            f"{m.background_top1:.2f} top-1, {m.background_top1 / m.chance:.1f}x chance "
            f"({rule}): its light differs between recording sessions, and a model of raw "
            "frames can learn the session instead of the touch; lookfeel's input subtracts "
            f"the no-contact frame (data.video_reference: subtract), which leaves "
            f"{_num(m.input_top1, '.2f')}, and `lookfeel cv` scores its untouched control"
        )
    if m.leak:
        return (
            f"LEAK: the background alone identifies the {noun} at {m.background_top1:.2f} top-1, "
            f"{m.background_top1 / m.chance:.1f}x chance ({rule}); a model can learn the "
            "capture session instead of the material"
        )
    if not decidable(m.chance, factor):
        return _too_few_to_decide(m.n_fabrics, m.chance, factor, noun)
    what = "no-contact frame" if m.press_videos else "background"
    said = f"no leak found: {_rule([(what, m.background_ci95[0])], m.chance, factor)}"
    if m.background_ci95[0] > m.chance:  # under the flag, yet surely above chance
        said += (
            f"; yet the {what} scores above chance ({m.background_top1:.2f} top-1, its interval "
            f"from {m.background_ci95[0]:.2f}, chance {m.chance:.2f}): a weaker session cue, "
            "which a model's background control would show"
        )
    return said


def _modality_lines(m: ModalityLeakage, factor: float, noun: str = "fabric") -> list[str]:
    """The table of one modality: whole image, background only, chance, verdict."""
    pooled = f"pooled {m.pool}x{m.pool} to {m.pooled_shape[0]}x{m.pooled_shape[1]}"
    if not m.press_videos:
        return [
            f"{m.modality.value}: {m.n_items} images of {m.n_fabrics} {noun}s, {pooled}, "
            f"background {m.background_fraction:.0%} of the image ({_source(m)})",
            f"  whole image       {_score(m.whole_top1, m.whole_ci95, 'nothing scored')}",
            "  background only   "
            + _score(m.background_top1, m.background_ci95, _no_background(m)),
            f"  chance            {_num(m.chance)}",
            f"  {_verdict(m, factor, noun)}",
        ]
    left = f" ({m.left_out} with no press left out, as runs leave them)" if m.left_out else ""
    part = "" if m.mask_source == "no-contact" else f" ({m.background_fraction:.0%} of it)"
    back = "the no-contact frame" + ("" if m.mask_source == "no-contact" else f", {_source(m)}")
    return [
        f"{m.modality.value}: {m.n_items} press videos of {m.n_fabrics} {noun}s{left}, {pooled}; "
        f"background: the no-contact frame, the sensor's own light before the press{part}",
        f"  whole image       {_score(m.whole_top1, m.whole_ci95, 'nothing scored')}   the "
        "pressed frame, raw",
        f"  lookfeel's input  {_score(m.input_top1, m.input_ci95, 'nothing scored')}   the "
        "pressed frame minus the no-contact frame",
        "  background only   "
        + _score(m.background_top1, m.background_ci95, _no_background(m))
        + f"   {back}",
        f"  chance            {_num(m.chance)}",
        f"  {_verdict(m, factor, noun)}",
    ]


def _pick(chance: float, sep: str = " ") -> str:
    """``pick 1 of 4``: how many candidates a draw offers, from its chance top-1 (1 over
    them): 10, or every fabric where there are fewer. ``sep`` joins the words."""
    n = round(1 / chance) if math.isfinite(chance) and chance > 0 else _N
    return sep.join(("pick", "1", "of", str(n)))


def _report_pick(report: LeakageReport) -> str:
    """The pick of the report's scores (`_pick`): one size, or the largest where modalities
    hold different numbers of fabrics (each modality's chance says its own)."""
    chances = [m.chance for m in report.modalities]
    if report.position is not None:
        chances.append(report.position.chance)
    picks = sorted({_pick(c) for c in chances}, key=lambda p: int(p.rsplit(" ", 1)[1]))
    if len(picks) > 1:
        return f"{picks[-1]} (or of every {report.noun}, where a modality has fewer)"
    return picks[0] if picks else _pick(1 / _N)


def format_leakage(report: LeakageReport) -> str:
    """The report as text: a table per modality and a verdict line for each (never ``nan``:
    a score that could not be computed reads ``n/a`` and why)."""
    lines = [
        f"Leak check of {report.root}: {_report_pick(report)} top-1 [95% over {report.noun}s] "
        "from raw pixels",
        f"(background: {_background_rule(report)}; {report.seconds:.1f} s)",
    ]
    for m in report.modalities:
        lines += ["", *_modality_lines(m, report.factor, report.noun)]
    if report.position is not None:
        lines += _position_lines(report.position, report.factor, report.noun)
    for name, why in report.skipped.items():
        lines += ["", f"{name}: not scored: {why}"]
    return "\n".join(lines)


def _position_lines(p: PositionLeakage, factor: float, noun: str = "fabric") -> list[str]:
    h, w = p.image_px
    lines = [
        "",
        f"depth, where the drape lies: {p.n_items} images of {p.n_fabrics} {noun}s registered "
        f"({w}x{h} px); two numbers per image, spread within a {noun} / over all in px",
    ]
    cues = (("drape's top", p.post_uv), ("drape's centroid", p.drape_centroid))
    for name, s in cues:
        lines.append(
            f"  {name:<18}{_score(s.top1, s.ci95, f'no image with a {name} found')}   spread "
            f"{_num(s.within_fabric_px, '.1f')} / {_num(s.overall_px, '.1f')}"
        )
    lines.append(f"  chance            {_num(p.chance)}")
    if p.leak:
        limit = factor * p.chance
        rule = _rule([(n, s.ci95[0]) for n, s in cues if s.ci95[0] > limit], p.chance, factor)
        lines.append(
            f"  LEAK: where the drape lies identifies the {noun} ({rule}"
            "): the camera or post moved between sessions; a model of registered depth can read "
            "the session from it (data.depth_post_at moves every drape to one place)"
        )
    elif not decidable(p.chance, factor):
        lines.append(f"  {_too_few_to_decide(p.n_fabrics, p.chance, factor, noun)}")
    else:
        ends = [(name, s.ci95[0]) for name, s in cues]
        lines.append(f"  no leak found: {_rule(ends, p.chance, factor)}")
    if p.no_floor:
        lines.append(f"  {_no_floor(p)}, e.g. {p.no_floor[0]}")
    return lines


def _no_floor(p: PositionLeakage) -> str:
    return (
        f"no floor found in {len(p.no_floor)} of {p.n_items} depth images (the cloth hides "
        "it, or the camera does not see it): their heights are measured from the nearest "
        "wall, so registered depth does not compare them with the rest"
    )


def leakage_problems(report: LeakageReport) -> list[Problem]:
    """One warning per leak found (background per modality; the drape's position), for
    ``lookfeel data check``, and one naming the depth images with no floor fitted (with the
    position check)."""
    pos = report.position
    found: list[Problem] = []
    if pos is not None and pos.leak:
        found.append(
            Problem(
                report.root / Modality.DEPTH.value,
                "where the drape lies in registered depth identifies the fabric at "
                f"{_pick(pos.chance, '-')} top-1 "
                f"{max(pos.post_uv.top1, pos.drape_centroid.top1):.2f} vs chance "
                f"{pos.chance:.2f}: the camera moved between sessions (see `lookfeel data leakage "
                "--position`; data.depth_post_at removes it)",
                "warning",
            )
        )
    if pos is not None and pos.no_floor:
        found.append(
            Problem(Path(pos.no_floor[0]), f"{_no_floor(pos)}; this one among them", "warning")
        )
    return found + [_leak_problem(report.root, m, report.noun) for m in report.leaks]


def _leak_problem(root: Path, m: ModalityLeakage, noun: str = "fabric") -> Problem:
    folder = Path(m.folder) if m.folder is not None else root / m.modality.value
    if m.press_videos:
        return Problem(
            folder,
            f"{m.modality.value}: the no-contact frame of each press video (the sensor's own "
            f"light, nothing touching it) identifies the {noun} at {_pick(m.chance, '-')} top-1 "
            f"{m.background_top1:.2f} {_ci(m.background_ci95)} vs chance {m.chance:.2f}: a "
            "model of raw frames can learn the recording session, not the touch; lookfeel's "
            "input subtracts that frame (data.video_reference: subtract), which leaves "
            f"{m.input_top1:.2f} (see `lookfeel data leakage`; `lookfeel cv` scores the "
            "untouched control)",
            "warning",
        )
    return Problem(
        folder,
        f"{m.modality.value} background ({m.background_fraction:.0%} of the image, "
        f"{_source(m)}) identifies the {noun} at {_pick(m.chance, '-')} top-1 "
        f"{m.background_top1:.2f} {_ci(m.background_ci95)} vs chance {m.chance:.2f}: "
        "a model can learn the capture session, not the material "
        "(see `lookfeel data leakage`)",
        "warning",
    )
