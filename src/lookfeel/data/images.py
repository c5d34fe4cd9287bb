"""Decoding and preprocessing images as the authors' code did, configurable, cached once per run.

- Depth: 16-bit PNG in millimetres; holes (0) filled from the nearest valid pixel (or left to
  the authors' mapping, where 0 mm falls below the range and becomes 0); mapped to [0, 1] as
  ``clip((d - 800) / 500, 0, 1)``; resized to the network size. Output (1, S, S) float32.
- Colour: 8-bit RGB, optionally centre-cropped to a square, resized. Output (3, S, S) in [0, 1].
- Touch: one frame of a press (the second-to-last by default, as the authors' code); a 960x720
  GelSight frame is cropped to its central 720x720 first; smaller sensors' frames (GelSight
  Mini, DIGIT) are kept whole. Output (3, S, S) in [0, 1]. A touch item may also be a press
  video (`lookfeel.data.files.VIDEO_SUFFIXES`: .mov, .mp4, .mkv ...): its press is found and
  one frame taken (the deepest contact or ``video_frame``) or the mean of ``video_frames``
  across the contact span, by default as its difference from the no-contact frames
  (`lookfeel.data.video.read_press`; every frame turned first by ``video_rotate``), then
  cropped and resized like a touch image.

Every file goes through one policy (`read_image_file`, `open_image`): it must be a regular file
(a FIFO, device or folder named like an image is refused at once, never waited on), and its
declared width x height must not exceed ``max_pixels`` (`DEFAULT_MAX_PIXELS`), checked from the
header before a pixel is decoded, so a small "decompression bomb" costs nothing. A truncated or
undecodable file raises `ImageError` naming the file. (Symbolic links leaving a dataset's folder
are refused by `lookfeel.data.layout.scan`, which knows the folder.)

`ImageLoader` keeps every preprocessed image in memory (as uint8 for RGB, float32 for depth)
and, with ``cache_dir``, on disk keyed by the file's content and the preprocessing settings
(`PreprocessSettings`: among them a press video's turn and the press detector's version,
`lookfeel.data.video.PRESS_DETECTOR_VERSION`). Of a press video it also keeps whether it had
no colour (`ImageLoader.is_grey`, `lookfeel.data.video.Press.grey`), in memory and beside its
disk cache entry (``<entry>.json``), so that nothing decodes the video again to ask. A depth
image with no valid pixel (all 0) is read as a blank input; the loader warns of such images
once (`BlankDepthWarning`), naming the first and counting those a preload read.
"""

from __future__ import annotations

import functools
import hashlib
import io
import json
import os
import threading
import warnings
from collections.abc import Callable, Iterable, Iterator, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from struct import error as struct_error
from typing import Any, TypeVar

import numpy as np
import torch
from PIL import Image, ImageFile

from lookfeel.atomic import atomic_write, atomic_write_text
from lookfeel.config import DataConfig
from lookfeel.data.catalog import Item
from lookfeel.data.files import DEFAULT_MAX_PIXELS, ImageError, file_kind, read_image_file
from lookfeel.data.holes import UNSEEN_REGION, fill_holes
from lookfeel.data.layout import IMAGE_SUFFIXES, press_frame_files
from lookfeel.data.video import (
    PRESS_DETECTOR_VERSION,
    VideoError,
    deep_frames,
    is_video,
    read_press,
    view_frames,
)
from lookfeel.modality import Modality, reprint_path
from lookfeel.processes import can_fork

__all__ = [
    "CACHE_SETTINGS",
    "DEFAULT_MAX_PIXELS",
    "GELSIGHT_SIZE",
    "WALL_GAP_NONE",
    "ArrayLoader",
    "BlankDepthWarning",
    "ImageError",
    "ImageLoader",
    "PreprocessSettings",
    "declared_size",
    "decode_depth",
    "decode_rgb",
    "depth_to_unit",
    "file_kind",
    "fill_holes",
    "open_rgb",
    "png_header",
    "preprocess_depth",
    "preprocess_rgb",
    "read_image_file",
    "registered_to_unit",
    "stack_views",
    "to_tensor",
]

ImageFile.LOAD_TRUNCATED_IMAGES = False  # a truncated file must fail, never decode half-grey
PROCESS_DECODE_MIN = 256
"""With ``data.decode: auto``, fewer files than this are decoded in threads: a pool of worker
processes is not worth starting for them."""
GELSIGHT_SIZE = (960, 720)
"""Frame size of the authors' fingertip GelSight; their code crops its central 720x720."""


_MAGIC = (b"\x89PNG\r\n\x1a\n", b"\xff\xd8\xff")
_JPEG_FRAMES = frozenset(range(0xC0, 0xD0)) - {0xC4, 0xC8, 0xCC}
"""JPEG start-of-frame markers (SOF0-SOF15 less DHT, JPG and DAC): where its size is declared."""


def png_header(data: bytes) -> tuple[int, int, int, int] | None:
    """Width, height, bit depth and colour type (0: greyscale, 2: RGB, ...) a PNG declares in
    its header chunk, from its first 26 bytes (nothing decoded); None if ``data`` does not
    begin with one. A 16-bit greyscale PNG (``(w, h, 16, 0)``) is how depth maps are stored."""
    if not data.startswith(_MAGIC[0]) or len(data) < 26 or data[12:16] != b"IHDR":
        return None
    return (
        int.from_bytes(data[16:20], "big"),
        int.from_bytes(data[20:24], "big"),
        data[24],
        data[25],
    )


def declared_size(data: bytes) -> tuple[int, int] | None:
    """Width and height a PNG or JPEG declares in its header, read from the bytes alone
    (nothing decoded, no Pillow): None for another format or a header too damaged to say.

    `_open` refuses an oversized image by this before Pillow opens it: Pillow warns of (or
    refuses) an image beyond its own `PIL.Image.MAX_IMAGE_PIXELS` as it opens it, and silencing
    that warning needs ``warnings.catch_warnings``, which swaps the process's warning filters
    and so is not safe in the decoding threads (two threads' filters can outlive both)."""
    png = png_header(data)
    if png is not None:
        return png[0], png[1]
    if data.startswith(_MAGIC[0]):
        return None  # a PNG whose header is cut or damaged
    if not data.startswith(b"\xff\xd8"):
        return None
    i = 2
    while i + 4 <= len(data):  # segments: FF <marker> <2-byte length, itself included> ...
        if data[i] != 0xFF:
            return None
        while i < len(data) and data[i] == 0xFF:  # fill bytes
            i += 1
        if i >= len(data):
            return None
        marker = data[i]
        i += 1
        if marker == 0x01 or 0xD0 <= marker <= 0xD8:  # no length: TEM, RSTn, SOI
            continue
        if marker in (0xD9, 0xDA):  # end of image, or the scan with no frame header before
            return None
        if marker in _JPEG_FRAMES:
            if i + 7 > len(data):
                return None
            h, w = (
                int.from_bytes(data[i + 3 : i + 5], "big"),
                int.from_bytes(data[i + 5 : i + 7], "big"),
            )
            return w, h
        if i + 2 > len(data):
            return None
        i += int.from_bytes(data[i : i + 2], "big")
    return None


