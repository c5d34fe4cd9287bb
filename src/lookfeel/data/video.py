"""Tactile videos in: decode a GelSight Mini / DIGIT recording and find its press.

A person presses a sensor and gets a ``.mov``, ``.mp4`` or ``.mkv``, not a folder of frames
(`lookfeel.data.files.VIDEO_SUFFIXES` lists the suffixes read).
This module decodes such a file with PyAV (FFmpeg's bindings; no OpenCV), finds the press in
it, and returns the frames the model needs:

- `read_video`: every frame as (T, H, W, 3) uint8 RGB.
- `detect_press`: the no-contact reference frames at the start, the contact span and the frame
  of deepest contact (`PressSpan`), from a per-frame contact signal: how far each frame's small
  greyscale version moved from the median of the first frames (the mean of its 5% most changed
  pixels, after removing a global brightness shift), thresholded relative to the noise of the
  frames before contact and to the peak. A change of the whole frame's light (the LED, the
  exposure) is told from contact by its shape: it is a gain and offset of the untouched frame;
  a camera's exposure settling in the first frames is skipped. A video that begins mid-press
  (its first frames already moving) is refused; one with two presses keeps the deeper, with a
  `TwoPressesWarning`.
- `contact_frames`, `reference_frame`, `difference_image`: the chosen frames and their
  difference from the no-contact frame (``128 + gain * (frame - reference)``), which removes
  the sensor's own light pattern and its drift.
- `read_press`: all of it at once (`Press`, which also says whether the video has no colour:
  `Press.grey`); `lookfeel.data.images.ImageLoader` calls it for a touch item whose file is a
  video, and caches the result like an image (keyed, among the settings, by
  `PRESS_DETECTOR_VERSION`).

`read_video`, `small_greyscale` and `read_press` can turn every frame as it is decoded
(``rotate``: 90, 180 or 270 degrees clockwise, `rotate_frame`; ``data.video_rotate``), for a
video recorded turned against the others (a sensor mounted on its side). The turn comes before
anything else sees a frame: the press is found on the turned frames, and the reference and the
differences are of turned frames. A turn does not change which frames a video yields: the
contact signal is of the small frames' pixels, not their order (every fourth of PhysiCLeAR's
401 videos reads the same frames turned 90 degrees, its images turned).

Decoding is fast because full RGB is made only for the frames kept: the press is found on the
luma plane of the decoded YUV frames (block-averaged to about 40x30), and only the chosen
frames and the reference frames are converted to RGB (from the decoded frames held in memory,
or, for a long or large video, by decoding again). Its memory does not grow with the video:
`read_press` holds at most 64 MB of decoded frames (`_KEEP_DECODED_BYTES`), one float32 frame
(the reference, summed as its frames come), the images it returns, and one frame at a time in
RGB; a 4K press of one image costs about 0.3 GB beyond the interpreter, not 1.5 GB.

Every file goes through the image policy (`lookfeel.data.files.read_image_file`: a regular
file, at most 512 MB). A frame larger than ``max_pixels`` (`DEFAULT_MAX_PIXELS`), a video of
more than `MAX_VIDEO_FRAMES` frames or more than 4 gigapixels in all is refused, from the
stream's header before decoding where it declares them. A file that cannot be decoded (not a
video, an image renamed, damaged, or fewer frames than it declares; a QuickTime/MP4 file whose
boxes end before they say, a copy interrupted, is said to look cut short: `CUT_SHORT`), a video
with no contact (a change of light alone included), one that begins mid-press, or one too short
raises `VideoError` naming the file. A file that declares its duration but not its frames (Matroska)
and whose frames end clearly before it is read as far as it goes, with a
`TruncatedVideoWarning` naming it.
"""

from __future__ import annotations

import io
import os
import warnings
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from lookfeel.data.files import DEFAULT_MAX_PIXELS, VIDEO_SUFFIXES, ImageError, read_image_file
from lookfeel.errors import caller_stacklevel

if TYPE_CHECKING:
    import av.video.frame

__all__ = [
    "CUT_SHORT",
    "DEFAULT_GAIN",
    "MAX_VIDEO_FRAMES",
    "MIN_VIDEO_FRAMES",
    "PRESS_DETECTOR_VERSION",
    "ROTATIONS",
    "VIDEO_SUFFIXES",
    "NoPressError",
    "Press",
    "PressSpan",
    "TruncatedVideoWarning",
    "TwoPressesWarning",
    "VideoError",
    "band_rows",
    "contact_frames",
    "deep_frames",
    "detect_press",
    "difference_image",
    "frame_at",
    "is_grey_video",
    "is_single_channel",
    "is_video",
    "read_press",
    "read_video",
    "reference_frame",
    "rotate_frame",
    "small_greyscale",
    "view_frames",
]

PRESS_DETECTOR_VERSION = 1
"""The version of how a press is found and its frames chosen (`detect_press`, `_scan`'s small
frames, `read_press`, `contact_frames`, `deep_frames`, `view_frames`). It is part of every
cache key of decoded images (`lookfeel.data.images.PreprocessSettings`) and so of a library's
shard keys: a press decoded by another version is decoded again, never reused. Raise it with
any change that changes which frames a video yields or their pixels."""
ROTATIONS = (0, 90, 180, 270)
"""The turns `rotate_frame` gives a frame, in degrees clockwise (``data.video_rotate``)."""
MAX_VIDEO_FRAMES = 10_000
"""Most frames decoded from one video (400 s at 25 frames/s); a longer one is refused."""
MIN_VIDEO_FRAMES = 5
"""Fewest frames a press video may have: a few no-contact frames, then the press."""
DEFAULT_GAIN = 8.0
"""Default ``gain`` of `difference_image`: the largest that saturates few pixels. On the 398
PhysiCLeAR presses the change at the deepest frame is at most 19 grey levels in 99% of pixels
(median video), so gain 8 saturates about 2% of them and keeps the depth of the rest. Pick 1 of
10 among objects from raw difference pixels is flat for gains 2-8 (0.40 top-1); larger gains
score higher on raw pixels (0.48 at 64, saturating half the pixels) by turning the image into a
contact mask (`benchmarks/bench_video_pixels.py`)."""
_MAX_DECODED_PIXELS = 4_000_000_000
"""Most pixels decoded from one video, all frames together (10,000 frames of 640x480 are 3.1
billion): a small file declaring many large frames would otherwise cost hours of decoding."""
_MAX_RGB_BYTES = 2 * 1024**3
"""`read_video` refuses to hold more than this many bytes of RGB frames."""
_KEEP_DECODED_BYTES = 64 * 1024**2
"""`read_press` holds decoded (YUV) frames up to this size to convert the chosen ones to RGB
without decoding again: every frame of a 320x240 video of up to 580 frames (23 s at 25
frames/s; PhysiCLeAR's are 126), 20 of 1080p. A larger video is decoded again rather than held
(its frames are not held beyond this while it is scanned)."""