def _too_many_pixels(path: Path, w: int, h: int, limit: int) -> ImageError:
    return ImageError(
        path,
        f"image declares {w}x{h} = {w * h / 1e6:.1f} megapixels; at most "
        f"{limit / 1e6:g} are decoded",
    )


def _open(path: Path, data: bytes | None = None, max_pixels: int | None = None) -> Image.Image:
    """Decode ``data`` (default: the file at ``path``), refusing oversized images unread.

    The size is checked from the header before Pillow opens a PNG or JPEG (`declared_size`),
    so Pillow's own warning of a "decompression bomb" (beyond its ``MAX_IMAGE_PIXELS``) is never
    reached for them, with no change to the process's warning filters (this runs in decoding
    threads); another format is checked once Pillow has read its header.

    Errors name ``path`` and never echo Pillow's message (it may hold a temp path).
    """
    limit = DEFAULT_MAX_PIXELS if max_pixels is None else max_pixels
    blob = read_image_file(path) if data is None else data
    if not blob:
        raise ImageError(path, "file is empty")
    size = declared_size(blob)
    if size is not None and size[0] * size[1] > limit:
        raise _too_many_pixels(path, size[0], size[1], limit)
    try:
        im = Image.open(io.BytesIO(blob))
        w, h = im.size
        if w * h > limit:
            raise _too_many_pixels(path, w, h, limit)
        im.load()
    except ImageError:
        raise
    except Image.DecompressionBombError:
        raise ImageError(path, "image declares too many pixels to decode") from None
    except (OSError, SyntaxError, ValueError, EOFError, struct_error, MemoryError) as e:
        text = str(e).lower()
        if "truncated" in text or isinstance(e, EOFError):
            raise ImageError(path, "file is truncated") from None
        if "cannot identify image file" in text and blob.startswith(_MAGIC):
            raise ImageError(
                path, "file is truncated or damaged (its header is incomplete)"
            ) from None
        if "cannot identify image file" in text:
            raise ImageError(
                path, "cannot decode image: not a PNG or JPEG Pillow can read"
            ) from None
        raise ImageError(
            path, f"cannot decode image ({type(e).__name__}: damaged or unsupported)"
        ) from None
    return im


def decode_depth(
    path: str | os.PathLike[str], data: bytes | None = None, max_pixels: int | None = None
) -> np.ndarray:
    """Read a depth PNG as millimetres.

    Args:
        path: the file; with ``data``, only the name used in errors.
        data: the file's bytes (an upload), read from ``path`` when ``None``.
        max_pixels: largest width x height decoded (default `DEFAULT_MAX_PIXELS`).

    Returns:
        (H, W) uint16 array; 0 where the sensor had no reading.

    Raises:
        ImageError: not a regular file, undecodable or truncated, too many pixels, or not 16-bit
            greyscale.
    """
    path = Path(path)
    im = _open(path, data, max_pixels)
    if im.mode not in ("I;16", "I;16B", "I;16L", "I"):
        raise ImageError(
            path, f"depth image is mode {im.mode}; expected 16-bit greyscale (millimetres)"
        )
    a = np.asarray(im)
    if a.dtype != np.uint16:
        if a.min() < 0 or a.max() > 65535:
            raise ImageError(path, "depth values outside 0..65535 mm")
        a = a.astype(np.uint16)
    return a


def decode_rgb(
    path: str | os.PathLike[str], data: bytes | None = None, max_pixels: int | None = None
) -> np.ndarray:
    """Read a colour or GelSight image as 8-bit RGB (greyscale and alpha are converted).

    Args: as `decode_depth`.

    Returns:
        (H, W, 3) uint8 array.

    Raises:
        ImageError: not a regular file, undecodable or truncated, too many pixels, or 16-bit
            (not an 8-bit RGB image).
    """
    return np.asarray(open_rgb(path, data, max_pixels))


def open_rgb(
    path: str | os.PathLike[str], data: bytes | None = None, max_pixels: int | None = None
) -> Image.Image:
    """`decode_rgb` as a Pillow image in mode RGB (`preprocess_rgb` then crops and resizes it
    without a copy through numpy)."""
    path = Path(path)
    im = _open(path, data, max_pixels)
    if im.mode in ("I;16", "I;16B", "I;16L", "I", "F"):
        raise ImageError(path, f"image is mode {im.mode} (16-bit or float); expected 8-bit RGB")
    return im if im.mode == "RGB" else im.convert("RGB")


def depth_to_unit(
    depth_mm: np.ndarray, min_mm: float = 800.0, range_mm: float = 500.0
) -> np.ndarray:
    """The authors' depth mapping: ``clip((d - min_mm) / range_mm, 0, 1)`` as float32."""
    out = (depth_mm.astype(np.float32) - np.float32(min_mm)) / np.float32(range_mm)
    return np.clip(out, 0.0, 1.0, out=out)


WALL_GAP_NONE = 1e4
"""The gap (mm) held where a drape's input has no cloth, or for a wall it lacks: no moved wall
reaches it."""


def _resize_float(a: np.ndarray, size: int) -> np.ndarray:
    if a.shape == (size, size):
        return a
    im = Image.fromarray(a).resize((size, size), Image.Resampling.BILINEAR)
    return np.array(im, dtype=np.float32)


def registered_to_unit(height_mm: np.ndarray, config: DataConfig) -> np.ndarray:
    """Registered heights (mm) -> the network's (S, S) float32 input:
    ``clip(height / depth_range_mm, 0, 1)``, resized."""
    unit = height_mm / np.float32(config.depth_range_mm)
    return _resize_float(np.clip(unit, 0.0, 1.0).astype(np.float32), config.image_size)


def preprocess_depth(depth_mm: np.ndarray, config: DataConfig) -> np.ndarray:
    """Millimetres -> (S, S) float32 in [0, 1]: fill holes, map the range, resize.

    With ``config.depth_input == "registered"`` the image is first registered
    (`lookfeel.data.register.registered_input`: the cloth's height above the fitted floor,
    0 off the cloth) and mapped as ``clip(height / depth_range_mm, 0, 1)``.

    Raises:
        RegistrationError: registered input, and no room could be fitted in the image.
    """
    if config.depth_input == "registered":
        from lookfeel.data.register import registered_input  # register imports this module

        return registered_to_unit(registered_input(depth_mm, config), config)
    d = fill_holes(depth_mm) if config.depth_holes == "nearest" else depth_mm
    return _resize_float(
        depth_to_unit(d, config.depth_min_mm, config.depth_range_mm), config.image_size
    )


T = TypeVar("T")


def _registering(path: Path, build: Callable[[], T]) -> T:
    """``build()``, a registration failure re-raised naming ``path`` (one line)."""
    from lookfeel.data.register import RegistrationError  # register imports this module

    try:
        return build()
    except RegistrationError as e:
        raise RegistrationError(
            f"{path}: cannot register depth (data.depth_input: registered): {e}"
        ) from None


def _preprocess_depth_file(path: Path, depth_mm: np.ndarray, config: DataConfig) -> np.ndarray:
    """`preprocess_depth`, a registration failure naming the file (one line)."""
    if config.depth_input != "registered":
        return preprocess_depth(depth_mm, config)
    return _registering(path, lambda: preprocess_depth(depth_mm, config))


def _center_square(a: np.ndarray) -> np.ndarray:
    h, w = a.shape[:2]
    s = min(h, w)
    top, left = (h - s) // 2, (w - s) // 2
    return a[top : top + s, left : left + s]


def preprocess_rgb(
    rgb: np.ndarray | Image.Image, modality: Modality | str, config: DataConfig
) -> np.ndarray:
    """8-bit RGB -> (S, S, 3) uint8, S = ``config.size_of(modality)``: crop as configured for
    the modality (a `Modality` or its name, ``"touch"``), then resize.

    ``rgb`` is an (H, W, 3) uint8 array or an RGB Pillow image (`open_rgb`); both give the
    same bytes.

    Raises:
        ModalityError: ``modality`` names no modality.
    """
    modality = Modality.of(modality)
    im = rgb if isinstance(rgb, Image.Image) else None
    w, h = im.size if im is not None else (rgb.shape[1], rgb.shape[0])  # type: ignore[union-attr]
    if modality is Modality.TOUCH:
        crop = config.touch_crop == "center" or (
            config.touch_crop == "auto" and (w, h) == GELSIGHT_SIZE
        )
    else:
        crop = config.color_crop == "center"
    if crop:
        side = min(h, w)
        top, left = (h - side) // 2, (w - side) // 2
        if im is not None:
            im = im.crop((left, top, left + side, top + side))
        else:
            rgb = _center_square(rgb)  # type: ignore[arg-type]
        w = h = side
    if modality is Modality.TOUCH and config.touch_zoom < 1.0:
        zw, zh = max(1, round(w * config.touch_zoom)), max(1, round(h * config.touch_zoom))
        left, top = (w - zw) // 2, (h - zh) // 2
        if im is not None:
            im = im.crop((left, top, left + zw, top + zh))
        else:
            rgb = rgb[top : top + zh, left : left + zw]  # type: ignore[index]
        w, h = zw, zh
    s = config.size_of(modality)
    if (h, w) != (s, s):
        im = im if im is not None else Image.fromarray(np.ascontiguousarray(rgb))
        im = im.resize((s, s), Image.Resampling.BILINEAR)
    return np.array(im if im is not None else rgb)  # writable, contiguous


@dataclass(frozen=True)
class PreprocessSettings:
    """The settings a preprocessed image depends on; part of every cache key."""

    image_size: int
    depth_min_mm: float
    depth_range_mm: float
    depth_holes: str
    color_crop: str
    touch_crop: str
    video_frame: float | None
    video_frames: int
    video_reference: str
    video_gain: float
    depth_registration: tuple[float | str | None, ...] | None = None
    """Registered depth input: (margin mm, focal px, cloth rule[, lowest cloth mm when not
    0][, "post", x, y when the drape is moved][, "top", mm when heights are measured from
    the drape's top][, "band", mm of ``depth_wall_band_mm`` when not 0]); ``None`` for raw
    depth."""
    touch_zoom: float | None = None
    """``data.touch_zoom`` when below 1 (``None``: the whole field, keys as before)."""
    touch_frames: tuple[int, ...] | None = None
    """``data.touch_frames`` when it stacks several frames (``None``: one frame, keys as
    before)."""
    color_size: int | None = None
    """``data.color_size`` when set (``None``: colour at ``image_size``, keys as before)."""
    video_rotate: int | None = None
    """``data.video_rotate`` when a press video is turned (``None``: 0, unturned, keys as
    before): a press decoded with another turn is never reused."""
    press_detector: int = PRESS_DETECTOR_VERSION
    """`lookfeel.data.video.PRESS_DETECTOR_VERSION`: which frames of a press video the images
    were made from (always in the key: keys made before it was kept are not reused, as they
    may hold presses an earlier detector chose)."""

    @classmethod
    def of(cls, config: DataConfig) -> PreprocessSettings:
        registration: tuple[float | str | None, ...] | None = None
        if config.depth_input == "registered":
            registration = (config.depth_margin_mm, config.depth_focal_px, config.depth_cloth)
            # Session 48: large regions without a reading left out of the fit
            # (`unseen_regions`): an image registered before is registered again.
            registration += ("unseen", UNSEEN_REGION)
            if config.depth_min_height_mm:
                registration += (config.depth_min_height_mm,)
            if config.depth_post_at is not None:
                registration += ("post", *config.depth_post_at)
            if config.depth_top_mm is not None:
                registration += ("top", config.depth_top_mm)
                if config.depth_top_from != "first_rows":
                    registration += (config.depth_top_from,)
            if config.depth_wall_band_mm:
                registration += ("band", config.depth_wall_band_mm)
        return cls(
            config.image_size,
            config.depth_min_mm,
            config.depth_range_mm,
            config.depth_holes,
            config.color_crop,
            config.touch_crop,
            config.video_frame,
            config.video_frames,
            config.video_reference,
            config.video_gain,
            registration,
            config.touch_zoom if config.touch_zoom < 1.0 else None,
            config.touch_frames if config.stacks_touch_frames else None,
            config.color_size,
            config.video_rotate or None,
            PRESS_DETECTOR_VERSION,
        )

    def digest(self) -> str:
        d = {k: v for k, v in self.__dict__.items() if v is not None}  # raw: keys as before
        blob = json.dumps(d, sort_keys=True).encode()
        return hashlib.sha1(blob).hexdigest()[:12]