_SIGNAL_SIDE = 30
"""The small greyscale version of a frame has about this many pixels on its short side."""
_TOP_FRACTION = 0.05
"""The contact signal averages this fraction of the most changed pixels of a frame."""
_LIGHT_SHARE = 0.5
"""A press's deepest frame must keep more than this share of its contrast once a change of the
whole frame's light (a gain and offset of the untouched frame) is removed, else the video is
a change of light with no press. Synthetic steps of 10-20% in brightness keep 3-40% (weaker
ones mostly stay under the contact threshold); the 398 PhysiCLeAR presses keep at least 75%
(median 99%), so the rule changes none of them."""
_SETTLE_LEVELS = 2.0
"""A first frame whose whole-frame light (a gain and offset) differs from the frames after it by
at least this many grey levels, with nothing else changed, is the camera's exposure settling
and is skipped (`_settle`). The 398 PhysiCLeAR presses change by at most 0.7 grey levels in
their first five frames (1.1 in mean brightness), so none is skipped; on a GelSight Mini frame
of mean grey 85, a settle from 92% of the light is 7 levels."""
_MAX_SETTLE = 30
"""Most frames skipped as the camera's exposure settling (about a second)."""
_MOVING_START = 1.75
"""A video whose gel moves before contact by more than this many times its own frame-to-frame
noise began mid-press (`_start_motion`). The 398 PhysiCLeAR presses move at most 1.37 times it
in their first five frames; clips cut from one of them (egg_1) 2 to 25 frames into its
contact move 2.0 to 4.7 times it."""
_FEW_FRAMES_AFTER = 10
"""With fewer frames than this after the reference frames, the floor and noise of the contact
signal come from the reference frames (`detect_press`)."""
_HELD_SHARE = 0.5
"""A floor (10th percentile after the reference frames) more than this share of the way from
the reference frames' level to the peak means the frames after them are nearly all pressed
(held to the end), if it is also as far above them as a press needs: the floor is then the
reference frames' level. The 398 PhysiCLeAR presses are at most 0.41 of the way."""
_SECOND_PRESS_SHARE = 0.5
"""Contact outside the chosen span is another press (`TwoPressesWarning`) when at least this
share as deep as the chosen one ..."""
_SECOND_PRESS_FRAMES = 3
"""... for at least this many frames, with the gel released in between."""
_TRUNCATED_SLACK = 0.02
"""A file's frames may end this fraction of its declared duration (and two frames) early
before `TruncatedVideoWarning` says it is truncated."""


class VideoError(ImageError):
    """A video cannot be used: undecodable, too short, too large, or no press found in it."""


class TruncatedVideoWarning(UserWarning):
    """A video's frames end clearly before the duration its file declares: the file was cut
    (a copy or a recording interrupted); what is there is read."""


class TwoPressesWarning(UserWarning):
    """A video holds more than one press (the gel released in between): the deepest is used,
    the others are left out."""


class NoPressError(VideoError):
    """A video decodes but holds no usable press: too short, no contact (or a change of light
    alone), or contact from its first frame (pressed, or already moving: begun mid-press). A
    dataset's run leaves such a recording out with a warning (`lookfeel.data.drop_unpressed`);
    a query that is one is an error."""


def is_video(path: str | os.PathLike[str]) -> bool:
    """Whether ``path`` names a video file, by its suffix (`VIDEO_SUFFIXES`, any case)."""
    return Path(path).suffix.lower() in VIDEO_SUFFIXES


def _read_bytes(path: Path) -> bytes:
    """The file's bytes under the image policy (`read_image_file`), errors worded for videos."""
    try:
        return read_image_file(path)
    except VideoError:
        raise
    except ImageError as e:
        raise VideoError(
            path, e.reason.replace("an image", "a video").replace("image", "video")
        ) from None


def _import_av(path: Path) -> Any:
    try:
        import av
    except ImportError:
        raise VideoError(
            path, "reading videos needs PyAV: install the `av` package (pip install av)"
        ) from None
    return av


# ---------------------------------------------------------------------------------------------
# Decoding.