CACHE_SETTINGS = "settings.json"
"""The file in each folder of a disk cache (``data.cache_dir/<digest>/``) that says, readably,
the `PreprocessSettings` its entries were made with (`ImageLoader`)."""


def to_tensor(a: np.ndarray) -> torch.Tensor:
    """A preprocessed array as the network's input: (S, S, 3) or (V, S, S, 3) uint8 ->
    (3, S, S) or (V, 3, S, S) in [0, 1]; (S, S) depth -> (1, S, S)."""
    if a.dtype == np.uint8:  # channels last -> channels first, in [0, 1]
        return torch.from_numpy(a).movedim(-1, -3).float().div_(255.0)
    return torch.from_numpy(a).unsqueeze(0).clone()  # (S, S) -> (1, S, S); the cache stays intact


def stack_views(images: Sequence[Any]) -> Any:
    """Stack images, some of them several views of one press (`ImageLoader.embed_array`,
    `ImageLoader.load_embedded`): numpy arrays or tensors. With no views this is a plain stack;
    otherwise a single image counts as every view (repeated), so the result has a view axis
    after the first: (N, V, ...).

    Raises:
        ValueError: two presses have different numbers of views.
    """
    counts = {len(a) for a in images if a.ndim == 4}
    if not counts:
        return np.stack(images) if isinstance(images[0], np.ndarray) else torch.stack(list(images))
    if len(counts) > 1:
        raise ValueError(f"presses with different numbers of views: {sorted(counts)}")
    v = counts.pop()
    if isinstance(images[0], np.ndarray):
        return np.stack([a if a.ndim == 4 else np.broadcast_to(a, (v, *a.shape)) for a in images])
    return torch.stack([a if a.ndim == 4 else a.expand(v, *a.shape) for a in images])


def _missing_frames(n: int, indices: Sequence[int]) -> int:
    """How many of a press's frames ``indices`` (negative from the end) a press of ``n``
    frames lacks: each is read as the nearest frame it has (`Item.frame`)."""
    return sum(not 0 <= (i if i >= 0 else n + i) < n for i in indices)


class BlankDepthWarning(UserWarning):
    """A depth image with no valid pixel (every pixel 0: no reading) was read. Nothing fills
    its holes, so it becomes a blank input (every pixel 0 after the mapping) that a run trains
    on, embeds and scores as if it were a drape. ``lookfeel data check`` warns of each such
    file and ``lookfeel match`` refuses one as a query; `ImageLoader` warns once."""


def _blank_depth_message(first: Path, more: int) -> str:
    """`BlankDepthWarning`'s text: ``first`` such file and how many ``more`` were read with it."""
    also = (
        f", as have {more} more depth image{'s' if more > 1 else ''} read with it" if more else ""
    )
    each, them = ("each", "them") if more else ("it", "it")
    return (
        f"{first}: depth image has no valid pixel (every pixel 0, no reading){also}: {each} is "
        "read as a blank input, which a run trains on and embeds as if it were a drape; leave "
        f"{them} out or record {them} again (`lookfeel data check` names every such file)"
    )


class ImageLoader:
    """Loads items as network-ready tensors, decoding and preprocessing each file once.

    Args:
        config: preprocessing settings (size, depth range and holes, crops, touch frame).
        cache_dir: optional folder for an on-disk cache shared across runs, keyed by the
            file's content hash and the preprocessing settings (never stale when either
            changes). ``None`` uses ``config.cache_dir``; the memory cache is always on.

    Example:
        >>> loader = ImageLoader(DataConfig(image_size=227))
        >>> loader.preload(catalog.items(Modality.DEPTH))
        >>> x = loader.load(item)  # (1, 227, 227) float32 in [0, 1]
    """

    def __init__(self, config: DataConfig, cache_dir: str | Path | None = None) -> None:
        self.config = config
        self.settings = PreprocessSettings.of(config)
        cd = cache_dir if cache_dir is not None else config.cache_dir
        self.cache_root = cd
        """The disk cache's folder as given (``cache_dir`` or ``config.cache_dir``)."""
        self.cache_dir = None if cd is None else Path(cd) / self.settings.digest()
        self._memory: dict[Path, np.ndarray] = {}
        self._views: dict[Path, np.ndarray] = {}
        self._embedded: dict[Path, np.ndarray] = {}
        self._bad_videos: dict[Path, VideoError] = {}
        self._grey: dict[Path, bool] = {}  # `is_grey`: of each press video read
        self._stacks: dict[Path, tuple[Path, ...]] = {}
        self._said_short = False  # `frame_path` warns once of presses with too few frames
        """Press frames stacked as one input (``data.touch_frames``), by `frame_path`."""
        self._blank: set[Path] = set()  # depth files with no valid pixel read (`_note_blank`)
        self._said_blank = False  # `BlankDepthWarning` said (once for the loader)
        self._in_decode_one = threading.local()  # ``on``: `array` leaves the saying to `_decode`
        self._lock = threading.Lock()
        self._described = False  # `_describe_cache`: its settings.json checked or written

    def __len__(self) -> int:
        return len(self._memory)

    def frame_path(self, item: Item) -> Path:
        """The file an item is read from and keyed by: for touch, the configured frame of
        the press (with ``data.touch_frames``, the last listed; the others are read with it).
        """
        if item.modality is not Modality.TOUCH:
            return item.path
        indices = self.config.touch_frame_indices
        path = item.frame(indices[-1])
        if self.config.stacks_touch_frames and path not in self._stacks:
            self._stacks[path] = tuple(item.frame(i) for i in indices)
            need = max(i if i >= 0 else -i - 1 for i in indices) + 1
            if len(item.frames) < need and not is_video(path) and not self._said_short:
                self._said_short = True
                warnings.warn(
                    f"data.touch_frames reads frames {list(indices)} of each press, and "
                    f"{item.path.name}'s press has {len(item.frames)}: the nearest frame is "
                    "read in place of each missing one (first such press; others may follow)",
                    stacklevel=2,
                )
        return path

    def source_files(self, item: Item) -> tuple[Path, ...]:
        """Every file ``item``'s input is read from: `frame_path`'s, or with
        ``data.touch_frames`` the press's stacked frames (what a cache of its embedding
        depends on)."""
        path = self.frame_path(item)
        stacked = item.modality is Modality.TOUCH and self.config.stacks_touch_frames
        return self._stack_files(path) if stacked and not is_video(path) else (path,)

    def _stack_files(self, path: Path) -> tuple[Path, ...]:
        """The frame files stacked for the press keyed by ``path``: those `frame_path` noted,
        or, for a file given as such (a query), the frames beside it of the same press."""
        known = self._stacks.get(path)
        if known is not None:
            return known
        if not path.is_file():
            read_image_file(path)  # raises its usual line: not found, a folder, not a file
        if path.suffix.lower() not in IMAGE_SUFFIXES:
            raise ImageError(path, f"not an image ({', '.join(IMAGE_SUFFIXES)}) of a press")
        frames = press_frame_files(path)
        if not frames or path not in frames:
            raise ImageError(
                path,
                f"data.touch_frames reads frames {list(self.config.touch_frame_indices)} of "
                "each press, and this file's name does not say its press: expected "
                "F<id>_<kind>_<frame>_<press>.<ext> beside the press's other frames",
            )
        indices = self.config.touch_frame_indices
        missing = _missing_frames(len(frames), indices)
        if missing and not self._said_short:
            self._said_short = True
            warnings.warn(
                f"{path}: data.touch_frames reads frames {list(indices)} of each press, and "
                f"this press has {len(frames)} frame{'' if len(frames) == 1 else 's'} in its "
                f"folder: the nearest frame is read in place of each of the {missing} missing",
                stacklevel=2,
            )
        press = Item(Modality.TOUCH, 0, frames)
        return tuple(press.frame(i) for i in indices)

    def _preprocess_stack(self, path: Path) -> np.ndarray:
        """(S, S, 3F) uint8: the press's frames (``data.touch_frames``) preprocessed and
        stacked as channels, cached under all their contents."""
        if is_video(path):
            raise ImageError(
                path,
                "data.touch_frames stacks frame images of a press; this press is a video "
                "(its frames are chosen by data.video_frame, video_frames and video_views)",
            )
        files = self._stack_files(path)
        blobs = [read_image_file(p) for p in files]

        def build() -> np.ndarray:
            parts = [
                preprocess_rgb(open_rgb(p, b), Modality.TOUCH, self.config)
                for p, b in zip(files, blobs, strict=True)
            ]
            return np.concatenate(parts, axis=-1)

        key = b"".join(hashlib.sha1(b).digest() for b in blobs)
        return self._cached(key, "touch", build)

    def _cached(
        self,
        data: bytes,
        suffix: str,
        build: Callable[[], np.ndarray],
        video: Path | None = None,
    ) -> np.ndarray:
        """``build()``, or its copy in the disk cache under the file's content hash and
        ``suffix`` (written atomically after a build; a damaged entry is rebuilt).

        With ``video`` (the press video the entry is made from), whether it had no colour
        (`is_grey`, which ``build`` notes) is kept beside the entry, ``{"grey": true}`` in
        ``<entry>.json`` (written first), and read back with it. An entry without one (written
        before it was kept) leaves `is_grey` unknown."""
        if self.cache_dir is None:
            return build()
        stem = f"{hashlib.sha1(data).hexdigest()}_{suffix}"
        disk, facts = self.cache_dir / f"{stem}.npy", self.cache_dir / f"{stem}.json"
        if disk.exists():
            try:
                a = np.load(disk, allow_pickle=False)
            except (OSError, ValueError):
                pass  # rebuilt below
            else:
                if video is not None:
                    self._read_grey(video, facts)
                return a
        a = build()
        self._describe_cache()
        grey = None if video is None else self._grey.get(video)
        if grey is not None:
            atomic_write_text(facts, json.dumps({"grey": grey}) + "\n")
        buf = io.BytesIO()
        np.save(buf, a, allow_pickle=False)
        atomic_write(disk, lambda f: f.write(buf.getvalue()))
        return a

    def _describe_cache(self) -> None:
        """Write `CACHE_SETTINGS` beside this loader's cache entries once: the settings they were
        made with, in words a person can read (the folder's name is only their digest), so that
        the folder of settings no longer used can be told and deleted."""
        if self.cache_dir is None or self._described:
            return
        path = self.cache_dir / CACHE_SETTINGS
        if not path.exists():
            from lookfeel import __version__

            about = {
                "what": "lookfeel's decoded images, made with these settings: a folder of "
                "other settings is never read by this one, and any such folder can be deleted "
                "(it is made again when needed)",
                "lookfeel": __version__,
                "settings": {k: v for k, v in self.settings.__dict__.items() if v is not None},
            }
            atomic_write_text(path, json.dumps(about, indent=2) + "\n")
        self._described = True

    def _read_grey(self, video: Path, facts: Path) -> None:
        """Note `is_grey` of ``video`` from a disk cache entry's ``facts`` file; a missing or
        unreadable one leaves it unknown."""
        try:
            grey = json.loads(facts.read_text(encoding="utf-8")).get("grey")
        except (OSError, ValueError, AttributeError):
            return
        if isinstance(grey, bool):
            with self._lock:
                self._grey.setdefault(video, grey)

    def is_grey(self, path: Path) -> bool | None:
        """Whether the press video ``path`` had no colour (`lookfeel.data.video.Press.grey`) as
        this loader read it, or read its image from the disk cache: None for a file it has not
        read, one that is not a press video, or one read from a cache entry written before the
        flag was kept (`lookfeel.data.video.is_grey_video` decodes it to say)."""
        return self._grey.get(path)

    def _preprocess_file(self, path: Path, modality: Modality) -> np.ndarray:
        if modality is Modality.TOUCH and self.config.stacks_touch_frames:
            return self._preprocess_stack(path)
        if self.wall_gaps_follow(modality) and not self.config.depth_wall_band_mm:
            # One registration serves the image and its gaps to the walls, whichever is
            # asked for first. With a wall band the image is not the views' first (that one
            # is unbanded: a training draw drops near the walls instead), so what embeds or
            # scores registers it on its own; training reads only the views.
            return self._read_wall_gaps(path)[0]
        data = read_image_file(path)

        video = modality is Modality.TOUCH and is_video(path)

        def build() -> np.ndarray:
            if modality is Modality.DEPTH:
                return _preprocess_depth_file(path, decode_depth(path, data), self.config)
            if video:
                return preprocess_rgb(self._video_image(path, data), modality, self.config)
            return preprocess_rgb(open_rgb(path, data), modality, self.config)

        a = self._cached(data, modality.value, build, path if video else None)
        if modality is Modality.DEPTH:
            self._note_blank(path, data, a)
        return a

    def _note_blank(self, path: Path, data: bytes, a: np.ndarray) -> None:
        """Note ``path`` (its bytes ``data``) as a depth image with no valid pixel when its
        preprocessed input ``a`` (built or from the disk cache) is constant and its pixels are
        all 0. A file is decoded again to ask only when its input is constant, which is rare
        with a valid pixel (holes take the nearest one's value: every reading would have to be
        alike, or beyond the mapped range); the check costs microseconds a file."""
        if a.min() != a.max() or decode_depth(path, data).any():
            return
        with self._lock:
            self._blank.add(path)

    def _say_blank(self, paths: Iterable[Path]) -> None:
        """Warn (`BlankDepthWarning`), once for the loader, of the first of ``paths`` noted as
        having no valid pixel, counting the others."""
        with self._lock:
            blank = [p for p in paths if p in self._blank]
            if not blank or self._said_blank:
                return
            self._said_blank = True
        warnings.warn(_blank_depth_message(blank[0], len(blank) - 1), BlankDepthWarning, 3)

    def _video_image(self, path: Path, data: bytes) -> np.ndarray:
        """The image of a press video the config asks for, as (H, W, 3) uint8: one frame, or
        the mean of ``video_frames`` frames across the contact span."""
        c = self.config
        press = read_press(
            path,
            data=data,
            frames=c.video_frames,
            position=c.video_frame,
            subtract_reference=c.video_reference == "subtract",
            gain=c.video_gain,
            rotate=c.video_rotate,
        )
        with self._lock:
            self._grey[path] = press.grey
        if len(press.images) == 1:
            return press.images[0]
        return np.rint(press.images.astype(np.float32).mean(axis=0)).astype(np.uint8)

    def array(self, path: Path, modality: Modality | str) -> np.ndarray:
        """The preprocessed array of one file: (S, S) float32 for depth, (S, S, 3) uint8 else
        ((S, S, 3F) for F touch frames stacked: ``data.touch_frames``)."""
        modality = Modality.of(modality)
        a = self._memory.get(path)
        if a is None:
            a = self._preprocess_file(path, modality)
            with self._lock:
                self._memory[path] = a
            if not getattr(self._in_decode_one, "on", False):  # else `_decode` says it
                self._say_blank([path])
        return a

    def load(self, item: Item) -> torch.Tensor:
        """One item as a tensor: (1, S, S) for depth, (3, S, S) for colour and touch ((3F, S, S)
        for F touch frames stacked: ``data.touch_frames``), in [0, 1]."""
        return to_tensor(self.array(self.frame_path(item), item.modality))

    def has_views(self, item: Item) -> bool:
        """Whether ``item`` has several training views: a press video with ``video_views`` >
        1, a colour photo with re-printed renders in its dataset's ``reprints/`` folder and
        ``color_reprints`` > 0 (`uses_reprints`), or a depth image with ``depth_wall_drop`` >
        0 (registered input: its gaps to the walls, `wall_gaps_follow`)."""
        if item.modality is Modality.COLOR:
            return self.uses_reprints(item.path)
        if item.modality is Modality.DEPTH:
            return self.wall_gaps_follow(item.modality)
        return (
            item.modality is Modality.TOUCH
            and self.config.video_views > 1
            and is_video(self.frame_path(item))
        )

    def uses_reprints(self, photo: Path) -> bool:
        """Whether training reads re-printed renders of the colour photo ``photo`` in its place:
        ``data.color_reprints`` > 0 and its dataset has a ``reprints/`` folder."""
        return self.config.color_reprints > 0 and reprint_path(photo, 1).parent.is_dir()

    def wall_gaps_follow(self, modality: Modality) -> bool:
        """Whether the training `views` of ``modality``'s items are an image and its gaps to
        the room's walls (``data.depth_wall_drop``), not several images."""
        return modality is Modality.DEPTH and self.config.depth_wall_drop > 0

    def skips_first_view(self, modality: Modality) -> bool:
        """Whether a training draw of ``modality`` leaves out each item's first view (its
        image): a re-printed photo is trained on through its renders alone."""
        return modality is Modality.COLOR and self.config.color_reprints > 0

    def views(self, item: Item) -> np.ndarray:
        """(V, S, S, 3) uint8 training views of one item: its image first (``load``'s), then
        for a press video with ``video_views`` > 1 its other deep frames (`deep_frames`), for
        a colour photo with ``color_reprints`` N its N re-printed renders (`reprint_path`);
        for a registered drape with ``depth_wall_drop`` > 0, (1 + P, S, S) float32: its image,
        then its gap to each of the P fitted planes but the floor (`_read_wall_gaps`: not
        images; `wall_gaps_follow`); (1, ...) for every other item. Cached in memory and on
        disk like images.

        Raises:
            ImageError: a photo has fewer than N renders (naming the missing file), or one
                cannot be read.
        """
        path = self.frame_path(item)
        if not self.has_views(item):
            return self.array(path, item.modality)[None]
        v = self._views.get(path)
        if v is None:
            if item.modality is Modality.COLOR:
                v = self._read_reprints(path)
            elif item.modality is Modality.DEPTH:
                v = self._read_wall_gaps(path)
            else:
                v = self._read_press_views(path)[0]
        return v

    def _read_wall_gaps(self, path: Path) -> np.ndarray:
        """(1 + P, S, S) float32: a registered drape's image, then the cloth's gap to each of
        the P fitted planes but the floor at the input's size (mm past ``depth_margin_mm``,
        averaged over each input pixel's cloth; `WALL_GAP_NONE` off the cloth), from
        `lookfeel.data.register.wall_gap_input`; cached on disk under their own key."""
        from lookfeel.data.register import wall_gap_input  # register imports this module

        c = self.config
        data = read_image_file(path)

        def build() -> np.ndarray:
            heights, share, gaps = _registering(
                path, lambda: wall_gap_input(decode_depth(path, data), c)
            )
            s = _resize_float(share, c.image_size)
            on = s > 1e-3
            out = [registered_to_unit(heights, c)]
            for g in gaps:
                g = _resize_float(g, c.image_size)
                out.append(np.where(on, g / np.where(on, s, 1.0), WALL_GAP_NONE))
            return np.stack(out).astype(np.float32)

        v = self._cached(data, "wallgaps", build)
        with self._lock:
            self._views[path] = v
            if not c.depth_wall_band_mm:  # else the image is the banded one (`array`)
                self._memory.setdefault(path, v[0])
        return v

    def _read_reprints(self, photo: Path) -> np.ndarray:
        n = self.config.color_reprints
        files = [reprint_path(photo, k) for k in range(1, n + 1)]
        for have, f in enumerate(files):
            if not f.is_file():
                fewer = f"{have} or fewer, as many as every photo has" if have else "0"
                raise ImageError(
                    f,
                    f"missing: data.color_reprints = {n} reads {n} re-printed render"
                    f"{'s' if n > 1 else ''} of {photo.name}, and its folder holds {have} "
                    f"(make the world with `lookfeel synth --reprints {n}`, or train with "
                    f"--set data.color_reprints={fewer})",
                )
        # Read through `_preprocess_file`, not `array`: the renders are not kept twice.
        v = np.stack(
            [self.array(photo, Modality.COLOR)]
            + [self._preprocess_file(f, Modality.COLOR) for f in files]
        )
        with self._lock:
            self._views[photo] = v
        return v

    def _read_press_views(self, path: Path) -> tuple[np.ndarray, np.ndarray | None]:
        """A press video's training views and, with ``video_embed: views``, its embedding
        views (`view_frames`, a superset of the training ones): one decode for both, each
        cached in memory and on disk under its own key. A video that cannot serve (no press,
        too short, undecodable) is remembered: asking again raises the same error without
        decoding it again (an ensemble's members share one loader)."""
        known = self._bad_videos.get(path)
        if known is not None:
            raise known
        try:
            return self._decode_press_views(path)
        except VideoError as e:
            with self._lock:
                self._bad_videos[path] = e
            raise

    def _decode_press_views(self, path: Path) -> tuple[np.ndarray, np.ndarray | None]:
        c = self.config
        data = read_image_file(path)
        pools = c.video_embed == "views"
        built: dict[str, np.ndarray] = {}

        def read(key: str) -> np.ndarray:
            if not built:
                press = read_press(
                    path,
                    data=data,
                    choose=(
                        (lambda span: view_frames(span, c.video_views))
                        if pools
                        else (lambda span: deep_frames(span, c.video_views, c.video_views_min))
                    ),
                    subtract_reference=c.video_reference == "subtract",
                    gain=c.video_gain,
                    rotate=c.video_rotate,
                )
                with self._lock:
                    self._grey[path] = press.grey
                ims = np.stack([preprocess_rgb(im, Modality.TOUCH, c) for im in press.images])
                built["embed"] = built["train"] = ims
                if pools:
                    first = {i: k for k, i in reversed(list(enumerate(press.indices)))}
                    chosen = deep_frames(press.span, c.video_views, c.video_views_min)
                    built["train"] = ims[[first[i] for i in chosen]]
            return built[key]

        train = self._cached(
            data, f"views{c.video_views}_{c.video_views_min:g}", lambda: read("train"), path
        )
        embed = (
            self._cached(data, f"embed{c.video_views}", lambda: read("embed"), path)
            if pools
            else None
        )
        with self._lock:
            self._views[path] = train
            self._memory.setdefault(path, train[0])
            if embed is not None:
                self._embedded[path] = embed
        return train, embed

    def pools_views(self, item: Item) -> bool:
        """Whether ``item`` is embedded from several views (``data.video_embed: views`` and a
        press video): `embed_array` then holds them all."""
        return self._pools(self.frame_path(item), item.modality)

    def _pools(self, path: Path, modality: Modality) -> bool:
        return self.config.video_embed == "views" and modality is Modality.TOUCH and is_video(path)

    def embed_array(self, item: Item) -> np.ndarray:
        """What ``item`` is embedded from: `array`'s image, or with `pools_views` the press's
        (V, S, S, 3) uint8 views (`view_frames`: the deepest frame, the image, first). Cached
        in memory and on disk like images."""
        return self.embed_file(self.frame_path(item), item.modality)

    def embed_file(self, path: Path, modality: Modality | str) -> np.ndarray:
        """`embed_array` of a file given as such (a query), of ``modality`` (or its name)."""
        modality = Modality.of(modality)
        if not self._pools(path, modality):
            return self.array(path, modality)
        v = self._embedded.get(path)
        if v is None:
            v = self._read_press_views(path)[1]
            assert v is not None  # _pools: video_embed is "views"
        return v

    def forget(self, items: Iterable[Item]) -> None:
        """Drop ``items``' decoded arrays from memory (the disk cache keeps its copies)."""
        with self._lock:
            for it in items:
                p = self.frame_path(it)
                for kept in (self._memory, self._views, self._embedded):
                    kept.pop(p, None)

    def load_embedded(self, item: Item) -> torch.Tensor:
        """`embed_array` as a tensor: `load`'s (C, S, S), or (V, 3, S, S) views in [0, 1]."""
        return to_tensor(self.embed_array(item))

    def _held(self, item: Item, views: bool) -> bool:
        """Whether what `preload` decodes for ``item`` is in memory already."""
        p = self.frame_path(item)
        if views and self.has_views(item):
            return p in self._views
        if self.pools_views(item):
            return p in self._embedded
        return p in self._memory

    def decode_one(self, item: Item, *, views: bool = False) -> None:
        """Decode and preprocess what `preload` needs of ``item`` into memory: its image, or
        its `embed_array` views where it `pools_views`, or with ``views`` its training
        `views`.

        A depth image with no valid pixel is noted, not warned of: `preload` warns once of
        all it decoded (`BlankDepthWarning`), and a worker process's loader returns the note
        with the file (`take`).

        Raises:
            ImageError: the file cannot be used (and the like: one line naming the file).
        """
        self._in_decode_one.on = True
        try:
            if views and self.has_views(item):
                self.views(item)
            elif self.pools_views(item):
                self.embed_array(item)
            else:
                self.array(self.frame_path(item), item.modality)
        finally:
            self._in_decode_one.on = False

    def take(self, path: Path) -> dict[str, np.ndarray]:
        """Remove and return everything held in memory for ``path``, by store (a decoding
        worker's result; `adopt` puts it into another loader), and, of a press video, its
        `is_grey` as ``grey`` (a 0-d bool array), of a depth image with no valid pixel
        ``blank`` (a 0-d True: `BlankDepthWarning`)."""
        with self._lock:
            out = {}
            for key, kept in (
                ("image", self._memory),
                ("views", self._views),
                ("embedded", self._embedded),
            ):
                a = kept.pop(path, None)
                if a is not None:
                    out[key] = a
            grey = self._grey.pop(path, None)
            if grey is not None:
                out["grey"] = np.array(grey)
            if path in self._blank:
                self._blank.discard(path)
                out["blank"] = np.array(True)
            return out

    def adopt(self, path: Path, entries: dict[str, np.ndarray]) -> None:
        """Keep what another loader with the same settings decoded for ``path`` (`take`)."""
        with self._lock:
            for key, kept in (
                ("image", self._memory),
                ("views", self._views),
                ("embedded", self._embedded),
            ):
                if key in entries:
                    kept.setdefault(path, entries[key])
            if "grey" in entries:
                self._grey.setdefault(path, bool(entries["grey"]))
            if "blank" in entries and bool(entries["blank"]):
                self._blank.add(path)

    def _uses_processes(self, files: int, workers: int) -> bool:
        """Whether `preload` decodes ``files`` files in worker processes (``data.decode``)."""
        if workers <= 1 or type(self) is not ImageLoader:  # a subclass serves its own arrays
            return False
        if self.config.decode == "processes":
            return True
        return self.config.decode == "auto" and files >= PROCESS_DECODE_MIN and can_fork()

    def preload(
        self, items: Iterable[Item], workers: int | None = None, *, views: bool = False
    ) -> int:
        """Decode and preprocess items in parallel, ``data.workers`` at a time, in threads or
        worker processes (``data.decode``; `lookfeel.data.decode_pool`).

        Args:
            items: what to decode: each item's image, or its `embed_array` views where it
                `pools_views`.
            workers: threads or processes (default ``config.workers``).
            views: decode the training `views` of each item (its image among them).

        Returns:
            The number of files decoded now (those already held are skipped).

        Warns:
            BlankDepthWarning: once for the loader, naming the first depth image decoded that
                has no valid pixel and counting the others.

        Raises:
            ImageError: for the first file that cannot be used, naming it.
        """
        items = list(items)
        todo = self._todo(items, views)
        for _ in self._decode(items, todo, workers, views):
            pass
        return len(todo)

    def preload_stream(
        self, items: Iterable[Item], workers: int | None = None, *, views: bool = False
    ) -> Iterator[int]:
        """`preload`, yielding as it goes how many of ``items``, from the first, are ready:
        a consumer (`lookfeel.embedding.embed_items`) embeds those while the rest decode.
        Yields at least once; the last value is ``len(items)``."""
        items = list(items)
        yield from self._decode(items, self._todo(items, views), workers, views)

    def _todo(self, items: Sequence[Item], views: bool) -> dict[Path, Item]:
        """The files among ``items`` still to decode, each with one of its items, in order."""
        todo: dict[Path, Item] = {}
        for it in items:
            if not self._held(it, views):
                todo.setdefault(self.frame_path(it), it)
        return todo

    def _decode(
        self, items: Sequence[Item], todo: dict[Path, Item], workers: int | None, views: bool
    ) -> Iterator[int]:
        n = workers or self.config.workers
        ready = _Ready(self, items, views)
        if not todo:
            yield len(items)
            return
        if self._uses_processes(len(todo), n):
            from lookfeel.data.decode_pool import decode_in_processes

            new_loader = functools.partial(ImageLoader, self.config, self.cache_root)
            for chunk in decode_in_processes(new_loader, list(todo.items()), n, views=views):
                for path, entries in zip(chunk.paths, chunk.entries, strict=True):
                    if entries is None:  # failed in a worker: raise its own error here
                        self.decode_one(todo[path], views=views)
                    else:
                        self.adopt(path, entries)
                yield ready.advance()
        elif n <= 1 or len(todo) < 8:
            for i, it in enumerate(todo.values()):
                self.decode_one(it, views=views)
                if i % 64 == 63:
                    yield ready.advance()
        else:
            with ThreadPoolExecutor(n) as pool:
                one = functools.partial(self.decode_one, views=views)
                for i, _ in enumerate(pool.map(one, todo.values())):
                    if i % 64 == 63:
                        yield ready.advance()
        self._say_blank(todo)  # in the order given, whichever thread or process read each
        yield ready.advance()