def rotate_frame(frame: np.ndarray, degrees: int) -> np.ndarray:
    """An (H, W) or (H, W, C) ``frame`` turned ``degrees`` clockwise (`ROTATIONS`): 90 makes a
    320x240 (landscape) frame 240x320 (portrait), its top row becoming its right column. 0
    returns ``frame`` itself; the others a view of it (``np.rot90``).

    Raises:
        ValueError: ``degrees`` is not one of `ROTATIONS`.
    """
    _check_turn(degrees)
    return np.rot90(frame, k=-(degrees // 90), axes=(0, 1)) if degrees else frame


def _check_turn(degrees: int) -> None:
    """Raise ValueError unless ``degrees`` is one of `ROTATIONS` (an int, not a bool)."""
    if type(degrees) is not int or degrees not in ROTATIONS:
        raise ValueError(f"rotate must be 0, 90, 180 or 270 (degrees clockwise); got {degrees!r}")


def _rgb(frame: av.video.frame.VideoFrame, rotate: int) -> np.ndarray:
    """(H, W, 3) uint8 RGB of a decoded frame, turned ``rotate`` degrees clockwise: where every
    frame kept in colour becomes an array."""
    return rotate_frame(frame.to_ndarray(format="rgb24"), rotate)


def _declared_seconds(container: Any, stream: Any) -> float | None:
    """How long the file says its video stream lasts, in seconds, or ``None`` if it does not.

    The stream's own duration where the container keeps one (QuickTime/MP4, AVI), else its
    ``DURATION`` tag (Matroska as FFmpeg writes it), else the whole file's duration when
    the video is its only stream (an audio track may last longer than the video).
    """
    if stream.duration and stream.time_base:
        return float(stream.duration * stream.time_base)
    tag = stream.metadata.get("DURATION") or stream.metadata.get("duration")
    if tag:
        try:
            h, m, sec = tag.split(":")
            return int(h) * 3600 + int(m) * 60 + float(sec)
        except ValueError:
            pass
    if container.duration and len(container.streams) == 1:
        return float(container.duration) / 1_000_000  # in AV_TIME_BASE units
    return None


def _warn_if_cut(
    path: Path, n: int, first: float | None, last: float | None, declared: float | None, rate: float
) -> None:
    """Warn (`TruncatedVideoWarning`) when the ``n`` frames decoded, presented from ``first`` to
    ``last`` seconds at ``rate`` frames/s, end clearly before the ``declared`` duration."""
    if declared is None or declared <= 0 or first is None or last is None:
        return
    step = 1.0 / rate if rate > 0 else 0.0
    read = last - first + step
    if declared - read <= max(2 * step, _TRUNCATED_SLACK * declared):
        return
    about = f" (about {round(declared * rate)} frames)" if rate > 0 else ""
    warnings.warn(
        TruncatedVideoWarning(
            f"{path}: video is truncated: {n} frames ({read:.2f} s) decoded of the "
            f"{declared:.2f} s{about} it declares; reading those"
        ),
        stacklevel=3,
    )


CUT_SHORT = "cannot decode video: the file looks cut short (copy it again)"
"""Why a QuickTime/MP4 file FFmpeg cannot open is refused when its boxes end before they say
they do (`_cut_short`): a copy or download interrupted, not a file of another kind."""

_QUICKTIME_BOXES = (b"ftyp", b"moov", b"mdat", b"wide", b"free", b"skip", b"pnot")
"""The boxes a QuickTime/MP4 file (.mov, .mp4, .m4v) begins with (as
`lookfeel.data.layout.sniff_video` knows them)."""


def _cut_short(blob: bytes) -> bool:
    """Whether ``blob`` is a QuickTime/MP4 file whose box structure is incomplete: a box that
    declares more bytes than the file holds (its media data ``mdat`` half there), one whose
    header is cut, or no ``moov`` box (the index of the frames, which a camera or FFmpeg writes
    last) after complete boxes. False for a file that begins as no such box, and for one whose
    boxes are whole (damaged otherwise)."""
    if blob[4:8] not in _QUICKTIME_BOXES:
        return False
    at, index = 0, False
    while at < len(blob):
        if at + 8 > len(blob):
            return True  # a box header cut
        size, kind, head = int.from_bytes(blob[at : at + 4], "big"), blob[at + 4 : at + 8], 8
        if size == 1:  # a 64-bit size follows the type
            if at + 16 > len(blob):
                return True
            size, head = int.from_bytes(blob[at + 8 : at + 16], "big"), 16
        elif size == 0:  # the box runs to the end of the file
            size = len(blob) - at
        if size < head:
            return False  # no box structure: damaged, not cut
        index = index or kind == b"moov"
        if at + size > len(blob):
            return True
        at += size
    return not index


def _decode(
    path: Path,
    data: bytes | None,
    max_pixels: int | None,
    max_frames: int | None,
) -> Iterator[av.video.frame.VideoFrame]:
    """Every decoded frame of the file's first video stream, checked against the limits.

    Raises:
        VideoError: not a regular file, not a video, undecodable, truncated, frames larger than
            ``max_pixels``, or more than ``max_frames`` frames.
    """
    av = _import_av(path)
    blob = _read_bytes(path) if data is None else data
    if not blob:
        raise VideoError(path, "cannot decode video: file is empty")
    limit = DEFAULT_MAX_PIXELS if max_pixels is None else max_pixels
    most = MAX_VIDEO_FRAMES if max_frames is None else max_frames
    errors = (av.FFmpegError, OSError, ValueError, EOFError, MemoryError)
    try:
        container = av.open(io.BytesIO(blob), mode="r")
    except errors:
        if _cut_short(blob):
            raise VideoError(path, CUT_SHORT) from None
        raise VideoError(path, "cannot decode video: not a video file FFmpeg can read") from None
    with container:
        fmt = container.format.name
        if fmt.endswith("_pipe") or fmt == "image2":
            raise VideoError(
                path, f"cannot decode video: the file is an image ({fmt}), not a video"
            )
        if not container.streams.video:
            raise VideoError(path, "cannot decode video: the file has no video stream")
        stream = container.streams.video[0]
        w, h = stream.codec_context.width, stream.codec_context.height
        if w * h > limit:
            raise VideoError(
                path,
                f"video declares {w}x{h} = {w * h / 1e6:.1f} megapixel frames; at most "
                f"{limit / 1e6:g} are decoded",
            )
        declared = stream.frames
        if declared > most:
            raise VideoError(
                path, f"video is too large: it declares {declared} frames; at most {most} are read"
            )
        if declared * w * h > _MAX_DECODED_PIXELS:
            raise VideoError(
                path,
                f"video is too large: {declared} frames of {w}x{h} exceed "
                f"{_MAX_DECODED_PIXELS / 1e9:g} gigapixels in all",
            )
        seconds = None if declared > 0 else _declared_seconds(container, stream)
        rate = float(stream.average_rate or stream.guessed_rate or 0)
        first: float | None = None
        last: float | None = None
        stream.thread_type = "AUTO"
        n = total = 0
        try:
            for frame in container.decode(stream):
                if frame.width * frame.height > limit:
                    raise VideoError(
                        path,
                        f"frame {n} is {frame.width}x{frame.height}; at most "
                        f"{limit / 1e6:g} megapixels are decoded",
                    )
                n += 1
                total += frame.width * frame.height
                if frame.time is not None:
                    first = frame.time if first is None else min(first, frame.time)
                    last = frame.time if last is None else max(last, frame.time)
                if n > most:
                    raise VideoError(path, f"video is too large: more than {most} frames")
                if total > _MAX_DECODED_PIXELS:
                    raise VideoError(
                        path,
                        f"video is too large: its frames exceed {_MAX_DECODED_PIXELS / 1e9:g} "
                        "gigapixels in all",
                    )
                yield frame
        except VideoError:
            raise
        except errors:
            raise VideoError(
                path, f"cannot decode video: damaged after {n} frames (truncated or corrupt)"
            ) from None
    if n == 0:
        raise VideoError(path, "cannot decode video: no frame could be decoded")
    if declared > 0 and n < declared:
        raise VideoError(
            path, f"video is truncated: {n} of the {declared} frames it declares could be decoded"
        )
    _warn_if_cut(path, n, first, last, seconds, rate)


def read_video(
    path: str | os.PathLike[str],
    *,
    data: bytes | None = None,
    max_frames: int | None = None,
    max_pixels: int | None = None,
    rotate: int = 0,
) -> np.ndarray:
    """Decode every frame of a video.

    Args:
        path: the file; with ``data``, only the name used in errors.
        data: the file's bytes, read from ``path`` when ``None``.
        max_frames: most frames decoded (default `MAX_VIDEO_FRAMES`); a longer video raises.
        max_pixels: largest width x height of a frame (default `DEFAULT_MAX_PIXELS`).
        rotate: turn every frame this many degrees clockwise (`rotate_frame`).

    Returns:
        (T, H, W, 3) uint8 RGB ((T, W, H, 3) turned 90 or 270 degrees).

    Raises:
        VideoError: as `read_press`, or the frames would take more than 2 GiB.
        ValueError: ``rotate`` is not one of `ROTATIONS`.
    """
    p = Path(path)
    _check_turn(rotate)  # before anything is read
    out: list[np.ndarray] = []
    size = 0
    for frame in _decode(p, data, max_pixels, max_frames):
        rgb = _rgb(frame, rotate)
        if out and rgb.shape != out[0].shape:
            raise VideoError(p, f"frame {len(out)} changes size to {rgb.shape[1]}x{rgb.shape[0]}")
        size += rgb.nbytes
        if size > _MAX_RGB_BYTES:
            raise VideoError(p, f"video is too large: its RGB frames exceed {_MAX_RGB_BYTES} bytes")
        out.append(rgb)
    return np.stack(out)


_PLANAR_8BIT = frozenset(
    ("yuv420p", "yuv422p", "yuv444p", "yuv411p", "yuv410p", "yuv440p", "nv12", "nv21", "gray")
)
_FULL_RANGE = frozenset(("yuvj420p", "yuvj422p", "yuvj444p", "yuvj440p", "yuvj411p"))
_LIMITED_SCALE = np.float32(255.0 / 219.0)
"""Video-range luma spans 16..235; ``(Y - 16) * 255 / 219`` is the full-range grey level."""


def _luma(frame: av.video.frame.VideoFrame) -> tuple[np.ndarray, bool]:
    """(H, W) uint8 luma of a decoded frame (the Y plane itself for 8-bit planar YUV), and
    whether it is video range (16..235)."""
    name = frame.format.name
    if name in _PLANAR_8BIT or name in _FULL_RANGE:
        plane = frame.planes[0]
        a = np.frombuffer(memoryview(plane), np.uint8)
        limited = name != "gray" and name not in _FULL_RANGE
        return a.reshape(frame.height, plane.line_size)[:, : frame.width], limited
    return np.asarray(frame.to_ndarray(format="gray")), False


def _block_factor(h: int, w: int) -> int:
    return max(1, min(h, w) // _SIGNAL_SIDE)


def _shrink(grey: np.ndarray, f: int) -> np.ndarray:
    """Mean of f x f blocks of an (H, W) or (T, H, W) image, float32 (remainder cropped)."""
    if f == 1:
        return grey.astype(np.float32)
    h, w = grey.shape[-2] // f * f, grey.shape[-1] // f * f
    g = grey[..., :h, :w].astype(np.uint32)
    rows = g[..., 0::f, :]
    for i in range(1, f):
        rows = rows + g[..., i::f, :]
    out = rows[..., 0::f]
    for j in range(1, f):
        out = out + rows[..., j::f]
    return out.astype(np.float32) / np.float32(f * f)


def _greyscale(frames: np.ndarray) -> np.ndarray:
    """(T, H, W, 3) RGB or (T, H, W) grey -> (T, H, W) float32 grey (BT.601 luma weights)."""
    if frames.ndim == 3:
        return frames.astype(np.float32)
    if frames.ndim != 4 or frames.shape[-1] != 3:
        raise ValueError(f"frames must be (T, H, W, 3) or (T, H, W); got {frames.shape}")
    w = np.array([0.299, 0.587, 0.114], dtype=np.float32)
    return frames.astype(np.float32) @ w


def small_greyscale(
    path: str | os.PathLike[str],
    *,
    data: bytes | None = None,
    max_frames: int | None = None,
    max_pixels: int | None = None,
    rotate: int = 0,
) -> np.ndarray:
    """Decode a video into small greyscale frames: what `detect_press` needs, and fast.

    Each frame's luma plane is block-averaged to about 40x30 pixels (no RGB conversion) and
    put on the full-range 0..255 grey scale, then turned ``rotate`` degrees clockwise
    (`rotate_frame`).

    Returns:
        (T, h, w) float32.

    Raises:
        VideoError: as `read_video`.
        ValueError: ``rotate`` is not one of `ROTATIONS`.
    """
    p = Path(path)
    _check_turn(rotate)  # before anything is read
    blob = _read_bytes(p) if data is None else data
    return _scan(p, blob, max_frames, max_pixels, keep_bytes=0, rotate=rotate)[0]


def _scan(
    p: Path,
    blob: bytes,
    max_frames: int | None,
    max_pixels: int | None,
    keep_bytes: int,
    rotate: int = 0,
) -> tuple[np.ndarray, list[av.video.frame.VideoFrame] | None, str]:
    """Small greyscale frames, the decoded frames themselves while they fit ``keep_bytes``
    (``None`` beyond: the caller decodes again rather than hold a long video in memory), and
    the first frame's pixel format.

    The small frames are turned ``rotate`` degrees clockwise once block-averaged, so that they
    are exactly the unturned ones turned (averaging first crops a remainder of rows and columns
    at the bottom and right, which would be other pixels once turned): the press is found on
    the same pixels, in another order, which the contact signal does not depend on."""
    small: list[np.ndarray] = []
    kept: list[av.video.frame.VideoFrame] | None = [] if keep_bytes > 0 else None
    held = 0
    factor = 0
    pixel_format = ""
    for frame in _decode(p, blob, max_pixels, max_frames):
        if not factor:
            factor = _block_factor(frame.height, frame.width)
            pixel_format = frame.format.name
        y, limited = _luma(frame)
        g = _shrink(y, factor)
        if limited:
            g -= np.float32(16.0)
            g *= _LIMITED_SCALE
        g = rotate_frame(g, rotate)
        if small and g.shape != small[0].shape:
            raise VideoError(p, f"frame {len(small)} changes size to {frame.width}x{frame.height}")
        small.append(g)
        if kept is not None:
            held += frame.width * frame.height * 3 // 2
            if held <= keep_bytes:
                kept.append(frame)
            else:
                kept = None
    return np.stack(small), kept, pixel_format


# ---------------------------------------------------------------------------------------------
# Finding the press.


@dataclass(frozen=True)
class PressSpan:
    """Where the press is in a video of T frames (indices into its frames)."""

    reference: tuple[int, int]
    """The no-contact reference frames, ``range(*reference)``: the first frames of the video
    (at least ``first`` of them when contact starts later, at most ``reference_frames``), after
    the frames of a camera's exposure settling where it has them."""
    start: int
    """First frame in contact."""
    peak: int
    """Frame of deepest contact (largest contact signal)."""
    end: int
    """First frame after the release (exclusive end of the contact span), or T."""
    strength: np.ndarray
    """(T,) float32 contact signal of every frame, in grey levels (0-255 scale); for the frames
    of a camera's exposure settling (before ``reference``), once their change of light is
    removed."""
    floor: float
    """The signal's level without contact (its 10th percentile after the first frames; in a
    short clip or one pressed to its end, the first frames' own level)."""
    noise: float
    """Frame-to-frame noise of the signal without contact (a robust standard deviation)."""
    threshold: float
    """Frames whose signal exceeds this are in contact."""

    @property
    def frames(self) -> int:
        """T, the number of frames of the video."""
        return len(self.strength)

    @property
    def contrast(self) -> float:
        """Peak signal above the no-contact floor, in grey levels."""
        return float(self.strength[self.peak]) - self.floor


def _strength(grey: np.ndarray, first: int) -> np.ndarray:
    """(T,) contact signal of (T, h, w) small grey frames against the median of the first ones.

    Each frame's difference from the reference, less its median (a global brightness shift is
    not contact), is scored by the mean of its most changed ``_TOP_FRACTION`` pixels: contact
    is local, so averaging the whole frame would drown a fingertip-sized press.
    """
    ref = np.median(grey[:first], axis=0)
    return _top_change((grey - ref).reshape(len(grey), -1))


def _top_change(d: np.ndarray) -> np.ndarray:
    """(T,) mean of the ``_TOP_FRACTION`` largest ``|d - median|`` of each row of (T, N) ``d``
    (changed in place)."""
    d -= np.median(d, axis=1, keepdims=True)
    np.abs(d, out=d)
    k = max(1, round(d.shape[1] * _TOP_FRACTION))
    top = np.partition(d, d.shape[1] - k, axis=1)[:, -k:]
    return top.mean(axis=1).astype(np.float32)


def _light_change(reference: np.ndarray, frame: np.ndarray) -> tuple[float, float]:
    """What of a frame's change is not a change of the whole frame's light.

    A step of the sensor's light (its LED, the camera's exposure) changes every pixel of the
    untouched frame by one gain and offset: ``frame ~ gain * reference + offset``. A press
    changes part of the gel, which no gain and offset reproduce. The gain and offset are
    fitted robustly (least squares, refitted twice on the half of the pixels it fits best, so
    that a press does not pull the fit) and removed.

    Returns:
        The contact signal of the remainder (as `_strength` measures a frame), and the fitted
        change of the frame's mean brightness, in grey levels.
    """
    x = reference.reshape(-1).astype(np.float64)
    y = frame.reshape(-1).astype(np.float64)
    design = np.stack([x, np.ones_like(x)], axis=1)
    keep = np.ones(len(x), bool)
    for _ in range(3):
        (gain, offset), *_ = np.linalg.lstsq(design[keep], y[keep], rcond=None)
        rest = y - (gain * x + offset)
        off = np.abs(rest - np.median(rest))
        keep = off <= np.median(off)
    left = float(_top_change(rest.astype(np.float32)[None])[0])
    return left, float((gain - 1.0) * x.mean() + offset)


def _settle(grey: np.ndarray, first: int) -> tuple[int, np.ndarray]:
    """How many frames at the start are a camera's exposure settling, and their contact signal.

    A webcam's auto exposure (a DIGIT's, for one) often takes a few frames to settle: the first
    frames are darker or brighter, then the light stays. Those frames are a gain and offset of
    the settled frames (`_light_change`), not contact. This finds the first frame ``j`` from
    which the light holds: the ``first + 2`` frames from ``j`` keep the light of the median of
    the ``first`` from ``j`` (within `_SETTLE_LEVELS`), and every frame before ``j`` differs
    from it by a change of light of at least `_SETTLE_LEVELS` that explains most of its change.
    Without such a ``j`` (at most `_MAX_SETTLE`), nothing is skipped. (A frame whose mean grey
    level is within `_SETTLE_LEVELS` of the reference's keeps its light without a fit: most
    videos cost five means.)

    Returns:
        ``j`` (0: nothing to skip), and the (j,) contact signal of the skipped frames once
        their change of light is removed.
    """

    def changed(ref: np.ndarray, frame: np.ndarray) -> bool:
        return (
            abs(float(frame.mean()) - float(ref.mean())) >= _SETTLE_LEVELS
            and abs(_light_change(ref, frame)[1]) >= _SETTLE_LEVELS
        )

    window = first + 2
    for j in range(min(_MAX_SETTLE, len(grey) - window) + 1):
        ref = np.median(grey[j : j + first], axis=0)
        if any(changed(ref, grey[i]) for i in range(j, j + window)):
            continue  # the light still changes from frame j on
        fits = [_light_change(ref, grey[i]) for i in range(j)]
        if all(abs(shift) >= _SETTLE_LEVELS and left <= 0.5 * abs(shift) for left, shift in fits):
            return j, np.array([left for left, _ in fits], np.float32)
        break
    return 0, np.zeros(0, np.float32)


def _motion(grey: np.ndarray, a: int, b: int) -> float:
    """How far frame ``b`` of (T, h, w) ``grey`` moved from frame ``a`` (as `_strength` scores
    a frame's change)."""
    return float(_top_change((grey[b] - grey[a]).reshape(1, -1))[0])


def _start_motion(grey: np.ndarray, start: int, first: int) -> float:
    """How much the gel moves in the frames before contact (at most ``first + 2``) of (T, h, w)
    small grey frames.

    An untouched gel is still: its first frames differ by the camera's noise alone. A video
    that begins mid-press shows a gel that is already moving (pressed deeper or released). This
    is the smallest change between frame 0 or 1 and one of the last two frames before contact,
    so that one odd frame (a camera's first frame is sometimes one) does not count.
    """
    n = min(start, first + 2)
    return min(_motion(grey, a, b) for a in (0, 1) for b in (n - 2, n - 1) if b > a)


def _step_noise(grey: np.ndarray) -> float:
    """The median change between consecutive frames of (T, h, w) small grey frames: how much
    a video's frames differ when little moves (its noise)."""
    steps = (grey[1:] - grey[:-1]).reshape(len(grey) - 1, -1)
    return float(np.median(_top_change(steps)))


def _runs(above: np.ndarray) -> list[tuple[int, int]]:
    """The ``(start, stop)`` of each run of True in a (T,) bool array."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], above.view(np.int8), [0]])))
    return [(int(a), int(b)) for a, b in zip(edges[0::2], edges[1::2], strict=True)]


def _other_presses(
    s: np.ndarray, span: tuple[int, int], after: int, floor: float, contrast: float, thr: float
) -> list[tuple[int, int]]:
    """Other presses than the contact ``span`` in the (T,) contact signal ``s``: runs of at
    least `_SECOND_PRESS_FRAMES` frames in contact (above ``thr``, from frame ``after`` on),
    pressed at least `_SECOND_PRESS_SHARE` as deep as the span, with the gel released between
    them and the span (the signal back below ``floor + contrast / 10``)."""
    above = s > thr
    above[: max(after, 0)] = False
    above[span[0] : span[1]] = False
    released = floor + 0.1 * contrast
    out = []
    for a, b in _runs(above):
        gap = s[b : span[0]] if b <= span[0] else s[span[1] : a]
        if (
            b - a >= _SECOND_PRESS_FRAMES
            and float(s[a:b].max()) - floor >= _SECOND_PRESS_SHARE * contrast
            and len(gap)
            and float(gap.min()) <= released
        ):
            out.append((a, b))
    return out


def detect_press(
    frames: np.ndarray,
    path: str | os.PathLike[str] | None = None,
    *,
    first: int = 3,
    reference_frames: int = 5,
    contact_fraction: float = 0.2,
    min_contrast: float = 1.0,
    min_snr: float = 8.0,
    min_frames: int = MIN_VIDEO_FRAMES,
) -> PressSpan:
    """Find the press in a video: its no-contact reference, contact span and deepest frame.

    The contact signal (`PressSpan.strength`) measures how far each frame moved from the median
    of the ``first`` frames. Its no-contact floor is its 10th percentile after those frames and
    its noise the median absolute frame-to-frame change there; a frame is in contact when its
    signal exceeds ``floor + contact_fraction * (peak - floor)``. The span is the run of
    contact frames around the peak; the reference is the first frames, as many as stay quiet
    (up to ``reference_frames``, never into the span).

    Where the frames after the reference cannot give the floor, the reference frames' own
    level (the median of their signal) is the floor: in a short clip (fewer than
    `_FEW_FRAMES_AFTER` frames after them, mostly pressed; the noise is then their signal's
    frame-to-frame change too), and where the floor lies above their level by more than half
    the way to the peak (`_HELD_SHARE`) and by as much as a press needs (``min_contrast``,
    ``min_snr`` times the noise): nearly every frame after them is pressed, as in a press held
    to the end of the recording.

    A camera's exposure settling in the first frames (a change of the whole frame's light that
    stops: `_settle`) is skipped: the reference and everything else start after it.

    A press changes part of the gel; a step of the sensor's light (its LED, the camera's
    exposure) changes the whole frame at once and stays. So the deepest frame must keep more
    than half its contrast (`_LIGHT_SHARE`) once the best gain and offset of the whole
    untouched frame are removed (`_light_change`), else the video is a change of light with no
    press (`NoPressError`). A press during which the light also changes still counts.

    A video must begin untouched: its reference is the gel before contact. One whose first
    frames already move (`_start_motion`: by more than ``min_contrast`` and more than
    `_MOVING_START` times the video's frame-to-frame noise, `_step_noise`) began mid-press,
    and is refused rather than read backwards (its release taken for the press). A video with
    two presses (the gel released in between) keeps the deeper one, with a
    `TwoPressesWarning` naming both.

    The signal is on brightness only (a GelSight press changes it; its colour channels are
    noisier after compression): a change of colour at constant brightness is not seen. On the
    401 PhysiCLeAR videos it finds a press in 398; the other three are two videos of 3 frames
    and one of 7 frames that change by at most 0.5 grey levels.

    Args:
        frames: (T, H, W, 3) uint8 RGB or (T, H, W) greyscale (small is enough: about 40x30).
        path: the video, named in errors.
        first: frames whose median is the signal's reference (the sensor untouched).
        reference_frames: most frames in the returned reference span.
        contact_fraction: threshold between the floor (0) and the peak (1).
        min_contrast: the peak must exceed the floor by this many grey levels ...
        min_snr: ... and by this many times the noise, else the video has no contact.
        min_frames: fewest frames accepted.

    Returns:
        `PressSpan`.

    Raises:
        NoPressError: fewer than ``min_frames`` frames, no contact (or a change of the whole
            frame's light alone), or contact from the first frame (no still, untouched frames
            at the start to compare against).
    """
    p = Path(path) if path is not None else Path("<frames>")
    t = len(frames)
    min_frames = max(min_frames, first + 2)
    if t < min_frames:
        raise NoPressError(
            p,
            f"video is too short: {t} frame{'s' if t != 1 else ''}; at least {min_frames} are "
            f"needed ({first} without contact, then the press)",
        )
    grey = _greyscale(frames)
    lead, settling = _settle(grey, first)
    if t - lead < min_frames:
        raise NoPressError(
            p,
            f"video is too short: {t - lead} frames after the camera's exposure settled (frame "
            f"{lead}); at least {min_frames} are needed ({first} without contact, then the press)",
        )
    g = grey[lead:]  # indices into g are frame - lead
    s = _strength(g, first)
    rest = s[first:]
    floor = float(np.percentile(rest, 10))
    quiet = rest[rest <= np.percentile(rest, 50)]
    jitter = np.abs(np.diff(quiet)) if len(quiet) > 2 else np.abs(np.diff(s[: first + 2]))
    noise = float(1.4826 * np.median(jitter)) if len(jitter) else 0.0
    peak = int(np.argmax(s))
    level = float(np.median(s[:first]))
    if len(rest) < _FEW_FRAMES_AFTER:  # a short clip: too few frames after the reference
        floor = level
        noise = float(1.4826 * np.median(np.abs(np.diff(s[:first])))) if first > 1 else 0.0
    elif floor - level > max(
        _HELD_SHARE * (float(s[peak]) - level), min_contrast, min_snr * noise
    ):  # the frames after the reference are nearly all pressed (clearly, against the noise)
        floor = level
    contrast = float(s[peak]) - floor
    need = max(min_contrast, min_snr * noise)
    if contrast < need:
        raise NoPressError(
            p,
            f"no contact found: the frames change by at most {contrast:.2f} grey levels from "
            f"its first frames (noise {noise:.2f}; a press needs {need:.2f}): nothing was "
            "pressed, or the gel was pressed from the first frame, leaving no untouched frames "
            "at its start to compare against (record from before the press)",
        )
    thr = floor + contact_fraction * contrast
    start = peak
    while start > 0 and s[start - 1] > thr:
        start -= 1
    end = peak + 1
    while end < len(s) and s[end] > thr:
        end += 1
    if start == 0:
        raise NoPressError(
            p,
            "contact from the first frame: no untouched frames at its start to compare against "
            "(record from before the press)",
        )
    moved = _start_motion(g, start, first)
    steps = _step_noise(g) if moved > min_contrast else np.inf  # slower: only where it can matter
    if moved > _MOVING_START * steps:
        raise NoPressError(
            p,
            f"the press began before the recording: the gel already moves in its first frames "
            f"({moved:.2f} grey levels over frames {lead}-{lead + min(start, first + 2) - 1}, "
            f"{moved / max(steps, 1e-6):.1f} times its frame-to-frame noise), so there is no "
            "untouched frame to compare against (record from before the press)",
        )
    reference = np.median(g[:first], axis=0)
    left, shift = _light_change(reference, g[peak])
    if left - floor <= _LIGHT_SHARE * contrast:
        changed = next(
            i
            for i in range(first, peak + 1)
            if abs(_light_change(reference, g[i])[1]) >= 0.5 * abs(shift)
        )
        raise NoPressError(
            p,
            f"no contact found: the light changed with no press (from frame {lead + changed} "
            f"the whole frame is {abs(shift):.1f} grey levels "
            f"{'brighter' if shift > 0 else 'darker'}; without that the frames change by "
            f"{max(left - floor, 0.0):.2f} grey levels, a press needs more than "
            f"{_LIGHT_SHARE * contrast:.2f})",
        )
    # The reference: the first frames (the signal's own reference, untouched by assumption),
    # extended while quiet up to ``reference_frames``. Measured on PhysiCLeAR, this beats the
    # quiet frames just before contact (pick 1 of 10 from difference pixels 0.40 vs 0.39),
    # which are sometimes one or two frames between early light touches.
    low = floor + 0.5 * contact_fraction * contrast
    stop = min(first, start)
    while stop < min(reference_frames, start) and s[stop] <= low:
        stop += 1
    others = _other_presses(s, (start, end), stop, floor, contrast, thr)
    if others:
        spans = ", ".join(f"{lead + a}-{lead + b - 1}" for a, b in others)
        warnings.warn(
            TwoPressesWarning(
                f"{p}: more than one press: frames {lead + start}-{lead + end - 1} (the "
                f"deepest, used) and {spans}; record one press per video to use each"
            ),
            stacklevel=caller_stacklevel(),
        )
    return PressSpan(
        reference=(lead, lead + stop),
        start=lead + start,
        peak=lead + peak,
        end=lead + end,
        strength=np.concatenate([settling, s]) if lead else s,
        floor=floor,
        noise=noise,
        threshold=thr,
    )


def frame_at(span: PressSpan, position: float) -> int:
    """The frame at ``position`` in [0, 1] across the contact span (0: start, 1: last)."""
    if not 0.0 <= position <= 1.0:
        raise ValueError(f"position must be in [0, 1]; got {position}")
    return round(span.start + position * (span.end - 1 - span.start))


def contact_frames(span: PressSpan, n: int = 1) -> list[int]:
    """Frames to show the model: ``[peak]`` for n == 1, else n spread evenly over the span.

    For n > 1 the first is the span's start and the last its last frame; a span shorter than n
    repeats frames.
    """
    if n < 1:
        raise ValueError(f"n must be >= 1; got {n}")
    if n == 1:
        return [span.peak]
    return [int(i) for i in np.linspace(span.start, span.end - 1, n).round()]


def deep_frames(span: PressSpan, n: int, min_fraction: float = 0.0) -> list[int]:
    """The deepest frame, then the others of ``contact_frames(span, n)`` pressed at least
    ``min_fraction`` as deep (contact signal above the floor, relative to the peak's).

    These are the training views of a press (``data.video_views``): the same contact at
    slightly different forces, so that a network learns the object, not one frame. A
    ``min_fraction`` above 0 leaves out the shallow start and end of the span (the gel barely
    touched).
    """
    if not 0.0 <= min_fraction <= 1.0:
        raise ValueError(f"min_fraction must be in [0, 1]; got {min_fraction}")
    need = span.floor + min_fraction * span.contrast
    rest = [i for i in dict.fromkeys(contact_frames(span, n)) if i != span.peak]
    return [span.peak, *(i for i in rest if span.strength[i] >= need)]


def view_frames(span: PressSpan, n: int) -> list[int]:
    """The frames a press is embedded from with ``data.video_embed: views``: its deepest
    frame, then ``contact_frames(span, n)`` (n spread evenly over the span, first to last).
    Always n + 1 frames, so that every press has as many views (a short span repeats frames,
    each then weighted by the time it lasts)."""
    return [span.peak, *contact_frames(span, n)]


def reference_frame(frames: np.ndarray, span: PressSpan) -> np.ndarray:
    """(H, W, 3) float32 mean of the no-contact reference frames of (T, H, W, 3) ``frames``."""
    a, b = span.reference
    return frames[a:b].astype(np.float32).mean(axis=0)


def difference_image(
    frame: np.ndarray, reference: np.ndarray, gain: float = DEFAULT_GAIN
) -> np.ndarray:
    """(H, W, 3) uint8 ``128 + gain * (frame - reference)``, clipped to 0..255.

    Subtracting the no-contact frame leaves what the contact changed (the sensor's own light
    pattern and slow drift cancel); the gain spreads the small changes over the 8-bit range.
    A large frame is worked out a band of rows at a time (`_BAND_VALUES`), so that its float
    copies stay small: a 4K frame's whole would be 100 MB each.
    """
    if frame.ndim < 1 or np.broadcast_shapes(frame.shape, np.shape(reference)) != frame.shape:
        return _difference(frame, reference, gain)  # the reference broadcasts the frame up
    out = np.empty(frame.shape, np.uint8)
    _difference_into(out, frame, reference, gain)
    return out


_BAND_VALUES = 1 << 18
"""`difference_image` and `_colourless` work on bands of rows of about this many values (1 MB
of float32), and so does the leak check's pooling (`band_rows`): a GelSight Mini's 320x240
frame is one band, a 4K frame about 100."""


def band_rows(row_values: int, multiple: int = 1) -> int:
    """How many rows of ``row_values`` values each make a band of about `_BAND_VALUES` values:
    a whole number of ``multiple`` rows (a pooling window's height), at least one of them."""
    return multiple * max(1, _BAND_VALUES // max(1, multiple * row_values))


def _difference(frame: np.ndarray, reference: np.ndarray, gain: float) -> np.ndarray:
    """`difference_image` of a whole frame at once."""
    d = frame.astype(np.float32) - reference
    d *= np.float32(gain)
    d += np.float32(128.0)
    np.rint(d, out=d)
    np.clip(d, 0, 255, out=d)
    return d.astype(np.uint8)


def _difference_into(
    out: np.ndarray, frame: np.ndarray, reference: np.ndarray, gain: float
) -> None:
    """Write `difference_image` of ``frame`` (its shape ``out``'s) into ``out``, a band of rows
    at a time: each pixel is computed as `_difference` computes it, so the bytes are the same."""
    rows = band_rows(frame[:1].size)
    whole = np.ndim(reference) == frame.ndim and np.shape(reference)[0] == len(frame)
    for top in range(0, len(frame), rows):
        band = slice(top, top + rows)
        out[band] = _difference(frame[band], reference[band] if whole else reference, gain)


# ---------------------------------------------------------------------------------------------
# One call: a press video in, the frames the model needs out.


def is_single_channel(pixel_format: str) -> bool:
    """Whether FFmpeg's ``pixel_format`` (a decoded frame's ``format.name``) holds one grey
    channel and no colour: ``gray`` and its deeper kinds, grey with alpha (``ya8``), black and
    white (``monob``)."""
    return pixel_format.startswith(("gray", "ya", "mono"))


def _colourless(rgb: np.ndarray) -> bool:
    """Whether an (H, W, 3) uint8 RGB frame has red, green and blue within 2 levels everywhere.

    Every 8th pixel of every 8th row first, which almost any colour frame fails; a frame that
    passes is then checked whole, a band of rows at a time (`_BAND_VALUES`), so that a large
    frame's 16-bit copies stay small."""

    def within(a: np.ndarray) -> bool:
        g = a[..., 1].astype(np.int16)
        return bool(
            np.abs(a[..., 0] - g).max(initial=0) <= 2 and np.abs(a[..., 2] - g).max(initial=0) <= 2
        )

    rows = band_rows(rgb[:1].size)
    return within(rgb[::8, ::8]) and all(
        within(rgb[top : top + rows]) for top in range(0, len(rgb), rows)
    )


@dataclass(frozen=True)
class Press:
    """What `read_press` took from a press video."""

    path: Path
    span: PressSpan
    indices: tuple[int, ...]
    """The frames selected (indices into the video)."""
    images: np.ndarray
    """(N, H, W, 3) uint8: the selected frames, or their `difference_image` from the reference."""
    reference: np.ndarray
    """(H, W, 3) float32 no-contact reference (mean of the reference frames)."""
    subtracted: bool
    """Whether ``images`` are differences from the reference."""
    pixel_format: str = ""
    """The pixel format of the decoded frames, as FFmpeg names it (``yuv420p``, ``gray`` ...)."""
    grey: bool = False
    """Whether the video has no colour: a single-channel pixel format (``gray``, ``gray16le``
    ...; `is_single_channel`), or red, green and blue equal (within 2 levels) in every frame
    read (a grey recording stored as colour). Its frames are read as RGB all the same, each
    channel the grey level: a model trained on colour presses never saw such an image."""


def read_press(
    path: str | os.PathLike[str],
    *,
    data: bytes | None = None,
    frames: int = 1,
    position: float | None = None,
    subtract_reference: bool = True,
    gain: float = DEFAULT_GAIN,
    max_frames: int | None = None,
    max_pixels: int | None = None,
    detect: Callable[..., PressSpan] = detect_press,
    choose: Callable[[PressSpan], Sequence[int]] | None = None,
    rotate: int = 0,
) -> Press:
    """Decode a press video, find its press and return the frames the model needs.

    Args:
        path: the video; with ``data``, only the name used in errors.
        data: the file's bytes, read from ``path`` when ``None``.
        frames: how many frames: 1 is the deepest contact (or ``position``), more are spread
            evenly over the contact span (`contact_frames`).
        position: with ``frames == 1``, take the frame at this position in [0, 1] across the
            contact span (`frame_at`) instead of the deepest one.
        subtract_reference: return `difference_image` of each frame from the no-contact
            reference, else the raw frames.
        gain: the difference's gain.
        max_frames: most frames decoded (default `MAX_VIDEO_FRAMES`).
        max_pixels: largest frame (default `DEFAULT_MAX_PIXELS`).
        detect: the press detector (`detect_press`), called with small greyscale frames.
        choose: picks the frames from the span instead of ``frames`` and ``position`` (for
            example ``lambda span: deep_frames(span, 12)``).
        rotate: turn every frame this many degrees clockwise as it is decoded (`rotate_frame`,
            ``data.video_rotate``): ``detect`` sees turned small frames, and the reference and
            the images are of turned frames. The turn does not change which frames are
            chosen.

    Returns:
        `Press`.

    Raises:
        VideoError: the file is not a regular file, cannot be decoded, is truncated, too large
            (frames or pixels), too short, or shows no contact; the message names the file.
        ValueError: ``rotate`` is not one of `ROTATIONS`.
    """
    p = Path(path)
    _check_turn(rotate)  # before anything is read
    blob = _read_bytes(p) if data is None else data
    small, decoded, pixel_format = _scan(
        p, blob, max_frames, max_pixels, keep_bytes=_KEEP_DECODED_BYTES, rotate=rotate
    )
    span = detect(small, p)
    if choose is not None:
        indices = list(choose(span))
    elif position is not None and frames == 1:
        indices = [frame_at(span, position)]
    else:
        indices = contact_frames(span, frames)
    made = _PressImages(
        indices, span.reference, subtract_reference, gain, is_single_channel(pixel_format)
    )
    for i, frame in _frames_at(p, blob, decoded, made.wanted, max_pixels, max_frames):
        made.add(i, _rgb(frame, rotate))
    del decoded  # the frames held from the scan, before the images are put together
    images, reference = made.result()
    return Press(
        p, span, tuple(indices), images, reference, subtract_reference, pixel_format, made.grey
    )


def _frames_at(
    p: Path,
    blob: bytes,
    decoded: list[av.video.frame.VideoFrame] | None,
    wanted: Sequence[int],
    max_pixels: int | None,
    max_frames: int | None,
) -> Iterator[tuple[int, av.video.frame.VideoFrame]]:
    """``(i, frame)`` for each of the sorted frame indices ``wanted``: from ``decoded`` (the
    frames `_scan` held), or, for a long or large video it did not hold, by decoding again, up to
    the last one wanted."""
    if decoded is not None:
        for i in wanted:
            yield i, decoded[i]
        return
    want = set(wanted)
    last = max(wanted)
    for i, frame in enumerate(_decode(p, blob, max_pixels, max_frames)):
        if i in want:
            yield i, frame
        if i >= last:
            break


class _PressImages:
    """`read_press`'s images and reference, made as the frames come (in order) rather than
    from all of them held at once: the reference frames are summed into the reference, and
    each chosen frame becomes its image (its difference from the reference once that is
    complete) as it is converted. At most one frame is held as RGB beside the result (more
    only for a frame chosen among the reference frames, kept until the reference is done), so
    that a 4K video costs its images and one float32 reference, not every frame wanted in
    float32. The bytes are those of the mean of the reference frames in float32 and of
    `difference_image` of each chosen frame: the sum of up to 65,793 8-bit frames is exact in
    float32, then divided as `numpy.mean` divides."""

    def __init__(
        self,
        indices: Sequence[int],
        reference: tuple[int, int],
        subtract: bool,
        gain: float,
        single: bool,
    ) -> None:
        self.a, self.b = reference
        self.n = len(indices)
        self.wanted = sorted(set(indices) | set(range(self.a, self.b)))
        """The frames to `add`, in this order."""
        self.subtract, self.gain = subtract, gain
        self.slots: dict[int, list[int]] = {}
        for k, i in enumerate(indices):
            self.slots.setdefault(i, []).append(k)
        self.sum: np.ndarray | None = None
        self.reference: np.ndarray | None = None
        self.held: dict[int, np.ndarray] = {}
        self.images: np.ndarray | None = None
        self.added = 0
        self.grey = single
        """Whether the video has no colour: a single-channel pixel format (``single``), or
        every frame added colourless (`_colourless`; final once `result` returns)."""
        self.colourless = True

    def add(self, i: int, rgb: np.ndarray) -> None:
        """Take frame ``i`` (the next of ``wanted``) as (H, W, 3) uint8 RGB."""
        self.added += 1
        if self.colourless and not self.grey:
            self.colourless = _colourless(rgb)
        if self.a <= i < self.b:
            if self.sum is None:
                self.sum = np.zeros(rgb.shape, np.float32)
            np.add(self.sum, rgb, out=self.sum)
            if i == self.b - 1:
                self.reference = self.sum
                np.true_divide(self.sum, np.intp(self.b - self.a), out=self.sum)
                for j in sorted(self.held):
                    self._image(j, self.held.pop(j))
        if i in self.slots:
            if self.subtract and self.reference is None:
                self.held[i] = rgb  # chosen among the reference frames: wait for all of them
            else:
                self._image(i, rgb)

    def _image(self, i: int, rgb: np.ndarray) -> None:
        if self.images is None:
            self.images = np.empty((self.n, *rgb.shape), np.uint8)
        first, *others = self.slots[i]
        if self.subtract:
            assert self.reference is not None
            _difference_into(self.images[first], rgb, self.reference, self.gain)
        else:
            self.images[first] = rgb
        for k in others:
            self.images[k] = self.images[first]

    def result(self) -> tuple[np.ndarray, np.ndarray]:
        """(N, H, W, 3) uint8 images, (H, W, 3) float32 reference."""
        if self.added < len(self.wanted):
            raise IndexError(f"frame {self.wanted[self.added]} chosen is past the video's end")
        if self.images is None or self.reference is None:
            raise ValueError("a press needs at least one reference frame and one frame chosen")
        self.grey = self.grey or self.colourless
        return self.images, self.reference


def is_grey_video(path: str | os.PathLike[str]) -> bool:
    """Whether a press video has no colour, as `lookfeel.data.video.Press.grey` says: its
    frames are of a single-channel pixel format (`is_single_channel`), or red, green and blue
    lie within 2 levels of each other in every frame. Decoding stops at the first frame with
    colour, so a colour video costs one frame. False for a file that cannot be decoded (its
    query's own error says why)."""
    try:
        for frame in _decode(Path(path), None, None, None):
            if is_single_channel(frame.format.name):
                return True
            if not _colourless(frame.to_ndarray(format="rgb24")):
                return False
    except VideoError:
        return False
    return True