class _Ready:
    """How many of ``items``, from the first, a loader holds (advanced as decoding goes)."""

    def __init__(self, loader: ImageLoader, items: Sequence[Item], views: bool) -> None:
        self.loader, self.items, self.views, self.count = loader, items, views, 0

    def advance(self) -> int:
        while self.count < len(self.items) and self.loader._held(
            self.items[self.count], self.views
        ):
            self.count += 1
        return self.count


class ArrayLoader(ImageLoader):
    """An `ImageLoader` serving given arrays in place of some files of one modality (a
    control's altered images: swapped backgrounds, untouched presses), keyed by file."""

    def __init__(
        self, config: DataConfig, arrays: dict[Path, np.ndarray], modality: Modality
    ) -> None:
        super().__init__(config, cache_dir=None)
        self._arrays = arrays
        self._modality = modality

    def _held(self, item: Item, views: bool) -> bool:
        if item.modality is self._modality and self.frame_path(item) in self._arrays:
            return True
        return super()._held(item, views)

    def array(self, path: Path, modality: Modality | str) -> np.ndarray:
        modality = Modality.of(modality)
        if modality is self._modality and path in self._arrays:
            return self._arrays[path]
        return super().array(path, modality)

    def _pools(self, path: Path, modality: Modality) -> bool:
        # A given array is one image (a batch repeats it as every view: `stack_views`).
        if modality is self._modality and path in self._arrays:
            return False
        return super()._pools(path, modality)
